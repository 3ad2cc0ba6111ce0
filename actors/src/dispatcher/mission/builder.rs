//! Missions built in code: the same task tree a mission file holds, put together with
//! methods — for an application that decides its missions at run time, or a test that
//! should not need a file.
//!
//! A built mission is written out as the TOML a file would hold and parsed by the same
//! parser, so it is checked exactly as a file is (every structural rule, every diagnostic);
//! the diagnostics name `<mission built in code>` as their file.
//!
//! ```
//! use marie_actors::dispatcher::mission::{ActionBuilder, MissionBuilder};
//! use marie_actors::property::{ParamMap, Value};
//!
//! let parsed = MissionBuilder::new("collatz-demo")
//!     .flags(["reached-one"])
//!     .success(["reached-one"])
//!     .action(
//!         ActionBuilder::new("walk")
//!             .op("collatz", ParamMap::from([("start".to_string(), Value::Int(97))])),
//!     )
//!     .build()
//!     .unwrap();
//! assert_eq!(parsed.name(), "collatz-demo");
//! assert_eq!(parsed.flags()["reached-one"], 0);
//! assert_eq!(parsed.ops().collect::<Vec<_>>(), ["collatz"]);
//! ```

use super::{Diagnostics, ParsedMission};
use crate::property::{ParamMap, Value};
use std::time::Duration;

/// What the diagnostics of a built mission name as its file.
pub const BUILT: &str = "<mission built in code>";

/// A mission put together in code; [`MissionBuilder::build`] checks it as a file would be.
#[derive(Clone, Debug, Default)]
pub struct MissionBuilder {
    name: String,
    description: String,
    flags: Vec<String>,
    initial: Vec<String>,
    success: Vec<String>,
    deadline: Option<Duration>,
    rebind_deadline: Option<Duration>,
    requires: Vec<(String, String)>,
    actions: Vec<ActionBuilder>,
}

/// One action of a [`MissionBuilder`]: the operations it runs with their parameters, when it
/// may run and what ends it.
#[derive(Clone, Debug, Default)]
pub struct ActionBuilder {
    name: String,
    when: Vec<String>,
    ops: Vec<(String, ParamMap)>,
    ends_on: Vec<String>,
    all_end: bool,
    deadline: Option<Duration>,
}

impl MissionBuilder {
    /// A mission named `name`, with no flags and no actions yet.
    pub fn new(name: impl Into<String>) -> Self {
        MissionBuilder {
            name: name.into(),
            ..MissionBuilder::default()
        }
    }

    /// What it is for.
    pub fn description(mut self, text: impl Into<String>) -> Self {
        self.description = text.into();
        self
    }

    /// Declare flags of the status word, on the next free bits in order (the `[flags]`
    /// table of a file).
    pub fn flags<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.flags.extend(names.into_iter().map(Into::into));
        self
    }

    /// Flags set before the first action.
    pub fn initial<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.initial.extend(names.into_iter().map(Into::into));
        self
    }

    /// Flags that must all be set for the mission to succeed.
    pub fn success<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.success.extend(names.into_iter().map(Into::into));
        self
    }

    /// How long the whole mission may take.
    pub fn deadline(mut self, deadline: Duration) -> Self {
        self.deadline = Some(deadline);
        self
    }

    /// How long a lost operation may stay without a stand-in before the mission stops.
    pub fn rebind_deadline(mut self, deadline: Duration) -> Self {
        self.rebind_deadline = Some(deadline);
        self
    }

    /// Accept only instances of `operation` whose version matches `requirement` (semver,
    /// e.g. `"^2"`; the `[requires]` table of a file).
    pub fn requires(
        mut self,
        operation: impl Into<String>,
        requirement: impl Into<String>,
    ) -> Self {
        self.requires.push((operation.into(), requirement.into()));
        self
    }

    /// Add an action, after those added before.
    pub fn action(mut self, action: ActionBuilder) -> Self {
        self.actions.push(action);
        self
    }

    /// The mission as a file would hold it (TOML).
    pub fn to_toml(&self) -> String {
        let mut doc = toml::Table::new();
        let mut header = toml::Table::new();
        header.insert("name".into(), self.name.clone().into());
        if !self.description.is_empty() {
            header.insert("description".into(), self.description.clone().into());
        }
        if !self.initial.is_empty() {
            header.insert("initial".into(), strings(&self.initial));
        }
        header.insert("success".into(), strings(&self.success));
        if let Some(d) = self.deadline {
            header.insert("deadline_s".into(), d.as_secs_f64().into());
        }
        if let Some(d) = self.rebind_deadline {
            header.insert("rebind_deadline_s".into(), d.as_secs_f64().into());
        }
        doc.insert("mission".into(), header.into());
        let mut flags = toml::Table::new();
        for (bit, name) in self.flags.iter().enumerate() {
            flags.insert(name.clone(), (bit as i64).into());
        }
        doc.insert("flags".into(), flags.into());
        if !self.requires.is_empty() {
            let mut requires = toml::Table::new();
            for (op, req) in &self.requires {
                requires.insert(op.clone(), req.clone().into());
            }
            doc.insert("requires".into(), requires.into());
        }
        let actions: Vec<toml::Value> = self.actions.iter().map(|a| a.to_toml().into()).collect();
        doc.insert("action".into(), toml::Value::Array(actions));
        doc.to_string()
    }

    /// Check its structure as the parser checks a file's; then validate the result against
    /// the operations that run ([`ParsedMission::validate`], or a node's `check_mission`).
    pub fn build(&self) -> Result<ParsedMission, Diagnostics> {
        match ParsedMission::parse(&self.to_toml(), None) {
            Ok(mut parsed) => {
                parsed.file = BUILT.to_string();
                Ok(parsed)
            }
            Err(Diagnostics(mut all)) => {
                for d in &mut all {
                    d.path = BUILT.to_string();
                }
                Err(Diagnostics(all))
            }
        }
    }
}

impl ActionBuilder {
    /// An action named `name` that may run from the start and ends when any of its
    /// operations finishes.
    pub fn new(name: impl Into<String>) -> Self {
        ActionBuilder {
            name: name.into(),
            ..ActionBuilder::default()
        }
    }

    /// It may run when the status word has all of these flags.
    pub fn when<S: Into<String>>(mut self, flags: impl IntoIterator<Item = S>) -> Self {
        self.when.extend(flags.into_iter().map(Into::into));
        self
    }

    /// Run `operation` (by name or id) with `params` (those it omits keep their declared
    /// defaults).
    pub fn op(mut self, operation: impl Into<String>, params: ParamMap) -> Self {
        self.ops.push((operation.into(), params));
        self
    }

    /// End the action when `operation` finishes (default: when any of its operations
    /// does); add several and call [`ActionBuilder::all`] to wait for every one.
    pub fn ends_on(mut self, operation: impl Into<String>) -> Self {
        self.ends_on.push(operation.into());
        self
    }

    /// End only when every operation of [`ActionBuilder::ends_on`] has finished.
    pub fn all(mut self) -> Self {
        self.all_end = true;
        self
    }

    /// How long the action may take.
    pub fn deadline(mut self, deadline: Duration) -> Self {
        self.deadline = Some(deadline);
        self
    }

    fn to_toml(&self) -> toml::Table {
        let mut t = toml::Table::new();
        t.insert("name".into(), self.name.clone().into());
        if !self.when.is_empty() {
            t.insert("when".into(), strings(&self.when));
        }
        if !self.ends_on.is_empty() {
            t.insert("ends_on".into(), strings(&self.ends_on));
        }
        if self.all_end {
            t.insert("end_mode".into(), "all".into());
        }
        if let Some(d) = self.deadline {
            t.insert("deadline_s".into(), d.as_secs_f64().into());
        }
        let mut ops = toml::Table::new();
        for (op, params) in &self.ops {
            let table: toml::Table = params.iter().map(|(k, v)| (k.clone(), value(v))).collect();
            ops.insert(op.clone(), table.into());
        }
        t.insert("ops".into(), ops.into());
        t
    }
}

fn strings(names: &[String]) -> toml::Value {
    toml::Value::Array(names.iter().map(|n| n.clone().into()).collect())
}

/// A parameter value as TOML writes it (the parser reads it back to the same value).
fn value(v: &Value) -> toml::Value {
    match v {
        Value::Bool(b) => (*b).into(),
        Value::Int(i) => (*i).into(),
        Value::Float(f) => (*f).into(),
        Value::Text(s) => s.clone().into(),
        Value::Array(items) => toml::Value::Array(items.iter().map(value).collect()),
        Value::Struct(fields) => {
            toml::Value::Table(fields.iter().map(|(k, v)| (k.clone(), value(v))).collect())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dispatcher::mission::{OpInfo, StaticCatalog};
    use crate::property::{ParamDecl, ParamSchema};
    use crate::status::FlagDecl;

    fn catalog() -> StaticCatalog {
        StaticCatalog::new(vec![OpInfo::new("walker", 7, "1.0.0")
            .params(ParamSchema::new(vec![
                ParamDecl::int("start", 27).range(1.0, 1e12),
                ParamDecl::float("gain", 0.5),
            ]))
            .flags(vec![FlagDecl::new("done", "")])])
    }

    fn walk(start: Value) -> MissionBuilder {
        MissionBuilder::new("m")
            .flags(["ready", "done"])
            .initial(["ready"])
            .success(["done"])
            .deadline(Duration::from_secs(60))
            .action(
                ActionBuilder::new("walk")
                    .when(["ready"])
                    .op("walker", ParamMap::from([("start".to_string(), start)]))
                    .ends_on("walker")
                    .deadline(Duration::from_secs(5)),
            )
    }

    #[test]
    fn a_built_mission_validates_like_the_file_it_stands_for() {
        let mission = walk(Value::Int(97))
            .build()
            .unwrap()
            .validate(&catalog())
            .unwrap();
        assert_eq!(mission.flags["done"], 1);
        assert_eq!(mission.actions[0].ops[0].params["start"], Value::Int(97));
        assert_eq!(mission.actions[0].deadline, Duration::from_secs(5));
        assert_eq!(mission.deadline, Some(Duration::from_secs(60)));
    }

    #[test]
    fn a_built_mission_gets_the_diagnostics_a_file_would_naming_it_built_in_code() {
        let err = walk(Value::Int(0))
            .build()
            .unwrap()
            .validate(&catalog())
            .unwrap_err();
        let text = err.to_string();
        assert!(text.starts_with(BUILT), "{text}");
        assert!(text.contains("start"), "{text}");
        let err = MissionBuilder::new("m")
            .success(["nowhere"])
            .build()
            .unwrap_err();
        assert!(err.to_string().contains("nowhere"), "{err}");
    }
}

//! Missions built in code: the same task tree a mission file holds, put together with
//! methods — for an application that decides its missions at run time, or a test that
//! should not need a file.
//!
//! A built mission is written out as the TOML a file would hold and parsed by the same
//! parser, so it is checked exactly as a file is (every structural rule, every diagnostic);
//! the diagnostics name `<mission built in code>` as their file. Actions and groups are
//! written in the order they were added: the order of the thesis' schedule among items
//! whose flags hold at once.
//!
//! ```
//! use marie_actors::dispatcher::mission::{ActionBuilder, MissionBuilder};
//! use marie_vocabulary::property::{ParamMap, Value};
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
//!
//! // control: try `walk` twice, else fall back to `rest`
//! use marie_actors::dispatcher::mission::{GroupBuilder, GroupKind};
//! use std::time::Duration;
//! let parsed = MissionBuilder::new("with-control")
//!     .flags(["reached-one"])
//!     .success(["reached-one"])
//!     .group(GroupBuilder::new("go", GroupKind::Fallback).children(["walk", "rest"]))
//!     .action(
//!         ActionBuilder::new("walk")
//!             .op("collatz", ParamMap::new())
//!             .retry(2, Duration::from_secs(1))
//!             .timeout(Duration::from_secs(30)),
//!     )
//!     .action(ActionBuilder::new("rest").op("collatz", ParamMap::new()))
//!     .build()
//!     .unwrap();
//! assert!(parsed.has_control());
//! ```

use super::{Diagnostics, GroupKind, ParsedMission};
use marie_vocabulary::property::{ParamMap, Value};
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
    items: Vec<Item>,
}

/// An action or a group, in the order added.
#[derive(Clone, Debug)]
enum Item {
    Action(ActionBuilder),
    Group(GroupBuilder),
}

/// How an action or a group is controlled ([`ActionBuilder::retry`] and the like).
#[derive(Clone, Debug, Default)]
struct ControlKeys {
    retry: Option<(u32, Duration)>,
    timeout: Option<Duration>,
    on_failure: Option<String>,
    while_: Vec<String>,
    unless: Vec<String>,
}

impl ControlKeys {
    fn write(&self, t: &mut toml::Table) {
        if let Some((attempts, backoff)) = self.retry {
            let mut r = toml::Table::new();
            r.insert("attempts".into(), i64::from(attempts).into());
            r.insert("backoff_s".into(), backoff.as_secs_f64().into());
            t.insert("retry".into(), r.into());
        }
        if let Some(d) = self.timeout {
            t.insert("timeout_s".into(), d.as_secs_f64().into());
        }
        if let Some(r) = &self.on_failure {
            t.insert("on_failure".into(), r.clone().into());
        }
        if !self.while_.is_empty() {
            t.insert("while".into(), strings(&self.while_));
        }
        if !self.unless.is_empty() {
            t.insert("unless".into(), strings(&self.unless));
        }
    }
}

/// Methods that set how an action or a group is controlled, shared by both builders.
macro_rules! control_methods {
    () => {
        /// Run it again after a failure, `attempts` in all (the first included), waiting
        /// `backoff` between (`retry = { attempts, backoff_s }`).
        pub fn retry(mut self, attempts: u32, backoff: Duration) -> Self {
            self.control.retry = Some((attempts, backoff));
            self
        }

        /// Halt it and count it failed once it ran `limit` (`timeout_s`).
        pub fn timeout(mut self, limit: Duration) -> Self {
            self.control.timeout = Some(limit);
            self
        }

        /// After a failure, run the action or group named `recovery` before the next
        /// attempt (`on_failure`).
        pub fn on_failure(mut self, recovery: impl Into<String>) -> Self {
            self.control.on_failure = Some(recovery.into());
            self
        }

        /// Halt it, failed, once one of these flags is no longer set while it runs
        /// (`while`).
        pub fn while_flags<S: Into<String>>(mut self, flags: impl IntoIterator<Item = S>) -> Self {
            self.control
                .while_
                .extend(flags.into_iter().map(Into::into));
            self
        }

        /// Halt it, failed, once one of these flags is set while it runs (`unless`).
        pub fn unless<S: Into<String>>(mut self, flags: impl IntoIterator<Item = S>) -> Self {
            self.control
                .unless
                .extend(flags.into_iter().map(Into::into));
            self
        }
    };
}

/// A group of a [`MissionBuilder`] (`[[group]]`): actions and groups, by name, run as a
/// sequence, a fallback, a parallel or a reactive sequence.
#[derive(Clone, Debug)]
pub struct GroupBuilder {
    name: String,
    kind: GroupKind,
    children: Vec<String>,
    when: Vec<String>,
    success: Option<u32>,
    failure: Option<u32>,
    control: ControlKeys,
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
    control: ControlKeys,
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

    /// Add an action, after the actions and groups added before.
    pub fn action(mut self, action: ActionBuilder) -> Self {
        self.items.push(Item::Action(action));
        self
    }

    /// Add a group, after the actions and groups added before.
    pub fn group(mut self, group: GroupBuilder) -> Self {
        self.items.push(Item::Group(group));
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
        let mut text = doc.to_string();
        // one array-of-tables entry at a time, so actions and groups keep their order
        for item in &self.items {
            let (key, table) = match item {
                Item::Action(a) => ("action", a.to_toml()),
                Item::Group(g) => ("group", g.to_toml()),
            };
            let mut one = toml::Table::new();
            one.insert(key.into(), toml::Value::Array(vec![table.into()]));
            text.push('\n');
            text.push_str(&one.to_string());
        }
        text
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

    control_methods!();

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
        self.control.write(&mut t);
        let mut ops = toml::Table::new();
        for (op, params) in &self.ops {
            let table: toml::Table = params.iter().map(|(k, v)| (k.clone(), value(v))).collect();
            ops.insert(op.clone(), table.into());
        }
        t.insert("ops".into(), ops.into());
        t
    }
}

impl GroupBuilder {
    /// A group named `name` of kind `kind`, without children yet.
    pub fn new(name: impl Into<String>, kind: GroupKind) -> Self {
        GroupBuilder {
            name: name.into(),
            kind,
            children: Vec::new(),
            when: Vec::new(),
            success: None,
            failure: None,
            control: ControlKeys::default(),
        }
    }

    /// Its children: actions and groups by name, in order.
    pub fn children<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.children.extend(names.into_iter().map(Into::into));
        self
    }

    /// At the top level: it may run when the status word has all these flags; inside a
    /// group: it fails at once unless they are set.
    pub fn when<S: Into<String>>(mut self, flags: impl IntoIterator<Item = S>) -> Self {
        self.when.extend(flags.into_iter().map(Into::into));
        self
    }

    /// A parallel: it succeeds once `count` children succeeded (default: all).
    pub fn success(mut self, count: u32) -> Self {
        self.success = Some(count);
        self
    }

    /// A parallel: it fails once `count` children failed (default 1).
    pub fn failure(mut self, count: u32) -> Self {
        self.failure = Some(count);
        self
    }

    control_methods!();

    fn to_toml(&self) -> toml::Table {
        let mut t = toml::Table::new();
        t.insert("name".into(), self.name.clone().into());
        t.insert("kind".into(), self.kind.word().into());
        t.insert("children".into(), strings(&self.children));
        if !self.when.is_empty() {
            t.insert("when".into(), strings(&self.when));
        }
        if let Some(n) = self.success {
            t.insert("success".into(), i64::from(n).into());
        }
        if let Some(n) = self.failure {
            t.insert("failure".into(), i64::from(n).into());
        }
        self.control.write(&mut t);
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
    use marie_vocabulary::property::{ParamDecl, ParamSchema};
    use marie_vocabulary::status::FlagDecl;

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
    fn a_built_mission_with_control_builds_the_tree_its_file_would_in_the_order_added() {
        use crate::dispatcher::tree::Node;
        let built = MissionBuilder::new("m")
            .flags(["ready", "done"])
            .success(["done"])
            .action(ActionBuilder::new("first").op("walker", ParamMap::new()))
            .group(
                GroupBuilder::new("either", GroupKind::Fallback)
                    .children(["walk", "rest"])
                    .timeout(Duration::from_secs(9)),
            )
            .action(
                ActionBuilder::new("walk")
                    .op("walker", ParamMap::new())
                    .retry(3, Duration::from_secs(2))
                    .on_failure("rest")
                    .unless(["ready"]),
            )
            .action(ActionBuilder::new("rest").op("walker", ParamMap::new()));
        let text = built.to_toml();
        let from_text = ParsedMission::parse(&text, None)
            .unwrap()
            .validate(&catalog())
            .unwrap();
        let mission = built.build().unwrap().validate(&catalog()).unwrap();
        assert_eq!(mission.control, from_text.control);
        let Node::Schedule(top) = &mission.control.root else {
            panic!("a schedule: {:?}", mission.control.root)
        };
        // `first`, then the group: in the order added, though the group's table follows
        assert_eq!(top[0].node, Node::Action(0));
        assert!(
            matches!(&top[1].node, Node::Timeout { child, .. } if matches!(**child, Node::Fallback(_))),
            "{:?}",
            top[1].node
        );
        assert_eq!(top.len(), 2, "walk and rest run inside the group");
        let err = MissionBuilder::new("m")
            .flags(["done"])
            .success(["done"])
            .action(
                ActionBuilder::new("walk")
                    .op("walker", ParamMap::new())
                    .retry(0, Duration::ZERO),
            )
            .build()
            .unwrap_err();
        assert!(err.to_string().contains("a retry of 0 attempts"), "{err}");
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

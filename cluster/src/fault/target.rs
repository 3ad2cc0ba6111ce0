//! What a fault hits: a [`Target`] names exactly one instance — the one the mission bound
//! for an operation (followed through rebinds), one of a version, or an actor id — and is
//! resolved against the registry and what the run has bound so far ([`RunView`]).

use super::FaultError;
use marie_actors::dispatcher::DispatchEvent;
use marie_actors::eo::EoClient;
use marie_actors::property::{Group, PropertyReply, PropertyRequest};
use marie_actors::registry::{self, Instance, ModuleKind};
use std::collections::HashMap;
use std::fmt;

/// The instance a fault hits, as written after `KIND:` in a fault spec.
///
/// | written | hits |
/// |---|---|
/// | `NAME` or `ID` (`wall-follower`, `1514`) | the instance the mission bound for that operation (after a rebind, its stand-in); when the mission binds none, the only instance running |
/// | `NAME#VERSION` or `ID#VERSION` (`wall-follower#2.0.0`) | the instance with exactly that version |
/// | an actor id (`0.42`: an operation's `address` in a run's report; a run is repeatable, so it is the same in the next run of that mission, world and seed) | that instance |
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// The instance the mission bound (name or id).
    Bound(String),
    /// The instance of an operation (name or id) with a version.
    Version {
        /// Operation name or id.
        operation: String,
        /// Its exact version, e.g. `2.0.0`.
        version: String,
    },
    /// An instance by actor id.
    Actor(String),
}

impl Target {
    /// Parse a target (see [`Target`]).
    pub fn parse(s: &str) -> Result<Target, TargetError> {
        let syntax = || TargetError::Syntax(s.to_string());
        let plain = |t: &str| {
            !t.is_empty()
                && t.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
        };
        if let Some((operation, version)) = s.split_once('#') {
            let version_ok = !version.is_empty()
                && version
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '+'));
            if !plain(operation) || !version_ok {
                return Err(syntax());
            }
            return Ok(Target::Version {
                operation: operation.to_string(),
                version: version.to_string(),
            });
        }
        if let Some((node, pid)) = s.split_once('.') {
            let digits = |t: &str| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit());
            if !digits(node) || !digits(pid) {
                return Err(syntax());
            }
            return Ok(Target::Actor(s.to_string()));
        }
        if !plain(s) {
            return Err(syntax());
        }
        Ok(Target::Bound(s.to_string()))
    }

    /// The operation (name or id) the target names, if it names one.
    pub fn operation(&self) -> Option<&str> {
        match self {
            Target::Bound(op) | Target::Version { operation: op, .. } => Some(op),
            Target::Actor(_) => None,
        }
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Bound(op) => f.write_str(op),
            Target::Version { operation, version } => write!(f, "{operation}#{version}"),
            Target::Actor(id) => f.write_str(id),
        }
    }
}

/// Why a fault's target names no instance to hit.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TargetError {
    /// Not a target.
    #[error(
        "`{0}` is not a fault target: expected NAME, ID, NAME#VERSION or an actor id like 0.42"
    )]
    Syntax(String),
    /// No instance of that operation runs.
    #[error("no operation `{0}` is running (running: {1})")]
    NotRunning(String, String),
    /// No instance of that operation has that version.
    #[error("no instance of `{operation}` has version {version} (running: {running})")]
    NoVersion {
        /// Operation name or id.
        operation: String,
        /// The version asked for.
        version: String,
        /// The versions that run.
        running: String,
    },
    /// No operation instance has that actor id.
    #[error("no operation instance {0} is running (running: {1})")]
    NoActor(String, String),
    /// Several instances run and no mission binds one of them.
    #[error(
        "{count} instances of `{operation}` run and no mission binds one: name one as {choices}"
    )]
    Ambiguous {
        /// Operation name or id.
        operation: String,
        /// How many run.
        count: usize,
        /// `NAME#VERSION` for each.
        choices: String,
    },
    /// The instance the mission bound is gone and no stand-in is bound yet.
    #[error("the instance of `{0}` the mission bound is gone and no stand-in is bound yet")]
    Gone(String),
    /// The instance was found but the fault could not be delivered.
    #[error(transparent)]
    Inject(#[from] FaultError),
}

/// What the injector knows of the run: which operations the running action has (chaos
/// picks among them) and which instance the mission bound for each operation.
#[derive(Clone, Debug, Default)]
pub(crate) struct RunView {
    /// The operations of the running action (chaos picks among them).
    pub(crate) running: Vec<String>,
    /// Whether the mission has bound its operations yet.
    pub(crate) bound: bool,
    /// Operation name → version of the bound instance.
    versions: HashMap<String, String>,
    /// Operation name → actor id of the instance bound by the latest rebind.
    actors: HashMap<String, String>,
}

impl RunView {
    /// Take in a dispatcher event.
    pub(crate) fn observe(&mut self, evt: &DispatchEvent) {
        match evt {
            DispatchEvent::Bound { operations } => {
                self.bound = true;
                for (name, version, _node) in operations {
                    self.versions.insert(name.clone(), version.clone());
                }
            }
            DispatchEvent::ActionStarted { operations, .. } => self.running = operations.clone(),
            DispatchEvent::ActionEnded { .. } => self.running.clear(),
            DispatchEvent::Rebound(r) => {
                self.actors.insert(r.operation.clone(), r.to.clone());
            }
            _ => {}
        }
    }
}

/// Check, before a run, that `target` names an instance: an operation that runs (and, when
/// several instances run, one the mission binds, `bound_by_mission` saying which names it
/// binds), a version that runs, an actor id that runs.
pub async fn check_target(
    target: &Target,
    bound_by_mission: impl Fn(&str) -> bool,
) -> Result<(), TargetError> {
    let mut view = RunView::default();
    if let Target::Bound(op) = target {
        let instances = registry::lookup(ModuleKind::Operation, op);
        if instances.first().is_some_and(|i| bound_by_mission(&i.name)) {
            return Ok(());
        }
        view.bound = true; // the mission will bind none of them
    }
    resolve(target, &view).await.map(drop)
}

/// The instance `target` names now, outside a run: a name or id that several instances
/// share is ambiguous (`marie props`, `marie kill`).
pub async fn find(target: &Target) -> Result<Instance, TargetError> {
    let view = RunView {
        bound: true,
        ..RunView::default()
    };
    resolve(target, &view).await
}

/// The instance `target` names now.
pub(super) async fn resolve(target: &Target, view: &RunView) -> Result<Instance, TargetError> {
    let operations = || {
        let names: Vec<String> = registry::list()
            .into_iter()
            .filter(|i| i.kind == ModuleKind::Operation)
            .map(|i| format!("{} ({}) {}", i.name, i.id, i.actor.get_id()))
            .collect();
        names.join(", ")
    };
    let instances_of = |op: &str| {
        let found = registry::lookup(ModuleKind::Operation, op);
        if found.is_empty() {
            Err(TargetError::NotRunning(op.to_string(), operations()))
        } else {
            Ok(found)
        }
    };
    match target {
        Target::Actor(id) => registry::list()
            .into_iter()
            .find(|i| i.kind == ModuleKind::Operation && i.actor.get_id().to_string() == *id)
            .ok_or_else(|| TargetError::NoActor(id.clone(), operations())),
        Target::Version { operation, version } => {
            let found = instances_of(operation)?;
            let mut running = Vec::new();
            for inst in found {
                let v = version_of(&inst).await;
                if v.as_deref() == Some(version.as_str()) {
                    return Ok(inst);
                }
                running.push(v.unwrap_or_else(|| "?".into()));
            }
            Err(TargetError::NoVersion {
                operation: operation.clone(),
                version: version.clone(),
                running: running.join(", "),
            })
        }
        Target::Bound(op) => {
            let found = instances_of(op)?;
            let name = found[0].name.clone();
            if let Some(actor) = view.actors.get(&name) {
                if let Some(inst) = found
                    .iter()
                    .find(|i| i.actor.get_id().to_string() == *actor)
                {
                    return Ok(inst.clone());
                }
            }
            if let Some(version) = view.versions.get(&name) {
                for inst in &found {
                    if version_of(inst).await.as_deref() == Some(version.as_str()) {
                        return Ok(inst.clone());
                    }
                }
                return Err(TargetError::Gone(name));
            }
            if found.len() == 1 {
                return Ok(found[0].clone());
            }
            let mut choices = Vec::new();
            for inst in &found {
                let v = version_of(inst).await.unwrap_or_else(|| "?".into());
                choices.push(format!("{name}#{v}"));
            }
            Err(TargetError::Ambiguous {
                operation: op.clone(),
                count: found.len(),
                choices: choices.join(" or "),
            })
        }
    }
}

/// The version an instance reports (identification property); `None` if it does not answer.
async fn version_of(inst: &Instance) -> Option<String> {
    let client = EoClient::from_cell(inst.actor.clone());
    match client
        .property(PropertyRequest::Group(Group::Identification))
        .await
    {
        Ok(PropertyReply::Identification(i)) => Some(i.version.to_string()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse_and_print_back() {
        for (text, want) in [
            ("wall-follower", Target::Bound("wall-follower".into())),
            ("1514", Target::Bound("1514".into())),
            (
                "wall-follower#2.0.0",
                Target::Version {
                    operation: "wall-follower".into(),
                    version: "2.0.0".into(),
                },
            ),
            ("0.42", Target::Actor("0.42".into())),
        ] {
            let t = Target::parse(text).unwrap();
            assert_eq!(t, want);
            assert_eq!(t.to_string(), text);
        }
        for bad in ["", "#1.0.0", "x#", "0.", ".4", "1.2.3", "a b", "x@1", "x:y"] {
            assert!(
                matches!(Target::parse(bad), Err(TargetError::Syntax(_))),
                "{bad:?}"
            );
        }
    }
}

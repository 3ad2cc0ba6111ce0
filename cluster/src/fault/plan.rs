//! Faults injected into a node's run on a schedule: `marie run --fault KIND:TARGET@SECS` and
//! `--chaos SEED` (the parent module does the injecting).
//!
//! Times are mission clock time since the run began, so a fault lands at the same point of a
//! simulated run whatever the speed. A fault names exactly the instance it hits
//! ([`Target`]): by default the one the mission has bound for that operation (after a
//! rebind, its stand-in), else a version or an actor id. Every planned fault is recorded for
//! the run report — injected, or why not (no such instance, the mission was over first);
//! none is dropped silently.

use super::{Chaos, FaultError, FaultKind, FaultSpec};
use marie_actors::clock::SharedClock;
use marie_actors::dispatcher::{DispatchEvent, FaultRecord, RunReport, REPORT_KEEPS};
use marie_actors::eo::EoClient;
use marie_actors::events::{EventBus, EventKind};
use marie_actors::property::{Group, PropertyReply, PropertyRequest};
use marie_actors::registry::{self, Instance, ModuleKind};
use std::collections::{HashMap, VecDeque};
use std::fmt;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// The faults to inject during a run.
#[derive(Clone, Debug, Default)]
pub struct FaultPlan {
    /// Faults at fixed times; each [`FaultSpec::target`] is a [`Target`].
    pub faults: Vec<FaultSpec>,
    /// Random kills of the running action's operations, seeded.
    pub chaos: Option<Chaos>,
}

impl FaultPlan {
    /// True when there is nothing to inject.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty() && self.chaos.is_none()
    }
}

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
    running: Vec<String>,
    bound: bool,
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
async fn resolve(target: &Target, view: &RunView) -> Result<Instance, TargetError> {
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
        Ok(PropertyReply::Identification(i)) => Some(i.version),
        _ => None,
    }
}

/// What became of a run's faults, bounded like the report: every fault counted, the latest
/// [`REPORT_KEEPS`] kept (the event stream has them all) — chaos over a long run must not
/// grow memory without limit.
#[derive(Debug, Default)]
pub(crate) struct FaultLog {
    /// The latest faults, oldest first.
    pub(crate) latest: VecDeque<FaultRecord>,
    /// Faults counted but no longer kept.
    pub(crate) dropped: u64,
}

impl FaultLog {
    /// Add `rec`, dropping the oldest beyond [`REPORT_KEEPS`].
    pub(crate) fn push(&mut self, rec: FaultRecord) {
        if self.latest.len() >= REPORT_KEEPS {
            self.latest.pop_front();
            self.dropped += 1;
        }
        self.latest.push_back(rec);
    }

    /// Fill the report's `faults` and `faults_total`.
    pub(crate) fn into_report(self, report: &mut RunReport) {
        report.record_faults(self.latest);
        report.faults_total += self.dropped;
    }
}

/// The injection tasks of one run.
pub(crate) struct Injector {
    tasks: Vec<JoinHandle<()>>,
    records: Arc<Mutex<FaultLog>>,
    /// Fixed faults not yet due, in time order.
    pending: Arc<Mutex<Vec<FaultSpec>>>,
    clock: SharedClock,
    t0: Duration,
    bus: EventBus,
}

/// Publish what became of a fault on the node's event bus.
fn publish(bus: &EventBus, rec: &FaultRecord) {
    bus.publish(match &rec.error {
        None => EventKind::FaultInjected {
            run_ms: rec.at_ms,
            fault: rec.fault,
            operation: rec.operation.clone(),
            actor: rec.actor.clone(),
        },
        Some(why) => EventKind::FaultNotInjected {
            run_ms: rec.at_ms,
            fault: rec.fault,
            operation: rec.operation.clone(),
            why: why.clone(),
        },
    });
}

impl Injector {
    /// Start injecting `plan` on `clock`, counting from now; `view` follows the run. Fixed
    /// faults wait for the mission's bindings, so that even a fault at 0 s hits the bound
    /// instance.
    pub(crate) fn start(
        plan: FaultPlan,
        clock: SharedClock,
        view: watch::Receiver<RunView>,
        bus: EventBus,
    ) -> Injector {
        let records = Arc::new(Mutex::new(FaultLog::default()));
        let t0 = clock.now();
        let mut faults = plan.faults;
        faults.sort_by_key(|f| f.at);
        let pending = Arc::new(Mutex::new(faults));
        let mut tasks = Vec::new();
        if !lock(&pending).is_empty() {
            let (clock, records, pending, mut view, bus) = (
                clock.clone(),
                records.clone(),
                pending.clone(),
                view.clone(),
                bus.clone(),
            );
            tasks.push(tokio::spawn(async move {
                if view.wait_for(|v| v.bound).await.is_err() {
                    return;
                }
                loop {
                    let Some(at) = lock(&pending).first().map(|f| f.at) else {
                        return;
                    };
                    clock.sleep((t0 + at).saturating_sub(clock.now())).await;
                    // it stays pending until recorded: a run that ends meanwhile reports it
                    let f = lock(&pending)[0].clone();
                    let current = view.borrow().clone();
                    let rec = inject(&clock, t0, f.kind, &f.target, &current).await;
                    lock(&pending).remove(0);
                    publish(&bus, &rec);
                    lock(&records).push(rec);
                }
            }));
        }
        if let Some(mut chaos) = plan.chaos {
            let (clock, records, bus) = (clock.clone(), records.clone(), bus.clone());
            tasks.push(tokio::spawn(async move {
                loop {
                    clock.sleep(chaos.next_gap()).await;
                    let current = view.borrow().clone();
                    if let Some(target) = chaos.pick(&current.running) {
                        let rec = inject(&clock, t0, FaultKind::Kill, target, &current).await;
                        publish(&bus, &rec);
                        lock(&records).push(rec);
                    }
                }
            }));
        }
        Injector {
            tasks,
            records,
            pending,
            clock,
            t0,
            bus,
        }
    }

    /// Stop injecting; the log of every fault: injected, not injected and why, and —
    /// for those not yet due — that the mission was over first.
    pub(crate) fn finish(self) -> FaultLog {
        for t in &self.tasks {
            t.abort();
        }
        let ended = self.clock.now().saturating_sub(self.t0);
        let mut records = std::mem::take(&mut *lock(&self.records));
        for f in std::mem::take(&mut *lock(&self.pending)) {
            let error = format!(
                "the mission was over (at {:.1}s) before it could be injected",
                ended.as_secs_f64()
            );
            tracing::warn!(fault = %f.kind, op = %f.target, "fault not injected: {error}");
            let rec = FaultRecord {
                at_ms: f.at.as_millis() as u64,
                fault: f.kind,
                operation: f.target,
                actor: String::new(),
                error: Some(error),
            };
            publish(&self.bus, &rec);
            records.push(rec);
        }
        records
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Inject `kind` into the instance `target` names now; the record of it.
async fn inject(
    clock: &SharedClock,
    t0: Duration,
    kind: FaultKind,
    target: &str,
    view: &RunView,
) -> FaultRecord {
    let result = match Target::parse(target) {
        Ok(t) => match resolve(&t, view).await {
            Ok(inst) => super::inject_into(kind, &inst).map_err(TargetError::from),
            Err(e) => Err(e),
        },
        Err(e) => Err(e),
    };
    let at_ms = clock.now().saturating_sub(t0).as_millis() as u64;
    match result {
        Ok(done) => FaultRecord {
            at_ms,
            fault: kind,
            operation: target.to_string(),
            actor: done.actor.to_string(),
            error: None,
        },
        Err(e) => {
            tracing::warn!(fault = %kind, op = %target, error = %e, "fault not injected");
            FaultRecord {
                at_ms,
                fault: kind,
                operation: target.to_string(),
                actor: String::new(),
                error: Some(e.to_string()),
            }
        }
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

//! Faults injected into a node's run on a schedule: `marie run --fault KIND:TARGET@SECS` and
//! `--chaos SEED` (the parent module does the injecting).
//!
//! Times are mission clock time since the run began, so a fault lands at the same point of a
//! simulated run whatever the speed. A fault names exactly the instance it hits
//! ([`Target`]): by default the one the mission has bound for that operation (after a
//! rebind, its stand-in), else a version or an actor id. Every planned fault is recorded for
//! the run report — injected, or why not (no such instance, the mission was over first);
//! none is dropped silently.

pub use super::target::{check_target, find, Target, TargetError};

use super::target::resolve;
pub(crate) use super::target::RunView;
use super::{Chaos, FaultKind, FaultSpec};
use marie_actors::clock::SharedClock;
use marie_actors::dispatcher::{FaultRecord, RunReport, REPORT_KEEPS};
use marie_actors::events::{EventBus, EventKind};
use std::collections::VecDeque;
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

impl From<Vec<FaultSpec>> for FaultPlan {
    /// Faults at fixed times, no chaos.
    fn from(faults: Vec<FaultSpec>) -> Self {
        FaultPlan {
            faults,
            chaos: None,
        }
    }
}

impl FaultPlan {
    /// True when there is nothing to inject.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty() && self.chaos.is_none()
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

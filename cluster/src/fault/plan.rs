//! Faults injected into a node's run on a schedule: `marie run --fault KIND:NAME@SECS` and
//! `--chaos SEED` (the parent module does the injecting).
//!
//! Times are mission clock time since the run began, so a fault lands at the same point of a
//! simulated run whatever the speed. Every injection — and every one that found nothing to
//! hit — is recorded for the run report.

use super::{Chaos, FaultKind, FaultSpec};
use marie_actors::clock::SharedClock;
use marie_actors::dispatcher::FaultRecord;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// The faults to inject during a run.
#[derive(Clone, Debug, Default)]
pub struct FaultPlan {
    /// Faults at fixed times.
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

/// The injection tasks of one run.
pub(crate) struct Injector {
    tasks: Vec<JoinHandle<()>>,
    records: Arc<Mutex<Vec<FaultRecord>>>,
}

impl Injector {
    /// Start injecting `plan` on `clock`, counting from now. `running` holds the operations
    /// of the action that runs (chaos picks among them).
    pub(crate) fn start(
        plan: FaultPlan,
        clock: SharedClock,
        running: watch::Receiver<Vec<String>>,
    ) -> Injector {
        let records = Arc::new(Mutex::new(Vec::new()));
        let t0 = clock.now();
        let mut tasks = Vec::new();
        if !plan.faults.is_empty() {
            let mut faults = plan.faults;
            faults.sort_by_key(|f| f.at);
            let (clock, records) = (clock.clone(), records.clone());
            tasks.push(tokio::spawn(async move {
                for f in faults {
                    let wait = (t0 + f.at).saturating_sub(clock.now());
                    clock.sleep(wait).await;
                    record(&records, &clock, t0, f.kind, &f.target);
                }
            }));
        }
        if let Some(mut chaos) = plan.chaos {
            let records = records.clone();
            tasks.push(tokio::spawn(async move {
                loop {
                    clock.sleep(chaos.next_gap()).await;
                    let ops = running.borrow().clone();
                    if let Some(target) = chaos.pick(&ops) {
                        record(&records, &clock, t0, FaultKind::Kill, target);
                    }
                }
            }));
        }
        Injector { tasks, records }
    }

    /// Stop injecting; the records of what was injected.
    pub(crate) fn finish(self) -> Vec<FaultRecord> {
        for t in &self.tasks {
            t.abort();
        }
        std::mem::take(&mut *self.records.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

fn record(
    records: &Mutex<Vec<FaultRecord>>,
    clock: &SharedClock,
    t0: Duration,
    kind: FaultKind,
    target: &str,
) {
    let at_ms = clock.now().saturating_sub(t0).as_millis() as u64;
    let rec = match super::inject(kind, target) {
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
    };
    records.lock().unwrap_or_else(|e| e.into_inner()).push(rec);
}

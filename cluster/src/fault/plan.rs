//! Faults injected into a run on a schedule — `--fault KIND:TARGET@SECS`, `--chaos SEED`
//! and `--chaos-nodes SEED` — through the run's [`Injector`].
//!
//! Times are mission clock time since the run began, so a fault lands at the same point of a
//! simulated run whatever the speed. Fixed faults wait until the mission has bound its
//! operations, so that even a fault at 0 s hits the bound instance. Every planned fault ends
//! up on the bus, so in the report — injected, or why not (no such instance, the mission
//! was over first); none is dropped silently. The node chaos's schedule alone runs on
//! across runs (see [`NodeChaos`]): its clock stops when a run ends and goes on when the
//! next one has bound its operations.

use super::{Chaos, FaultSpec, Injector, NodeChaos, Target};
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::FaultKind;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::task::JoinHandle;

/// The faults to inject during a run.
#[derive(Clone, Debug, Default)]
pub(crate) struct FaultPlan {
    /// Faults at fixed times.
    pub(crate) faults: Vec<FaultSpec>,
    /// Random kills of the running action's operations, seeded.
    pub(crate) chaos: Option<Chaos>,
    /// Random node faults, seeded.
    pub(crate) node_chaos: Option<NodeChaos>,
}

/// The injection tasks of one run.
pub(crate) struct PlanRun {
    tasks: Vec<JoinHandle<()>>,
    /// The node chaos, whose schedule outlives the run (see [`NodeChaos`]).
    node_chaos: Option<NodeChaos>,
    /// Fixed faults not yet done, in time order.
    pending: Arc<Mutex<Vec<FaultSpec>>>,
    injector: Injector,
    clock: SharedClock,
    t0: Duration,
}

impl PlanRun {
    /// Start injecting `plan` through `injector` (which follows the run) on `clock`,
    /// counting from now.
    pub(crate) fn start(plan: FaultPlan, injector: Injector, clock: SharedClock) -> PlanRun {
        let t0 = clock.now();
        let mut faults = plan.faults;
        faults.sort_by_key(|f| f.at);
        let pending = Arc::new(Mutex::new(faults));
        let mut tasks = Vec::new();
        if !lock(&pending).is_empty() {
            let (clock, pending, injector) = (clock.clone(), pending.clone(), injector.clone());
            tasks.push(tokio::spawn(async move {
                injector.bound().await;
                loop {
                    let Some(at) = lock(&pending).first().map(|f| f.at) else {
                        return;
                    };
                    clock.sleep((t0 + at).saturating_sub(clock.now())).await;
                    // it stays pending until done: a run that ends meanwhile reports it
                    let spec = lock(&pending)[0].clone();
                    let _ = injector.inject_due(&spec).await;
                    lock(&pending).remove(0);
                }
            }));
        }
        if let Some(mut chaos) = plan.chaos {
            let (clock, injector) = (clock.clone(), injector.clone());
            tasks.push(tokio::spawn(async move {
                loop {
                    clock.sleep(chaos.next_gap()).await;
                    let bindings = injector.bindings();
                    let mut victims = bindings.running();
                    if chaos.datamanagers {
                        let mut dms: Vec<String> = registry::list_of(ModuleKind::Datamanager)
                            .into_iter()
                            .map(|i| i.name)
                            .collect();
                        dms.sort();
                        dms.dedup();
                        victims.extend(dms);
                    }
                    if let Some(key) = chaos.pick(&victims) {
                        let target = Target::Bound(key.clone());
                        let _ = injector.inject(FaultKind::Kill, &target).await;
                    }
                }
            }));
        }
        if let Some(chaos) = plan.node_chaos.clone() {
            let (clock, injector) = (clock.clone(), injector.clone());
            tasks.push(tokio::spawn(async move {
                injector.bound().await;
                // the schedule's clock runs from the binding on (see `NodeChaos`)
                chaos.lap_begins(clock.now());
                loop {
                    clock.sleep(chaos.until_next(clock.now())).await;
                    let Some(strike) = chaos.draw(injector.processes()) else {
                        tracing::info!(
                            "node chaos: no node to hit now; the next strike is due later"
                        );
                        chaos.done(None, clock.now().saturating_sub(t0));
                        continue;
                    };
                    let injected = injector
                        .inject_for(strike.kind, &strike.target, strike.lasting)
                        .await;
                    let outcome = injected.map(|_| ()).map_err(|e| e.to_string());
                    chaos.done(Some((strike, outcome)), clock.now().saturating_sub(t0));
                }
            }));
        }
        PlanRun {
            tasks,
            node_chaos: plan.node_chaos,
            pending,
            injector,
            clock,
            t0,
        }
    }

    /// Stop injecting; tell the bus of each fault not yet due that the mission was over
    /// first.
    pub(crate) fn finish(mut self) {
        self.stop();
        let ended = self.clock.now().saturating_sub(self.t0);
        for spec in std::mem::take(&mut *lock(&self.pending)) {
            let why = format!(
                "the mission was over (at {:.1}s) before it could be injected",
                ended.as_secs_f64()
            );
            self.injector.not_injected(&spec, &why);
        }
    }
}

impl PlanRun {
    /// Stop the tasks; the node chaos's schedule stops with the run's mission time.
    fn stop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
        if let Some(chaos) = self.node_chaos.take() {
            chaos.lap_ends(self.clock.now());
        }
    }
}

impl Drop for PlanRun {
    fn drop(&mut self) {
        self.stop();
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

//! Running a mission on a node: [`Node::run`] with its [`RunOptions`] — the one way to run
//! one.
//!
//! A run is told on the node's one bus and nowhere else: the dispatcher's steps, the
//! bindings and choices, the supervisors and the registry, every fault whatever its source
//! (the options' plan and chaos, `marie kill`, the monitor's page), the nodes, the robot's
//! live events and its judgement. The report is a
//! [`ReportBuilder`](marie_vocabulary::report::ReportBuilder) folded over those events while the
//! run lasts — so it equals [`RunReport::from_events`] of the run's events file — and
//! observers see the same events as they are published.
//!
//! # Invariants
//! - A node runs one mission at a time (a second [`Node::run`] waits for the first): the
//!   bus then carries one run, and its fold is that run's report.
//! - Faults are checked before anything of the run starts: one that names nothing refuses
//!   the run ([`NodeError::Fault`]).
//! - Every planned fault ends up on the bus — injected, or why not.

use super::robot::RunJudgement;
use super::{Node, NodeError};
use crate::fault::{Chaos, FaultPlan, FaultSpec, Injector, NodeChaos, NodeProcesses, PlanRun};
use marie_actors::dispatcher::mission::Mission;
use marie_actors::dispatcher::{self, DispatcherArgs, DispatcherMsg};
use marie_supervision::{ChildSpec, Restart, Shutdown};
use marie_vocabulary::events::{Event, EventKind};
use marie_vocabulary::report::{ReportBuilder, RunReport};
use marie_vocabulary::run::provenance::{rfc3339, this_build};
use marie_vocabulary::run::{NodeBuild, Outcome, Provenance};
use ractor::ActorRef;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use super::tree::{abort_on_give_up, DATAMANAGERS};
use super::MissionInput;

/// How long a run's start waits for a peer to name its build (heartbeats come every
/// period; a peer just joined may not have beaten yet): wall-clock time.
const PEER_BUILDS_WAIT: Duration = Duration::from_secs(2);

/// An observer of a run's events ([`RunOptions::observe`]).
type Observer = Arc<dyn Fn(&Event) + Send + Sync>;

/// How to run a mission ([`Node::run`]): faults to inject, chaos, the node processes a fault
/// may stop, observers of the run's events. The default runs the mission as it is.
///
/// ```
/// use marie_cluster::fault::Chaos;
/// use marie_cluster::node::RunOptions;
/// let options = RunOptions::new()
///     .fault("panic:pump@0.5".parse().unwrap())
///     .chaos(Chaos::new(7))
///     .observe(|event| tracing::info!(?event.kind, "run"));
/// assert_eq!(options.planned_faults().len(), 1);
/// ```
#[derive(Clone, Default)]
pub struct RunOptions {
    faults: Vec<FaultSpec>,
    chaos: Option<Chaos>,
    node_chaos: Option<NodeChaos>,
    processes: NodeProcesses,
    observers: Vec<Observer>,
    dispatch_on: Option<String>,
    provenance: Option<Provenance>,
}

impl std::fmt::Debug for RunOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions")
            .field("faults", &self.faults)
            .field("chaos", &self.chaos)
            .field("node_chaos", &self.node_chaos)
            .field("processes", &self.processes)
            .field("observers", &self.observers.len())
            .field("dispatch_on", &self.dispatch_on)
            .field("provenance", &self.provenance.is_some())
            .finish()
    }
}

impl RunOptions {
    /// Run the mission as it is.
    pub fn new() -> RunOptions {
        RunOptions::default()
    }

    /// Inject `fault` at its time of the run (`KIND:TARGET@SECS`: a plain name hits the
    /// instance the mission bound, through its rebinds).
    pub fn fault(mut self, fault: FaultSpec) -> RunOptions {
        self.faults.push(fault);
        self
    }

    /// Inject each of `faults` at its time.
    pub fn faults(mut self, faults: impl IntoIterator<Item = FaultSpec>) -> RunOptions {
        self.faults.extend(faults);
        self
    }

    /// Kill the bound instance of a random operation of the running action at the gaps
    /// `chaos` draws (seeded: the same picks for the same seed).
    pub fn chaos(mut self, chaos: Chaos) -> RunOptions {
        self.chaos = Some(chaos);
        self
    }

    /// Stop, freeze or cut off a random node (never one the chaos spares) at the gaps
    /// `chaos` draws (seeded). Needs [node processes](Self::node_processes) to hit.
    pub fn node_chaos(mut self, chaos: NodeChaos) -> RunOptions {
        self.node_chaos = Some(chaos);
        self
    }

    /// The node processes a fault may stop, freeze or cut apart (`stop-node:NAME@SECS`,
    /// `freeze-node:NAME@SECS+SECS`, `partition:A|B@SECS+SECS`): `marie up`'s children.
    /// Without them a node fault is refused before the run.
    pub fn node_processes(mut self, processes: NodeProcesses) -> RunOptions {
        self.processes = processes;
        self
    }

    /// Call `f` with every event of the node's bus while the run lasts, from before its
    /// first event to its judgement, in the order they are published, none lost. `f` runs
    /// in the publisher's call: keep it quick (count, filter, forward into a channel of
    /// your own), and do not publish from it.
    pub fn observe(mut self, f: impl Fn(&Event) + Send + Sync + 'static) -> RunOptions {
        self.observers.push(Arc::new(f));
        self
    }

    /// Dispatch the run on the desk of node `node` ([`super::desk`]: a node config with
    /// `dispatcher = "active"` or `"standby"`) instead of this node, and follow it there —
    /// and to whichever standby takes it over should that node be lost. Its events are
    /// republished on this node's bus, so the report, faults and observers work as for a
    /// run dispatched here.
    pub fn dispatch_on(mut self, node: impl Into<String>) -> RunOptions {
        self.dispatch_on = Some(node.into());
        self
    }

    /// What runs, as the run's first event tells it ([`Provenance`]): the command line, the
    /// files read with their texts, the seed and speed — what only the caller knows. The
    /// node fills in the rest: this process's build ([`this_build`]) unless given, the
    /// start time unless given, and every node of the run with its build (this one, then
    /// its peers). Without it the run's provenance holds only what the node fills in.
    pub fn provenance(mut self, provenance: Provenance) -> RunOptions {
        self.provenance = Some(provenance);
        self
    }

    /// The node the run is dispatched on, if not this one ([`RunOptions::dispatch_on`]).
    pub fn dispatched_on(&self) -> Option<&str> {
        self.dispatch_on.as_deref()
    }

    /// The faults planned at fixed times.
    pub fn planned_faults(&self) -> &[FaultSpec] {
        &self.faults
    }
}

impl Node {
    /// Run a mission and give its report: a mission file's text, a
    /// [`MissionBuilder`](marie_actors::dispatcher::mission::MissionBuilder), a parsed or an
    /// already checked [`Mission`]. Text and built missions are checked against the
    /// instances that run first; a mission that does not fit is refused with its
    /// diagnostics ([`NodeError::Mission`]), a fault that names nothing with why
    /// ([`NodeError::Fault`]) — before anything runs. The run binds the instances the
    /// check chose, re-selecting only an operation whose instances changed since
    /// ([`Mission::checked`]).
    ///
    /// The report is the run's events folded (see the module docs): with a
    /// [`Robot`](super::Robot), its judgement too (for the simulated cart its final pose,
    /// collisions, seed and the world's verdict, which may turn the dispatcher's success
    /// into a failure). A crashed operation is restarted by its supervisor and the
    /// dispatcher rebinds to the new instance: the options' faults test exactly that.
    ///
    /// ```
    /// # use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    /// # use marie_vocabulary::status::{FlagDecl, StatusFlags};
    /// # #[derive(Default)] struct Tick { n: u32 }
    /// # impl Operation for Tick {
    /// #     fn identity(&self) -> Identity { Identity::new("f-tick", 4401, "1.0.0", "ticks") }
    /// #     fn flags(&self) -> Vec<FlagDecl> { vec![FlagDecl::new("ticked", "done")] }
    /// #     fn period(&self) -> std::time::Duration { std::time::Duration::from_millis(10) }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
    /// #         self.n += 1;
    /// #         Ok(if self.n >= 30 { Step::Finish(StatusFlags(1)) } else { Step::Continue })
    /// #     }
    /// # }
    /// use marie_cluster::node::{Node, NodeError, RunOptions};
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let node = Node::builder("runs").operation::<Tick>().start().await?;
    /// let mission = "[mission]\nname = \"m\"\nsuccess = [\"ticked\"]\n[flags]\nticked = 0\n\
    ///                [[action]]\nname = \"a\"\n[action.ops.f-tick]\n";
    /// // 0.1 s in, the operation panics: its supervisor restarts it, the mission is rebound
    /// let faulty = RunOptions::new().fault("panic:f-tick@0.1".parse()?);
    /// let report = node.run(mission, faulty).await?;
    /// assert!(report.succeeded());
    /// assert_eq!((report.rebinds.len(), report.faults.len()), (1, 1));
    /// // the same mission again, as it is
    /// assert!(node.run(mission, RunOptions::new()).await?.succeeded());
    ///
    /// // a mission the running instances do not fit is refused with its diagnostics
    /// let typo = mission.replace("[action.ops.f-tick]", "[action.ops.f-tock]");
    /// let Err(NodeError::Mission(diags)) = node.run(typo, RunOptions::new()).await else {
    ///     panic!()
    /// };
    /// assert!(diags.to_string().contains("f-tock"));
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    pub async fn run(
        &self,
        mission: impl Into<MissionInput>,
        options: RunOptions,
    ) -> Result<RunReport, NodeError> {
        // one run at a time: the bus carries one run, and its fold is that run's report
        let _one = self.one_run.lock().await;
        if !self.config.dispatcher {
            return Err(NodeError::NoDispatcher(self.config.name.clone()));
        }
        let mission = self.resolve(mission.into()).await?;
        self.check_faults(&mission, &options).await?;
        let RunOptions {
            faults,
            chaos,
            node_chaos,
            processes,
            observers,
            dispatch_on,
            provenance,
        } = options;
        let report = ReportBuilder::attach(&self.bus);
        // what the run's stores get acknowledged, for the check of the datamanagers
        let audit = super::audit::RunAudit::start(&self.bus).await;
        let _observers: Vec<_> = observers
            .into_iter()
            .map(|f| self.bus.tap(move |event| f(event)))
            .collect();
        // what runs: the run's first event
        let provenance = self.provenance(provenance.unwrap_or_default()).await;
        self.bus
            .publish(EventKind::Provenance(Box::new(provenance)));
        // what its datamanagers started from (told at the node's start, before any run
        // listened): the events file and the report say what the run began with
        self.tell_datamanager_starts().await;
        // the robot's world first, before the run's own events; the previous run's
        // reporting ends first, so nothing is told twice
        if let Some(robot) = &self.robot {
            self.abort_run_tasks();
            let tasks = robot.run_starting(&self.bus).await;
            *self.run_tasks.lock().unwrap_or_else(|e| e.into_inner()) = tasks;
        }
        let injector = Injector::new(&self.bus)
            .with_processes(processes)
            .aiming_at_bindings();
        let plan = PlanRun::start(
            FaultPlan {
                faults,
                chaos,
                node_chaos,
            },
            injector,
            self.starter.clock.clone(),
        );
        let ended = match &dispatch_on {
            Some(on) => self.dispatch_on(mission, on).await,
            None => self.dispatch(mission).await,
        };
        plan.finish();
        ended?;
        if let Some(robot) = &self.robot {
            let so_far = report.report();
            let RunJudgement {
                outcome,
                reason,
                robot,
            } = robot.judge(&so_far).await;
            self.bus.publish(EventKind::Judged {
                outcome,
                reason,
                robot,
            });
        }
        // the mission is over: is everything acknowledged during it still there?
        audit.finish(&self.bus).await;
        Ok(report.finish())
    }

    /// `provenance` completed by what the node knows: this process's build, the start
    /// time, and the nodes — this one, then each peer with the build its heartbeats named
    /// (waited for up to [`PEER_BUILDS_WAIT`] should a peer not have said yet).
    /// Tell again what each of this node's datamanagers started from (`dm_recovered`,
    /// `dm_inherited`).
    async fn tell_datamanager_starts(&self) {
        let Ok(dms) = super::tree::child_supervisor(&self.starter.root, DATAMANAGERS).await else {
            return; // a node without datamanagers
        };
        for dm in dms.which_children().await.unwrap_or_default() {
            if let Some(actor) = dm.state.actor() {
                super::events::tell_start(&self.bus, actor.clone()).await;
            }
        }
    }

    async fn provenance(&self, mut provenance: Provenance) -> Provenance {
        let this = this_build();
        provenance.marie.get_or_insert_with(|| this.clone());
        if provenance.started_unix_ms == 0 {
            provenance.started_unix_ms = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_millis() as u64);
        }
        if provenance.started.is_empty() {
            provenance.started = rfc3339(provenance.started_unix_ms);
        }
        let peers = crate::net::heartbeat::peer_builds(PEER_BUILDS_WAIT).await;
        provenance.nodes = std::iter::once(NodeBuild {
            node: self.config.name.clone(),
            marie: Some(this),
        })
        .chain(
            peers
                .into_iter()
                .map(|(node, marie)| NodeBuild { node, marie }),
        )
        .collect();
        provenance
    }

    /// Check that every fault of `options` names something to hit: an operation the
    /// mission binds or that runs, a version, an actor id, an instance on a node, a node
    /// process the options may stop.
    pub async fn check_faults(
        &self,
        mission: &Mission,
        options: &RunOptions,
    ) -> Result<(), NodeError> {
        let bound = mission.operation_names();
        let injector = Injector::new(&self.bus).with_processes(options.processes.clone());
        for spec in &options.faults {
            injector
                .check(spec, |name| bound.contains(&name))
                .await
                .map_err(|error| NodeError::Fault {
                    spec: spec.to_string(),
                    error,
                })?;
        }
        if options.node_chaos.is_some() && options.processes.is_empty() {
            return Err(NodeError::NodeChaos(
                "only `marie up` stops, freezes or cuts off node processes, the ones it started"
                    .into(),
            ));
        }
        Ok(())
    }

    /// Run `mission` on a dispatcher started as a temporary child of the node's supervisor;
    /// the dispatcher's outcome. Should an operation supervisor give up (restart intensity
    /// exceeded) during the run, the mission is aborted with a reason naming the operation
    /// that kept failing.
    async fn dispatch(&self, mission: Mission) -> Result<Outcome, NodeError> {
        let n = self.runs.fetch_add(1, Ordering::Relaxed);
        let args = DispatcherArgs::new(mission, self.starter.clock.clone(), self.bus.clone());
        let spec = dispatcher_child(format!("dispatcher-{n}"), args);
        // subscribe before the run starts, so no give-up goes unseen
        let mut give_ups = Vec::new();
        for sup in self.config.operation_supervisors() {
            match self.child_supervisor(&sup.name).await {
                Ok(s) => give_ups.push((sup.name, s.subscribe().await?)),
                Err(e) => tracing::warn!("running without supervisor `{}`: {e}", sup.name),
            }
        }
        let dispatcher: ActorRef<DispatcherMsg> = self.starter.root.start_child(spec).await?.into();
        let guards: Vec<_> = give_ups
            .into_iter()
            .map(|(name, rx)| tokio::spawn(abort_on_give_up(name, rx, dispatcher.clone())))
            .collect();
        let outcome = dispatcher::request_run(&dispatcher).await;
        for guard in guards {
            guard.abort();
        }
        Ok(outcome?)
    }
}

/// A run's dispatcher with `args` as a temporary child `id` of a node's root: not restarted
/// (a run is not run twice), given a second to stop.
pub(super) fn dispatcher_child(id: String, args: DispatcherArgs) -> ChildSpec {
    ChildSpec::worker(id, move |sup| {
        let args = args.clone();
        async move {
            Ok(dispatcher::spawn_dispatcher(args, Some(sup))
                .await?
                .get_cell())
        }
    })
    .with_restart(Restart::Temporary)
    .with_shutdown(Shutdown::Timeout(Duration::from_secs(1)))
}

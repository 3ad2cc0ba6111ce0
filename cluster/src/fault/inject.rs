//! The road every fault takes: an [`Injector`] resolves a target, does the fault, and tells
//! the node's bus what became of it.

use super::processes::NodeProcesses;
use super::resolve::{resolve, Hit, RunBindings};
use super::target::Target;
use super::{FaultError, FaultSpec};
use marie_actors::dispatcher::{DispatcherMsg, DISPATCHER_ID};
use marie_actors::eo::EoClient;
use marie_dm::DmMsg;
use marie_vocabulary::events::{EventBus, EventKind, Tap};
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use marie_vocabulary::run::{Aim, FaultKind};
use ractor::ActorRef;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::sync::watch;

/// What was done, to whom.
#[derive(Clone, Debug)]
pub struct Injected {
    /// The fault.
    pub kind: FaultKind,
    /// The target, as asked.
    pub target: Target,
    /// What got it.
    pub hit: Hit,
    /// For a fault that lasts: for how long (it is undone after that).
    pub lasting: Option<Duration>,
}

impl Injected {
    /// What got it, as events and reports name it: an instance's address, a node's
    /// process as `pid N`, or a cut as its two groups `A,B|C,D`.
    pub fn victim(&self) -> String {
        match &self.hit {
            Hit::Instance(inst) => inst.actor.get_id().to_string(),
            Hit::Process { pid, .. } => format!("pid {pid}"),
            Hit::Cut { a, b } => format!("{}|{}", a.join(","), b.join(",")),
        }
    }
}

/// Injects faults for one process, and tells its node's bus: the one road of `--fault`,
/// `--chaos`, `marie kill` and the monitor's page.
///
/// It resolves a [`Target`] against the registry, the bindings of the runs on its bus (see
/// [`aiming_at_bindings`](Self::aiming_at_bindings): a plain name then means the instance the
/// mission bound, through its rebinds) and the node processes it may stop; does the fault
/// ([`inject_into`] for an operation, `SIGKILL` for a node's process); and publishes
/// `fault_injected` — or `fault_not_injected` and why — so every fault, whatever its
/// source, is in the run's events and report. Cheap to clone; clones share the bindings
/// they aim at.
///
/// ```
/// use marie_vocabulary::clock::RealClock;
/// use marie_vocabulary::events::EventBus;
/// use marie_vocabulary::run::FaultKind;
/// use marie_cluster::fault::{Injector, Target};
/// # #[tokio::main(flavor = "current_thread")] async fn main() {
/// let bus = EventBus::new("doc", RealClock::shared());
/// let injector = Injector::new(&bus);
/// // only a process that started nodes may stop one
/// assert!(injector.offers().contains(&FaultKind::Kill));
/// assert!(!injector.offers().contains(&FaultKind::StopNode));
/// let err = injector.inject(FaultKind::Kill, &Target::Bound("nobody".into())).await.unwrap_err();
/// assert!(err.to_string().contains("no operation `nobody` is running"), "{err}");
/// # }
/// ```
#[derive(Clone)]
pub struct Injector {
    bus: EventBus,
    processes: NodeProcesses,
    run: Option<Arc<Bindings>>,
}

/// The bindings of the runs on the bus, kept by a tap: what a plain name aims at.
struct Bindings {
    bindings: Arc<Mutex<RunBindings>>,
    bound: watch::Receiver<bool>,
    _tap: Tap,
}

impl std::fmt::Debug for Injector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Injector")
            .field("bus", &self.bus)
            .field("processes", &self.processes)
            .field("aims_at_bindings", &self.run.is_some())
            .finish()
    }
}

impl Injector {
    /// An injector that tells `bus`, stops no node process and aims at no run's bindings.
    pub fn new(bus: &EventBus) -> Injector {
        Injector {
            bus: bus.clone(),
            processes: NodeProcesses::default(),
            run: None,
        }
    }

    /// May stop these node processes (`marie up`'s children).
    pub fn with_processes(mut self, processes: NodeProcesses) -> Injector {
        self.processes = processes;
        self
    }

    /// Keep the bindings of the runs on the bus from now on: a plain name (`NAME`, `ID`) then means the
    /// instance the latest run bound for that operation (after a rebind, its stand-in).
    pub fn aiming_at_bindings(mut self) -> Injector {
        let bindings = Arc::new(Mutex::new(RunBindings::default()));
        let (tell, bound) = watch::channel(false);
        let fold = bindings.clone();
        let tap = self.bus.tap(move |event| {
            let mut b = lock(&fold);
            b.observe(&event.kind);
            tell.send_if_modified(|was| std::mem::replace(was, b.bound()) != b.bound());
        });
        self.run = Some(Arc::new(Bindings {
            bindings,
            bound,
            _tap: tap,
        }));
        self
    }

    /// The kinds this injector can do: every operation kind, the node kinds when it may
    /// stop a node's process, and a partition when those nodes run in a network it can
    /// cut.
    pub fn offers(&self) -> Vec<FaultKind> {
        FaultKind::ALL
            .into_iter()
            .filter(|k| match k.aim() {
                Aim::Operation => true,
                Aim::Node => !self.processes.is_empty(),
                Aim::Cut => self.processes.can_cut(),
            })
            .collect()
    }

    /// The node processes it may stop.
    pub fn processes(&self) -> &NodeProcesses {
        &self.processes
    }

    /// The bus it tells.
    pub fn bus(&self) -> &EventBus {
        &self.bus
    }

    /// What the latest run has bound so far (nothing, when it aims at no run's bindings).
    pub fn bindings(&self) -> RunBindings {
        match &self.run {
            Some(run) => lock(&run.bindings).clone(),
            None => RunBindings::none(),
        }
    }

    /// Wait until the latest run has bound its operations (at once when it aims at no bindings).
    pub(crate) async fn bound(&self) {
        if let Some(run) = &self.run {
            let mut bound = run.bound.clone();
            let _ = bound.wait_for(|b| *b).await;
        }
    }

    /// What `target` names now.
    pub async fn find(&self, target: &Target) -> Result<Hit, FaultError> {
        Ok(resolve(target, &self.bindings(), &self.processes).await?)
    }

    /// Check before a run that `spec` names something to hit: a running operation (and,
    /// when several instances run, one the mission binds — `bound_by_mission` says which
    /// names it binds; the fault then hits the bound one), a version, an actor id or an
    /// instance on a node that runs, or a node process this injector may stop.
    pub async fn check(
        &self,
        spec: &FaultSpec,
        bound_by_mission: impl Fn(&str) -> bool,
    ) -> Result<(), FaultError> {
        if let Target::Bound(op) = &spec.target {
            let instances = registry::lookup(ModuleKind::Operation, op);
            if instances.first().is_some_and(|i| bound_by_mission(&i.name)) {
                return Ok(());
            }
            // the run's own dispatcher, which starts with the run
            let dispatcher = op == "dispatcher" || *op == DISPATCHER_ID.to_string();
            if dispatcher && registry::lookup(ModuleKind::Operation, op).is_empty() {
                if !spec.kind.hits_datamanager() {
                    return Err(FaultError::Mismatch {
                        kind: spec.kind,
                        wants: "an operation",
                        target: "dispatcher (the run's dispatcher)".into(),
                    });
                }
                return Ok(());
            }
        }
        resolve(&spec.target, &RunBindings::none(), &self.processes).await?;
        Ok(())
    }

    /// Inject `kind` into what `target` names now, and tell the bus. A fault that
    /// [lasts](FaultKind::lasts) lasts [`FaultKind::DEFAULT_LASTING`].
    pub async fn inject(&self, kind: FaultKind, target: &Target) -> Result<Injected, FaultError> {
        self.strike(kind, target, None, None).await
    }

    /// Inject a planned fault that is due now (`due`: its time in the run), and tell the
    /// bus with the time it was due.
    pub(crate) async fn inject_due(&self, spec: &FaultSpec) -> Result<Injected, FaultError> {
        self.strike(spec.kind, &spec.target, Some(spec.at), spec.lasting)
            .await
    }

    /// Inject `kind` into what `target` names now, for `lasting` of mission time if it
    /// [lasts](FaultKind::lasts) (`None`: the default), and tell the bus — what the seeded
    /// node chaos does.
    pub(crate) async fn inject_for(
        &self,
        kind: FaultKind,
        target: &Target,
        lasting: Option<Duration>,
    ) -> Result<Injected, FaultError> {
        self.strike(kind, target, None, lasting).await
    }

    /// Tell the bus that a planned fault was not injected, and why.
    pub(crate) fn not_injected(&self, spec: &FaultSpec, why: &str) {
        tracing::warn!(fault = %spec.kind, target = %spec.target, "fault not injected: {why}");
        self.bus.publish(EventKind::FaultNotInjected {
            fault: spec.kind,
            operation: spec.target.to_string(),
            why: why.to_string(),
            due_ms: Some(spec.at.as_millis() as u64),
        });
    }

    async fn strike(
        &self,
        kind: FaultKind,
        target: &Target,
        due: Option<Duration>,
        lasting: Option<Duration>,
    ) -> Result<Injected, FaultError> {
        let due_ms = due.map(|d| d.as_millis() as u64);
        let done = self.resolve_and_do(kind, target, lasting).await;
        match &done {
            Ok(injected) => {
                tracing::warn!(fault = %kind, %target, victim = %injected.victim(), "fault injected");
                self.bus.publish(EventKind::FaultInjected {
                    fault: kind,
                    operation: target.to_string(),
                    actor: injected.victim(),
                    node: injected.hit.node().map(str::to_string),
                    due_ms,
                    lasting_ms: injected.lasting.map(|d| d.as_millis() as u64),
                });
                if let Some(lasting) = injected.lasting {
                    self.undo_after(injected.clone(), lasting);
                }
            }
            Err(e) => {
                tracing::warn!(fault = %kind, %target, error = %e, "fault not injected");
                self.bus.publish(EventKind::FaultNotInjected {
                    fault: kind,
                    operation: target.to_string(),
                    why: e.to_string(),
                    due_ms,
                });
            }
        }
        done
    }

    async fn resolve_and_do(
        &self,
        kind: FaultKind,
        target: &Target,
        lasting: Option<Duration>,
    ) -> Result<Injected, FaultError> {
        if kind.aim() != target.aim() {
            return Err(FaultError::Mismatch {
                kind,
                wants: match kind.aim() {
                    Aim::Operation => "an operation",
                    Aim::Node => "a node",
                    Aim::Cut => "two groups of nodes",
                },
                target: target.to_string(),
            });
        }
        // a kind that lasts lasts as asked, or the default; any other does not
        let lasting = kind
            .lasts()
            .then(|| lasting.unwrap_or(FaultKind::DEFAULT_LASTING));
        let hit = self.find(target).await?;
        match &hit {
            Hit::Instance(inst) => inject_into(kind, inst)?,
            Hit::Process { node, pid } => {
                let done = match kind {
                    FaultKind::FreezeNode => self.processes.freeze(node),
                    _ => self.processes.kill(node),
                };
                done.map_err(|e| FaultError::Signal {
                    kind,
                    node: node.clone(),
                    pid: *pid,
                    why: e.to_string(),
                })?;
            }
            Hit::Cut { a, b } => {
                self.processes.cut(a, b).map_err(|e| FaultError::Network {
                    cut: target.to_string(),
                    why: e.to_string(),
                })?;
            }
        }
        Ok(Injected {
            kind,
            target: target.clone(),
            hit,
            lasting,
        })
    }

    /// Undo a lasting fault once `lasting` of mission time has passed — a frozen node let
    /// go on, a cut healed — and tell the bus (`fault_healed`). A task of its own: the
    /// run may end meanwhile, and the fault is undone all the same (`marie up` lets every
    /// frozen node go on before stopping them, whatever is pending).
    fn undo_after(&self, injected: Injected, lasting: Duration) {
        let (processes, bus) = (self.processes.clone(), self.bus.clone());
        tokio::spawn(async move {
            bus.clock().sleep(lasting).await;
            let undone = match &injected.hit {
                Hit::Process { node, .. } => processes.thaw(node),
                Hit::Cut { a, b } => processes.heal(a, b),
                Hit::Instance(_) => Ok(()),
            };
            let target = injected.target.to_string();
            match undone {
                Ok(()) => {
                    tracing::warn!(fault = %injected.kind, %target, "fault healed");
                    bus.publish(EventKind::FaultHealed {
                        fault: injected.kind,
                        operation: target,
                    });
                }
                Err(e) => {
                    tracing::error!(fault = %injected.kind, %target, "cannot undo the fault: {e}")
                }
            }
        });
    }
}

/// Do `kind` to the module instance `inst` (an operation or a datamanager), telling nobody
/// — the behaviour of the operation kinds, under [`Injector::inject`] (which resolves, and
/// tells the bus). A kill of a local instance kills its actor; a remote instance, and every
/// other kind, is told through its actor (killing a remote actor's local stand-in would
/// kill the stand-in alone). A datamanager suffers only the kinds that
/// [hit one](FaultKind::hits_datamanager).
pub fn inject_into(kind: FaultKind, inst: &Instance) -> Result<(), FaultError> {
    if kind.aim() != Aim::Operation {
        return Err(FaultError::Mismatch {
            kind,
            wants: "a node",
            target: inst.name.clone(),
        });
    }
    let datamanager = inst.kind == ModuleKind::Datamanager;
    let dispatcher = inst.kind == ModuleKind::Dispatcher;
    if (datamanager || dispatcher) && !kind.hits_datamanager() {
        return Err(FaultError::Mismatch {
            kind,
            wants: "an operation",
            target: format!(
                "{} (a {})",
                inst.name,
                if dispatcher {
                    "dispatcher"
                } else {
                    "datamanager"
                }
            ),
        });
    }
    let unreachable = || FaultError::Unreachable(inst.name.clone());
    match kind {
        FaultKind::Kill if inst.actor.get_id().is_local() => inst.actor.kill(),
        _ if dispatcher => ActorRef::<DispatcherMsg>::from(inst.actor.clone())
            .cast(DispatcherMsg::Inject { fault: kind })
            .map_err(|_| unreachable())?,
        _ if datamanager => ActorRef::<DmMsg>::from(inst.actor.clone())
            .cast(DmMsg::Inject { fault: kind })
            .map_err(|_| unreachable())?,
        _ => EoClient::from_cell(inst.actor.clone())
            .inject(kind)
            .map_err(|_| unreachable())?,
    }
    Ok(())
}

fn lock(b: &Mutex<RunBindings>) -> MutexGuard<'_, RunBindings> {
    b.lock().unwrap_or_else(|e| e.into_inner())
}

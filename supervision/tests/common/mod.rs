//! Test actors and helpers shared by the supervision tests.
#![allow(dead_code)]

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use marie_supervision::{
    ChildSpec, ChildStart, ChildTemplate, ExitReason, Shutdown, SupervisorEvent, SupervisorRef,
    SupervisorSpec,
};
use ractor::{Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use tokio::sync::{broadcast, mpsc, oneshot};

/// How long a test waits for something that must happen. Generous: the tests run on a
/// loaded 2-core machine, and they never wait this long when things work.
pub(crate) const PATIENCE: Duration = Duration::from_secs(10);

/// A shared record of what the workers did, in order ("start c1", "stop c1", "stopped c1").
#[derive(Clone, Default)]
pub(crate) struct Log(Arc<Mutex<Vec<String>>>);

impl Log {
    pub(crate) fn push(&self, s: String) {
        self.0.lock().unwrap().push(s);
    }
    pub(crate) fn entries(&self) -> Vec<String> {
        self.0.lock().unwrap().clone()
    }
    /// The entries that start with `prefix` (e.g. "stop "), in order.
    pub(crate) fn with_prefix(&self, prefix: &str) -> Vec<String> {
        self.entries()
            .into_iter()
            .filter(|e| e.starts_with(prefix))
            .collect()
    }
    pub(crate) fn clear(&self) {
        self.0.lock().unwrap().clear();
    }
}

/// What a test can make a worker do.
pub(crate) enum WorkerMsg {
    /// Return an error from the handler (ActorFailed).
    Fail,
    /// Panic in the handler (ActorFailed).
    Panic,
    /// Stop itself with this reason.
    Stop(Option<String>),
    /// Answer, to prove it is alive.
    Ping(RpcReplyPort<()>),
}
impl ractor::Message for WorkerMsg {}

/// A worker that logs its start and stop, and may take its time to stop.
pub(crate) struct Worker;

#[derive(Clone)]
pub(crate) struct WorkerArgs {
    pub name: String,
    pub log: Log,
    /// `post_stop` sleeps this long after logging "stop <name>" (to ignore a stop request).
    pub stop_delay: Option<Duration>,
    /// Unlink from the supervisor in `post_start`.
    pub unlink: bool,
}

impl Actor for Worker {
    type Msg = WorkerMsg;
    type State = WorkerArgs;
    type Arguments = WorkerArgs;

    async fn pre_start(
        &self,
        _: ActorRef<WorkerMsg>,
        args: WorkerArgs,
    ) -> Result<WorkerArgs, ActorProcessingErr> {
        args.log.push(format!("start {}", args.name));
        Ok(args)
    }

    async fn post_start(
        &self,
        myself: ActorRef<WorkerMsg>,
        state: &mut WorkerArgs,
    ) -> Result<(), ActorProcessingErr> {
        if state.unlink {
            if let Some(sup) = myself.try_get_supervisor() {
                myself.get_cell().unlink(sup);
            }
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<WorkerMsg>,
        msg: WorkerMsg,
        _: &mut WorkerArgs,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            WorkerMsg::Fail => return Err("induced failure".into()),
            WorkerMsg::Panic => panic!("induced panic"),
            WorkerMsg::Stop(reason) => myself.stop(reason),
            WorkerMsg::Ping(reply) => {
                let _ = reply.send(());
            }
        }
        Ok(())
    }

    async fn post_stop(
        &self,
        _: ActorRef<WorkerMsg>,
        state: &mut WorkerArgs,
    ) -> Result<(), ActorProcessingErr> {
        state.log.push(format!("stop {}", state.name));
        if let Some(d) = state.stop_delay {
            tokio::time::sleep(d).await;
        }
        state.log.push(format!("stopped {}", state.name));
        Ok(())
    }
}

/// Options of a test worker's spec.
#[derive(Clone, Default)]
pub(crate) struct WorkerOpts {
    pub stop_delay: Option<Duration>,
    pub unlink: bool,
    /// While set, starts fail (with a spawn error, as a failing `pre_start` would).
    pub fail_start: Option<Arc<AtomicBool>>,
    /// While set, starts never finish.
    pub hang_start: Option<Arc<AtomicBool>>,
    /// While positive, starts fail and count it down.
    pub fail_count: Option<Arc<AtomicUsize>>,
    /// While set, starts answer `ChildStart::Ignore`.
    pub ignore: Option<Arc<AtomicBool>>,
}

/// A permanent worker with a 5 s shutdown.
pub(crate) fn worker(id: &str, log: &Log) -> ChildSpec {
    worker_with(id, log, WorkerOpts::default())
}

impl WorkerOpts {
    /// Starts fail while `flag` is set.
    pub(crate) fn failing(flag: &Arc<AtomicBool>) -> Self {
        WorkerOpts {
            fail_start: Some(flag.clone()),
            ..Default::default()
        }
    }

    /// Starts never finish while `flag` is set.
    pub(crate) fn hanging(flag: &Arc<AtomicBool>) -> Self {
        WorkerOpts {
            hang_start: Some(flag.clone()),
            ..Default::default()
        }
    }

    /// Starts answer ignore while `flag` is set.
    pub(crate) fn ignoring(flag: &Arc<AtomicBool>) -> Self {
        WorkerOpts {
            ignore: Some(flag.clone()),
            ..Default::default()
        }
    }
}

pub(crate) fn worker_with(id: &str, log: &Log, opts: WorkerOpts) -> ChildSpec {
    let args = WorkerArgs {
        name: id.to_string(),
        log: log.clone(),
        stop_delay: opts.stop_delay,
        unlink: opts.unlink,
    };
    ChildSpec::worker(id, move |sup| {
        let args = args.clone();
        let fail = opts
            .fail_start
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst))
            || opts.fail_count.as_ref().is_some_and(|n| {
                n.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
                    .is_ok()
            });
        let hang = opts
            .hang_start
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst));
        let ignore = opts
            .ignore
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst));
        async move {
            if hang {
                std::future::pending::<()>().await;
            }
            if fail {
                args.log.push(format!("failed start {}", args.name));
                return Err(SpawnErr::StartupFailed("induced start failure".into()));
            }
            if ignore {
                args.log.push(format!("ignored start {}", args.name));
                return Ok(ChildStart::Ignore);
            }
            let (actor, _) = Actor::spawn_linked(None, Worker, args, sup).await?;
            Ok(ChildStart::Started(actor.get_cell()))
        }
    })
    .with_shutdown(Shutdown::Timeout(Duration::from_secs(5)))
}

pub(crate) fn flag(initially: bool) -> Arc<AtomicBool> {
    Arc::new(AtomicBool::new(initially))
}

pub(crate) fn counter(n: usize) -> Arc<AtomicUsize> {
    Arc::new(AtomicUsize::new(n))
}

/// The running incarnation of child `id`.
pub(crate) async fn running(sup: &SupervisorRef, id: &str) -> ActorCell {
    let children = sup.which_children().await.expect("supervisor answers");
    let child = children
        .iter()
        .find(|c| c.id == id)
        .unwrap_or_else(|| panic!("no child {id}"));
    child
        .state
        .actor()
        .unwrap_or_else(|| panic!("child {id} is not running: {:?}", child.state))
        .clone()
}

/// Wait until `cell` has stopped. A crashed actor is reported to its supervisor a moment
/// before ractor marks it stopped, so its status must be awaited, not asserted.
pub(crate) async fn stopped(cell: &ActorCell) {
    cell.wait(Some(PATIENCE))
        .await
        .unwrap_or_else(|_| panic!("{cell:?} did not stop"));
}

pub(crate) fn send(cell: &ActorCell, msg: WorkerMsg) {
    ActorRef::<WorkerMsg>::from(cell.clone())
        .cast(msg)
        .expect("worker alive");
}

/// Make `cell` fail (an `Err` from its handler).
pub(crate) fn crash(cell: &ActorCell) {
    send(cell, WorkerMsg::Fail);
}

/// The next event that satisfies `pred`, skipping others; panics after [`PATIENCE`].
pub(crate) async fn wait_for(
    rx: &mut broadcast::Receiver<SupervisorEvent>,
    what: &str,
    pred: impl Fn(&SupervisorEvent) -> bool,
) -> SupervisorEvent {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        match tokio::time::timeout_at(deadline, rx.recv()).await {
            Err(_) => panic!("timed out waiting for {what}"),
            Ok(Ok(e)) if pred(&e) => return e,
            Ok(Ok(_)) | Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
            Ok(Err(broadcast::error::RecvError::Closed)) => {
                panic!("event channel closed while waiting for {what}")
            }
        }
    }
}

/// Wait for the restart of child `id`; returns the new incarnation.
pub(crate) async fn restarted(
    rx: &mut broadcast::Receiver<SupervisorEvent>,
    id: &str,
) -> ActorCell {
    match wait_for(
        rx,
        &format!("restart of {id}"),
        |e| matches!(e, SupervisorEvent::ChildRestarted { id: i, .. } if i == id),
    )
    .await
    {
        SupervisorEvent::ChildRestarted { new, .. } => new,
        _ => unreachable!(),
    }
}

/// Collect events until (and including) the first that satisfies `last`.
pub(crate) async fn events_until(
    rx: &mut broadcast::Receiver<SupervisorEvent>,
    what: &str,
    last: impl Fn(&SupervisorEvent) -> bool,
) -> Vec<SupervisorEvent> {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    let mut seen = Vec::new();
    loop {
        match tokio::time::timeout_at(deadline, rx.recv()).await {
            Err(_) => panic!("timed out waiting for {what}; saw {seen:?}"),
            Ok(Ok(e)) => {
                let done = last(&e);
                seen.push(e);
                if done {
                    return seen;
                }
            }
            Ok(Err(broadcast::error::RecvError::Lagged(n))) => {
                panic!("lagged by {n} events waiting for {what}")
            }
            Ok(Err(broadcast::error::RecvError::Closed)) => {
                panic!("event channel closed waiting for {what}; saw {seen:?}")
            }
        }
    }
}

/// A parent that reports its children's exits: stands in for "the parent sees the supervisor
/// fail".
pub(crate) struct Probe;

pub(crate) type Exits = mpsc::UnboundedReceiver<(ActorId, ExitReason)>;

impl Actor for Probe {
    type Msg = ();
    type State = mpsc::UnboundedSender<(ActorId, ExitReason)>;
    type Arguments = mpsc::UnboundedSender<(ActorId, ExitReason)>;

    async fn pre_start(
        &self,
        _: ActorRef<()>,
        tx: Self::Arguments,
    ) -> Result<Self::State, ActorProcessingErr> {
        Ok(tx)
    }

    async fn handle_supervisor_evt(
        &self,
        _: ActorRef<()>,
        event: ractor::SupervisionEvent,
        tx: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        if let Some((cell, reason)) = ExitReason::from_supervision_event(&event) {
            let _ = tx.send((cell.get_id(), reason));
        }
        Ok(())
    }
}

/// A probe parent and the receiver of its children's exits.
pub(crate) async fn probe() -> (ActorRef<()>, Exits) {
    let (tx, rx) = mpsc::unbounded_channel();
    let (probe, _) = Actor::spawn(None, Probe, tx).await.expect("probe spawns");
    (probe, rx)
}

/// The exit reason of `who` as its probe parent saw it.
pub(crate) async fn exit_of(exits: &mut Exits, who: ActorId) -> ExitReason {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        match tokio::time::timeout_at(deadline, exits.recv()).await {
            Err(_) => panic!("timed out waiting for the exit of {who}"),
            Ok(None) => panic!("probe gone"),
            Ok(Some((id, reason))) if id == who => return reason,
            Ok(Some(_)) => {}
        }
    }
}

/// Start a supervisor linked to a fresh probe.
pub(crate) async fn start_probed(
    spec: SupervisorSpec,
    children: Vec<ChildSpec>,
) -> (SupervisorRef, ActorRef<()>, Exits) {
    let (probe, exits) = probe().await;
    let (sup, _) =
        marie_supervision::Supervisor::start_linked(None, spec, children, probe.get_cell())
            .await
            .expect("supervisor starts");
    (sup, probe, exits)
}

/// The argument of one instance of the test template ([`template`]).
#[derive(Clone, Default)]
pub(crate) struct Inst {
    /// The worker's name in the log.
    pub name: String,
    /// While set, starts fail.
    pub fail_start: Option<Arc<AtomicBool>>,
    /// Starts answer ignore.
    pub ignore: bool,
    /// `post_stop` sleeps this long.
    pub stop_delay: Option<Duration>,
    /// Held by the argument only: counts who keeps the argument alive.
    pub payload: Option<Arc<()>>,
}

impl Inst {
    pub(crate) fn named(name: &str) -> Self {
        Inst {
            name: name.to_string(),
            ..Default::default()
        }
    }
}

/// A simple-one-for-one template of permanent test workers (5 s shutdown) named "child",
/// each started from an [`Inst`].
pub(crate) fn template(log: &Log) -> ChildTemplate {
    let log = log.clone();
    ChildTemplate::worker("child", move |sup, inst: Inst| {
        let args = WorkerArgs {
            name: inst.name.clone(),
            log: log.clone(),
            stop_delay: inst.stop_delay,
            unlink: false,
        };
        let fail = inst
            .fail_start
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst));
        let ignore = inst.ignore;
        async move {
            if fail {
                args.log.push(format!("failed start {}", args.name));
                return Err(SpawnErr::StartupFailed("induced start failure".into()));
            }
            if ignore {
                return Ok(ChildStart::Ignore);
            }
            let (actor, _) = Actor::spawn_linked(None, Worker, args, sup).await?;
            Ok(ChildStart::Started(actor.get_cell()))
        }
    })
}

/// What the test tells a gated start to do.
pub(crate) enum Verdict {
    Start,
    Fail,
}

/// Starts waiting for a verdict: the child's id and where to send the verdict.
pub(crate) type Gates = mpsc::UnboundedReceiver<(String, oneshot::Sender<Verdict>)>;

/// A permanent worker whose every start asks the test (through `gates`) whether to start or
/// fail: the test steps through a restart one start at a time (OTP's `supervisor_3`).
pub(crate) fn gated(
    id: &str,
    log: &Log,
    gates: &mpsc::UnboundedSender<(String, oneshot::Sender<Verdict>)>,
) -> ChildSpec {
    let args = WorkerArgs {
        name: id.to_string(),
        log: log.clone(),
        stop_delay: None,
        unlink: false,
    };
    let gates = gates.clone();
    ChildSpec::worker(id, move |sup| {
        let args = args.clone();
        let gates = gates.clone();
        async move {
            let (tx, rx) = oneshot::channel();
            if gates.send((args.name.clone(), tx)).is_err() {
                return Err(SpawnErr::StartupFailed("the test is gone".into()));
            }
            match rx.await {
                Ok(Verdict::Start) => {
                    let (actor, _) = Actor::spawn_linked(None, Worker, args, sup).await?;
                    Ok(actor.get_cell())
                }
                _ => {
                    args.log.push(format!("failed start {}", args.name));
                    Err(SpawnErr::StartupFailed("the test failed this start".into()))
                }
            }
        }
    })
}

/// The next gated start; it must be `id`'s. Answer it with `verdict`.
pub(crate) async fn answer(gates: &mut Gates, id: &str, verdict: Verdict) {
    let (who, reply) = tokio::time::timeout(PATIENCE, gates.recv())
        .await
        .unwrap_or_else(|_| panic!("timed out waiting for the start of {id}"))
        .expect("gates open");
    assert_eq!(who, id, "expected the start of {id}, got {who}'s");
    let _ = reply.send(verdict);
}

//! A dispatcher whose run a newer term took over commands nothing of it any more — not
//! even from messages that were already waiting in its mailbox when its checkpoint was
//! refused.
//!
//! What the soak met (issue 43): spare's dispatcher (term 2) froze; features' desk took the
//! run over at term 4 and held the cart's operations at its epochs. Woken, the old
//! dispatcher found its instances gone (its sessions redialled: new actor ids), adopted
//! them again — an adoption raises the epoch above the instance's, which was term 4's —
//! and, its checkpoint refused but its `Fenced` still queued behind other messages, ended
//! an action on one of them: its suspension, at the raised epoch, was obeyed, and term 4's
//! run failed: "operation `ultrasonic` was suspended by another party".
//!
//! Here in one process, each step ordered by the test: the dispatcher (term 1) records the
//! run in a datamanager behind a gate the test opens and closes; a successor's claim (term
//! 2) is stored; the gate closes; the successor starts its own instance of the held
//! operation at its epoch; the held instance is killed (the dispatcher loses it, adopts the
//! successor's instance, and waits for that checkpoint behind the gate); another operation
//! of the action reports a suspension it did not ask for (a failure of the action: every
//! operation is to be suspended); then the gate opens, the checkpoint is refused. The
//! successor's activation must run on.

mod common;

use common::ops::{general, Worker};
use marie_actors::dispatcher::checkpoint::CheckpointArgs;
use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{request_run, spawn_dispatcher, DispatcherArgs, RegistryCatalog};
use marie_actors::eo::EoClient;
use marie_dm::{spawn_datamanager, DmClient, DmMsg, DmSpec};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use marie_vocabulary::property::{ParamMap, Value};
use ractor::{Actor, ActorProcessingErr, ActorRef};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);
const RUN: &str = "fenced-run";
/// Steps of 2 ms: the activations outlast the test.
const STEPS: i64 = 100_000;

/// A gate in front of a datamanager: open, it passes every message on; closed, it holds
/// them until [`Gate::open`].
#[derive(Clone)]
struct Gate {
    closed: Arc<AtomicBool>,
    held: Arc<Mutex<Vec<DmMsg>>>,
    dm: ActorRef<DmMsg>,
}

impl Gate {
    fn close(&self) {
        self.closed.store(true, Ordering::SeqCst);
    }

    /// Open it and pass on what it held, in order (only the dispatcher's writer sends
    /// through it, one checkpoint at a time).
    fn open(&self) {
        self.closed.store(false, Ordering::SeqCst);
        for msg in std::mem::take(&mut *self.held.lock().unwrap()) {
            self.dm.cast(msg).unwrap();
        }
    }
}

impl Actor for Gate {
    type Msg = DmMsg;
    type State = ();
    type Arguments = ();

    async fn pre_start(&self, _: ActorRef<DmMsg>, _: ()) -> Result<(), ActorProcessingErr> {
        Ok(())
    }

    async fn handle(
        &self,
        _: ActorRef<DmMsg>,
        msg: DmMsg,
        _: &mut (),
    ) -> Result<(), ActorProcessingErr> {
        match self.closed.load(Ordering::SeqCst) {
            true => self.held.lock().unwrap().push(msg),
            false => self.dm.cast(msg)?,
        }
        Ok(())
    }
}

async fn run_datamanager() -> ActorRef<DmMsg> {
    let args = DmSpec::new("fenced-run-dm", 4811)
        .args(RealClock::shared())
        .without_heir();
    spawn_datamanager(args).await.expect("the DM starts").0
}

/// Wait until `c` runs an activation.
async fn activated(c: &EoClient) {
    timeout(T, async {
        while !general(c).await.in_use {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await
    .expect("activated in time");
}

/// Wait for the first event `pick` accepts.
async fn event(events: &mut EventSubscription, pick: impl Fn(&EventKind) -> bool) {
    timeout(T, async {
        loop {
            let e = events.recv().await.expect("the bus stays open");
            if pick(&e.kind) {
                return;
            }
        }
    })
    .await
    .expect("event in time");
}

fn mission() -> String {
    format!(
        r#"
        [mission]
        name = "fenced"
        success = ["done"]
        rebind_deadline_s = 20.0
        [flags]
        done = 0
        [[action]]
        name = "work"
        [action.ops.fx-held]
        steps = {STEPS}
        [action.ops.fx-other]
        steps = {STEPS}
    "#
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dispatcher_fenced_off_never_suspends_what_its_successor_holds() {
    let held = Worker::new("fx-held", 4812, "1.0.0").start().await;
    let other = Worker::new("fx-other", 4813, "1.0.0").start().await;
    let dm = run_datamanager().await;
    let gate = Gate {
        closed: Arc::new(AtomicBool::new(false)),
        held: Arc::new(Mutex::new(Vec::new())),
        dm: dm.clone(),
    };
    let (through_gate, _) = Actor::spawn(None, gate.clone(), ()).await.unwrap();

    // the dispatcher of term 1, recording the run through the gate
    let parsed = ParsedMission::parse(&mission(), None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mission = parsed.validate(&catalog).expect("mission validates");
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let mut events = bus.subscribe();
    let checkpoint = CheckpointArgs {
        run: RUN.to_string(),
        term: 1,
        dm: DmClient::new(through_gate, "dispatcher"),
        watcher: None,
    };
    let dispatcher = spawn_dispatcher(
        DispatcherArgs {
            checkpoint: Some(checkpoint),
            ..DispatcherArgs::new(mission, clock, bus)
        },
        None,
    )
    .await
    .unwrap();
    let running = dispatcher.clone();
    tokio::spawn(async move { request_run(&running).await });
    activated(&held).await;
    activated(&other).await;

    // a successor claims the run at term 2 (the fence of the run's checkpoints), and holds
    // an instance of the held operation of its own, at an epoch above the dispatcher's
    DmClient::new(dm.clone(), "successor")
        .with_source(&format!("dispatcher/{RUN}"))
        .with_epoch(2)
        .store(
            "checkpoint",
            Some(RUN),
            None,
            &"claimed by term 2".to_string(),
        )
        .await
        .expect("the successor's claim is stored");
    gate.close();
    let successors = Worker::new("fx-held", 4812, "1.0.0").start().await;
    let epoch = general(&held).await.epoch + 1;
    let mut params = ParamMap::new();
    params.insert("steps".into(), Value::Int(STEPS));
    let mut report = successors.activate(params, epoch).unwrap();
    activated(&successors).await;

    // the held instance dies: the dispatcher loses it, finds the successor's, adopts it at
    // an epoch above the successor's, and waits for that checkpoint behind the gate
    held.actor().kill();
    event(
        &mut events,
        |k| matches!(k, EventKind::Lost { operation, .. } if operation == "fx-held"),
    )
    .await;
    // meanwhile the action's other operation reports a suspension the dispatcher did not
    // ask for: the action fails, and what still runs of it is to be suspended
    let epoch_other = general(&other).await.epoch;
    other.suspend(epoch_other).unwrap();
    timeout(T, async {
        while general(&other).await.in_use {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await
    .expect("the other operation suspended");
    // its report reaches the dispatcher's mailbox through a task of the dispatcher's: let
    // it get there before the refusal (were it later, this test could only pass wrongly,
    // never fail wrongly — the fenced dispatcher must command nothing either way)
    tokio::time::sleep(Duration::from_millis(300)).await;

    // the checkpoint is refused for term 2
    gate.open();
    event(&mut events, |k| {
        matches!(
            k,
            EventKind::DispatcherFenced {
                term: 1,
                newer: 2,
                ..
            }
        )
    })
    .await;
    timeout(T, async {
        while !matches!(
            dispatcher.get_status(),
            ractor::ActorStatus::Stopped | ractor::ActorStatus::Stopping
        ) {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await
    .expect("the fenced dispatcher stops");

    // what the successor holds runs on, at its epoch
    let now = general(&successors).await;
    assert!(now.in_use, "the successor's activation was ended: {now:?}");
    assert_eq!(
        now.epoch, epoch,
        "a command of an epoch above the successor's was obeyed"
    );
    assert!(
        report.try_recv().is_err(),
        "the successor's activation reported an end"
    );
}

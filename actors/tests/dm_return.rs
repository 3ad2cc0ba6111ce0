//! An operation whose datamanager is gone waits for the DM's next incarnation and steps on:
//! its host holds its steps (answering every command meanwhile) until a DM of that name is
//! published again, at most `eo::DATAMANAGER_RETURN`, and only then fails the activation.
//!
//! Each test uses a datamanager of its own name: the registry is one per process.

use marie_actors::eo::{
    spawn_operation, EoClient, EoReport, HostOptions, Identity, OpContext, OpError, Operation,
    Step, DATAMANAGER_RETURN,
};
use marie_dm::{spawn_datamanager, DmArgs, DmClient, DmConfig, DmMsg, Query};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::property::{
    param_map, Group, ParamDecl, ParamSchema, PropertyReply, PropertyRequest, Value,
};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::status::StatusFlags;
use ractor::ActorRef;
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

/// Stores its step number in its datamanager at every step (a call: it sees at once that
/// the DM is gone); finishes after `steps` steps. Its property `missed` counts the steps
/// that found the DM gone.
struct Recorder {
    dm: &'static str,
    taken: i64,
    missed: i64,
    /// A step at which the DM is found absent though it is published (once): the race of
    /// a call that failed before a new leader was published and a look after it.
    absent_at: Option<(i64, OpError)>,
}

impl Operation for Recorder {
    fn identity(&self) -> Identity {
        Identity::new(
            &format!("recorder-{}", self.dm),
            4300,
            "1.0.0",
            "logs its steps",
        )
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("steps", 10).range(1.0, 100_000.0)])
    }
    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "missed").then_some(Value::Int(self.missed))
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.taken = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let n = self.taken.to_string();
        if self
            .absent_at
            .as_ref()
            .is_some_and(|(at, _)| *at == self.taken)
        {
            self.missed += 1;
            if let Some((_, e)) = self.absent_at.take() {
                return Err(e);
            }
        }
        let stored = match ctx.dm(self.dm) {
            Ok(dm) => dm
                .store("step", Some(&n), None, &self.taken)
                .await
                .map_err(OpError::from),
            Err(e) => Err(e),
        };
        if let Err(e) = stored {
            self.missed += 1;
            return Err(e);
        }
        self.taken += 1;
        Ok(if self.taken >= ctx.params().i64("steps")? {
            Step::Finish(StatusFlags(0))
        } else {
            Step::Continue
        })
    }
}

async fn datamanager(name: &str) -> ActorRef<DmMsg> {
    spawn_datamanager(DmArgs {
        id: 4301,
        name: name.to_string(),
        clock: RealClock::shared(),
        config: DmConfig::default(),
        durability: Default::default(),
        journal_dir: None,
        replication: None,
        events: None,
        heir: None,
    })
    .await
    .expect("the DM starts")
    .0
}

async fn recorder(dm: &'static str) -> EoClient {
    recorder_absent_at(dm, None).await
}

async fn recorder_absent_at(dm: &'static str, absent_at: Option<(i64, OpError)>) -> EoClient {
    let (actor, _) = spawn_operation(
        Recorder {
            dm,
            taken: 0,
            missed: 0,
            absent_at,
        },
        HostOptions::default(),
    )
    .await
    .expect("the host starts");
    EoClient::new(actor)
}

/// Wait until the DM `name` holds the step `n`.
async fn until_step(name: &str, n: i64) {
    let client = DmClient::lookup(name, "test").unwrap();
    let query = Query::class("step").sub1(n.to_string());
    let found = client.select_wait(query, T).await.unwrap();
    assert_eq!(found.len(), 1, "the operation steps");
}

/// Kill the DM's actor and wait until it left the registry.
async fn kill(dm: ActorRef<DmMsg>) {
    let mut watch = registry::watch(Some(ModuleKind::Datamanager))
        .await
        .unwrap();
    let id = dm.get_id();
    dm.kill();
    timeout(T, async {
        while let Some(event) = watch.next().await {
            if matches!(&event, RegistryEvent::Left(i) if i.actor.get_id() == id) {
                return;
            }
        }
    })
    .await
    .expect("the DM leaves the registry");
}

/// How many of the operation's steps found its DM gone.
/// Activate `op` for `steps` steps at `epoch`; its report at the end.
async fn run_to_end(op: &EoClient, steps: i64, epoch: u64) -> EoReport {
    let report = op
        .activate(param_map([("steps", Value::Int(steps))]), epoch)
        .unwrap();
    timeout(T, report).await.unwrap().unwrap()
}

async fn missed(op: &EoClient) -> i64 {
    match op.property(PropertyRequest::Get("missed".into())).await {
        Ok(PropertyReply::Value(Value::Int(n))) => n,
        other => panic!("{other:?}"),
    }
}

#[tokio::test]
async fn an_operation_steps_on_into_its_datamanagers_next_incarnation() {
    let first = datamanager("logbook-back").await;
    let op = recorder("logbook-back").await;
    let report = op
        .activate(param_map([("steps", Value::Int(400))]), 1)
        .unwrap();
    until_step("logbook-back", 5).await;
    kill(first).await;
    // the operation meets the gone DM: it holds its steps, and still answers
    timeout(T, async {
        while missed(&op).await == 0 {
            tokio::task::yield_now().await;
        }
    })
    .await
    .expect("a step finds the DM gone");
    let answer = timeout(T, op.property(PropertyRequest::Group(Group::General)))
        .await
        .unwrap()
        .unwrap();
    match answer {
        PropertyReply::General(g) => assert!(g.in_use, "still active"),
        other => panic!("{other:?}"),
    }
    let second = datamanager("logbook-back").await;
    let report = timeout(T, report).await.unwrap().unwrap();
    assert!(matches!(report, EoReport::Finished { .. }), "{report:?}");
    // the steps after the gap are in the new incarnation, the last one among them
    let stored = DmClient::lookup("logbook-back", "test")
        .unwrap()
        .select_typed::<i64>(Query::class("step"))
        .await
        .unwrap();
    assert_eq!(stored.last().map(|(_, v)| *v), Some(399));
    // it waited for the new incarnation: one missed step, not one per period
    assert_eq!(missed(&op).await, 1);
    assert!(
        stored.len() < 400,
        "the first incarnation's records went with it"
    );
    second.stop(None);
    op.actor().stop(None);
}

#[tokio::test]
async fn a_datamanager_absent_at_the_call_but_published_by_the_look_is_waited_for_not_failed() {
    // the thesis layout's operations node killed: the world DM's call failed "no datamanager
    // is registered", a new leader was published before the host looked, and the host
    // failed the activation (the module was not gone by then) — the mission with it
    let dm = datamanager("logbook-race").await;
    let absent = marie_dm::DmError::NotRegistered("logbook-race".into());
    let op = recorder_absent_at(
        "logbook-race",
        Some((3, OpError::of_dm("logbook-race", &absent))),
    )
    .await;
    let report = run_to_end(&op, 20, 1).await;
    assert!(matches!(report, EoReport::Finished { .. }), "{report:?}");
    assert_eq!(missed(&op).await, 1);
    dm.stop(None);
    op.actor().stop(None);
}

#[tokio::test]
async fn an_operation_fails_when_its_datamanager_does_not_come_back() {
    let dm = datamanager("logbook-gone").await;
    let op = recorder("logbook-gone").await;
    let report = op
        .activate(param_map([("steps", Value::Int(100_000))]), 1)
        .unwrap();
    until_step("logbook-gone", 2).await;
    kill(dm).await;
    let report = timeout(T + DATAMANAGER_RETURN, report)
        .await
        .unwrap()
        .unwrap();
    match report {
        EoReport::Failed { reason, .. } => {
            assert!(reason.contains("logbook-gone"), "{reason}");
            assert!(reason.contains("not back within"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    op.actor().stop(None);
}

/// A hardware module that does nothing but be published, as a cart is.
struct StandIn;

impl ractor::Actor for StandIn {
    type Msg = ();
    type State = ();
    type Arguments = &'static str;
    async fn pre_start(
        &self,
        myself: ActorRef<()>,
        name: &'static str,
    ) -> Result<(), ractor::ActorProcessingErr> {
        registry::publish(ModuleKind::Hardware, 4302, name, myself.get_cell())?;
        Ok(())
    }
}

#[tokio::test]
async fn hardware_lost_mid_call_but_back_by_the_look_is_waited_for_and_one_that_runs_unanswering_fails(
) {
    // the cart's node cut off for 4 s: the session closed, the cart's call ended at its own
    // deadline (5 s) — by then the node was back and the cart published again, so the look
    // found nothing gone and the activation (the mission with it) failed
    let (stand_in, _) = ractor::Actor::spawn(None, StandIn, "rig-race")
        .await
        .unwrap();
    let dm = datamanager("logbook-rig").await;
    let lost = OpError::absent(
        ModuleKind::Hardware,
        "rig-race",
        "the rig was lost before it answered",
    );
    let op = recorder_absent_at("logbook-rig", Some((3, lost))).await;
    let report = run_to_end(&op, 20, 1).await;
    assert!(matches!(report, EoReport::Finished { .. }), "{report:?}");
    assert_eq!(missed(&op).await, 1);
    op.actor().stop(None);

    // the same module running but not answering is a failure, not a wait
    let silent = OpError::unreachable(ModuleKind::Hardware, "rig-race", "the rig did not answer");
    let op = recorder_absent_at("logbook-rig", Some((3, silent))).await;
    match run_to_end(&op, 20, 2).await {
        EoReport::Failed { reason, .. } => assert_eq!(reason, "the rig did not answer"),
        other => panic!("{other:?}"),
    }
    op.actor().stop(None);
    dm.stop(None);
    stand_in.stop(None);
}

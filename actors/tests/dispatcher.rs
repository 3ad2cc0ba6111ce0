//! The action dispatcher, end to end: real EO hosts, the registry, missions from TOML.

mod common;

use common::ops::general;
use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::{
    spawn_operation, EoClient, EoMsg, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{Event, EventBus, EventKind};
use marie_vocabulary::property::{ParamDecl, ParamSchema, PropertyReply, PropertyRequest, Value};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::{OpEnd, Outcome};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use ractor::ActorRef;
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

/// What a test operation does when activated.
#[derive(Clone, Copy)]
enum Behaviour {
    /// Finish after `steps` steps (parameter), raising its one flag.
    Finish,
    /// Never finish by itself.
    Run,
    /// Fail on the first step.
    Fail,
}

struct TestOp {
    name: String,
    id: u32,
    behaviour: Behaviour,
    taken: i64,
}

impl Operation for TestOp {
    fn identity(&self) -> Identity {
        Identity::new(&self.name, self.id, "1.0.0", "test operation")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::int("steps", 2).range(1.0, 1000.0),
            ParamDecl::float("level", 0.5).range(0.0, 1.0),
        ])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(format!("{}-done", self.name), "finished")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.taken = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken += 1;
        match self.behaviour {
            Behaviour::Fail => Err(OpError::failed("sensor unplugged")),
            Behaviour::Run => Ok(Step::Continue),
            Behaviour::Finish if self.taken >= ctx.params().i64("steps")? => {
                Ok(Step::Finish(StatusFlags(1)))
            }
            Behaviour::Finish => Ok(Step::Continue),
        }
    }
}

async fn spawn(name: &str, id: u32, behaviour: Behaviour) -> EoClient {
    let op = TestOp {
        name: name.to_string(),
        id,
        behaviour,
        taken: 0,
    };
    let (actor, _): (ActorRef<EoMsg>, _) =
        spawn_operation(op, HostOptions::default()).await.unwrap();
    EoClient::new(actor)
}

async fn run(src: &str) -> RunReport {
    run_with_events(src).await.0
}

async fn run_with_events(src: &str) -> (RunReport, Vec<Event>) {
    let parsed = ParsedMission::parse(src, None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mission = parsed.validate(&catalog).expect("mission validates");
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let mut events = bus.subscribe();
    let report = timeout(T, run_mission(mission, clock, Some(bus)))
        .await
        .expect("mission ends")
        .expect("dispatcher runs");
    // the dispatcher publishes every event before it reports
    let events = events.drain();
    assert_eq!(
        RunReport::from_events(&events),
        report,
        "the report replays from the events"
    );
    (report, events)
}

#[tokio::test]
async fn actions_run_in_flag_implication_order_not_file_order() {
    let _a = spawn("order-a", 3101, Behaviour::Finish).await;
    let _b = spawn("order-b", 3102, Behaviour::Finish).await;
    let report = run(r#"
        [mission]
        name = "order"
        success = ["order-b-done"]
        [flags]
        order-a-done = 0
        order-b-done = 1
        [[action]]
        name = "second"
        when = ["order-a-done"]
        [action.ops.order-b]
        [[action]]
        name = "first"
        [action.ops.order-a]
    "#)
    .await;
    assert!(report.succeeded(), "{}", report.reason);
    let names: Vec<&str> = report.actions.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["first", "second"]);
    assert_eq!(report.actions[0].flags, ["order-a-done"]);
    assert_eq!(report.actions[1].flags, ["order-a-done", "order-b-done"]);
    assert_eq!(report.status, 0b11);
}

#[tokio::test]
async fn an_action_ends_when_its_ender_finishes_and_the_others_are_suspended() {
    let ender = spawn("end-ender", 3201, Behaviour::Finish).await;
    let runner = spawn("end-runner", 3202, Behaviour::Run).await;
    let report = run(r#"
        [mission]
        name = "ends"
        success = ["end-ender-done"]
        [flags]
        end-ender-done = 0
        end-runner-done = 1
        [[action]]
        name = "drive"
        ends_on = ["end-ender"]
        [action.ops.end-ender]
        steps = 5
        [action.ops.end-runner]
    "#)
    .await;
    assert!(report.succeeded(), "{}", report.reason);
    let ops = &report.actions[0].operations;
    let ended: Vec<(&str, OpEnd)> = ops.iter().map(|o| (o.name.as_str(), o.ended)).collect();
    assert_eq!(
        ended,
        [
            ("end-ender", OpEnd::Finished),
            ("end-runner", OpEnd::Suspended)
        ]
    );
    // suspended, not stopped: the runner is alive, idle, and was activated once
    let g = general(&runner).await;
    assert!(!g.in_use);
    assert_eq!(g.activations, 1);
    assert!(!general(&ender).await.in_use);
    assert!(ops
        .iter()
        .all(|o| o.version == "1.0.0" && o.node == "local"));
}

#[tokio::test]
async fn end_mode_all_waits_for_every_ender() {
    let _a = spawn("all-a", 3301, Behaviour::Finish).await;
    let _b = spawn("all-b", 3302, Behaviour::Finish).await;
    let report = run(r#"
        [mission]
        name = "all"
        success = ["all-a-done", "all-b-done"]
        [flags]
        all-a-done = 0
        all-b-done = 1
        [[action]]
        name = "both"
        end_mode = "all"
        [action.ops.all-a]
        steps = 2
        [action.ops.all-b]
        steps = 30
    "#)
    .await;
    assert!(report.succeeded(), "{}", report.reason);
    assert!(report.actions[0]
        .operations
        .iter()
        .all(|o| o.ended == OpEnd::Finished));
}

#[tokio::test]
async fn a_failing_operation_is_a_full_stop() {
    let _f = spawn("stop-failer", 3401, Behaviour::Fail).await;
    let runner = spawn("stop-runner", 3402, Behaviour::Run).await;
    let _later = spawn("stop-later", 3403, Behaviour::Finish).await;
    let report = run(r#"
        [mission]
        name = "stop"
        success = ["stop-later-done"]
        [flags]
        stop-failer-done = 0
        stop-later-done = 1
        [[action]]
        name = "sense"
        ends_on = ["stop-runner"]
        [action.ops.stop-failer]
        [action.ops.stop-runner]
        [[action]]
        name = "never"
        [action.ops.stop-later]
    "#)
    .await;
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(
        report.reason.contains("`stop-failer` failed"),
        "{}",
        report.reason
    );
    assert!(
        report.reason.contains("sensor unplugged"),
        "{}",
        report.reason
    );
    assert_eq!(report.actions.len(), 1, "the second action never ran");
    // the rest of the running action was suspended
    let deadline = tokio::time::Instant::now() + T;
    while general(&runner).await.in_use {
        assert!(
            tokio::time::Instant::now() < deadline,
            "runner still in use"
        );
        tokio::task::yield_now().await;
    }
}

#[tokio::test]
async fn a_stuck_action_stops_at_its_deadline_naming_the_operation() {
    let runner = spawn("stuck-runner", 3501, Behaviour::Run).await;
    let report = run(r#"
        [mission]
        name = "stuck"
        [flags]
        x = 0
        [[action]]
        name = "wait"
        deadline_s = 0.3
        [action.ops.stuck-runner]
    "#)
    .await;
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(report.reason.contains("deadline"), "{}", report.reason);
    assert!(
        report.reason.contains("`stuck-runner`"),
        "{}",
        report.reason
    );
    let deadline = tokio::time::Instant::now() + T;
    while general(&runner).await.in_use {
        assert!(
            tokio::time::Instant::now() < deadline,
            "runner still in use"
        );
        tokio::task::yield_now().await;
    }
}

#[tokio::test]
async fn omitted_parameters_take_the_declared_defaults() {
    let op = spawn("defaults-op", 3601, Behaviour::Finish).await;
    let report = run(r#"
        [mission]
        name = "defaults"
        [flags]
        defaults-op-done = 0
        [[action]]
        name = "set"
        [action.ops.defaults-op]
        level = 0.9
        [[action]]
        name = "omit"
        when = ["defaults-op-done"]
        [action.ops.defaults-op]
    "#)
    .await;
    assert!(report.succeeded(), "{}", report.reason);
    let level = op
        .property(PropertyRequest::Get("param.level".into()))
        .await
        .unwrap();
    assert_eq!(level, PropertyReply::Value(Value::Float(0.5)));
    let previous = op
        .property(PropertyRequest::Collection(
            marie_vocabulary::property::Collection::Previous,
        ))
        .await
        .unwrap();
    let PropertyReply::Previous(prev) = previous else {
        panic!()
    };
    assert_eq!(prev["level"], Value::Float(0.9));
}

#[tokio::test]
async fn no_runnable_action_and_missing_success_flags_are_failures_with_reasons() {
    let _a = spawn("nr-a", 3701, Behaviour::Finish).await;
    let _b = spawn("nr-b", 3702, Behaviour::Finish).await;
    let report = run(r#"
        [mission]
        name = "stranded"
        initial = ["go"]
        [flags]
        go = 0
        nr-a-done = 1
        nr-b-done = 2
        [[action]]
        name = "first"
        when = ["go"]
        [action.ops.nr-a]
        [[action]]
        name = "blocked"
        when = ["nr-b-done"]
        [action.ops.nr-b]
    "#)
    .await;
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(
        report.reason.contains("`blocked` waits for nr-b-done"),
        "{}",
        report.reason
    );
}

#[tokio::test]
async fn progress_events_follow_the_run() {
    let _a = spawn("events-a", 3801, Behaviour::Finish).await;
    let (report, events) = run_with_events(
        r#"
        [mission]
        name = "events"
        success = ["events-a-done"]
        [flags]
        events-a-done = 4
        [[action]]
        name = "only"
        [action.ops.events-a]
    "#,
    )
    .await;
    assert!(report.succeeded(), "{}", report.reason);
    assert_eq!(report.status, 1 << 4);
    let kinds: Vec<&EventKind> = events.iter().map(|e| &e.kind).collect();
    assert!(
        matches!(kinds[0], EventKind::RunStarted { mission, .. } if mission == "events"),
        "{kinds:?}"
    );
    // the tree right after the start: a thesis mission's schedule of its one action
    assert!(
        matches!(kinds[1], EventKind::ControlPlan { items: nodes } if nodes.len() == 2 && nodes[1].label == "only"),
        "{kinds:?}"
    );
    assert!(
        matches!(kinds[2], EventKind::Selected { choice } if choice.operation == "events-a" && choice.chosen().is_some()),
        "{kinds:?}"
    );
    assert!(matches!(kinds[3], EventKind::Bound { .. }));
    assert!(
        matches!(kinds[4], EventKind::ActionStarted { action, operations, .. } if action == "only" && operations[0].key == "events-a")
    );
    assert!(
        matches!(kinds[5], EventKind::OpEnded { key, ended: OpEnd::Finished, flags, .. } if key == "events-a" && flags == &["events-a-done"])
    );
    assert!(matches!(kinds[6], EventKind::ActionEnded { status, .. } if *status == 1 << 4));
    assert!(matches!(
        kinds.last(),
        Some(EventKind::RunEnded {
            outcome: Outcome::Succeeded,
            ..
        })
    ));
    assert_eq!(kinds.len(), 8, "{kinds:?}");
    assert!(events.iter().all(|e| e.node == "test"));
    assert!(events.windows(2).all(|w| w[0].at_ms <= w[1].at_ms));
}

#[tokio::test]
async fn an_operation_that_dies_mid_action_with_no_stand_in_stops_the_mission_naming_it() {
    let runner = spawn("dies-runner", 3901, Behaviour::Run).await;
    let actor = runner.actor().clone();
    let src = r#"
        [mission]
        name = "dies"
        rebind_deadline_s = 1.0
        [flags]
        x = 0
        [[action]]
        name = "wait"
        deadline_s = 25.0
        [action.ops.dies-runner]
    "#;
    let run = tokio::spawn(run(src));
    // kill it once the dispatcher has activated it
    let deadline = tokio::time::Instant::now() + T;
    while !general(&runner).await.in_use {
        assert!(tokio::time::Instant::now() < deadline, "never activated");
        tokio::task::yield_now().await;
    }
    actor.kill();
    let report = timeout(T, run).await.unwrap().unwrap();
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(
        report
            .reason
            .contains("operation `dies-runner` was lost (died")
            && report
                .reason
                .contains("no compatible instance appeared within 1.0s"),
        "{}",
        report.reason
    );
}

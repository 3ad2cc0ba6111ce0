//! The event stream, end to end: the registry bridge on a bus, and a report rebuilt from the
//! events of a run that had faults and a judgement.

use marie_actors::eo::{
    spawn_operation, EoMsg, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie_vocabulary::clock::{Clock, ManualClock, RealClock};
use marie_vocabulary::events::{
    bridge_registry, Event, EventBus, EventKind, ModuleInfo, OpStarted,
};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::registry::ModuleKind;
use marie_vocabulary::report::{FaultRecord, ReportBuilder, RunReport, REPORT_KEEPS};
use marie_vocabulary::run::{FaultKind, LossCause, OpEnd, Outcome, RebindRecord};
use ractor::ActorRef;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

struct Idle;

impl Operation for Idle {
    fn identity(&self) -> Identity {
        Identity::new("bridge-op", 9101, "1.0.0", "does nothing")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(Vec::new())
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_registry_bridge_publishes_joins_and_leaves() {
    let bus = EventBus::new("bridge-node", RealClock::shared());
    let mut events = bus.subscribe();
    let bridge = bridge_registry(bus.clone(), Some(ModuleKind::Operation))
        .await
        .expect("bridge");
    let (actor, _): (ActorRef<EoMsg>, _) = spawn_operation(Idle, HostOptions::default())
        .await
        .expect("spawn");
    let expected = |info: &ModuleInfo| {
        info.module == ModuleKind::Operation
            && (info.name.as_str(), info.id) == ("bridge-op", 9101)
            && info.address == actor.get_id().to_string()
    };
    let joined = timeout(T, async {
        loop {
            let e = events.recv().await.expect("events");
            if let EventKind::Joined(info) = &e.kind {
                if expected(info) {
                    return e;
                }
            }
        }
    })
    .await
    .expect("a join in time");
    assert_eq!(joined.node, "bridge-node");
    actor.stop(None);
    timeout(T, async {
        loop {
            match events.recv().await.expect("events").kind {
                EventKind::Left(info) if expected(&info) => return,
                _ => {}
            }
        }
    })
    .await
    .expect("a leave in time");
    drop(bridge);
}

#[tokio::test]
async fn a_report_is_rebuilt_with_its_faults_judgement_and_latest_rebinds() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n", clock.clone());
    let mut sub = bus.subscribe();
    let op = OpStarted {
        key: "op".into(),
        name: "op".into(),
        id: 7,
        version: "1.0.0".into(),
        node: "n".into(),
        address: "0.1".into(),
        params: Vec::new(),
    };
    let rebind = |i: u64| RebindRecord {
        operation: "op".into(),
        cause: LossCause::Gone,
        from: format!("0.{i}"),
        to: format!("0.{}", i + 1),
        from_node: "n".into(),
        to_node: "n".into(),
        downtime_ms: 1,
        epoch: i + 1,
    };
    bus.publish(EventKind::RunStarted {
        mission: "m".into(),
        actions: vec![],
        success: vec![],
    });
    bus.publish(EventKind::ActionStarted {
        action: "a".into(),
        run_ms: 0,
        operations: vec![op],
    });
    for i in 1..=150 {
        clock.advance(Duration::from_millis(1));
        bus.publish(EventKind::Rebound(rebind(i)));
    }
    bus.publish(EventKind::FaultInjected {
        fault: FaultKind::Kill,
        operation: "op".into(),
        actor: "0.1".into(),
        node: Some("n".into()),
        due_ms: Some(5),
        lasting_ms: None,
    });
    bus.publish(EventKind::FaultNotInjected {
        fault: FaultKind::Hang,
        operation: "ghost".into(),
        why: "no operation `ghost` is running".into(),
        due_ms: Some(6),
    });
    bus.publish(EventKind::RunEnded {
        outcome: Outcome::Succeeded,
        reason: String::new(),
        run_ms: clock.now().as_millis() as u64,
        status: 1,
        flags: vec!["done".into()],
    });
    // a robot's judgement: an outcome, and what it says of the run (untyped here)
    let robot = serde_json::json!({
        "final_pose": [1.0, 2.0, 0.5],
        "collisions": 0,
        "seed": 3,
        "inside_goal": false,
        "judgement": "failure: outside the goal area",
        "refused_commands": {"wall-follower": 4},
        "mission": "a robot cannot rename the run",
    });
    bus.publish(EventKind::Judged {
        outcome: Outcome::Failed,
        reason: "outside the goal area".into(),
        robot: robot.as_object().cloned().unwrap_or_default(),
    });
    let events = sub.drain();
    let report = RunReport::from_events(&events);
    assert_eq!(report.mission, "m");
    assert_eq!(
        (report.outcome, report.reason.as_str()),
        (Outcome::Failed, "outside the goal area")
    );
    assert_eq!(
        report.robot["final_pose"],
        serde_json::json!([1.0, 2.0, 0.5])
    );
    assert_eq!(
        report.robot["refused_commands"],
        serde_json::json!({"wall-follower": 4})
    );
    assert_eq!(
        report.mission, "m",
        "the report's own keys are not the robot's"
    );
    assert_eq!(report.robot.get("mission"), None);
    assert_eq!(
        (report.rebinds_total, report.rebinds.len()),
        (150, REPORT_KEEPS)
    );
    assert_eq!(report.rebinds.last(), Some(&rebind(150)));
    let action = &report.actions[0];
    assert_eq!((action.start_ms, action.end_ms, action.status), (0, 150, 1));
    // the action's operation was still running at the end, by the last stand-in
    assert_eq!(action.operations[0].ended, OpEnd::Running);
    assert_eq!(action.operations[0].address, "0.151");
    assert_eq!(report.faults_total, 2);
    assert_eq!(
        report.faults[1],
        FaultRecord {
            at_ms: 6,
            fault: FaultKind::Hang,
            operation: "ghost".into(),
            actor: String::new(),
            node: None,
            error: Some("no operation `ghost` is running".into()),
            lasting_ms: None,
            healed_at_ms: None,
        }
    );
    // an injected fault's time is its stamp, counted from the run's start
    assert_eq!(report.faults[0].at_ms, 150);
    // a builder fed the same events agrees, and a new run starts over
    let mut builder = ReportBuilder::new();
    for e in &events {
        builder.apply(e);
    }
    assert_eq!(builder.report(), &report);
    builder.apply(&Event {
        at_ms: 200,
        node: "n".into(),
        kind: EventKind::RunStarted {
            mission: "next".into(),
            actions: vec![],
            success: vec![],
        },
    });
    assert_eq!(builder.report().actions.len(), 0);
    assert_eq!(builder.finish().mission, "next");
}

#[tokio::test]
async fn a_report_attached_to_a_bus_equals_the_fold_of_what_a_subscriber_received() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n", clock.clone());
    let mut sub = bus.subscribe();
    let attached = ReportBuilder::attach(&bus);
    bus.publish(EventKind::RunStarted {
        mission: "m".into(),
        actions: vec![],
        success: vec![],
    });
    clock.advance(Duration::from_millis(40));
    // a fault from any source, with no time of its own: its stamp says when
    bus.publish(EventKind::FaultInjected {
        fault: FaultKind::Kill,
        operation: "op".into(),
        actor: "0.4".into(),
        node: None,
        due_ms: None,
        lasting_ms: None,
    });
    bus.publish(EventKind::RunEnded {
        outcome: Outcome::Succeeded,
        reason: String::new(),
        run_ms: 40,
        status: 0,
        flags: vec![],
    });
    let report = attached.finish();
    bus.publish(EventKind::RunStarted {
        mission: "after".into(),
        actions: vec![],
        success: vec![],
    });
    assert_eq!(report.faults[0].at_ms, 40);
    assert_eq!(report.mission, "m", "a finished report is detached");
    let events: Vec<Event> = sub.drain().into_iter().take(3).collect();
    assert_eq!(RunReport::from_events(&events), report);
}

#[test]
fn a_report_folds_lasting_faults_and_the_nodes_lost_and_back() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n", clock.clone());
    let mut sub = bus.subscribe();
    let at = |ms: u64| clock.advance(Duration::from_millis(ms).saturating_sub(clock.now()));
    at(1000);
    bus.publish(EventKind::RunStarted {
        mission: "m".into(),
        actions: vec![],
        success: vec![],
    });
    at(3000);
    bus.publish(EventKind::FaultInjected {
        fault: FaultKind::FreezeNode,
        operation: "spare".into(),
        actor: "pid 9".into(),
        node: Some("spare".into()),
        due_ms: Some(2000),
        lasting_ms: Some(4000),
    });
    // frozen: declared down, then its sessions end — one loss; then it is back
    at(4300);
    bus.publish(EventKind::NodeDown {
        peer: "spare".into(),
        silent_ms: 1300,
    });
    at(4301);
    bus.publish(EventKind::NodeLost {
        peer: "spare".into(),
        address: "127.0.0.1:1".into(),
    });
    at(7000);
    bus.publish(EventKind::FaultHealed {
        fault: FaultKind::FreezeNode,
        operation: "spare".into(),
    });
    at(7500);
    bus.publish(EventKind::NodeUp {
        peer: "spare".into(),
        address: "127.0.0.1:1".into(),
    });
    // killed: its sessions end, it never comes back
    at(9000);
    bus.publish(EventKind::NodeLost {
        peer: "features".into(),
        address: "127.0.0.1:2".into(),
    });
    let events = sub.drain();
    let report = RunReport::from_events(&events);
    assert_eq!(report.faults.len(), 1);
    let freeze = &report.faults[0];
    assert_eq!(
        (freeze.at_ms, freeze.lasting_ms, freeze.healed_at_ms),
        (2000, Some(4000), Some(6000))
    );
    let lost: Vec<(String, u64, bool, Option<u64>)> = report
        .nodes_lost
        .iter()
        .map(|n| (n.peer.clone(), n.at_ms, n.declared_down, n.back_at_ms))
        .collect();
    assert_eq!(
        lost,
        [
            ("spare".to_string(), 3300, true, Some(6500)),
            ("features".to_string(), 8000, false, None)
        ]
    );
}

#[test]
fn a_report_is_one_run_across_a_takeover_and_folds_only_the_current_dispatchers_word() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("up", clock.clone());
    let mut sub = bus.subscribe();
    let at = |ms: u64| clock.advance(Duration::from_millis(ms).saturating_sub(clock.now()));
    let ended = |outcome, reason: &str, run_ms| EventKind::RunEnded {
        outcome,
        reason: reason.into(),
        run_ms,
        status: 0,
        flags: vec![],
    };
    at(1000);
    bus.republish(
        "features",
        EventKind::RunStarted {
            mission: "m".into(),
            actions: vec![],
            success: vec![],
        },
    );
    at(2000);
    bus.republish(
        "features",
        EventKind::ActionStarted {
            action: "a".into(),
            run_ms: 1000,
            operations: vec![],
        },
    );
    at(5000);
    bus.republish(
        "spare",
        EventKind::Takeover {
            run: "r".into(),
            from: "features".into(),
            to: "spare".into(),
            term: 2,
            gap_ms: 40,
            since_checkpoint_ms: 3000,
            unix_ms: 1,
        },
    );
    // the old dispatcher, woken: what it says is not the run's any more
    at(6000);
    bus.republish(
        "features",
        EventKind::Lost {
            operation: "op".into(),
            cause: LossCause::Gone,
        },
    );
    bus.republish("features", ended(Outcome::Failed, "cut off", 5000));
    bus.republish(
        "features",
        EventKind::DispatcherFenced {
            run: "r".into(),
            term: 1,
            newer: 2,
        },
    );
    at(9000);
    bus.republish(
        "spare",
        EventKind::ActionEnded {
            action: "a".into(),
            run_ms: 8000,
            flags: vec![],
            status: 1,
            result: None,
        },
    );
    bus.republish("spare", ended(Outcome::Succeeded, "", 8000));
    let report = RunReport::from_events(&sub.drain());
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(report.duration_ms, 8000);
    assert_eq!(report.takeovers.len(), 1);
    let t = &report.takeovers[0];
    assert_eq!(
        (t.at_ms, t.from.as_str(), t.to.as_str(), t.term),
        (4000, "features", "spare", 2)
    );
    // the action started under features and ended under spare: one record
    assert_eq!(report.actions.len(), 1);
    assert_eq!(
        (report.actions[0].start_ms, report.actions[0].end_ms),
        (1000, 8000)
    );
}

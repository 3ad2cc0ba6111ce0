//! Self-healing in the dispatcher: bindings survive the death of their instance.
//!
//! The "supervisor" here is the test itself (it spawns a replacement when it sees the old
//! instance leave the registry), so these tests pin down the dispatcher's half of
//! self-healing on its own; the node's real supervision tree is tested in the `marie` package.

mod common;

use common::ops::{general, Worker};
use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::EoClient;
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use marie_vocabulary::property::{Collection, PropertyReply, PropertyRequest, Value};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::run::Verdict;
use marie_vocabulary::run::{LossCause, OpEnd, Outcome};
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

/// Steps of an action whose operation the test kills while it runs: 3 s of 2 ms steps, so
/// that a test task slowed down on a loaded machine still finds it running (at 150 steps,
/// 0.3 s, a CI run once saw the action over before its first look: "never activated").
const STEPS: u32 = 1500;

/// An instance of [`Worker`] `name` in `version`, quick to be declared hung.
async fn start(name: &str, version: &'static str) -> EoClient {
    Worker::new(name, 4000, version)
        .deadline(Duration::from_millis(300))
        .start()
        .await
}

/// Act as a supervisor for `name`: each time an instance leaves the registry, start a new
/// one (up to `times` times).
async fn replace_on_death(name: &str, times: usize) -> tokio::task::JoinHandle<()> {
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.unwrap();
    let name = name.to_string();
    tokio::spawn(async move {
        let mut left = times;
        while left > 0 {
            match watch.next().await {
                Some(RegistryEvent::Left(i)) if i.name == name => {
                    start(&name, "1.0.0").await;
                    left -= 1;
                }
                Some(_) => {}
                None => break,
            }
        }
    })
}

/// The operation's `resumed` property: whether its last activation took over a lost one's.
async fn resumed(c: &EoClient) -> Value {
    match c
        .property(PropertyRequest::Get("resumed".into()))
        .await
        .unwrap()
    {
        PropertyReply::Value(v) => v,
        other => panic!("{other:?}"),
    }
}

/// Wait until `c` runs an activation.
async fn activated(c: &EoClient) {
    let deadline = tokio::time::Instant::now() + T;
    while !general(c).await.in_use {
        assert!(tokio::time::Instant::now() < deadline, "never activated");
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
}

/// A run's events: `live` for waiting on, `log` keeps every one for a replay.
struct Events {
    live: EventSubscription,
    log: EventSubscription,
}

/// Start `src` on a dispatcher; returns the run and its events.
async fn launch(src: &str) -> (tokio::task::JoinHandle<RunReport>, Events) {
    let parsed = ParsedMission::parse(src, None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mission = parsed.validate(&catalog).expect("mission validates");
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let events = Events {
        live: bus.subscribe(),
        log: bus.subscribe(),
    };
    let run = tokio::spawn(async move {
        timeout(T, run_mission(mission, clock, Some(bus)))
            .await
            .expect("mission ends")
            .expect("dispatcher runs")
    });
    (run, events)
}

/// Wait for the first event that `pick` accepts.
async fn event<R>(events: &mut Events, mut pick: impl FnMut(&EventKind) -> Option<R>) -> R {
    timeout(T, async {
        loop {
            let e = events
                .live
                .recv()
                .await
                .expect("dispatcher events end early");
            if let Some(r) = pick(&e.kind) {
                return r;
            }
        }
    })
    .await
    .expect("event in time")
}

fn mission(name: &str, op: &str, steps: u32) -> String {
    format!(
        r#"
        [mission]
        name = "{name}"
        success = ["done"]
        rebind_deadline_s = 20.0
        [flags]
        done = 0
        [[action]]
        name = "work"
        [action.ops.{op}]
        steps = {steps}
        gain = 2.5
    "#
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_operation_is_rebound_to_its_replacement_and_the_action_completes() {
    let first = start("rb-kill", "1.0.0").await;
    let _sup = replace_on_death("rb-kill", 1).await;
    let (run, mut events) = launch(&mission("kill", "rb-kill", STEPS)).await;
    activated(&first).await;
    first.actor().kill();
    let record = event(&mut events, |e| match e {
        EventKind::Rebound(r) => Some(r.clone()),
        _ => None,
    })
    .await;
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(report.rebinds, vec![record.clone()]);
    assert_eq!(report.rebinds_total, 1);
    // the whole report, rebind included, replays from the run's events
    let log = events.log.drain();
    assert!(log
        .iter()
        .any(|e| matches!(&e.kind, EventKind::Lost { operation, .. } if operation == "rb-kill")));
    assert_eq!(RunReport::from_events(&log), report);
    assert_eq!(record.operation, "rb-kill");
    assert_eq!(record.from, first.actor().get_id().to_string());
    assert_ne!(record.to, record.from);
    assert!(died(&record.cause), "{}", record.cause);
    // the operation's record in the action names the instance that finished it
    assert_eq!(report.actions[0].operations[0].address, record.to);
    assert_eq!(report.actions[0].operations[0].ended, OpEnd::Finished);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operation_stopped_mid_action_is_rebound_not_taken_for_a_suspension() {
    // a node that comes back after its peers declared it down stops its operations (a new
    // incarnation of each): the soak's run 7 failed so, its dispatcher on that very node
    // hearing "suspended" from each — "operation `docking-detector` was suspended by
    // another party"
    let first = start("rb-stop", "1.0.0").await;
    let _sup = replace_on_death("rb-stop", 1).await;
    let (run, mut events) = launch(&mission("stop", "rb-stop", STEPS)).await;
    activated(&first).await;
    first.actor().stop(None);
    let record = event(&mut events, |e| match e {
        EventKind::Rebound(r) => Some(r.clone()),
        _ => None,
    })
    .await;
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(record.from, first.actor().get_id().to_string());
    assert!(died(&record.cause), "{}", record.cause);
    assert_eq!(report.actions[0].operations[0].ended, OpEnd::Finished);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_stand_in_gets_the_last_parameters_a_higher_epoch_and_resumes() {
    let first = start("rb-params", "1.0.0").await;
    let _sup = replace_on_death("rb-params", 1).await;
    let (run, mut events) = launch(&mission("params", "rb-params", STEPS)).await;
    activated(&first).await;
    assert_eq!(
        resumed(&first).await,
        Value::Bool(false),
        "a fresh activation"
    );
    let old_epoch = general(&first).await.epoch;
    first.inject(FaultKind::Panic).unwrap();
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let lost = event(&mut events, |e| match e {
        EventKind::Lost { cause, .. } => Some(cause.clone()),
        _ => None,
    })
    .await;
    assert!(died(&lost), "{lost}");
    let now = registry::lookup(ModuleKind::Operation, "rb-params");
    assert_eq!(now.len(), 1, "only the replacement is alive");
    let stand_in = EoClient::from_cell(now[0].actor.clone());
    match stand_in
        .property(PropertyRequest::Collection(Collection::Current))
        .await
        .unwrap()
    {
        PropertyReply::Current(p) => {
            assert_eq!(p.get("steps"), Some(&Value::Int(STEPS.into())));
            assert_eq!(p.get("gain"), Some(&Value::Float(2.5)));
        }
        other => panic!("{other:?}"),
    }
    let g = general(&stand_in).await;
    assert!(g.epoch > old_epoch, "{} > {old_epoch}", g.epoch);
    assert_eq!(g.activations, 1, "re-activated once");
    assert_eq!(
        resumed(&stand_in).await,
        Value::Bool(true),
        "the stand-in knows it takes over"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_live_instance_stands_in_at_once() {
    let first = start("rb-twin", "1.0.0").await;
    let twin = start("rb-twin", "1.2.0").await;
    let (run, _events) = launch(&mission("twin", "rb-twin", STEPS)).await;
    // the dispatcher binds the first instance in registry order
    activated(&first).await;
    first.actor().kill();
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(report.rebinds.len(), 1);
    assert_eq!(report.rebinds[0].to, twin.actor().get_id().to_string());
    assert_eq!(report.actions[0].operations[0].version, "1.0.0");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stand_in_is_chosen_by_the_same_ranking_as_at_the_start_and_the_choice_is_explained() {
    let first = start("rb-rank", "1.0.0").await;
    let (run, mut events) =
        launch(&mission("rank", "rb-rank", 100_000).replace("20.0", "5.0")).await;
    activated(&first).await;
    // the superset shows up first: taking the first that fits would take it
    let superset = start("rb-rank", "3.0.0").await;
    let exact = start("rb-rank", "1.1.0").await;
    first.actor().kill();
    let lost = first.actor().get_id().to_string();
    let choice = event(&mut events, |e| match e {
        EventKind::Selected { choice } if choice.replacing.is_some() => Some(choice.clone()),
        _ => None,
    })
    .await;
    assert_eq!(choice.replacing.as_deref(), Some(lost.as_str()));
    let chosen = choice.chosen().expect("a stand-in was chosen");
    assert_eq!(chosen.address, exact.actor().get_id().to_string());
    let other = choice
        .candidates
        .iter()
        .find(|c| c.address == superset.actor().get_id().to_string())
        .expect("the superset was a candidate");
    match &other.verdict {
        Verdict::Lost { reason } => assert!(reason.contains("also declares mode"), "{reason}"),
        v => panic!("the superset should have lost, not {v:?}"),
    }
    let record = event(&mut events, |e| match e {
        EventKind::Rebound(r) => Some(r.clone()),
        _ => None,
    })
    .await;
    assert_eq!(record.to, chosen.address);
    exact.actor().kill();
    superset.actor().kill();
    let report = run.await.unwrap();
    // the report keeps the stand-in's choice beside the first one
    assert!(
        report
            .selection
            .iter()
            .any(|c| c.replacing.as_deref() == Some(lost.as_str())),
        "{:?}",
        report.selection
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hung_operation_is_killed_and_rebound() {
    let first = start("rb-hang", "1.0.0").await;
    let _sup = replace_on_death("rb-hang", 1).await;
    let (run, mut events) = launch(&mission("hang", "rb-hang", STEPS)).await;
    activated(&first).await;
    first.inject(FaultKind::Hang).unwrap();
    let cause = event(&mut events, |e| match e {
        EventKind::Lost { cause, .. } => Some(cause.clone()),
        _ => None,
    })
    .await;
    assert_eq!(cause, LossCause::Hung { deadline_ms: 300 });
    assert!(cause.to_string().contains("300 ms"), "{cause}");
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(report.rebinds.len(), 1);
    // killed: its actor is gone
    assert!(registry::lookup(ModuleKind::Operation, "rb-hang")
        .iter()
        .all(|i| i.actor.get_id() != first.actor().get_id()));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_version_the_mission_does_not_accept_does_not_stand_in_and_the_mission_stops_naming_the_operation(
) {
    let first = start("rb-major", "1.0.0").await;
    let src = mission("major", "rb-major", 100_000).replace("20.0", "1.0")
        + "\n[requires]\nrb-major = \"^1\"\n";
    let (run, mut events) = launch(&src).await;
    activated(&first).await;
    let _v2 = start("rb-major", "2.0.0").await;
    first.actor().kill();
    // it stops at the mission's rebind deadline (1 s), not the default (10 s)
    let waited = event(&mut events, |e| match e {
        EventKind::RebindGaveUp { waited_ms, .. } => Some(*waited_ms),
        _ => None,
    })
    .await;
    assert!((1000..10_000).contains(&waited), "{waited} ms");
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(
        report.reason.contains("operation `rb-major` was lost"),
        "{}",
        report.reason
    );
    // and why the instance that did show up could not stand in
    assert!(
        report.reason.contains("refused as stand-ins")
            && report
                .reason
                .contains("does not match the mission's requirement ^1"),
        "{}",
        report.reason
    );
    assert!(report.rebinds.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_major_version_stands_in_when_the_mission_could_have_chosen_it() {
    // no `[requires]`: version 2 takes the same parameters, so it could have been chosen at
    // the start, and may stand in
    let first = start("rb-any", "1.0.0").await;
    let src = mission("any", "rb-any", 100_000).replace("20.0", "1.0");
    let (run, mut events) = launch(&src).await;
    activated(&first).await;
    let v2 = start("rb-any", "2.0.0").await;
    first.actor().kill();
    let record = event(&mut events, |e| match e {
        EventKind::Rebound(r) => Some(r.clone()),
        _ => None,
    })
    .await;
    assert_eq!(record.to, v2.actor().get_id().to_string());
    v2.actor().kill();
    let _ = run.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operation_lost_between_actions_is_rebound_before_its_next_action() {
    let a = start("rb-between-a", "1.0.0").await;
    let b = start("rb-between-b", "1.0.0").await;
    let _sup = replace_on_death("rb-between-b", 1).await;
    // both raise `done`: the second action runs once the first has finished
    let src = format!(
        r#"
        [mission]
        name = "between"
        success = ["done"]
        [flags]
        done = 0
        [[action]]
        name = "first"
        [action.ops.rb-between-a]
        steps = {STEPS}
        [[action]]
        name = "second"
        when = ["done"]
        [action.ops.rb-between-b]
        steps = 5
    "#
    );
    let (run, mut events) = launch(&src).await;
    activated(&a).await;
    b.actor().kill(); // b is bound but idle
    let record = event(&mut events, |e| match e {
        EventKind::Rebound(r) => Some(r.clone()),
        _ => None,
    })
    .await;
    assert_eq!(record.operation, "rb-between-b");
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let second = &report.actions[1];
    assert_eq!(second.name, "second");
    assert_eq!(second.operations[0].address, record.to);
}

/// A cause that says the instance died (rather than hung or lost its node).
fn died(cause: &LossCause) -> bool {
    matches!(
        cause,
        LossCause::DiedInAction { .. } | LossCause::LeftRegistry | LossCause::Gone
    )
}

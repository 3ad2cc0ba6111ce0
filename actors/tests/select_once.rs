//! Select once: a mission checked against the running instances carries the check's
//! choices to its dispatcher, which binds them without asking every candidate again —
//! unless an instance changed since the check: the chosen one is gone, busy or silent, or a
//! new instance of the operation appeared. Then that operation is selected again, among
//! every live instance.
//!
//! Each test uses operations of its own name: the registry is one per process.

mod common;

use common::ops::Worker;
use marie_actors::dispatcher::mission::{Mission, ParsedMission};
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::{EoClient, ParamOutcome};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{BoundOp, Event, EventBus, EventKind};
use marie_vocabulary::property::{ParamMap, Value};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::{Choice, FaultKind, Outcome, Verdict};
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

/// An instance of [`Worker`] `name` in `version`.
async fn start(name: &str, version: &'static str) -> EoClient {
    Worker::new(name, 4100, version).start().await
}

fn address(c: &EoClient) -> String {
    c.actor().get_id().to_string()
}

/// One action running `op` for a few steps; `steps` and `gain` supplied (version 1 fits
/// exactly, version 3 is a compatible superset).
fn mission_text(op: &str) -> String {
    format!(
        r#"
        [mission]
        name = "once"
        success = ["done"]
        [flags]
        done = 0
        [[action]]
        name = "work"
        [action.ops.{op}]
        steps = 5
        gain = 2.5
    "#
    )
}

/// The mission checked against the running instances, as `Node::check_mission` does.
async fn check(op: &str) -> Mission {
    let parsed = ParsedMission::parse(&mission_text(op), None).expect("mission parses");
    let catalog = RegistryCatalog::for_mission(&parsed).await.unwrap();
    parsed.validate(&catalog).expect("mission validates")
}

/// Run `mission` on a dispatcher of its own: its report and every event of the run.
async fn run(mission: Mission) -> (RunReport, Vec<Event>) {
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let mut log = bus.subscribe();
    let report = timeout(T, run_mission(mission, clock, Some(bus)))
        .await
        .expect("mission ends")
        .expect("dispatcher runs");
    (report, log.drain())
}

/// The run's choice at its start (not a stand-in's).
fn selected(events: &[Event]) -> Vec<Choice> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Selected { choice } if choice.replacing.is_none() => Some(choice.clone()),
            _ => None,
        })
        .collect()
}

fn bound(events: &[Event]) -> Vec<BoundOp> {
    events
        .iter()
        .find_map(|e| match &e.kind {
            EventKind::Bound { operations } => Some(operations.clone()),
            _ => None,
        })
        .expect("a bound event")
}

/// Wait until the registry no longer lists `c` (its leave is seen by `watch`).
async fn left(watch: &mut registry::Watch, c: &EoClient) {
    let id = c.actor().get_id();
    timeout(T, async {
        loop {
            match watch.next().await {
                Some(RegistryEvent::Left(i)) if i.actor_id() == id => return,
                Some(_) => {}
                None => panic!("the registry watch ended"),
            }
        }
    })
    .await
    .expect("the instance leaves the registry");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_checked_mission_binds_the_checks_choice_without_asking_the_other_candidates_again() {
    let exact = start("so-quiet", "1.0.0").await;
    let superset = start("so-quiet", "3.0.0").await;
    let mission = check("so-quiet").await;
    let checked = mission.checked().choice("so-quiet").cloned().unwrap();
    assert_eq!(checked.chosen().unwrap().address, address(&exact));
    // the candidate that lost stops answering: a selection at the bind would wait for it
    // and leave it out; binding the check's choice never asks it
    superset.inject(FaultKind::Hang).unwrap();
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(selected(&events), vec![checked.clone()]);
    assert_eq!(report.selection, vec![checked]);
    assert_eq!(bound(&events)[0].address, address(&exact));
    assert!(report.rebinds.is_empty());
    superset.actor().kill();
    exact.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_instance_chosen_at_the_check_and_killed_before_the_run_is_not_bound() {
    let exact = start("so-killed", "1.0.0").await;
    let superset = start("so-killed", "3.0.0").await;
    let mission = check("so-killed").await;
    assert_eq!(
        mission
            .checked()
            .choice("so-killed")
            .unwrap()
            .chosen()
            .unwrap()
            .address,
        address(&exact)
    );
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.unwrap();
    exact.actor().kill();
    left(&mut watch, &exact).await;
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    // selected again, among the live instances only
    let choice = &selected(&events)[0];
    assert_eq!(choice.candidates.len(), 1, "{choice:?}");
    assert_eq!(choice.chosen().unwrap().address, address(&superset));
    assert_eq!(bound(&events)[0].address, address(&superset));
    assert_eq!(report.actions[0].operations[0].address, address(&superset));
    assert!(
        report.rebinds.is_empty(),
        "bound to the live one from the start"
    );
    superset.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_instance_chosen_at_the_check_and_killed_just_before_the_run_is_not_bound() {
    // the run starts at once after the kill: the registry may still list the dead
    // instance, which then does not answer the bind's request
    let exact = start("so-dying", "1.0.0").await;
    let superset = start("so-dying", "3.0.0").await;
    let mission = check("so-dying").await;
    exact.actor().kill();
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let choice = &selected(&events)[0];
    assert_eq!(choice.chosen().unwrap().address, address(&superset));
    assert!(choice
        .candidates
        .iter()
        .all(|c| c.address != address(&exact)));
    assert_eq!(bound(&events)[0].address, address(&superset));
    assert!(report.rebinds.is_empty());
    superset.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_better_fitting_instance_that_appears_after_the_check_is_chosen_at_the_run() {
    let superset = start("so-newcomer", "3.0.0").await;
    let mission = check("so-newcomer").await;
    assert_eq!(
        mission
            .checked()
            .choice("so-newcomer")
            .unwrap()
            .chosen()
            .unwrap()
            .address,
        address(&superset)
    );
    // an exact fit starts after the check (it is in the registry once `start` returns)
    let exact = start("so-newcomer", "1.1.0").await;
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let choice = &selected(&events)[0];
    assert_eq!(choice.chosen().unwrap().address, address(&exact));
    let lost = choice
        .candidates
        .iter()
        .find(|c| c.address == address(&superset))
        .expect("the superset is a candidate");
    match &lost.verdict {
        Verdict::Lost { reason } => assert!(reason.contains("also declares mode"), "{reason}"),
        v => panic!("the superset should have lost, not {v:?}"),
    }
    assert_eq!(report.actions[0].operations[0].version, "1.1.0");
    exact.actor().kill();
    superset.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_instance_chosen_at_the_check_and_busy_since_is_not_bound() {
    let one = start("so-busy", "1.0.0").await;
    let two = start("so-busy", "1.0.0").await;
    let mission = check("so-busy").await;
    let chosen = mission
        .checked()
        .choice("so-busy")
        .unwrap()
        .chosen()
        .unwrap()
        .address
        .clone();
    let (busy, free) = if chosen == address(&one) {
        (one, two)
    } else {
        (two, one)
    };
    // another binding activates the chosen instance for a long task
    let mut long = ParamMap::new();
    long.insert("steps".into(), Value::Int(100_000));
    let _running = busy.activate(long, 1).unwrap();
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let choice = &selected(&events)[0];
    assert_eq!(choice.chosen().unwrap().address, address(&free));
    assert_eq!(bound(&events)[0].address, address(&free));
    busy.actor().kill();
    free.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_checked_mission_binds_above_the_epoch_its_instance_accepted_since_and_runs_twice() {
    let only = start("so-epoch", "1.0.0").await;
    let mission = check("so-epoch").await;
    let checked = mission.checked().choice("so-epoch").cloned().unwrap();
    // someone else commands the instance at a high epoch after the check
    let high = 1_000_000_000_000_000;
    let outcome = only.parameterize(ParamMap::new(), high).await.unwrap();
    assert_eq!(outcome, ParamOutcome::Applied);
    let (report, events) = run(mission.clone()).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(selected(&events), vec![checked.clone()]);
    assert!(bound(&events)[0].epoch > high, "{:?}", bound(&events));
    // the same checked mission again: its first run raised the epoch; nothing else changed
    let first_epoch = bound(&events)[0].epoch;
    let (report, events) = run(mission).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(selected(&events), vec![checked]);
    assert!(bound(&events)[0].epoch > first_epoch);
    only.actor().kill();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mission_without_its_checks_choices_selects_at_the_bind() {
    let exact = start("so-unchecked", "1.0.0").await;
    let superset = start("so-unchecked", "3.0.0").await;
    let mission = check("so-unchecked").await;
    assert_eq!(mission.checked().len(), 1);
    // read back from JSON, or told to forget: nothing is carried
    let json = serde_json::to_string(&mission).unwrap();
    let read: Mission = serde_json::from_str(&json).unwrap();
    assert!(read.checked().is_empty());
    assert!(mission.clone().unchecked().checked().is_empty());
    let (report, events) = run(read).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let choice = &selected(&events)[0];
    assert_eq!(choice.candidates.len(), 2, "{choice:?}");
    assert_eq!(choice.chosen().unwrap().address, address(&exact));
    superset.actor().kill();
    exact.actor().kill();
}

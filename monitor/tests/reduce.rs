//! The reducer on a recorded run: `marie run missions/docking.toml --speed max --fault
//! kill:wall-follower@20 --events docking-kill.jsonl` (regenerate the fixture with that
//! command when the event schema grows).

use marie_monitor::state::mission::ActionState;
use marie_monitor::state::timeline::TIMELINE_LIMIT;
use marie_monitor::MonitorState;
use marie_vocabulary::events::Event;
use marie_vocabulary::run::Outcome;

fn recorded() -> Vec<Event> {
    include_str!("fixtures/docking-kill.jsonl")
        .lines()
        .map(|l| Event::from_json_line(l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .collect()
}

#[test]
fn a_recorded_run_ends_with_every_action_succeeded_and_one_rebind() {
    let events = recorded();
    let state = MonitorState::from_events(&events);
    assert_eq!(state.events, events.len() as u64);
    assert_eq!(state.mission.name, "docking");
    let names: Vec<_> = state
        .mission
        .actions
        .iter()
        .map(|a| a.name.as_str())
        .collect();
    assert_eq!(names, ["find-wall", "follow-wall", "plan-parking", "park"]);
    for a in &state.mission.actions {
        assert_eq!(a.state, ActionState::Succeeded, "{}", a.name);
    }
    let follow = &state.mission.actions[1];
    assert_eq!(follow.when, ["wall-found"]);
    assert!(follow.ops.iter().any(|o| o.name == "wall-follower"));
    let wf = &state.bindings.0["wall-follower"];
    assert_eq!(wf.rebinds, 1);
    assert_eq!(wf.status, "bound");
    assert_eq!(wf.address.as_deref(), Some("0.18"));
    assert_eq!(wf.history.len(), 2, "lost, then rebound: {:?}", wf.history);
    assert_eq!(state.bindings.0.len(), 10);
    let outcome = state.mission.outcome.as_ref().unwrap();
    assert_eq!(outcome.outcome, Outcome::Succeeded);
    assert!(outcome.judgement.is_some());
    let classes: Vec<_> = state.timeline.entries.iter().map(|e| e.class).collect();
    for class in ["fault", "lost", "rebind", "restart"] {
        assert!(classes.contains(&class), "{class} in {classes:?}");
    }
    assert!(state.cluster.0.contains_key("embedded"));
}

#[test]
fn a_state_midway_has_the_running_action_and_the_later_ones_waiting() {
    let events = recorded();
    let second = events
        .iter()
        .position(|e| {
            matches!(&e.kind, marie_vocabulary::events::EventKind::ActionStarted { action, .. } if action == "follow-wall")
        })
        .unwrap();
    let state = MonitorState::from_events(&events[..=second]);
    let states: Vec<_> = state.mission.actions.iter().map(|a| a.state).collect();
    assert_eq!(
        states,
        [
            ActionState::Succeeded,
            ActionState::Running,
            ActionState::Waiting,
            ActionState::Waiting
        ]
    );
    assert_eq!(state.mission.flags, ["wall-found"]);
    assert!(state.mission.outcome.is_none());
}

#[test]
fn the_timeline_is_bounded() {
    let events = recorded();
    let fault = events
        .iter()
        .find(|e| {
            matches!(
                e.kind,
                marie_vocabulary::events::EventKind::FaultInjected { .. }
            )
        })
        .unwrap()
        .clone();
    let mut state = MonitorState::default();
    for _ in 0..TIMELINE_LIMIT + 10 {
        state.apply(&fault);
    }
    assert_eq!(state.timeline.entries.len(), TIMELINE_LIMIT);
    assert_eq!(state.timeline.dropped, 10);
}

#[test]
fn the_state_serializes_for_the_page() {
    let state = MonitorState::from_events(&recorded());
    let json = serde_json::to_value(&state).unwrap();
    assert_eq!(json["mission"]["actions"][0]["state"], "succeeded");
    assert_eq!(json["mission"]["outcome"]["outcome"], "succeeded");
    assert_eq!(json["bindings"]["wall-follower"]["rebinds"], 1);
}

//! The behaviour tree of a run (issue 24) folded into the monitor's state: the plan's
//! nodes, the running branch, how nodes ended, and each node's control decisions (retry
//! counts, timeouts, fallbacks, conditions lost, recoveries).

use marie_monitor::state::tree::{ControlTree, NodeEnd, DECISIONS_KEPT};
use marie_monitor::MonitorState;
use marie_vocabulary::events::{ActionPlan, Event, EventKind, PlanItem};
use marie_vocabulary::run::{OpEnd, Outcome};

fn event(kind: EventKind) -> Event {
    Event {
        at_ms: 1_000,
        node: "robot".into(),
        kind,
    }
}

fn node(id: usize, parent: Option<usize>, kind: &str, label: &str, detail: &str) -> PlanItem {
    PlanItem {
        id,
        parent,
        kind: kind.into(),
        label: label.into(),
        detail: detail.into(),
    }
}

/// ```text
/// 0 schedule patrol
/// 1   retry(guarded)            3 attempts
/// 2     timeout(guarded)        40.0 s
/// 3       fallback guarded
/// 4         sequence main
/// 5           find-wall
/// 6           follow-wall
/// 7         recover(back-off, then turn)
/// 8           back-off
/// 9           turn
/// 10  reactive careful           while wall-found
/// 11    condition(0x1)
/// 12    creep
/// 13  parallel both              succeeds at 2 of 2, fails at 1
/// 14    look
/// 15    listen
/// ```
fn plan() -> Vec<PlanItem> {
    vec![
        node(0, None, "schedule", "patrol", ""),
        node(
            1,
            Some(0),
            "retry",
            "retry(guarded)",
            "3 attempts, 2.0 s apart",
        ),
        node(2, Some(1), "timeout", "timeout(guarded)", "40.0 s"),
        node(3, Some(2), "fallback", "guarded", ""),
        node(4, Some(3), "sequence", "main", ""),
        node(5, Some(4), "action", "find-wall", "ultrasonic, wall-finder"),
        node(6, Some(4), "action", "follow-wall", "wall-follower"),
        node(7, Some(3), "recover", "recover(back-off, then turn)", ""),
        node(8, Some(7), "action", "back-off", "cart"),
        node(9, Some(7), "action", "turn", "cart"),
        node(10, Some(0), "reactive", "careful", "while wall-found"),
        node(
            11,
            Some(10),
            "condition",
            "condition(0x1)",
            "needs wall-found",
        ),
        node(12, Some(10), "action", "creep", "cart"),
        node(
            13,
            Some(0),
            "parallel",
            "both",
            "succeeds at 2 of 2, fails at 1",
        ),
        node(14, Some(13), "action", "look", "camera"),
        node(15, Some(13), "action", "listen", "microphone"),
    ]
}

/// A run of `patrol` with its plan.
fn planned() -> MonitorState {
    let mut state = MonitorState::default();
    let actions = ["find-wall", "follow-wall", "back-off", "turn", "creep"]
        .iter()
        .map(|name| ActionPlan {
            name: name.to_string(),
            when: vec![],
            ops: vec!["cart".into()],
            ends_on: vec!["cart".into()],
        })
        .collect();
    state.apply(&event(EventKind::RunStarted {
        mission: "patrol".into(),
        actions,
        success: vec![],
    }));
    state.apply(&event(EventKind::ControlPlan { items: plan() }));
    state
}

fn started(state: &mut MonitorState, action: &str) {
    state.apply(&event(EventKind::ActionStarted {
        action: action.into(),
        run_ms: 0,
        operations: vec![],
    }));
}

fn op_ended(state: &mut MonitorState, action: &str, ended: OpEnd) {
    state.apply(&event(EventKind::OpEnded {
        action: action.into(),
        key: "cart".into(),
        ended,
        flags: vec![],
    }));
}

fn ended(state: &mut MonitorState, action: &str) {
    state.apply(&event(EventKind::ActionEnded {
        action: action.into(),
        run_ms: 0,
        flags: vec![],
        status: 0,
        result: None,
    }));
}

fn decided(state: &mut MonitorState, label: &str, decision: &str) {
    state.apply(&event(EventKind::Control {
        item: label.into(),
        decision: decision.into(),
        run_ms: 5_000,
    }));
}

/// The ids of the nodes that run.
fn running(tree: &ControlTree) -> Vec<usize> {
    tree.items
        .iter()
        .filter(|n| n.running)
        .map(|n| n.id)
        .collect()
}

fn end(tree: &ControlTree, id: usize) -> Option<NodeEnd> {
    tree.items[id].ended
}

#[test]
fn the_plan_gives_every_node_its_parent_depth_and_nothing_runs_yet() {
    let state = planned();
    let tree = &state.tree;
    assert_eq!(tree.plan, 1);
    assert_eq!(tree.items.len(), 16);
    let depths: Vec<_> = tree.items.iter().map(|n| n.depth).collect();
    assert_eq!(depths, [0, 1, 2, 3, 4, 5, 5, 4, 5, 5, 1, 2, 2, 1, 2, 2]);
    assert_eq!(tree.items[6].parent, Some(4));
    assert_eq!(tree.items[6].label, "follow-wall");
    assert_eq!(tree.items[2].detail, "40.0 s");
    assert!(running(tree).is_empty());
    assert!(tree.items.iter().all(|n| n.ended.is_none()));
}

#[test]
fn the_running_branch_is_the_running_action_and_its_ancestors() {
    let mut state = planned();
    started(&mut state, "find-wall");
    assert_eq!(running(&state.tree), [0, 1, 2, 3, 4, 5]);
    assert_eq!(state.tree.items[5].starts, 1);
    ended(&mut state, "find-wall");
    assert_eq!(end(&state.tree, 5), Some(NodeEnd::Succeeded));
    assert!(running(&state.tree).is_empty(), "between two actions");
    started(&mut state, "follow-wall");
    assert_eq!(running(&state.tree), [0, 1, 2, 3, 4, 6]);
    ended(&mut state, "follow-wall");
    // the sequence, the fallback, the timeout and the retry succeeded with it
    for id in [4, 3, 2, 1] {
        assert_eq!(end(&state.tree, id), Some(NodeEnd::Succeeded), "node {id}");
    }
    assert_eq!(end(&state.tree, 0), None, "the schedule goes on");
    assert_eq!(end(&state.tree, 7), None, "the recovery never ran");
}

#[test]
fn a_parallel_runs_two_actions_at_once_and_halts_the_other_when_decided() {
    let mut state = planned();
    started(&mut state, "look");
    started(&mut state, "listen");
    assert_eq!(running(&state.tree), [0, 13, 14, 15]);
    op_ended(&mut state, "look", OpEnd::Failed);
    ended(&mut state, "look");
    assert_eq!(end(&state.tree, 14), Some(NodeEnd::Failed));
    assert_eq!(running(&state.tree), [0, 13, 15]);
    decided(&mut state, "both", "parallel failed");
    assert_eq!(running(&state.tree), [0, 13, 15], "until the halt is done");
    ended(&mut state, "listen");
    assert_eq!(end(&state.tree, 15), Some(NodeEnd::Halted));
    assert_eq!(end(&state.tree, 13), Some(NodeEnd::Failed));
    assert_eq!(
        end(&state.tree, 0),
        Some(NodeEnd::Failed),
        "the schedule fails"
    );
    assert_eq!(state.tree.items[13].decisions[0].text, "parallel failed");
}

#[test]
fn fallback_recovery_timeout_and_retry_are_counted_on_their_nodes() {
    let mut state = planned();
    started(&mut state, "find-wall");
    ended(&mut state, "find-wall");
    started(&mut state, "follow-wall");
    // it missed its deadline: no operation failed, the fallback says it failed
    ended(&mut state, "follow-wall");
    // the decision names the item fallen back to, under its decorator
    decided(&mut state, "guarded", "fallback to `back-off`");
    let tree = &state.tree;
    assert_eq!(tree.items[3].fallbacks, 1);
    assert_eq!(end(tree, 4), Some(NodeEnd::Failed), "the sequence failed");
    assert_eq!(end(tree, 6), Some(NodeEnd::Failed), "its last action too");
    assert_eq!(end(tree, 5), Some(NodeEnd::Succeeded));
    assert_eq!(end(tree, 3), None, "the fallback goes on");
    started(&mut state, "back-off");
    assert_eq!(running(&state.tree), [0, 1, 2, 3, 7, 8]);
    op_ended(&mut state, "back-off", OpEnd::Lost);
    ended(&mut state, "back-off");
    decided(
        &mut state,
        "recover(back-off, then turn)",
        "recovery `turn`",
    );
    assert_eq!(state.tree.items[7].recoveries, 1);
    started(&mut state, "turn");
    decided(&mut state, "timeout(guarded)", "timeout after 40.0 s");
    assert_eq!(state.tree.items[2].timeouts, 1);
    assert_eq!(end(&state.tree, 2), None, "it runs until the halt is done");
    ended(&mut state, "turn");
    let tree = &state.tree;
    assert_eq!(end(tree, 9), Some(NodeEnd::Halted));
    assert_eq!(end(tree, 2), Some(NodeEnd::Failed));
    assert_eq!(end(tree, 1), None, "the retry tries again");
    assert!(running(tree).is_empty());
    // the second attempt: the first one's ends are forgotten, its counts kept
    decided(&mut state, "retry(guarded)", "retry 2 of 3");
    let tree = &state.tree;
    assert_eq!(tree.items[1].attempt, Some([2, 3]));
    assert!((2..=9).all(|id| end(tree, id).is_none()));
    assert_eq!(tree.items[2].timeouts, 1);
    started(&mut state, "find-wall");
    assert_eq!(state.tree.items[5].starts, 2);
    assert_eq!(running(&state.tree), [0, 1, 2, 3, 4, 5]);
    op_ended(&mut state, "find-wall", OpEnd::Failed);
    ended(&mut state, "find-wall");
    decided(&mut state, "retry(guarded)", "retry 3 of 3");
    decided(&mut state, "retry(guarded)", "gave up after 3 attempts");
    let tree = &state.tree;
    assert!(tree.items[1].gave_up);
    assert_eq!(tree.items[1].attempt, Some([3, 3]));
    assert_eq!(end(tree, 1), Some(NodeEnd::Failed));
    assert_eq!(end(tree, 0), Some(NodeEnd::Failed));
    assert_eq!(tree.items[1].told, 3);
}

#[test]
fn a_condition_lost_halts_the_reactive_sequence() {
    let mut state = planned();
    started(&mut state, "creep");
    assert_eq!(running(&state.tree), [0, 10, 12]);
    decided(&mut state, "careful", "condition no longer holds");
    ended(&mut state, "creep");
    let tree = &state.tree;
    assert_eq!(tree.items[10].conditions_lost, 1);
    assert_eq!(end(tree, 12), Some(NodeEnd::Halted));
    assert_eq!(end(tree, 10), Some(NodeEnd::Failed));
}

#[test]
fn a_decision_that_names_no_node_only_goes_to_the_timeline_and_decisions_are_bounded() {
    let mut state = planned();
    decided(&mut state, "nowhere", "retry 2 of 3");
    assert!(state.tree.items.iter().all(|n| n.told == 0));
    assert!(state
        .timeline
        .entries
        .iter()
        .any(|e| e.class == "control" && e.text == "nowhere: retry 2 of 3 at 5.0s"));
    for i in 0..DECISIONS_KEPT + 3 {
        decided(&mut state, "guarded", &format!("fallback to `x{i}`"));
    }
    let fallback = &state.tree.items[3];
    assert_eq!(fallback.decisions.len(), DECISIONS_KEPT);
    assert_eq!(fallback.told as usize, DECISIONS_KEPT + 3);
    assert_eq!(fallback.fallbacks as usize, DECISIONS_KEPT + 3);
    assert_eq!(
        fallback.decisions.back().unwrap().text,
        format!("fallback to `x{}`", DECISIONS_KEPT + 2)
    );
}

#[test]
fn the_run_ends_what_still_runs_and_the_root() {
    let mut state = planned();
    started(&mut state, "creep");
    state.apply(&event(EventKind::RunEnded {
        outcome: Outcome::Failed,
        reason: "no stand-in".into(),
        run_ms: 9_000,
        status: 0,
        flags: vec![],
    }));
    let tree = &state.tree;
    assert!(running(tree).is_empty());
    assert_eq!(end(tree, 12), Some(NodeEnd::Failed));
    assert_eq!(end(tree, 0), Some(NodeEnd::Failed));
}

#[test]
fn a_stream_without_a_plan_has_no_tree_and_a_new_run_forgets_the_old_one() {
    let mut state = MonitorState::default();
    state.apply(&event(EventKind::RunStarted {
        mission: "old".into(),
        actions: vec![],
        success: vec![],
    }));
    started(&mut state, "find-wall");
    assert!(state.tree.items.is_empty());
    assert_eq!(state.tree.plan, 0);
    assert_eq!(state.mission.actions.len(), 1, "the task tree still has it");
    let mut state = planned();
    state.apply(&event(EventKind::RunStarted {
        mission: "again".into(),
        actions: vec![],
        success: vec![],
    }));
    assert!(state.tree.items.is_empty());
    state.apply(&event(EventKind::ControlPlan { items: plan() }));
    assert_eq!(state.tree.plan, 2, "a new plan: the page draws it anew");
}

#[test]
fn the_tree_serializes_for_the_page_without_its_defaults() {
    let mut state = planned();
    started(&mut state, "find-wall");
    decided(&mut state, "timeout(guarded)", "timeout after 40.0 s");
    let json = serde_json::to_value(&state).unwrap();
    let nodes = json["tree"]["items"].as_array().unwrap();
    assert_eq!(nodes.len(), 16);
    assert_eq!(json["tree"]["plan"], 1);
    assert_eq!(
        nodes[5],
        serde_json::json!({
            "id": 5, "parent": 4, "depth": 5, "kind": "action", "label": "find-wall",
            "detail": "ultrasonic, wall-finder", "running": true, "starts": 1
        })
    );
    assert_eq!(nodes[2]["timeouts"], 1);
    assert_eq!(nodes[2]["decisions"][0]["text"], "timeout after 40.0 s");
    assert_eq!(nodes[2]["decisions"][0]["run_ms"], 5_000);
    assert_eq!(
        nodes[15],
        serde_json::json!({
            "id": 15, "parent": 13, "depth": 2, "kind": "action", "label": "listen",
            "detail": "microphone"
        })
    );
    assert!(nodes[0].get("parent").is_none());
}

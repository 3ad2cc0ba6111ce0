//! The mission as a task tree: each action's condition flags, operations and state, and the
//! status word by name — what the page's tree panel draws.
//!
//! The tree comes from [`EventKind::RunStarted`]'s plan; a stream without one (an older
//! file, a monitor that joined mid-run) still shows every action it sees start.

use marie_vocabulary::events::{ActionPlan, EventKind, OpStarted};
use marie_vocabulary::run::{OpEnd, Outcome};
use serde::Serialize;

/// Where an action is in its run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionState {
    /// Not started yet (its condition may not hold yet).
    Waiting,
    /// Started: its operations are active.
    Running,
    /// Ended, and the run went on.
    Succeeded,
    /// The run came to a full stop while it ran.
    Failed,
}

/// One operation of an action, and how its part went.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OpView {
    /// The operation as the action names it (name or id).
    pub key: String,
    /// Operation name.
    pub name: String,
    /// How its part ended (`running` while the action runs; absent before it starts).
    pub ended: Option<OpEnd>,
    /// The mission's flags it raised.
    pub flags: Vec<String>,
    /// The instance that ran it (actor address), once started.
    pub address: Option<String>,
}

/// One action of the mission.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActionView {
    /// Action name.
    pub name: String,
    /// Its condition flags, by name.
    pub when: Vec<String>,
    /// The keys of the operations that end it.
    pub ends_on: Vec<String>,
    /// Its operations.
    pub ops: Vec<OpView>,
    /// Where it is.
    pub state: ActionState,
    /// When it started and ended, in ms since the run began.
    pub started_ms: Option<u64>,
    /// When it ended, in ms since the run began.
    pub ended_ms: Option<u64>,
}

/// The mission's run: name, task tree, flags, outcome.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MissionView {
    /// Mission name (empty before a run starts).
    pub name: String,
    /// The actions, in the mission's order.
    pub actions: Vec<ActionView>,
    /// The flags that must all be set for it to succeed.
    pub success: Vec<String>,
    /// The status word, by name, as of the latest action end.
    pub flags: Vec<String>,
    /// The verdict, once the run ended (a robot's judgement replaces the dispatcher's).
    pub outcome: Option<OutcomeView>,
}

/// How the run ended.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OutcomeView {
    /// `succeeded` or `failed`.
    pub outcome: Outcome,
    /// Why it failed (empty on success).
    pub reason: String,
    /// The run's duration, ms.
    pub run_ms: Option<u64>,
    /// The world's verdict, when a robot judged the run.
    pub judgement: Option<String>,
    /// The cart's final pose `[x, y, heading]`, when judged.
    pub final_pose: Option<[f64; 3]>,
    /// Collisions counted, when judged.
    pub collisions: Option<u64>,
}

impl MissionView {
    /// Take the run's and its actions' events into the task tree; others pass by.
    pub fn apply(&mut self, kind: &EventKind) {
        match kind {
            EventKind::RunStarted {
                mission,
                actions,
                success,
            } => self.started(mission, actions, success),
            EventKind::ActionStarted {
                action,
                run_ms,
                operations,
            } => self.action_started(action, *run_ms, operations),
            EventKind::OpEnded {
                action,
                key,
                ended,
                flags,
            } => self.op_ended(action, key, *ended, flags),
            EventKind::ActionEnded {
                action,
                run_ms,
                flags,
                ..
            } => self.action_ended(action, *run_ms, flags),
            EventKind::RunEnded {
                outcome,
                reason,
                run_ms,
                flags,
                ..
            } => self.run_ended(*outcome, reason, *run_ms, flags),
            EventKind::Judged {
                outcome,
                reason,
                robot,
            } => {
                // what marie's simulated robot says of a run, by its documented keys
                // (another robot's may lack them)
                let key = |k: &str| robot.get(k).cloned().unwrap_or_default();
                let judgement: Option<String> =
                    serde_json::from_value(key("judgement")).ok().flatten();
                self.judged(
                    *outcome,
                    reason,
                    judgement.as_deref(),
                    serde_json::from_value(key("final_pose")).ok().flatten(),
                    serde_json::from_value(key("collisions")).ok().flatten(),
                );
            }
            _ => {}
        }
    }

    /// A run of `mission` begins: the tree from its plan, every action waiting.
    pub fn started(&mut self, mission: &str, plan: &[ActionPlan], success: &[String]) {
        *self = MissionView {
            name: mission.to_string(),
            success: success.to_vec(),
            actions: plan
                .iter()
                .map(|a| ActionView {
                    name: a.name.clone(),
                    when: a.when.clone(),
                    ends_on: a.ends_on.clone(),
                    ops: a
                        .ops
                        .iter()
                        .map(|name| OpView {
                            key: name.clone(),
                            name: name.clone(),
                            ended: None,
                            flags: Vec::new(),
                            address: None,
                        })
                        .collect(),
                    state: ActionState::Waiting,
                    started_ms: None,
                    ended_ms: None,
                })
                .collect(),
            ..MissionView::default()
        };
    }

    /// The action named `name`, added at the end when the plan did not have it.
    fn action(&mut self, name: &str) -> &mut ActionView {
        let i = match self.actions.iter().position(|a| a.name == name) {
            Some(i) => i,
            None => {
                self.actions.push(ActionView {
                    name: name.to_string(),
                    when: Vec::new(),
                    ends_on: Vec::new(),
                    ops: Vec::new(),
                    state: ActionState::Waiting,
                    started_ms: None,
                    ended_ms: None,
                });
                self.actions.len() - 1
            }
        };
        &mut self.actions[i]
    }

    /// An action started with these instances.
    pub fn action_started(&mut self, name: &str, run_ms: u64, ops: &[OpStarted]) {
        let action = self.action(name);
        action.state = ActionState::Running;
        action.started_ms = Some(run_ms);
        for op in ops {
            let view = match action
                .ops
                .iter_mut()
                .position(|o| o.key == op.key || o.name == op.name)
            {
                Some(i) => &mut action.ops[i],
                None => {
                    action.ops.push(OpView {
                        key: op.key.clone(),
                        name: op.name.clone(),
                        ended: None,
                        flags: Vec::new(),
                        address: None,
                    });
                    action.ops.last_mut().expect("just pushed")
                }
            };
            view.key = op.key.clone();
            view.name = op.name.clone();
            view.ended = Some(OpEnd::Running);
            view.address = Some(op.address.clone());
        }
    }

    /// An operation's part in an action ended.
    pub fn op_ended(&mut self, action: &str, key: &str, ended: OpEnd, flags: &[String]) {
        let action = self.action(action);
        if let Some(op) = action
            .ops
            .iter_mut()
            .find(|o| o.key == key || o.name == key)
        {
            op.ended = Some(ended);
            op.flags = flags.to_vec();
        }
    }

    /// An action ended; the run goes on.
    pub fn action_ended(&mut self, name: &str, run_ms: u64, flags: &[String]) {
        let action = self.action(name);
        action.state = ActionState::Succeeded;
        action.ended_ms = Some(run_ms);
        self.flags = flags.to_vec();
    }

    /// The run ended: a failure fails the action that was running.
    pub fn run_ended(&mut self, outcome: Outcome, reason: &str, run_ms: u64, flags: &[String]) {
        if outcome == Outcome::Failed {
            for a in &mut self.actions {
                if a.state == ActionState::Running {
                    a.state = ActionState::Failed;
                    a.ended_ms = Some(run_ms);
                }
            }
        }
        self.flags = flags.to_vec();
        self.outcome = Some(OutcomeView {
            outcome,
            reason: reason.to_string(),
            run_ms: Some(run_ms),
            judgement: None,
            final_pose: None,
            collisions: None,
        });
    }

    /// The world judged the run: its verdict replaces the dispatcher's.
    pub fn judged(
        &mut self,
        outcome: Outcome,
        reason: &str,
        judgement: Option<&str>,
        final_pose: Option<[f64; 3]>,
        collisions: Option<u64>,
    ) {
        let run_ms = self.outcome.as_ref().and_then(|o| o.run_ms);
        self.outcome = Some(OutcomeView {
            outcome,
            reason: reason.to_string(),
            run_ms,
            judgement: judgement.map(str::to_string),
            final_pose,
            collisions,
        });
    }
}

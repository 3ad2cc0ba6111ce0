//! Every event as a line of Foxglove's Log panel (`foxglove.Log` on `/events`): when, how
//! grave, a readable one-line text, and the node that published it.
//!
//! The levels: ERROR for what ends or breaks a run (a failed run or judgement, a rebind
//! or a supervisor that gave up, records a datamanager lost); WARNING for faults and what
//! they cause (an injection, a loss, a child's exit other than a normal one, a restart, a
//! node lost or frozen, a failed action or operation, a collision); DEBUG for the
//! high-rate telemetry (poses ten times a second, echoes, datamanager acknowledgements),
//! so that the panel's INFO filter shows the run's story; INFO for the rest.
//!
//! A kind not named here (a new one) is written as its `type` and its fields as compact
//! JSON, cut at [`GENERIC_LIMIT`] characters: every event reaches the log, readable or not.

use super::schemas::{Log, Time};
use marie::events::{ActionResult, Event, EventKind};
use marie::run::{OpEnd, Outcome};
use serde_json::Value;

/// `foxglove.LogLevel` DEBUG.
pub(crate) const DEBUG: u8 = 1;
/// INFO.
pub(crate) const INFO: u8 = 2;
/// WARNING.
pub(crate) const WARNING: u8 = 3;
/// ERROR.
pub(crate) const ERROR: u8 = 4;

/// A generic line (a kind without its own text) is cut to this many characters.
pub(crate) const GENERIC_LIMIT: usize = 300;

/// `event` as a log line.
pub(crate) fn log(event: &Event) -> Log {
    Log {
        timestamp: Time::from_ms(event.at_ms),
        level: level(&event.kind),
        message: text(&event.kind),
        name: event.node.clone(),
        file: "",
        line: 0,
    }
}

/// How grave `kind` is (see the module docs).
pub(crate) fn level(kind: &EventKind) -> u8 {
    match kind {
        EventKind::RunEnded { outcome, .. } | EventKind::Judged { outcome, .. } => match outcome {
            Outcome::Succeeded => INFO,
            Outcome::Failed => ERROR,
        },
        EventKind::RebindGaveUp { .. } | EventKind::SupervisorGaveUp { .. } => ERROR,
        EventKind::DmChecked(check) if check.lost > 0 || check.error.is_some() => ERROR,
        EventKind::ActionEnded {
            result: Some(ActionResult::Failed),
            ..
        } => WARNING,
        EventKind::OpEnded {
            ended: OpEnd::Failed | OpEnd::Lost | OpEnd::Unresponsive,
            ..
        } => WARNING,
        EventKind::FaultInjected { .. }
        | EventKind::FaultNotInjected { .. }
        | EventKind::Lost { .. }
        | EventKind::ChildRestarted { .. }
        | EventKind::Takeover { .. }
        | EventKind::DispatcherFenced { .. }
        | EventKind::NodeLost { .. }
        | EventKind::NodeDown { .. }
        | EventKind::NodeFrozen { .. }
        | EventKind::NodeRefused { .. }
        | EventKind::ConnectionRefused { .. }
        | EventKind::DmFenced { .. } => WARNING,
        EventKind::DmRecovered { torn: Some(_), .. } => WARNING,
        EventKind::ChildExited { reason, .. } if reason != "normal" => WARNING,
        EventKind::DmAcked { .. } | EventKind::DmDeleted { .. } | EventKind::DmState { .. } => {
            DEBUG
        }
        EventKind::Robot { what, .. } => match what.as_str() {
            "pose" | "echoes" => DEBUG,
            "collision" => WARNING,
            _ => INFO,
        },
        _ => INFO,
    }
}

/// `kind` in words, on one line.
pub(crate) fn text(kind: &EventKind) -> String {
    match kind {
        EventKind::RunStarted {
            mission,
            actions,
            success,
        } => {
            let mut t = format!("mission `{mission}` started");
            if !actions.is_empty() {
                t += &format!(" ({} actions)", actions.len());
            }
            if !success.is_empty() {
                t += &format!(", succeeds with [{}]", success.join(", "));
            }
            t
        }
        EventKind::Bound { operations } => {
            let ops: Vec<String> = operations
                .iter()
                .map(|o| format!("{} v{} on {} ({})", o.name, o.version, o.node, o.address))
                .collect();
            format!("bound {}", ops.join(", "))
        }
        EventKind::ActionStarted {
            action, operations, ..
        } => {
            let keys: Vec<&str> = operations.iter().map(|o| o.key.as_str()).collect();
            format!("action `{action}` started: {}", keys.join(", "))
        }
        EventKind::OpEnded {
            action,
            key,
            ended,
            flags,
        } => format!(
            "{key} of action `{action}` ended {ended}{}",
            listed(" raising", flags)
        ),
        EventKind::ActionEnded {
            action,
            flags,
            status,
            result,
            ..
        } => {
            let how = result.map_or("ended", ActionResult::name);
            format!(
                "action `{action}` {how}, status {status:#010x}{}",
                listed("", flags)
            )
        }
        EventKind::ControlPlan { nodes } => {
            let actions = nodes.iter().filter(|n| n.kind == "action").count();
            format!(
                "the mission's tree: {} nodes, {actions} actions",
                nodes.len()
            )
        }
        EventKind::Control { node, decision, .. } => format!("{node}: {decision}"),
        EventKind::RunEnded {
            outcome,
            reason,
            run_ms,
            flags,
            ..
        } => format!(
            "run {} after {:.1} s{}{}",
            outcome_word(*outcome),
            *run_ms as f64 / 1000.0,
            because(reason),
            listed("", flags)
        ),
        EventKind::Judged {
            outcome,
            reason,
            robot,
        } => {
            let said = robot
                .get("judgement")
                .and_then(Value::as_str)
                .map(|j| format!(" — {j}"))
                .unwrap_or_default();
            format!("judged: {}{}{said}", outcome_word(*outcome), because(reason))
        }
        EventKind::Lost { operation, cause } => format!("{operation} lost: {cause}"),
        EventKind::Rebound(r) => format!(
            "{} rebound: {} on {} -> {} on {} after {} ms",
            r.operation, r.from, r.from_node, r.to, r.to_node, r.downtime_ms
        ),
        EventKind::RebindGaveUp {
            operation,
            cause,
            waited_ms,
        } => format!("no stand-in for {operation} ({cause}) within {waited_ms} ms: full stop"),
        EventKind::Takeover {
            from,
            to,
            term,
            gap_ms,
            ..
        } => format!("the run taken over by {to} from {from} (term {term}, {gap_ms} ms)"),
        EventKind::DispatcherFenced { term, newer, .. } => {
            format!("the dispatcher of term {term} fenced off by term {newer}")
        }
        EventKind::Joined(m) => format!(
            "{} {} ({}) joined at {} on {}",
            m.module, m.name, m.id, m.address, m.node
        ),
        EventKind::Left(m) => format!(
            "{} {} ({}) left from {} on {}",
            m.module, m.name, m.id, m.address, m.node
        ),
        EventKind::ChildStarted {
            supervisor,
            child,
            actor,
        } => format!("{supervisor} started {child} ({actor})"),
        EventKind::ChildExited {
            supervisor,
            child,
            reason,
        } => format!("{child} exited under {supervisor}: {reason}"),
        EventKind::ChildRestarted {
            supervisor,
            child,
            actor,
            restarts,
            reason,
        } => format!("{supervisor} restarted {child} as {actor} (restart {restarts}): {reason}"),
        EventKind::SupervisorGaveUp { supervisor, reason } => {
            format!("supervisor {supervisor} gave up: {reason}")
        }
        EventKind::FaultInjected {
            fault,
            operation,
            actor,
            ..
        } => format!("{fault} injected into {operation} ({actor})"),
        EventKind::FaultHealed { fault, operation } => format!("{fault} of {operation} healed"),
        EventKind::FaultNotInjected {
            fault,
            operation,
            why,
            ..
        } => format!("{fault} not injected into {operation}: {why}"),
        EventKind::NodeUp { peer, address } => format!("node {peer} up ({address})"),
        EventKind::NodeLost { peer, address } => format!("node {peer} lost ({address})"),
        EventKind::NodeDown { peer, silent_ms } => {
            format!("node {peer} declared down (silent {silent_ms} ms)")
        }
        EventKind::NodeFrozen { silent_ms } => {
            format!("this node was frozen {silent_ms} ms: it restarts its operations")
        }
        EventKind::NodeRefused { peer, theirs, ours } => {
            format!("node {peer} refused: protocol {theirs}, ours {ours}")
        }
        EventKind::ConnectionRefused { from, reason } => {
            format!("a connection from {from} refused: {reason}")
        }
        EventKind::Selected { choice } => match choice.chosen() {
            Some(c) => format!(
                "{}: chose {} (v{} on {}) of {} candidates",
                choice.operation,
                c.address,
                c.version,
                c.node,
                choice.candidates.len()
            ),
            None => format!(
                "{}: none of {} candidates fits",
                choice.operation,
                choice.candidates.len()
            ),
        },
        EventKind::DmRecovered {
            dm,
            records,
            bytes,
            ms,
            torn,
            ..
        } => format!(
            "datamanager {dm} read its journal back: {records} records ({bytes} bytes) in {ms} ms{}",
            torn.as_ref()
                .map(|why| format!(", up to a torn end ({why})"))
                .unwrap_or_default()
        ),
        EventKind::DmPromoted { dm, node, term } => {
            format!("datamanager {dm}: the copy on {node} is the primary now (term {term})")
        }
        EventKind::DmFenced {
            dm,
            node,
            term,
            why,
        } => format!("datamanager {dm}: the primary on {node} (term {term}) stepped down: {why}"),
        EventKind::DmChecked(check) => match &check.error {
            None => format!(
                "datamanager {}: {} acknowledged records, {} held, {} lost",
                check.dm, check.acknowledged, check.held, check.lost
            ),
            Some(why) => format!(
                "datamanager {}: could not be checked ({why}): {} acknowledged records count lost",
                check.dm, check.acknowledged
            ),
        },
        EventKind::Robot { what, data } => robot_text(what, data),
        other => generic(other),
    }
}

/// A robot's event in words: its contract's (`marie_missions::telemetry`) by their
/// fields, any other as its name and data.
fn robot_text(what: &str, data: &Value) -> String {
    let num = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    let point = |v: &Value| format!("({:.2}, {:.2})", num(&v[0]), num(&v[1]));
    let count = |key: &str| data[key].as_array().map_or(0, Vec::len);
    match what {
        "world" => format!(
            "world: {} walls{}{}",
            count("walls"),
            if data["dock"].is_array() {
                ", a dock"
            } else {
                ""
            },
            if data["goal"].is_array() {
                ", a goal"
            } else {
                ""
            },
        ),
        "pose" => format!(
            "pose ({:.2}, {:.2}) heading {:.1}°",
            num(&data["x"]),
            num(&data["y"]),
            num(&data["heading"]).to_degrees()
        ),
        "echoes" => format!("{} sonar echoes", count("points")),
        "followed-wall" => format!(
            "following the wall from {} to {}",
            point(&data["from"]),
            point(&data["to"])
        ),
        "dock-found" => {
            let corners: Vec<String> = data["corners"]
                .as_array()
                .into_iter()
                .flatten()
                .map(point)
                .collect();
            format!("dock found: {}", corners.join(" "))
        }
        "planned-path" => {
            let end = data["points"]
                .as_array()
                .and_then(|p| p.last())
                .map(|p| format!(" to {}", point(p)))
                .unwrap_or_default();
            format!("planned a path of {} points{end}", count("points"))
        }
        "collision" => format!("collision at {}", point(&json_pair(data))),
        _ => cut(format!("robot {what}: {data}")),
    }
}

/// `{"x":..,"y":..}` as `[x, y]`.
fn json_pair(data: &Value) -> Value {
    Value::Array(vec![data["x"].clone(), data["y"].clone()])
}

/// A kind without its own text: its `type` and its other fields as JSON.
fn generic(kind: &EventKind) -> String {
    match serde_json::to_value(kind) {
        Ok(Value::Object(mut fields)) => {
            let kind = fields
                .remove("type")
                .and_then(|t| t.as_str().map(str::to_string))
                .unwrap_or_else(|| "event".to_string());
            cut(format!("{kind} {}", Value::Object(fields)))
        }
        Ok(other) => cut(other.to_string()),
        Err(e) => format!("an event that cannot be written as JSON: {e}"),
    }
}

/// `text` cut to [`GENERIC_LIMIT`] characters.
fn cut(text: String) -> String {
    match text.char_indices().nth(GENERIC_LIMIT) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text,
    }
}

fn outcome_word(outcome: Outcome) -> &'static str {
    match outcome {
        Outcome::Succeeded => "succeeded",
        Outcome::Failed => "FAILED",
    }
}

fn because(reason: &str) -> String {
    match reason.is_empty() {
        true => String::new(),
        false => format!(": {reason}"),
    }
}

fn listed(before: &str, flags: &[String]) -> String {
    match flags.is_empty() {
        true => String::new(),
        false => format!("{before} [{}]", flags.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The module docs' example line of each kind.
    const LINES: &str = r#"{"at_ms":1260,"node":"n","kind":{"type":"action_started","action":"follow","run_ms":60,"operations":[{"key":"wall-follower","name":"wall-follower","id":1512,"version":"1.0.0","node":"n","address":"0.41"}]}}
{"at_ms":9810,"node":"n","kind":{"type":"action_ended","action":"follow","run_ms":8610,"flags":["dock_found"],"status":4,"result":"failed"}}
{"at_ms":30000,"node":"n","kind":{"type":"run_ended","outcome":"failed","reason":"no dock","run_ms":28800,"status":12,"flags":[]}}
{"at_ms":5000,"node":"n","kind":{"type":"fault_injected","fault":"kill","operation":"wall-follower","actor":"0.41","node":"n","due_ms":3800}}
{"at_ms":4100,"node":"n","kind":{"type":"dm_acked","dm":"world","source":"wall-sensor","class":"wall","seq":212,"digest":1311768467463790320}}
{"at_ms":20,"node":"n","kind":{"type":"robot","what":"pose","data":{"heading":3.14,"x":12.5,"y":1.5}}}
{"at_ms":4000,"node":"n","kind":{"type":"robot","what":"collision","data":{"x":1.0,"y":2.0}}}"#;

    #[test]
    fn events_read_as_lines_at_their_level() {
        let logs: Vec<Log> = LINES
            .lines()
            .map(|l| log(&Event::from_json_line(l).unwrap()))
            .collect();
        let got: Vec<(u8, &str)> = logs.iter().map(|l| (l.level, l.message.as_str())).collect();
        assert_eq!(
            got,
            [
                (INFO, "action `follow` started: wall-follower"),
                (WARNING, "action `follow` failed, status 0x00000004 [dock_found]"),
                (ERROR, "run FAILED after 28.8 s: no dock"),
                (WARNING, "kill injected into wall-follower (0.41)"),
                (
                    DEBUG,
                    "dm_acked {\"class\":\"wall\",\"digest\":1311768467463790320,\"dm\":\"world\",\"seq\":212,\"source\":\"wall-sensor\"}"
                ),
                (DEBUG, "pose (12.50, 1.50) heading 179.9°"),
                (WARNING, "collision at (1.00, 2.00)"),
            ]
        );
        assert_eq!(logs[0].name, "n");
        assert_eq!(logs[2].timestamp, Time { sec: 30, nsec: 0 });
    }

    #[test]
    fn a_long_generic_line_is_cut() {
        let long = "x".repeat(1000);
        assert_eq!(cut(long).chars().count(), GENERIC_LIMIT + 1);
        assert_eq!(cut("short".into()), "short");
    }
}

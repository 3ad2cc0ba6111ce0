//! Every event in words, worded here once: the live lines of `marie run`, the log of a run
//! written as MCAP and the monitor's timeline all tell an event with a [`Teller`], so an
//! event reads the same wherever a person meets it.
//!
//! A reader chooses *which* events it shows (the live lines leave out the datamanagers'
//! acknowledgements, the timeline the robot's poses) and *how* (a line on stdout with its
//! [`Mark`], a log entry at its [`Gravity`], a row of the page); what an event *says* is
//! [`Teller::tell`]'s.
//!
//! Why a teller and not a method of [`EventKind`]: a few words depend on the run so far —
//! a time is said in seconds since the run began (a fault, a takeover), and a binding
//! says where the operation was bound before — so the teller follows the stream it is
//! told. And the robot's own events ([`EventKind::Robot`]) are worded by the robot's
//! contract, which this crate does not know: a reader that knows it hands the teller its
//! words ([`Teller::with_robot_words`]).

use super::{ActionResult, Event, EventKind, Family};
use crate::run::{DmCheck, Outcome};
use crate::status::StatusFlags;
use serde_json::Value;
use std::collections::BTreeMap;

/// How grave an event is for a person following a run: what ends or breaks a run is an
/// [`Error`](Gravity::Error), faults and what they cause a [`Warning`](Gravity::Warning),
/// high-rate telemetry a [`Detail`](Gravity::Detail) (poses ten times a second,
/// acknowledgements), the rest — the run's story — [`Info`](Gravity::Info).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Gravity {
    /// High-rate telemetry, shown on demand.
    Detail,
    /// The run's story.
    Info,
    /// A fault or what a fault caused.
    Warning,
    /// What ends or breaks a run.
    Error,
}

/// The sign a line of `marie run` starts with, by what the event is about:
///
/// | mark | events |
/// |---|---|
/// | `>` | an action started |
/// | `<` | an action ended |
/// | `?` | a decision: a control decision of the mission's tree, an instance chosen |
/// | `!` | a loss: an operation lost, no stand-in, records lost, a supervisor gave up |
/// | `~` | a rebind |
/// | `*` | a fault injected, healed, or not injected |
/// | `#` | the dispatcher: a takeover, a dispatcher fenced off |
/// | ` ` | a binding (indented under what caused it) |
/// | `=` | the run: provenance, start, end, judgement, its tree, an operation's part, parameters |
/// | `+`, `-` | a module joined, left the location table |
/// | `^` | a supervisor's child started, exited, restarted |
/// | `@` | the cluster: a node up, lost, down, frozen, refused |
/// | `%` | a datamanager |
/// | `.` | the robot |
pub type Mark = char;

/// An event told: its sign, its text (one line; a binding of several operations is one
/// line per operation that moved), how grave it is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Words {
    /// The sign of its line (see [`Mark`]).
    pub mark: Mark,
    /// What it says.
    pub text: String,
    /// False when it only repeats what was told before: a binding that moved no operation
    /// (a takeover binds again where the run was). A reader of the run's story may skip it.
    pub news: bool,
    /// How grave it is.
    pub gravity: Gravity,
}

/// A robot's words for its own event (`what`, `data`) and how grave it is, or `None` for
/// one it does not know.
pub type RobotWords = fn(what: &str, data: &Value) -> Option<(String, Gravity)>;

/// Tells a run's events in words, one after another in the order they were published.
///
/// ```
/// use marie_vocabulary::events::{Event, EventKind, Gravity, Teller};
/// let mut teller = Teller::default();
/// let at = |at_ms, kind| Event { at_ms, node: "n".into(), kind };
/// teller.tell(&at(1000, EventKind::RunStarted { mission: "m".into(), actions: vec![], success: vec![] }));
/// let lost = EventKind::Lost {
///     operation: "wall-follower".into(),
///     cause: marie_vocabulary::run::LossCause::Gone,
/// };
/// let words = teller.tell(&at(4000, lost));
/// assert_eq!((words.mark, words.gravity), ('!', Gravity::Warning));
/// assert!(words.text.starts_with("wall-follower lost: "), "{}", words.text);
/// ```
#[derive(Clone, Debug, Default)]
pub struct Teller {
    /// The stamp of the run's `run_started`: times are told in seconds since.
    start_ms: Option<u64>,
    /// Where each operation was bound, as told (a takeover's bindings tell only what moved).
    bound: BTreeMap<String, String>,
    robot: Option<RobotWords>,
}

impl Teller {
    /// A teller that words the robot's events with `words` (those it does not know are told
    /// by their name and data).
    pub fn with_robot_words(mut self, words: RobotWords) -> Teller {
        self.robot = Some(words);
        self
    }

    /// Follow the run through `event` without wording it: a reader that shows only some
    /// events [`tell`](Self::tell)s those and heeds the rest, so that it formats no text it
    /// throws away (poses ten times a second, every acknowledgement) and its words still know
    /// when the run began and where each operation was bound.
    pub fn heed(&mut self, event: &Event) {
        match &event.kind {
            EventKind::RunStarted { .. } => self.start_ms = Some(event.at_ms),
            EventKind::Bound { operations } => {
                for op in operations {
                    self.bound.insert(op.name.clone(), op.node.clone());
                }
            }
            _ => {}
        }
    }

    /// `event` in words. Tell (or [`heed`](Self::heed)) every event of a stream, in order:
    /// the teller follows the run.
    pub fn tell(&mut self, event: &Event) -> Words {
        let kind = &event.kind;
        if let EventKind::RunStarted { .. } = kind {
            self.start_ms = Some(event.at_ms);
        }
        if let EventKind::Robot { what, data } = kind {
            let (text, gravity) = self
                .robot
                .and_then(|words| words(what, data))
                .unwrap_or_else(|| (cut(format!("robot {what}: {data}")), Gravity::Info));
            return Words {
                mark: mark(kind),
                text,
                news: true,
                gravity,
            };
        }
        let (text, news) = match kind {
            EventKind::Bound { operations } => self.bound(operations),
            _ => (self.text(event), true),
        };
        Words {
            mark: mark(kind),
            text,
            news,
            gravity: gravity(kind),
        }
    }

    /// A binding: a line per operation bound for the first time or elsewhere than before,
    /// or — when none moved — where they all are, which is no news.
    fn bound(&mut self, operations: &[super::BoundOp]) -> (String, bool) {
        let mut lines = Vec::new();
        for op in operations {
            match self.bound.insert(op.name.clone(), op.node.clone()) {
                None => lines.push(format!("bound {} v{} on {}", op.name, op.version, op.node)),
                Some(before) if before != op.node => lines.push(format!(
                    "bound {} v{} on {} (was on {before})",
                    op.name, op.version, op.node
                )),
                Some(_) => {}
            }
        }
        if lines.is_empty() {
            let all: Vec<String> = operations
                .iter()
                .map(|op| format!("{} v{} on {}", op.name, op.version, op.node))
                .collect();
            return (format!("bound as before: {}", all.join(", ")), false);
        }
        (lines.join("\n"), true)
    }

    /// Seconds of the run at `at_ms`.
    fn run_secs(&self, at_ms: u64) -> f64 {
        at_ms.saturating_sub(self.start_ms.unwrap_or(at_ms)) as f64 / 1000.0
    }

    fn text(&mut self, event: &Event) -> String {
        let node = event.node.as_str();
        match &event.kind {
            EventKind::Takeover {
                from,
                to,
                term,
                gap_ms,
                ..
            } => format!(
                "the run taken over by {to} from {from} at {:.1}s (term {term}, claimed \
                 {gap_ms} ms after the loss was noticed)",
                self.run_secs(event.at_ms)
            ),
            EventKind::FaultInjected {
                fault,
                operation,
                actor,
                lasting_ms,
                ..
            } => {
                let lasting = lasting_ms
                    .map(|ms| format!(" for {:.1} s", ms as f64 / 1000.0))
                    .unwrap_or_default();
                format!(
                    "injected {fault} into {operation} ({actor}){lasting} at {:.1}s",
                    self.run_secs(event.at_ms)
                )
            }
            EventKind::FaultNotInjected {
                fault,
                operation,
                why,
                due_ms,
            } => {
                let at = due_ms.map_or(self.run_secs(event.at_ms), |d| d as f64 / 1000.0);
                format!("could not inject {fault} into {operation} at {at:.1}s: {why}")
            }
            kind => said(node, kind),
        }
    }
}

/// The words of the kinds that need nothing of the run so far, by family; `node` is the
/// node that published the event.
fn said(node: &str, kind: &EventKind) -> String {
    match kind.family() {
        Family::Run => run(kind),
        Family::Action => action(kind),
        Family::Binding => binding(kind),
        Family::Dispatcher => dispatcher(node, kind),
        Family::Registry => registry(kind),
        Family::Supervisor => supervisor(kind),
        Family::Fault => fault(kind),
        Family::Node => cluster(node, kind),
        Family::Datamanager => datamanager(node, kind),
        Family::Robot => generic(kind),
    }
}

/// What runs, a run's start, end and judgement.
fn run(kind: &EventKind) -> String {
    match kind {
        EventKind::Provenance(p) => {
            let files: Vec<String> = p
                .files
                .iter()
                .map(|f| format!("{} {}", f.role, f.path))
                .collect();
            let build = p
                .marie
                .as_ref()
                .map_or_else(|| "marie of unknown build".into(), |b| format!("marie {b}"));
            format!("{build}; {}", files.join(", "))
        }
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
            format!(
                "judged: {}{}{said}",
                outcome_word(*outcome),
                because(reason)
            )
        }
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// Actions, their operations' parts and parameters, the tree and its decisions.
fn action(kind: &EventKind) -> String {
    match kind {
        EventKind::Reparameterized {
            operation, values, ..
        } => {
            let values: Vec<String> = values
                .iter()
                .map(|v| format!("{} = {}", v.name, v.value))
                .collect();
            format!("`{operation}` parameters set: {}", values.join(", "))
        }
        EventKind::ActionStarted {
            action, operations, ..
        } => {
            let keys: Vec<&str> = operations.iter().map(|o| o.key.as_str()).collect();
            format!("{action}: start [{}]", keys.join(", "))
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
            // a success is the action's plain end
            let how = result
                .filter(|r| *r != ActionResult::Succeeded)
                .map_or("end", ActionResult::name);
            format!(
                "{action}: {how}, status {} [{}]",
                StatusFlags(*status),
                flags.join(", ")
            )
        }
        EventKind::ControlPlan { items: nodes } => {
            let actions = nodes.iter().filter(|n| n.kind == "action").count();
            format!(
                "the mission's tree: {} items, {actions} actions",
                nodes.len()
            )
        }
        EventKind::Control {
            item,
            decision,
            run_ms,
        } => format!("{item}: {decision} at {:.1}s", *run_ms as f64 / 1000.0),
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// Choices, losses and rebinds (a binding is the teller's: it tells what moved).
fn binding(kind: &EventKind) -> String {
    match kind {
        EventKind::Lost { operation, cause } => format!("{operation} lost: {cause}"),
        EventKind::Rebound(r) if !r.from_node.is_empty() && r.from_node != r.to_node => format!(
            "{} rebound: {} on {} -> {} on {} after {} ms",
            r.operation, r.from, r.from_node, r.to, r.to_node, r.downtime_ms
        ),
        EventKind::Rebound(r) => format!(
            "{} rebound: {} -> {} after {} ms",
            r.operation, r.from, r.to, r.downtime_ms
        ),
        EventKind::BindingUpgraded(u) => format!(
            "{} upgraded at `{}`: v{} {} on {} -> v{} {} on {}",
            u.operation,
            u.action,
            u.from_version,
            u.from,
            u.from_node,
            u.to_version,
            u.to,
            u.to_node
        ),
        EventKind::BindingRolledBack(r) => format!(
            "{} rolled back at `{}`: v{} {} on {} -> v{} {} on {}: {}",
            r.operation,
            r.action,
            r.from_version,
            r.from,
            r.from_node,
            r.to_version,
            r.to,
            r.to_node,
            r.reason
        ),
        EventKind::BindingUpgradeRefused {
            operation,
            address,
            version,
            node,
            reason,
        } => format!("{operation} stays: not moving to v{version} {address} on {node}: {reason}"),
        EventKind::RebindGaveUp {
            operation,
            cause,
            waited_ms,
        } => format!("no stand-in for {operation} ({cause}) within {waited_ms} ms: full stop"),
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
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// A dispatcher fenced off (a takeover is the teller's: it is told in run time).
fn dispatcher(node: &str, kind: &EventKind) -> String {
    match kind {
        EventKind::DispatcherFenced { term, newer, .. } => {
            format!("the dispatcher on {node} (term {term}) fenced off by term {newer}")
        }
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// The location table's comings and goings.
fn registry(kind: &EventKind) -> String {
    match kind {
        EventKind::Joined(m) => format!(
            "{} {} ({}) joined at {} on {}",
            m.module, m.name, m.id, m.address, m.node
        ),
        EventKind::Left(m) => format!(
            "{} {} ({}) left from {} on {}",
            m.module, m.name, m.id, m.address, m.node
        ),
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// Supervisors and their children.
fn supervisor(kind: &EventKind) -> String {
    match kind {
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
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// A fault healed (one injected or not is the teller's: told in run time).
fn fault(kind: &EventKind) -> String {
    match kind {
        EventKind::FaultHealed { fault, operation } => format!("{fault} of {operation} healed"),
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// The cluster's nodes, as the node that tells (`node`) sees them.
fn cluster(node: &str, kind: &EventKind) -> String {
    match kind {
        EventKind::NodeUp { peer, address } => format!("{node} sees {peer} ({address})"),
        EventKind::NodeBack {
            peer,
            address,
            down_ms,
        } => format!(
            "{node} sees {peer} back ({address}) after {:.1} s",
            *down_ms as f64 / 1000.0
        ),
        EventKind::NodeLost { peer, address } => format!("{node} lost {peer} ({address})"),
        EventKind::NodeDown { peer, silent_ms } => {
            format!("{node} declared {peer} down (silent {silent_ms} ms)")
        }
        EventKind::NodeFrozen { silent_ms } => {
            format!("{node} was frozen {silent_ms} ms: it restarts its operations")
        }
        EventKind::NodeRefused {
            peer,
            theirs,
            ours,
            theirs_speak,
            ours_speak,
        } => {
            // the ranges when the event names them, else the newest of each side
            let say = |range: &Option<crate::wire::ProtocolRange>, newest: &u16| match range {
                Some(r) => crate::wire::envelope::speaks(r.oldest, r.newest),
                None => format!("protocol version {newest}"),
            };
            format!(
                "{node} refused {peer}: it speaks {}, {node} speaks {}",
                say(theirs_speak, theirs),
                say(ours_speak, ours)
            )
        }
        EventKind::ConnectionRefused { from, reason } => {
            format!("{node} refused a connection from {from}: {reason}")
        }
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// Datamanagers: journals read back, leaders, acknowledgements, checks.
fn datamanager(node: &str, kind: &EventKind) -> String {
    match kind {
        EventKind::DmRecovered {
            dm,
            records,
            bytes,
            ms,
            dropped_bytes,
            dropped_records,
            torn,
        } => match torn {
            None => format!(
                "datamanager {dm} on {node} read its journal back: {records} records \
                 ({bytes} bytes) in {ms} ms"
            ),
            Some(why) => format!(
                "datamanager {dm} on {node} read its journal back up to a torn end ({why}): \
                 {records} records ({bytes} bytes) kept, {dropped_records} records \
                 ({dropped_bytes} bytes) dropped, in {ms} ms"
            ),
        },
        EventKind::DmPromoted { dm, node: on, term } => {
            format!("datamanager {dm}: the replica on {on} is the leader now (term {term})")
        }
        EventKind::DmFenced {
            dm,
            node: on,
            term,
            why,
        } => format!(
            "datamanager {dm}: the leader on {on} (term {term}) stepped down: {why}; it \
             goes on as a follower"
        ),
        EventKind::DmRetention {
            dm,
            node: on,
            class,
            bound,
        } => format!(
            "datamanager {dm} on {on}: class {class} holds its retention bound of {bound} \
             records; storing more drops its oldest"
        ),
        EventKind::DmState {
            dm,
            durability,
            records,
            role,
            term,
            ..
        } => {
            let role = role
                .as_ref()
                .map(|r| format!(", {r} of term {term}"))
                .unwrap_or_default();
            format!("datamanager {dm} on {node}: {records} records ({durability}){role}")
        }
        EventKind::DmNoMajority {
            dm,
            members,
            answering,
            missing,
        } => no_majority(dm, members, answering, missing),
        EventKind::DmAcked {
            dm,
            source,
            class,
            seq,
            ..
        } => format!("datamanager {dm} acknowledged {class} #{seq} to {source}"),
        EventKind::DmDeleted {
            dm,
            source,
            class,
            deleted,
        } => format!(
            "datamanager {dm} deleted {deleted} records{} for {source}",
            class
                .as_ref()
                .map(|c| format!(" of {c}"))
                .unwrap_or_default()
        ),
        EventKind::DmApplied { dm, spans } => {
            let records: u64 = spans.iter().map(|s| s.records).sum();
            let classes: Vec<String> = spans
                .iter()
                .map(|s| format!("{} {} (#{}–#{})", s.class, s.records, s.from, s.to))
                .collect();
            cut(format!(
                "datamanager {dm} on {node} applied {records} put records: {}",
                classes.join(", ")
            ))
        }
        EventKind::DmReplicaAdded {
            dm,
            node: on,
            voters,
        } => format!(
            "datamanager {dm}: a replica on {on} was added as a learner; it catches up before \
             it votes (voters: {})",
            voters.join(", ")
        ),
        EventKind::DmReplicaPromoted {
            dm,
            node: on,
            voters,
        } => format!(
            "datamanager {dm}: the replica on {on} caught up and votes now (voters: {})",
            voters.join(", ")
        ),
        EventKind::DmReplicaRemoved {
            dm,
            node: on,
            voters,
        } => format!(
            "datamanager {dm}: the replica on {on} was removed (voters: {})",
            voters.join(", ")
        ),
        EventKind::DmReplicaOut {
            dm,
            node: on,
            voters,
        } => format!(
            "datamanager {dm}: the replica on {on} knows it is none of the replicas: it takes \
             no part, and its node stops it (voters: {})",
            voters.join(", ")
        ),
        EventKind::DmReplicaReplaced {
            dm,
            gone,
            by,
            after_secs,
            voters,
        } => format!(
            "datamanager {dm}: {gone} had been gone {after_secs:.1} s, its replica was replaced \
             by one on {by}, caught up and voting (voters: {})",
            voters.join(", ")
        ),
        EventKind::DmReplicaCaughtUp {
            dm,
            node: on,
            after_ms,
        } => format!(
            "datamanager {dm}: the replica on {on} caught up, {:.1} s after it was lost",
            *after_ms as f64 / 1000.0
        ),
        EventKind::DmRedundancyRestored {
            dm,
            replicas,
            after_ms,
        } => format!(
            "datamanager {dm}: redundancy restored, all {replicas} replicas current {:.1} s \
             after the first was lost",
            *after_ms as f64 / 1000.0
        ),
        EventKind::DmInherited {
            dm,
            records,
            refused,
        } => match refused {
            0 => format!(
                "datamanager {dm} on {node} restarted with the {records} records its \
                 previous incarnation left"
            ),
            refused => format!(
                "datamanager {dm} on {node} restarted with the records its previous \
                 incarnation left: {records} kept, {refused} refused by their check"
            ),
        },
        EventKind::DmChecked(check) => checked(check),
        // told by the teller itself, or of another family: its type and fields
        _ => generic(kind),
    }
}

/// The check of a datamanager at the end of a run: its acknowledged records, then its
/// put records if it told any applied.
fn checked(check: &DmCheck) -> String {
    let acknowledged = acknowledged_checked(check);
    if check.applied == 0 {
        return acknowledged;
    }
    if let Some(why) = &check.error {
        return format!(
            "datamanager {}: could not be checked, its {} acknowledged and {} put records \
             count lost: {why}",
            check.dm, check.acknowledged, check.applied
        );
    }
    let puts = match (check.applied_lost, &check.why) {
        (0, _) => format!("{} put records held, 0 lost", check.applied),
        (lost, Some(why)) => format!("{lost} of {} put records lost ({why})", check.applied),
        (lost, None) => format!("{lost} of {} put records lost", check.applied),
    };
    format!("{acknowledged}; {puts}")
}

/// The check of a datamanager's acknowledged records.
fn acknowledged_checked(check: &DmCheck) -> String {
    match (&check.error, check.lost) {
        (Some(why), _) => format!(
            "datamanager {}: could not be checked, its {} acknowledged records count lost: \
             {why}",
            check.dm, check.acknowledged
        ),
        (None, 0) => format!(
            "datamanager {}: {} acknowledged records, {} held on {}, 0 lost",
            check.dm,
            check.acknowledged,
            check.held,
            check.node.as_deref().unwrap_or("?")
        ),
        (None, lost) => match &check.why {
            Some(why) => format!(
                "datamanager {}: {lost} of {} acknowledged records lost ({why})",
                check.dm, check.acknowledged,
            ),
            None => format!(
                "datamanager {}: {lost} of {} acknowledged records lost (its leader on {} no \
                 longer holds them)",
                check.dm,
                check.acknowledged,
                check.node.as_deref().unwrap_or("?")
            ),
        },
    }
}

/// The sign of `kind`'s line (see [`Mark`]).
pub fn mark(kind: &EventKind) -> Mark {
    match kind {
        EventKind::ActionStarted { .. } => '>',
        EventKind::ActionEnded { .. } => '<',
        EventKind::Control { .. }
        | EventKind::Selected { .. }
        | EventKind::BindingUpgradeRefused { .. } => '?',
        EventKind::Lost { .. }
        | EventKind::BindingRolledBack(_)
        | EventKind::RebindGaveUp { .. }
        | EventKind::SupervisorGaveUp { .. }
        | EventKind::DmChecked(_) => '!',
        EventKind::Rebound(_) | EventKind::BindingUpgraded(_) => '~',
        EventKind::FaultInjected { .. }
        | EventKind::FaultHealed { .. }
        | EventKind::FaultNotInjected { .. } => '*',
        EventKind::Takeover { .. } | EventKind::DispatcherFenced { .. } => '#',
        EventKind::Bound { .. } => ' ',
        EventKind::Provenance(_)
        | EventKind::Reparameterized { .. }
        | EventKind::RunStarted { .. }
        | EventKind::OpEnded { .. }
        | EventKind::ControlPlan { .. }
        | EventKind::RunEnded { .. }
        | EventKind::Judged { .. } => '=',
        EventKind::Joined(_) => '+',
        EventKind::Left(_) => '-',
        EventKind::ChildStarted { .. }
        | EventKind::ChildExited { .. }
        | EventKind::ChildRestarted { .. } => '^',
        EventKind::NodeUp { .. }
        | EventKind::NodeBack { .. }
        | EventKind::NodeLost { .. }
        | EventKind::NodeDown { .. }
        | EventKind::NodeFrozen { .. }
        | EventKind::NodeRefused { .. }
        | EventKind::ConnectionRefused { .. } => '@',
        EventKind::DmRecovered { .. }
        | EventKind::DmPromoted { .. }
        | EventKind::DmFenced { .. }
        | EventKind::DmRetention { .. }
        | EventKind::DmState { .. }
        | EventKind::DmNoMajority { .. }
        | EventKind::DmAcked { .. }
        | EventKind::DmDeleted { .. }
        | EventKind::DmApplied { .. }
        | EventKind::DmInherited { .. }
        | EventKind::DmReplicaAdded { .. }
        | EventKind::DmReplicaPromoted { .. }
        | EventKind::DmReplicaRemoved { .. }
        | EventKind::DmReplicaOut { .. }
        | EventKind::DmReplicaReplaced { .. }
        | EventKind::DmReplicaCaughtUp { .. }
        | EventKind::DmRedundancyRestored { .. } => '%',
        EventKind::Robot { .. } => '.',
    }
}

/// How grave `kind` is (see [`Gravity`]).
pub fn gravity(kind: &EventKind) -> Gravity {
    use crate::run::OpEnd;
    match kind {
        EventKind::RunEnded { outcome, .. } | EventKind::Judged { outcome, .. } => match outcome {
            Outcome::Succeeded => Gravity::Info,
            Outcome::Failed => Gravity::Error,
        },
        EventKind::RebindGaveUp { .. } | EventKind::SupervisorGaveUp { .. } => Gravity::Error,
        EventKind::DmChecked(check)
            if check.lost > 0 || check.applied_lost > 0 || check.error.is_some() =>
        {
            Gravity::Error
        }
        EventKind::ActionEnded {
            result: Some(ActionResult::Failed),
            ..
        } => Gravity::Warning,
        EventKind::OpEnded {
            ended: OpEnd::Failed | OpEnd::Lost | OpEnd::Unresponsive,
            ..
        } => Gravity::Warning,
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
        | EventKind::DmFenced { .. }
        | EventKind::DmReplicaRemoved { .. }
        | EventKind::DmReplicaOut { .. }
        | EventKind::DmReplicaReplaced { .. }
        | EventKind::DmRetention { .. }
        | EventKind::DmNoMajority { .. } => Gravity::Warning,
        EventKind::DmRecovered { torn: Some(_), .. } => Gravity::Warning,
        EventKind::ChildExited { reason, .. } if reason != "normal" => Gravity::Warning,
        EventKind::DmAcked { .. }
        | EventKind::DmDeleted { .. }
        | EventKind::DmApplied { .. }
        | EventKind::DmState { .. } => Gravity::Detail,
        // the robot's own events: as grave as its words say (see `Teller::tell`)
        _ => Gravity::Info,
    }
}

/// How a replicated datamanager without a leader is told — by the page's `dm_no_majority`
/// and by whoever waited for it in vain (`marie ls`, a run that failed for it): its
/// replicas `members`, those `answering`, and the `missing` nodes a majority needs.
pub fn no_majority(
    dm: &str,
    members: &[String],
    answering: &[String],
    missing: &[String],
) -> String {
    if members.is_empty() {
        return format!(
            "datamanager `{dm}` has no leader and none of its replicas answers from here"
        );
    }
    format!(
        "datamanager `{dm}` has no majority: {} of its {} replicas answer{} ({}), a leader needs \
         {}; missing: {}",
        answering.len(),
        members.len(),
        if answering.len() == 1 { "s" } else { "" },
        answering.join(", "),
        members.len() / 2 + 1,
        if missing.is_empty() {
            "none (an election is under way)".to_string()
        } else {
            missing.join(", ")
        }
    )
}

/// A text told from data of unknown length is cut to this many characters.
pub const TEXT_LIMIT: usize = 300;

/// A kind as its `type` and its other fields as compact JSON.
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

/// `text` cut to [`TEXT_LIMIT`] characters.
fn cut(text: String) -> String {
    match text.char_indices().nth(TEXT_LIMIT) {
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

    /// The events `marie run` prints, as its lines have always read: a line is the mark,
    /// a space and the words.
    const RUN: &str = r#"{"at_ms":1000,"node":"a","kind":{"type":"run_started","mission":"docking"}}
{"at_ms":1010,"node":"a","kind":{"type":"bound","operations":[{"name":"wall-follower","version":"1.0.0","node":"a","epoch":1,"address":"0.41"},{"name":"sampler","version":"1.0.0","node":"b","epoch":1,"address":"0.42"}]}}
{"at_ms":1020,"node":"a","kind":{"type":"action_started","action":"follow-wall","run_ms":20,"operations":[{"key":"wall-follower","name":"wall-follower","id":1512,"version":"1.0.0","node":"a","address":"0.41"}]}}
{"at_ms":3000,"node":"a","kind":{"type":"fault_injected","fault":"kill","operation":"wall-follower","actor":"0.41"}}
{"at_ms":3001,"node":"a","kind":{"type":"lost","operation":"wall-follower","cause":{"type":"gone"}}}
{"at_ms":3002,"node":"a","kind":{"type":"rebound","operation":"wall-follower","cause":{"type":"gone"},"from":"0.41","to":"0.57","from_node":"a","to_node":"a","downtime_ms":2,"epoch":2}}
{"at_ms":3003,"node":"a","kind":{"type":"rebound","operation":"sampler","cause":{"type":"gone"},"from":"0.42","to":"0.58","from_node":"b","to_node":"c","downtime_ms":5,"epoch":3}}
{"at_ms":3500,"node":"a","kind":{"type":"fault_not_injected","fault":"hang","operation":"nobody","why":"no operation `nobody` is running","due_ms":2500}}
{"at_ms":4000,"node":"a","kind":{"type":"action_ended","action":"follow-wall","run_ms":3000,"flags":["dock_found"],"status":4,"result":"failed"}}
{"at_ms":4001,"node":"a","kind":{"type":"control","node":"find-dock","decision":"fallback to `back-along-wall`","run_ms":3001}}
{"at_ms":9000,"node":"c","kind":{"type":"takeover","run":"r","from":"a","to":"c","term":2,"gap_ms":84,"since_checkpoint_ms":100,"unix_ms":1}}
{"at_ms":9001,"node":"c","kind":{"type":"bound","operations":[{"name":"wall-follower","version":"1.0.0","node":"a","epoch":4,"address":"0.57"},{"name":"sampler","version":"1.0.0","node":"c","epoch":4,"address":"0.58"}]}}
{"at_ms":9500,"node":"a","kind":{"type":"dispatcher_fenced","run":"r","term":1,"newer":2}}
{"at_ms":9900,"node":"c","kind":{"type":"action_ended","action":"park","run_ms":8900,"flags":["parked"],"status":8,"result":"succeeded"}}
{"at_ms":9990,"node":"c","kind":{"type":"dm_checked","dm":"world","acknowledged":10,"held":8,"lost":2,"node":"b"}}"#;

    #[test]
    fn a_refusal_names_both_ranges_and_reads_an_event_of_the_build_before_ranges() {
        let new: Event = serde_json::from_str(
            r#"{"at_ms":1,"node":"r1","kind":{"type":"node_refused","peer":"far","theirs":4,"ours":3,"theirs_speak":{"oldest":4,"newest":4},"ours_speak":{"oldest":2,"newest":3}}}"#,
        )
        .unwrap();
        assert_eq!(
            said(&new.node, &new.kind),
            "r1 refused far: it speaks protocol version 4, r1 speaks protocol versions 2..=3"
        );
        let old: Event = serde_json::from_str(
            r#"{"at_ms":1,"node":"r1","kind":{"type":"node_refused","peer":"old","theirs":1,"ours":2}}"#,
        )
        .unwrap();
        assert_eq!(
            said(&old.node, &old.kind),
            "r1 refused old: it speaks protocol version 1, r1 speaks protocol version 2"
        );
    }

    #[test]
    fn the_lines_of_a_run_read_as_they_always_have() {
        let mut teller = Teller::default();
        let mut lines = Vec::new();
        for line in RUN.lines() {
            let event = Event::from_json_line(line).unwrap();
            let words = teller.tell(&event);
            if words.news {
                lines.extend(words.text.lines().map(|l| format!("{} {l}", words.mark)));
            }
        }
        assert_eq!(
            lines[1..],
            [
                "  bound wall-follower v1.0.0 on a",
                "  bound sampler v1.0.0 on b",
                "> follow-wall: start [wall-follower]",
                "* injected kill into wall-follower (0.41) at 2.0s",
                "! wall-follower lost: died: its actor is gone",
                "~ wall-follower rebound: 0.41 -> 0.57 after 2 ms",
                "~ sampler rebound: 0.42 on b -> 0.58 on c after 5 ms",
                "* could not inject hang into nobody at 2.5s: no operation `nobody` is running",
                "< follow-wall: failed, status 0x00000004 [dock_found]",
                "? find-dock: fallback to `back-along-wall` at 3.0s",
                "# the run taken over by c from a at 8.0s (term 2, claimed 84 ms after the loss \
                 was noticed)",
                "  bound sampler v1.0.0 on c (was on b)",
                "# the dispatcher on a (term 1) fenced off by term 2",
                "< park: end, status 0x00000008 [parked]",
                "! datamanager world: 2 of 10 acknowledged records lost (its leader on b no \
                 longer holds them)",
            ]
        );
    }

    #[test]
    fn a_check_with_put_records_says_how_many_were_lost_and_why() {
        let check = DmCheck {
            dm: "feature".into(),
            node: Some("embedded".into()),
            acknowledged: 3,
            held: 3,
            applied: 900,
            applied_lost: 300,
            why: Some("the feature datamanager restarted empty".into()),
            ..DmCheck::default()
        };
        assert_eq!(
            checked(&check),
            "datamanager feature: 3 acknowledged records, 3 held on embedded, 0 lost; 300 of \
             900 put records lost (the feature datamanager restarted empty)"
        );
        assert_eq!(
            gravity(&EventKind::DmChecked(check.clone())),
            Gravity::Error
        );
        let held = DmCheck {
            applied_lost: 0,
            why: None,
            ..check
        };
        assert_eq!(
            checked(&held),
            "datamanager feature: 3 acknowledged records, 3 held on embedded, 0 lost; 900 put \
             records held, 0 lost"
        );
        assert_eq!(gravity(&EventKind::DmChecked(held)), Gravity::Info);
    }

    #[test]
    fn a_binding_that_moved_nothing_is_no_news_but_still_says_where() {
        let mut teller = Teller::default();
        let bound = r#"{"at_ms":1,"node":"a","kind":{"type":"bound","operations":[{"name":"x","version":"1.0.0","node":"a","epoch":1,"address":"0.1"}]}}"#;
        let event = Event::from_json_line(bound).unwrap();
        assert!(teller.tell(&event).news);
        let again = teller.tell(&event);
        assert!(!again.news);
        assert_eq!(again.text, "bound as before: x v1.0.0 on a");
    }

    #[test]
    fn a_robot_event_is_told_by_the_robots_words_or_by_its_name_and_data() {
        let robot =
            r#"{"at_ms":1,"node":"a","kind":{"type":"robot","what":"beep","data":{"loud":true}}}"#;
        let event = Event::from_json_line(robot).unwrap();
        let plain = Teller::default().tell(&event);
        assert_eq!(
            (plain.text.as_str(), plain.gravity),
            ("robot beep: {\"loud\":true}", Gravity::Info)
        );
        fn beeps(what: &str, _: &Value) -> Option<(String, Gravity)> {
            (what == "beep").then(|| ("a beep".to_string(), Gravity::Warning))
        }
        let told = Teller::default().with_robot_words(beeps).tell(&event);
        assert_eq!(
            (told.text.as_str(), told.gravity, told.mark),
            ("a beep", Gravity::Warning, '.')
        );
    }

    #[test]
    fn heeding_the_events_not_shown_words_the_rest_as_telling_them_all_does() {
        let shown = |kind: &EventKind| {
            !matches!(kind, EventKind::RunStarted { .. } | EventKind::Bound { .. })
        };
        let mut all = Teller::default();
        let mut some = Teller::default();
        for line in RUN.lines() {
            let event = Event::from_json_line(line).unwrap();
            let told = all.tell(&event);
            if shown(&event.kind) {
                assert_eq!(some.tell(&event), told, "{line}");
            } else {
                some.heed(&event);
            }
        }
        // the takeover's binding, told after heeding the first: only what moved is news
        let rebound = RUN.lines().nth(11).unwrap();
        let event = Event::from_json_line(rebound).unwrap();
        assert_eq!(
            some.tell(&event).text,
            "bound as before: wall-follower v1.0.0 on a, sampler v1.0.0 on c"
        );
    }

    #[test]
    fn a_long_text_is_cut() {
        let long = "x".repeat(1000);
        assert_eq!(cut(long).chars().count(), TEXT_LIMIT + 1);
        assert_eq!(cut("short".into()), "short");
    }
}

//! The lines a run prints on stdout: its events as they are published on the node's bus
//! (a subscriber, as the monitor is), then its outcome from the report.

use marie::events::{ActionResult, BusError, DispatcherVoice, Event, EventBus, EventKind};
use marie::report::RunReport;
use marie::run::{Choice, Outcome, Verdict};
use marie::status::StatusFlags;
use marie_missions::robot::RobotReport;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// How `marie run` prints its progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Progress {
    /// Event lines.
    Lines,
    /// Event lines, each choice of an instance explained (`--explain`).
    Explained,
    /// Only the choices, one JSON object per line (`--explain --json`).
    ChoicesAsJson,
}

/// The live lines of a run: a subscriber of the node's bus that prints each event of the
/// run as it comes, until [`finish`](LiveLines::finish)ed.
pub(crate) struct LiveLines {
    stop: oneshot::Sender<()>,
    task: JoinHandle<()>,
}

impl LiveLines {
    /// Print what `bus` publishes from now on.
    pub(crate) fn start(bus: &EventBus, progress: Progress) -> LiveLines {
        let mut sub = bus.subscribe();
        let (stop, mut stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let mut printer = Printer {
                progress,
                start_ms: None,
                bound: Default::default(),
                voice: DispatcherVoice::default(),
            };
            loop {
                tokio::select! {
                    biased;
                    received = sub.recv() => match received {
                        Ok(event) => printer.print(&event),
                        Err(BusError::Lagged { missed }) => {
                            tracing::warn!(missed, "the live lines fell behind the event bus")
                        }
                        Err(BusError::Closed) => break,
                    },
                    _ = &mut stopped => {
                        for event in sub.drain() {
                            printer.print(&event);
                        }
                        break;
                    }
                }
            }
        });
        LiveLines { stop, task }
    }

    /// Print what was published before this call, then stop.
    pub(crate) async fn finish(self) {
        let _ = self.stop.send(());
        let _ = self.task.await;
    }
}

/// Prints events, knowing when the run began (its fault lines say when, in run time).
struct Printer {
    progress: Progress,
    /// The stamp of the run's `run_started`.
    start_ms: Option<u64>,
    /// Where each operation was bound, as printed (a takeover's bindings print only
    /// what moved).
    bound: std::collections::BTreeMap<String, String>,
    /// Whose word the run is: what another node's dispatcher says (one fenced off, woken
    /// from a freeze) is not printed, as the report does not fold it.
    voice: DispatcherVoice,
}

impl Printer {
    /// Seconds of the run at `at_ms`.
    fn run_secs(&self, at_ms: u64) -> f64 {
        at_ms.saturating_sub(self.start_ms.unwrap_or(at_ms)) as f64 / 1000.0
    }

    fn print(&mut self, event: &Event) {
        if !self.voice.hears(event) {
            return;
        }
        match (&event.kind, self.progress) {
            (EventKind::RunStarted { .. }, _) => self.start_ms = Some(event.at_ms),
            // a node of another commit is named, on stderr whatever the progress shown
            (EventKind::Provenance(p), _) => {
                let this = super::this_build();
                for node in p.nodes_of_other_commits(&this) {
                    if let Some(theirs) = &node.marie {
                        eprintln!(
                            "marie: warning: node `{}` runs marie {theirs}; this is marie {this}",
                            node.node
                        );
                    }
                }
            }
            (EventKind::Selected { choice }, Progress::ChoicesAsJson) => {
                // a Choice is plain data: it always serializes
                if let Ok(line) = serde_json::to_string(choice) {
                    println!("{line}");
                }
            }
            (_, Progress::ChoicesAsJson) => {}
            (EventKind::Selected { choice }, Progress::Explained) => print_choice(choice),
            (kind, _) => self.print_line(event, kind),
        }
    }

    fn print_line(&mut self, event: &Event, kind: &EventKind) {
        match kind {
            EventKind::Bound { operations } => {
                for op in operations {
                    let before = self.bound.insert(op.name.clone(), op.node.clone());
                    match before {
                        None => println!("  bound {} v{} on {}", op.name, op.version, op.node),
                        Some(node) if node != op.node => println!(
                            "  bound {} v{} on {} (was on {node})",
                            op.name, op.version, op.node
                        ),
                        Some(_) => {}
                    }
                }
            }
            EventKind::Takeover {
                from,
                to,
                term,
                gap_ms,
                ..
            } => println!(
                "# the run taken over by {to} from {from} at {:.1}s (term {term}, claimed \
                 {gap_ms} ms after the loss was noticed)",
                self.run_secs(event.at_ms)
            ),
            EventKind::DispatcherFenced { term, newer, .. } => println!(
                "# the dispatcher on {} (term {term}) fenced off by term {newer}",
                event.node
            ),
            EventKind::ActionStarted {
                action, operations, ..
            } => {
                let keys: Vec<&str> = operations.iter().map(|o| o.key.as_str()).collect();
                println!("> {action}: start [{}]", keys.join(", "));
            }
            EventKind::ActionEnded {
                action,
                flags,
                status,
                result,
                ..
            } => {
                let status = StatusFlags(*status);
                // a success is the action's plain end
                let how = result
                    .filter(|r| *r != ActionResult::Succeeded)
                    .map_or("end", ActionResult::name);
                println!("< {action}: {how}, status {status} [{}]", flags.join(", "));
            }
            EventKind::Control {
                node,
                decision,
                run_ms,
            } => println!("? {node}: {decision} at {:.1}s", *run_ms as f64 / 1000.0),
            EventKind::Lost { operation, cause } => println!("! {operation} lost: {cause}"),
            EventKind::Rebound(r) if !r.from_node.is_empty() && r.from_node != r.to_node => {
                println!(
                    "~ {} rebound: {} on {} -> {} on {} after {} ms",
                    r.operation, r.from, r.from_node, r.to, r.to_node, r.downtime_ms
                );
            }
            EventKind::Rebound(r) => println!(
                "~ {} rebound: {} -> {} after {} ms",
                r.operation, r.from, r.to, r.downtime_ms
            ),
            EventKind::FaultInjected {
                fault,
                operation,
                actor,
                ..
            } => println!(
                "* injected {fault} into {operation} ({actor}) at {:.1}s",
                self.run_secs(event.at_ms)
            ),
            EventKind::FaultNotInjected {
                fault,
                operation,
                why,
                due_ms,
            } => {
                let at = due_ms.map_or(self.run_secs(event.at_ms), |d| d as f64 / 1000.0);
                println!("* could not inject {fault} into {operation} at {at:.1}s: {why}");
            }
            EventKind::DmChecked(check) if check.lost > 0 => match &check.error {
                None => println!(
                    "! datamanager {}: {} of {} acknowledged records lost (its primary on {} \
                     no longer holds them)",
                    check.dm,
                    check.lost,
                    check.acknowledged,
                    check.node.as_deref().unwrap_or("?")
                ),
                Some(why) => println!(
                    "! datamanager {}: could not be checked, its {} acknowledged records count \
                     lost: {why}",
                    check.dm, check.acknowledged
                ),
            },
            _ => {}
        }
    }
}

/// `mission succeeded`, or `mission FAILED (full stop): why` — after the robot's judgement.
pub(crate) fn end_line(report: &RunReport) -> String {
    match report.outcome {
        Outcome::Succeeded => "mission succeeded".to_string(),
        Outcome::Failed => format!("mission FAILED (full stop): {}", report.reason),
    }
}

/// `outcome: succeeded — final pose (x, y, heading°), inside goal: yes, collisions: 0`.
pub(crate) fn outcome_line(report: &RunReport) -> String {
    let outcome = match report.outcome {
        Outcome::Succeeded => "succeeded",
        Outcome::Failed => "failed",
    };
    let cart = RobotReport::of(report);
    let Some([x, y, heading]) = cart.final_pose else {
        return format!("outcome: {outcome} — the cart did not report its final pose");
    };
    let inside = match cart.inside_goal {
        Some(true) => "yes",
        Some(false) => "no",
        None => "no goal area",
    };
    format!(
        "outcome: {outcome} — final pose ({x:.2}, {y:.2}, {:.1}°), inside goal: {inside}, collisions: {}",
        heading.to_degrees(),
        cart.collisions.unwrap_or_default()
    )
}

/// What a faulted run went through, in one line — `None` for a run without faults, lost
/// nodes or lost records: `verdict: 2 faults injected (freeze-node 1, partition 1), 1 node
/// lost (1 back), 3 rebinds, 0 of 412 acknowledged records lost, 12 commands refused by
/// epoch, 0 obeyed from an old epoch, 0 collisions`.
pub(crate) fn verdict_line(report: &RunReport) -> Option<String> {
    let lost = report.acknowledged_lost.unwrap_or_default();
    if report.faults_total == 0 && report.nodes_lost.is_empty() && lost == 0 {
        return None;
    }
    let mut kinds: std::collections::BTreeMap<String, u64> = Default::default();
    for f in report.faults.iter().filter(|f| f.error.is_none()) {
        *kinds.entry(f.fault.to_string()).or_default() += 1;
    }
    let injected: u64 = kinds.values().sum();
    let not_injected = report.faults.iter().filter(|f| f.error.is_some()).count();
    let by_kind: Vec<String> = kinds.iter().map(|(k, n)| format!("{k} {n}")).collect();
    let back = report
        .nodes_lost
        .iter()
        .filter(|n| n.back_at_ms.is_some())
        .count();
    let cart = RobotReport::of(report);
    let refused: u64 = cart
        .refused_commands
        .as_ref()
        .map_or(0, |r| r.values().sum());
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    let mut parts = vec![format!(
        "{injected} fault{} injected{}",
        if injected == 1 { "" } else { "s" },
        if by_kind.is_empty() {
            String::new()
        } else {
            format!(" ({})", by_kind.join(", "))
        }
    )];
    if not_injected > 0 {
        parts.push(format!("{not_injected} not injected"));
    }
    if report.faults.len() as u64 != report.faults_total {
        parts.push(format!(
            "(of {} faults in all, the latest {} counted)",
            report.faults_total,
            report.faults.len()
        ));
    }
    parts.push(format!(
        "{} ({back} back)",
        plural(report.nodes_lost.len(), "node lost", "nodes lost")
    ));
    parts.push(plural(report.takeovers.len(), "takeover", "takeovers"));
    parts.push(plural(report.rebinds_total as usize, "rebind", "rebinds"));
    if report.acknowledged_lost.is_some() {
        let acknowledged: u64 = report.dm_checks.iter().map(|c| c.acknowledged).sum();
        parts.push(format!(
            "{lost} of {acknowledged} acknowledged records lost"
        ));
    }
    parts.push(format!("{refused} commands refused by epoch"));
    match &cart.obeyed_late {
        Some(late) if late.is_empty() => parts.push("0 obeyed from an old epoch".to_string()),
        Some(late) => parts.push(format!(
            "{} obeyed from an old epoch ({})",
            plural(late.len(), "epoch", "epochs"),
            late.iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        )),
        None => {}
    }
    if let Some(c) = cart.collisions {
        parts.push(plural(c as usize, "collision", "collisions"));
    }
    Some(format!("verdict: {}", parts.join(", ")))
}

/// `--explain`: the candidates for one operation, the chosen one first, each other with why
/// it lost or was rejected.
pub(crate) fn print_choice(choice: &Choice) {
    match &choice.replacing {
        None => println!(
            "? {}: {} candidate(s)",
            choice.operation,
            choice.candidates.len()
        ),
        Some(lost) => println!(
            "? {}: a stand-in for {lost}, {} candidate(s)",
            choice.operation,
            choice.candidates.len()
        ),
    }
    let mut rows: Vec<_> = choice.candidates.iter().collect();
    rows.sort_by_key(|c| !matches!(c.verdict, Verdict::Chosen));
    for c in rows {
        let what = format!(
            "{} on {}, version {}, schema [{}]",
            c.address,
            c.node,
            c.version,
            c.schema.join(", ")
        );
        match &c.verdict {
            Verdict::Chosen => println!("    chosen    {what}"),
            Verdict::Lost { reason } => println!("    lost      {what}: {reason}"),
            Verdict::Rejected { reason } => println!("    rejected  {what}: {reason}"),
        }
    }
}

//! The lines a run prints on stdout: its events as they are published on the node's bus
//! (a subscriber, as the monitor is), in the words every reader of events shares
//! ([`Teller`]), then its outcome from the report.

use marie::events::{BusError, DispatcherVoice, Event, EventBus, EventKind, Teller};
use marie::report::RunReport;
use marie::run::{Choice, Outcome, Verdict};
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
            let mut printer = Printer::new(progress);
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

/// Prints events as the one voice words them ([`Teller`]), each line after its mark.
struct Printer {
    progress: Progress,
    /// Words every event heard (also those not printed: it follows the run).
    teller: Teller,
    /// Whose word the run is: what another node's dispatcher says (one fenced off, woken
    /// from a freeze) is not printed, as the report does not fold it.
    voice: DispatcherVoice,
}

impl Printer {
    fn new(progress: Progress) -> Printer {
        Printer {
            progress,
            teller: Teller::default().with_robot_words(marie_telemetry::words),
            voice: DispatcherVoice::default(),
        }
    }

    fn print(&mut self, event: &Event) {
        if !self.voice.hears(event) {
            return;
        }
        match (&event.kind, self.progress) {
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
            (kind, Progress::Lines | Progress::Explained) if printed(kind) => {
                let words = self.teller.tell(event);
                if words.news {
                    for line in words.text.lines() {
                        println!("{} {line}", words.mark);
                    }
                }
                return;
            }
            _ => {}
        }
        self.teller.heed(event);
    }
}

/// The events `marie run` prints as lines: the run's story as it happens — bindings,
/// actions, decisions, losses, rebinds, upgrades, faults, takeovers, records lost — but not what
/// the report and the outcome line tell at the end, nor the registry's, the supervisors',
/// the cluster's or the robot's news (the monitor and `--events` have those).
fn printed(kind: &EventKind) -> bool {
    match kind {
        EventKind::Bound { .. }
        | EventKind::Takeover { .. }
        | EventKind::DispatcherFenced { .. }
        | EventKind::ActionStarted { .. }
        | EventKind::ActionEnded { .. }
        | EventKind::Control { .. }
        | EventKind::Lost { .. }
        | EventKind::Rebound(_)
        | EventKind::BindingUpgraded(_)
        | EventKind::BindingRolledBack(_)
        | EventKind::BindingUpgradeRefused { .. }
        | EventKind::FaultInjected { .. }
        | EventKind::FaultNotInjected { .. } => true,
        EventKind::DmChecked(check) => check.lost > 0,
        _ => false,
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
/// lost (1 back), 3 rebinds, 0 of 412 acknowledged records lost, 0 of 5120 put records
/// lost, 12 commands refused by epoch, 0 obeyed from an old epoch, 0 collisions` — a loss
/// with why when the check knows (`812 of 5120 put records lost (the feature datamanager
/// restarted empty)`).
pub(crate) fn verdict_line(report: &RunReport) -> Option<String> {
    let lost = report.acknowledged_lost.unwrap_or_default();
    let applied_lost = report.applied_lost.unwrap_or_default();
    if report.faults_total == 0 && report.nodes_lost.is_empty() && lost + applied_lost == 0 {
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
        let applied: u64 = report.dm_checks.iter().map(|c| c.applied).sum();
        if applied > 0 {
            parts.push(format!("{applied_lost} of {applied} put records lost"));
        }
        let why: Vec<&str> = report
            .dm_checks
            .iter()
            .filter(|c| c.lost + c.applied_lost > 0)
            .filter_map(|c| c.why.as_deref())
            .collect();
        if let (false, Some(last)) = (why.is_empty(), parts.last_mut()) {
            last.push_str(&format!(" ({})", why.join("; ")));
        }
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

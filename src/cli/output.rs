//! The lines a run prints on stdout: its progress events and its outcome.

use marie::actors::dispatcher::{DispatchEvent, Outcome, RunReport};
use marie::fault::plan::TargetError;

/// How `marie run` prints its progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Event lines.
    Lines,
    /// Event lines, each choice of an instance explained (`--explain`).
    Explained,
    /// Only the choices, one JSON object per line (`--explain --json`).
    ChoicesAsJson,
}

/// One progress line per dispatcher event.
pub fn print_event(evt: &DispatchEvent, progress: Progress) {
    match (evt, progress) {
        (DispatchEvent::Selected(choice), Progress::ChoicesAsJson) => {
            // a Choice is plain data: it always serializes
            if let Ok(line) = serde_json::to_string(choice) {
                println!("{line}");
            }
            return;
        }
        (_, Progress::ChoicesAsJson) => return,
        (DispatchEvent::Selected(choice), Progress::Explained) => {
            print_choice(choice);
            return;
        }
        _ => {}
    }
    match evt {
        DispatchEvent::Selected(_) => {}
        DispatchEvent::Bound { operations } => {
            for (name, version, node) in operations {
                println!("  bound {name} v{version} on {node}");
            }
        }
        DispatchEvent::ActionStarted { action, operations } => {
            println!("> {action}: start [{}]", operations.join(", "));
        }
        DispatchEvent::ActionEnded {
            action,
            flags,
            status,
        } => {
            println!("< {action}: end, status {status} [{}]", flags.join(", "));
        }
        DispatchEvent::Lost { operation, cause } => {
            println!("! {operation} lost: {cause}");
        }
        DispatchEvent::Rebound(r) if !r.from_node.is_empty() && r.from_node != r.to_node => {
            println!(
                "~ {} rebound: {} on {} -> {} on {} after {} ms",
                r.operation, r.from, r.from_node, r.to, r.to_node, r.downtime_ms
            );
        }
        DispatchEvent::Rebound(r) => {
            println!(
                "~ {} rebound: {} -> {} after {} ms",
                r.operation, r.from, r.to, r.downtime_ms
            );
        }
        DispatchEvent::Ended { outcome, reason } => match outcome {
            Outcome::Succeeded => println!("mission succeeded"),
            Outcome::Failed => println!("mission FAILED (full stop): {reason}"),
        },
    }
}

/// One line per fault of the report: injected, or why it could not be.
pub fn print_faults(report: &RunReport) {
    for f in &report.faults {
        match &f.error {
            None => println!(
                "* injected {} into {} ({}) at {:.1}s",
                f.fault,
                f.operation,
                f.actor,
                f.at_ms as f64 / 1000.0
            ),
            Some(e) => println!(
                "* could not inject {} into {} at {:.1}s: {e}",
                f.fault,
                f.operation,
                f.at_ms as f64 / 1000.0
            ),
        }
    }
}

/// `outcome: succeeded — final pose (x, y, heading°), inside goal: yes, collisions: 0`.
pub fn outcome_line(report: &RunReport) -> String {
    let outcome = match report.outcome {
        Outcome::Succeeded => "succeeded",
        Outcome::Failed => "failed",
    };
    let Some([x, y, heading]) = report.final_pose else {
        return format!("outcome: {outcome} — the cart did not report its final pose");
    };
    let inside = match report.inside_goal {
        Some(true) => "yes",
        Some(false) => "no",
        None => "no goal area",
    };
    format!(
        "outcome: {outcome} — final pose ({x:.2}, {y:.2}, {:.1}°), inside goal: {inside}, collisions: {}",
        heading.to_degrees(),
        report.collisions.unwrap_or_default()
    )
}

/// The message for an operation that names no running instance.
pub fn not_found(e: TargetError) -> String {
    e.to_string()
}

/// `--explain`: the candidates for one operation, the chosen one first, each other with why
/// it lost or was rejected.
pub fn print_choice(choice: &marie::actors::dispatcher::selection::Choice) {
    use marie::actors::dispatcher::selection::Verdict;
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

//! The aspects of two runs compared, one function each: which marie ran them, the run's
//! settings (mission, seed, speed, nodes), the faults injected, how the mission ended and
//! where the cart stopped. Each gives `None` when the runs are the same in it, else a
//! [`Difference`]: a few words for the summary, the section's lines, the same as JSON.
//!
//! What is compared is what the user set or what the run did, never what differs between
//! any two runs by nature (the start time, the command line with its report's path, actor
//! addresses): a report diffed with a run of the same inputs is the same.

use marie::report::{FaultRecord, RunReport};
use marie::run::{Build, Provenance};
use serde_json::{json, Value as Json};
use std::fmt;

/// Which of the two runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    /// The first report given.
    A,
    /// The second.
    B,
}

impl Side {
    /// `a` or `b`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Side::A => "a",
            Side::B => "b",
        }
    }
}

impl fmt::Display for Side {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How two runs differ in one aspect.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct Difference {
    /// A few words for the summary at the top (`seed 3 -> 4`).
    pub summary: String,
    /// The section's lines, indented by two (a unified diff's are not: it can be cut out
    /// and applied as it is).
    pub lines: Vec<String>,
    /// The same for `--json`.
    pub json: Json,
}

/// A value as text on both sides, with its label: a row of a section that holds several.
struct Row {
    label: &'static str,
    a: String,
    b: String,
}

/// The longest value a summary line shows (`65.400 s`); a longer one is named only.
const SHORT: usize = 12;

/// The section of the rows that differ (`label: a -> b`, summed up by their labels).
fn rows(all: impl IntoIterator<Item = Row>) -> Option<Difference> {
    let mut diff = Difference::default();
    let (mut labels, mut json) = (Vec::new(), serde_json::Map::new());
    for row in all.into_iter().filter(|r| r.a != r.b) {
        diff.lines
            .push(format!("  {}: {} -> {}", row.label, row.a, row.b));
        // short values are worth their place in the summary (`seed 3 -> 4`)
        labels.push(match row.a.len().max(row.b.len()) <= SHORT {
            true => format!("{} {} -> {}", row.label, row.a, row.b),
            false => row.label.to_string(),
        });
        json.insert(row.label.into(), json!({"a": row.a, "b": row.b}));
    }
    if labels.is_empty() {
        return None;
    }
    diff.summary = labels.join(", ");
    diff.json = json.into();
    Some(diff)
}

/// Compare what the runs' provenances say with `compare`. When only one run has provenance
/// (the other's report is older) that is the difference: `what` is unknown for the other;
/// when neither has, there is nothing to compare.
pub(crate) fn with_provenance(
    a: &RunReport,
    b: &RunReport,
    what: &str,
    compare: impl FnOnce(&Provenance, &Provenance) -> Option<Difference>,
) -> Option<Difference> {
    let side = match (&a.provenance, &b.provenance) {
        (Some(pa), Some(pb)) => return compare(pa, pb),
        (None, None) => return None,
        (None, Some(_)) => Side::A,
        (Some(_), None) => Side::B,
    };
    Some(Difference {
        summary: format!("unknown in {side}"),
        lines: vec![format!(
            "  {side} has no provenance (an older report): {what} unknown"
        )],
        json: json!({side.name(): null}),
    })
}

/// Which marie ran each run (its dispatcher's build).
pub(crate) fn marie(a: Option<&Build>, b: Option<&Build>) -> Option<Difference> {
    if a == b {
        return None;
    }
    let text = |b: Option<&Build>| b.map_or_else(|| "unknown".to_string(), Build::to_string);
    let short = |c: &Option<String>| {
        c.as_deref()
            .map_or_else(|| "unknown".to_string(), |c| c.chars().take(12).collect())
    };
    let summary = match (a, b) {
        (Some(x), Some(y)) if x.version != y.version => {
            format!("version {} -> {}", x.version, y.version)
        }
        (Some(x), Some(y)) if x.commit != y.commit => {
            format!("commit {} -> {}", short(&x.commit), short(&y.commit))
        }
        (Some(_), Some(_)) => "uncommitted changes".into(),
        (None, _) => "unknown in a".into(),
        (_, None) => "unknown in b".into(),
    };
    Some(Difference {
        summary,
        lines: vec![format!("  a: {}", text(a)), format!("  b: {}", text(b))],
        json: json!({"a": a, "b": b}),
    })
}

/// A note when both runs name the same build that had uncommitted changes: the same
/// `marie:` then does not prove the same code.
pub(crate) fn marie_note(a: Option<&Build>, b: Option<&Build>) -> Option<String> {
    match (a, b) {
        (Some(x), Some(y)) if x == y && x.commit.is_some() && !x.same_code(y) => {
            let commit: String = x.commit.iter().flat_map(|c| c.chars()).take(12).collect();
            Some(format!(
                "note: both runs' marie is {} at commit {commit} with uncommitted changes: \
                 its code may differ all the same",
                x.version
            ))
        }
        _ => None,
    }
}

/// What the run was set to: the mission's name, the seed, the clock's speed, the nodes.
pub(crate) fn run(a: &RunReport, b: &RunReport) -> Option<Difference> {
    let seed = |r: &RunReport| {
        r.provenance
            .as_ref()
            .and_then(|p| p.seed)
            .or_else(|| r.robot.get("seed").and_then(Json::as_u64))
            .map_or_else(|| "none".to_string(), |s| s.to_string())
    };
    let speed = |p: &Provenance| p.speed.clone().unwrap_or_else(|| "unknown".into());
    let nodes = |p: &Provenance| match p.nodes.is_empty() {
        true => "none".to_string(),
        false => p
            .nodes
            .iter()
            .map(|n| n.node.as_str())
            .collect::<Vec<_>>()
            .join(", "),
    };
    let mut all = vec![
        Row {
            label: "mission",
            a: a.mission.clone(),
            b: b.mission.clone(),
        },
        Row {
            label: "seed",
            a: seed(a),
            b: seed(b),
        },
    ];
    // the speed and the nodes are known from the provenance alone: a report without it
    // (older) is noted once, not as a row of unknowns
    if let (Some(pa), Some(pb)) = (&a.provenance, &b.provenance) {
        all.push(Row {
            label: "speed",
            a: speed(pa),
            b: speed(pb),
        });
        all.push(Row {
            label: "nodes",
            a: nodes(pa),
            b: nodes(pb),
        });
    }
    let mut diff = rows(all);
    // a cluster's nodes may each run another build: a node of both runs whose build changed
    if let (Some(pa), Some(pb)) = (&a.provenance, &b.provenance) {
        if pa.nodes.len() > 1 || pb.nodes.len() > 1 {
            for na in &pa.nodes {
                let Some(nb) = pb.nodes.iter().find(|n| n.node == na.node) else {
                    continue;
                };
                if let Some(build) = marie(na.marie.as_ref(), nb.marie.as_ref()) {
                    let diff = diff.get_or_insert_with(|| Difference {
                        json: json!({}),
                        ..Difference::default()
                    });
                    diff.lines.push(format!("  node {}:", na.node));
                    diff.lines
                        .extend(build.lines.iter().map(|l| format!("  {l}")));
                    if let Some(map) = diff.json.as_object_mut() {
                        map.insert(format!("node {}", na.node), build.json);
                    }
                    let summary = format!("node {} {}", na.node, build.summary);
                    diff.summary = match diff.summary.is_empty() {
                        true => summary,
                        false => format!("{}, {summary}", diff.summary),
                    };
                }
            }
        }
    }
    diff
}

/// `ms` as seconds with milliseconds (`20.000 s`).
pub(crate) fn secs(ms: u64) -> String {
    format!("{}.{:03} s", ms / 1000, ms % 1000)
}

/// One fault as a line: when, what, aimed at what, what it hit or why it could not.
fn fault_text(f: &FaultRecord) -> String {
    let mut s = format!("{} {} {}", secs(f.at_ms), f.fault, f.operation);
    match &f.error {
        Some(e) => s.push_str(&format!(": not injected: {e}")),
        None if !f.actor.is_empty() => {
            s.push_str(&format!(": {}", f.actor));
            if let Some(node) = &f.node {
                s.push_str(&format!(" on {node}"));
            }
        }
        None => {}
    }
    if let Some(l) = f.lasting_ms {
        s.push_str(&format!(", for {}", secs(l)));
    }
    if let Some(h) = f.healed_at_ms {
        s.push_str(&format!(", healed at {}", secs(h)));
    }
    s
}

/// The faults injected (or tried) in each run: the same when the same faults hit the same
/// operations on the same nodes at the same times (the instance's address aside).
pub(crate) fn faults(a: &RunReport, b: &RunReport) -> Option<Difference> {
    let key = |r: &RunReport| -> Vec<String> {
        r.faults
            .iter()
            .map(|f| {
                format!(
                    "{} {} {} {:?} {:?} {:?} {:?}",
                    f.at_ms, f.fault, f.operation, f.node, f.error, f.lasting_ms, f.healed_at_ms
                )
            })
            .collect()
    };
    if a.faults_total == b.faults_total && key(a) == key(b) {
        return None;
    }
    let mut lines = Vec::new();
    for (side, r) in [(Side::A, a), (Side::B, b)] {
        let count = match r.faults_total {
            0 => "none".to_string(),
            1 => "1 fault".to_string(),
            n if n as usize > r.faults.len() => {
                format!("{n} faults (the latest {} kept)", r.faults.len())
            }
            n => format!("{n} faults"),
        };
        lines.push(format!("  {side}: {count}"));
        lines.extend(r.faults.iter().map(|f| format!("    {}", fault_text(f))));
    }
    Some(Difference {
        summary: format!("{} -> {}", a.faults_total, b.faults_total),
        lines,
        json: json!({
            "a": {"total": a.faults_total, "faults": a.faults},
            "b": {"total": b.faults_total, "faults": b.faults},
        }),
    })
}

/// A value the robot said of the run, as text (`none` when it did not say).
fn robot_text(r: &RunReport, key: &str) -> String {
    match r.robot.get(key) {
        None | Some(Json::Null) => "none".into(),
        Some(Json::Bool(true)) => "yes".into(),
        Some(Json::Bool(false)) => "no".into(),
        Some(Json::String(s)) => s.clone(),
        Some(v) => v.to_string(),
    }
}

/// How the mission ended: the outcome and why, the mission time it took, the final flags,
/// and the robot's judgement of it (inside the goal, collisions).
pub(crate) fn outcome(a: &RunReport, b: &RunReport) -> Option<Difference> {
    let outcome = |r: &RunReport| match r.reason.is_empty() {
        true => r.outcome.to_string(),
        false => format!("{}: {}", r.outcome, r.reason),
    };
    let flags = |r: &RunReport| match r.flags.is_empty() {
        true => "none".to_string(),
        false => r.flags.join(", "),
    };
    rows([
        Row {
            label: "outcome",
            a: outcome(a),
            b: outcome(b),
        },
        Row {
            label: "duration",
            a: secs(a.duration_ms),
            b: secs(b.duration_ms),
        },
        Row {
            label: "flags",
            a: flags(a),
            b: flags(b),
        },
        Row {
            label: "inside goal",
            a: robot_text(a, "inside_goal"),
            b: robot_text(b, "inside_goal"),
        },
        Row {
            label: "collisions",
            a: robot_text(a, "collisions"),
            b: robot_text(b, "collisions"),
        },
        Row {
            label: "judgement",
            a: robot_text(a, "judgement"),
            b: robot_text(b, "judgement"),
        },
    ])
}

/// A pose `[x, y, heading_rad]` as the robot wrote it, if it is one.
fn pose(v: Option<&Json>) -> Option<[f64; 3]> {
    match v?.as_array()?.as_slice() {
        [x, y, h] => Some([x.as_f64()?, y.as_f64()?, h.as_f64()?]),
        _ => None,
    }
}

/// `(x, y, heading°)`.
fn pose_text(p: [f64; 3]) -> String {
    format!("({:.3}, {:.3}, {:.1}°)", p[0], p[1], p[2].to_degrees())
}

/// How far `b` turned from `a`, in degrees, within ±180°.
pub(crate) fn heading_change_deg(a: f64, b: f64) -> f64 {
    let d = (b - a).to_degrees().rem_euclid(360.0);
    if d > 180.0 {
        d - 360.0
    } else {
        d
    }
}

/// Where the cart stopped in each run: both poses, how far apart, how much turned.
pub(crate) fn final_pose(a: &RunReport, b: &RunReport) -> Option<Difference> {
    let (ja, jb) = (a.robot.get("final_pose"), b.robot.get("final_pose"));
    match (pose(ja), pose(jb)) {
        (Some(pa), Some(pb)) => {
            // the same within rounding: a run read back from its events file is equal to
            // the bit, another machine's floats may not be
            if pa.iter().zip(&pb).all(|(x, y)| (x - y).abs() <= 1e-9) {
                return None;
            }
            let distance = (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
            // -0.0° is no turn
            let turn = match heading_change_deg(pa[2], pb[2]) {
                t if t.abs() < 0.05 => 0.0,
                t => t,
            };
            Some(Difference {
                summary: format!("{distance:.3} m, {turn:+.1}°"),
                lines: vec![
                    format!("  a: {}", pose_text(pa)),
                    format!("  b: {}", pose_text(pb)),
                    format!("  {distance:.3} m apart, heading {turn:+.1}°"),
                ],
                json: json!({"a": pa, "b": pb, "distance_m": distance, "heading_deg": turn}),
            })
        }
        _ => {
            let (ja, jb) = (ja.filter(|v| !v.is_null()), jb.filter(|v| !v.is_null()));
            if ja == jb {
                return None;
            }
            let text = |v: Option<&Json>| match (pose(v), v) {
                (Some(p), _) => pose_text(p),
                (None, Some(v)) => v.to_string(),
                (None, None) => "none".into(),
            };
            Some(Difference {
                summary: format!("{} -> {}", text(ja), text(jb)),
                lines: vec![format!("  a: {}", text(ja)), format!("  b: {}", text(jb))],
                json: json!({"a": ja, "b": jb}),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::run::{FaultKind, NodeBuild, Outcome};

    fn report(seed: u64, pose: [f64; 3]) -> RunReport {
        let mut r = RunReport::new("docking", Outcome::Succeeded, "");
        r.duration_ms = 63_650;
        r.robot.insert("final_pose".into(), json!(pose));
        r.robot.insert("seed".into(), json!(seed));
        r.robot.insert("inside_goal".into(), json!(true));
        r.provenance = Some(Provenance {
            marie: Some(Build::new("0.1.0", Some("aaaa"), Some(false))),
            seed: Some(seed),
            speed: Some("max".into()),
            nodes: vec![NodeBuild {
                node: "embedded".into(),
                marie: None,
            }],
            ..Provenance::default()
        });
        r
    }

    #[test]
    fn a_report_is_the_same_as_itself_in_every_aspect() {
        let r = report(3, [6.0, -0.4, 3.07]);
        assert_eq!(run(&r, &r), None);
        assert_eq!(faults(&r, &r), None);
        assert_eq!(outcome(&r, &r), None);
        assert_eq!(final_pose(&r, &r), None);
        let build = r.provenance.as_ref().and_then(|p| p.marie.as_ref());
        assert_eq!(marie(build, build), None);
        assert_eq!(
            marie_note(build, build),
            None,
            "a clean build is the same code"
        );
    }

    #[test]
    fn another_seed_is_a_row_of_the_run_section() {
        let diff = run(&report(3, [0.0; 3]), &report(4, [0.0; 3])).expect("differs");
        assert_eq!(diff.summary, "seed 3 -> 4");
        assert_eq!(diff.lines, vec!["  seed: 3 -> 4"]);
        assert_eq!(diff.json["seed"], json!({"a": "3", "b": "4"}));
    }

    #[test]
    fn poses_are_told_with_their_distance_and_the_heading_turned() {
        let (a, b) = (report(3, [1.0, 1.0, 0.1]), report(3, [4.0, 5.0, 0.1]));
        let diff = final_pose(&a, &b).expect("differs");
        assert_eq!(diff.summary, "5.000 m, +0.0°");
        assert_eq!(diff.lines[2], "  5.000 m apart, heading +0.0°");
        assert_eq!(diff.json["distance_m"], 5.0);
        // headings wrap: from 179° to -179° is a turn of 2°
        let turn = heading_change_deg(179f64.to_radians(), (-179f64).to_radians());
        assert!((turn - 2.0).abs() < 1e-9, "{turn}");
        let turn = heading_change_deg((-179f64).to_radians(), 179f64.to_radians());
        assert!((turn + 2.0).abs() < 1e-9, "{turn}");
    }

    #[test]
    fn a_pose_that_is_not_one_is_shown_as_written_and_no_pose_on_both_sides_is_the_same() {
        let mut a = report(3, [0.0; 3]);
        let mut b = a.clone();
        a.robot.insert("final_pose".into(), json!("garbage"));
        let diff = final_pose(&a, &b).expect("differs");
        assert_eq!(diff.lines[0], "  a: \"garbage\"");
        a.robot.insert("final_pose".into(), Json::Null);
        b.robot.remove("final_pose");
        assert_eq!(final_pose(&a, &b), None);
    }

    #[test]
    fn the_outcome_section_names_what_changed_in_how_the_run_ended() {
        let a = report(3, [0.0; 3]);
        let mut b = a.clone();
        b.outcome = Outcome::Failed;
        b.reason = "deadline".into();
        b.robot.insert("inside_goal".into(), json!(false));
        let diff = outcome(&a, &b).expect("differs");
        assert_eq!(diff.summary, "outcome, inside goal yes -> no");
        assert_eq!(
            diff.lines,
            vec![
                "  outcome: succeeded -> failed: deadline",
                "  inside goal: yes -> no"
            ]
        );
    }

    #[test]
    fn faults_are_listed_for_each_run() {
        let a = report(1, [0.0; 3]);
        let mut b = a.clone();
        b.record_faults([FaultRecord {
            at_ms: 20_000,
            fault: FaultKind::Kill,
            operation: "wall-follower".into(),
            actor: "0.18".into(),
            node: Some("embedded".into()),
            error: None,
            lasting_ms: None,
            healed_at_ms: None,
        }]);
        let diff = faults(&a, &b).expect("differs");
        assert_eq!(diff.summary, "0 -> 1");
        assert_eq!(
            diff.lines,
            vec![
                "  a: none",
                "  b: 1 fault",
                "    20.000 s kill wall-follower: 0.18 on embedded"
            ]
        );
        assert_eq!(diff.json["b"]["faults"][0]["fault"], "kill");
    }

    #[test]
    fn a_build_of_another_commit_or_unknown_is_a_difference() {
        let x = Build::new("0.1.0", Some("aaaaaaaaaaaaaaaa"), Some(false));
        let y = Build::new("0.1.0", Some("bbbbbbbbbbbbbbbb"), Some(false));
        let diff = marie(Some(&x), Some(&y)).expect("differs");
        assert_eq!(diff.summary, "commit aaaaaaaaaaaa -> bbbbbbbbbbbb");
        assert_eq!(diff.lines[1], "  b: 0.1.0 (commit bbbbbbbbbbbbbbbb)");
        assert_eq!(
            marie(None, Some(&y)).expect("differs").summary,
            "unknown in a"
        );
        let dirty = Build::new("0.1.0", Some("aaaa"), Some(true));
        assert!(marie_note(Some(&dirty), Some(&dirty)).is_some());
    }

    #[test]
    fn a_report_without_provenance_is_compared_on_what_it_has() {
        let a = report(3, [0.0; 3]);
        let mut old = a.clone();
        old.provenance = None;
        let diff = with_provenance(&old, &a, "the files", |_, _| None).expect("differs");
        assert_eq!(
            diff.lines,
            vec!["  a has no provenance (an older report): the files unknown"]
        );
        assert_eq!(with_provenance(&old, &old, "the files", |_, _| None), None);
        // the seed is also the robot's: still compared
        let mut other = a.clone();
        other.provenance = None;
        other.robot.insert("seed".into(), json!(9));
        let diff = run(&a, &other).expect("differs");
        assert!(
            diff.lines.contains(&"  seed: 3 -> 9".to_string()),
            "{diff:?}"
        );
    }
}

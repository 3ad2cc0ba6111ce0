//! `marie run --replay REPORT.json`: run a past run again from its report alone — the
//! mission, world and node config from the texts its provenance holds, its seed, its planned
//! faults and chaos from its command line — on the embedded node, and say whether the
//! outcome, the bindings, the final pose and the parameters match.
//!
//! Why from the texts and not the paths: the files may have changed or gone since; the
//! report holds what ran. A report of another marie commit is replayed with a warning
//! naming both: the same inputs may then give another run, and the table shows where.

use super::error::BadInput;
use marie::cluster::fault::FaultSpec;
use marie::report::RunReport;
use marie::run::{Aim, Build, FileRole, ParamSetting, ParamSource, Provenance};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A report to replay, its files written out to a directory of their own.
#[derive(Debug)]
pub(crate) struct Replay {
    /// The report replayed.
    pub path: PathBuf,
    /// The report as it was written.
    pub report: RunReport,
    /// Its provenance.
    pub provenance: Provenance,
    /// Where its files were written (removed when the replay is dropped).
    dir: PathBuf,
    /// The mission, written out.
    pub mission: PathBuf,
    /// The world, written out, if the run had one.
    pub world: Option<PathBuf>,
    /// The node config, written out, if the run had one.
    pub node: Option<PathBuf>,
}

impl Drop for Replay {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl Replay {
    /// Read `path` and write its files out: refused (exit 2) when it is not a report, or
    /// one without provenance or without its mission's text.
    pub(crate) fn load(path: &Path) -> Result<Replay, BadInput> {
        let bad = |why: String| BadInput(format!("--replay {}: {why}", path.display()));
        let text =
            std::fs::read_to_string(path).map_err(|e| bad(format!("cannot be read: {e}")))?;
        let report: RunReport = serde_json::from_str(&text)
            .map_err(|e| bad(format!("is not a run report (`marie run --report`): {e}")))?;
        let Some(provenance) = report.provenance.clone() else {
            return Err(bad(
                "holds no provenance (a report of an older marie): there is nothing to \
                 replay from"
                    .into(),
            ));
        };
        if provenance.file(FileRole::Mission).is_none() {
            return Err(bad(
                "its provenance holds no mission file: the run was not started from one".into(),
            ));
        }
        let dir = std::env::temp_dir().join(format!(
            "marie-replay-{}-{}",
            std::process::id(),
            provenance.started_unix_ms
        ));
        let write = |role: FileRole| -> Result<Option<PathBuf>, BadInput> {
            let Some(file) = provenance.file(role) else {
                return Ok(None);
            };
            // the file's own name, in a directory of its role: a diagnostic names the file
            // the user knows
            let name = Path::new(&file.path)
                .file_name()
                .map_or_else(|| format!("{role}.toml").into(), |n| n.to_os_string());
            let at = dir.join(role.name()).join(name);
            std::fs::create_dir_all(at.parent().unwrap_or(&dir))
                .and_then(|()| std::fs::write(&at, &file.text))
                .map_err(|e| BadInput(format!("cannot write {}: {e}", at.display())))?;
            Ok(Some(at))
        };
        let mut replay = Replay {
            path: path.to_path_buf(),
            report,
            mission: PathBuf::new(),
            world: None,
            node: None,
            dir: dir.clone(),
            provenance: provenance.clone(),
        };
        replay.mission = write(FileRole::Mission)?.unwrap_or_default();
        replay.world = write(FileRole::World)?;
        // a cluster's node configs are its nodes': the replay runs on the built-in node
        if provenance.file(FileRole::Cluster).is_none() {
            replay.node = write(FileRole::Node)?;
        }
        Ok(replay)
    }

    /// The line that says what is replayed.
    pub(crate) fn header(&self) -> String {
        let p = &self.provenance;
        let mut files: Vec<String> = p
            .files
            .iter()
            .map(|f| format!("{} {}", f.role, f.path))
            .collect();
        if files.is_empty() {
            files.push("no file".into());
        }
        format!(
            "replay of {} (mission `{}`, {}, seed {}, {}; run {})",
            self.path.display(),
            self.report.mission,
            files.join(", "),
            p.seed.map_or_else(|| "none".into(), |s| s.to_string()),
            p.marie
                .as_ref()
                .map_or_else(|| "marie unknown".into(), |b| format!("marie {b}")),
            if p.started.is_empty() {
                "at an unknown time"
            } else {
                &p.started
            }
        )
    }

    /// A warning when the report was made by another marie commit than `this` — or when it
    /// ran on several nodes and is replayed on one.
    pub(crate) fn warnings(&self, this: &Build) -> Vec<String> {
        let mut out = Vec::new();
        match &self.provenance.marie {
            Some(theirs) if theirs.other_commit(this) => out.push(format!(
                "warning: {} was made by marie {theirs}; this is marie {this}: the replay \
                 may differ",
                self.path.display()
            )),
            Some(_) => {}
            None => out.push(format!(
                "warning: {} does not say which marie made it; this is marie {this}",
                self.path.display()
            )),
        }
        if self.provenance.nodes.len() > 1 || self.provenance.file(FileRole::Cluster).is_some() {
            let nodes: Vec<&str> = self
                .provenance
                .nodes
                .iter()
                .map(|n| n.node.as_str())
                .collect();
            out.push(format!(
                "warning: the run was on a cluster ({}); its replay runs on the embedded \
                 node alone, so the bindings' nodes differ",
                nodes.join(", ")
            ));
        }
        out
    }

    /// What its command planned — `--fault`s, `--chaos SEED`, `--chaos-dms` — read back by
    /// the command's own parser, and a warning for what cannot be replayed: a node's fault
    /// (`stop-node`, `freeze-node`, `partition`) needs `marie up`'s processes, and a replay
    /// runs on one; a command this marie does not parse (another version's) plans nothing.
    pub(crate) fn planned(&self) -> (Planned, Vec<String>) {
        planned(&self.provenance.command)
    }

    /// Compare the replay's report `now` with the report replayed.
    pub(crate) fn compare(&self, now: &RunReport) -> Comparison {
        let was = &self.report;
        let mut rows = Vec::new();
        rows.push(Row::new(
            "outcome",
            outcome_text(was),
            outcome_text(now),
            was.outcome == now.outcome && was.reason == now.reason,
        ));
        let (b_was, b_now) = (bindings(was), bindings(now));
        rows.push(Row::new(
            "bindings",
            join_set(&b_was),
            join_set(&b_now),
            b_was == b_now,
        ));
        let (p_was, p_now) = (pose(was), pose(now));
        let same_pose = match (&p_was, &p_now) {
            (Some(a), Some(b)) => {
                a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-9)
            }
            (None, None) => true,
            _ => false,
        };
        rows.push(Row::new(
            "final pose",
            pose_text(&p_was),
            pose_text(&p_now),
            same_pose,
        ));
        let (q_was, q_now) = (parameters(was), parameters(now));
        rows.push(Row::new(
            "parameters",
            format!("{} values", q_was.len()),
            match q_was == q_now {
                true => format!("{} values", q_now.len()),
                false => {
                    let differ: Vec<&String> = q_was.symmetric_difference(&q_now).collect();
                    format!(
                        "{} values; differ: {}",
                        q_now.len(),
                        differ
                            .iter()
                            .take(4)
                            .map(|s| s.as_str())
                            .collect::<Vec<_>>()
                            .join("; ")
                    )
                }
            },
            q_was == q_now,
        ));
        Comparison { rows }
    }
}

/// The faults and chaos a run's command planned ([`Replay::planned`]).
#[derive(Debug, Default, PartialEq)]
pub(crate) struct Planned {
    /// Its operation faults.
    pub faults: Vec<FaultSpec>,
    /// Its chaos seed.
    pub chaos: Option<u64>,
    /// Whether the datamanagers were among the chaos' victims.
    pub chaos_dms: bool,
}

/// What `command` planned, parsed as `marie` parses it; warnings for what is not replayed.
fn planned(command: &[String]) -> (Planned, Vec<String>) {
    use clap::Parser;
    let (faults, chaos, chaos_dms) = match super::Cli::try_parse_from(command) {
        Ok(cli) => match cli.command {
            super::Command::Run(run) => (run.faults, run.chaos, run.chaos_dms),
            super::Command::Up(up) => (up.faults, None, false),
            _ => (Vec::new(), None, false),
        },
        Err(e) => {
            let why = e.to_string();
            let why = why.lines().next().unwrap_or_default();
            let warning = format!(
                "warning: the run's command line does not parse here ({why}): no fault \
                 or chaos of it is replayed"
            );
            return (Planned::default(), vec![warning]);
        }
    };
    let (faults, node_faults): (Vec<FaultSpec>, Vec<FaultSpec>) = faults
        .into_iter()
        .partition(|f| f.kind.aim() == Aim::Operation);
    let warnings = node_faults
        .iter()
        .map(|f| {
            format!("warning: the run's --fault {f} is a node's fault: not replayed on one process")
        })
        .collect();
    let planned = Planned {
        faults,
        chaos,
        chaos_dms,
    };
    (planned, warnings)
}

fn outcome_text(r: &RunReport) -> String {
    match r.reason.is_empty() {
        true => r.outcome.to_string(),
        false => format!("{}: {}", r.outcome, r.reason),
    }
}

/// Every instance the run's actions ran: `name#version@node`.
fn bindings(r: &RunReport) -> BTreeSet<String> {
    r.actions
        .iter()
        .flat_map(|a| &a.operations)
        .map(|o| format!("{}#{}@{}", o.name, o.version, o.node))
        .collect()
}

fn join_set(s: &BTreeSet<String>) -> String {
    match s.len() {
        0 => "none".into(),
        n => format!("{n}: {}", s.iter().cloned().collect::<Vec<_>>().join(", ")),
    }
}

fn pose(r: &RunReport) -> Option<Vec<f64>> {
    r.robot
        .get("final_pose")?
        .as_array()?
        .iter()
        .map(serde_json::Value::as_f64)
        .collect()
}

fn pose_text(p: &Option<Vec<f64>>) -> String {
    match p {
        Some(v) if v.len() == 3 => format!("({:.4}, {:.4}, {:.2}°)", v[0], v[1], v[2].to_degrees()),
        Some(v) => format!("{v:?}"),
        None => "none".into(),
    }
}

/// The values the mission and the defaults gave, as `action/operation.name = value (source)`
/// (re-parameterizations are an outsider's doing, not the run's inputs).
fn parameters(r: &RunReport) -> BTreeSet<String> {
    let Some(p) = &r.provenance else {
        return BTreeSet::new();
    };
    p.parameters
        .iter()
        .filter(|s| s.source != ParamSource::Reparameterized)
        .map(setting_text)
        .collect()
}

fn setting_text(s: &ParamSetting) -> String {
    format!(
        "{}/{}.{} = {} ({})",
        s.action, s.operation, s.name, s.value, s.source
    )
}

/// One compared property.
#[derive(Debug)]
pub(crate) struct Row {
    /// What is compared.
    pub what: &'static str,
    /// In the report replayed.
    pub was: String,
    /// In the replay.
    pub now: String,
    /// Whether they match.
    pub matches: bool,
}

impl Row {
    fn new(what: &'static str, was: String, now: String, matches: bool) -> Row {
        Row {
            what,
            was,
            now,
            matches,
        }
    }
}

/// How a replay compares with the report it replayed.
#[derive(Debug)]
pub(crate) struct Comparison {
    /// Outcome, bindings, final pose, parameters.
    pub rows: Vec<Row>,
}

impl Comparison {
    /// Whether everything matches.
    pub(crate) fn matches(&self) -> bool {
        self.rows.iter().all(|r| r.matches)
    }

    /// The table: one line per property (`match` or `DIFFERS`, then what the report said
    /// and, when it differs, what the replay gave), and the verdict.
    pub(crate) fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        for r in &self.rows {
            match r.matches {
                true => out.push(format!("  {:<11} match    {}", r.what, r.was)),
                false => {
                    out.push(format!("  {:<11} DIFFERS  was: {}", r.what, r.was));
                    out.push(format!("  {:<11}          now: {}", "", r.now));
                }
            }
        }
        out.push(match self.matches() {
            true => "replay: matches the report (outcome, bindings, final pose, parameters)".into(),
            false => {
                let differ: Vec<&str> = self
                    .rows
                    .iter()
                    .filter(|r| !r.matches)
                    .map(|r| r.what)
                    .collect();
                format!("replay: differs from the report in {}", differ.join(", "))
            }
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_lines_faults_and_chaos_are_read_in_both_spellings() {
        let cmd: Vec<String> = [
            "marie",
            "run",
            "m.toml",
            "--fault",
            "kill:a@1",
            "--fault=hang:b@2",
            "--fault",
            "stop-node:n@3",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let (p, warnings) = planned(&cmd);
        let faults: Vec<String> = p.faults.iter().map(|f| f.to_string()).collect();
        assert_eq!(faults, vec!["kill:a@1", "hang:b@2"]);
        assert_eq!(p.chaos, None);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("stop-node:n@3"), "{warnings:?}");
        let chaos: Vec<String> = ["marie", "run", "m.toml", "--chaos=7", "--chaos-dms"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let (p, _) = planned(&chaos);
        assert_eq!((p.chaos, p.chaos_dms), (Some(7), true));
        // another version's flags: nothing planned, and said
        let other: Vec<String> = ["marie", "run", "m.toml", "--warp", "9"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let (p, warnings) = planned(&other);
        assert_eq!(p, Planned::default());
        assert!(warnings[0].contains("does not parse"), "{warnings:?}");
    }
}

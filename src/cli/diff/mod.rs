//! `marie diff A.json B.json`: what differs between two runs, from their reports — which
//! marie ran them, the run's settings (mission, seed, speed, nodes), the files they read (a
//! unified diff of their texts), the parameter values, the bindings and rebinds, the faults,
//! the outcome and the final pose. Exit 0 when the runs are the same in every aspect, 1
//! when they differ (as `diff` does), 2 when a file is not a report.
//!
//! Why: the thesis complained that old experiments could not be compared with new ones. A
//! report carries what ran ([`Provenance`](marie::run::Provenance)); this says
//! what changed between two of them, so "why did this run end elsewhere?" starts from the
//! answer to "what did I change?".
//!
//! Each aspect is compared by a pure function ([`aspects`], [`files`], [`parameters`],
//! [`bindings`]); this module reads the reports and prints.

mod aspects;
mod bindings;
mod files;
mod parameters;

use super::error::BadInput;
use aspects::Difference;
use marie::report::RunReport;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags of `marie diff`.
#[derive(clap::Args, Debug)]
pub(crate) struct DiffArgs {
    /// The first run's report (`marie run --report`'s JSON).
    #[arg(value_name = "A.json")]
    pub a: PathBuf,
    /// The second run's report.
    #[arg(value_name = "B.json")]
    pub b: PathBuf,
    /// Print the differences as one JSON object (`a`, `b`, `differ`: aspect -> what
    /// differs, `same`: the aspects that do not, `notes`) instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Compare the two reports, print what differs; exit 1 when anything does.
pub(crate) fn diff(args: DiffArgs) -> anyhow::Result<ExitCode> {
    let a = load(&args.a)?;
    let b = load(&args.b)?;
    let comparison = compare(&a, &b);
    if args.json {
        let runs = json!({"a": run_json(&args.a, &a), "b": run_json(&args.b, &b)});
        println!("{}", comparison.json(runs));
    } else {
        println!("{}", header("a", &args.a, &a));
        println!("{}", header("b", &args.b, &b));
        for line in comparison.lines() {
            println!("{line}");
        }
    }
    Ok(match comparison.same() {
        true => ExitCode::SUCCESS,
        false => ExitCode::from(1),
    })
}

/// The report at `path`; refused (exit 2), naming the file, when it cannot be read or is
/// not a report.
fn load(path: &Path) -> Result<RunReport, BadInput> {
    let bad = |why: String| BadInput(format!("{}: {why}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot be read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| {
        bad(format!(
            "is not a run report (`marie run --report`'s JSON): {e}"
        ))
    })
}

/// `a: PATH: mission `docking`, started …, marie …`: which run a side is.
fn header(side: &str, path: &Path, r: &RunReport) -> String {
    let what = match &r.provenance {
        None => "no provenance".to_string(),
        Some(p) => {
            let started = match p.started.is_empty() {
                true => "at an unknown time",
                false => &p.started,
            };
            let build = p
                .marie
                .as_ref()
                .map_or_else(|| "unknown".into(), |b| b.to_string());
            format!("started {started}, marie {build}")
        }
    };
    format!(
        "{side}: {}: mission `{}`, {what}",
        path.display(),
        r.mission
    )
}

/// The same for `--json`.
fn run_json(path: &Path, r: &RunReport) -> serde_json::Value {
    let p = r.provenance.as_ref();
    json!({
        "report": path.display().to_string(),
        "mission": r.mission,
        "started": p.map(|p| &p.started),
        "marie": p.and_then(|p| p.marie.as_ref()),
    })
}

/// One aspect of the two runs, compared.
#[derive(Debug)]
struct Aspect {
    /// Its name, as its section's header says it (`final pose`).
    name: &'static str,
    /// How the runs differ in it; `None` when they do not.
    diff: Option<Difference>,
}

/// Every aspect of two runs compared, and what the reader should know besides.
#[derive(Debug)]
struct Comparison {
    aspects: Vec<Aspect>,
    notes: Vec<String>,
}

/// Compare `a` with `b` in every aspect, in the order the sections are printed.
fn compare(a: &RunReport, b: &RunReport) -> Comparison {
    let (pa, pb) = (a.provenance.as_ref(), b.provenance.as_ref());
    let aspects = vec![
        Aspect {
            name: "marie",
            diff: aspects::with_provenance(a, b, "which marie ran it is", |x, y| {
                aspects::marie(x.marie.as_ref(), y.marie.as_ref())
            }),
        },
        Aspect {
            name: "run",
            diff: aspects::run(a, b),
        },
        Aspect {
            name: "files",
            diff: aspects::with_provenance(a, b, "the files it read are", files::compare),
        },
        Aspect {
            name: "parameters",
            diff: aspects::with_provenance(a, b, "its parameter values are", parameters::compare),
        },
        Aspect {
            name: "bindings",
            diff: bindings::compare(a, b),
        },
        Aspect {
            name: "faults",
            diff: aspects::faults(a, b),
        },
        Aspect {
            name: "outcome",
            diff: aspects::outcome(a, b),
        },
        Aspect {
            name: "final pose",
            diff: aspects::final_pose(a, b),
        },
    ];
    let mut notes = Vec::new();
    for (side, p) in [("a", pa), ("b", pb)] {
        if p.is_none() {
            notes.push(format!(
                "{side} has no provenance (an older report): it is compared on what it has"
            ));
        }
    }
    // a report compared with itself is one run: nothing to warn of
    let one_run = pa
        .zip(pb)
        .is_some_and(|(x, y)| x.started_unix_ms != 0 && x.started_unix_ms == y.started_unix_ms);
    notes.extend(
        aspects::marie_note(
            pa.and_then(|p| p.marie.as_ref()),
            pb.and_then(|p| p.marie.as_ref()),
        )
        .filter(|_| !one_run),
    );
    Comparison { aspects, notes }
}

impl Comparison {
    /// The aspects in which the runs do not differ, in the order compared.
    fn same_aspects(&self) -> Vec<&'static str> {
        self.aspects
            .iter()
            .filter(|a| a.diff.is_none())
            .map(|a| a.name)
            .collect()
    }

    /// Whether the runs are the same in every aspect.
    fn same(&self) -> bool {
        self.aspects.iter().all(|a| a.diff.is_none())
    }

    /// The text after the two header lines: the notes, a summary of the aspects that
    /// differ (one line each, as `git diff --stat`), a section for each, and the aspects
    /// that are the same on one line.
    fn lines(&self) -> Vec<String> {
        let mut out = self.notes.clone();
        let differ: Vec<(&str, &Difference)> = self
            .aspects
            .iter()
            .filter_map(|a| a.diff.as_ref().map(|d| (a.name, d)))
            .collect();
        let width = differ.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
        for (name, d) in &differ {
            out.push(format!(" {name:<width$} | {}", d.summary));
        }
        out.push(match differ.len() {
            0 => "the runs are the same in every aspect".to_string(),
            n => format!("{n} of {} aspects differ", self.aspects.len()),
        });
        for (name, d) in &differ {
            out.push(String::new());
            out.push(format!("{name}:"));
            out.extend(d.lines.iter().cloned());
        }
        let same = self.same_aspects();
        if !same.is_empty() {
            if !differ.is_empty() {
                out.push(String::new());
            }
            out.push(format!("same: {}", same.join(", ")));
        }
        out
    }

    /// The comparison as one JSON object: `runs`' `a` and `b`, `differ` (aspect → what
    /// differs), `same` (the aspects that do not), `notes`.
    fn json(&self, runs: serde_json::Value) -> serde_json::Value {
        let mut differ = serde_json::Map::new();
        for a in &self.aspects {
            if let Some(d) = &a.diff {
                differ.insert(a.name.to_string(), d.json.clone());
            }
        }
        let same = self.same_aspects();
        json!({
            "a": runs["a"],
            "b": runs["b"],
            "differ": differ,
            "same": same,
            "notes": self.notes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::run::{Outcome, Provenance};

    fn report(seed: u64) -> RunReport {
        let mut r = RunReport::new("docking", Outcome::Succeeded, "");
        r.robot.insert("final_pose".into(), json!([1.0, 2.0, 0.5]));
        r.provenance = Some(Provenance {
            seed: Some(seed),
            started: "2026-11-27T17:50:00.123Z".into(),
            ..Provenance::default()
        });
        r
    }

    #[test]
    fn a_report_compared_with_itself_is_the_same_in_every_aspect() {
        let r = report(3);
        let c = compare(&r, &r);
        assert!(c.same());
        assert_eq!(
            c.lines(),
            vec![
                "the runs are the same in every aspect",
                "same: marie, run, files, parameters, bindings, faults, outcome, final pose"
            ]
        );
        assert_eq!(c.json(json!({}))["differ"], json!({}));
    }

    #[test]
    fn the_summary_comes_first_then_a_section_per_aspect_that_differs_then_the_same() {
        let c = compare(&report(3), &report(4));
        assert!(!c.same());
        assert_eq!(
            c.lines(),
            vec![
                " run | seed 3 -> 4",
                "1 of 8 aspects differ",
                "",
                "run:",
                "  seed: 3 -> 4",
                "",
                "same: marie, files, parameters, bindings, faults, outcome, final pose",
            ]
        );
        assert_eq!(c.json(json!({}))["differ"]["run"]["seed"]["b"], "4");
    }

    #[test]
    fn a_report_without_provenance_is_noted_and_compared_on_what_it_has() {
        let mut old = report(3);
        old.provenance = None;
        let c = compare(&old, &old);
        assert!(c.same(), "{:?}", c.lines());
        assert_eq!(
            c.notes,
            vec![
                "a has no provenance (an older report): it is compared on what it has",
                "b has no provenance (an older report): it is compared on what it has"
            ]
        );
        let c = compare(&old, &report(3));
        let lines = c.lines();
        assert!(lines.contains(&"marie:".to_string()), "{lines:#?}");
        assert!(
            lines.contains(
                &"  a has no provenance (an older report): which marie ran it is unknown"
                    .to_string()
            ),
            "{lines:#?}"
        );
    }

    #[test]
    fn a_file_that_is_not_a_report_is_refused_naming_it() {
        let dir = std::env::temp_dir().join(format!("marie-diff-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temp dir");
        let path = dir.join("not-a-report.json");
        std::fs::write(&path, r#"{"hello": 1}"#).expect("written");
        let e = load(&path).expect_err("refused");
        assert!(
            e.0.starts_with(&format!("{}: is not a run report", path.display())),
            "{e}"
        );
        let e = load(&dir.join("missing.json")).expect_err("refused");
        assert!(e.0.contains("missing.json: cannot be read"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

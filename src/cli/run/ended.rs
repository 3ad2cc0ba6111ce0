//! What a run leaves once its node has stopped: its report, the files written while it ran,
//! its picture — told as the end lines, written as the outputs asked for, judged as the
//! exit code — and, with `--monitor`, its page, which stays up until Ctrl-C.

use super::page::LivePage;
use super::plan::Plan;
use super::taps::FilesWritten;
use crate::cli::output::{end_line, outcome_line, verdict_line};
use anyhow::Context;
use marie::clock::Paced;
use marie::cluster::net::Transport;
use marie::report::RunReport;
use marie::run::Outcome;
use marie_missions::picture::Picture;
use marie_missions::world::World;
use std::path::Path;
use std::process::ExitCode;

/// Pixels per metre of `--svg` pictures.
const SVG_SCALE: f64 = 50.0;

/// A run that has ended: its node stopped, its outputs not yet written.
pub(super) struct Ended {
    pub(super) plan: Plan,
    /// The run's report (with the robot's fields, null without one).
    pub(super) report: RunReport,
    /// How the files written while it ran ended.
    pub(super) files: FilesWritten,
    /// The robot's run drawn, with `--svg`.
    pub(super) picture: Option<Picture>,
    /// The robot's world, when one ran.
    pub(super) world: Option<World>,
    /// The run's page, with `--monitor`.
    pub(super) page: Option<LivePage>,
    /// The cluster's membership, kept while the page is up.
    pub(super) transport: Option<Transport>,
    /// The pacer, stopped while the page is read.
    pub(super) pace: Option<Paced>,
}

impl Ended {
    /// How the mission ended, its outcome and verdict.
    pub(super) fn tell(&self) {
        if !self.plan.says() {
            return;
        }
        println!("{}", end_line(&self.report));
        if self.world.is_some() {
            println!("{}", outcome_line(&self.report));
        }
        if let Some(line) = verdict_line(&self.report) {
            println!("{line}");
        }
    }

    /// Write every output asked for, even when one of them cannot be written; whether all
    /// were.
    pub(super) fn write_outputs(&self) -> bool {
        let mut written = true;
        if let Some(Err(e)) = &self.files.events {
            eprintln!("marie: {e:#}");
            written = false;
        }
        if let Some(Err(e)) = &self.files.mcap {
            eprintln!("marie: {e:#}");
            written = false;
        }
        if let Some(p) = &self.plan.outputs.report {
            if let Err(e) = write_report(p, &self.report) {
                eprintln!("marie: {e:#}");
                written = false;
            }
        }
        let svg = &self.plan.outputs.svg;
        if let (Some(p), Some(picture), Some(world)) = (svg, &self.picture, &self.world) {
            let svg = picture.render(world, SVG_SCALE);
            if let Err(e) = std::fs::write(p, svg) {
                eprintln!("marie: cannot write the picture to {}: {e}", p.display());
                written = false;
            }
        }
        written
    }

    /// The exit code: 0 when the mission succeeded and every output was `written` — for a
    /// replay, when it matched (whatever the outcome it matched), said in its table.
    pub(super) fn verdict(&self, written: bool) -> ExitCode {
        let Some(replay) = &self.plan.replay else {
            return match (self.report.outcome, written) {
                (Outcome::Succeeded, true) => ExitCode::SUCCESS,
                _ => ExitCode::from(1),
            };
        };
        let comparison = replay.compare(&self.report);
        for line in comparison.lines() {
            println!("{line}");
        }
        match (comparison.matches(), written) {
            (true, true) => ExitCode::SUCCESS,
            _ => ExitCode::from(1),
        }
    }

    /// The outputs are written: the mission is over for whoever runs it. The page stays up
    /// for as long as the user reads it; then the cluster is left.
    pub(super) async fn close(self) {
        let Ended {
            plan,
            page,
            transport,
            pace,
            ..
        } = self;
        match page {
            None => plan.mission_over.set(),
            Some(page) => {
                // virtual time need not run on while the page is read
                drop(pace);
                page.linger(&plan.mission_over).await;
            }
        }
        if let Some(t) = transport {
            t.stop().await;
        }
    }
}

/// Write `report` as pretty JSON to `path`.
fn write_report(path: &Path, report: &RunReport) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(report)?;
    std::fs::write(path, json + "\n")
        .with_context(|| format!("cannot write the report to {}", path.display()))
}

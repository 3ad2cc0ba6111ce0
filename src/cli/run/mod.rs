//! `marie run MISSION`: run a mission on the embedded node (or as a member of a cluster),
//! print its progress and outcome, write the report, the events, the MCAP file and the
//! picture, and serve its live page.
//!
//! A run is a [`Plan`] — what the command line asks for, checked before
//! anything starts — and a [`Session`] that carries it out: started, made
//! ready, followed while the mission runs, and [`Ended`](ended::Ended).
//!
//! - `flags.rs` — the flags, as clap parses them;
//! - `plan.rs` — the plan made of them: every refusal that needs no node;
//! - `session.rs` — the node started, the mission run, the node stopped;
//! - `ready.rs` — between the node's start and the mission's: what only the node can
//!   refuse, the provenance, the first lines;
//! - `taps.rs` — the followers of the run's events: lines, files, page, relays;
//! - `page.rs` — the `--monitor` page, up until Ctrl-C;
//! - `ended.rs` — the end lines, the outputs written, the exit code;
//! - `mission_over.rs` — when `marie up --run` may let a Ctrl-C be the run's;
//! - `kept.rs` — the report handed back to `marie up --runs`.

mod ended;
mod flags;
mod kept;
mod mission_over;
mod page;
mod plan;
mod ready;
mod session;
mod taps;

pub(crate) use flags::RunArgs;
pub(crate) use kept::KeptReport;
pub(crate) use mission_over::MissionOver;

use plan::Plan;
use session::Session;
use std::process::ExitCode;

/// Run the mission; exit 0 when it succeeded and every output was written, else 1 (a
/// replay: when it matched); a refusal is exit 2.
pub(crate) async fn run(flags: RunArgs) -> anyhow::Result<ExitCode> {
    // what the command line asks for, checked before anything starts
    let plan = Plan::new(flags)?;
    // the pacer and the node started; what only the node can refuse refused; the first lines
    let session = Session::start(plan).await?;
    // the mission runs, its events followed; then the node stops
    let ended = session.follow().await?;
    ended.tell();
    ended.plan.kept.keep(&ended.report);
    let written = ended.write_outputs();
    let code = ended.verdict(written);
    // the page stays up until Ctrl-C; then the cluster is left
    ended.close().await;
    Ok(code)
}

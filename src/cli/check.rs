//! `marie check MISSION`: load and check a mission (and its world) without running it.

use super::args::RobotArgs;
use super::prepare::prepare;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `marie check`.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// Mission file.
    pub mission: PathBuf,
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Check the mission against the operations of a freshly started node.
pub async fn check(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let CheckArgs { mission, robot } = args;
    let prepared = prepare(&mission, robot).await?;
    let m = &prepared.mission;
    println!(
        "{}: ok — mission `{}`, {} actions, {} operations{}",
        mission.display(),
        m.name,
        m.actions.len(),
        m.operation_names().len(),
        prepared
            .robot
            .as_ref()
            .map(|r| format!(", world `{}`", r.world().name))
            .unwrap_or_default()
    );
    prepared.node.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

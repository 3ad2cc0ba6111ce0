//! `marie check MISSION`: load and check a mission (and its world) without running it.

use super::args::RobotArgs;
use super::join::JoinArgs;
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
    /// `--join ADDR --cookie C`: check against the instances of a running cluster.
    #[command(flatten)]
    pub cluster: JoinArgs,
}

/// Check the mission against the operations of a freshly started node.
pub async fn check(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let CheckArgs {
        mission,
        robot,
        cluster,
    } = args;
    let joining = cluster.joining("check", &robot, 1.0)?;
    let prepared = prepare(&mission, robot, joining.as_ref()).await?;
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
    // which instance would serve each operation, as the dispatcher would choose now
    let choices = marie::actors::dispatcher::survey(m).await;
    let (mut supplied, mut defaulted) = (0, 0);
    for choice in &choices {
        let Some(chosen) = choice.chosen() else {
            println!("  {:<24} {}", choice.operation, choice.why_none());
            continue;
        };
        println!(
            "  {:<24} {} on {}, version {}, of {} candidate(s)",
            choice.operation,
            chosen.address,
            chosen.node,
            chosen.version,
            choice.candidates.len()
        );
        for op in m.actions.iter().flat_map(|a| &a.ops) {
            if op.name == choice.operation {
                supplied += op.params.len();
                defaulted += chosen
                    .schema
                    .iter()
                    .filter(|p| !op.params.contains_key(*p))
                    .count();
            }
        }
    }
    println!(
        "control details: {supplied} supplied by the mission, {defaulted} from declared defaults"
    );
    prepared.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

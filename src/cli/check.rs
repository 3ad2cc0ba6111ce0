//! `marie check MISSION`: verify a mission against the instances that would serve it,
//! without running it — each operation's choice, the source of every flag it waits for,
//! and the control details it supplies against those left at declared defaults.

use super::args::RobotArgs;
use super::join::JoinArgs;
use super::prepare::prepare;
use marie::actors::dispatcher::survey::Survey;
use marie::actors::dispatcher::{mission::Mission, survey};
use marie::cluster::node::NodeError;
use marie_missions::embedded::EmbeddedError;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags of `marie check`.
#[derive(clap::Args, Debug)]
pub(crate) struct CheckArgs {
    /// Mission file.
    pub mission: PathBuf,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// `--join ADDR --cookie C`: check against the instances of a running cluster.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// Print the verdict as one JSON document on stdout (`ok`, the choices, the flags, the
    /// control details — or `ok: false` and the errors); the exit code is the same.
    #[arg(long)]
    pub json: bool,
}

/// Check the mission against the operations of a freshly started node, or of the cluster.
pub(crate) async fn check(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let CheckArgs {
        mission,
        robot,
        cluster,
        json,
    } = args;
    let joining = cluster.joining("check", &robot, 1.0)?;
    let prepared = match prepare(&mission, robot, joining.as_ref()).await {
        Ok(p) => p,
        Err(e) => {
            if json {
                let doc = serde_json::json!({
                    "ok": false,
                    "mission": mission.display().to_string(),
                    "errors": errors_of(&e),
                });
                println!("{}", serde_json::to_string_pretty(&doc)?);
            }
            return Err(e);
        }
    };
    let m = &prepared.mission;
    let surveyed = survey(m).await;
    let world = prepared.robot.as_ref().map(|r| r.world().name.clone());
    if json {
        let doc = serde_json::json!({
            "ok": true,
            "mission": mission.display().to_string(),
            "name": m.name,
            "actions": m.actions.len(),
            "operations": m.operation_names().len(),
            "world": world,
            "survey": surveyed,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print_text(&mission, m, world.as_deref(), &surveyed);
    }
    prepared.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

/// The errors of a failed check as JSON: each diagnostic (`path`, `line`, `column`,
/// `message`) of a bad mission, node config or world; else the one message.
fn errors_of(e: &anyhow::Error) -> serde_json::Value {
    let diags = match (
        e.downcast_ref::<NodeError>(),
        e.downcast_ref::<EmbeddedError>(),
    ) {
        (Some(NodeError::Mission(d)), _) => Some(d),
        (_, Some(EmbeddedError::Config(d) | EmbeddedError::World(d))) => Some(d),
        (_, Some(EmbeddedError::Node(NodeError::Mission(d)))) => Some(d),
        _ => None,
    };
    match diags {
        Some(d) => serde_json::json!(d.0),
        None => serde_json::json!([{ "message": format!("{e:#}") }]),
    }
}

fn print_text(path: &Path, m: &Mission, world: Option<&str>, surveyed: &Survey) {
    println!(
        "{}: ok — mission `{}`, {} actions, {} operations{}",
        path.display(),
        m.name,
        m.actions.len(),
        m.operation_names().len(),
        world.map(|w| format!(", world `{w}`")).unwrap_or_default()
    );
    // which instance would serve each operation, as the dispatcher would choose now
    for choice in &surveyed.choices {
        match choice.chosen() {
            None => println!("  {:<24} {}", choice.operation, choice.why_none()),
            Some(chosen) => println!(
                "  {:<24} {} on {}, version {}, of {} candidate(s)",
                choice.operation,
                chosen.address,
                chosen.node,
                chosen.version,
                choice.candidates.len()
            ),
        }
    }
    let sources: Vec<String> = surveyed
        .flags
        .iter()
        .map(|f| {
            let mut from = f.raised_by.clone();
            if f.initial {
                from.push("initial".to_string());
            }
            format!("{} ← {}", f.flag, from.join(", "))
        })
        .collect();
    let unraised: Vec<&str> = surveyed
        .flags
        .iter()
        .filter(|f| !f.is_raised())
        .map(|f| f.flag.as_str())
        .collect();
    if unraised.is_empty() {
        println!(
            "condition flags: {} awaited, each raised: {}",
            surveyed.flags.len(),
            sources.join("; ")
        );
    } else {
        println!(
            "condition flags: {} awaited, never raised: {}",
            surveyed.flags.len(),
            unraised.join(", ")
        );
    }
    let c = surveyed.control_details;
    println!(
        "control details: {} supplied by the mission, {} from declared defaults",
        c.supplied, c.defaulted
    );
}

//! `marie check MISSION`: verify a mission against the instances that would serve it,
//! without running it — each operation's choice, the source of every flag it waits for,
//! the control details it supplies against those left at declared defaults, and, for a
//! mission with recoveries (`on_failure`), the mission flags each recovery can raise.
//!
//! It also refuses a mission whose parameters a newer compatible version of one of its
//! operations could not take (a renamed parameter without a declared migration, a value
//! outside a changed range): a binding would stay on its old version at run time, so the
//! operator hears of it now. The newer versions it knows are this build's declarations (its
//! catalogue, hosted anywhere or not) and the instances it sees — the check's own node's,
//! or a joined cluster's, a newer build's among them (see
//! `marie::dispatcher::upgrade_check`). A mission that pins the operation is not refused.

use super::args::RobotArgs;
use super::error::BadInput;
use super::join::JoinArgs;
use super::prepare::prepare;
use marie::cluster::node::NodeError;
use marie::dispatcher::mission::OpInfo;
use marie::dispatcher::survey::Survey;
use marie::dispatcher::upgrade_check::{refusing_versions, UpgradeRefusal};
use marie::dispatcher::{mission::Mission, survey};
use marie::run::Choice;
use marie_missions::embedded::EmbeddedError;
use std::collections::BTreeSet;
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
    let refusals = refusing_versions(m, &this_build()).await;
    if !refusals.is_empty() {
        prepared.shutdown().await;
        return Err(refused(&mission, &refusals, json)?);
    }
    let surveyed = survey(m).await;
    let world = prepared.robot.as_ref().map(|r| r.world().name.clone());
    let recoveries = recoveries(m, &surveyed.choices);
    if json {
        let mut doc = serde_json::json!({
            "ok": true,
            "mission": mission.display().to_string(),
            "name": m.name,
            "actions": m.actions.len(),
            "operations": m.operation_names().len(),
            "world": world,
            "survey": surveyed,
        });
        if !recoveries.is_empty() {
            doc["recoveries"] = serde_json::json!(recoveries);
        }
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print_text(&mission, m, world.as_deref(), &surveyed);
        for r in &recoveries {
            println!("{}", r.line());
        }
    }
    prepared.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

/// What this build's catalogue declares, one entry per operation version.
fn this_build() -> Vec<OpInfo> {
    marie_missions::catalog()
        .iter()
        .filter_map(|f| f.declared())
        .map(OpInfo::from_declared)
        .collect()
}

/// The error of a mission that newer versions could not take over (printed as JSON first
/// with `--json`): bad input, exit 2.
fn refused(
    mission: &Path,
    refusals: &[UpgradeRefusal],
    json: bool,
) -> anyhow::Result<anyhow::Error> {
    let lines: Vec<String> = refusals.iter().map(ToString::to_string).collect();
    if json {
        let doc = serde_json::json!({
            "ok": false,
            "mission": mission.display().to_string(),
            "errors": lines.iter().map(|l| serde_json::json!({ "message": l })).collect::<Vec<_>>(),
            "upgrades_refused": refusals,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    }
    Ok(BadInput(format!(
        "{}: a newer version could not take the mission's parameters:\n  {}",
        mission.display(),
        lines.join("\n  ")
    ))
    .into())
}

/// A recovery of the mission (`on_failure`) and the mission flags its operations can raise.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
struct Raisable {
    /// The action or group that recovers.
    recovery: String,
    /// The action or group whose failure it follows.
    of: String,
    /// The mission's flags (lowest bit first) that the chosen instances of the operations
    /// the recovery runs declare they can raise.
    can_raise: Vec<String>,
}

impl Raisable {
    /// Its line in the text output.
    fn line(&self) -> String {
        let flags = if self.can_raise.is_empty() {
            "no flags".to_string()
        } else {
            self.can_raise.join(", ")
        };
        format!(
            "recovery `{}` (on failure of `{}`) can raise: {flags}",
            self.recovery, self.of
        )
    }
}

/// Each recovery of `m` once (one used after several failures is listed for each), with
/// what its operations can raise as `choices` chose their instances: what a status word
/// may hold once it ran — the flags a `when` after it could be waiting for.
fn recoveries(m: &Mission, choices: &[Choice]) -> Vec<Raisable> {
    let mut out: Vec<Raisable> = Vec::new();
    for r in &m.control.recoveries {
        if out.iter().any(|o| o.recovery == r.recovery && o.of == r.of) {
            continue;
        }
        let ops: BTreeSet<&str> = r
            .actions
            .iter()
            .filter_map(|a| m.actions.get(*a))
            .flat_map(|a| a.ops.iter().map(|o| o.name.as_str()))
            .collect();
        let declared: BTreeSet<&str> = choices
            .iter()
            .filter(|c| ops.contains(c.operation.as_str()))
            .filter_map(Choice::chosen)
            .flat_map(|c| c.flags.iter().map(String::as_str))
            .collect();
        let mut flags: Vec<(u8, &str)> = m
            .flags
            .iter()
            .filter(|(name, _)| declared.contains(name.as_str()))
            .map(|(name, bit)| (*bit, name.as_str()))
            .collect();
        flags.sort();
        out.push(Raisable {
            recovery: r.recovery.clone(),
            of: r.of.clone(),
            can_raise: flags.into_iter().map(|(_, n)| n.to_string()).collect(),
        });
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;
    use marie::dispatcher::mission::{OpInfo, ParsedMission, StaticCatalog};
    use marie::dispatcher::selection::{choose, Offer};
    use marie::status::FlagDecl;

    #[test]
    fn each_recovery_says_which_mission_flags_its_operations_can_raise() {
        let src = "[mission]\nname = \"m\"\n[flags]\nwall-found = 0\nclear = 1\n\
                   [[action]]\nname = \"follow-wall\"\non_failure = \"back-off\"\n[action.ops.follower]\n\
                   [[action]]\nname = \"park\"\non_failure = \"wait\"\n[action.ops.driver]\n\
                   [[action]]\nname = \"back-off\"\n[action.ops.reverse]\n[action.ops.sensor]\n\
                   [[action]]\nname = \"wait\"\n[action.ops.idle]\n";
        let flags = |names: &[&str]| names.iter().map(|n| FlagDecl::new(*n, "")).collect();
        let ops = [
            OpInfo::new("follower", 1, "1.0.0"),
            OpInfo::new("driver", 2, "1.0.0"),
            // `other` is not a flag of the mission: left out
            OpInfo::new("reverse", 3, "1.0.0").flags(flags(&["clear", "other"])),
            OpInfo::new("sensor", 4, "1.0.0").flags(flags(&["wall-found"])),
            OpInfo::new("idle", 5, "1.0.0"),
        ];
        let m = ParsedMission::parse(src, None)
            .and_then(|p| p.validate(&StaticCatalog::new(ops.clone())))
            .unwrap_or_else(|d| panic!("{d}"));
        let choices: Vec<Choice> = m
            .operation_names()
            .into_iter()
            .map(|name| {
                let offers: Vec<Offer> = ops
                    .iter()
                    .filter(|o| o.name == name)
                    .map(|o| Offer::new("a", "n1", o.clone()))
                    .collect();
                choose(&m.need(name), &offers, "n1")
            })
            .collect();
        let lines: Vec<String> = recoveries(&m, &choices)
            .iter()
            .map(Raisable::line)
            .collect();
        assert_eq!(
            lines,
            [
                "recovery `back-off` (on failure of `follow-wall`) can raise: wall-found, clear",
                "recovery `wait` (on failure of `park`) can raise: no flags",
            ]
        );
    }
}

//! `marie ls`: the location table — of the embedded node, or of a running cluster
//! (`--join ADDR --cookie C`).

use super::args::RobotArgs;
use super::join::{join, member_name, JoinArgs};
use super::prepare::start_node;
use marie::cluster::net::heartbeat::{peers_said, PeerSaid};
use marie::dm::{DmClient, DmStats, Durability};
use marie::registry::{self, Instance, ModuleKind};
use std::collections::BTreeMap;
use std::process::ExitCode;
use std::time::Duration;

/// Flags of `marie ls`.
#[derive(clap::Args, Debug)]
pub(crate) struct LsArgs {
    /// Print JSON instead of the start-up log format.
    #[arg(long)]
    pub json: bool,
    /// `--join ADDR --cookie C`: list every module of a running cluster, with its node.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// `--node FILE`: list what that node hosts; `--world FILE`: with the robot too.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Start the node (or join the cluster) and list what is published.
pub(crate) async fn ls(args: LsArgs) -> anyhow::Result<ExitCode> {
    if let Some(target) = args.cluster.target_alone(&args.robot, "lists")? {
        // a member that hosts nothing: what it lists is the others'
        let transport = join(&member_name("ls"), &target).await?;
        let said = peers_said(PEERS_SAID_WITHIN).await;
        let result = print_listing(&registry::list(), &said, args.json).await;
        transport.stop().await;
        return result.map(|()| ExitCode::SUCCESS);
    }
    let node = start_node(args.robot.options(None)).await?.node;
    print_listing(&registry::list(), &BTreeMap::new(), args.json).await?;
    node.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

/// How long `ls --join` waits for every node to have named its build and protocol.
const PEERS_SAID_WITHIN: Duration = Duration::from_secs(2);

/// What the nodes of the cluster said in their beats, by node name.
type Said = BTreeMap<String, Option<PeerSaid>>;

/// How a node's protocol reads in `ls`: `protocol 2 (speaks 2..=3)`.
fn protocol_words(said: &PeerSaid) -> String {
    format!("protocol {} (speaks {})", said.agreed, said.speaks)
}

/// A node's line: its protocol agreed with this member and its build.
fn node_line(node: &str, said: &Option<PeerSaid>) -> String {
    match said {
        None => format!("node {node}: has not said its protocol and build"),
        Some(s) => {
            let build = s.build.as_ref().map_or_else(
                || "a build that does not say".to_string(),
                |b| b.to_string(),
            );
            format!("node {node}: {}, build {build}", protocol_words(s))
        }
    }
}

/// How long `ls` waits for a datamanager's stats.
const STATS_WITHIN: Duration = Duration::from_secs(2);

/// What `ls` shows of a datamanager beyond its place: its durability, records and journal.
async fn dm_state(i: &Instance) -> Option<DmStats> {
    if i.kind != ModuleKind::Datamanager {
        return None;
    }
    let client = DmClient::from_instance(i, "ls")
        .with_timeout(STATS_WITHIN)
        .with_follow(Duration::ZERO);
    client.stats().await.ok()
}

async fn print_listing(list: &[Instance], said: &Said, json: bool) -> anyhow::Result<()> {
    let mut dms = Vec::with_capacity(list.len());
    for i in list {
        dms.push(dm_state(i).await);
    }
    // replicated datamanagers without a leader are in no listing of the registry: their
    // replicas say why
    let leaderless = marie::dm::leaderless(STATS_WITHIN).await;
    // every replica's own numbers (what it holds in memory among them): the leader's
    // stats speak for the datamanager, not for its followers
    let views = match json {
        true => marie::dm::replica_views(STATS_WITHIN).await,
        false => Default::default(),
    };
    if json {
        let rows: Vec<_> = list
            .iter()
            .zip(&dms)
            .map(|(i, dm)| {
                let mut row = serde_json::json!({
                    "kind": i.kind.label(), "id": i.id, "name": i.name,
                    "node": i.node, "address": i.actor.get_id().to_string(),
                });
                if let Some(Some(s)) = said.get(&i.node) {
                    row["protocol"] = serde_json::json!({
                        "agreed": s.agreed, "speaks": s.speaks.to_string(),
                        "build": s.build.as_ref().map(ToString::to_string),
                    });
                }
                if let Some(s) = dm {
                    row["durability"] = s.durability.as_str().into();
                    row["records"] = s.records.into();
                    row["journal_bytes"] = s.journal_bytes.into();
                    if let Some(r) = &s.replica {
                        row["replica"] = serde_json::to_value(r).unwrap_or_default();
                        row["stray_replicas"] = stray(&i.name, r).into();
                        if let Some(all) = views.get(&i.name) {
                            row["replicas"] = serde_json::to_value(all).unwrap_or_default();
                        }
                    }
                }
                row
            })
            .chain(leaderless.iter().map(|lost| {
                serde_json::json!({
                    "kind": ModuleKind::Datamanager.label(), "name": lost.dm, "node": null,
                    "no_majority": {
                        "members": lost.members, "answering": lost.answering,
                        "missing": lost.missing, "term": lost.term,
                        "why": lost.to_string(),
                    },
                })
            }))
            .collect();
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{}", registry::render_listing(list));
        for (node, s) in said {
            println!("{}", node_line(node, s));
        }
        for (i, s) in list.iter().zip(&dms) {
            let Some(s) = s else { continue };
            let journal = match s.durability {
                Durability::Memory => "in memory".to_string(),
                d => format!("{d}, journal {}", bytes(s.journal_bytes)),
            };
            let replicas = match &s.replica {
                None => String::new(),
                Some(r) => {
                    // a learner (added while it runs) is said: it does not vote yet
                    let lags: Vec<String> = r
                        .lag
                        .iter()
                        .map(|(node, lag)| match r.learners.contains(node) {
                            true => format!("{node} (lag {lag}, learning)"),
                            false => format!("{node} (lag {lag})"),
                        })
                        .collect();
                    format!(
                        "; {}, term {}, replicas on {}",
                        r.role,
                        r.term,
                        lags.join(", ")
                    )
                }
            };
            println!(
                "DM {} on {}: {} records, {journal}{replicas}",
                i.name, i.node, s.records
            );
            for node in s
                .replica
                .as_ref()
                .map(|r| stray(&i.name, r))
                .unwrap_or_default()
            {
                println!(
                    "DM {}: the replica on {node} is none of its replicas (removed while its \
                     node was away, or started again on a wiped data directory): it takes no \
                     part — stop it, or add it with marie dm add-replica",
                    i.name
                );
            }
        }
        for lost in &leaderless {
            println!("DM {}: no majority — {lost}", lost.dm);
        }
    }
    Ok(())
}

/// The nodes where a replica of `dm` runs that the leader's configuration `r` does not
/// name (only a leader's word is taken: a follower's may be behind).
fn stray(dm: &str, r: &marie::dm::ReplicaStats) -> Vec<String> {
    if r.role != marie::replica::ReplicaRole::Leader {
        return Vec::new();
    }
    marie::dm::replica_nodes(dm)
        .into_iter()
        .filter(|n| *n != r.node && !r.members.contains(n) && !r.learners.contains(n))
        .collect()
}

/// A size as people read it.
fn bytes(n: u64) -> String {
    match n {
        n if n >= 1 << 20 => format!("{:.1} MiB", n as f64 / (1u64 << 20) as f64),
        n if n >= 1 << 10 => format!("{:.1} KiB", n as f64 / 1024.0),
        n => format!("{n} B"),
    }
}

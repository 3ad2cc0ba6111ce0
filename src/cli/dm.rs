//! `marie dm add-replica DM NODE --join ADDR --cookie C` and `marie dm remove-replica`: move
//! a replicated datamanager's replicas while the cluster runs ([`marie::cluster::replicas`]),
//! telling each step on stdout; `marie dm probe` ([`super::probe`]).

use super::error::BadInput;
use super::join::{join, member_name, JoinArgs};
use marie::cluster::replicas::{self, ChangeFailure, Step};
use std::process::ExitCode;
use std::time::Duration;

/// Flags of `marie dm`.
#[derive(clap::Args, Debug)]
pub(crate) struct DmArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: DmCommand,
}

/// The `marie dm` verbs.
#[derive(clap::Subcommand, Debug)]
pub(crate) enum DmCommand {
    /// Add a replica of datamanager DM on node NODE (a learner, then a voter).
    ///
    /// The node's host starts the replica; it catches up as a learner (its lag told as it
    /// falls), then the leader promotes it to a voter. Exit 0 once it votes, 1 when the cluster could not do it (no leader, a change
    /// already under way, the node's host refused or did not answer, not done in time), 2
    /// for a datamanager or node that does not exist or a node that already keeps one.
    AddReplica(ReplicaArgs),
    /// Remove the replica of datamanager DM on node NODE, and stop it there.
    ///
    /// The leader removes it from the replicas (a leader removing itself hands its role
    /// over first), then its node's host stops it and drops its journal — or, when
    /// the node is gone, only remove it. Exit 0 once removed, 1 when the cluster could not
    /// (fewer than three voters would be left, the others could not commit it: no
    /// majority, a change under way, not done in time), 2 for a datamanager or node that
    /// keeps no such replica.
    RemoveReplica(ReplicaArgs),
    /// Write numbered records into DM and read them back — by name and from each replica —
    /// until Ctrl-C or `--for SECS`, checking that no read is stale.
    ///
    /// A read is stale when it shows an older record than one acknowledged before it was
    /// sent (the reads are linearizable against the writes). Says every 10 s how it goes;
    /// then the verdict: reads answered, refused and unanswered per road, each stale read,
    /// and whether the newest acknowledged write was read back. Run it while you kill,
    /// freeze and cut off nodes. Exit 0 when nothing was wrong, 1 when a read was stale or
    /// the newest write missing, 2 for a datamanager without a leader.
    Probe(super::probe::ProbeArgs),
}

/// The flags of `add-replica` and `remove-replica`.
#[derive(clap::Args, Debug)]
pub(crate) struct ReplicaArgs {
    /// The datamanager (its name, e.g. `feature`).
    pub dm: String,
    /// The node whose replica is added or removed (its name, as `marie ls` shows it).
    pub node: String,
    /// `--join ADDR --cookie C` (required): the running cluster.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// Give up after this many seconds (a learner catching up a large store takes a while).
    #[arg(long, value_name = "SECS", default_value_t = replicas::CHANGE_WITHIN.as_secs(), value_parser = clap::value_parser!(u64).range(1..=86_400))]
    pub within: u64,
}

/// Do the `marie dm` verb.
pub(crate) async fn dm(args: DmArgs) -> anyhow::Result<ExitCode> {
    let (adding, args) = match args.command {
        DmCommand::AddReplica(a) => (true, a),
        DmCommand::RemoveReplica(a) => (false, a),
        DmCommand::Probe(a) => return super::probe::probe(a).await,
    };
    let verb = if adding {
        "add-replica"
    } else {
        "remove-replica"
    };
    let Some(target) = args.cluster.target() else {
        return Err(BadInput(format!(
            "marie dm {verb} acts on a running cluster: give --join ADDR --cookie C"
        ))
        .into());
    };
    let transport = join(&member_name("dm"), &target).await?;
    let within = Duration::from_secs(args.within);
    let tell = |step: &Step| println!("{}: {step}", args.dm);
    let done = match adding {
        true => replicas::add(&args.dm, &args.node, within, tell).await,
        false => replicas::remove(&args.dm, &args.node, within, tell).await,
    };
    transport.stop().await;
    match done {
        Ok(()) => {
            println!(
                "{}: replica on {} {}",
                args.dm,
                args.node,
                if adding { "added" } else { "removed" }
            );
            Ok(ExitCode::SUCCESS)
        }
        Err(e) if e.is_bad_input() => Err(BadInput(e.to_string()).into()),
        Err(e) => Err(Failed(e).into()),
    }
}

/// A change the cluster could not make: exit 1.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Failed(ChangeFailure);

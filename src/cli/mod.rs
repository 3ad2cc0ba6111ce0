//! The `marie` command line: the flags of every verb, and which verb runs what.
//!
//! One module per verb (`run`, `check`, `ls`, `props`, `kill`, `node`, `up`, `monitor`, `dm`), each holding its flags and
//! its work; the modules beside them hold what verbs share: flags and parsers (`args`), the
//! node a mission is prepared on (`prepare`), the printed lines (`output`), the runtime and
//! tracing set-up (`runtime`) and how an error becomes an exit code (`error`).

pub(crate) mod args;
pub(crate) mod check;
pub(crate) mod children;
pub(crate) mod compat;
pub(crate) mod diff;
pub(crate) mod dm;
pub(crate) mod error;
pub(crate) mod events_file;
pub(crate) mod export;
pub(crate) mod feed;
pub(crate) mod files;
pub(crate) mod give_back;
pub(crate) mod huge_pages;
pub(crate) mod join;
pub(crate) mod kill;
pub(crate) mod ls;
pub(crate) mod mcap;
pub(crate) mod monitor;
pub(crate) mod netns;
pub(crate) mod node;
pub(crate) mod output;
pub(crate) mod page_control;
pub(crate) mod prepare;
pub(crate) mod probe;
pub(crate) mod props;
pub(crate) mod provenance;
pub(crate) mod replay;
pub(crate) mod run;
pub(crate) mod runtime;
pub(crate) mod signal;
pub(crate) mod up;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// `marie`: its global flags and the verb.
#[derive(Parser, Debug)]
#[command(
    name = "marie",
    version = env!("MARIE_BUILD"),
    about = "Run MARIE missions on ractor actors"
)]
pub(crate) struct Cli {
    /// Diagnostics format on stderr (filter with RUST_LOG, default `warn`).
    #[arg(long, value_enum, default_value_t = runtime::LogFormat::Text, global = true)]
    pub log_format: runtime::LogFormat,
    /// The verb.
    #[command(subcommand)]
    pub command: Command,
}

/// The verbs.
// parsed once per process: the size of the largest variant costs nothing
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand, Debug)]
pub(crate) enum Command {
    /// Run a mission on the embedded node.
    Run(run::RunArgs),
    /// Check a mission against the running operations without running it.
    Check(check::CheckArgs),
    /// List the location table.
    Ls(ls::LsArgs),
    /// Kill an operation (or a datamanager) on the embedded node and show its supervisor
    /// restarting it.
    Kill(kill::KillArgs),
    /// Show every property of an operation.
    Props(props::PropsArgs),
    /// Run a cluster member: host what a node config says and join its peers.
    Node(node::NodeArgs),
    /// Start the nodes of a cluster file as processes on 127.0.0.1, run a mission on them.
    Up(up::UpArgs),
    /// Show a run in the browser: a running cluster live (`--join`), or a past run's events
    /// file replayed (`--events`).
    Monitor(monitor::MonitorArgs),
    /// Convert a run's events file (`marie run --events`) to MCAP (`--mcap FILE.mcap`):
    /// Foxglove opens it and draws the world, the cart, the echoes and the paths, with every
    /// event in its log and the task tree's state.
    Export(export::ExportArgs),
    /// Say what differs between two runs: marie build, seed, files, parameters, bindings,
    /// faults, outcome, final pose — from their reports (`marie run --report`).
    ///
    /// The files are paired by role (mission, world, node, cluster) and shown as a unified
    /// diff of their texts. Exit 0 when the runs are the same in every aspect, 1 when they
    /// differ, 2 when a file is not a report.
    Diff(diff::DiffArgs),
    /// Change a replicated datamanager's replicas while the cluster runs (`--join`): add
    /// one on a node, remove one.
    Dm(dm::DmArgs),
    /// The compatibility gate: write this build's corpus of encodings (every message that
    /// crosses nodes, the event frames, the records a datamanager stores), check that this
    /// build still reads a corpus and writes back every key it had, compare two corpora.
    Compat(compat::CompatArgs),
}

/// This binary's build, as its `build.rs` captured it (`--version` says the same).
pub(crate) fn this_build() -> marie::run::Build {
    let dirty = match env!("MARIE_UNCOMMITTED") {
        "true" => Some(true),
        "false" => Some(false),
        _ => None,
    };
    marie::run::Build::new(env!("CARGO_PKG_VERSION"), Some(env!("MARIE_COMMIT")), dirty)
}

impl Command {
    /// Say which build this process is, for its heartbeats and its runs' provenance:
    /// [`this_build`], or the commit a node claims (`marie node --claim-commit`, hidden:
    /// only to see a run name a node of another commit).
    pub(crate) fn set_build(&self) {
        let mut build = this_build();
        if let Command::Node(node) = self {
            if let Some(commit) = &node.claim_commit {
                build.commit = Some(commit.clone());
                build.uncommitted_changes = Some(false);
            }
        }
        marie::run::provenance::set_this_build(build);
    }

    /// True when the verb runs in virtual time (see [`runtime::build`]): a mission run,
    /// whose outcome must not depend on its speed.
    pub(crate) fn virtual_time(&self) -> bool {
        matches!(self, Command::Run(run) if run.cluster.join.is_none())
    }

    /// True when the verb may use sockets or watch signals (tokio's I/O driver): every verb
    /// but a run with neither a cluster to join nor a monitor to serve.
    pub(crate) fn io(&self) -> bool {
        !matches!(self, Command::Run(run) if run.cluster.join.is_none() && run.monitor.is_none())
    }

    /// What must be done before the runtime's threads exist: `marie up` may move the
    /// process into a private network of namespaces ([`netns`]), which every thread must
    /// share. The guard deletes it when dropped, after the runtime.
    pub(crate) fn before_runtime(&self) -> anyhow::Result<Option<netns::NetGuard>> {
        match self {
            Command::Up(args) => up::private_network(args),
            _ => Ok(None),
        }
    }

    /// Do what the verb says.
    pub(crate) async fn execute(self) -> anyhow::Result<ExitCode> {
        match self {
            Command::Run(args) => run::run(args).await,
            Command::Check(args) => check::check(args).await,
            Command::Ls(args) => ls::ls(args).await,
            Command::Kill(args) => kill::kill(args).await,
            Command::Props(args) => props::props(args).await,
            Command::Node(args) => node::node(args).await,
            Command::Up(args) => up::up(args).await,
            Command::Monitor(args) => monitor::monitor(args).await,
            Command::Export(args) => export::export(args).await,
            Command::Diff(args) => diff::diff(args),
            Command::Dm(args) => dm::dm(args).await,
            Command::Compat(args) => compat::compat(args).await,
        }
    }
}

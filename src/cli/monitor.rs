//! `marie monitor`: the web page of a run — live on a running cluster (`--join ADDR
//! --cookie C`), or the replay of a past run (`--events FILE.jsonl`); and the live monitor
//! `run --monitor` and `up --monitor` start on their own run.
//!
//! The server is `marie_monitor`'s (its own thread; the node it watches only publishes on its
//! bus). This module joins the cluster when asked, feeds the monitor what the bus alone does
//! not carry — the modules that joined before it started, the other nodes' events from the
//! cluster's relay — prints the page's address and waits for Ctrl-C.

use super::error::BadInput;
use super::join::{join, member_name, ClusterEntry, JoinArgs};
use super::page_control::PageControl;
use marie::clock::ScaledClock;
use marie::cluster::fault::NodeProcesses;
use marie::events::{bridge_registry, Event, EventBus, EventKind, ModuleInfo, RegistryBridge};
use marie::registry;
use marie_monitor::{Feed, Monitor, MonitorError, MonitorHandle, MonitorOptions};
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use tokio::task::JoinHandle;

/// Events of the other nodes a monitor keeps while it is behind.
const FROM_OTHERS: usize = 4096;

/// Flags of `marie monitor`.
#[derive(clap::Args, Debug)]
pub(crate) struct MonitorArgs {
    /// Replay a past run from its events file (`run --events FILE.jsonl`): play, pause,
    /// speed and a time slider on the page.
    #[arg(long, value_name = "FILE.jsonl", conflicts_with = "join")]
    pub events: Option<PathBuf>,
    /// `--join ADDR --cookie C`: watch a running cluster live.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// Serve the page here (port 0: one the OS picks; the address is printed). Beyond
    /// loopback every request needs the token printed at the start.
    #[arg(long, value_name = "ADDR", default_value = marie_monitor::DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// Require the token on loopback too.
    #[arg(long)]
    pub require_token: bool,
    /// Let the page inject faults into the cluster it watches: kill or hang an operation,
    /// wherever it runs.
    #[arg(long, conflicts_with = "events")]
    pub allow_faults: bool,
    /// With `--join`: the cluster's clock speed, a factor of real time (default 1), so that
    /// what this monitor tells itself (nodes seen and lost, faults injected) is timed as the
    /// nodes time their events.
    #[arg(long, value_name = "FACTOR", requires = "join")]
    pub speed: Option<f64>,
    /// Let the page change the cluster it watches: add a datamanager's replica on a node,
    /// remove one (what `marie dm add-replica` and `remove-replica` do).
    #[arg(long, conflicts_with = "events")]
    pub allow_changes: bool,
}

/// Serve the replay or the live cluster until SIGINT or SIGTERM.
pub(crate) async fn monitor(args: MonitorArgs) -> anyhow::Result<ExitCode> {
    let options = MonitorOptions {
        require_token: args.require_token,
        ..MonitorOptions::new(args.listen)
    }
    .allowing_changes(args.allow_changes);
    if let Some(path) = &args.events {
        let monitor = Monitor::replay(path, options).map_err(bad_file)?;
        // watched before the page's line: a Ctrl-C right after it is not missed
        let stop = super::signal::shutdown_signal(false);
        announce(&monitor, &format!("replaying {}", path.display()));
        let signal = stop.await;
        println!("monitor stopped ({signal})");
        monitor.stop();
        return Ok(ExitCode::SUCCESS);
    }
    let Some(target) = args.cluster.target() else {
        return Err(BadInput(
            "marie monitor needs what to show: --events FILE.jsonl (a past run) or --join ADDR \
             --cookie C (a running cluster)"
                .into(),
        )
        .into());
    };
    let speed = marie::cluster::layout::cluster_speed(args.speed.unwrap_or(1.0))
        .map_err(|e| BadInput(format!("--speed: {e}")))?;
    let stop = super::signal::shutdown_signal(false);
    let watching = ClusterWatch::start(
        &target,
        speed,
        options,
        args.allow_faults,
        NodeProcesses::default(),
    )
    .await?;
    let signal = stop.await;
    println!("monitor stopped ({signal})");
    watching.stop().await;
    Ok(ExitCode::SUCCESS)
}

/// A file that cannot be replayed is bad input (exit 2); anything else an error.
fn bad_file(e: MonitorError) -> anyhow::Error {
    match e {
        e @ (MonitorError::Read { .. } | MonitorError::Parse { .. }) => {
            BadInput(e.to_string()).into()
        }
        e => e.into(),
    }
}

/// Print where the page is: `monitor: http://ADDR/` (with the token when one is required).
pub(crate) fn announce(monitor: &MonitorHandle, what: &str) {
    println!("monitor: {} ({what})", monitor.url());
    let _ = std::io::stdout().flush();
}

/// A live monitor on `bus` (a run's own node): the modules already in the registry first,
/// then every event of the bus. `other_nodes`: also the other nodes' events (a member of a
/// cluster).
///
/// No registry bridge of its own, unlike [`ClusterWatch`]: `bus` is a node's, and the node
/// bridges its registry onto it from its start for as long as it runs (`Node::start`) —
/// the joins and leaves of every node's modules, also of a node that joins the cluster
/// after the run started (its own relay told them before it knew of this watcher). A
/// second bridge would publish each of them twice on the node's bus, and so into its
/// `--events` file.
pub(crate) async fn start_live(
    bus: &EventBus,
    options: MonitorOptions,
    other_nodes: bool,
    dispatched_elsewhere: bool,
) -> anyhow::Result<(MonitorHandle, Option<JoinHandle<()>>)> {
    let monitor = Monitor::live(bus, options)?;
    let feed = monitor.feed().expect("a live monitor has a feed");
    let relay = if other_nodes {
        let relay = relay_into(feed.clone(), dispatched_elsewhere).await?;
        let poll = poll_datamanagers(feed.clone(), bus.clone());
        // one handle for both: the poller ends with the relay, and the relay (and with it
        // the poller) when this task is aborted
        Some(tokio::spawn(async move {
            struct Abort(JoinHandle<()>);
            impl Drop for Abort {
                fn drop(&mut self) {
                    self.0.abort();
                }
            }
            let _poll = Abort(poll);
            let mut relay = Abort(relay);
            let _ = (&mut relay.0).await;
        }))
    } else {
        None
    };
    feed_listing(&feed, bus);
    Ok((monitor, relay))
}

/// How often the page's datamanagers are asked what they hold.
const DM_POLL: std::time::Duration = std::time::Duration::from_secs(2);

/// Ask every datamanager in the registry what it holds — durability, records, journal, and
/// for a replicated one its role, term and replicas' lag — every [`DM_POLL`], and feed it to
/// the page (`dm_state`), and the replicas of each without a leader who is missing
/// (`dm_no_majority`), until aborted. Only the monitor sees these: the bus does not.
fn poll_datamanagers(feed: Feed, bus: EventBus) -> JoinHandle<()> {
    use marie::dm::DmClient;
    tokio::spawn(async move {
        let mut ticks = tokio::time::interval(DM_POLL);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            ticks.tick().await;
            for inst in registry::list_of(registry::ModuleKind::Datamanager) {
                let client = DmClient::from_instance(&inst, "monitor")
                    .with_timeout(std::time::Duration::from_secs(1))
                    .with_follow(std::time::Duration::ZERO);
                let Ok(s) = client.stats().await else {
                    continue;
                };
                let (role, term, lag) = match s.replica {
                    Some(r) => (Some(r.role), r.term, r.lag),
                    None => (None, 0, Default::default()),
                };
                feed.offer(Event {
                    at_ms: bus.clock().now().as_millis() as u64,
                    node: inst.node.clone(),
                    kind: EventKind::DmState {
                        dm: s.name,
                        durability: s.durability.as_str().to_string(),
                        records: s.records,
                        journal_bytes: s.journal_bytes,
                        role,
                        term,
                        lag,
                    },
                });
            }
            // a datamanager without a leader is in no registry listing: ask its replicas
            for lost in marie::dm::leaderless(marie::dm::VIEW_TIMEOUT).await {
                feed.offer(Event {
                    at_ms: bus.clock().now().as_millis() as u64,
                    node: bus.node().to_string(),
                    kind: lost.event(),
                });
            }
        }
    })
}

/// Feed the modules in the registry now, as if they had just joined (they joined before the
/// monitor started).
fn feed_listing(feed: &Feed, bus: &EventBus) {
    let at_ms = bus.clock().now().as_millis() as u64;
    for inst in registry::list() {
        feed.offer(Event {
            at_ms,
            node: inst.node.clone(),
            kind: EventKind::Joined(ModuleInfo::from(&inst)),
        });
    }
}

/// Watch the other nodes' events (the cluster's relay) into `feed`, until aborted.
async fn relay_into(feed: Feed, without_dispatch: bool) -> anyhow::Result<JoinHandle<()>> {
    let mut watch = marie::cluster::relay::watch(FROM_OTHERS).await?;
    // a run dispatched elsewhere is on the bus, republished: not twice
    if without_dispatch {
        watch = watch.without_dispatch();
    }
    Ok(tokio::spawn(async move {
        while let Some(event) = watch.recv().await {
            feed.offer(event);
        }
    }))
}

/// A live monitor of a running cluster from a member of its own that hosts nothing.
pub(crate) struct ClusterWatch {
    monitor: MonitorHandle,
    transport: marie::cluster::net::Transport,
    tasks: Vec<JoinHandle<()>>,
    _registry: RegistryBridge,
}

impl ClusterWatch {
    /// Join the cluster at `target`, whose clocks run `speed` times real time, watch every
    /// node's events and serve them; the page asks operations for their properties,
    /// injects faults when `allow_faults` (also stopping `processes`), and moves replicas
    /// when `options` allow changes.
    ///
    /// Why the speed: this member's own news (nodes seen and lost, faults injected) is
    /// stamped by a clock of its own, which must read the nodes' time — at another speed
    /// its events would sort decades apart from theirs, and the page, which shows times
    /// from the earliest event, would show the nodes' at nonsense.
    pub(crate) async fn start(
        target: &ClusterEntry,
        speed: f64,
        options: MonitorOptions,
        allow_faults: bool,
        processes: NodeProcesses,
    ) -> anyhow::Result<ClusterWatch> {
        let me = member_name("monitor");
        let transport = join(&me, target).await?;
        // this member's own news of the cluster (nodes seen, lost, declared down), and the
        // faults its page injects
        let bus = EventBus::new(me.clone(), Arc::new(ScaledClock::cluster(speed)));
        let options = options.with_control(PageControl::new(bus.clone(), processes), allow_faults);
        let monitor = match Monitor::live(&bus, options) {
            Ok(m) => m,
            Err(e) => {
                transport.stop().await;
                return Err(e.into());
            }
        };
        let feed = monitor.feed().expect("a live monitor has a feed");
        // watching before listing: nothing between the two goes unseen. The relay carries
        // what each node tells of itself from now on; this member's registry, what any node
        // hosts — also a node that starts later, whose modules joined before its relay
        // knew of this watcher.
        let relay = relay_into(feed.clone(), false).await?;
        let registry = bridge_registry(bus.clone(), None).await?;
        feed_listing(&feed, &bus);
        let poll = poll_datamanagers(feed.clone(), bus.clone());
        let news = marie::cluster::net::publish_on(&transport, bus);
        announce(&monitor, &format!("watching the cluster as {me}"));
        Ok(ClusterWatch {
            monitor,
            transport,
            tasks: vec![relay, news, poll],
            _registry: registry,
        })
    }

    /// Stop serving and leave the cluster.
    pub(crate) async fn stop(self) {
        for t in &self.tasks {
            t.abort();
        }
        self.monitor.stop();
        self.transport.stop().await;
    }
}

//! `marie run MISSION`: run a mission on the embedded node, print its progress and outcome,
//! write the report and the picture.

use super::args::{parse_seed, parse_speed, RobotArgs};
use super::error::BadInput;
use super::events_file::EventsFile;
use super::files;
use super::join::JoinArgs;
use super::output::{end_line, outcome_line, verdict_line, LiveLines, Progress};
use super::page_control::PageControl;
use super::prepare::{prepare, Prepared};
use super::replay::{Planned, Replay};
use super::signal::Shutdown;
use anyhow::Context;
use marie::clock::Pacer;
use marie::cluster::fault::{Chaos, FaultSpec, NodeChaos, NodeProcesses};
use marie::cluster::node::{NodeError, RunOptions};
use marie::report::RunReport;
use marie::run::{FileRole, Outcome};
use marie_missions::robot::RobotReport;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Flags of `marie run`.
#[derive(clap::Args, Debug)]
pub(crate) struct RunArgs {
    /// Mission file (TOML task tree).
    #[arg(required_unless_present = "replay")]
    pub mission: Option<PathBuf>,
    /// Run a past run again from its report alone (`--report`'s JSON: its provenance holds
    /// the mission, world and node config texts, the seed, the command's faults), on this
    /// node, and say whether the outcome, the bindings, the final pose and the parameters
    /// match; exit 0 when they all do. A report of another marie commit is replayed with a
    /// warning naming both.
    #[arg(long, value_name = "REPORT.json",
          conflicts_with_all = ["mission", "join", "world", "node", "seed", "faults", "chaos"])]
    pub replay: Option<PathBuf>,
    /// The files `marie up` read to start the run's nodes — its cluster file, then the node
    /// configs it names — for the run's provenance.
    #[arg(skip)]
    pub read_by_up: Vec<(FileRole, PathBuf)>,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Keep the datamanagers' records in journals in DIR (`process` durability: what they
    /// acknowledged survives their crash and the process's); DIR is locked while the run
    /// lasts. Default: the node config's `data_dir`, and none for the built-in node —
    /// in memory, nothing written to disk. Not with `--join` (the cluster's datamanagers
    /// are its nodes').
    #[arg(long, value_name = "DIR", conflicts_with = "join")]
    pub data_dir: Option<PathBuf>,
    /// Write the run report (JSON) here.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Explain the self-configuration: for each operation, every live instance (node,
    /// version, schema), the one chosen and why each other lost or was rejected.
    #[arg(long)]
    pub explain: bool,
    /// With `--explain`: print only the choices, each as one JSON object per line (the
    /// `choice` of the `selected` event: operation, candidates with node, version, schema,
    /// flags and verdict, and `replacing` for a stand-in after a failure); the outcome is
    /// the exit code, and the report if `--report` is given.
    #[arg(long, requires = "explain")]
    pub json: bool,
    /// Write every event of the run here, one JSON object per line (the schema is in the
    /// docs of `marie::events`): dispatcher, bindings, supervisors, registry, faults,
    /// the robot. The report can be rebuilt from it.
    #[arg(long, value_name = "FILE.jsonl")]
    pub events: Option<PathBuf>,
    /// Write the run as MCAP here, for Foxglove: the world, the cart, the sonar echoes and
    /// the paths in its 3D panel, every event in its log, the task tree's state as JSON
    /// (the same as `marie export` makes of an events file).
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<PathBuf>,
    /// Draw the robot's run (walls, driven path, sonar echoes, segments, followed wall,
    /// detected dock, planned path, final footprint) as an SVG picture here. Needs a world.
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Clock speed: a factor of real time (`1` is real time), or `max`: as fast as the CPU
    /// allows (the default). Only paces the run: the outcome is the same at every speed.
    /// With `--join`: the cluster's factor (default 1; `max` is refused, a cluster runs on
    /// the wall clock).
    #[arg(long, value_parser = parse_speed, allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// `--join ADDR --cookie C`: run the dispatcher as a member of a running cluster; the
    /// operations, datamanagers and cart are the cluster's.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// With `--join`: put the cluster's simulated cart back at rest at the world's start
    /// before the run, its collisions and path started anew. Without it a run starts where
    /// the cluster's last run left the cart (parked in the dock, after docking).
    #[arg(long, requires = "join")]
    pub from_start: bool,
    /// Inject a fault while the mission runs: KIND `kill`, `panic`, `hang` or `slow` (an
    /// operation) or `stop-node`, `freeze-node` or `partition` (node processes `marie up`
    /// started: see `marie up --fault`); TARGET the operation's name or id
    /// (the instance the mission bound), `NAME#VERSION` (the instance with that version),
    /// `NAME/NODE` (the one on that node) or an actor id like `0.42` — a datamanager's
    /// name, id or address (`kill`, `panic`, `hang`) — or a node's name;
    /// SECS mission time, 0 to 86400 (a day). Repeatable. A fault that cannot be injected
    /// is reported, never dropped.
    #[arg(long = "fault", value_name = "KIND:TARGET@SECS")]
    pub faults: Vec<FaultSpec>,
    /// Kill a random operation of the running action every 4 to 12 s of mission time,
    /// picked by a generator seeded with SEED.
    #[arg(long, value_name = "SEED", value_parser = parse_seed, allow_hyphen_values = true)]
    pub chaos: Option<u64>,
    /// With `--chaos`: the datamanagers are among the victims too (a kill of a
    /// datamanager, which its supervisor restarts: with `--data-dir` it comes back with its
    /// records).
    #[arg(long, requires = "chaos")]
    pub chaos_dms: bool,
    /// Show the run live in the browser: serve the monitor's page on ADDR (default
    /// 127.0.0.1:7700; port 0: one the OS picks), print its address, and after the run keep
    /// serving its final state until Ctrl-C. With `--join`, the other nodes' events too.
    #[arg(long, value_name = "ADDR", num_args = 0..=1,
          default_missing_value = marie_monitor::DEFAULT_LISTEN)]
    pub monitor: Option<std::net::SocketAddr>,
    /// With `--monitor`: let the page inject faults — kill or hang an operation (and, under
    /// `marie up`, stop a node's process) — and watch the dispatcher rebind.
    #[arg(long, requires = "monitor")]
    pub allow_faults: bool,
    /// The node processes the page and the faults may stop, freeze or cut apart (`marie
    /// up`'s children; none otherwise).
    #[arg(skip)]
    pub node_processes: NodeProcesses,
    /// Random node faults (`marie up --chaos-nodes`).
    #[arg(skip)]
    pub node_chaos: Option<Box<NodeChaos>>,
    /// Set once the mission has ended and a Ctrl-C is the run's own to hear (see
    /// [`MissionOver`]).
    #[arg(skip)]
    pub mission_over: MissionOver,
    /// With `--join`: dispatch the run on NODE (a node whose config says `dispatcher =
    /// "active"` or `"standby"`, e.g. `features` of the thesis layout) instead of this
    /// member, and follow it there — and to the standby that takes it over should NODE be
    /// lost. `marie up --run` does so on the cluster file's active node.
    #[arg(long, value_name = "NODE", requires = "join")]
    pub dispatch_on: Option<String>,
}

/// Set once a run's mission has ended, its outputs written — and, with a monitor, once the
/// run listens for the Ctrl-C that closes its page. Whoever runs it (`marie up --run`) and
/// hears a Ctrl-C then lets the run end by itself instead of cutting the mission short.
///
/// That runner hands the run its own Ctrl-C watch ([`MissionOver::heard_by`]), watching
/// since before the run: the page closes on the same watch, so one Ctrl-C ends both,
/// whenever it comes. With a watch each, a Ctrl-C between the run's last line and the
/// moment it watched for itself was the runner's alone, and the run waited for another.
#[derive(Clone, Debug, Default)]
pub(crate) struct MissionOver(Arc<Over>);

#[derive(Debug, Default)]
struct Over {
    set: AtomicBool,
    /// The runner's Ctrl-C watch; `None`: the run watches for itself from the moment its
    /// page's last line is due.
    heard_by: Option<Shutdown>,
}

impl MissionOver {
    /// For a run whose runner watches Ctrl-C with `shutdown`.
    pub(crate) fn heard_by(shutdown: Shutdown) -> MissionOver {
        MissionOver(Arc::new(Over {
            set: AtomicBool::new(false),
            heard_by: Some(shutdown),
        }))
    }

    fn set(&self) {
        self.0.set.store(true, Ordering::SeqCst);
    }

    /// Whether the mission has ended (and the run hears a Ctrl-C itself).
    pub(crate) fn is_set(&self) -> bool {
        self.0.set.load(Ordering::SeqCst)
    }

    /// The Ctrl-C watch the page closes on: the runner's, else one from now on.
    fn ctrl_c(&self) -> Shutdown {
        self.0
            .heard_by
            .clone()
            .unwrap_or_else(|| Shutdown::watch(false))
    }
}

/// Pixels per metre of `--svg` pictures.
const SVG_SCALE: f64 = 50.0;
/// How long the end of a run waits for its monitor to take the run's last events.
const MONITOR_FLUSH: std::time::Duration = std::time::Duration::from_secs(5);
/// Events of the other nodes a `run --join --events` keeps while its file writer is behind.
const EVENTS_FROM_OTHERS: usize = 4096;

/// Run the mission; exit 0 when it succeeded and every output was written, else 1.
pub(crate) async fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let RunArgs {
        mission,
        replay,
        read_by_up,
        mut robot,
        data_dir,
        report: report_path,
        explain,
        json,
        events: events_path,
        mcap: mcap_path,
        svg: svg_path,
        speed,
        faults,
        chaos,
        chaos_dms,
        node_chaos,
        cluster,
        from_start,
        monitor: monitor_listen,
        allow_faults,
        node_processes,
        mission_over,
        dispatch_on,
    } = args;
    let this_build = super::this_build();
    // a replay: the report's files written out, its seed, its command's faults and chaos
    let replay = match replay {
        Some(p) => Some(Replay::load(&p)?),
        None => None,
    };
    let (path, faults, chaos, chaos_dms) = match &replay {
        Some(r) => {
            robot.world = r.world.clone();
            robot.node = r.node.clone();
            robot.seed = r.provenance.seed;
            let (planned, warnings) = r.planned();
            for warning in warnings {
                eprintln!("marie: {warning}");
            }
            let Planned {
                faults,
                chaos,
                chaos_dms,
            } = planned;
            (r.mission.clone(), faults, chaos, chaos_dms)
        }
        None => (
            mission.ok_or_else(|| {
                BadInput("a mission file is needed (or --replay REPORT.json)".into())
            })?,
            faults,
            chaos,
            chaos_dms,
        ),
    };
    let node_path = robot.node.clone();
    robot.data_dir = data_dir;
    let progress = match (explain, json) {
        (true, true) => Progress::ChoicesAsJson,
        (true, false) => Progress::Explained,
        _ => Progress::Lines,
    };
    let say = progress != Progress::ChoicesAsJson;
    let joining = cluster.joining("run", &robot, speed.unwrap_or(1.0))?;
    // outputs first: a run must not end in a report it cannot write
    if let Some(p) = &report_path {
        files::output("--report", p)?;
    }
    if let Some(p) = &svg_path {
        files::output("--svg", p)?;
    }
    if let Some(p) = &events_path {
        files::output("--events", p)?;
    }
    if let Some(p) = &mcap_path {
        super::mcap::output("--mcap", p)?;
    }
    let mut options = RunOptions::new()
        .faults(faults)
        .node_processes(node_processes.clone());
    if let Some(seed) = chaos {
        let chaos = Chaos::new(seed);
        options = options.chaos(match chaos_dms {
            true => chaos.with_datamanagers(),
            false => chaos,
        });
    }
    if let Some(chaos) = node_chaos {
        options = options.node_chaos(*chaos);
    }
    // a run dispatched on a node: its dispatcher's events come to this node's bus, not
    // (again) with the other nodes' events
    let remote = dispatch_on.is_some();
    if let Some(node) = dispatch_on {
        options = options.dispatch_on(node);
    }
    // The runtime's paused clock is the mission clock (the node's "real" clock reads it);
    // the pacer only holds it back to `speed`, from before the node starts to the end.
    // (a member of a cluster runs on the cluster's wall clock instead)
    let pace = joining
        .is_none()
        .then(|| Pacer::new(speed.unwrap_or(f64::INFINITY)).spawn());
    let prepared = prepare(&path, robot, joining.as_ref()).await?;
    // a joined run drives the cluster's cart from where it is, or from the world's start
    let start_line = match prepared.cart_start(from_start).await {
        Ok(line) => line,
        Err(e) => {
            prepared.shutdown().await;
            return Err(e.into());
        }
    };
    if svg_path.is_some() && prepared.robot.is_none() {
        prepared.shutdown().await;
        return Err(BadInput(format!(
            "--svg draws a robot's run, but no robot runs: give a world with --world FILE \
             or `world = \"...\"` in the `[mission]` of {}",
            path.display()
        ))
        .into());
    }
    // what runs, the run's first event: the files as read, the seed, the speed
    let mut read: Vec<(FileRole, &Path)> = vec![(FileRole::Mission, path.as_path())];
    if let Some(world) = &prepared.world_path {
        read.push((FileRole::World, world));
    }
    if let Some(node) = &node_path {
        read.push((FileRole::Node, node));
    }
    read.extend(read_by_up.iter().map(|(role, p)| (*role, p.as_path())));
    let mut provenance = super::provenance::of_run(
        &read,
        prepared
            .robot
            .as_ref()
            .map(|r| prepared.cart_seed.unwrap_or_else(|| r.seed())),
        match &joining {
            None => Some(speed.unwrap_or(super::args::MAX_SPEED)),
            Some(j) => Some(j.speed),
        },
    );
    if let Some(r) = &replay {
        // the files as the report held them, under the paths it named
        for (file, was) in provenance.files.iter_mut().zip(&r.provenance.files) {
            if file.role == was.role && file.sha256 == was.sha256 {
                file.path = was.path.clone();
            }
        }
    }
    options = options.provenance(provenance);
    if let Some(r) = &replay {
        if say {
            println!("{}", r.header());
        }
        for warning in r.warnings(&this_build) {
            eprintln!("marie: {warning}");
        }
    }
    if say {
        println!(
            "mission `{}` ({} actions) from {}",
            prepared.mission.name,
            prepared.mission.actions.len(),
            path.display()
        );
        if let Some(line) = prepared.world_line() {
            println!("{line}");
        }
        if let Some(line) = start_line {
            println!("{line}");
        }
    }
    // a fault that names nothing is refused before anything runs
    match prepared
        .node
        .check_faults(&prepared.mission, &options)
        .await
    {
        Ok(()) => {}
        Err(NodeError::Fault { spec, error }) => {
            prepared.shutdown().await;
            return Err(BadInput(format!("--fault {spec}: {error}")).into());
        }
        Err(e @ NodeError::NodeChaos(_)) => {
            prepared.shutdown().await;
            return Err(BadInput(e.to_string()).into());
        }
        Err(e) => {
            prepared.shutdown().await;
            return Err(e.into());
        }
    }
    // a run dispatched on a node that runs no desk is refused before it starts
    if let Some(on) = options.dispatched_on() {
        let desks = marie::registry::lookup(
            marie::registry::ModuleKind::Dispatcher,
            marie::cluster::node::desk::DESK_NAME,
        );
        if !desks.iter().any(|d| d.node == on) {
            let nodes: Vec<String> = desks.iter().map(|d| d.node.clone()).collect();
            prepared.shutdown().await;
            return Err(BadInput(format!(
                "--dispatch-on {on}: that node runs no dispatcher desk (`dispatcher = \
                 \"active\"` or `\"standby\"` in its config); {}",
                match nodes.is_empty() {
                    true => "no node of this cluster runs one".to_string(),
                    false => format!("these do: {}", nodes.join(", ")),
                }
            ))
            .into());
        }
    }
    let Prepared {
        node,
        robot,
        mission,
        transport,
        ..
    } = prepared;
    // the cluster's news (nodes up, lost, down) join the run's events
    let publisher = transport
        .as_ref()
        .map(|t| marie::cluster::net::publish_on(t, node.events().clone()));
    // the live lines subscribe to the node's bus, as the events file and the monitor do
    let lines = LiveLines::start(node.events(), progress);
    // this member's events go to whoever watches the cluster; its events file has theirs
    let forwarder = transport
        .as_ref()
        .map(|_| marie::cluster::relay::forward(node.events().clone()));
    // the other nodes' events, for each file that writes them (a watch each)
    let others = || async {
        match &transport {
            Some(_) => marie::cluster::relay::watch(EVENTS_FROM_OTHERS)
                .await
                .map(|watch| match remote {
                    true => Some(watch.without_dispatch()),
                    false => Some(watch),
                }),
            None => Ok(None),
        }
    };
    let events = match &events_path {
        Some(p) => Some(
            EventsFile::start(node.events(), others().await?, p)
                .with_context(|| format!("cannot write the events to {}", p.display()))?,
        ),
        None => None,
    };
    let mcap = match &mcap_path {
        Some(p) => Some(super::mcap::McapFile::start(
            node.events(),
            others().await?,
            p,
        )?),
        None => None,
    };
    let monitor = match monitor_listen {
        Some(listen) => {
            let control = PageControl::new(node.events().clone(), node_processes);
            let options = super::netns::PrivateNet::monitor_options(listen)
                .with_control(control, allow_faults);
            let (monitor, relay) =
                super::monitor::start_live(node.events(), options, transport.is_some(), remote)
                    .await?;
            let what = format!("mission `{}`", mission.name);
            if say {
                super::monitor::announce(&monitor, &what);
            } else {
                // `--explain --json`: stdout holds the choices alone
                eprintln!("monitor: {} ({what})", monitor.url());
            }
            Some((monitor, relay))
        }
        None => None,
    };
    let report = node.run(mission, options).await;
    lines.finish().await;
    let events = match events {
        Some(file) => Some(file.finish().await),
        None => None,
    };
    let mcap = match mcap {
        Some(file) => Some(file.finish().await),
        None => None,
    };
    let picture = match (&report, &svg_path, &robot) {
        (Ok(report), Some(_), Some(robot)) => Some(robot.picture(report).await),
        _ => None,
    };
    let world = robot.as_ref().map(|r| r.world().clone());
    node.shutdown().await;
    for task in publisher.into_iter().chain(forwarder) {
        task.abort();
    }
    // a monitor's page still reaches the cluster after the run (its properties, its
    // faults, the other nodes' news): the membership ends with the page
    let transport = match (transport, &monitor) {
        (Some(t), None) => {
            t.stop().await;
            None
        }
        (t, _) => t,
    };
    let report = match report {
        Ok(report) => report,
        Err(e) => {
            if let Some(t) = transport {
                t.stop().await;
            }
            return Err(e.into());
        }
    };
    // the report of `marie run` always holds the simulated robot's fields (null without one)
    let mut report = report;
    if report.robot.is_empty() {
        report.robot = RobotReport::default().section();
    }
    if say {
        println!("{}", end_line(&report));
        if world.is_some() {
            println!("{}", outcome_line(&report));
        }
        if let Some(line) = verdict_line(&report) {
            println!("{line}");
        }
    }

    // Write every output asked for, even when one of them cannot be written.
    let mut written = true;
    if let Some(Err(e)) = &events {
        eprintln!("marie: {e:#}");
        written = false;
    }
    if let Some(Err(e)) = &mcap {
        eprintln!("marie: {e:#}");
        written = false;
    }
    if let Some(p) = &report_path {
        if let Err(e) = write_report(p, &report) {
            eprintln!("marie: {e:#}");
            written = false;
        }
    }
    if let (Some(p), Some(picture), Some(world)) = (&svg_path, &picture, &world) {
        let svg = picture.render(world, SVG_SCALE);
        if let Err(e) = std::fs::write(p, svg) {
            eprintln!("marie: cannot write the picture to {}: {e}", p.display());
            written = false;
        }
    }
    let mut code = match (report.outcome, written) {
        (Outcome::Succeeded, true) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    };
    // a replay's verdict is whether it matched, whatever the outcome it matched
    if let Some(r) = &replay {
        let comparison = r.compare(&report);
        for line in comparison.lines() {
            println!("{line}");
        }
        code = match (comparison.matches(), written) {
            (true, true) => ExitCode::SUCCESS,
            _ => ExitCode::from(1),
        };
    }

    // the outputs are written: the page stays up for as long as the user reads it
    if monitor.is_none() {
        mission_over.set();
    }
    if let Some((monitor, relay)) = monitor {
        // virtual time need not run on while the page is read
        drop(pace);
        // the page must hold the run's last events (the outcome) once the line says so
        if !monitor.flush(MONITOR_FLUSH) {
            tracing::warn!(
                "the monitor had not taken the run's last events within {MONITOR_FLUSH:?}"
            );
        }
        // watched before the line: a Ctrl-C right after it is not missed (under `marie up`,
        // watched since before the run: nor is one that came before the line)
        let stop = mission_over.ctrl_c();
        mission_over.set();
        let over = "monitor: the run is over; its page stays up until Ctrl-C";
        if say {
            println!("{over}");
            let _ = std::io::Write::flush(&mut std::io::stdout());
        } else {
            eprintln!("{over}");
        }
        let signal = stop.wait().await;
        if say {
            println!("monitor stopped ({signal})");
        }
        if let Some(relay) = relay {
            relay.abort();
        }
        monitor.stop();
    }
    if let Some(t) = transport {
        t.stop().await;
    }
    Ok(code)
}

fn write_report(path: &Path, report: &RunReport) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(report)?;
    std::fs::write(path, json + "\n")
        .with_context(|| format!("cannot write the report to {}", path.display()))
}

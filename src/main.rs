//! The `marie` command: run missions, list the location table, ask operations about
//! themselves. Results go to stdout, diagnostics (tracing) to stderr.
//!
//! Exit codes (DESIGN.md §8): 0 success, 1 mission failed, 2 bad input.

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use marie::actors::dispatcher::mission::Mission;
use marie::actors::dispatcher::{DispatchEvent, Outcome, RunReport};
use marie::actors::eo::EoClient;
use marie::actors::property::{Group, PropertyReply, PropertyRequest};
use marie::actors::registry::{self, ModuleKind};
use marie::embedded::{Embedded, EmbeddedError, EmbeddedOptions};
use marie::fault::{self, Chaos, FaultKind, FaultPlan, FaultSpec};
use marie::node::{Node, NodeError};
use marie::supervision::SupervisorEvent;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tokio::sync::mpsc;

#[derive(Parser, Debug)]
#[command(name = "marie", version, about = "Run MARIE missions on ractor actors")]
struct Cli {
    /// Diagnostics format on stderr (filter with RUST_LOG, default `warn`).
    #[arg(long, value_enum, default_value_t = LogFormat::Text, global = true)]
    log_format: LogFormat,
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum LogFormat {
    Text,
    Json,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a mission on the embedded node.
    Run {
        /// Mission file (TOML task tree).
        mission: PathBuf,
        #[command(flatten)]
        robot: RobotArgs,
        /// Write the run report (JSON) here.
        #[arg(long, value_name = "FILE")]
        report: Option<PathBuf>,
        /// Draw the robot's run (walls, driven path, sonar echoes, segments, followed wall,
        /// detected dock, planned path, final footprint) as an SVG picture here. Needs a world.
        #[arg(long, value_name = "FILE.svg")]
        svg: Option<PathBuf>,
        /// Clock speed: a factor of real time (`1` is real time), or `max`: virtual time, as
        /// fast as the CPU allows (the default).
        #[arg(long, default_value = "max", value_parser = parse_speed)]
        speed: f64,
        /// Inject a fault while the mission runs: `kill:NAME@SECS`, `panic:NAME@SECS` or
        /// `hang:NAME@SECS` (NAME: operation name or id; SECS: mission time). Repeatable.
        #[arg(long = "fault", value_name = "KIND:NAME@SECS")]
        faults: Vec<FaultSpec>,
        /// Kill a random operation of the running action every 4 to 12 s of mission time,
        /// picked by a generator seeded with SEED.
        #[arg(long, value_name = "SEED")]
        chaos: Option<u64>,
    },
    /// Check a mission against the running operations without running it.
    Check {
        /// Mission file.
        mission: PathBuf,
        #[command(flatten)]
        robot: RobotArgs,
    },
    /// List the location table of the embedded node.
    Ls {
        /// Print JSON instead of the start-up log format.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        robot: RobotArgs,
    },
    /// Kill an operation on the embedded node and show its supervisor restarting it.
    Kill {
        /// Operation name or numeric id.
        operation: String,
        #[command(flatten)]
        robot: RobotArgs,
    },
    /// Show every property of an operation.
    Props {
        /// Operation name or numeric id.
        operation: String,
        /// Print JSON.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        robot: RobotArgs,
    },
}

/// The simulated robot a mission runs with.
#[derive(clap::Args, Debug)]
struct RobotArgs {
    /// World file the simulated robot drives in; overrides the mission's `world`. Without
    /// either, no robot is started.
    #[arg(long, value_name = "FILE")]
    world: Option<PathBuf>,
    /// Seed of the simulation's noise (same world, seed and mission: same run); default:
    /// the node config's, else 1.
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Host exactly what this node config says (`missions/nodes/*.toml`); default: a
    /// built-in node that hosts everything.
    #[arg(long, value_name = "FILE")]
    node: Option<PathBuf>,
}

impl RobotArgs {
    /// The embedded node's options for a mission whose world is `mission_world`.
    fn options(&self, mission_world: Option<&Path>) -> EmbeddedOptions {
        EmbeddedOptions {
            node: self.node.clone(),
            world: self.world.clone(),
            mission_world: mission_world.map(Path::to_path_buf),
            seed: self.seed,
            ..EmbeddedOptions::default()
        }
    }
}

/// `--speed max`: virtual time, as fast as the CPU allows.
const MAX_SPEED: f64 = f64::INFINITY;

fn parse_speed(s: &str) -> Result<f64, String> {
    if s == "max" {
        return Ok(MAX_SPEED);
    }
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("expected a positive number or `max`, got {s:?}")),
    }
}

/// The runtime: multi-threaded in real (or scaled) time; for `--speed max` a single thread
/// with tokio's paused clock, which jumps to the next timer whenever every actor is idle.
fn runtime(speed: f64) -> std::io::Result<tokio::runtime::Runtime> {
    if speed.is_infinite() {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(true)
            .build()
    } else {
        tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
    }
}

fn init_tracing(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match format {
        LogFormat::Text => builder.init(),
        LogFormat::Json => builder.json().init(),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_tracing(cli.log_format);
    let speed = match &cli.command {
        Command::Run { speed, .. } => *speed,
        _ => 1.0,
    };
    let runtime = match runtime(speed) {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("marie: cannot start the runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(run(cli.command)) {
        Ok(code) => code,
        Err(e) => {
            // Bad input is reported as exit 2, everything else as 1.
            if let Some(NodeError::Mission(diags)) = e.downcast_ref::<NodeError>() {
                eprintln!("{diags}");
                return ExitCode::from(2);
            }
            if let Some(err) = e.downcast_ref::<EmbeddedError>() {
                if err.is_bad_input() {
                    eprintln!("{err}");
                    return ExitCode::from(2);
                }
            }
            if e.downcast_ref::<BadInput>().is_some() {
                eprintln!("marie: {e:#}");
                return ExitCode::from(2);
            }
            eprintln!("marie: {e:#}");
            ExitCode::from(1)
        }
    }
}

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct BadInput(String);

async fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::Run {
            mission,
            robot,
            report,
            svg,
            speed,
            faults,
            chaos,
        } => {
            let plan = FaultPlan {
                faults,
                chaos: chaos.map(Chaos::new),
            };
            run_mission(mission, robot, report, svg, speed, plan).await
        }
        Command::Kill { operation, robot } => kill(&operation, robot).await,
        Command::Check { mission, robot } => {
            let prepared = prepare(&mission, robot, 1.0).await?;
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
        Command::Ls { json, robot } => {
            let node = Embedded::start(robot.options(None)).await?.node;
            let list = registry::list();
            if json {
                let rows: Vec<_> = list
                    .iter()
                    .map(|i| {
                        serde_json::json!({
                            "kind": i.kind.label(), "id": i.id, "name": i.name,
                            "node": i.node, "address": i.actor.get_id().to_string(),
                        })
                    })
                    .collect();
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                print!("{}", registry::render_listing(&list));
            }
            node.shutdown().await;
            Ok(ExitCode::SUCCESS)
        }
        Command::Props {
            operation,
            json,
            robot,
        } => {
            let node = Embedded::start(robot.options(None)).await?.node;
            let result = props(&operation, json).await;
            node.shutdown().await;
            result
        }
    }
}

/// A node started for a mission, with the mission checked against it.
struct Prepared {
    node: Node,
    robot: Option<std::sync::Arc<marie::missions::robot::SimRobot>>,
    mission: Mission,
    /// The world file the robot drives in, when one runs.
    world_path: Option<PathBuf>,
}

impl Prepared {
    /// `world `lab` from FILE, seed N`, when a robot runs.
    fn world_line(&self) -> Option<String> {
        let robot = self.robot.as_ref()?;
        Some(format!(
            "world `{}` from {}, seed {}",
            robot.world().name,
            self.world_path
                .as_deref()
                .map_or_else(|| "?".into(), |p| p.display().to_string()),
            robot.seed()
        ))
    }
}

/// Parse the mission, load its world (`--world`, else the mission's `world`, else none),
/// start the node (with the robot when there is a world) and check the mission against it.
async fn prepare(path: &Path, robot: RobotArgs, speed: f64) -> anyhow::Result<Prepared> {
    let parsed = Mission::parse_file(path).map_err(NodeError::Mission)?;
    let mut options = robot.options(parsed.world());
    options.mission_world_at = parsed.world_diagnostic("the world named here does not load:");
    if speed.is_finite() && (speed - 1.0).abs() > f64::EPSILON {
        options.clock = std::sync::Arc::new(marie::actors::clock::ScaledClock::new(speed));
    }
    let Embedded {
        node,
        robot,
        world_path,
    } = Embedded::start(options).await?;
    match node.check_mission(&parsed).await {
        Ok(mission) => Ok(Prepared {
            node,
            robot,
            mission,
            world_path,
        }),
        Err(e) => {
            node.shutdown().await;
            Err(e.into())
        }
    }
}

async fn run_mission(
    path: PathBuf,
    robot: RobotArgs,
    report_path: Option<PathBuf>,
    svg_path: Option<PathBuf>,
    speed: f64,
    plan: FaultPlan,
) -> anyhow::Result<ExitCode> {
    // on the paused-clock runtime, the runtime's own time is already virtual
    let speed = if speed.is_infinite() { 1.0 } else { speed };
    let prepared = prepare(&path, robot, speed).await?;
    if svg_path.is_some() && prepared.robot.is_none() {
        prepared.node.shutdown().await;
        return Err(BadInput(format!(
            "--svg draws a robot's run, but no robot runs: give a world with --world FILE \
             or `world = \"...\"` in the `[mission]` of {}",
            path.display()
        ))
        .into());
    }
    println!(
        "mission `{}` ({} actions) from {}",
        prepared.mission.name,
        prepared.mission.actions.len(),
        path.display()
    );
    if let Some(line) = prepared.world_line() {
        println!("{line}");
    }
    for f in &plan.faults {
        if registry::lookup(ModuleKind::Operation, &f.target).is_empty() {
            prepared.node.shutdown().await;
            return Err(BadInput(format!(
                "--fault {f}: no operation `{}` is running (`marie ls` lists them)",
                f.target
            ))
            .into());
        }
    }
    let Prepared {
        node,
        robot,
        mission,
        ..
    } = prepared;
    let (tx, mut rx) = mpsc::unbounded_channel();
    let printer = tokio::spawn(async move {
        while let Some(evt) = rx.recv().await {
            print_event(&evt);
        }
    });
    let report = node.run_with_faults(mission, Some(tx), plan).await;
    let _ = printer.await;
    let picture = match (&report, &svg_path, &robot) {
        (Ok(report), Some(_), Some(robot)) => Some(robot.picture(report).await),
        _ => None,
    };
    let world = robot.as_ref().map(|r| r.world().clone());
    node.shutdown().await;
    let report = report?;
    for f in &report.faults {
        match &f.error {
            None => println!(
                "* injected {} into {} ({}) at {:.1}s",
                f.fault,
                f.operation,
                f.actor,
                f.at_ms as f64 / 1000.0
            ),
            Some(e) => println!(
                "* could not inject {} into {} at {:.1}s: {e}",
                f.fault,
                f.operation,
                f.at_ms as f64 / 1000.0
            ),
        }
    }
    if world.is_some() {
        println!("{}", outcome_line(&report));
    }

    // Write every output asked for, even when one of them cannot be written.
    let mut written = true;
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
    Ok(match (report.outcome, written) {
        (Outcome::Succeeded, true) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    })
}

/// `marie kill`: start the embedded node, kill the operation's live instance and wait for
/// the operation supervisor to restart it.
async fn kill(operation: &str, robot: RobotArgs) -> anyhow::Result<ExitCode> {
    let node = Embedded::start(robot.options(None)).await?.node;
    let result = kill_on(&node, operation).await;
    node.shutdown().await;
    result
}

async fn kill_on(node: &Node, operation: &str) -> anyhow::Result<ExitCode> {
    let Some(inst) = registry::lookup(ModuleKind::Operation, operation)
        .into_iter()
        .next()
    else {
        return Err(BadInput(format!(
            "no operation `{operation}` is running (`marie ls` lists them)"
        ))
        .into());
    };
    let supervisor = node.operation_supervisor().await?;
    let mut events = supervisor.subscribe().await?;
    let started = std::time::Instant::now();
    let done = fault::inject_into(FaultKind::Kill, &inst)?;
    println!("killed {} ({}) at {}", inst.name, inst.id, done.actor);
    let restarted = tokio::time::timeout(std::time::Duration::from_secs(10), async {
        loop {
            match events.recv().await {
                Ok(SupervisorEvent::ChildRestarted { old, new, .. }) if old == Some(done.actor) => {
                    return Some(new)
                }
                Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                Err(_) => return None,
            }
        }
    })
    .await;
    match restarted {
        Ok(Some(new)) => {
            println!(
                "restarted by the operation supervisor as {} after {:.2} ms",
                new.get_id(),
                started.elapsed().as_secs_f64() * 1000.0
            );
            Ok(ExitCode::SUCCESS)
        }
        _ => {
            println!("not restarted within 10 s");
            Ok(ExitCode::from(1))
        }
    }
}

/// Pixels per metre of `--svg` pictures.
const SVG_SCALE: f64 = 50.0;

/// `outcome: succeeded — final pose (x, y, heading°), inside goal: yes, collisions: 0`.
fn outcome_line(report: &RunReport) -> String {
    let outcome = match report.outcome {
        Outcome::Succeeded => "succeeded",
        Outcome::Failed => "failed",
    };
    let Some([x, y, heading]) = report.final_pose else {
        return format!("outcome: {outcome} — the cart did not report its final pose");
    };
    let inside = match report.inside_goal {
        Some(true) => "yes",
        Some(false) => "no",
        None => "no goal area",
    };
    format!(
        "outcome: {outcome} — final pose ({x:.2}, {y:.2}, {:.1}°), inside goal: {inside}, collisions: {}",
        heading.to_degrees(),
        report.collisions.unwrap_or_default()
    )
}

fn write_report(path: &Path, report: &RunReport) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(report)?;
    std::fs::write(path, json + "\n")
        .with_context(|| format!("cannot write the report to {}", path.display()))
}

fn print_event(evt: &DispatchEvent) {
    match evt {
        DispatchEvent::Bound { operations } => {
            for (name, version, node) in operations {
                println!("  bound {name} v{version} on {node}");
            }
        }
        DispatchEvent::ActionStarted { action, operations } => {
            println!("> {action}: start [{}]", operations.join(", "));
        }
        DispatchEvent::ActionEnded {
            action,
            flags,
            status,
        } => {
            println!("< {action}: end, status {status} [{}]", flags.join(", "));
        }
        DispatchEvent::Lost { operation, cause } => {
            println!("! {operation} lost: {cause}");
        }
        DispatchEvent::Rebound(r) => {
            println!(
                "~ {} rebound: {} -> {} after {} ms",
                r.operation, r.from, r.to, r.downtime_ms
            );
        }
        DispatchEvent::Ended { outcome, reason } => match outcome {
            Outcome::Succeeded => println!("mission succeeded"),
            Outcome::Failed => println!("mission FAILED (full stop): {reason}"),
        },
    }
}

async fn props(operation: &str, json: bool) -> anyhow::Result<ExitCode> {
    let Some(inst) = registry::lookup(ModuleKind::Operation, operation)
        .into_iter()
        .next()
    else {
        let names: Vec<String> = registry::list()
            .into_iter()
            .filter(|i| i.kind == ModuleKind::Operation)
            .map(|i| format!("{} ({})", i.name, i.id))
            .collect();
        return Err(BadInput(format!(
            "no operation `{operation}` is running (running: {})",
            names.join(", ")
        ))
        .into());
    };
    let client = EoClient::from_cell(inst.actor);
    let mut replies = Vec::new();
    for req in [
        PropertyRequest::Group(Group::Identification),
        PropertyRequest::Group(Group::Location),
        PropertyRequest::Group(Group::General),
        PropertyRequest::Group(Group::Specific),
    ] {
        replies.push(client.property(req).await?);
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&replies)?);
        return Ok(ExitCode::SUCCESS);
    }
    for reply in &replies {
        print_reply(reply);
    }
    Ok(ExitCode::SUCCESS)
}

fn print_reply(reply: &PropertyReply) {
    match reply {
        PropertyReply::Identification(i) => {
            println!("identification");
            println!("  name:        {}", i.name);
            println!("  id:          {}", i.id);
            println!("  version:     {}", i.version);
            println!("  description: {}", i.description);
        }
        PropertyReply::Location(l) => {
            println!("location");
            println!("  node:    {}", l.node);
            println!("  address: {}", l.address);
            println!("  alive:   {}", l.alive);
        }
        PropertyReply::General(g) => {
            println!("general");
            println!("  parameters:  {}", g.param_count);
            println!("  up-time:     {} ms", g.uptime_ms);
            println!("  in use:      {}", g.in_use);
            println!("  activations: {}", g.activations);
        }
        PropertyReply::Specific(s) => {
            println!("parameters");
            for d in &s.params {
                let range = match (d.min, d.max) {
                    (None, None) => String::new(),
                    (a, b) => format!(
                        " [{}, {}]",
                        a.map_or("-inf".into(), |v| v.to_string()),
                        b.map_or("+inf".into(), |v| v.to_string())
                    ),
                };
                let unit = d
                    .unit
                    .as_deref()
                    .map(|u| format!(" {u}"))
                    .unwrap_or_default();
                let current = s
                    .current
                    .get(&d.name)
                    .map(|v| v.to_string())
                    .unwrap_or_default();
                println!(
                    "  {:<18} {:<10} default {}{unit}{range}; current {current}{}  {}",
                    d.name,
                    d.ty.to_string(),
                    d.default,
                    if d.read_only { " (read-only)" } else { "" },
                    d.description
                );
            }
            if !s.flags.is_empty() {
                println!("flags");
                for (i, f) in s.flags.iter().enumerate() {
                    println!("  bit {i}: {:<14} {}", f.name, f.description);
                }
            }
        }
        other => println!("{other:?}"),
    }
}

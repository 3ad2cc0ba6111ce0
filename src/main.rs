//! The `marie` command: run missions, list the location table, ask operations about
//! themselves. Results go to stdout, diagnostics (tracing) to stderr.
//!
//! Exit codes (DESIGN.md §8): 0 success, 1 mission failed, 2 bad input.

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use marie::actors::dispatcher::{DispatchEvent, Outcome, RunReport};
use marie::actors::eo::EoClient;
use marie::actors::property::{Group, PropertyReply, PropertyRequest};
use marie::actors::registry::{self, ModuleKind};
use marie::node::{Node, NodeError, NodeOptions};
use std::path::PathBuf;
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
        /// Write the run report (JSON) here.
        #[arg(long, value_name = "FILE")]
        report: Option<PathBuf>,
        /// Clock speed: a factor of real time, or `max` (virtual time, as fast as possible).
        #[arg(long, default_value = "1", value_parser = parse_speed)]
        speed: f64,
    },
    /// Check a mission against the running operations without running it.
    Check {
        /// Mission file.
        mission: PathBuf,
    },
    /// List the location table.
    Ls {
        /// Print JSON instead of the start-up log format.
        #[arg(long)]
        json: bool,
    },
    /// Show every property of an operation.
    Props {
        /// Operation name or numeric id.
        operation: String,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
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
            report,
            speed,
        } => run_mission(mission, report, speed).await,
        Command::Check { mission } => {
            let node = Node::start(NodeOptions::default()).await?;
            let m = node.load_mission(&mission).await;
            node.shutdown().await;
            let m = m?;
            println!(
                "{}: ok — mission `{}`, {} actions, {} operations",
                mission.display(),
                m.name,
                m.actions.len(),
                m.operation_names().len()
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Ls { json } => {
            let node = Node::start(NodeOptions::default()).await?;
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
        Command::Props { operation, json } => {
            let node = Node::start(NodeOptions::default()).await?;
            let result = props(&operation, json).await;
            node.shutdown().await;
            result
        }
    }
}

async fn run_mission(
    path: PathBuf,
    report_path: Option<PathBuf>,
    speed: f64,
) -> anyhow::Result<ExitCode> {
    let node = Node::start(NodeOptions {
        // on the paused-clock runtime, the runtime's own time is already virtual
        speed: if speed.is_infinite() { 1.0 } else { speed },
        ..Default::default()
    })
    .await?;
    let mission = node.load_mission(&path).await?;
    println!(
        "mission `{}` ({} actions) from {}",
        mission.name,
        mission.actions.len(),
        path.display()
    );
    let (tx, mut rx) = mpsc::unbounded_channel();
    let printer = tokio::spawn(async move {
        while let Some(evt) = rx.recv().await {
            print_event(&evt);
        }
    });
    let report = node.run(mission, Some(tx)).await;
    let _ = printer.await;
    node.shutdown().await;
    let report = report?;
    if let Some(p) = report_path {
        write_report(&p, &report)?;
    }
    Ok(match report.outcome {
        Outcome::Succeeded => ExitCode::SUCCESS,
        Outcome::Failed => ExitCode::from(1),
    })
}

fn write_report(path: &PathBuf, report: &RunReport) -> anyhow::Result<()> {
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

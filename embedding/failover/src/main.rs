//! `failover-app`: one process of the three-process application of `marie_failover_app`
//! (see the crate docs for the whole story and the numbers behind a failover).
//!
//! ```text
//! failover-app --name NAME --data-dir DIR --replicas N1,N2,N3 [--listen ADDR] [--peer ADDR]...
//!              [--cookie C] [--rate L] [--standby] [--run LITRES]
//! ```
//!
//! - `--listen` defaults to `127.0.0.1:0` (a port the system picks; the first line says
//!   which): `node NAME listening on ADDR`.
//! - `--data-dir`: where its replica of the pump log keeps its journal (created if need be;
//!   one process per directory).
//! - `--replicas`: the nodes that keep the pump log, the preferred leader first — the same
//!   list in every process, this one among them. Once a majority of them is up it prints
//!   `pump-log leader: N`, and again each time another node's replica is elected; each
//!   step its pumps logged is `pump-log: STATION#STEP stored as seq S`.
//! - `--rate`: litres its station moves per step (default 1).
//! - `--standby`: its pump starts only when no pump runs anywhere in the cluster.
//! - `--run LITRES`: this process runs the dispatcher and the mission (pump LITRES litres)
//!   once a pump runs somewhere, prints what happens — `pump runs on node N`, `pump lost:
//!   …`, `pump rebound from node X to node Y …`, then `rebind: pump from X to Y` for each
//!   rebind of the report, the run's check of the pump log (`pump-log check: H of A
//!   acknowledged held, L lost`), every step the log holds (`pump-log holds N records:
//!   b#1=2 b#2=3 …`, each `STATION#STEP=SEQ`) and `outcome: succeeded|failed …` — and
//!   exits 0 if the mission succeeded, 1 if not.
//! - Without `--run` it hosts until its standard input closes, then leaves the cluster.
//!
//! A bad flag is exit 2. The lines go to standard output, flushed at once, for whoever waits
//! for them (a person, `tests/failover.rs`).

use marie::cluster::node::RunOptions;
use marie::dm::DmClient;
use marie::events::EventKind;
use marie::report::RunReport;
use marie_failover_app::{
    logged_steps, mission, node, pump_log, tell_leaders, wait_for_pump, Setup, Station, PUMP,
    PUMP_LOG,
};
use std::io::Write;
use std::process::ExitCode;
use std::time::Duration;

/// How long the dispatcher's process waits for a pump to appear in the cluster.
const PUMP_TIMEOUT: Duration = Duration::from_secs(60);
/// How long a process waits for the pump log's first leader (a majority of its replicas'
/// processes started, and an election).
const LOG_TIMEOUT: Duration = Duration::from_secs(60);

fn main() -> ExitCode {
    let (setup, run) = match parse(std::env::args().skip(1)) {
        Ok(parsed) => parsed,
        Err(e) => {
            eprintln!("failover-app: {e}");
            return ExitCode::from(2);
        }
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a tokio runtime");
    match runtime.block_on(serve(setup, run)) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("failover-app: {e}");
            ExitCode::from(1)
        }
    }
}

/// Start the node (it joins the cluster), tell the pump log's leaders, then run the mission
/// or host until stdin closes.
async fn serve(setup: Setup, run: Option<f64>) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let station = Station::new(&setup.name, setup.litres_per_step);
    station.on_logged(|step, seq| {
        say(&format!(
            "{}: {} stored as seq {seq}",
            PUMP_LOG.name,
            step.label()
        ))
    });
    let node = node(&setup, station).start().await?;
    let name = setup.name.clone();
    let listen = node.transport().map(|t| t.listen());
    say(&format!(
        "node {name} listening on {}",
        listen.map_or_else(|| "?".into(), |a| a.to_string())
    ));
    let log = match pump_log(&name, LOG_TIMEOUT).await {
        Ok(log) => log,
        Err(e) => {
            node.shutdown().await;
            return Err(format!("the pump log has no leader within {LOG_TIMEOUT:?}: {e}").into());
        }
    };
    tokio::spawn(tell_leaders(log.clone(), |leader| match leader {
        Ok(node) => say(&format!("{} leader: {node}", PUMP_LOG.name)),
        Err(e) => say(&format!("{} leader: none to ask ({e})", PUMP_LOG.name)),
    }));
    let Some(litres) = run else {
        stdin_closed().await;
        node.shutdown().await;
        say(&format!("node {name} stopped"));
        return Ok(ExitCode::SUCCESS);
    };
    let Some(on) = wait_for_pump(PUMP_TIMEOUT).await else {
        node.shutdown().await;
        return Err(format!("no pump appeared in the cluster within {PUMP_TIMEOUT:?}").into());
    };
    say(&format!("pump found on node {on}"));
    // the run's events as lines, as they are published (a line is quick to print)
    let options = RunOptions::new().observe(|event| {
        if let Some(line) = describe(&event.kind) {
            say(&line);
        }
    });
    let report = node.run(mission(litres), options).await;
    let listed = list_log(&log).await;
    node.shutdown().await;
    let report = report?;
    for r in &report.rebinds {
        say(&format!(
            "rebind: {} from {} to {}",
            r.operation, r.from_node, r.to_node
        ));
    }
    say(&checked(&report));
    say(&listed?);
    say(&format!(
        "outcome: {}{}",
        if report.succeeded() {
            "succeeded"
        } else {
            "failed"
        },
        if report.reason.is_empty() {
            String::new()
        } else {
            format!(" ({})", report.reason)
        }
    ));
    Ok(if report.succeeded() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The run's own check of the pump log: of the steps the run heard acknowledged (the pumps'
/// nodes tell them), how many the log's leader holds at the run's end.
fn checked(report: &RunReport) -> String {
    match report.dm_checks.iter().find(|c| c.dm == PUMP_LOG.name) {
        Some(c) => format!(
            "{} check: {} of {} acknowledged held, {} lost",
            PUMP_LOG.name, c.held, c.acknowledged, c.lost
        ),
        None => format!("{} check: not checked", PUMP_LOG.name),
    }
}

/// Every step the pump log holds, as one line: `pump-log holds N records: b#1=2 …`.
async fn list_log(log: &DmClient) -> Result<String, Box<dyn std::error::Error>> {
    let steps = logged_steps(log).await?;
    let listed: Vec<String> = steps
        .iter()
        .map(|(header, step)| format!("{}={}", step.label(), header.seq))
        .collect();
    Ok(format!(
        "{} holds {} records: {}",
        PUMP_LOG.name,
        listed.len(),
        listed.join(" ")
    ))
}

/// The line an event of the run gives, if any.
fn describe(kind: &EventKind) -> Option<String> {
    match kind {
        EventKind::ActionStarted { operations, .. } => operations
            .iter()
            .find(|o| o.name == PUMP)
            .map(|o| format!("pump runs on node {}", o.node)),
        EventKind::Lost { operation, cause } => Some(format!("{operation} lost: {cause}")),
        EventKind::Rebound(r) => Some(format!(
            "{} rebound from node {} to node {} after {} ms",
            r.operation, r.from_node, r.to_node, r.downtime_ms
        )),
        _ => None,
    }
}

/// Until standard input closes (the process that started this one holds the other end).
async fn stdin_closed() {
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    std::thread::spawn(move || {
        let _ = std::io::copy(&mut std::io::stdin().lock(), &mut std::io::sink());
        let _ = tx.send(());
    });
    let _ = rx.await;
}

/// The flags: the process's setup and, with `--run`, the litres of the mission.
fn parse(mut args: impl Iterator<Item = String>) -> Result<(Setup, Option<f64>), FlagError> {
    let mut setup = Setup {
        name: String::new(),
        listen: ([127, 0, 0, 1], 0).into(),
        peers: Vec::new(),
        cookie: "failover".into(),
        litres_per_step: 1.0,
        standby: false,
        dispatcher: false,
        data_dir: Default::default(),
        log_replicas: Vec::new(),
    };
    let mut run = None;
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or_else(|| FlagError::NoValue(flag.clone()));
        match flag.as_str() {
            "--name" => setup.name = value()?,
            "--listen" => setup.listen = address(&flag, &value()?)?,
            "--peer" => {
                let peer = value()?;
                setup.peers.push(address(&flag, &peer)?);
            }
            "--cookie" => setup.cookie = value()?,
            "--rate" => setup.litres_per_step = litres(&flag, &value()?)?,
            "--standby" => setup.standby = true,
            "--data-dir" => setup.data_dir = value()?.into(),
            "--replicas" => {
                setup.log_replicas = value()?.split(',').map(|n| n.trim().to_string()).collect();
            }
            "--run" => {
                run = Some(litres(&flag, &value()?)?);
                setup.dispatcher = true;
            }
            _ => return Err(FlagError::Unknown(flag)),
        }
    }
    if setup.name.is_empty() {
        return Err(FlagError::Missing("--name NAME"));
    }
    if setup.data_dir.as_os_str().is_empty() {
        return Err(FlagError::Missing(
            "--data-dir DIR (the pump log's journal)",
        ));
    }
    if setup.log_replicas.is_empty() {
        return Err(FlagError::Missing(
            "--replicas N1,N2,N3 (the nodes that keep the pump log)",
        ));
    }
    Ok((setup, run))
}

fn address(flag: &str, text: &str) -> Result<std::net::SocketAddr, FlagError> {
    text.parse().map_err(|e| FlagError::NotAnAddress {
        flag: flag.to_string(),
        text: text.to_string(),
        error: e,
    })
}

fn litres(flag: &str, text: &str) -> Result<f64, FlagError> {
    match text.parse::<f64>() {
        Ok(l) if l.is_finite() && l > 0.0 => Ok(l),
        _ => Err(FlagError::NotLitres {
            flag: flag.to_string(),
            text: text.to_string(),
        }),
    }
}

/// A command line that does not say what to do (exit 2). Written out by hand: the
/// application depends on marie and tokio alone.
#[derive(Debug)]
enum FlagError {
    /// A flag that takes a value ends the line.
    NoValue(String),
    /// A flag this program does not know.
    Unknown(String),
    /// A flag that must be given is not.
    Missing(&'static str),
    /// An address flag whose value is none.
    NotAnAddress {
        flag: String,
        text: String,
        error: std::net::AddrParseError,
    },
    /// A litres flag whose value is not a positive number.
    NotLitres { flag: String, text: String },
}

impl std::fmt::Display for FlagError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FlagError::NoValue(flag) => write!(f, "{flag} needs a value"),
            FlagError::Unknown(flag) => write!(f, "unknown flag {flag}"),
            FlagError::Missing(what) => write!(f, "{what} is required"),
            FlagError::NotAnAddress { flag, text, error } => {
                write!(f, "{flag} {text}: not an address (ip:port): {error}")
            }
            FlagError::NotLitres { flag, text } => {
                write!(f, "{flag} {text}: expected a positive number of litres")
            }
        }
    }
}

impl std::error::Error for FlagError {}

/// A line on stdout, flushed at once (stdout is a pipe when a parent waits for it).
fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

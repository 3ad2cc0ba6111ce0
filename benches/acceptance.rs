//! The acceptance of issue 23 (point 5): N seeded schedules (default 30), each one node
//! fault — `stop-node`, `freeze-node` (+D) or `partition` (+D) of a node other than the
//! cart's, at a moment drawn over the whole run — in one `marie up
//! missions/clusters/thesis.toml --run missions/docking.toml`; then the table of their
//! verdicts from the reports and a summary: the goal is that at least 29 of 30 dock, none
//! loses an acknowledged record, none obeys a command from an old epoch, none collides. Exits 1 when the goal does not hold, 130
//! when interrupted.
//!
//! ```text
//! scripts/acceptance                      # 30 schedules at wall-clock speed, 3 at a time
//! scripts/acceptance 10 --from 31         # schedules 31..40
//! scripts/acceptance --speed 4 --jobs 1   # four times faster, one run at a time
//! scripts/acceptance --run-secs 64        # skip the fault-free run that measures the run
//! scripts/acceptance --logs DIR           # keep each run's stdout, stderr and report
//! scripts/acceptance --run-secs 64 --list # only print each schedule's --fault
//! ```
//!
//! The default speed is 1, wall-clock time: a failover's delays are real time (the failure
//! detector's 1.2 s deadline, an election, an operation's 5 s wait for a module gone) and a
//! mission's limits mission time (a wall follower fails after 15 s without progress), so a
//! faster run turns each real-time stall into a multiple of mission time — at `--speed 4`
//! a cut of the features node that docks at speed 1 failed on a 20 s stall of the wall
//! following. At speed 1 a run of the thesis layout takes about a fifth of a core: three at
//! a time (`--jobs`, default 3) hold on two cores, 30 schedules in about 13 minutes.
//!
//! What a schedule is, how its fault is drawn and how its verdict is read:
//! `tests/common/acceptance.rs`, shared with `tests/acceptance.rs` (the five CI runs), so
//! the script and the test cannot drift apart.
//!
//! A bench binary rather than a shell script: the victims come from the cluster file as
//! `marie up` reads it (its loader: every node but those running the cart's drivers — a
//! node added to the file, a dispatcher's, is among them by itself), the reports are read
//! as JSON without `jq`, the faults are drawn by the project's seeded generator, and the
//! test runs the very same code.
//!
//! Nothing is left behind: each `marie up` runs in a process group of its own and stops
//! its nodes, their namespaces and data directories when it exits; a Ctrl-C (SIGINT or
//! SIGTERM to this process) is passed on to the running ones once, which then stop their
//! clusters (killed if they have not within 30 s), the table so far is printed, and the
//! temporary directory of the reports is removed.

#[allow(dead_code)]
#[path = "../tests/common/acceptance.rs"]
mod acceptance;

use acceptance::{header, summary, Draw, Layout, Running, Schedule, Verdict};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Set by SIGINT or SIGTERM.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// The command line.
struct Args {
    count: u64,
    from: u64,
    speed: f64,
    jobs: usize,
    run_secs: Option<f64>,
    logs: Option<PathBuf>,
    list: bool,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        count: 30,
        from: 1,
        speed: 1.0,
        jobs: 3,
        run_secs: None,
        logs: None,
        list: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            // cargo bench passes it to every bench binary
            "--bench" => {}
            "--from" => {
                args.from = value("--from")?
                    .parse()
                    .map_err(|e| format!("--from: {e}"))?
            }
            "--speed" => {
                args.speed = value("--speed")?
                    .parse()
                    .map_err(|e| format!("--speed: {e}"))?
            }
            "--jobs" => {
                args.jobs = value("--jobs")?
                    .parse()
                    .map_err(|e| format!("--jobs: {e}"))?
            }
            "--run-secs" => {
                args.run_secs = Some(
                    value("--run-secs")?
                        .parse()
                        .map_err(|e| format!("--run-secs: {e}"))?,
                )
            }
            "--logs" => args.logs = Some(PathBuf::from(value("--logs")?)),
            "--list" => args.list = true,
            n => {
                args.count = n
                    .parse()
                    .map_err(|_| format!("unknown argument `{n}` (see benches/acceptance.rs)"))?
            }
        }
    }
    if !(0.01..=20.0).contains(&args.speed) {
        return Err(format!(
            "--speed {}: a cluster runs at 0.01 to 20",
            args.speed
        ));
    }
    args.jobs = args.jobs.max(1);
    Ok(args)
}

/// Whether partitions can be made here: `marie up` needs root and `ip`.
fn partitions_possible() -> bool {
    // SAFETY: geteuid(2) takes nothing and cannot fail
    let root = unsafe { libc::geteuid() } == 0;
    root && std::process::Command::new("ip")
        .arg("-V")
        .output()
        .is_ok_and(|o| o.status.success())
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("acceptance: {e}");
            return ExitCode::from(2);
        }
    };
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
    let layout = match Layout::load(acceptance::CLUSTER) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("acceptance: {e}");
            return ExitCode::from(2);
        }
    };
    // the reports' directory: removed at the end unless --logs keeps them
    let temporary = match tempfile::Builder::new()
        .prefix("marie-acceptance-")
        .tempdir()
    {
        Ok(d) => d,
        Err(e) => {
            eprintln!("acceptance: a temporary directory: {e}");
            return ExitCode::from(2);
        }
    };
    let base = args
        .logs
        .clone()
        .unwrap_or_else(|| temporary.path().to_path_buf());
    let partitions = partitions_possible();
    println!(
        "acceptance: {} on {} with {}, --speed {}, {} at a time; victims: {} (every node but \
         the cart's){}",
        plural(args.count, "schedule"),
        acceptance::CLUSTER,
        acceptance::MISSION,
        args.speed,
        args.jobs,
        layout.victims.join(", "),
        if partitions {
            ""
        } else {
            "; no partitions (they need root and `ip`)"
        }
    );
    let run_secs = match args.run_secs {
        Some(s) => s,
        None => {
            let start = Instant::now();
            match acceptance::measure(args.speed, &base.join("fault-free")) {
                Ok(s) => {
                    println!(
                        "a fault-free run: {s:.1} s of mission time ({:.0} s in all)",
                        start.elapsed().as_secs_f64()
                    );
                    s
                }
                Err(e) => {
                    eprintln!("acceptance: {e}");
                    return ExitCode::from(1);
                }
            }
        }
    };
    if INTERRUPTED.load(Ordering::SeqCst) {
        return ExitCode::from(130);
    }
    let draw = Draw {
        run_secs,
        speed: args.speed,
        partitions,
    };
    let schedules: Vec<Schedule> = (args.from..args.from + args.count)
        .map(|n| Schedule::draw(n, &layout, &draw))
        .collect();
    if args.list {
        for s in &schedules {
            println!("schedule {}: --fault {}", s.number, s.spec());
        }
        return ExitCode::SUCCESS;
    }
    let (verdicts, interrupted) = run_all(&schedules, &args, &base);
    println!("{}", header());
    for v in &verdicts {
        println!("{}", v.row());
    }
    let (line, goal) = summary(&verdicts);
    println!("{line}");
    if let Some(logs) = &args.logs {
        println!(
            "each run's stdout, stderr and report: {}/N/",
            logs.display()
        );
    }
    drop(temporary);
    match (interrupted, goal) {
        (true, _) => {
            println!(
                "interrupted: {} of {} schedules ran",
                verdicts.len(),
                schedules.len()
            );
            ExitCode::from(130)
        }
        (false, true) => ExitCode::SUCCESS,
        (false, false) => ExitCode::from(1),
    }
}

fn plural(n: u64, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

/// Run `schedules`, `args.jobs` at a time, each into `base/N`; their verdicts in schedule
/// order, and whether a signal cut the runs short.
fn run_all(schedules: &[Schedule], args: &Args, base: &std::path::Path) -> (Vec<Verdict>, bool) {
    let mut pending = schedules.iter();
    let mut running: Vec<(Schedule, Running)> = Vec::new();
    let mut done: Vec<Verdict> = Vec::new();
    loop {
        if INTERRUPTED.load(Ordering::SeqCst) {
            eprintln!("acceptance: interrupted; stopping the running clusters");
            // dropping a run tells it to stop and waits for it
            running.clear();
            done.sort_by_key(|v| v.schedule.number);
            return (done, true);
        }
        while running.len() < args.jobs {
            let Some(s) = pending.next() else { break };
            let dir = base.join(s.number.to_string());
            match Running::start(Some(&s.spec()), args.speed, &dir) {
                Ok(run) => {
                    eprintln!("schedule {}: --fault {}", s.number, s.spec());
                    running.push((s.clone(), run));
                }
                Err(e) => {
                    eprintln!("acceptance: cannot start marie up: {e}");
                    INTERRUPTED.store(true, Ordering::SeqCst);
                    break;
                }
            }
        }
        if running.is_empty() {
            break;
        }
        let mut i = 0;
        while i < running.len() {
            match running[i].1.poll() {
                Some(exit) => {
                    let (s, run) = running.swap_remove(i);
                    let v = Verdict::of(&s, &run.report(), exit, run.elapsed());
                    if !v.passes() {
                        eprintln!("schedule {}: {}", s.number, run.stderr_tail(5));
                    }
                    eprintln!("{}", v.row());
                    done.push(v);
                }
                None => i += 1,
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    done.sort_by_key(|v| v.schedule.number);
    (done, false)
}

//! The monitor never slows the robot: the docking mission at `--speed max` (virtual time, as
//! fast as the CPU allows, as `marie run` does it) with ten viewers on the monitor's live
//! stream — one of which never reads — against the same run without a monitor, measured
//! in the same process, interleaved (goal: within 10 %).
//!
//! `cargo bench --bench monitor`

use marie::clock::Pacer;
use marie::dispatcher::mission::ParsedMission;
use marie_missions::embedded::{Embedded, EmbeddedOptions};
use marie_monitor::{Monitor, MonitorOptions};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

mod common;

/// Viewers per monitored run.
const VIEWERS: usize = 10;
/// Runs of each kind.
const RUNS: usize = 7;

/// A viewer of `/api/live` on `addr`: tells `ready` once the first bytes (the snapshot)
/// arrived, then reads until the server closes — or, `stuck`, never reads again.
fn viewer(addr: std::net::SocketAddr, stuck: bool, ready: mpsc::Sender<()>) {
    std::thread::spawn(move || {
        let Ok(mut s) = TcpStream::connect(addr) else {
            return;
        };
        let _ = write!(
            s,
            "GET /api/live HTTP/1.1\r\nHost: {addr}\r\nAccept: text/event-stream\r\n\r\n"
        );
        let mut buf = [0u8; 16 * 1024];
        if matches!(s.read(&mut buf), Ok(n) if n > 0) {
            let _ = ready.send(());
        }
        if stuck {
            // holds the connection open, reading nothing, until the monitor closes it
            std::thread::sleep(Duration::from_secs(60));
            return;
        }
        while matches!(s.read(&mut buf), Ok(n) if n > 0) {}
    });
}

/// One docking run at `--speed max`, with a live monitor if `monitored` and `viewers` on
/// it; the run's wall time.
fn run(mission: &Path, monitored: bool, viewers: usize) -> Duration {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("a runtime");
    rt.block_on(async {
        let _pace = Pacer::new(f64::INFINITY).spawn();
        let parsed = ParsedMission::parse_file(mission).expect("docking parses");
        let embedded = Embedded::start(EmbeddedOptions {
            mission_world: parsed.world().map(PathBuf::from),
            ..EmbeddedOptions::default()
        })
        .await
        .expect("the node starts");
        let node = embedded.node;
        let monitor = monitored.then(|| {
            let listen = "127.0.0.1:0".parse().expect("an address");
            let m = Monitor::live(node.events(), MonitorOptions::new(listen)).expect("serves");
            let (tx, rx) = mpsc::channel();
            for i in 0..viewers {
                viewer(m.addr(), i == 0, tx.clone());
            }
            for _ in 0..viewers {
                rx.recv_timeout(Duration::from_secs(30))
                    .expect("every viewer connected");
            }
            m
        });
        let mission = node.check_mission(&parsed).await.expect("docking fits");
        let started = Instant::now();
        let report = node
            .run(mission, marie::cluster::node::RunOptions::new())
            .await
            .expect("the run");
        let took = started.elapsed();
        assert!(report.succeeded(), "{}", report.reason);
        node.shutdown().await;
        drop(monitor);
        took
    })
}

fn main() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mission = repo.join("missions/docking.toml");
    let (mut bare, mut unwatched, mut watched) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..RUNS {
        bare.push(run(&mission, false, 0));
        unwatched.push(run(&mission, true, 0));
        watched.push(run(&mission, true, VIEWERS));
    }
    bare.sort();
    unwatched.sort();
    watched.sort();
    let (b, u, w) = (
        common::percentile(&bare, 0.5),
        common::percentile(&unwatched, 0.5),
        common::percentile(&watched, 0.5),
    );
    let ms = |d: Duration| d.as_secs_f64() * 1000.0;
    println!("docking at --speed max, median of {RUNS} runs each, interleaved");
    println!("  without a monitor:                 {:>6.1} ms", ms(b));
    println!(
        "  monitor, no viewer:                {:>6.1} ms  ({:.2}×)",
        ms(u),
        ms(u) / ms(b)
    );
    println!(
        "  monitor with {VIEWERS} viewers (1 stuck): {:>6.1} ms  ({:.2}×)",
        ms(w),
        ms(w) / ms(b)
    );
    let worst = (ms(u) / ms(b)).max(ms(w) / ms(b));
    let verdict = if worst <= 1.10 { "met" } else { "MISSED" };
    println!("goal: within 10 % (≤ 1.10×): {verdict} ({worst:.2}×)");
}

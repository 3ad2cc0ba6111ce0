//! The monitor's server over real HTTP on 127.0.0.1: the replay API on a recorded run, the
//! live state and its stream on a bus, the token.

// the one HTTP client of the tests, shared with the `marie` package's end-to-end tests
#[allow(dead_code)] // each test file uses part of it
#[path = "../../tests/common/http.rs"]
mod http;

use marie_monitor::{Monitor, MonitorOptions};
use marie_vocabulary::clock::ManualClock;
use marie_vocabulary::events::{EventBus, EventKind};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn loopback() -> MonitorOptions {
    MonitorOptions::new("127.0.0.1:0".parse().unwrap())
}

const FIXTURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/docking-kill.jsonl"
);

#[test]
fn a_replay_answers_its_extent_and_the_state_at_any_time() {
    let monitor = Monitor::replay(Path::new(FIXTURE), loopback()).unwrap();
    let addr = monitor.addr();
    assert_eq!(monitor.url(), format!("http://{addr}/"));
    let info = http::get_json(addr, "/api/replay/info");
    assert_eq!(info["events"], 51);
    let end = info["end_ms"].as_u64().unwrap();
    assert!(end > 20_000, "{info}");
    let last = http::get_json(addr, &format!("/api/replay/state?at_ms={end}"));
    for a in last["mission"]["actions"].as_array().unwrap() {
        assert_eq!(a["state"], "succeeded", "{a}");
    }
    assert_eq!(last["bindings"]["wall-follower"]["rebinds"], 1);
    assert_eq!(last["mission"]["outcome"]["outcome"], "succeeded");
    let first = http::get_json(addr, "/api/replay/state?at_ms=0");
    assert!(first["mission"]["outcome"].is_null());
    assert_eq!(http::get_json(addr, "/api/state"), last);
    assert_eq!(http::get_json(addr, "/api/info")["mode"], "replay");
    let (status, page) = http::get(addr, "/", &[]);
    assert_eq!(status, 200);
    assert!(page.contains("app.js"), "{page}");
    assert_eq!(http::get(addr, "/app.js", &[]).0, 200);
    assert_eq!(http::get(addr, "/style.css", &[]).0, 200);
    assert_eq!(http::get(addr, "/api/live", &[]).0, 404);
    assert_eq!(http::get(addr, "/api/replay/state?at_ms=soon", &[]).0, 400);
    monitor.stop();
}

#[test]
fn a_bad_events_file_is_refused_naming_its_line() {
    let dir = std::env::temp_dir().join(format!("marie-monitor-bad-{}", std::process::id()));
    std::fs::write(&dir, "\n{\"not\": \"an event\"}\n").unwrap();
    let e = Monitor::replay(&dir, loopback()).err().unwrap();
    let _ = std::fs::remove_file(&dir);
    assert!(e.to_string().contains(":2: not an event"), "{e}");
}

#[test]
fn a_required_token_is_checked_on_every_request() {
    let options = MonitorOptions {
        require_token: true,
        ..loopback()
    };
    let monitor = Monitor::replay(Path::new(FIXTURE), options).unwrap();
    let addr = monitor.addr();
    let token = monitor.token().unwrap().to_string();
    assert!(monitor.url().ends_with(&format!("/?token={token}")));
    for path in ["/", "/app.js", "/api/state", "/api/replay/info"] {
        assert_eq!(http::get(addr, path, &[]).0, 401, "{path}");
        assert_eq!(http::get(addr, &format!("{path}?token=wrong"), &[]).0, 401);
        assert_eq!(
            http::get(addr, &format!("{path}?token={token}"), &[]).0,
            200
        );
    }
    let bearer = format!("Bearer {token}");
    assert_eq!(
        http::get(addr, "/api/state", &[("Authorization", &bearer)]).0,
        200
    );
    // the page's links carry it on
    let (_, page) = http::get(addr, &format!("/?token={token}"), &[]);
    assert!(page.contains(&format!("app.js?token={token}")), "{page}");
}

#[test]
fn a_live_monitor_streams_a_snapshot_then_the_changes() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n1", clock);
    let monitor = Monitor::live(&bus, loopback()).unwrap();
    let addr = monitor.addr();
    assert_eq!(http::get_json(addr, "/api/info")["mode"], "live");
    let mut stream = http::EventStream::open(addr, "/api/live");
    let (name, data) = stream.next();
    assert_eq!(name, "snapshot");
    let first: serde_json::Value = serde_json::from_str(&data).unwrap();
    assert_eq!(first["events"], 0);
    bus.publish(EventKind::RunStarted {
        mission: "m".into(),
        actions: vec![],
        success: vec![],
    });
    let deadline = Instant::now() + http::TIMEOUT;
    loop {
        let (name, data) = stream.next();
        assert_eq!(name, "state");
        let state: serde_json::Value = serde_json::from_str(&data).unwrap();
        if state["mission"]["name"] == "m" {
            break;
        }
        assert!(Instant::now() < deadline, "no update with the run: {state}");
    }
    assert_eq!(http::get_json(addr, "/api/state")["mission"]["name"], "m");
    // events fed besides the bus count too
    let feed = monitor.feed().unwrap();
    assert!(feed.offer(marie_vocabulary::events::Event {
        at_ms: 5,
        node: "n2".into(),
        kind: EventKind::NodeFrozen { silent_ms: 1 },
    }));
    // once the monitor has taken it (flush), the state shows it
    assert!(
        monitor.flush(http::TIMEOUT),
        "the fed event was never taken"
    );
    // (a woken node is up again, and says it woke: `frozen` was a status for good)
    let n2 = &http::get_json(addr, "/api/state")["cluster"]["n2"];
    assert_eq!(
        (&n2["status"], &n2["woke"]["silent_ms"]),
        (&"up".into(), &1.into())
    );
    assert_eq!(http::get(addr, "/api/replay/info", &[]).0, 404);
    monitor.stop();
}

#[test]
fn a_stuck_viewer_is_told_it_lagged_and_resynchronised_while_the_node_publishes_on() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n1", clock.clone());
    let monitor = Monitor::live(&bus, loopback()).unwrap();
    // a big world makes every update big: a viewer that reads nothing soon fills the
    // socket's buffers, and the updates queue up for it on the monitor's side
    let walls: Vec<_> = (0..40_000)
        .map(|i| [[i as f64, 0.0], [i as f64, 1.0]])
        .collect();
    bus.publish(EventKind::Robot {
        what: "world".into(),
        data: serde_json::json!({ "walls": walls }),
    });
    let mut stream = http::EventStream::open(monitor.addr(), "/api/live");
    assert_eq!(stream.next().0, "snapshot");
    // the viewer reads nothing while the node publishes for a while: publishing never waits
    let started = Instant::now();
    let mut n = 0u64;
    while started.elapsed() < Duration::from_secs(5) {
        clock.advance(Duration::from_millis(1));
        bus.publish(EventKind::Robot {
            what: "pose".into(),
            data: serde_json::json!({"x": n as f64, "y": 0.0, "heading": 0.0}),
        });
        n += 1;
        if n % 100 == 0 {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    let publishing = started.elapsed();
    assert!(n > 1000, "published {n} in {publishing:?}");
    // now it reads: the updates it missed are reported, then a fresh snapshot
    let mut seen = Vec::new();
    loop {
        let (name, data) = stream.next();
        if name == "lagged" {
            let v: serde_json::Value = serde_json::from_str(&data).unwrap();
            assert!(v["missed"].as_u64().unwrap() > 0, "{v}");
            assert_eq!(stream.next().0, "snapshot");
            break;
        }
        seen.push(name);
        assert!(seen.len() < 1000, "never told it lagged: {seen:?}");
    }
}

#[test]
fn after_a_flush_the_state_holds_every_event_published_and_fed_before_it() {
    let clock = Arc::new(ManualClock::new());
    let bus = EventBus::new("n1", clock);
    let monitor = Monitor::live(&bus, loopback()).unwrap();
    let addr = monitor.addr();
    let feed = monitor.feed().unwrap();
    // several rounds: each read comes right after the last publish, well within the
    // reducer's poll period — only the flush makes the state whole by then
    for round in 1..=5u64 {
        for i in 0..100 {
            bus.publish(EventKind::Robot {
                what: "pose".into(),
                data: serde_json::json!({"x": i as f64, "y": 0.0, "heading": 0.0}),
            });
        }
        assert!(feed.offer(marie_vocabulary::events::Event {
            at_ms: round,
            node: format!("fed-{round}"),
            kind: EventKind::NodeFrozen { silent_ms: 1 },
        }));
        assert!(monitor.flush(http::TIMEOUT), "flushed in time");
        let state = http::get_json(addr, "/api/state");
        assert_eq!(state["events"], round * 101, "round {round}: {state}");
        assert_eq!(state["robot"]["poses"], round * 100);
        assert_eq!(
            state["cluster"][format!("fed-{round}")]["woke"]["at_ms"],
            round
        );
    }
    // a replay is whole from the start
    let replay = Monitor::replay(Path::new(FIXTURE), loopback()).unwrap();
    assert!(replay.flush(Duration::ZERO));
    monitor.stop();
}

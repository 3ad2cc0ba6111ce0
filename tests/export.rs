//! `marie run --mcap FILE.mcap` and `marie export EVENTS.jsonl --mcap FILE.mcap`: a run as
//! MCAP for Foxglove — read back with the `mcap` crate (the command's own dependency, under
//! its default feature `mcap`): each topic's channel with its Foxglove schema, JSON
//! messages, as many as the events file says; the export of the run's events file is the
//! very file the run wrote; a broken events file is refused naming its line. Built without
//! the feature, both say so.

use crate::common::{marie, text};

#[cfg(feature = "mcap")]
use {
    marie::events::{Event, EventKind},
    std::collections::BTreeMap,
    std::path::Path,
};

/// A message of an MCAP file: its channel's topic, schema name, schema encoding and
/// message encoding; its log time; its data.
#[cfg(feature = "mcap")]
#[derive(Debug, PartialEq)]
struct Read {
    topic: String,
    schema: String,
    schema_encoding: String,
    encoding: String,
    log_time: u64,
    data: Vec<u8>,
}

/// Every message of the MCAP file at `path`, in file order, and its summary's count of
/// messages per topic.
#[cfg(feature = "mcap")]
fn read_mcap(path: &Path) -> (Vec<Read>, BTreeMap<String, u64>) {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("the file has a summary");
    let stats = summary.stats.expect("the summary has statistics");
    let counted: BTreeMap<String, u64> = stats
        .channel_message_counts
        .iter()
        .map(|(id, n)| (summary.channels[id].topic.clone(), *n))
        .collect();
    let messages = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let schema = m
                .channel
                .schema
                .as_ref()
                .expect("every channel has a schema");
            Read {
                topic: m.channel.topic.clone(),
                schema: schema.name.clone(),
                schema_encoding: schema.encoding.clone(),
                encoding: m.channel.message_encoding.clone(),
                log_time: m.log_time,
                data: m.data.into_owned(),
            }
        })
        .collect();
    (messages, counted)
}

/// `a` and `b` are the same JSON, their numbers equal to 1e-12 (relative).
#[cfg(feature = "mcap")]
fn close(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1.0),
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| close(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| close(v, w)))
        }
        // base64 of float32 points: compared as floats too
        (Value::String(x), Value::String(y)) if x != y => match (floats(x), floats(y)) {
            (Some(x), Some(y)) => {
                x.len() == y.len()
                    && x.iter()
                        .zip(&y)
                        .all(|(x, y)| (x - y).abs() <= 1e-6 * x.abs().max(1.0))
            }
            _ => false,
        },
        _ => a == b,
    }
}

/// The little-endian float32s of a base64 text (a point cloud's `data`).
#[cfg(feature = "mcap")]
fn floats(base64: &str) -> Option<Vec<f32>> {
    let bytes = data_encoding::BASE64.decode(base64.as_bytes()).ok()?;
    (bytes.len() % 4 == 0).then(|| {
        bytes
            .chunks(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    })
}

/// The robot's `what` of `event`, if it is a robot's.
#[cfg(feature = "mcap")]
fn robot_what(event: &Event) -> Option<&str> {
    match &event.kind {
        EventKind::Robot { what, .. } => Some(what),
        _ => None,
    }
}

#[cfg(feature = "mcap")]
#[test]
fn a_docking_run_as_mcap_holds_every_event_and_its_scene_in_foxglove_schemas_and_exports_the_same()
{
    let dir = tempfile::tempdir().unwrap();
    let (events, run_mcap, exported) = (
        dir.path().join("run.jsonl"),
        dir.path().join("run.mcap"),
        dir.path().join("exported.mcap"),
    );
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--events",
        events.to_str().unwrap(),
        "--mcap",
        run_mcap.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let lines = std::fs::read_to_string(&events).unwrap();
    let events_read: Vec<Event> = lines
        .lines()
        .map(|l| Event::from_json_line(l).unwrap())
        .collect();

    let (messages, counted) = read_mcap(&run_mcap);
    // the channels: topic, schema, encodings
    let mut channels = BTreeMap::new();
    for m in &messages {
        assert_eq!(m.schema_encoding, "jsonschema", "{}", m.topic);
        assert_eq!(m.encoding, "json", "{}", m.topic);
        let value: serde_json::Value = serde_json::from_slice(&m.data)
            .unwrap_or_else(|e| panic!("{}: {e}: {}", m.topic, text(&m.data)));
        assert!(value.is_object(), "{}", m.topic);
        channels
            .entry(m.topic.as_str())
            .or_insert_with(|| m.schema.as_str());
        assert_eq!(channels[m.topic.as_str()], m.schema, "one schema per topic");
    }
    assert_eq!(
        channels,
        BTreeMap::from([
            ("/cart", "foxglove.SceneUpdate"),
            ("/control", "marie.ControlState"),
            ("/detections", "foxglove.SceneUpdate"),
            ("/echoes", "foxglove.PointCloud"),
            ("/events", "foxglove.Log"),
            ("/path/driven", "foxglove.SceneUpdate"),
            ("/path/planned", "foxglove.SceneUpdate"),
            ("/tf", "foxglove.FrameTransform"),
            ("/world", "foxglove.SceneUpdate"),
        ])
    );

    // the counts, from the events file
    let robot = |what: &str| {
        events_read
            .iter()
            .filter(|e| robot_what(e) == Some(what))
            .count() as u64
    };
    let control = events_read
        .iter()
        .filter(|e| {
            matches!(
                e.kind,
                EventKind::RunStarted { .. }
                    | EventKind::ControlPlan { .. }
                    | EventKind::ActionStarted { .. }
                    | EventKind::ActionEnded { .. }
                    | EventKind::Control { .. }
                    | EventKind::RunEnded { .. }
            )
        })
        .count() as u64;
    let poses = robot("pose");
    assert!(poses > 100, "{poses} poses");
    let expected = BTreeMap::from([
        ("/events".to_string(), events_read.len() as u64),
        ("/control".to_string(), control),
        ("/world".to_string(), robot("world")),
        ("/cart".to_string(), poses),
        ("/tf".to_string(), poses),
        ("/echoes".to_string(), robot("echoes")),
        ("/path/planned".to_string(), robot("planned-path")),
        (
            "/detections".to_string(),
            robot("followed-wall") + robot("dock-found"),
        ),
    ]);
    let mut seen: BTreeMap<String, u64> = BTreeMap::new();
    for m in &messages {
        *seen.entry(m.topic.clone()).or_default() += 1;
    }
    // the driven path goes out at a bounded rate: with the first pose, at most twice a
    // second after, and with the last pose
    let driven = seen.remove("/path/driven").unwrap_or(0);
    let last_pose = events_read
        .iter()
        .rfind(|e| robot_what(e) == Some("pose"))
        .unwrap();
    let seconds = last_pose.at_ms / 1000;
    assert!(
        (2..=2 * seconds + 2).contains(&driven),
        "{driven} driven paths in {seconds} s"
    );
    let mut counted = counted;
    assert_eq!(counted.remove("/path/driven"), Some(driven));
    assert_eq!(seen, expected, "messages per topic");
    assert_eq!(counted, expected, "the summary's statistics");
    let path = messages
        .iter()
        .rfind(|m| m.topic == "/path/driven")
        .unwrap();
    assert_eq!(path.log_time, last_pose.at_ms * 1_000_000);
    let path: serde_json::Value = serde_json::from_slice(&path.data).unwrap();
    assert_eq!(
        path["entities"][0]["lines"][0]["points"]
            .as_array()
            .unwrap()
            .len() as u64,
        poses,
        "the last driven path holds every pose"
    );

    // the log: one line per event, in order, at its time, named by its node
    let logs: Vec<&Read> = messages.iter().filter(|m| m.topic == "/events").collect();
    for (event, log) in events_read.iter().zip(&logs) {
        assert_eq!(log.log_time, event.at_ms * 1_000_000);
        let log: serde_json::Value = serde_json::from_slice(&log.data).unwrap();
        assert_eq!(log["name"], event.node.as_str());
        assert_eq!(log["timestamp"]["sec"], event.at_ms / 1000);
        assert!(!log["message"].as_str().unwrap().is_empty());
        assert!((1..=5).contains(&log["level"].as_u64().unwrap()));
    }
    // the task tree's last state: the run succeeded, nothing runs
    let last = messages.iter().rfind(|m| m.topic == "/control").unwrap();
    let last: serde_json::Value = serde_json::from_slice(&last.data).unwrap();
    assert_eq!(last["outcome"], "succeeded");
    assert_eq!(last["active"], "");
    assert!(last["items"].as_array().unwrap().len() > 1);
    // the cart: a box of the world's cart at each pose
    let cart = messages.iter().find(|m| m.topic == "/cart").unwrap();
    let cart: serde_json::Value = serde_json::from_slice(&cart.data).unwrap();
    assert_eq!(cart["entities"][0]["cubes"][0]["size"]["x"], 1.0);
    assert_eq!(cart["entities"][0]["frame_id"], "world");

    // the echoes: x, y, z of each point, float32, base64
    let (echoes, cloud) = (
        events_read
            .iter()
            .find(|e| robot_what(e) == Some("echoes"))
            .unwrap(),
        messages.iter().find(|m| m.topic == "/echoes").unwrap(),
    );
    let EventKind::Robot { data, .. } = &echoes.kind else {
        unreachable!()
    };
    let cloud: serde_json::Value = serde_json::from_slice(&cloud.data).unwrap();
    assert_eq!(cloud["point_stride"], 12);
    let points: Vec<f32> = data["points"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|p| {
            [
                p[0].as_f64().unwrap() as f32,
                p[1].as_f64().unwrap() as f32,
                0.0,
            ]
        })
        .collect();
    assert!(!points.is_empty());
    assert_eq!(floats(cloud["data"].as_str().unwrap()), Some(points));

    // the events file exported: the very messages the run wrote
    let out = marie(&[
        "export",
        events.to_str().unwrap(),
        "--mcap",
        exported.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let said = text(&out.stdout);
    assert!(
        said.contains(&format!("{} events, 9 channels", events_read.len()))
            && said.contains(&format!("/events {}", events_read.len())),
        "{said}"
    );
    // to a device, which cannot seek: the writer never does
    let out = marie(&["export", events.to_str().unwrap(), "--mcap", "/dev/null"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let (again, mut again_counted) = read_mcap(&exported);
    assert_eq!(again_counted.remove("/path/driven"), Some(driven));
    assert_eq!(again_counted, expected);
    // the same messages — but for the last digit of a float: serde_json reads a float of
    // the events file back to within an ulp of what the run had
    let differs = |a: &Read, b: &Read| {
        (&a.topic, &a.schema, a.log_time) != (&b.topic, &b.schema, b.log_time)
            || !close(
                &serde_json::from_slice(&a.data).unwrap(),
                &serde_json::from_slice(&b.data).unwrap(),
            )
    };
    if let Some((a, b)) = again.iter().zip(&messages).find(|(a, b)| differs(a, b)) {
        panic!(
            "the export differs from the run's own file:\n{} {} {}\n{} {} {}",
            a.topic,
            a.log_time,
            text(&a.data),
            b.topic,
            b.log_time,
            text(&b.data)
        );
    }
    assert_eq!(again.len(), messages.len());
}

#[cfg(feature = "mcap")]
#[test]
fn a_broken_events_file_is_refused_naming_its_file_and_line_and_leaves_no_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let (events, out_path) = (dir.path().join("broken.jsonl"), dir.path().join("x.mcap"));
    std::fs::write(
        &events,
        concat!(
            r#"{"at_ms":0,"node":"n","kind":{"type":"run_started","mission":"m"}}"#,
            "\n\n",
            r#"{"at_ms":20,"node":"n","kind":{"type":"robot","what":"pose","data":{"heading":0.0,"x":1.0,"y":2.0}}}"#,
            "\n",
            r#"{"at_ms":30,"node":"n","kind":{"type":"no_such_kind"}}"#,
            "\n",
        ),
    )
    .unwrap();
    let out = marie(&[
        "export",
        events.to_str().unwrap(),
        "--mcap",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains(&format!("{}:4: not an event", events.display())),
        "{stderr}"
    );
    assert!(!out_path.exists(), "the half-written file is removed");

    // a file that is not there
    let missing = dir.path().join("missing.jsonl");
    let out = marie(&[
        "export",
        missing.to_str().unwrap(),
        "--mcap",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "cannot read the events file {}",
            missing.display()
        )),
        "{stderr}"
    );
}

#[cfg(feature = "mcap")]
#[test]
fn an_mcap_path_that_cannot_be_written_is_refused_before_the_run() {
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--mcap",
        "no/such/dir/run.mcap",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--mcap no/such/dir/run.mcap"));
    assert!(!text(&out.stdout).contains("mission"), "nothing ran");
}

#[cfg(not(feature = "mcap"))]
#[test]
fn built_without_mcap_the_run_and_the_export_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("run.jsonl");
    std::fs::write(&events, "").unwrap();
    let out = marie(&[
        "export",
        events.to_str().unwrap(),
        "--mcap",
        dir.path().join("x.mcap").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("built without MCAP support"));
    let out = marie(&["run", "missions/demo.toml", "--mcap", "run.mcap"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("built without MCAP support"));
}

/// `marie up … --run … --mcap`: a cluster's run as MCAP holds every node's events — the
/// cart's node's robot events draw the scene — as its events file does.
#[cfg(feature = "mcap")]
#[test]
fn a_clusters_run_as_mcap_holds_every_nodes_events_and_the_carts_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (events, run_mcap) = (dir.path().join("up.jsonl"), dir.path().join("up.mcap"));
    let out = marie(&[
        "up",
        "missions/clusters/thesis.toml",
        "--run",
        "missions/docking.toml",
        "--speed",
        "8",
        "--events",
        events.to_str().unwrap(),
        "--mcap",
        run_mcap.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let events_read: Vec<Event> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| Event::from_json_line(l).unwrap())
        .collect();
    let (_, counted) = read_mcap(&run_mcap);
    let nodes: std::collections::BTreeSet<&str> =
        events_read.iter().map(|e| e.node.as_str()).collect();
    assert!(nodes.contains("cart") && nodes.len() > 2, "{nodes:?}");
    // each file follows the bus and the relay on its own: both hold every event
    assert_eq!(counted["/events"], events_read.len() as u64, "{counted:?}");
    let poses = events_read
        .iter()
        .filter(|e| robot_what(e) == Some("pose"))
        .count() as u64;
    assert!(poses > 100, "the cart's node's poses: {poses}");
    assert_eq!(counted["/cart"], poses, "{counted:?}");
    assert_eq!(counted["/tf"], poses, "{counted:?}");
    // each node that runs the world tells it (the scene is drawn again, the same)
    let worlds = events_read
        .iter()
        .filter(|e| robot_what(e) == Some("world"))
        .count() as u64;
    assert!(worlds >= 1);
    assert_eq!(counted["/world"], worlds, "{counted:?}");
    assert!(counted["/echoes"] > 0, "{counted:?}");
}

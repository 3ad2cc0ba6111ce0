//! The simulated robot end to end through the `marie` binary: the thesis' docking-spot mission
//! in the lab world over many seeds, and its clean failures.
//!
//! Each run is its own process (ractor's registry is per process), in virtual time.

mod common;

use common::{marie, report_of, text};

/// Run `mission` with `seed` and assert the world judged it a success, with these actions.
fn succeeds(mission: &str, seed: u64, actions: &[&str]) {
    let seed = seed.to_string();
    let (out, json) = report_of(&["run", mission, "--seed", &seed]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "seed {seed}: {}\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    assert_eq!(json["outcome"], "succeeded", "seed {seed}: {json}");
    assert_eq!(json["inside_goal"], true, "seed {seed}");
    assert_eq!(json["collisions"], 0, "seed {seed}");
    assert_eq!(json["seed"].as_u64(), seed.parse().ok());
    let names: Vec<&str> = json["actions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, actions, "seed {seed}");
}

const DOCKING: &[&str] = &["find-wall", "follow-wall", "plan-parking", "park"];
const CORNER: &[&str] = &["plan", "drive-to-wall", "align", "back-into-corner"];

#[test]
fn docking_succeeds_in_the_lab_for_seeds_1_to_10() {
    (1..=10).for_each(|s| succeeds("missions/docking.toml", s, DOCKING));
}

#[test]
fn docking_succeeds_in_the_lab_for_seeds_11_to_20() {
    (11..=20).for_each(|s| succeeds("missions/docking.toml", s, DOCKING));
}

#[test]
fn docking_succeeds_in_the_corridor_for_seeds_1_to_10() {
    (1..=10).for_each(|s| succeeds("missions/docking-corridor.toml", s, DOCKING));
}

#[test]
fn docking_succeeds_in_the_corridor_for_seeds_11_to_20() {
    (11..=20).for_each(|s| succeeds("missions/docking-corridor.toml", s, DOCKING));
}

const DOCKING_LSHAPE: &[&str] = &[
    "plan-approach",
    "approach",
    "find-wall",
    "follow-wall",
    "plan-parking",
    "park",
];

#[test]
fn docking_succeeds_in_the_lshape_room_for_seeds_1_to_10() {
    (1..=10).for_each(|s| succeeds("missions/docking-lshape.toml", s, DOCKING_LSHAPE));
}

#[test]
fn docking_succeeds_in_the_lshape_room_for_seeds_11_to_20() {
    (11..=20).for_each(|s| succeeds("missions/docking-lshape.toml", s, DOCKING_LSHAPE));
}

#[test]
fn the_corner_mission_backs_into_the_corner_for_seeds_1_to_10() {
    (1..=10).for_each(|s| succeeds("missions/corner.toml", s, CORNER));
}

#[test]
fn the_corner_mission_backs_into_the_corner_for_seeds_11_to_20() {
    (11..=20).for_each(|s| succeeds("missions/corner.toml", s, CORNER));
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let (_, a) = report_of(&["run", "missions/docking.toml", "--seed", "3"]);
    let (_, b) = report_of(&["run", "missions/docking.toml", "--seed", "3"]);
    assert_eq!(a["final_pose"], b["final_pose"]);
    assert_eq!(a["duration_ms"], b["duration_ms"]);
    let (_, c) = report_of(&["run", "missions/docking.toml", "--seed", "4"]);
    assert_ne!(
        a["final_pose"], c["final_pose"],
        "another seed, other noise"
    );
}

#[test]
fn a_docking_spot_larger_than_the_real_one_is_missed_and_the_mission_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string("missions/docking.toml")
        .unwrap()
        .replace("breadth = 2.8", "breadth = 3.6")
        .replace(
            "world = \"worlds/lab.toml\"",
            &format!(
                "world = {:?}",
                std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/worlds/lab.toml")
            ),
        );
    let path = dir.path().join("wrong-breadth.toml");
    std::fs::write(&path, src).unwrap();
    let (out, json) = report_of(&["run", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert_eq!(json["outcome"], "failed");
    let reason = json["reason"].as_str().unwrap();
    assert!(reason.contains("`docking-detector`"), "{reason}");
    assert!(text(&out.stdout).contains("mission FAILED (full stop)"));
    assert_eq!(
        json["actions"].as_array().unwrap().len(),
        2,
        "parking never started"
    );
}

#[test]
fn a_world_without_a_dock_ends_in_a_clean_full_stop() {
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--world",
        "missions/worlds/nodock.toml",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert_eq!(json["outcome"], "failed");
    assert_eq!(json["collisions"], 0);
    // the follower notices it is stuck in the room's corner long before the action's 120 s
    let reason = json["reason"].as_str().unwrap();
    assert!(
        reason.contains("wall-follower") && reason.contains("no progress along the wall"),
        "{json}"
    );
    assert!(json["duration_ms"].as_u64().unwrap() < 100_000, "{json}");
}

#[test]
fn the_picture_shows_walls_path_echoes_dock_plan_and_footprint() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("docking.svg");
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let svg = std::fs::read_to_string(&svg).unwrap();
    assert!(svg.starts_with("<svg"));
    for title in [
        "goal area",
        "planned path",
        "detected dock",
        "driven path",
        "final footprint",
        "followed wall",
    ] {
        assert!(
            svg.contains(&format!("<title>{title}</title>")),
            "no {title}"
        );
    }
    assert!(svg.matches("<circle").count() > 100, "sonar echoes drawn");
}

//! Worlds and the simulated robot: loading and checking world files, the cart's kinematics,
//! emergency stop, collisions, sonar, determinism and judging.

use marie_missions::geom::{Point, Pose};
use marie_missions::sim::{Rng, Simulation};
use marie_missions::world::{builtin_names, worlds_dir, Beam, SonarMount, World};
use std::f64::consts::PI;
use std::path::Path;

/// A world from text, which must be valid.
fn world(src: &str) -> World {
    match World::parse(src, Some(Path::new("test.toml"))) {
        Ok(w) => w,
        Err(e) => panic!("test world does not load:\n{e}"),
    }
}

/// Diagnostics of a bad world, one per line.
fn errors(src: &str) -> String {
    match World::parse(src, Some(Path::new("bad.toml"))) {
        Ok(_) => panic!("expected diagnostics"),
        Err(e) => e.to_string(),
    }
}

/// A large empty room (40 m × 40 m around the origin) with the cart at the origin facing +x.
fn open_room() -> World {
    world(
        r#"
[world]
name = "open"
[[wall]]
points = [[-20, -20], [20, -20], [20, 20], [-20, 20], [-20, -20]]
[cart]
start = { x = 0, y = 0, heading_deg = 0 }
speed_time_constant = 0
"#,
    )
}

/// A world with one straight wall `x = wall_x` (from y = -10 to 10), a cart facing +x and one
/// sonar (1 m ahead of the rear axle, at the world's origin) looking along `angle_deg` with
/// `beam`.
fn sonar_world(wall_x: f64, angle_deg: f64, beam: &str, sigma: f64) -> World {
    world(&sonar_world_src(wall_x, angle_deg, beam, sigma))
}

/// The text of [`sonar_world`], its `[sim]` table last.
fn sonar_world_src(wall_x: f64, angle_deg: f64, beam: &str, sigma: f64) -> String {
    format!(
        r#"
[world]
name = "sonar"
[[wall]]
points = [[{wall_x}, -10], [{wall_x}, 10]]
[cart]
start = {{ x = -1, y = 0, heading_deg = 0 }}
[[sonar]]
x = 1
y = 0
angle_deg = {angle_deg}
beam = "{beam}"
range = 8
[sim]
sonar_sigma = {sigma}
sonar_dropout = 0
"#
    )
}

#[test]
fn every_shipped_world_loads_and_its_start_pose_is_clear() {
    let mut files: Vec<_> = std::fs::read_dir(worlds_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 5, "{files:?}");
    for path in &files {
        let w = World::load(path).unwrap_or_else(|e| panic!("{}:\n{e}", path.display()));
        assert!(!w.footprint_collides(&w.start), "{}", w.name);
        assert!(!w.description.is_empty(), "{}", w.name);
        let stem = path.file_stem().unwrap().to_str().unwrap();
        assert_eq!(w.name, stem);
        assert!(builtin_names().contains(&stem), "{stem} is not built in");
        assert_eq!(World::builtin(stem).unwrap(), w);
        // the cart can look around and drive a little without trouble
        let mut sim = Simulation::new(&w, 1);
        assert_eq!(sim.sonar_scan().len(), w.sonars.len());
        sim.command(0.3, 0.0);
        sim.step(0.5);
        assert_eq!(sim.collisions(), 0, "{}", w.name);
    }
    assert_eq!(files.len(), builtin_names().len());
    let unknown = World::builtin("moon").unwrap_err().to_string();
    assert!(
        unknown.contains("unknown world `moon` (expected one of: lab,"),
        "{unknown}"
    );
}

#[test]
fn the_lab_dock_is_80_by_280_cm_and_every_dock_holds_the_cart() {
    let lab = World::builtin("lab").unwrap();
    let dock = lab.dock.unwrap();
    assert!((dock.breadth - 2.8).abs() < 1e-12 && (dock.depth - 0.8).abs() < 1e-12);
    assert!((dock.opening().length() - 2.8).abs() < 1e-12);
    // the thesis: the cart starts at the far right of the wall
    let (lo, hi) = lab.bounds().unwrap();
    assert!(lab.start.x > lo.x + 0.8 * (hi.x - lo.x));
    for name in ["lab", "corridor", "lshape"] {
        let w = World::builtin(name).unwrap();
        let dock = w.dock.unwrap();
        let goal = w.goal.unwrap();
        assert_eq!(dock.rect().center, goal.area.center, "{name}");
        // the cart centred in the recess, along it: clear of the walls, with margin
        let center = dock.rect().pose();
        let parked = center.compose(Pose::new(-w.cart.center_offset(), 0.0, 0.0));
        assert!(!w.footprint_collides(&parked), "{name}");
        for shift in [-0.09, 0.09] {
            let p = parked.compose(Pose::new(0.0, shift, 0.0));
            assert!(!w.footprint_collides(&p), "{name}: no 9 cm margin");
        }
        assert!(w.judge(parked, 0).success, "{name}");
    }
    assert!(World::builtin("nodock").unwrap().dock.is_none());
}

#[test]
fn a_bad_world_file_gets_every_problem_at_its_line_and_column() {
    let src = r#"[world]
name = "bad"
colour = "red"

[[wall]]
points = [[0, 0]]

[[wall]]
points = [[0, 0], [1, nan]]

[cart]
start = { x = 1, y = 1 }
width = -0.6
length = "long"
wheels = 4

[[sonar]]
x = 0.85
y = 0
angle_deg = 0
beam = "medium"

[goal]
center = { x = 5, y = 0.4 }
length = 2.8
width = 0.8
heading_tolerance_deg = 200

[lidar]
"#;
    let text = errors(src);
    let expected = [
        "bad.toml:3:1: unknown key `colour` in [world] (expected one of: name, description)",
        "bad.toml:6:10: [[wall]] #1 needs at least 2 points, found 1",
        "bad.toml:9:23: `points` must be a finite number",
        "bad.toml:13:9: `width` must be in (0, 10], found -0.6",
        "bad.toml:14:10: expected a number for `length`, found string",
        "bad.toml:15:1: unknown key `wheels` in [cart] (expected one of: start, length, width, \
         wheelbase, rear_overhang, max_speed, max_steer_deg, max_steer_rate_deg, \
         speed_time_constant)",
        "bad.toml:21:8: unknown beam `medium` (expected \"narrow\" or \"wide\")",
        "bad.toml:27:25: `heading_tolerance_deg` must be in (0, 180], found 200",
        "bad.toml:29:2: unknown key `lidar` in the world file (expected one of: world, wall, \
         obstacle, cart, sonar, goal, dock, sim)",
    ];
    assert_eq!(text.lines().collect::<Vec<_>>(), expected, "\n{text}");
}

#[test]
fn missing_parts_and_syntax_errors_are_located() {
    let text = errors("[world]\nname = \"x\"\n[[wall]]\npoints = [[0, 0], [0, 0.0005]]\n");
    assert_eq!(
        text.lines().collect::<Vec<_>>(),
        [
            "bad.toml:1:1: missing table `[cart]` (expected at least \
             `start = { x = .., y = .., heading_deg = .. }`)",
            "bad.toml:4:19: this point repeats the previous one (edges must be at least 1 mm long)",
        ]
    );
    let text = errors("[world]\nname = \"x\"\n[cart]\nstart = { x = 1 }\n[[wall]]\npoints = 3\n");
    assert!(
        text.contains("bad.toml:4:9: missing `y` in `start`"),
        "{text}"
    );
    assert!(
        text.contains("bad.toml:6:10: expected an array of points `[[x, y], ...]` for `points`, found integer"),
        "{text}"
    );
    let text = errors("[world]\nname = \"x\"\n[cart\n");
    assert!(text.starts_with("bad.toml:3:"), "{text}");
    assert!(text.contains("syntax error"), "{text}");
    let text = World::load("/nonexistent/w.toml").unwrap_err().to_string();
    assert!(
        text.starts_with("/nonexistent/w.toml:1:1: cannot read world file"),
        "{text}"
    );
}

#[test]
fn start_pose_in_a_wall_and_goal_outside_the_walls_are_rejected() {
    let text = errors(
        r#"[world]
name = "x"
[[wall]]
points = [[0, 0], [10, 0], [10, 5]]
[cart]
start = { x = 2, y = 0.1, heading_deg = 0 }
[goal]
center = { x = 12, y = 1 }
length = 2
width = 1
"#,
    );
    assert_eq!(
        text.lines().collect::<Vec<_>>(),
        [
            "bad.toml:6:9: the cart's footprint at its start pose touches a wall or an obstacle",
            "bad.toml:7:1: the goal area reaches outside the world's walls (x 0.000..10.000, y 0.000..5.000)",
        ]
    );
    // inside an obstacle counts as touching it
    let text = errors(
        r#"[world]
name = "x"
[[wall]]
points = [[-5, -5], [5, -5]]
[[obstacle]]
points = [[-3, -3], [3, -3], [3, 3], [-3, 3]]
[cart]
start = { x = 0, y = 0 }
"#,
    );
    assert!(
        text.contains("bad.toml:8:9: the cart's footprint"),
        "{text}"
    );
}

#[test]
fn no_input_makes_the_loader_panic() {
    let lab = std::fs::read_to_string(worlds_dir().join("lab.toml")).unwrap();
    let bytes = lab.as_bytes();
    let mut rng = Rng::new(5);
    let junk = [
        "", "[", "]", "=", "\"", "nan", "-inf", "1e999", "[[", "{", "0x10", "ç", "\n", "[[0,0]]",
        "true",
    ];
    for _ in 0..2000 {
        let mut text = bytes.to_vec();
        for _ in 0..3 {
            let at = (rng.next_u64() % (text.len() as u64 + 1)) as usize;
            let cut = (rng.next_u64() % 8) as usize;
            let end = (at + cut).min(text.len());
            let j = junk[(rng.next_u64() % junk.len() as u64) as usize];
            text.splice(at..end, j.bytes());
        }
        if let Ok(src) = String::from_utf8(text) {
            if let Ok(w) = World::parse(&src, None) {
                let mut sim = Simulation::new(&w, 3);
                sim.command(0.5, 0.2);
                sim.step(0.1);
                let _ = sim.sonar_scan();
            }
        }
    }
}

#[test]
fn a_hand_made_world_never_makes_the_simulation_panic() {
    let mut w = open_room();
    w.walls = vec![
        vec![],
        vec![Point::new(f64::NAN, 0.0), Point::new(1.0, 1.0)],
    ];
    w.obstacles = vec![vec![Point::new(0.0, 0.0)]];
    w.cart.wheelbase = f64::NAN;
    w.start = Pose {
        x: f64::INFINITY,
        y: 0.0,
        theta: 0.0,
    };
    w.sonars[0].range = -1.0;
    let mut sim = Simulation::new(&w, 0);
    sim.command(f64::NAN, f64::INFINITY);
    sim.step(f64::NAN);
    sim.step(-1.0);
    sim.step(0.1);
    assert!(sim.sonar_scan().iter().all(|r| r.range.is_none()));
    assert!(!sim.judge().success);
}

#[test]
fn driving_straight_goes_straight() {
    let mut w = open_room();
    // perfect odometry, to compare it with the truth exactly
    w.sim.odometry_distance_sigma = 0.0;
    w.sim.odometry_heading_sigma = 0.0;
    w.sim.odometry_heading_walk = 0.0;
    let mut sim = Simulation::new(&w, 0);
    sim.command(0.5, 0.0);
    for _ in 0..500 {
        sim.step(0.02);
    }
    let p = sim.pose();
    assert!((p.x - 5.0).abs() < 1e-9, "{p:?}"); // no lag in this world: 0.5 m/s × 10 s
    assert!(p.y.abs() < 1e-12 && p.theta.abs() < 1e-12, "{p:?}");
    assert_eq!(sim.odometry(), p);
    assert!((sim.time() - 10.0).abs() < 1e-9);
    // backwards, at an angle
    let mut w = open_room();
    w.start = Pose::new(0.0, 0.0, PI / 4.0);
    let mut sim = Simulation::new(&w, 0);
    sim.command(-0.2, 0.0);
    sim.step(5.0);
    let p = sim.pose();
    assert!((p.x + 0.5f64.sqrt()).abs() < 1e-9 && (p.y + 0.5f64.sqrt()).abs() < 1e-9);
    assert!((p.theta - PI / 4.0).abs() < 1e-12);
    // the trace samples the path
    assert!(sim.trace().len() > 15 && sim.trace()[0].pose == w.start);
}

#[test]
fn constant_steering_drives_a_circle_of_radius_wheelbase_over_tan_steer() {
    let w = open_room();
    let l = w.cart.wheelbase;
    for steer in [0.3, -0.5, w.cart.max_steer] {
        let mut sim = Simulation::new(&w, 0);
        sim.command(0.5, steer);
        sim.step(1.0); // the steering settles (rate limit) on the way
        assert!((sim.steer() - steer).abs() < 1e-12);
        let radius = l / steer.tan();
        let p = sim.pose();
        // the circle's centre is `radius` to the left of the rear axle
        let center = Point::new(p.x - radius * p.theta.sin(), p.y + radius * p.theta.cos());
        let mut turned = 0.0;
        let mut last = p.theta;
        for _ in 0..3000 {
            sim.step(0.02);
            let q = sim.pose();
            let r = (q.point() - center).norm();
            assert!((r - radius.abs()).abs() < 1e-6, "radius {r} vs {radius}");
            // headings stay wrapped in (-π, π]
            assert!(q.theta > -PI && q.theta <= PI);
            turned += marie_missions::geom::wrap_angle(q.theta - last);
            last = q.theta;
        }
        // 0.5 m/s for 60 s along a circle of that radius
        let expected = 0.5 * 60.0 / radius;
        assert!((turned - expected).abs() < 1e-6, "{turned} vs {expected}");
        assert!(turned.abs() > 4.0 * PI, "the heading wrapped several times");
    }
    // steering beyond the limit is clamped
    let mut sim = Simulation::new(&w, 0);
    sim.command(9.0, 2.0);
    sim.step(2.0);
    assert_eq!(sim.commanded(), (w.cart.max_speed, w.cart.max_steer));
    assert!((sim.steer() - w.cart.max_steer).abs() < 1e-12);
    assert!((w.cart.min_turn_radius() - 1.0).abs() < 0.01);
}

#[test]
fn the_speed_follows_with_a_lag() {
    let w = World::builtin("lab").unwrap();
    let tau = w.cart.speed_time_constant;
    let mut sim = Simulation::new(&w, 0);
    sim.command(0.5, 0.0);
    sim.step(tau);
    assert!((sim.speed() - 0.5 * (1.0 - (-1.0f64).exp())).abs() < 1e-9);
    sim.step(10.0 * tau);
    assert!((sim.speed() - 0.5).abs() < 1e-4);
}

#[test]
fn the_emergency_stop_holds_the_cart() {
    let w = World::builtin("lab").unwrap();
    let mut sim = Simulation::new(&w, 0);
    sim.command(0.5, 0.1);
    sim.step(1.0);
    assert!(sim.speed() > 0.4);
    sim.emergency_stop(true);
    assert!(sim.is_emergency_stopped());
    assert_eq!(sim.speed(), 0.0);
    let held = sim.pose();
    let steer = sim.steer();
    for cmd in [(0.5, 0.3), (-0.5, -0.3), (0.2, 0.0)] {
        sim.command(cmd.0, cmd.1);
        sim.step(2.0);
        assert_eq!(sim.pose(), held);
        assert_eq!(sim.speed(), 0.0);
        assert_eq!(sim.steer(), steer);
    }
    sim.emergency_stop(false);
    sim.step(1.0);
    assert!(sim.pose() != held && sim.speed() > 0.1);
}

#[test]
fn driving_into_a_wall_counts_one_collision_and_stops_the_cart() {
    // the lab, facing the room's east wall (x = 14) 1.5 m away
    let mut w = World::builtin("lab").unwrap();
    w.start = Pose::new(12.0, 3.0, 0.0);
    let mut sim = Simulation::new(&w, 0);
    sim.command(0.5, 0.0);
    for _ in 0..1000 {
        sim.step(0.02);
    }
    assert_eq!(sim.collisions(), 1);
    assert!(sim.is_collided());
    assert_eq!(sim.speed(), 0.0);
    let stopped = sim.pose();
    let front = stopped.x + w.cart.front();
    assert!(front < 14.0 && front > 14.0 - 0.005, "front at {front}");
    assert!(!w.footprint_collides(&stopped));
    assert_eq!(sim.collision_events().len(), 1);
    assert!((sim.collision_events()[0].speed - 0.5).abs() < 1e-3);
    assert!(!sim.judge().success);
    // pushing on: still one collision, not a millimetre further
    sim.command(0.3, 0.2);
    sim.step(2.0);
    assert_eq!((sim.collisions(), sim.pose()), (1, stopped));
    // backing away releases the latch
    sim.command(-0.3, 0.0);
    sim.step(1.0);
    assert!(!sim.is_collided() && sim.pose().x < stopped.x - 0.2);
    // and driving in again is a second collision
    sim.command(0.3, 0.0);
    sim.step(5.0);
    assert_eq!(sim.collisions(), 2);
    // an explicit reset releases it too
    sim.clear_collision();
    assert!(!sim.is_collided());
    sim.command(0.3, 0.0);
    sim.step(0.5);
    assert_eq!(sim.collisions(), 3);
}

#[test]
fn a_restart_puts_the_cart_back_at_rest_at_the_start_with_nothing_counted_while_time_goes_on() {
    let mut w = World::builtin("lab").unwrap();
    w.start = Pose::new(12.0, 3.0, 0.0);
    let mut sim = Simulation::new(&w, 0);
    sim.command(0.5, 0.1);
    for _ in 0..1000 {
        sim.step(0.02);
    }
    assert!(sim.collisions() > 0 && sim.is_collided());
    sim.emergency_stop(true);
    let then = sim.time();
    sim.restart();
    assert_eq!((sim.pose(), sim.odometry()), (w.start, w.start));
    assert_eq!((sim.collisions(), sim.is_collided()), (0, false));
    assert!(sim.collision_events().is_empty());
    assert_eq!(
        (sim.speed(), sim.steer(), sim.commanded()),
        (0.0, 0.0, (0.0, 0.0))
    );
    assert!(!sim.is_emergency_stopped());
    assert_eq!(sim.time(), then, "time goes on from where it was");
    assert_eq!(sim.trace().len(), 1);
    assert_eq!((sim.trace()[0].time, sim.trace()[0].pose), (then, w.start));
    // at rest until commanded, then it drives from the start as it did the first time
    sim.step(1.0);
    assert_eq!(sim.pose(), w.start);
    sim.command(0.5, 0.0);
    sim.step(1.0);
    assert!(sim.pose().x > w.start.x + 0.2 && sim.collisions() == 0);
}

#[test]
fn a_reading_carries_the_cone_of_its_beam_as_the_world_sets_it() {
    // the default data sheet: narrow 8 degrees, wide 25 (half angles)
    for (beam, deg) in [("narrow", 8.0), ("wide", 25.0)] {
        let w = sonar_world(2.0, 0.0, beam, 0.0);
        let r = Simulation::new(&w, 1).sonar_read(0).unwrap();
        assert!(
            (r.half_angle - f64::to_radians(deg)).abs() < 1e-12,
            "{beam}"
        );
    }
    // a world with other sensors: the reading says so (the clearance guard places its echo
    // on that cone, not on an assumed one)
    let src = format!(
        "{}narrow_half_angle_deg = 12\nwide_half_angle_deg = 30\n",
        sonar_world_src(2.0, 0.0, "narrow", 0.0)
    );
    let r = Simulation::new(&world(&src), 1).sonar_read(0).unwrap();
    assert!((r.half_angle - 12f64.to_radians()).abs() < 1e-12);
}

#[test]
fn a_narrow_sonar_facing_a_wall_reads_its_distance() {
    for d in [0.5, 1.7, 3.9] {
        let w = sonar_world(d, 0.0, "narrow", 0.01);
        let mut sim = Simulation::new(&w, 11);
        let readings: Vec<_> = (0..200).map(|_| sim.sonar_read(0).unwrap()).collect();
        let mut sum = 0.0;
        for r in &readings {
            let range = r.range.expect("a facing wall echoes");
            assert!((range - d).abs() < 0.06, "{range} vs {d}");
            let hit = r.hit.unwrap();
            assert!((hit - Point::new(d, 0.0)).norm() < 1e-9);
            assert_eq!(r.beam, Beam::Narrow);
            sum += range;
        }
        let mean = sum / readings.len() as f64;
        assert!((mean - d).abs() < 0.004, "mean {mean} vs {d}");
        // noise-free: exact
        let w = sonar_world(d, 0.0, "narrow", 0.0);
        let r = Simulation::new(&w, 11).sonar_read(0).unwrap();
        assert!((r.range.unwrap() - d).abs() < 1e-9);
        assert!((r.axis_point().unwrap() - Point::new(d, 0.0)).norm() < 1e-9);
    }
    // beyond the range: no echo
    let w = sonar_world(8.5, 0.0, "narrow", 0.0);
    let r = Simulation::new(&w, 0).sonar_read(0).unwrap();
    assert_eq!((r.range, r.hit, r.range_or_max()), (None, None, 8.0));
}

#[test]
fn a_wall_at_80_degrees_incidence_is_lost_by_a_narrow_beam_but_not_by_a_wide_one() {
    // the wall x = 1 seen along 80° from +x: its normal is the x axis, the incidence 80°
    let w = sonar_world(1.0, 80.0, "narrow", 0.0);
    let r = Simulation::new(&w, 0).sonar_read(0).unwrap();
    assert_eq!(r.range, None, "{r:?}");
    // the same wall at 50° incidence echoes
    let w = sonar_world(1.0, 50.0, "narrow", 0.0);
    let r = Simulation::new(&w, 0).sonar_read(0).unwrap();
    // the nearest ray is the cone's edge nearest the normal, 50° - 8°
    let nearest = 1.0 / 42f64.to_radians().cos();
    assert!((r.range.unwrap() - nearest).abs() < 1e-9, "{r:?}");
    // a wide beam at 80°: its rays up to 25° nearer the normal still echo (at ≤ 65°)
    let w = sonar_world(1.0, 80.0, "wide", 0.0);
    let r = Simulation::new(&w, 0).sonar_read(0).unwrap();
    let range = r.range.expect("the wide cone's inner rays echo");
    assert!(
        (range - 1.0 / 55f64.to_radians().cos()).abs() < 1e-9,
        "{range}"
    );
}

#[test]
fn a_wide_beam_sees_the_nearest_object_in_its_cone() {
    // wall straight ahead at 2.5 m; a post about 20° off the axis at 1 m
    let src = |beam: &str| {
        format!(
            r#"
[world]
name = "post"
[[wall]]
points = [[2.5, -10], [2.5, 10]]
[[obstacle]]
points = [[0.9, 0.25], [1.1, 0.25], [1.1, 0.45], [0.9, 0.45]]
[cart]
start = {{ x = -1, y = 0, heading_deg = 0 }}
[[sonar]]
x = 1
y = 0
angle_deg = 0
beam = "{beam}"
[sim]
sonar_sigma = 0
sonar_dropout = 0
"#
        )
    };
    let wide = world(&src("wide"));
    let r = Simulation::new(&wide, 0).sonar_read(0).unwrap();
    let range = r.range.unwrap();
    // the 16.7° ray meets the post's near face
    let expected = 0.9 / (50f64 / 3.0).to_radians().cos();
    assert!(
        (range - expected).abs() < 1e-9,
        "wide: the post, got {range}"
    );
    assert!((r.hit.unwrap().x - 0.9).abs() < 1e-9);
    let narrow = world(&src("narrow"));
    let r = Simulation::new(&narrow, 0).sonar_read(0).unwrap();
    assert!(
        (r.range.unwrap() - 2.5).abs() < 1e-9,
        "narrow: the wall, {r:?}"
    );
}

#[test]
fn the_same_seed_gives_the_same_readings_and_another_seed_other_noise() {
    let w = World::builtin("lab").unwrap();
    let scans = |seed: u64| {
        let mut sim = Simulation::new(&w, seed);
        (0..20).flat_map(|_| sim.sonar_scan()).collect::<Vec<_>>()
    };
    let a = scans(7);
    assert_eq!(a, scans(7));
    let b = scans(8);
    assert_ne!(a, b);
    // the noise differs, the geometry does not
    let differ = a
        .iter()
        .zip(&b)
        .filter(|(x, y)| x.range.is_some() && y.range.is_some() && x.range != y.range)
        .count();
    assert!(differ > 20, "{differ}");
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.mount, y.mount);
        if let (Some(p), Some(q)) = (x.hit, y.hit) {
            assert_eq!(p, q);
        }
    }
}

/// The worlds' default odometry drifts as a real cart's: over 10 m driven straight, 1σ of
/// about 1 % of the distance and 0.5° of heading per metre (plus a little slip).
#[test]
fn the_default_odometry_drifts_as_a_real_carts() {
    let w = open_room();
    assert_eq!(w.sim.odometry_distance_sigma, 0.01);
    assert!((w.sim.odometry_heading_sigma - 0.5f64.to_radians()).abs() < 1e-15);
    let (mut along, mut heading) = (Vec::new(), Vec::new());
    for seed in 1..=200 {
        let mut sim = Simulation::new(&w, seed);
        sim.command(0.5, 0.0);
        sim.step(20.0);
        let (o, p) = (sim.odometry(), sim.pose());
        assert!((p.x - 10.0).abs() < 1e-6, "{p:?}");
        along.push(o.x.hypot(o.y) - 10.0);
        heading.push(o.theta.to_degrees());
    }
    let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    // 1 % of 10 m; 0.5°/m × 10 m with a random walk of 0.1°·√10 on top: ≈ 5.0°
    assert!((0.07..0.13).contains(&sd(&along)), "{}", sd(&along));
    assert!((4.0..6.5).contains(&sd(&heading)), "{}", sd(&heading));
}

#[test]
fn the_same_seed_and_commands_give_an_identical_run() {
    let mut w = World::builtin("corner").unwrap();
    w.sim.odometry_distance_sigma = 0.02;
    w.sim.odometry_heading_sigma = 0.01;
    let run = |seed: u64| {
        let mut sim = Simulation::new(&w, seed);
        let mut scans = Vec::new();
        for i in 0..400 {
            let steer = ((i / 50) as f64 - 4.0) * 0.1;
            sim.command(if i < 300 { 0.4 } else { -0.3 }, steer);
            sim.step(0.05);
            if i % 10 == 0 {
                scans.push(sim.sonar_scan());
            }
        }
        (sim.trace().to_vec(), sim.odometry(), sim.pose(), scans)
    };
    let (t1, o1, p1, s1) = run(99);
    let (t2, o2, p2, s2) = run(99);
    assert_eq!((&t1, o1, p1, &s1), (&t2, o2, p2, &s2));
    assert!(t1.len() > 50);
    let (t3, o3, p3, _) = run(100);
    assert_eq!(
        (t1, p1),
        (t3, p3),
        "the true path does not depend on the seed"
    );
    assert_ne!(o1, o3, "the odometry noise does");
    assert!((o1.point() - p1.point()).norm() > 0.0);
}

#[test]
fn judging_against_the_lab_dock() {
    let w = World::builtin("lab").unwrap();
    let goal = w.goal.unwrap();
    // rear axle so the footprint is centred in the recess, heading along the wall
    let centred = |theta: f64| {
        let c = goal.area.center;
        let back = w.cart.center_offset();
        Pose::new(c.x - back * theta.cos(), c.y - back * theta.sin(), theta)
    };
    let inside = w.judge(centred(0.0), 0);
    assert!(inside.success && inside.inside_goal, "{inside}");
    assert!(inside.heading_error_deg.unwrap() < 1e-9);
    // either way round, within the tolerance
    assert!(w.judge(centred(PI), 0).success);
    assert!(w.judge(centred(PI - 5f64.to_radians()), 0).success);
    // sticking out of the recess (0.3 m towards the room)
    let out = {
        let p = centred(0.0);
        w.judge(Pose::new(p.x, p.y + 0.3, p.theta), 0)
    };
    assert!(!out.inside_goal && !out.success, "{out}");
    // too far along it: the front pokes past the recess' end
    let p = centred(0.0);
    assert!(!w.judge(Pose::new(p.x + 1.0, p.y, 0.0), 0).success);
    // heading off by 20°: even if the footprint still fitted, the heading fails
    let skew = w.judge(centred(20f64.to_radians()), 0);
    assert!(!skew.success);
    assert!((skew.heading_error_deg.unwrap() - 20.0).abs() < 1e-9);
    // a collision fails the run
    let bumped = w.judge(centred(0.0), 1);
    assert!(bumped.inside_goal && !bumped.success && bumped.collisions == 1);
    assert!(bumped
        .to_string()
        .starts_with("failure: inside the goal area"));
    // no goal: never a success
    let nodock = World::builtin("nodock").unwrap();
    let j = nodock.judge(nodock.start, 0);
    assert!(!j.success && j.heading_error_deg.is_none());
}

#[test]
fn the_corner_goal_wants_the_cart_backed_in_facing_out() {
    let w = World::builtin("corner").unwrap();
    // rear 0.3 m from the west wall, side 0.3 m from the south wall, facing east
    let parked = Pose::new(0.3 + w.cart.rear_overhang, 0.6, 0.0);
    assert!(!w.footprint_collides(&parked));
    assert!(w.judge(parked, 0).success);
    // facing the corner instead: the goal is not either-way
    let c = w.cart.footprint_center(&parked);
    let turned = Pose::new(c.x + w.cart.center_offset(), c.y, PI);
    assert!(w.judge(turned, 0).inside_goal);
    assert!(!w.judge(turned, 0).success);
}

#[test]
fn sonar_mounts_of_the_default_ring_sit_on_the_footprint() {
    let w = World::builtin("lab").unwrap();
    assert_eq!(w.sonars, SonarMount::default_ring(&w.cart));
    let beams = |b: Beam| w.sonars.iter().filter(|s| s.beam == b).count();
    assert!(beams(Beam::Narrow) >= 4 && beams(Beam::Wide) >= 2);
    let (h, f, r) = (w.cart.width / 2.0, w.cart.front(), -w.cart.rear_overhang);
    for s in &w.sonars {
        assert!(
            s.x >= r - 1e-12 && s.x <= f + 1e-12 && s.y.abs() <= h + 1e-12,
            "{s:?}"
        );
    }
}

#[test]
fn numbers_out_of_a_worlds_range_are_refused_at_their_position() {
    let src = "[world]\nname = \"w\"\n[[wall]]\npoints = [[0, 0], [4e9, 0]]\n\
               [cart]\nstart = { x = 1, y = 1e300 }\nlength = 1e6\nmax_speed = 500\n";
    let err = World::parse(src, None).unwrap_err().to_string();
    for want in [
        "<world>:4:20: coordinates in `points` must be in [-1000, 1000] metres, found 4e9",
        "<world>:6:22: `y` must be in [-1000, 1000], found 1e300",
        "<world>:7:10: `length` must be in (0, 10], found 1e6",
        "<world>:8:13: `max_speed` must be in (0, 5], found 500",
    ] {
        assert!(err.contains(want), "`{want}` not in:\n{err}");
    }
}

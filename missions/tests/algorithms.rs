//! The algorithms of `marie_missions::algo` on synthetic scenes: seeded noise, outliers and a
//! small ray-casting sonar written here, the bicycle model integrated with Euler steps.

use marie_missions::algo::avoid::{avoid, AvoidDecision, AvoidMode, AvoidParams, SonarReading};
use marie_missions::algo::dock::{detect_dock, detect_dock_in_segments, DockParams};
use marie_missions::algo::follow::{follow_command, is_aligned, FollowMode, FollowParams};
use marie_missions::algo::planner::{
    path_clearance, plan, point_clearance, Bounds, NoPathReason, Path, PlanError, PlannerParams,
};
use marie_missions::algo::pursuit::{PurePursuit, PursuitParams, PursuitStatus};
use marie_missions::algo::segments::{extract_segments, FittedSegment, SegmentParams};
use marie_missions::algo::wall::{sense_wall, Side, WallParams};
use marie_missions::algo::{bicycle_step, Command, DEFAULT_WHEELBASE};
use marie_missions::geom::{wrap_angle, Point, Pose, Segment, Vector};
use std::f64::consts::{FRAC_PI_2, PI};

// ---------------------------------------------------------------------------------------------
// Test helpers: a seeded RNG, noisy walls and a ray-casting sonar.

struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn gauss(&mut self, sigma: f64) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Segment {
    Segment::new(Point::new(ax, ay), Point::new(bx, by))
}

/// Points along `from → to` every `step`, with perpendicular noise `sigma`.
fn noisy_wall(from: Point, to: Point, step: f64, sigma: f64, rng: &mut Rng) -> Vec<Point> {
    let d = to - from;
    let n = (d.norm() / step).round().max(1.0) as usize;
    let normal = Vector::new(-d.y, d.x) / d.norm();
    (0..=n)
        .map(|i| from + d * (i as f64 / n as f64) + normal * rng.gauss(sigma))
        .collect()
}

/// Distance along the ray `origin + t·dir` to `s`, if it hits.
fn ray_hit(origin: Point, dir: Vector, s: &Segment) -> Option<f64> {
    let e = s.b - s.a;
    let denom = dir.perp(&e);
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = s.a - origin;
    let t = w.perp(&e) / denom;
    let u = w.perp(&dir) / denom;
    (t > 1e-9 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// A sonar with a cone of `rays` rays over ±`half_cone`: the nearest hit, placed on the
/// sensor's axis, with range noise; `None` beyond `max_range`.
#[allow(clippy::too_many_arguments)]
fn sonar(
    walls: &[Segment],
    origin: Point,
    axis: f64,
    half_cone: f64,
    rays: usize,
    max_range: f64,
    sigma: f64,
    rng: &mut Rng,
) -> Option<f64> {
    let mut best = f64::INFINITY;
    for k in 0..rays {
        let a = if rays > 1 {
            axis - half_cone + 2.0 * half_cone * k as f64 / (rays - 1) as f64
        } else {
            axis
        };
        let dir = Vector::new(a.cos(), a.sin());
        for w in walls {
            if let Some(t) = ray_hit(origin, dir, w) {
                best = best.min(t);
            }
        }
    }
    (best <= max_range).then(|| best + rng.gauss(sigma))
}

/// Sonar points (world frame) of a left-looking sensor on a cart driving along y = `y`
/// from x = `x0` to `x1`, every `step`.
fn drive_by_scan(
    walls: &[Segment],
    y: f64,
    x0: f64,
    x1: f64,
    step: f64,
    rng: &mut Rng,
) -> Vec<Point> {
    let mut pts = Vec::new();
    let mut x = x0;
    while x <= x1 {
        let origin = Point::new(x, y);
        if let Some(r) = sonar(walls, origin, FRAC_PI_2, 0.05, 5, 3.0, 0.01, rng) {
            pts.push(origin + Vector::new(0.0, r));
        }
        x += step;
    }
    pts
}

/// Wall at y = 1 with a recess of `breadth` (along the wall) × `depth` (behind it) starting at
/// x = 4.
fn dock_world(breadth: f64, depth: f64) -> Vec<Segment> {
    let (x0, x1) = (4.0, 4.0 + breadth);
    vec![
        seg(-1.0, 1.0, x0, 1.0),
        seg(x0, 1.0, x0, 1.0 + depth),
        seg(x0, 1.0 + depth, x1, 1.0 + depth),
        seg(x1, 1.0 + depth, x1, 1.0),
        seg(x1, 1.0, 14.0, 1.0),
    ]
}

fn lines(segs: &[FittedSegment]) -> Vec<Segment> {
    segs.iter().map(|s| s.segment).collect()
}

// ---------------------------------------------------------------------------------------------
// Segments.

#[test]
fn segments_fit_known_lines_despite_noise_and_outliers() {
    for seed in 0..20 {
        let mut rng = Rng(seed);
        let mut pts = noisy_wall(
            Point::new(0.0, 0.0),
            Point::new(5.0, 0.0),
            0.04,
            0.02,
            &mut rng,
        );
        pts.extend(noisy_wall(
            Point::new(5.0, 0.04),
            Point::new(5.0, 3.0),
            0.04,
            0.02,
            &mut rng,
        ));
        // 3 % stray echoes, 0.4–1.5 m off.
        for p in pts.iter_mut() {
            if rng.uniform() < 0.03 {
                let off = 0.4 + 1.1 * rng.uniform();
                *p += Vector::new(-off, off);
            }
        }
        let segs = extract_segments(&pts, &SegmentParams::default());
        assert_eq!(segs.len(), 2, "seed {seed}: {segs:?}");
        let (a, b) = (segs[0].segment, segs[1].segment);
        assert!(a.angle().abs() < 0.02, "seed {seed}: {a:?}");
        assert!((b.angle() - FRAC_PI_2).abs() < 0.02, "seed {seed}: {b:?}");
        assert!(
            (a.a - Point::new(0.0, 0.0)).norm() < 0.1,
            "seed {seed}: {a:?}"
        );
        assert!(
            (a.b - Point::new(5.0, 0.0)).norm() < 0.15,
            "seed {seed}: {a:?}"
        );
        assert!(
            (b.b - Point::new(5.0, 3.0)).norm() < 0.1,
            "seed {seed}: {b:?}"
        );
        assert!(segs.iter().all(|s| s.rms < 0.03 && s.points > 50));
    }
}

#[test]
fn a_gap_splits_the_segment() {
    let mut rng = Rng(42);
    let mut pts = noisy_wall(
        Point::new(0.0, 2.0),
        Point::new(3.0, 2.0),
        0.04,
        0.015,
        &mut rng,
    );
    pts.extend(noisy_wall(
        Point::new(4.0, 2.0),
        Point::new(7.0, 2.0),
        0.04,
        0.015,
        &mut rng,
    ));
    let segs = extract_segments(&pts, &SegmentParams::default());
    assert_eq!(segs.len(), 2, "{segs:?}");
    assert!((segs[0].segment.b.x - 3.0).abs() < 0.05);
    assert!((segs[1].segment.a.x - 4.0).abs() < 0.05);
    // Bridging the gap needs a max_gap larger than the gap.
    let wide = SegmentParams {
        max_gap: 1.2,
        ..SegmentParams::default()
    };
    assert_eq!(extract_segments(&pts, &wide).len(), 1);
}

#[test]
fn too_strict_parameters_lose_the_wall() {
    let mut rng = Rng(7);
    let pts = noisy_wall(
        Point::new(0.0, 0.0),
        Point::new(4.0, 0.0),
        0.04,
        0.02,
        &mut rng,
    );
    // A threshold below the noise shatters the wall into many short pieces.
    let strict = SegmentParams {
        distance_threshold: 0.005,
        ..SegmentParams::default()
    };
    let segs = extract_segments(&pts, &strict);
    assert!(segs.iter().all(|s| s.segment.length() < 3.0), "{segs:?}");
    // A gap threshold below the sampling step finds nothing at all.
    let sparse = SegmentParams {
        max_gap: 0.02,
        ..SegmentParams::default()
    };
    assert!(extract_segments(&pts, &sparse).is_empty());
}

// ---------------------------------------------------------------------------------------------
// Wall.

#[test]
fn wall_selection_from_sonar_segments() {
    let walls = dock_world(2.8, 0.8);
    let mut rng = Rng(3);
    let pts = drive_by_scan(&walls, 0.4, 0.0, 12.0, 0.04, &mut rng);
    let segs = extract_segments(&pts, &SegmentParams::default());
    // Wall before the recess, its back wall, wall after it.
    assert!(segs.len() >= 3, "{segs:?}");
    let pose = Pose::new(10.0, 0.4, 0.03);
    let w = sense_wall(&lines(&segs), &pose, &WallParams::default()).expect("wall");
    assert_eq!(w.side, Side::Left);
    assert!((w.distance - 0.6).abs() < 0.03, "{w:?}");
    assert!((w.angle + 0.03).abs() < 0.02, "{w:?}");
    // The two collinear pieces form the wall, not the recess' back wall.
    assert!(w.segments >= 2);
    assert!(w.line.a.x < 4.0 && w.line.b.x > 7.0);
    // Only walls on the right: none.
    let right = WallParams {
        side: Some(Side::Right),
        ..WallParams::default()
    };
    assert!(sense_wall(&lines(&segs), &pose, &right).is_none());
    // Far away from everything: none.
    assert!(sense_wall(
        &lines(&segs),
        &Pose::new(5.0, -4.0, 0.0),
        &WallParams::default()
    )
    .is_none());
}

// ---------------------------------------------------------------------------------------------
// Docking spot.

fn sensed_dock_scene(seed: u64, walls: &[Segment]) -> (Vec<Point>, Vec<FittedSegment>) {
    let mut rng = Rng(seed);
    let mut pts = drive_by_scan(walls, 0.4, 0.0, 12.0, 0.04, &mut rng);
    for p in pts.iter_mut() {
        if rng.uniform() < 0.02 {
            *p += Vector::new(0.0, -0.3 - rng.uniform());
        }
    }
    let segs = extract_segments(&pts, &SegmentParams::default());
    (pts, segs)
}

#[test]
fn dock_is_found_at_the_right_place() {
    for seed in 0..10 {
        let (pts, segs) = sensed_dock_scene(seed, &dock_world(2.8, 0.8));
        let pose = Pose::new(9.0, 0.4, 0.0);
        let wall = sense_wall(&lines(&segs), &pose, &WallParams::default()).expect("wall");
        let dock = detect_dock(&wall, &pts, &DockParams::default()).expect("dock");
        // Centre of the 2.80 × 0.80 recess: x = 5.4, y = 1.4; parked heading along the wall.
        assert!((dock.pose.x - 5.4).abs() < 0.08, "seed {seed}: {dock:?}");
        assert!((dock.pose.y - 1.4).abs() < 0.05, "seed {seed}: {dock:?}");
        assert!(wrap_angle(dock.pose.theta).abs() < 0.03);
        assert!((dock.breadth - 2.8).abs() < 0.2 && (dock.depth - 0.8).abs() < 0.05);
        // The same from the extracted segments alone.
        let d2 = detect_dock_in_segments(&wall, &lines(&segs), &DockParams::default())
            .expect("dock from segments");
        assert!((d2.pose.point() - dock.pose.point()).norm() < 0.1, "{d2:?}");
        // A 1.0 × 0.6 cart parked there (centred) stays inside the recess.
        let h = dock.pose.heading();
        let n = Vector::new(-h.y, h.x);
        for (l, w) in [(0.5, 0.3), (0.5, -0.3), (-0.5, 0.3), (-0.5, -0.3)] {
            let c = dock.pose.point() + h * l + n * w;
            assert!(c.x > 4.0 && c.x < 6.8 && c.y > 1.0 && c.y < 1.8, "{c:?}");
        }
    }
}

#[test]
fn dock_is_missed_with_wrong_dimensions() {
    let (pts, segs) = sensed_dock_scene(5, &dock_world(2.8, 0.8));
    let wall = sense_wall(
        &lines(&segs),
        &Pose::new(9.0, 0.4, 0.0),
        &WallParams::default(),
    )
    .expect("wall");
    let good = DockParams::default();
    assert!(detect_dock(&wall, &pts, &good).is_some());
    for (breadth, depth) in [
        (2.8 * 1.3, 0.8),
        (2.8, 0.8 * 1.3),
        (2.8 * 1.3, 0.8 * 1.3),
        (2.8 * 0.7, 0.8),
        (2.8, 0.8 * 0.7),
    ] {
        let p = DockParams {
            breadth,
            depth,
            ..good
        };
        assert!(
            detect_dock(&wall, &pts, &p).is_none(),
            "found with breadth {breadth}, depth {depth}"
        );
    }
}

#[test]
fn no_dock_in_a_plain_wall_or_a_different_recess() {
    let plain = vec![seg(-1.0, 1.0, 14.0, 1.0)];
    let (pts, segs) = sensed_dock_scene(11, &plain);
    let wall = sense_wall(
        &lines(&segs),
        &Pose::new(9.0, 0.4, 0.0),
        &WallParams::default(),
    )
    .expect("wall");
    assert!(detect_dock(&wall, &pts, &DockParams::default()).is_none());
    // Sonar drop-outs leave a gap in the wall, but no back wall behind it.
    let holed: Vec<Point> = pts
        .iter()
        .copied()
        .filter(|p| p.x < 4.0 || p.x > 6.8)
        .collect();
    assert!(detect_dock(&wall, &holed, &DockParams::default()).is_none());
    // A recess of another size is not the lab's docking spot.
    let (pts, segs) = sensed_dock_scene(12, &dock_world(1.5, 0.8));
    let wall = sense_wall(
        &lines(&segs),
        &Pose::new(9.0, 0.4, 0.0),
        &WallParams::default(),
    )
    .expect("wall");
    assert!(detect_dock(&wall, &pts, &DockParams::default()).is_none());
}

// ---------------------------------------------------------------------------------------------
// Planner.

fn room_with_obstacle() -> Vec<Segment> {
    vec![
        // The room, 10 × 8.
        seg(0.0, 0.0, 10.0, 0.0),
        seg(10.0, 0.0, 10.0, 8.0),
        seg(10.0, 8.0, 0.0, 8.0),
        seg(0.0, 8.0, 0.0, 0.0),
        // A box in the middle.
        seg(3.5, 2.5, 6.5, 2.5),
        seg(6.5, 2.5, 6.5, 5.5),
        seg(6.5, 5.5, 3.5, 5.5),
        seg(3.5, 5.5, 3.5, 2.5),
        // A wall stub from the top.
        seg(8.0, 8.0, 8.0, 4.0),
    ]
}

fn room_bounds() -> Bounds {
    Bounds::new(Point::new(0.0, 0.0), Point::new(10.0, 8.0))
}

fn assert_clear(path: &Path, obstacles: &[Segment], inflation: f64) {
    for w in &path.waypoints {
        assert!(
            point_clearance(*w, obstacles) >= inflation - 1e-9,
            "waypoint {w:?} too close"
        );
    }
    assert!(
        path_clearance(path, obstacles) >= inflation - 1e-9,
        "{path:?}"
    );
}

#[test]
fn planner_finds_a_clear_path_around_the_obstacle() {
    let obstacles = room_with_obstacle();
    let params = PlannerParams::default();
    let start = Pose::new(1.0, 4.0, 0.0);
    let goal = Pose::new(9.0, 2.0, FRAC_PI_2);
    let path = plan(&obstacles, &start, &goal, &room_bounds(), &params).expect("path");
    assert_eq!(path.waypoints[0], start.point());
    assert_eq!(*path.waypoints.last().unwrap(), goal.point());
    assert_eq!(path.goal_heading, Some(FRAC_PI_2));
    assert_clear(&path, &obstacles, params.inflation);
    // Shortcutting leaves a handful of waypoints, not a staircase of cells.
    assert!(path.waypoints.len() <= 8, "{path:?}");
    // The final approach: the last leg runs along the goal heading, 1 m long.
    let n = path.waypoints.len();
    let last = path.waypoints[n - 1] - path.waypoints[n - 2];
    assert!((last.norm() - params.approach_distance).abs() < 1e-9);
    assert!(wrap_angle(last.y.atan2(last.x) - FRAC_PI_2).abs() < 1e-9);
    // Not absurdly long: the straight distance is ~8.2 m.
    assert!(path.length() < 11.0, "{}", path.length());

    // Backing in: the approach comes from the other side.
    let back = PlannerParams {
        reverse: true,
        ..params
    };
    let path = plan(
        &obstacles,
        &start,
        &Pose::new(9.0, 2.0, -FRAC_PI_2),
        &room_bounds(),
        &back,
    )
    .expect("path");
    let n = path.waypoints.len();
    let last = path.waypoints[n - 1] - path.waypoints[n - 2];
    assert!(wrap_angle(last.y.atan2(last.x) - FRAC_PI_2).abs() < 1e-9);
    assert_clear(&path, &obstacles, params.inflation);
}

#[test]
fn planner_reports_no_path() {
    let mut obstacles = room_with_obstacle();
    // A closed 2 × 2 box around the goal.
    obstacles.extend([
        seg(7.0, 0.5, 9.5, 0.5),
        seg(9.5, 0.5, 9.5, 3.0),
        seg(9.5, 3.0, 7.0, 3.0),
        seg(7.0, 3.0, 7.0, 0.5),
    ]);
    let start = Pose::new(1.0, 4.0, 0.0);
    let err = plan(
        &obstacles,
        &start,
        &Pose::new(8.25, 1.75, 0.0),
        &room_bounds(),
        &PlannerParams::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        PlanError::NoPath {
            reason: NoPathReason::Unreachable
        }
    );
    assert!(err.to_string().contains("cannot be reached"));
    // Goal inside the obstacle box.
    let err = plan(
        &room_with_obstacle(),
        &start,
        &Pose::new(5.0, 4.0, 0.0),
        &room_bounds(),
        &PlannerParams::default(),
    );
    // (inside the box but far from its walls: reachable only from inside, so unreachable)
    assert!(matches!(err, Err(PlanError::NoPath { .. })));
    // Goal on a wall.
    let err = plan(
        &room_with_obstacle(),
        &start,
        &Pose::new(5.0, 2.6, 0.0),
        &room_bounds(),
        &PlannerParams::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        PlanError::NoPath {
            reason: NoPathReason::GoalBlocked
        }
    );
    // A corridor narrower than twice the inflation is no way through.
    let narrow = vec![
        seg(0.0, 0.0, 6.0, 0.0),
        seg(0.0, 3.0, 6.0, 3.0),
        seg(3.0, 0.0, 3.0, 1.2),
        seg(3.0, 3.0, 3.0, 1.8),
    ];
    let b = Bounds::new(Point::new(0.0, 0.0), Point::new(6.0, 3.0));
    let p = plan(
        &narrow,
        &Pose::new(1.0, 1.5, 0.0),
        &Pose::new(5.0, 1.5, 0.0),
        &b,
        &PlannerParams::default(),
    );
    assert!(matches!(
        p,
        Err(PlanError::NoPath {
            reason: NoPathReason::Unreachable
        })
    ));
    let slim = PlannerParams {
        inflation: 0.2,
        ..PlannerParams::default()
    };
    let p = plan(
        &narrow,
        &Pose::new(1.0, 1.5, 0.0),
        &Pose::new(5.0, 1.5, 0.0),
        &b,
        &slim,
    )
    .expect("slim cart passes");
    assert_clear(&p, &narrow, 0.2);
}

// ---------------------------------------------------------------------------------------------
// Pure pursuit.

/// Drive `path` with pure pursuit on the Euler-integrated bicycle model (dt = 0.02 s).
/// Returns the final pose, the largest distance from the path and the status.
fn pursue(
    params: PursuitParams,
    path: &Path,
    start: Pose,
    max_t: f64,
) -> (Pose, f64, PursuitStatus) {
    let mut pp = PurePursuit::new(params);
    let mut pose = start;
    let mut worst: f64 = 0.0;
    for _ in 0..(max_t / 0.02) as usize {
        let c = pp.command(&pose, path);
        if c.is_stop() {
            break;
        }
        pose = bicycle_step(&pose, c, params.wheelbase, 0.02);
        worst = worst.max(pp.cross_track_error(&pose));
    }
    (pose, worst, pp.status(&pose))
}

#[test]
fn pure_pursuit_converges_on_a_straight_path() {
    let path = Path::new(vec![Point::new(0.0, 0.0), Point::new(8.0, 0.0)]);
    let (end, worst, status) = pursue(
        PursuitParams::default(),
        &path,
        Pose::new(0.0, -0.4, 0.3),
        120.0,
    );
    assert_eq!(status, PursuitStatus::Arrived);
    assert!((end.point() - Point::new(8.0, 0.0)).norm() < 0.1, "{end:?}");
    assert!(end.y.abs() < 0.03 && end.theta.abs() < 0.05, "{end:?}");
    assert!(worst < 0.6);
}

#[test]
fn pure_pursuit_converges_on_an_l_shaped_path() {
    let path = Path::new(vec![
        Point::new(0.0, 0.0),
        Point::new(6.0, 0.0),
        Point::new(6.0, 5.0),
    ])
    .with_heading(FRAC_PI_2);
    let params = PursuitParams {
        heading_tolerance: Some(0.1),
        ..PursuitParams::default()
    };
    let (end, worst, status) = pursue(params, &path, Pose::new(0.0, 0.0, 0.0), 120.0);
    assert_eq!(status, PursuitStatus::Arrived, "{end:?}");
    assert!((end.point() - Point::new(6.0, 5.0)).norm() < 0.1, "{end:?}");
    assert!(wrap_angle(end.theta - FRAC_PI_2).abs() < 0.1);
    // Pure pursuit cuts the corner, but boundedly: at the 1.28 m minimum turning radius R
    // even the tightest arc misses a right-angle corner by R(√2 − 1) ≈ 0.53 m.
    assert!(worst < 0.7, "lateral error {worst}");
}

#[test]
fn pure_pursuit_backs_along_a_straight_path() {
    let path = Path::new(vec![Point::new(5.0, 0.0), Point::new(0.0, 0.0)]);
    let params = PursuitParams {
        reverse: true,
        ..PursuitParams::default()
    };
    let (end, worst, status) = pursue(params, &path, Pose::new(5.0, 0.3, -0.1), 120.0);
    assert_eq!(status, PursuitStatus::Arrived);
    assert!(end.point().coords.norm() < 0.1, "{end:?}");
    assert!(
        end.theta.abs() < 0.05,
        "heading kept while backing: {end:?}"
    );
    assert!(worst < 0.5);
}

#[test]
fn planned_path_is_driven_without_touching_walls() {
    let obstacles = room_with_obstacle();
    let params = PlannerParams::default();
    // A goal the car-like cart can reach: the planner knows no turning radius, so the
    // approach must leave room to turn (9, 2 heading north is a corner it cannot drive).
    let goal = Pose::new(8.5, 1.2, 0.0);
    let path = plan(
        &obstacles,
        &Pose::new(1.0, 4.0, 0.0),
        &goal,
        &room_bounds(),
        &params,
    )
    .unwrap();
    let pp = PursuitParams {
        lookahead: 0.5,
        heading_tolerance: Some(0.15),
        ..PursuitParams::default()
    };
    let mut ctl = PurePursuit::new(pp);
    let mut pose = Pose::new(1.0, 4.0, 0.0);
    let mut closest = f64::INFINITY;
    for _ in 0..10_000 {
        let c = ctl.command(&pose, &path);
        if c.is_stop() {
            break;
        }
        pose = bicycle_step(&pose, c, DEFAULT_WHEELBASE, 0.02);
        closest = closest.min(point_clearance(pose.point(), &obstacles));
    }
    assert!(ctl.finished(&pose), "{pose:?} {path:?}");
    assert!((pose.point() - goal.point()).norm() < 0.1);
    // The rear axle kept well away from the walls (the path keeps 0.4 m; corner cutting
    // eats into that margin only a little).
    assert!(closest > 0.25, "closest approach {closest}");
}

// ---------------------------------------------------------------------------------------------
// Wall following.

fn follow_sim(params: &FollowParams, walls: &[Segment], start: Pose, secs: f64) -> Pose {
    let mut pose = start;
    let side_params = |side| WallParams {
        side: Some(side),
        ..WallParams::default()
    };
    for _ in 0..(secs / 0.02) as usize {
        let wall = sense_wall(walls, &pose, &side_params(Side::Right)).expect("wall on the right");
        let other = sense_wall(walls, &pose, &side_params(Side::Left));
        let c = follow_command(&wall, other.as_ref(), params);
        pose = bicycle_step(&pose, c, params.wheelbase, 0.02);
    }
    pose
}

#[test]
fn wall_following_converges_to_the_requested_distance() {
    let walls = vec![seg(-100.0, 0.0, 100.0, 0.0)];
    for (start, speed) in [
        (Pose::new(0.0, 1.5, -0.2), 0.3),
        (Pose::new(0.0, 0.35, 0.3), 0.3),
        (Pose::new(0.0, 1.2, 0.1), -0.3),
    ] {
        for distance in [0.5, 0.8] {
            let p = FollowParams {
                distance,
                speed,
                ..FollowParams::default()
            };
            let end = follow_sim(&p, &walls, start, 40.0);
            assert!(
                (end.y - distance).abs() < 0.02,
                "{start:?} {speed} {distance}: {end:?}"
            );
            assert!(end.theta.abs() < 0.02, "{end:?}");
            let w = sense_wall(&walls, &end, &WallParams::default()).unwrap();
            assert!(is_aligned(&w, None, &p));
        }
    }
}

#[test]
fn corridor_following_centres_between_walls() {
    let walls = vec![seg(-100.0, 0.0, 100.0, 0.0), seg(-100.0, 2.2, 100.0, 2.2)];
    let p = FollowParams {
        mode: FollowMode::Corridor,
        ..FollowParams::default()
    };
    let end = follow_sim(&p, &walls, Pose::new(0.0, 0.5, 0.2), 40.0);
    assert!((end.y - 1.1).abs() < 0.03, "{end:?}");
    // The same walls in wall mode keep the requested 0.6 m from the followed wall instead.
    let v1 = FollowParams::default();
    let end = follow_sim(&v1, &walls, Pose::new(0.0, 0.5, 0.2), 40.0);
    assert!((end.y - 0.6).abs() < 0.03, "{end:?}");
}

// ---------------------------------------------------------------------------------------------
// Collision avoidance.

fn cart_sonars(walls: &[Segment], pose: &Pose) -> Vec<SonarReading> {
    // Front sensors at the nose (0.85 m ahead of the rear axle), rear ones at the tail.
    let mounts = [
        (Point::new(0.85, 0.0), 0.0),
        (Point::new(0.85, 0.25), 0.4),
        (Point::new(0.85, -0.25), -0.4),
        (Point::new(0.35, 0.3), FRAC_PI_2),
        (Point::new(0.35, -0.3), -FRAC_PI_2),
        (Point::new(-0.15, 0.0), PI),
        (Point::new(-0.15, 0.25), PI - 0.4),
        (Point::new(-0.15, -0.25), -PI + 0.4),
    ];
    let mut rng = Rng(1);
    mounts
        .iter()
        .map(|(pos, angle)| {
            let origin = pose.transform(*pos);
            let range = sonar(
                walls,
                origin,
                pose.theta + angle,
                0.1,
                3,
                4.0,
                0.0,
                &mut rng,
            )
            .unwrap_or(f64::INFINITY);
            SonarReading {
                position: *pos,
                angle: *angle,
                range,
            }
        })
        .collect()
}

#[test]
fn avoidance_stops_for_obstacles_ahead_only() {
    let p = AvoidParams {
        mode: AvoidMode::ControlledStop,
        ..AvoidParams::default()
    };
    // A wall across the way at x = 5, one behind at x = -1.
    let walls = vec![seg(5.0, -3.0, 5.0, 3.0), seg(-1.0, -3.0, -1.0, 3.0)];
    let mut pose = Pose::new(0.0, 0.0, 0.0);
    let mut slowed = false;
    let stop = loop {
        let readings = cart_sonars(&walls, &pose);
        let d = avoid(&readings, Command::new(0.4, 0.0), &p);
        match d {
            AvoidDecision::Stopped { distance, bearing } => break (distance, bearing),
            AvoidDecision::Slow { .. } => slowed = true,
            AvoidDecision::Pass(_) => {}
            other => panic!("unexpected {other:?}"),
        }
        pose = bicycle_step(&pose, d.command(), DEFAULT_WHEELBASE, 0.02);
        assert!(pose.x < 5.0, "drove into the wall");
    };
    assert!(slowed, "slowed down before stopping");
    assert!(
        stop.0 <= p.stop_range && stop.0 > p.stop_range - 0.05,
        "{stop:?}"
    );
    assert!(stop.1.abs() < 0.5);
    // The tail 0.35 m from the wall at x = -1 behind: driving forward is fine…
    let pose = Pose::new(-0.5, 0.0, 0.0);
    let readings = cart_sonars(&walls, &pose);
    let fwd = Command::new(0.4, 0.0);
    assert_eq!(avoid(&readings, fwd, &p), AvoidDecision::Pass(fwd));
    // …backing is not.
    assert!(avoid(&readings, Command::new(-0.2, 0.0), &p).is_stopped());
}

#[test]
fn corner_manoeuvre_backs_along_the_wall_until_the_controlled_stop() {
    // Corner mission, steps 3–4: follow the wall (on the right) backwards until the rear
    // sonars see the other wall.
    let walls = vec![seg(0.0, 0.0, 20.0, 0.0), seg(0.0, 0.0, 0.0, 5.0)];
    let follow = FollowParams {
        speed: -0.25,
        ..FollowParams::default()
    };
    let avoid_params = AvoidParams {
        mode: AvoidMode::ControlledStop,
        ..AvoidParams::default()
    };
    let mut pose = Pose::new(8.0, 0.9, 0.1);
    let mut stopped = None;
    for _ in 0..20_000 {
        let wall = sense_wall(
            &walls,
            &pose,
            &WallParams {
                side: Some(Side::Right),
                max_angle: 1.0,
                ..WallParams::default()
            },
        )
        .expect("wall");
        let c = follow_command(&wall, None, &follow);
        let d = avoid(&cart_sonars(&walls, &pose), c, &avoid_params);
        if d.is_stopped() {
            stopped = d.obstacle();
            break;
        }
        pose = bicycle_step(&pose, d.command(), DEFAULT_WHEELBASE, 0.02);
    }
    let (distance, bearing) = stopped.expect("controlled stop");
    assert!((wrap_angle(bearing - PI)).abs() < 0.5);
    assert!(distance <= avoid_params.stop_range);
    // Parked in the corner: tail ~0.4 m from the end wall, 0.6 m from the side wall.
    assert!(
        (pose.x - 0.15 - avoid_params.stop_range).abs() < 0.1,
        "{pose:?}"
    );
    assert!((pose.y - 0.6).abs() < 0.05, "{pose:?}");
}

//! The validated world: walls, obstacles, the cart, its sonar ring, the goal area, the dock,
//! the simulation settings — and the collision geometry built from them.

use crate::geom::{wrap_angle, Point, Pose, Segment, Vector};
use nalgebra::Isometry2;
use parry2d_f64::query::{self, Ray, RayCast};
use parry2d_f64::shape::{Cuboid, Polyline};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt;

/// A world: what the simulated robot drives in, and how its outcome is judged.
///
/// Built by [`World::load`] or [`World::parse`], which check every value; the fields are public
/// so tests can adjust a loaded world (e.g. silence the sonar noise).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct World {
    /// Short name, e.g. `lab`.
    pub name: String,
    /// One-line description.
    pub description: String,
    /// Walls: open polylines, metres, each with at least two points.
    pub walls: Vec<Vec<Point>>,
    /// Obstacles: closed polygons (the last point joins the first), each with at least three
    /// points.
    pub obstacles: Vec<Vec<Point>>,
    /// The cart's footprint, kinematics and limits.
    pub cart: CartSpec,
    /// The cart's start pose (reference point: the rear-axle centre, see [`CartSpec`]).
    pub start: Pose,
    /// The ultrasonic sensors, in the cart frame.
    pub sonars: Vec<SonarMount>,
    /// The area the cart must end in; `None` when the world has no goal (no success possible).
    pub goal: Option<GoalArea>,
    /// Ground truth of the docking spot, for tests and reports; `None` when there is none.
    pub dock: Option<Dock>,
    /// Sensor and odometry model.
    pub sim: SimSettings,
}

/// The cart: a rectangle with car-like (bicycle) kinematics.
///
/// The cart frame's origin — the point a [`Pose`] of the cart gives — is the **centre of the
/// rear axle**, x forward, y to the left. The footprint reaches `length - rear_overhang` ahead
/// of it and `rear_overhang` behind it, `width / 2` to each side. The front (steered) axle is
/// `wheelbase` ahead of the rear axle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartSpec {
    /// Footprint length, metres.
    pub length: f64,
    /// Footprint width, metres.
    pub width: f64,
    /// Distance between the axles, metres.
    pub wheelbase: f64,
    /// Footprint behind the rear axle, metres.
    pub rear_overhang: f64,
    /// Largest speed either way, m/s.
    pub max_speed: f64,
    /// Largest steering angle either way, radians.
    pub max_steer: f64,
    /// Largest steering rate, rad/s.
    pub max_steer_rate: f64,
    /// Time constant of the drive's first-order lag, seconds (0: the speed follows at once).
    pub speed_time_constant: f64,
}

impl Default for CartSpec {
    /// The thesis' cart (a Vesa Trekka): about 1.0 m × 0.6 m, wheelbase 0.7 m, 0.5 m/s,
    /// ±35° steering (1.0 m smallest turning radius at the rear axle).
    fn default() -> Self {
        let (length, wheelbase) = (1.0, 0.7);
        CartSpec {
            length,
            width: 0.6,
            wheelbase,
            // axles centred in the footprint, computed as the loader computes it
            rear_overhang: (length - wheelbase) / 2.0,
            max_speed: 0.5,
            max_steer: 35f64.to_radians(),
            max_steer_rate: 90f64.to_radians(),
            speed_time_constant: 0.2,
        }
    }
}

impl CartSpec {
    /// Half length and half width.
    pub fn half_extents(&self) -> Vector {
        Vector::new(self.length / 2.0, self.width / 2.0)
    }

    /// Distance from the rear axle forward to the footprint's centre.
    pub fn center_offset(&self) -> f64 {
        self.length / 2.0 - self.rear_overhang
    }

    /// Distance from the rear axle forward to the front bumper.
    pub fn front(&self) -> f64 {
        self.length - self.rear_overhang
    }

    /// The footprint's centre, with the cart's heading, for a cart at `pose`.
    pub fn footprint_center(&self, pose: &Pose) -> Pose {
        pose.compose(Pose::new(self.center_offset(), 0.0, 0.0))
    }

    /// The footprint's corners in world coordinates, counter-clockwise from front-left.
    pub fn footprint(&self, pose: &Pose) -> [Point; 4] {
        let (f, r, h) = (self.front(), -self.rear_overhang, self.width / 2.0);
        [
            pose.transform(Point::new(f, h)),
            pose.transform(Point::new(r, h)),
            pose.transform(Point::new(r, -h)),
            pose.transform(Point::new(f, -h)),
        ]
    }

    /// Turning radius of the rear-axle centre at the largest steering angle.
    pub fn min_turn_radius(&self) -> f64 {
        self.wheelbase / self.max_steer.tan()
    }

    /// True when every value is finite and in range (what the world loader enforces).
    pub fn is_valid(&self) -> bool {
        let finite = [
            self.length,
            self.width,
            self.wheelbase,
            self.rear_overhang,
            self.max_speed,
            self.max_steer,
            self.max_steer_rate,
            self.speed_time_constant,
        ]
        .iter()
        .all(|v| v.is_finite());
        finite
            && self.length > 0.0
            && self.width > 0.0
            && self.wheelbase > 0.0
            && self.rear_overhang >= 0.0
            && self.rear_overhang + self.wheelbase <= self.length
            && self.max_speed > 0.0
            && self.max_steer > 0.0
            && self.max_steer < PI / 2.0
            && self.max_steer_rate > 0.0
            && self.speed_time_constant >= 0.0
    }
}

/// The beam of an ultrasonic sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Beam {
    /// A narrow cone ([`SimSettings::narrow_half_angle`]): precise bearing, loses oblique walls.
    Narrow,
    /// A wide cone ([`SimSettings::wide_half_angle`]): sees the nearest thing in a broad sector.
    Wide,
}

impl Beam {
    /// The name used in world files: `narrow` or `wide`.
    pub fn as_str(self) -> &'static str {
        match self {
            Beam::Narrow => "narrow",
            Beam::Wide => "wide",
        }
    }
}

impl fmt::Display for Beam {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where an ultrasonic sensor sits on the cart and how it looks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarMount {
    /// Position in the cart frame (rear-axle centre, x forward, y left), metres.
    pub x: f64,
    /// Position in the cart frame, metres.
    pub y: f64,
    /// Direction of the beam's axis in the cart frame, radians (0 = straight ahead).
    pub angle: f64,
    /// Beam shape.
    pub beam: Beam,
    /// Largest range, metres; nothing farther echoes.
    pub range: f64,
}

impl SonarMount {
    /// The mount as a pose in the cart frame.
    pub fn pose(&self) -> Pose {
        Pose::new(self.x, self.y, self.angle)
    }

    /// The ring used when a world lists no `[[sonar]]`: ten sensors on the footprint's edge —
    /// front (narrow), front corners at ±30° (wide), two on each side at ±90° (narrow, 0.65 m
    /// apart on the default cart, so a wall's angle can be measured), rear (narrow) and rear
    /// corners at ±150° (wide). Narrow beams reach 4 m, wide ones 3 m.
    pub fn default_ring(cart: &CartSpec) -> Vec<SonarMount> {
        let (f, r, h) = (cart.front(), -cart.rear_overhang, cart.width / 2.0);
        let side_front = (f - 0.2).max(r);
        let side_rear = 0.0f64.clamp(r, f);
        let mount = |x: f64, y: f64, deg: f64, beam: Beam| SonarMount {
            x,
            y,
            angle: wrap_angle(deg.to_radians()),
            beam,
            range: match beam {
                Beam::Narrow => 4.0,
                Beam::Wide => 3.0,
            },
        };
        vec![
            mount(f, 0.0, 0.0, Beam::Narrow),
            mount(f, 0.8 * h, 30.0, Beam::Wide),
            mount(f, -0.8 * h, -30.0, Beam::Wide),
            mount(side_front, h, 90.0, Beam::Narrow),
            mount(side_rear, h, 90.0, Beam::Narrow),
            mount(side_front, -h, -90.0, Beam::Narrow),
            mount(side_rear, -h, -90.0, Beam::Narrow),
            mount(r, 0.0, 180.0, Beam::Narrow),
            mount(r, 0.8 * h, 150.0, Beam::Wide),
            mount(r, -0.8 * h, -150.0, Beam::Wide),
        ]
    }
}

/// An oriented rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    /// Centre.
    pub center: Point,
    /// Direction of the `length` side, radians.
    pub heading: f64,
    /// Extent along `heading`, metres.
    pub length: f64,
    /// Extent across `heading`, metres.
    pub width: f64,
}

impl Rect {
    /// The rectangle's frame: centre and heading.
    pub fn pose(&self) -> Pose {
        Pose::new(self.center.x, self.center.y, self.heading)
    }

    /// Corners, counter-clockwise from (+length/2, +width/2).
    pub fn corners(&self) -> [Point; 4] {
        let pose = self.pose();
        let (l, w) = (self.length / 2.0, self.width / 2.0);
        [
            pose.transform(Point::new(l, w)),
            pose.transform(Point::new(-l, w)),
            pose.transform(Point::new(-l, -w)),
            pose.transform(Point::new(l, -w)),
        ]
    }

    /// True when `p` lies inside or on the edge (within `tolerance` metres).
    pub fn contains(&self, p: Point, tolerance: f64) -> bool {
        let local = self.pose().isometry().inverse_transform_point(&p);
        local.x.abs() <= self.length / 2.0 + tolerance
            && local.y.abs() <= self.width / 2.0 + tolerance
    }
}

/// The area the cart must end in for a run to succeed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalArea {
    /// The rectangle all four corners of the footprint must lie in.
    pub area: Rect,
    /// The cart's required heading, radians.
    pub heading: f64,
    /// Largest heading error allowed, radians.
    pub heading_tolerance: f64,
    /// When true the cart may park either way round: the heading counts modulo 180°.
    pub either_way: bool,
}

impl GoalArea {
    /// Heading error of a cart heading `theta`, radians in [0, π] (in [0, π/2] when
    /// `either_way`).
    pub fn heading_error(&self, theta: f64) -> f64 {
        let e = wrap_angle(theta - self.heading).abs();
        if self.either_way {
            e.min(PI - e)
        } else {
            e
        }
    }
}

/// Ground truth of a docking spot: a rectangular recess behind an opening in a wall.
///
/// The recess lies on the **left** of `a → b` (looking from `a` to `b`), `depth` deep.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Dock {
    /// One end of the opening, on the wall's line.
    pub a: Point,
    /// The other end of the opening.
    pub b: Point,
    /// Size along the wall, metres (the opening's length).
    pub breadth: f64,
    /// Size into the wall, metres.
    pub depth: f64,
}

impl Dock {
    /// The opening as a segment.
    pub fn opening(&self) -> Segment {
        Segment::new(self.a, self.b)
    }

    /// The recess as a rectangle (heading along `a → b`).
    pub fn rect(&self) -> Rect {
        let along = self.b - self.a;
        let heading = along.y.atan2(along.x);
        let left = Vector::new(-heading.sin(), heading.cos());
        Rect {
            center: nalgebra::center(&self.a, &self.b) + left * (self.depth / 2.0),
            heading,
            length: along.norm(),
            width: self.depth,
        }
    }
}

/// Default odometry distance error, 1σ, fraction of the distance driven (1 %).
pub const DEFAULT_ODOMETRY_DISTANCE_SIGMA: f64 = 0.01;
/// Default odometry heading error, 1σ, degrees per metre driven.
pub const DEFAULT_ODOMETRY_HEADING_SIGMA_DEG: f64 = 0.5;
/// Default odometry heading random walk, 1σ, degrees per √metre driven: slip on a lab floor,
/// small beside the systematic drift.
pub const DEFAULT_ODOMETRY_HEADING_WALK_DEG: f64 = 0.1;

/// The sensor and odometry model of a simulation run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimSettings {
    /// Standard deviation of the Gaussian range noise of a sonar echo, metres.
    pub sonar_sigma: f64,
    /// Probability that a reading is spuriously lost (no echo: max range).
    pub sonar_dropout: f64,
    /// A ray meeting a surface at more than this angle from the surface normal is reflected
    /// away and lost (specular reflection), radians.
    pub incidence_limit: f64,
    /// Rays cast per beam cone, spread evenly over it (1: the axis only).
    pub rays_per_beam: u32,
    /// Half the opening angle of a narrow beam, radians.
    pub narrow_half_angle: f64,
    /// Half the opening angle of a wide beam, radians.
    pub wide_half_angle: f64,
    /// Odometry distance error, 1σ, as a fraction of the distance driven: one scale error
    /// drawn per run (a wheel whose diameter is not quite the calibrated one).
    pub odometry_distance_sigma: f64,
    /// Odometry heading error, 1σ, radians per metre driven: one drift rate drawn per run
    /// (a steering offset, so the error grows with the distance).
    pub odometry_heading_sigma: f64,
    /// Odometry heading random walk, 1σ, radians per √metre driven (wheel slip).
    pub odometry_heading_walk: f64,
}

impl Default for SimSettings {
    /// 1 cm range noise, 1 % dropouts, 65° incidence limit, 7 rays per beam, narrow ±8°,
    /// wide ±25°; odometry off by 1 % of the distance and 0.5° of heading per metre (1σ), with
    /// a heading random walk of 0.1° per √metre, as a real cart's: the robot must correct its pose from what it senses, not trust its
    /// wheels.
    fn default() -> Self {
        SimSettings {
            sonar_sigma: 0.01,
            sonar_dropout: 0.01,
            incidence_limit: 65f64.to_radians(),
            rays_per_beam: 7,
            narrow_half_angle: 8f64.to_radians(),
            wide_half_angle: 25f64.to_radians(),
            odometry_distance_sigma: DEFAULT_ODOMETRY_DISTANCE_SIGMA,
            odometry_heading_sigma: DEFAULT_ODOMETRY_HEADING_SIGMA_DEG.to_radians(),
            odometry_heading_walk: DEFAULT_ODOMETRY_HEADING_WALK_DEG.to_radians(),
        }
    }
}

impl SimSettings {
    /// Half the opening angle of `beam`.
    pub fn half_angle(&self, beam: Beam) -> f64 {
        match beam {
            Beam::Narrow => self.narrow_half_angle,
            Beam::Wide => self.wide_half_angle,
        }
    }
}

/// How a run ended, judged against the world's goal area.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Judgement {
    /// All four corners of the footprint lie in the goal area.
    pub inside_goal: bool,
    /// Heading error, degrees (modulo 180° when the goal allows either way round); `None` when
    /// the world has no goal.
    pub heading_error_deg: Option<f64>,
    /// Collisions counted during the run.
    pub collisions: u32,
    /// Inside the goal, heading within tolerance, and no collision.
    pub success: bool,
}

impl fmt::Display for Judgement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let verdict = if self.success { "success" } else { "failure" };
        match self.heading_error_deg {
            None => write!(
                f,
                "{verdict}: the world has no goal area, {} collision(s)",
                self.collisions
            ),
            Some(e) => write!(
                f,
                "{verdict}: {} the goal area, heading error {e:.1}°, {} collision(s)",
                if self.inside_goal {
                    "inside"
                } else {
                    "outside"
                },
                self.collisions
            ),
        }
    }
}

/// Tolerance of the inside-the-goal test, metres.
const INSIDE_TOLERANCE: f64 = 1e-6;

impl World {
    /// Every wall and obstacle edge as a segment (obstacles closed).
    pub fn segments(&self) -> Vec<Segment> {
        let mut out = Vec::new();
        for wall in &self.walls {
            out.extend(wall.windows(2).map(|w| Segment::new(w[0], w[1])));
        }
        for obstacle in &self.obstacles {
            out.extend(obstacle.windows(2).map(|w| Segment::new(w[0], w[1])));
            if let (Some(first), Some(last)) = (obstacle.first(), obstacle.last()) {
                if obstacle.len() > 2 {
                    out.push(Segment::new(*last, *first));
                }
            }
        }
        out
    }

    /// The axis-aligned bounds (min, max) of all walls and obstacles; `None` without any.
    pub fn bounds(&self) -> Option<(Point, Point)> {
        let mut points = self.walls.iter().chain(&self.obstacles).flatten();
        let first = *points.next()?;
        Some(points.fold((first, first), |(lo, hi), p| {
            (
                Point::new(lo.x.min(p.x), lo.y.min(p.y)),
                Point::new(hi.x.max(p.x), hi.y.max(p.y)),
            )
        }))
    }

    /// Judge a run that ended at `final_pose` after `collisions` collisions.
    pub fn judge(&self, final_pose: Pose, collisions: u32) -> Judgement {
        let Some(goal) = &self.goal else {
            return Judgement {
                inside_goal: false,
                heading_error_deg: None,
                collisions,
                success: false,
            };
        };
        let inside_goal = self
            .cart
            .footprint(&final_pose)
            .iter()
            .all(|c| goal.area.contains(*c, INSIDE_TOLERANCE));
        let error = goal.heading_error(final_pose.theta);
        let heading_ok = error <= goal.heading_tolerance;
        Judgement {
            inside_goal,
            heading_error_deg: Some(error.to_degrees()),
            collisions,
            success: inside_goal && heading_ok && collisions == 0,
        }
    }

    /// True when the cart's footprint at `pose` touches a wall or an obstacle. Builds the
    /// collision geometry on every call: for repeated queries keep a [`WorldGeometry`].
    pub fn footprint_collides(&self, pose: &Pose) -> bool {
        WorldGeometry::new(self).footprint_collides(&self.cart, pose)
    }
}

/// A ray's first hit on a wall or obstacle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance from the ray's origin, metres.
    pub distance: f64,
    /// Where it hit.
    pub point: Point,
    /// Unit normal of the surface at the hit.
    pub normal: Vector,
}

/// The collision geometry of a world, built once: every wall and obstacle edge in one parry2d
/// [`Polyline`] (with its bounding-volume tree), plus the obstacle polygons for inside tests.
#[derive(Clone)]
pub struct WorldGeometry {
    lines: Option<Polyline>,
    obstacles: Vec<Vec<Point>>,
}

impl fmt::Debug for WorldGeometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("WorldGeometry")
            .field(
                "segments",
                &self.lines.as_ref().map_or(0, |l| l.num_segments()),
            )
            .field("obstacles", &self.obstacles.len())
            .finish()
    }
}

impl WorldGeometry {
    /// Build the geometry of `world`. Non-finite points and zero-length edges are skipped, so
    /// a hand-made world never makes this panic.
    pub fn new(world: &World) -> Self {
        let finite = |p: &Point| p.x.is_finite() && p.y.is_finite();
        let mut vertices: Vec<Point> = Vec::new();
        let mut indices: Vec<[u32; 2]> = Vec::new();
        for s in world.segments() {
            if finite(&s.a) && finite(&s.b) && s.length() > 1e-9 {
                let i = vertices.len() as u32;
                vertices.push(s.a);
                vertices.push(s.b);
                indices.push([i, i + 1]);
            }
        }
        let lines = (!indices.is_empty()).then(|| Polyline::new(vertices, Some(indices)));
        let obstacles = world
            .obstacles
            .iter()
            .filter(|o| o.len() >= 3 && o.iter().all(finite))
            .cloned()
            .collect();
        WorldGeometry { lines, obstacles }
    }

    /// True when the footprint of `cart` at `pose` touches a wall or an obstacle edge, or lies
    /// inside an obstacle.
    pub fn footprint_collides(&self, cart: &CartSpec, pose: &Pose) -> bool {
        let center = cart.footprint_center(pose);
        if !(center.x.is_finite() && center.y.is_finite() && center.theta.is_finite()) {
            return false;
        }
        let half = cart.half_extents();
        if let Some(lines) = &self.lines {
            let cuboid = Cuboid::new(half);
            let hit = query::intersection_test(
                &center.isometry(),
                &cuboid,
                &Isometry2::identity(),
                lines,
            )
            .unwrap_or_else(|_| {
                let c = center.isometry();
                lines.segments().any(|s| {
                    let local = s.transformed(&c.inverse());
                    query::details::intersection_test_cuboid_segment(
                        &Isometry2::identity(),
                        &cuboid,
                        &local,
                    )
                })
            });
            if hit {
                return true;
            }
        }
        self.obstacles
            .iter()
            .any(|o| point_in_polygon(center.point(), o))
    }

    /// The first wall or obstacle hit by a ray from `origin` along `dir` (need not be unit)
    /// within `max_distance`.
    pub fn cast_ray(&self, origin: Point, dir: Vector, max_distance: f64) -> Option<RayHit> {
        let lines = self.lines.as_ref()?;
        let norm = dir.norm();
        if !(norm > 0.0 && norm.is_finite() && max_distance > 0.0) {
            return None;
        }
        let dir = dir / norm;
        let ray = Ray::new(origin, dir);
        let hit = lines.cast_local_ray_and_get_normal(&ray, max_distance, true)?;
        let n = hit.normal;
        let n_norm = n.norm();
        let normal = if n_norm > 0.0 { n / n_norm } else { -dir };
        Some(RayHit {
            distance: hit.time_of_impact,
            point: ray.point_at(hit.time_of_impact),
            normal,
        })
    }
}

/// Even-odd point-in-polygon test (the polygon is closed implicitly).
pub(crate) fn point_in_polygon(p: Point, polygon: &[Point]) -> bool {
    let mut inside = false;
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + n - 1) % n];
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if p.x < x {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_corners_follow_the_rear_axle_pose() {
        let cart = CartSpec::default();
        let c = cart.footprint(&Pose::new(0.0, 0.0, 0.0));
        assert!((c[0] - Point::new(0.85, 0.3)).norm() < 1e-12);
        assert!((c[2] - Point::new(-0.15, -0.3)).norm() < 1e-12);
        let c = cart.footprint(&Pose::new(1.0, 1.0, PI / 2.0));
        assert!((c[0] - Point::new(0.7, 1.85)).norm() < 1e-12);
    }

    #[test]
    fn rect_contains_and_dock_rect_lies_left_of_the_opening() {
        let dock = Dock {
            a: Point::new(0.0, 0.0),
            b: Point::new(-2.8, 0.0),
            breadth: 2.8,
            depth: 0.8,
        };
        // a → b points to -x, so left is -y
        let r = dock.rect();
        assert!((r.center - Point::new(-1.4, -0.4)).norm() < 1e-12);
        assert!(r.contains(Point::new(-0.1, -0.7), 0.0));
        assert!(!r.contains(Point::new(-0.1, 0.1), 0.0));
    }

    #[test]
    fn heading_error_either_way() {
        let goal = GoalArea {
            area: Rect {
                center: Point::origin(),
                heading: 0.0,
                length: 1.0,
                width: 1.0,
            },
            heading: 0.0,
            heading_tolerance: 0.1,
            either_way: true,
        };
        assert!(goal.heading_error(PI - 0.05) < 0.051);
        let strict = GoalArea {
            either_way: false,
            ..goal
        };
        assert!((strict.heading_error(PI - 0.05) - (PI - 0.05)).abs() < 1e-12);
    }

    #[test]
    fn polygon_inside() {
        let sq = [
            Point::new(0.0, 0.0),
            Point::new(1.0, 0.0),
            Point::new(1.0, 1.0),
            Point::new(0.0, 1.0),
        ];
        assert!(point_in_polygon(Point::new(0.5, 0.5), &sq));
        assert!(!point_in_polygon(Point::new(1.5, 0.5), &sq));
    }
}

//! Parking manoeuvres for a car-like cart: backing into a spot beside the path it drove, the
//! way a driver parallel-parks.
//!
//! A grid planner knows nothing of a turning circle; a cart that has just driven past a
//! docking spot cannot turn into it. This planner builds the manoeuvre a driver would: pull
//! forward (if needed) until there is room, then back in along an S of two arcs of radius
//! `radius` and a straight tail, ending on the goal pose. Every pose along both legs is
//! checked against the map with the cart's footprint; radii are tried from the tightest
//! allowed upwards, and when none fits the answer is a clean [`ParkError`].

use crate::geom::{wrap_angle, Point, Pose, Segment, Vector};

/// A leg of a manoeuvre: driven forwards or backwards along its waypoints.
#[derive(Clone, Debug, PartialEq)]
pub struct Leg {
    /// Waypoints, world frame; the first is where the leg starts.
    pub waypoints: Vec<Point>,
    /// Driven backwards.
    pub reverse: bool,
    /// Heading of the cart along the leg's end (the cart's heading, not the motion's).
    pub heading: f64,
}

/// The cart's footprint relative to its reference point (rear-axle centre).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Distance from the reference point back to the rear bumper, m.
    pub rear: f64,
    /// Distance from the reference point forward to the front bumper, m.
    pub front: f64,
    /// Half the width, m.
    pub half_width: f64,
}

impl Footprint {
    /// The corners at `pose`.
    pub fn corners(&self, pose: &Pose) -> [Point; 4] {
        [
            pose.transform(Point::new(-self.rear, -self.half_width)),
            pose.transform(Point::new(self.front, -self.half_width)),
            pose.transform(Point::new(self.front, self.half_width)),
            pose.transform(Point::new(-self.rear, self.half_width)),
        ]
    }

    /// Smallest distance from the footprint's outline to any wall (0 when they cross).
    pub fn clearance(&self, pose: &Pose, walls: &[Segment]) -> f64 {
        let c = self.corners(pose);
        let edges = [
            Segment::new(c[0], c[1]),
            Segment::new(c[1], c[2]),
            Segment::new(c[2], c[3]),
            Segment::new(c[3], c[0]),
        ];
        let mut best = f64::INFINITY;
        for w in walls {
            for e in &edges {
                best = best.min(super::planner::segment_distance(e, w));
            }
        }
        best
    }
}

/// Parameters of the manoeuvre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParkParams {
    /// Tightest arc radius tried, m (at least the cart's turning radius).
    pub min_radius: f64,
    /// Widest arc radius tried, m.
    pub max_radius: f64,
    /// Straight tail before the goal, m.
    pub tail: f64,
    /// Clearance every pose must keep from the walls, m.
    pub clearance: f64,
    /// Spacing of the waypoints, m.
    pub step: f64,
    /// How far the goal may slide deeper along the spot (against the goal heading), m: a
    /// spot longer than the cart leaves room, and backing in needs it.
    pub slide: f64,
    /// Length of a last, forward leg along the goal heading, m (0: none). Backing into a spot
    /// along an S leaves the heading still swinging at its end; a short forward run
    /// straightens it, as a driver does. The cart backs in this much deeper than the goal (it
    /// must fit within `slide`; when no such manoeuvre fits, one without it is planned).
    pub settle: f64,
}

impl Default for ParkParams {
    fn default() -> Self {
        ParkParams {
            min_radius: 1.3,
            max_radius: 3.0,
            tail: 0.5,
            clearance: 0.03,
            step: 0.05,
            slide: 0.0,
            settle: 0.0,
        }
    }
}

/// Why no manoeuvre was found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParkError {
    /// The goal is not beside the cart's path (its heading differs too much).
    #[error("the spot's heading differs from the cart's by {0:.0}°: no parallel manoeuvre")]
    NotParallel(f64),
    /// Every radius tried makes the footprint touch a wall.
    #[error("no manoeuvre with an arc radius in [{min:.2}, {max:.2}] m keeps clear of the walls")]
    Blocked {
        /// Smallest radius tried.
        min: f64,
        /// Largest radius tried.
        max: f64,
    },
    /// Bad input.
    #[error("invalid input: {0}")]
    Invalid(String),
}

/// Plan a pull-forward-and-back-in manoeuvre from `start` into `goal` (both rear-axle poses;
/// the goal's heading is the parked cart's). The goal is flipped by 180° when that matches
/// the cart's heading better (a spot may be parked in either way round).
pub fn plan_parking(
    start: &Pose,
    goal: &Pose,
    footprint: &Footprint,
    walls: &[Segment],
    params: &ParkParams,
) -> Result<Vec<Leg>, ParkError> {
    let finite = [start.x, start.y, start.theta, goal.x, goal.y, goal.theta]
        .iter()
        .all(|v| v.is_finite());
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !finite || !positive(params.step) || !positive(params.min_radius) {
        return Err(ParkError::Invalid(
            "non-finite pose or non-positive step/radius".into(),
        ));
    }
    let mut goal = *goal;
    if wrap_angle(goal.theta - start.theta).abs() > std::f64::consts::FRAC_PI_2 {
        goal = Pose::new(goal.x, goal.y, goal.theta + std::f64::consts::PI);
    }
    let misalign = wrap_angle(goal.theta - start.theta).abs();
    if misalign > 0.35 {
        return Err(ParkError::NotParallel(misalign.to_degrees()));
    }
    let slides = (params.slide.max(0.0) / 0.1).floor() as usize;
    let settle = if params.settle.is_finite() {
        params.settle.max(0.0)
    } else {
        0.0
    };
    // the back-in goal must lie `settle` deeper than the goal: slide at least that far
    let first = (settle / 0.1 - 1e-9).ceil().max(0.0) as usize;
    for k in first..=slides {
        // slide the goal deeper into the spot (backwards along its heading)
        let h = goal.heading();
        let g = Pose::new(
            goal.x - h.x * 0.1 * k as f64,
            goal.y - h.y * 0.1 * k as f64,
            goal.theta,
        );
        // the start in the goal's frame: x forward along the goal heading, y to its left
        let left = Vector::new(-h.y, h.x);
        let rel = start.point() - g.point();
        let (sx, sy) = (rel.dot(&h), rel.dot(&left));
        let mut radius = params.min_radius.max(1e-3);
        while radius <= params.max_radius + 1e-9 {
            if let Some(mut legs) = try_radius(radius, sx, sy, &g, footprint, walls, params) {
                if settle <= 0.0 {
                    return Ok(legs);
                }
                if let Some(forward) = settle_leg(&g, settle, footprint, walls, params) {
                    legs.push(forward);
                    return Ok(legs);
                }
            }
            radius += 0.1;
        }
    }
    if settle > 0.0 {
        return plan_parking(
            start,
            &goal,
            footprint,
            walls,
            &ParkParams {
                settle: 0.0,
                ..*params
            },
        );
    }
    Err(ParkError::Blocked {
        min: params.min_radius,
        max: params.max_radius,
    })
}

/// The forward leg `length` long from `from` along its heading, if it keeps clear.
fn settle_leg(
    from: &Pose,
    length: f64,
    footprint: &Footprint,
    walls: &[Segment],
    params: &ParkParams,
) -> Option<Leg> {
    let h = from.heading();
    let n = (length / params.step).ceil().max(1.0) as usize;
    let poses: Vec<Pose> = (0..=n)
        .map(|k| {
            let d = length * k as f64 / n as f64;
            Pose::new(from.x + h.x * d, from.y + h.y * d, from.theta)
        })
        .collect();
    poses
        .iter()
        .all(|p| footprint.clearance(p, walls) >= params.clearance)
        .then(|| Leg {
            waypoints: poses.iter().map(Pose::point).collect(),
            reverse: false,
            heading: from.theta,
        })
}

#[allow(clippy::too_many_arguments)]
fn try_radius(
    radius: f64,
    sx: f64,
    sy: f64,
    goal: &Pose,
    footprint: &Footprint,
    walls: &[Segment],
    params: &ParkParams,
) -> Option<Vec<Leg>> {
    // two arcs turning by `alpha` each cover the lateral offset |sy|
    let cos_a = 1.0 - sy.abs() / (2.0 * radius);
    if !(-1.0..=1.0).contains(&cos_a) {
        return None;
    }
    let alpha = cos_a.acos();
    let s_len = 2.0 * radius * alpha.sin();
    let s_start_x = s_len + params.tail; // where the S begins, in the goal frame
    let to_world = |x: f64, y: f64, th: f64| {
        let p = goal.transform(Point::new(x, y));
        Pose::new(p.x, p.y, goal.theta + th)
    };
    // leg 1: straight along the start's lateral line to the S's beginning
    let mut poses1 = Vec::new();
    let d1 = s_start_x - sx;
    let n1 = (d1.abs() / params.step).ceil().max(1.0) as usize;
    for k in 0..=n1 {
        let x = sx + d1 * k as f64 / n1 as f64;
        poses1.push(to_world(x, sy, 0.0));
    }
    // leg 2: backwards along the S (from y = sy to y = 0) and the tail
    let sign = sy.signum();
    let mut poses2 = Vec::new();
    let n_arc = ((radius * alpha) / params.step).ceil().max(1.0) as usize;
    // first arc: centre beside the start of the S, on the side of the goal line
    let c1 = (s_start_x, sy - sign * radius);
    for k in 0..=n_arc {
        let phi = alpha * k as f64 / n_arc as f64;
        // backing: x decreases; the heading turns so the rear swings towards the goal line
        let x = c1.0 - radius * phi.sin();
        let y = c1.1 + sign * radius * phi.cos();
        poses2.push(to_world(x, y, sign * phi));
    }
    let c2 = (s_start_x - s_len, sign * radius);
    for k in 1..=n_arc {
        let phi = alpha * (1.0 - k as f64 / n_arc as f64);
        let x = c2.0 + radius * phi.sin();
        let y = c2.1 - sign * radius * phi.cos();
        poses2.push(to_world(x, y, sign * phi));
    }
    let n_tail = (params.tail / params.step).ceil().max(1.0) as usize;
    for k in 1..=n_tail {
        let x = params.tail * (1.0 - k as f64 / n_tail as f64);
        poses2.push(to_world(x, 0.0, 0.0));
    }
    let clear = |p: &Pose| footprint.clearance(p, walls) >= params.clearance;
    if !poses1.iter().all(clear) || !poses2.iter().all(clear) {
        return None;
    }
    let mut legs = Vec::new();
    if d1 > params.step {
        legs.push(Leg {
            waypoints: poses1.iter().map(Pose::point).collect(),
            reverse: false,
            heading: goal.theta,
        });
    } else if d1 < -params.step {
        // already past the S's beginning: back straight to it first
        poses2.splice(0..0, poses1.iter().copied());
    }
    legs.push(Leg {
        waypoints: poses2.iter().map(Pose::point).collect(),
        reverse: true,
        heading: goal.theta,
    });
    Some(legs)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The thesis-like cart: 1.0 m × 0.6 m, rear axle 0.15 m from the rear bumper (the
    /// clearance guard's tests use it too).
    pub(crate) fn cart() -> Footprint {
        Footprint {
            rear: 0.15,
            front: 0.85,
            half_width: 0.3,
        }
    }

    /// The lab's wall along y = 0 with a 2.8 × 0.8 recess at x 4.0–6.8.
    fn lab() -> Vec<Segment> {
        let p = |x: f64, y: f64| Point::new(x, y);
        vec![
            Segment::new(p(0.0, 0.0), p(4.0, 0.0)),
            Segment::new(p(4.0, 0.0), p(4.0, -0.8)),
            Segment::new(p(4.0, -0.8), p(6.8, -0.8)),
            Segment::new(p(6.8, -0.8), p(6.8, 0.0)),
            Segment::new(p(6.8, 0.0), p(14.0, 0.0)),
        ]
    }

    #[test]
    fn backs_into_the_lab_recess_after_pulling_forward() {
        let start = Pose::new(4.5, 0.8, std::f64::consts::PI);
        let goal = Pose::new(5.75, -0.4, std::f64::consts::PI);
        // without room to slide deeper, the S would clip the spot's near corner
        assert!(plan_parking(&start, &goal, &cart(), &lab(), &ParkParams::default()).is_err());
        let params = ParkParams {
            slide: 0.8,
            ..ParkParams::default()
        };
        let legs = plan_parking(&start, &goal, &cart(), &lab(), &params).unwrap();
        assert_eq!(legs.len(), 2);
        assert!(!legs[0].reverse && legs[1].reverse);
        let end = *legs[1].waypoints.last().unwrap();
        assert!((end.y - goal.y).abs() < 1e-6 && end.x >= goal.x && end.x <= goal.x + 0.8 + 1e-9);
        let fp = cart();
        let parked = Pose::new(end.x, end.y, goal.theta);
        assert!(fp
            .corners(&parked)
            .iter()
            .all(|c| c.x > 4.0 && c.x < 6.8 && c.y > -0.8 && c.y < 0.0));
        // the S stays clear of the recess walls: checked inside, and the end is in the recess
        assert!(end.y < -0.3 && end.x > 4.5 && end.x < 6.5);
    }

    #[test]
    fn a_settling_leg_straightens_the_cart_forward_onto_the_goal() {
        let start = Pose::new(4.5, 0.8, std::f64::consts::PI);
        let goal = Pose::new(5.75, -0.4, std::f64::consts::PI);
        let params = ParkParams {
            slide: 0.8,
            settle: 0.3,
            ..ParkParams::default()
        };
        let legs = plan_parking(&start, &goal, &cart(), &lab(), &params).unwrap();
        assert_eq!(legs.len(), 3);
        let (back, forward) = (&legs[1], &legs[2]);
        assert!(back.reverse && !forward.reverse);
        let (a, b) = (forward.waypoints[0], *forward.waypoints.last().unwrap());
        assert_eq!(a, *back.waypoints.last().unwrap());
        // 0.3 m forward (heading -x), along the goal line, ending within the slide
        assert!(((a - b).norm() - 0.3).abs() < 1e-9 && (b.y - goal.y).abs() < 1e-6);
        assert!(b.x < a.x && b.x >= goal.x - 1e-9 && b.x <= goal.x + 0.8 + 1e-9);
        // no room to back in deeper: planned without the settling leg
        let tight = ParkParams {
            slide: 0.8,
            settle: 5.0,
            ..ParkParams::default()
        };
        let legs = plan_parking(&start, &goal, &cart(), &lab(), &tight).unwrap();
        assert_eq!(legs.len(), 2);
    }

    #[test]
    fn a_spot_too_short_for_any_radius_is_refused() {
        let p = |x: f64, y: f64| Point::new(x, y);
        let walls = vec![
            Segment::new(p(0.0, 0.0), p(5.0, 0.0)),
            Segment::new(p(5.0, 0.0), p(5.0, -0.8)),
            Segment::new(p(5.0, -0.8), p(6.0, -0.8)),
            Segment::new(p(6.0, -0.8), p(6.0, 0.0)),
            Segment::new(p(6.0, 0.0), p(14.0, 0.0)),
        ];
        let start = Pose::new(4.5, 0.8, std::f64::consts::PI);
        let goal = Pose::new(5.65, -0.4, std::f64::consts::PI);
        let params = ParkParams {
            slide: 0.3,
            ..ParkParams::default()
        };
        assert!(matches!(
            plan_parking(&start, &goal, &cart(), &walls, &params),
            Err(ParkError::Blocked { .. })
        ));
    }

    #[test]
    fn perpendicular_goals_and_bad_input_are_errors() {
        let start = Pose::new(4.5, 0.8, std::f64::consts::PI);
        let goal = Pose::new(5.75, -0.4, std::f64::consts::FRAC_PI_2);
        assert!(matches!(
            plan_parking(&start, &goal, &cart(), &lab(), &ParkParams::default()),
            Err(ParkError::NotParallel(_))
        ));
        let nan = Pose::new(f64::NAN, 0.0, 0.0);
        assert!(plan_parking(&nan, &goal, &cart(), &lab(), &ParkParams::default()).is_err());
    }
}

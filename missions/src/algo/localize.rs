//! Localization by map matching: correct a drifting odometry pose from sonar segments that
//! lie on walls of the a-priori map.
//!
//! The robot's pose is its odometry composed with a *correction* (a rigid transform from the
//! odometry frame to the map frame, identity at the start). Wheel odometry drifts — a real
//! cart's by about 1 % of the distance and half a degree of heading per metre — so the
//! correction must follow it. Segments fitted to recent echoes (placed with the current
//! correction) are matched against the map's walls: a segment matches a wall when it runs
//! nearly parallel to it, close to its line and alongside it, and no other wall would do as
//! well. One matched wall fixes the heading and the offset across that wall; a second,
//! non-parallel one fixes the position along the first. What the matches do not constrain
//! (the position along a single wall) is left as the odometry has it.
//!
//! [`localize`] measures the error of the current correction; [`Fix::apply`] blends it in
//! with a gain, so one bad scan cannot throw the pose far.

use super::segments::Line;
pub use super::sweep::{recent_travel, swept_segments, SensedPoint};
use crate::geom::{wrap_angle, Point, Pose, Segment, Vector};
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;

/// Parameters of the map matching.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LocalizeParams {
    /// Largest angle between a segment and the wall it matches, radians. Default 0.1
    /// (≈ 5.7°): several metres of drift, not a crossing wall.
    pub max_angle: f64,
    /// Largest distance of a segment's midpoint from its wall's line, metres. Default 0.35:
    /// less than half a docking recess's depth, so the recess's back wall and the wall line
    /// are never confused.
    pub max_offset: f64,
    /// Shortest segment used, metres. Default 0.3.
    pub min_length: f64,
    /// How far inside a wall's ends both of a segment's ends must project to match it,
    /// metres. Default 0.1: echoes near a wall's edge come off the edge, not the wall.
    pub end_margin: f64,
    /// A match is ambiguous (and dropped) when a second wall is within this distance of the
    /// best one's offset, metres. Default 0.15.
    pub ambiguity: f64,
    /// Shortest segment whose direction corrects the heading, metres (shorter ones only
    /// correct the offset: a direction's error grows fast as a segment shortens). Default 0.8.
    pub min_turn_length: f64,
    /// Least matched length (m) a direction needs to be corrected: below it, the position
    /// along that direction is left alone. Default 0.5.
    pub min_support: f64,
    /// Largest heading correction one [`Fix::apply`] makes, radians. Default 0.005 (≈ 0.3°):
    /// the odometry drifts far slower than that between two fixes, so a larger step can only
    /// come from a bad match, which must not throw the pose.
    pub max_turn: f64,
    /// Largest position correction one [`Fix::apply`] makes, metres. Default 0.03.
    pub max_shift: f64,
}

impl Default for LocalizeParams {
    fn default() -> Self {
        LocalizeParams {
            max_angle: 0.1,
            max_offset: 0.35,
            min_length: 0.3,
            end_margin: 0.1,
            ambiguity: 0.15,
            min_turn_length: 0.8,
            min_support: 0.5,
            max_turn: 0.005,
            max_shift: 0.03,
        }
    }
}

/// One segment matched to one map wall.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallMatch {
    /// The sensed segment.
    pub segment: Segment,
    /// The map wall it lies on.
    pub wall: Segment,
    /// Angle to turn the segment by to make it parallel to the wall, radians in (-π/2, π/2].
    pub angle_error: f64,
    /// Signed distance from the segment's midpoint to the wall's line, along the wall's
    /// normal, metres (how far to move the segment onto the wall).
    pub offset: f64,
}

/// The error of a correction, as measured by the map: turn by `rotation` about the cart's
/// position, then move by `shift`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fix {
    /// Heading correction, radians.
    pub rotation: f64,
    /// Position correction, metres (zero along unconstrained directions).
    pub shift: Vector,
    /// Segments matched.
    pub matched: usize,
    /// Directions the position was constrained in: 1 (across one wall direction) or 2.
    pub constrained: usize,
}

impl Fix {
    /// This fix with its rotation cut to ±`max_turn` and its shift to `max_shift` long (so one
    /// fix can move the pose only so far; non-finite limits leave it as it is).
    pub fn limited(&self, max_turn: f64, max_shift: f64) -> Fix {
        let mut fix = *self;
        if max_turn.is_finite() && max_turn >= 0.0 {
            fix.rotation = fix.rotation.clamp(-max_turn, max_turn);
        }
        let norm = fix.shift.norm();
        if max_shift.is_finite() && max_shift >= 0.0 && norm > max_shift && norm.is_finite() {
            fix.shift *= max_shift / norm;
        }
        fix
    }

    /// The correction `correction` with a fraction `gain` (clamped to [0, 1]) of this fix
    /// applied, the rotation about `pivot` (the cart's position in the map frame).
    pub fn apply(&self, correction: &Pose, pivot: Point, gain: f64) -> Pose {
        let g = if gain.is_finite() {
            gain.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let rotation = self.rotation * g;
        let shift = self.shift * g;
        if !(rotation.is_finite() && shift.x.is_finite() && shift.y.is_finite()) {
            return *correction;
        }
        let (s, c) = rotation.sin_cos();
        let rel = Vector::new(correction.x - pivot.x, correction.y - pivot.y);
        let turned = Vector::new(c * rel.x - s * rel.y, s * rel.x + c * rel.y);
        Pose::new(
            pivot.x + turned.x + shift.x,
            pivot.y + turned.y + shift.y,
            correction.theta + rotation,
        )
    }
}

/// The pose in the map frame of a cart whose odometry reads `odometry`, under `correction`.
pub fn corrected(correction: &Pose, odometry: &Pose) -> Pose {
    correction.compose(*odometry)
}

/// A point given in the frame of correction `from` (placed with it), in the frame of
/// correction `to`: back to the odometry frame, then out with `to`.
pub fn reframe(point: Point, from: &Pose, to: &Pose) -> Point {
    Reframe::new(from, to).apply(point)
}

/// [`reframe`] between two corrections for many points (the echoes of one scan): the two
/// transforms, a sine and a cosine each, are made once instead of for every point. The
/// points come out exactly as [`reframe`]'s.
#[derive(Clone, Copy, Debug)]
pub struct Reframe {
    from: nalgebra::Isometry2<f64>,
    to: nalgebra::Isometry2<f64>,
}

impl Reframe {
    /// From correction `from`'s frame to correction `to`'s.
    pub fn new(from: &Pose, to: &Pose) -> Reframe {
        Reframe {
            from: from.isometry(),
            to: to.isometry(),
        }
    }

    /// `point`, given in `from`'s frame, in `to`'s.
    pub fn apply(&self, point: Point) -> Point {
        let odometry = self.from.inverse_transform_point(&point);
        self.to * odometry
    }
}

/// `a - b` for undirected lines: in (-π/2, π/2].
fn line_angle_difference(a: f64, b: f64) -> f64 {
    let d = wrap_angle(a - b);
    if d > FRAC_PI_2 {
        d - std::f64::consts::PI
    } else if d <= -FRAC_PI_2 {
        d + std::f64::consts::PI
    } else {
        d
    }
}

/// The map wall `segment` lies on, if exactly one fits (see [`LocalizeParams`]).
pub fn match_segment(
    segment: &Segment,
    map: &[Segment],
    params: &LocalizeParams,
) -> Option<WallMatch> {
    let length = segment.length();
    if !(length.is_finite() && length >= params.min_length) {
        return None;
    }
    let mid = segment.midpoint();
    let mut candidates: Vec<WallMatch> = map
        .iter()
        .filter_map(|wall| {
            let line = Line::of_segment(wall)?;
            let angle_error = line_angle_difference(line.angle(), segment.angle());
            if angle_error.abs() > params.max_angle {
                return None;
            }
            let span = wall.length();
            let inside = |p: Point| {
                let t = line.project(p);
                t >= params.end_margin && t <= span - params.end_margin
            };
            if !(inside(segment.a) && inside(segment.b)) {
                return None;
            }
            let offset = -line.signed_distance(mid);
            (offset.abs() <= params.max_offset).then_some(WallMatch {
                segment: *segment,
                wall: *wall,
                angle_error,
                offset,
            })
        })
        .collect();
    candidates.sort_by(|a, b| a.offset.abs().total_cmp(&b.offset.abs()));
    let best = *candidates.first()?;
    let rival = candidates.iter().skip(1).find(|c| {
        // the same line continued (a polyline's next edge) is no rival
        let same_line = Line::of_segment(&c.wall)
            .is_some_and(|l| l.distance(best.wall.a) < 1e-6 && l.distance(best.wall.b) < 1e-6);
        !same_line && c.offset.abs() - best.offset.abs() < params.ambiguity
    });
    rival.is_none().then_some(best)
}

/// Every segment that matches a map wall.
pub fn match_walls(
    segments: &[Segment],
    map: &[Segment],
    params: &LocalizeParams,
) -> Vec<WallMatch> {
    segments
        .iter()
        .filter_map(|s| match_segment(s, map, params))
        .collect()
}

/// Measure the error of the correction the `segments` were placed with: the rotation about
/// `pivot` (the cart's position) and the shift that put the matched segments on their walls
/// (length-weighted least squares). `None` when no segment matches a wall.
pub fn localize(
    segments: &[Segment],
    map: &[Segment],
    pivot: Point,
    params: &LocalizeParams,
) -> Option<Fix> {
    if !(pivot.x.is_finite() && pivot.y.is_finite()) {
        return None;
    }
    let matches = match_walls(segments, map, params);
    let weight = |m: &WallMatch| m.segment.length();
    let total: f64 = matches.iter().map(weight).sum();
    if matches.is_empty() || !(total > 0.0 && total.is_finite()) {
        return None;
    }
    // the heading only from segments long enough for a precise direction
    let long = || {
        matches
            .iter()
            .filter(|m| m.segment.length() >= params.min_turn_length)
    };
    let long_total: f64 = long().map(weight).sum();
    let rotation = if long_total > 0.0 {
        long().map(|m| m.angle_error * weight(m)).sum::<f64>() / long_total
    } else {
        0.0
    };
    let (s, c) = rotation.sin_cos();
    let turn = |p: Point| {
        let r = p - pivot;
        pivot + Vector::new(c * r.x - s * r.y, s * r.x + c * r.y)
    };
    // normal equations of Σ w (n·t - d)², d the offset left after the rotation
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for m in &matches {
        let Some(line) = Line::of_segment(&m.wall) else {
            continue;
        };
        let n = line.normal();
        let d = -line.signed_distance(turn(m.segment.midpoint()));
        let w = weight(m);
        a11 += w * n.x * n.x;
        a12 += w * n.x * n.y;
        a22 += w * n.y * n.y;
        b1 += w * d * n.x;
        b2 += w * d * n.y;
    }
    // eigen-decomposition of the symmetric 2 × 2 matrix: solve only along the directions
    // the walls constrain
    let mean = (a11 + a22) / 2.0;
    let spread = (((a11 - a22) / 2.0).powi(2) + a12 * a12).sqrt();
    let theta = 0.5 * (2.0 * a12).atan2(a11 - a22);
    let axes = [
        (mean + spread, Vector::new(theta.cos(), theta.sin())),
        (mean - spread, Vector::new(-theta.sin(), theta.cos())),
    ];
    let mut shift = Vector::zeros();
    let mut constrained = 0;
    for (lambda, v) in axes {
        if lambda >= params.min_support && lambda.is_finite() {
            shift += v * ((v.x * b1 + v.y * b2) / lambda);
            constrained += 1;
        }
    }
    let fix = Fix {
        rotation,
        shift,
        matched: matches.len(),
        constrained,
    };
    (fix.rotation.is_finite() && fix.shift.x.is_finite() && fix.shift.y.is_finite()).then_some(fix)
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Rng;
    use super::*;

    fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Segment {
        Segment::new(Point::new(ax, ay), Point::new(bx, by))
    }

    /// The lab's docking wall and the room around it.
    fn lab() -> Vec<Segment> {
        let pts = [
            (0.0, 0.0),
            (4.0, 0.0),
            (4.0, -0.8),
            (6.8, -0.8),
            (6.8, 0.0),
            (14.0, 0.0),
            (14.0, 6.0),
            (0.0, 6.0),
            (0.0, 0.0),
        ];
        pts.windows(2)
            .map(|w| seg(w[0].0, w[0].1, w[1].0, w[1].1))
            .collect()
    }

    /// Move the true segments into a frame that is off by `error` (the drifted odometry's
    /// view of them), about `pivot`.
    fn drifted(segs: &[Segment], error: &Fix, pivot: Point) -> Vec<Segment> {
        segs.iter()
            .map(|s| {
                let f = |p: Point| {
                    let c = error.apply(&Pose::new(p.x, p.y, 0.0), pivot, 1.0);
                    Point::new(c.x, c.y)
                };
                Segment::new(f(s.a), f(s.b))
            })
            .collect()
    }

    #[test]
    fn one_wall_fixes_heading_and_offset_but_not_the_position_along_it() {
        let map = lab();
        let pivot = Point::new(10.0, 1.0);
        let truth = [seg(11.0, 0.0, 9.0, 0.0)];
        let error = Fix {
            rotation: 0.05,
            shift: Vector::new(0.3, 0.1),
            matched: 0,
            constrained: 0,
        };
        let seen = drifted(&truth, &error, pivot);
        let fix = localize(&seen, &map, pivot, &LocalizeParams::default()).unwrap();
        assert_eq!((fix.matched, fix.constrained), (1, 1));
        assert!((fix.rotation + 0.05).abs() < 1e-9, "{fix:?}");
        assert!(fix.shift.x.abs() < 1e-9, "along the wall: unknown, {fix:?}");
        // the fix puts the seen wall back on the map's
        let back = drifted(&seen, &fix, pivot);
        assert!(
            back[0].a.y.abs() < 1e-9 && back[0].b.y.abs() < 1e-9,
            "{back:?}"
        );
    }

    #[test]
    fn two_walls_fix_the_whole_pose() {
        let map = lab();
        let pivot = Point::new(12.5, 1.0);
        let truth = [seg(13.0, 0.0, 11.0, 0.0), seg(14.0, 0.5, 14.0, 2.0)];
        let error = Fix {
            rotation: -0.04,
            shift: Vector::new(-0.2, 0.15),
            matched: 0,
            constrained: 0,
        };
        let seen = drifted(&truth, &error, pivot);
        let fix = localize(&seen, &map, pivot, &LocalizeParams::default()).unwrap();
        assert_eq!((fix.matched, fix.constrained), (2, 2));
        // applying the fix to a correction that carries the error undoes it
        let wrong = error.apply(&Pose::default(), pivot, 1.0);
        let right = fix.apply(&wrong, pivot, 1.0);
        assert!(
            right.x.abs() < 1e-9 && right.y.abs() < 1e-9 && right.theta.abs() < 1e-9,
            "{right:?}"
        );
    }

    #[test]
    fn the_recess_back_wall_is_not_taken_for_the_wall_line() {
        let map = lab();
        // seen 0.3 m too deep: still the back wall at -0.8, not the line at 0
        let m =
            match_segment(&seg(6.5, -1.1, 4.3, -1.1), &map, &LocalizeParams::default()).unwrap();
        assert!(
            (m.wall.a.y + 0.8).abs() < 1e-12 && (m.offset - 0.3).abs() < 1e-9,
            "{m:?}"
        );
        // half-way between: ambiguous or too far, never matched
        assert!(
            match_segment(&seg(6.5, -0.4, 4.3, -0.4), &map, &LocalizeParams::default()).is_none()
        );
    }

    #[test]
    fn crossing_short_and_far_segments_do_not_match() {
        let map = lab();
        let p = LocalizeParams::default();
        assert!(
            match_segment(&seg(9.0, 0.0, 9.0, 2.0), &map, &p).is_none(),
            "crossing"
        );
        assert!(
            match_segment(&seg(9.0, 0.0, 9.2, 0.0), &map, &p).is_none(),
            "short"
        );
        assert!(
            match_segment(&seg(9.0, 1.0, 11.0, 1.0), &map, &p).is_none(),
            "far"
        );
        assert!(
            match_segment(&seg(20.0, 0.0, 22.0, 0.0), &map, &p).is_none(),
            "beyond the end"
        );
        assert!(localize(&[], &map, Point::new(1.0, 1.0), &p).is_none());
    }

    #[test]
    fn a_reframe_made_once_moves_points_exactly_as_reframe_does() {
        let (from, to) = (Pose::new(0.3, -1.2, 0.71), Pose::new(-0.05, 0.4, -2.3));
        let frame = Reframe::new(&from, &to);
        for i in 0..50 {
            let p = Point::new(i as f64 * 0.37 - 4.0, 1.0 / (i as f64 + 0.5));
            // bit for bit: the run's outcome must not change
            assert_eq!(frame.apply(p), reframe(p, &from, &to), "{p:?}");
        }
    }

    #[test]
    fn a_gain_applies_part_of_the_fix() {
        let fix = Fix {
            rotation: 0.1,
            shift: Vector::new(0.2, 0.0),
            matched: 1,
            constrained: 1,
        };
        let c = fix.apply(&Pose::default(), Point::new(0.0, 0.0), 0.5);
        assert!((c.theta - 0.05).abs() < 1e-12 && (c.x - 0.1).abs() < 1e-12);
        assert_eq!(
            fix.apply(&Pose::default(), Point::new(0.0, 0.0), f64::NAN),
            Pose::default()
        );
        let cut = fix.limited(0.01, 0.05);
        assert!((cut.rotation - 0.01).abs() < 1e-12 && (cut.shift.norm() - 0.05).abs() < 1e-12);
        assert_eq!(fix.limited(f64::NAN, f64::INFINITY), fix);
    }

    #[test]
    fn reframing_moves_points_between_corrections() {
        let a = Pose::new(1.0, 0.0, 0.0);
        let b = Pose::new(0.0, 0.0, FRAC_PI_2);
        // odometry point (1, 0): at (2, 0) under a, at (0, 1) under b
        let q = reframe(Point::new(2.0, 0.0), &a, &b);
        assert!((q - Point::new(0.0, 1.0)).norm() < 1e-12, "{q}");
        let p = corrected(&a, &Pose::new(1.0, 0.0, 0.3));
        assert!((p.x - 2.0).abs() < 1e-12 && (p.theta - 0.3).abs() < 1e-12);
    }

    #[test]
    fn no_panic_on_any_input() {
        let mut rng = Rng::new(11);
        let map = lab();
        let junk = [f64::NAN, f64::INFINITY, -f64::INFINITY, 0.0, 1e300, -1e-300];
        for _ in 0..2000 {
            let mut v = || {
                if rng.uniform() < 0.2 {
                    junk[(rng.uniform() * junk.len() as f64) as usize % junk.len()]
                } else {
                    rng.uniform() * 20.0 - 3.0
                }
            };
            let segs: Vec<Segment> = (0..3).map(|_| seg(v(), v(), v(), v())).collect();
            let pivot = Point::new(v(), v());
            if let Some(fix) = localize(&segs, &map, pivot, &LocalizeParams::default()) {
                assert!(
                    fix.rotation.is_finite() && fix.shift.x.is_finite() && fix.shift.y.is_finite()
                );
                let _ = fix.apply(&Pose::new(v(), v(), v()), pivot, v());
            }
            let _ = localize(&map, &segs, pivot, &LocalizeParams::default());
        }
    }
}

//! Docking-spot detection (the docking-spot detector's algorithm).
//!
//! A docking spot is a rectangular **recess in the followed wall**:
//!
//! - **breadth** is the width of the opening, measured *along* the wall (the lab's spot:
//!   2.80 m);
//! - **depth** is how far the recess reaches *behind* the wall line, to its back wall, which is
//!   parallel to the wall (the lab's spot: 0.80 m).
//!
//! The 1.0 m × 0.6 m cart parks in it lengthwise, parallel to the wall: 1.0 m of cart in
//! 2.80 m of opening and 0.6 m of cart in 0.80 m of depth.
//!
//! Detection works in the wall's frame (s along the wall line, t behind it). Points within
//! [`DockParams::wall_band`] of the line are *wall points*; sorted along the line, they form
//! pieces of wall (consecutive points at most [`DockParams::wall_spacing`] apart, at least
//! [`DockParams::min_wall_points`] of them — stray echoes in an opening are not wall). A gap
//! between consecutive pieces is a candidate opening when its width is `breadth` within
//! [`DockParams::breadth_tolerance`]. The candidate is a docking spot only if behind the
//! opening there are at least [`DockParams::min_back_points`] points at `depth` within
//! [`DockParams::depth_tolerance`], spanning [`DockParams::min_back_coverage`] of the opening,
//! and the space between the opening and the back wall is not cluttered (an occupied spot).
//! Both dimensions are checked against the parameters, so the detector is as sensitive to them
//! as the thesis' one (4.6.1.2, 9.3.2): a breadth or depth off by more than its tolerance and
//! the cart drives past the spot. Among several matching openings the best match wins
//! (smallest breadth and depth errors relative to their tolerances).
//!
//! Wide-beam sonars see the corners of the opening before and after it, which shrinks the
//! measured breadth by about 2·d·tan(half beam angle) at wall distance d (0.32 m for ±15° at
//! 0.6 m) — more than the default tolerance: feed narrow-beam points, or state the breadth
//! the sensors will see.

use super::segments::Line;
use super::wall::WallEstimate;
use crate::geom::{Point, Pose, Segment, Vector};
use serde::{Deserialize, Serialize};

/// Parameters of the docking-spot detector.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DockParams {
    /// Width of the opening along the wall, metres. Default 2.80.
    pub breadth: f64,
    /// Depth of the recess behind the wall line, metres. Default 0.80.
    pub depth: f64,
    /// Accepted |measured − `breadth`|, metres. Default 0.20.
    pub breadth_tolerance: f64,
    /// Accepted |measured − `depth`|, metres. Default 0.12.
    pub depth_tolerance: f64,
    /// Points within this distance of the wall line are wall points, metres. Default 0.10.
    pub wall_band: f64,
    /// Wall points closer than this (along the wall) belong to one piece of wall, metres;
    /// must exceed the sonar's point spacing along the wall (speed / sampling rate).
    /// Default 0.15.
    pub wall_spacing: f64,
    /// Fewest points a piece of wall needs; smaller pieces (stray echoes inside an opening)
    /// are ignored. Default 3.
    pub min_wall_points: usize,
    /// Fewest back-wall points behind an opening. Default 5.
    pub min_back_points: usize,
    /// Fraction of the opening the back-wall points must span, in [0, 1]. Default 0.5.
    pub min_back_coverage: f64,
    /// Margin at each end of the opening ignored by the clutter check (the recess' side walls
    /// are seen there), metres. Default 0.25.
    pub edge_margin: f64,
    /// Largest number of points inside the recess (between the wall line and the back wall),
    /// as a fraction of the back-wall points, before the spot counts as occupied. Default 0.3.
    pub max_clutter: f64,
    /// Spacing of the points sampled along segments by [`detect_dock_in_segments`], metres.
    /// Default 0.05.
    pub sample_step: f64,
}

impl Default for DockParams {
    fn default() -> Self {
        DockParams {
            breadth: 2.80,
            depth: 0.80,
            breadth_tolerance: 0.20,
            depth_tolerance: 0.12,
            wall_band: 0.10,
            wall_spacing: 0.15,
            min_wall_points: 3,
            min_back_points: 5,
            min_back_coverage: 0.5,
            edge_margin: 0.25,
            max_clutter: 0.3,
            sample_step: 0.05,
        }
    }
}

/// A detected docking spot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Dock {
    /// Centre of the parking rectangle (mid-opening, half the measured depth behind the wall
    /// line), with the heading a parked cart should have: along the wall line's direction.
    pub pose: Pose,
    /// The opening, on the wall line, in the line's direction.
    pub opening: Segment,
    /// The seen part of the back wall.
    pub back: Segment,
    /// Measured breadth (opening width), metres.
    pub breadth: f64,
    /// Measured depth (median distance of the back-wall points behind the wall line), metres.
    pub depth: f64,
    /// Number of back-wall points.
    pub back_points: usize,
}

impl Dock {
    /// The pose of the cart's reference point (rear axle) that puts the cart's centre at the
    /// dock centre: `axle_to_centre` metres behind it along the parking heading.
    pub fn reference_pose(&self, axle_to_centre: f64) -> Pose {
        let h = self.pose.heading();
        Pose::new(
            self.pose.x - h.x * axle_to_centre,
            self.pose.y - h.y * axle_to_centre,
            self.pose.theta,
        )
    }
}

/// Look for a docking spot in the followed `wall`, among sonar `points` (world frame).
/// The recess is searched on the far side of the wall from the cart.
pub fn detect_dock(wall: &WallEstimate, points: &[Point], params: &DockParams) -> Option<Dock> {
    detect_dock_on_line(&wall.line, wall.normal, points, params)
}

/// Like [`detect_dock`], with the sensed scene given as segments (sampled every
/// [`DockParams::sample_step`]).
pub fn detect_dock_in_segments(
    wall: &WallEstimate,
    segments: &[Segment],
    params: &DockParams,
) -> Option<Dock> {
    let step = if params.sample_step.is_finite() && params.sample_step > 1e-3 {
        params.sample_step
    } else {
        0.05
    };
    let mut points = Vec::new();
    for s in segments {
        let len = s.length();
        if !len.is_finite() {
            continue;
        }
        let n = ((len / step).ceil() as usize).clamp(1, 100_000);
        for i in 0..=n {
            points.push(s.a + (s.b - s.a) * (i as f64 / n as f64));
        }
    }
    detect_dock_on_line(&wall.line, wall.normal, &points, params)
}

/// The core: the wall's line as `line` (its direction becomes the parking heading),
/// `into_wall` any vector pointing from the free side through the wall (towards the recess).
/// `None` for a degenerate line or direction, or when no spot matches.
pub fn detect_dock_on_line(
    line: &Segment,
    into_wall: Vector,
    points: &[Point],
    params: &DockParams,
) -> Option<Dock> {
    let l = Line::of_segment(line)?;
    let side = l.normal().dot(&into_wall);
    if side.is_nan() || side.abs() <= 1e-12 {
        return None;
    }
    let n = if side > 0.0 { l.normal() } else { -l.normal() };
    let st: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .map(|p| (l.project(*p), (*p - l.point).dot(&n)))
        .collect();
    let band = params.wall_band.max(0.0);
    let tol_b = params.breadth_tolerance.max(0.0);
    let tol_d = params.depth_tolerance.max(0.0);
    let mut wall_s: Vec<f64> = st
        .iter()
        .filter(|(_, t)| t.abs() <= band)
        .map(|(s, _)| *s)
        .collect();
    wall_s.sort_by(|a, b| a.total_cmp(b));
    // Pieces of wall (first and last s of each), without stray echoes.
    let mut pieces: Vec<(f64, f64)> = Vec::new();
    let mut i = 0;
    while i < wall_s.len() {
        let mut j = i;
        while j + 1 < wall_s.len() && wall_s[j + 1] - wall_s[j] <= params.wall_spacing {
            j += 1;
        }
        if j + 1 - i >= params.min_wall_points.max(1) {
            pieces.push((wall_s[i], wall_s[j]));
        }
        i = j + 1;
    }

    let mut best: Option<(f64, Dock)> = None;
    for w in pieces.windows(2) {
        let (s0, s1) = (w[0].1, w[1].0);
        let gap = s1 - s0;
        if gap.is_nan() || gap <= 0.0 || (gap - params.breadth).abs() > tol_b {
            continue;
        }
        let mut back: Vec<(f64, f64)> = st
            .iter()
            .copied()
            .filter(|(s, t)| *s > s0 && *s < s1 && (t - params.depth).abs() <= tol_d)
            .collect();
        if back.len() < params.min_back_points.max(1) {
            continue;
        }
        let (bmin, bmax) = back
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (s, _)| {
                (lo.min(*s), hi.max(*s))
            });
        if bmax - bmin < params.min_back_coverage.clamp(0.0, 1.0) * gap {
            continue;
        }
        back.sort_by(|a, b| a.1.total_cmp(&b.1));
        let depth = back[back.len() / 2].1;
        let (i0, i1) = (s0 + params.edge_margin, s1 - params.edge_margin);
        let clutter = st
            .iter()
            .filter(|(s, t)| *s > i0 && *s < i1 && *t > band && *t < depth - tol_d)
            .count();
        if clutter as f64 > params.max_clutter.max(0.0) * back.len() as f64 {
            continue;
        }
        let score = (gap - params.breadth).abs() / tol_b.max(1e-9)
            + (depth - params.depth).abs() / tol_d.max(1e-9);
        let mid = l.at(0.5 * (s0 + s1));
        let centre = mid + n * (0.5 * depth);
        let dock = Dock {
            pose: Pose::new(centre.x, centre.y, l.angle()),
            opening: Segment::new(l.at(s0), l.at(s1)),
            back: Segment::new(l.at(bmin) + n * depth, l.at(bmax) + n * depth),
            breadth: gap,
            depth,
            back_points: back.len(),
        };
        if best.as_ref().is_none_or(|(b, _)| score < *b) {
            best = Some((score, dock));
        }
    }
    best.map(|(_, d)| d)
}

/// Largest angle between a detected dock's back wall and the map wall taken for it, radians.
const MAP_MATCH_ANGLE: f64 = 0.1;

/// Largest distance (m) between a detected dock's back wall and the line of the map wall
/// taken for it.
const MAP_MATCH_OFFSET: f64 = 0.3;

/// Largest difference (m) between the detected breadth and the length of that map wall.
const MAP_MATCH_BREADTH: f64 = 0.5;

/// Largest distance (m) along the wall between the detected dock and the map's recess: more
/// than the odometry drifts along a wall that nothing across it pins down.
const MAP_MATCH_ALONG: f64 = 1.0;

/// Where the map's recess lies from a dock detected at `corners` (opening first, then the back
/// wall's ends) of `breadth`, along the wall: the vector to move the
/// detected dock by to put it on the map's recess, the same map wall's back wall (parallel,
/// near, of the dock's breadth). `None` unless exactly one map wall fits.
///
/// Along a straight wall the localizer fixes only the offset across it; the position along it
/// is the odometry's, which drifts by a percent of the distance driven. The docking spot's
/// ends are the one landmark along the wall the sonars have measured: the detected dock is
/// where the recess is *as the cart sees it*, so the map moved back by this vector is the map
/// as the cart's pose sees it — what a manoeuvre that must clear the spot's edges by a few
/// centimetres has to be checked against.
pub fn offset_to_map(corners: &[Point; 4], breadth: f64, map: &[Segment]) -> Option<Vector> {
    let along = (corners[1] - corners[0]).try_normalize(1e-9)?;
    let back = Segment::new(corners[3], corners[2]);
    let opening_mid = Point::from((corners[0].coords + corners[1].coords) / 2.0);
    let back_mid = back.midpoint();
    let mut fits = map.iter().filter_map(|wall| {
        let dir = (wall.b - wall.a).try_normalize(1e-9)?;
        let parallel = dir.dot(&along).abs() >= MAP_MATCH_ANGLE.cos();
        let line = Line::of_segment(wall)?;
        let near = line.distance(back_mid) <= MAP_MATCH_OFFSET;
        let sized = (wall.length() - breadth).abs() <= MAP_MATCH_BREADTH;
        let shift = (wall.midpoint() - opening_mid).dot(&along);
        (parallel && near && sized && shift.abs() <= MAP_MATCH_ALONG).then_some(along * shift)
    });
    let first = fits.next()?;
    fits.next().is_none().then_some(first)
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Rng;
    use super::*;

    #[test]
    fn a_dock_seen_off_along_the_wall_is_put_on_the_maps_recess() {
        // the lab: a recess at x 4.0-6.8, 0.8 deep, in the wall y = 0
        let map = [
            Segment::new(Point::new(0.0, 0.0), Point::new(4.0, 0.0)),
            Segment::new(Point::new(4.0, 0.0), Point::new(4.0, -0.8)),
            Segment::new(Point::new(4.0, -0.8), Point::new(6.8, -0.8)),
            Segment::new(Point::new(6.8, -0.8), Point::new(6.8, 0.0)),
            Segment::new(Point::new(6.8, 0.0), Point::new(14.0, 0.0)),
        ];
        // seen 0.2 m too far west (and 3 cm shallow), driving west
        let seen = [
            Point::new(6.6, 0.0),
            Point::new(3.8, 0.0),
            Point::new(3.8, -0.77),
            Point::new(6.6, -0.77),
        ];
        let v = offset_to_map(&seen, 2.8, &map).expect("the recess");
        assert!((v.x - 0.2).abs() < 1e-9 && v.y.abs() < 1e-9, "{v:?}");
        // a dock nowhere near the map's recess, or of another size: no landmark
        let far: Vec<Point> = seen.iter().map(|p| p - Vector::new(2.0, 0.0)).collect();
        assert_eq!(
            offset_to_map(&[far[0], far[1], far[2], far[3]], 2.8, &map),
            None
        );
        assert_eq!(offset_to_map(&seen, 1.5, &map), None);
    }

    /// Points seen along a wall at y = 1 with a recess of `breadth` × `depth` at x ∈ [3, 3 + b].
    fn scene(breadth: f64, depth: f64, rng: &mut Rng) -> Vec<Point> {
        let mut pts = Vec::new();
        let mut x = 0.0;
        while x < 9.0 {
            let y = if x > 3.0 && x < 3.0 + breadth {
                1.0 + depth
            } else {
                1.0
            };
            pts.push(Point::new(x, y + rng.gauss(0.015)));
            x += 0.04;
        }
        pts
    }

    fn line() -> Segment {
        Segment::new(Point::new(0.0, 1.0), Point::new(9.0, 1.0))
    }

    #[test]
    fn finds_the_lab_spot() {
        let mut rng = Rng::new(9);
        let pts = scene(2.8, 0.8, &mut rng);
        let d = detect_dock_on_line(&line(), Vector::new(0.0, 1.0), &pts, &DockParams::default())
            .expect("dock");
        assert!((d.pose.x - 4.4).abs() < 0.05, "{d:?}");
        assert!((d.pose.y - 1.4).abs() < 0.03);
        assert!(d.pose.theta.abs() < 1e-9);
        assert!((d.breadth - 2.8).abs() < 0.1 && (d.depth - 0.8).abs() < 0.03);
        let r = d.reference_pose(0.35);
        assert!((r.x - 4.05).abs() < 0.05);
    }

    #[test]
    fn sensitive_to_both_dimensions() {
        let mut rng = Rng::new(10);
        let pts = scene(2.8, 0.8, &mut rng);
        let into = Vector::new(0.0, 1.0);
        for (b, d) in [(3.64, 0.8), (1.96, 0.8), (2.8, 1.04), (2.8, 0.56)] {
            let p = DockParams {
                breadth: b,
                depth: d,
                ..DockParams::default()
            };
            assert!(
                detect_dock_on_line(&line(), into, &pts, &p).is_none(),
                "{b} {d}"
            );
        }
        // Looking on the wrong side of the wall finds nothing either.
        assert!(detect_dock_on_line(&line(), -into, &pts, &DockParams::default()).is_none());
    }

    #[test]
    fn occupied_spot_is_rejected() {
        let mut rng = Rng::new(11);
        let mut pts = scene(2.8, 0.8, &mut rng);
        for i in 0..30 {
            pts.push(Point::new(3.8 + i as f64 * 0.03, 1.3));
        }
        assert!(
            detect_dock_on_line(&line(), Vector::new(0.0, 1.0), &pts, &DockParams::default())
                .is_none()
        );
    }

    #[test]
    fn degenerate_inputs() {
        let p = DockParams::default();
        let deg = Segment::new(Point::origin(), Point::origin());
        assert!(detect_dock_on_line(&deg, Vector::new(0.0, 1.0), &[], &p).is_none());
        assert!(detect_dock_on_line(&line(), Vector::zeros(), &[], &p).is_none());
        assert!(detect_dock_on_line(&line(), Vector::new(0.0, 1.0), &[], &p).is_none());
    }
}

//! Wall sensing: pick "the wall" among extracted segments, as seen from the cart.
//!
//! Segments are grouped into collinear sets (directions within [`WallParams::merge_angle`],
//! each one's midpoint within [`WallParams::merge_offset`] of the other's line), so a wall
//! broken by a doorway or a docking spot stays one wall. Among the sets near the cart (some
//! member within [`WallParams::max_distance`]), on the requested side and within the angle
//! limit, the one with the largest total length wins if it is at least
//! [`WallParams::min_length`] long. Its line is a length-weighted total-least-squares fit of
//! the members' end points.

use super::segments::{line_angle_between, Line};
use crate::geom::{wrap_angle, Point, Pose, Segment, Vector};
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;

/// Which side of the cart (relative to its heading) a wall is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Side {
    /// To the left of the heading.
    Left,
    /// To the right of the heading.
    Right,
}

impl Side {
    /// +1 for left, −1 for right.
    pub fn sign(self) -> f64 {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }

    /// The other side.
    pub fn opposite(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
}

/// Parameters of the wall sensor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallParams {
    /// A wall must have a segment within this distance of the cart, metres. Default 2.5.
    pub max_distance: f64,
    /// Shortest total length (sum of its segments) of a wall, metres. Default 0.5.
    pub min_length: f64,
    /// Largest angle between segments of one wall, radians. Default 0.1.
    pub merge_angle: f64,
    /// Largest perpendicular offset between segments of one wall, metres. Default 0.1.
    pub merge_offset: f64,
    /// Only walls whose direction is within this angle of the cart's heading, radians in
    /// [0, π/2]. Default π/2 (any wall).
    pub max_angle: f64,
    /// Only walls on this side; `None` (default) takes either.
    pub side: Option<Side>,
}

impl Default for WallParams {
    fn default() -> Self {
        WallParams {
            max_distance: 2.5,
            min_length: 0.5,
            merge_angle: 0.1,
            merge_offset: 0.1,
            max_angle: FRAC_PI_2,
            side: None,
        }
    }
}

/// The wall, as seen from the cart.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallEstimate {
    /// The wall's extent on its fitted line, oriented along the cart's heading
    /// (`(b − a) · heading ≥ 0`). It may span openings between collinear segments.
    pub line: Segment,
    /// Perpendicular distance from the cart's reference point to the wall's line, metres.
    pub distance: f64,
    /// Direction of the wall relative to the cart's heading, radians in (−π/2, π/2]:
    /// positive when the wall turns counter-clockwise from the heading.
    pub angle: f64,
    /// The side of the cart the wall is on.
    pub side: Side,
    /// Unit normal (world frame) pointing from the cart towards the wall.
    pub normal: Vector,
    /// Sum of the lengths of the supporting segments, metres (gaps excluded).
    pub length: f64,
    /// Number of supporting segments.
    pub segments: usize,
}

/// Find the wall among `segments` as seen from `pose`; `None` when no wall qualifies.
pub fn sense_wall(segments: &[Segment], pose: &Pose, params: &WallParams) -> Option<WallEstimate> {
    let segs: Vec<(Segment, Line)> = segments
        .iter()
        .filter_map(|s| Line::of_segment(s).map(|l| (*s, l)))
        .collect();
    let groups = group_collinear(&segs, params);
    let me = pose.point();
    let mut best: Option<WallEstimate> = None;
    for group in groups {
        let near = group
            .iter()
            .map(|&i| segs[i].0.distance_to(me))
            .fold(f64::INFINITY, f64::min);
        if near.is_nan() || params.max_distance.is_nan() || near > params.max_distance {
            continue;
        }
        let Some(est) = estimate(&segs, &group, pose) else {
            continue;
        };
        if est.length < params.min_length || est.angle.abs() > params.max_angle + 1e-12 {
            continue;
        }
        if params.side.is_some_and(|s| s != est.side) {
            continue;
        }
        let better = match &best {
            None => true,
            Some(b) => {
                est.length > b.length + 1e-9
                    || ((est.length - b.length).abs() <= 1e-9 && est.distance < b.distance)
            }
        };
        if better {
            best = Some(est);
        }
    }
    best
}

/// Union–find grouping of collinear segments.
fn group_collinear(segs: &[(Segment, Line)], params: &WallParams) -> Vec<Vec<usize>> {
    let n = segs.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let (si, li) = &segs[i];
            let (sj, lj) = &segs[j];
            let collinear = line_angle_between(li, lj) <= params.merge_angle
                && li.distance(sj.midpoint()) <= params.merge_offset
                && lj.distance(si.midpoint()) <= params.merge_offset;
            if collinear {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                if ri != rj {
                    parent[rj] = ri;
                }
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut index_of_root: Vec<Option<usize>> = vec![None; n];
    for i in 0..n {
        let r = root(&mut parent, i);
        match index_of_root[r] {
            Some(g) => groups[g].push(i),
            None => {
                index_of_root[r] = Some(groups.len());
                groups.push(vec![i]);
            }
        }
    }
    groups
}

fn estimate(segs: &[(Segment, Line)], group: &[usize], pose: &Pose) -> Option<WallEstimate> {
    let mut weighted: Vec<(Point, f64)> = Vec::with_capacity(group.len() * 2);
    let mut length = 0.0;
    for &i in group {
        let s = &segs[i].0;
        let l = s.length();
        length += l;
        weighted.push((s.a, l));
        weighted.push((s.b, l));
    }
    let mut line = Line::fit_weighted(&weighted)?;
    let heading = pose.heading();
    if line.direction.dot(&heading) < 0.0 {
        line = line.reversed();
    }
    let (mut tmin, mut tmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for (p, _) in &weighted {
        let t = line.project(*p);
        tmin = tmin.min(t);
        tmax = tmax.max(t);
    }
    let me = pose.point();
    // Positive when the wall's line passes to the left of the cart.
    let foot = line.at(line.project(me));
    let to_wall = foot - me;
    let distance = to_wall.norm();
    let side_sign = heading.perp(&to_wall);
    let side = if side_sign < 0.0 {
        Side::Right
    } else {
        Side::Left
    };
    let normal = if distance > 1e-12 {
        to_wall / distance
    } else {
        let left = Vector::new(-heading.y, heading.x);
        left * side.sign()
    };
    let mut angle = wrap_angle(line.angle() - pose.theta);
    // The line is oriented along the heading, so |angle| ≤ π/2 up to rounding.
    if angle <= -FRAC_PI_2 {
        angle = FRAC_PI_2;
    }
    Some(WallEstimate {
        line: Segment::new(line.at(tmin), line.at(tmax)),
        distance,
        angle: angle.clamp(-FRAC_PI_2, FRAC_PI_2),
        side,
        normal,
        length,
        segments: group.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Segment {
        Segment::new(Point::new(ax, ay), Point::new(bx, by))
    }

    #[test]
    fn longest_collinear_set_wins() {
        // A wall at y = 1 broken by an opening, and a longer far wall at y = -5.
        let segs = [
            seg(0.0, 1.0, 2.0, 1.0),
            seg(4.8, 1.0, 7.0, 1.0),
            seg(0.0, -5.0, 9.0, -5.0),
            seg(2.0, 1.8, 4.8, 1.8),
        ];
        let pose = Pose::new(3.0, 0.4, 0.05);
        let w = sense_wall(&segs, &pose, &WallParams::default()).unwrap();
        assert_eq!(w.segments, 2);
        assert_eq!(w.side, Side::Left);
        assert!((w.distance - 0.6).abs() < 1e-9);
        assert!((w.angle + 0.05).abs() < 1e-9);
        assert!((w.length - 4.2).abs() < 1e-9);
        assert!((w.normal - Vector::new(0.0, 1.0)).norm() < 1e-9);
        assert!(w.line.b.x > w.line.a.x);
    }

    #[test]
    fn side_filter_and_reverse_heading() {
        let segs = [seg(0.0, 1.0, 5.0, 1.0), seg(0.0, -1.0, 3.0, -1.0)];
        let pose = Pose::new(2.0, 0.0, std::f64::consts::PI);
        let w = sense_wall(&segs, &pose, &WallParams::default()).unwrap();
        // Facing −x, the y = 1 wall is on the right.
        assert_eq!(w.side, Side::Right);
        assert!(w.line.b.x < w.line.a.x);
        let p = WallParams {
            side: Some(Side::Left),
            ..WallParams::default()
        };
        let w = sense_wall(&segs, &pose, &p).unwrap();
        assert!((w.line.a.y + 1.0).abs() < 1e-9);
    }

    #[test]
    fn no_wall_when_too_far_short_or_absent() {
        let pose = Pose::new(0.0, 0.0, 0.0);
        let p = WallParams::default();
        assert!(sense_wall(&[], &pose, &p).is_none());
        assert!(sense_wall(&[seg(0.0, 3.0, 5.0, 3.0)], &pose, &p).is_none());
        assert!(sense_wall(&[seg(0.0, 1.0, 0.3, 1.0)], &pose, &p).is_none());
        assert!(sense_wall(&[seg(1.0, 1.0, 1.0, 1.0)], &pose, &p).is_none());
        let ahead_only = WallParams {
            max_angle: 0.3,
            ..p
        };
        assert!(sense_wall(&[seg(1.0, -2.0, 1.0, 2.0)], &pose, &ahead_only).is_none());
    }
}

//! Line-segment extraction from 2-D sonar points (the segment extractor's algorithm).
//!
//! The points are in world coordinates and **ordered** along the scan or the cart's trajectory
//! (one sensor's stream, oldest first; interleave several sensors and every pair of
//! consecutive points looks like a gap). The extraction is split-and-merge:
//!
//! 1. **Runs.** The sequence is cut wherever consecutive points are more than
//!    [`SegmentParams::max_gap`] apart — a doorway or a docking-spot opening ends a segment.
//!    Up to [`SegmentParams::max_outlier_run`] isolated points that jump away and back are
//!    dropped as outliers instead of cutting the run; longer bursts of stray points form runs
//!    of their own, which are dropped when shorter than [`SegmentParams::min_points`], and the
//!    runs they interrupted are re-joined when their ends are within `max_gap`.
//! 2. **Split.** Each run is split recursively at the point farthest from the chord between its
//!    ends while that point is farther than [`SegmentParams::distance_threshold`]
//!    (iterative end-point fit).
//! 3. **Merge.** Neighbouring pieces are merged while a total-least-squares line through their
//!    union keeps 90 % of the points within the threshold (collinear neighbours that noise had
//!    split), and only if their directions agree within [`SegmentParams::merge_angle`].
//! 4. **Fit.** Each piece gets an orthogonal-regression (total least squares) line, refitted
//!    twice without the points farther than the threshold; the segment spans the projections
//!    of its inliers. Pieces with fewer than [`SegmentParams::min_points`] inliers or shorter
//!    than [`SegmentParams::min_length`] are discarded.

use super::safe_div;
use crate::geom::{Point, Segment, Vector};
use serde::{Deserialize, Serialize};

/// Parameters of the segment extractor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentParams {
    /// Largest perpendicular distance of a point from its segment's line, metres. Default
    /// 0.06; should be at least 2.5 × the sonar's range noise (σ).
    pub distance_threshold: f64,
    /// Fewest inlier points a segment needs. Default 6.
    pub min_points: usize,
    /// Largest distance between consecutive points of one segment, metres; larger jumps end
    /// the segment. Default 0.25.
    pub max_gap: f64,
    /// Shortest segment reported, metres. Default 0.30.
    pub min_length: f64,
    /// Largest angle between two neighbouring pieces that may be merged, radians. Default 0.1.
    pub merge_angle: f64,
    /// Most consecutive stray points skipped as outliers before a jump counts as a gap.
    /// Default 2.
    pub max_outlier_run: usize,
}

impl Default for SegmentParams {
    fn default() -> Self {
        SegmentParams {
            distance_threshold: 0.06,
            min_points: 6,
            max_gap: 0.25,
            min_length: 0.30,
            merge_angle: 0.1,
            max_outlier_run: 2,
        }
    }
}

/// An extracted segment with the quality of its fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FittedSegment {
    /// The segment, oriented in the order the points were given (`a` seen first).
    pub segment: Segment,
    /// Number of inlier points that support it.
    pub points: usize,
    /// Root-mean-square perpendicular distance of the inliers from the line, metres.
    pub rms: f64,
}

/// An infinite line: a point on it and a unit direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Line {
    /// A point on the line (for fitted lines, the centroid).
    pub point: Point,
    /// Unit direction.
    pub direction: Vector,
}

impl Line {
    /// The line through `a` and `b`; `None` when they (nearly) coincide.
    pub fn through(a: Point, b: Point) -> Option<Line> {
        let d = b - a;
        let n = d.norm();
        if !n.is_finite() || n <= 1e-12 {
            return None;
        }
        Some(Line {
            point: a,
            direction: d / n,
        })
    }

    /// The line carrying `segment`; `None` for a degenerate segment.
    pub fn of_segment(segment: &Segment) -> Option<Line> {
        Line::through(segment.a, segment.b)
    }

    /// Total-least-squares (orthogonal regression) fit; `None` for fewer than two distinct
    /// points.
    pub fn fit(points: &[Point]) -> Option<Line> {
        // the weighted fit with every weight 1 (the same arithmetic), without a weighted
        // copy of the points
        Line::fit_pairs(|| points.iter().map(|p| (*p, 1.0)))
    }

    /// Weighted total-least-squares fit (non-positive or non-finite weights are ignored);
    /// `None` when the points do not determine a line.
    pub fn fit_weighted(points: &[(Point, f64)]) -> Option<Line> {
        Line::fit_pairs(|| points.iter().copied())
    }

    /// [`Line::fit_weighted`] of the (point, weight) pairs `pairs()` yields (it is walked
    /// four times).
    fn fit_pairs<I: Iterator<Item = (Point, f64)>>(pairs: impl Fn() -> I) -> Option<Line> {
        let usable = || {
            pairs().filter(|(p, w)| w.is_finite() && *w > 0.0 && p.x.is_finite() && p.y.is_finite())
        };
        let wsum: f64 = usable().map(|(_, w)| w).sum();
        if !wsum.is_finite() || wsum <= 0.0 {
            return None;
        }
        let cx = usable().map(|(p, w)| p.x * w).sum::<f64>() / wsum;
        let cy = usable().map(|(p, w)| p.y * w).sum::<f64>() / wsum;
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for (p, w) in usable() {
            let (dx, dy) = (p.x - cx, p.y - cy);
            sxx += w * dx * dx;
            syy += w * dy * dy;
            sxy += w * dx * dy;
        }
        let spread = (sxx + syy) / wsum;
        if !spread.is_finite() || spread <= 1e-18 {
            return None;
        }
        // Principal axis of the scatter matrix.
        let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        Some(Line {
            point: Point::new(cx, cy),
            direction: Vector::new(angle.cos(), angle.sin()),
        })
    }

    /// Direction angle, radians.
    pub fn angle(&self) -> f64 {
        self.direction.y.atan2(self.direction.x)
    }

    /// Unit normal, the direction rotated +90°.
    pub fn normal(&self) -> Vector {
        Vector::new(-self.direction.y, self.direction.x)
    }

    /// Coordinate of `p`'s projection along the line (0 at [`Line::point`]).
    pub fn project(&self, p: Point) -> f64 {
        (p - self.point).dot(&self.direction)
    }

    /// Signed perpendicular distance of `p`: positive to the left of the direction.
    pub fn signed_distance(&self, p: Point) -> f64 {
        (p - self.point).dot(&self.normal())
    }

    /// Perpendicular distance of `p`.
    pub fn distance(&self, p: Point) -> f64 {
        self.signed_distance(p).abs()
    }

    /// The point at coordinate `t` along the line.
    pub fn at(&self, t: f64) -> Point {
        self.point + self.direction * t
    }

    /// The same line, pointing the other way.
    pub fn reversed(&self) -> Line {
        Line {
            point: self.point,
            direction: -self.direction,
        }
    }

    /// Root-mean-square perpendicular distance of `points` (0 for none).
    pub fn rms(&self, points: &[Point]) -> f64 {
        if points.is_empty() {
            return 0.0;
        }
        let ss: f64 = points
            .iter()
            .map(|p| self.signed_distance(*p).powi(2))
            .sum();
        (ss / points.len() as f64).sqrt()
    }
}

/// Angle between two undirected lines, in [0, π/2].
pub fn line_angle_between(a: &Line, b: &Line) -> f64 {
    let c = a.direction.dot(&b.direction).abs().min(1.0);
    let s = a.direction.perp(&b.direction).abs().min(1.0);
    s.atan2(c)
}

/// Extract line segments from points ordered along a scan or trajectory (see the module doc).
/// Non-finite points are ignored; the result is empty when nothing qualifies.
pub fn extract_segments(points: &[Point], params: &SegmentParams) -> Vec<FittedSegment> {
    let pts: Vec<Point> = points
        .iter()
        .copied()
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .collect();
    let threshold = params.distance_threshold.max(1e-6);
    let mut out = Vec::new();
    for run in join_runs(split_runs(&pts, params), params) {
        let pieces = split(&run, threshold);
        for (lo, hi) in merge(&run, &pieces, threshold, params.merge_angle) {
            if let Some(f) = fit_piece(&run[lo..=hi], threshold) {
                if f.points >= params.min_points.max(2) && f.segment.length() >= params.min_length {
                    out.push(f);
                }
            }
        }
    }
    out
}

/// Cut the ordered points into runs at gaps, skipping short bursts of outliers.
fn split_runs(pts: &[Point], params: &SegmentParams) -> Vec<Vec<Point>> {
    let mut runs = Vec::new();
    let Some(first) = pts.first() else {
        return runs;
    };
    let max_gap = params.max_gap.max(0.0);
    let mut cur = vec![*first];
    let mut i = 1;
    while i < pts.len() {
        let last = *cur.last().unwrap_or(&pts[i]);
        if (pts[i] - last).norm() <= max_gap {
            cur.push(pts[i]);
            i += 1;
            continue;
        }
        // A stray burst: a later point (within max_outlier_run) continues the run.
        let rejoin = (i + 1..=i.saturating_add(params.max_outlier_run).min(pts.len() - 1))
            .find(|&j| (pts[j] - last).norm() <= max_gap);
        match rejoin {
            Some(j) => {
                cur.push(pts[j]);
                i = j + 1;
            }
            _ => {
                runs.push(std::mem::take(&mut cur));
                cur.push(pts[i]);
                i += 1;
            }
        }
    }
    runs.push(cur);
    runs
}

/// Drop runs too short to hold a segment (bursts of stray echoes) and re-join the runs they
/// interrupted: consecutive remaining runs whose ends are within `max_gap`.
fn join_runs(runs: Vec<Vec<Point>>, params: &SegmentParams) -> Vec<Vec<Point>> {
    let mut out: Vec<Vec<Point>> = Vec::new();
    for run in runs {
        if run.len() < params.min_points.max(2) {
            continue;
        }
        if let (Some(prev), Some(first)) = (out.last_mut(), run.first()) {
            if prev
                .last()
                .is_some_and(|l| (*first - *l).norm() <= params.max_gap.max(0.0))
            {
                prev.extend(run);
                continue;
            }
        }
        out.push(run);
    }
    out
}

/// Iterative end-point fit: index ranges (inclusive, sharing their split points).
fn split(run: &[Point], threshold: f64) -> Vec<(usize, usize)> {
    let mut done = Vec::new();
    if run.len() < 2 {
        return done;
    }
    let mut stack = vec![(0, run.len() - 1)];
    while let Some((lo, hi)) = stack.pop() {
        if hi - lo < 2 {
            done.push((lo, hi));
            continue;
        }
        let chord = Line::through(run[lo], run[hi]);
        let (mut worst, mut k) = (0.0, lo);
        for (j, p) in run.iter().enumerate().take(hi).skip(lo + 1) {
            let d = match &chord {
                Some(l) => l.distance(*p),
                None => (*p - run[lo]).norm(),
            };
            if d > worst {
                worst = d;
                k = j;
            }
        }
        if worst > threshold && k > lo && k < hi {
            // Push the right half first so the left half is processed first.
            stack.push((k, hi));
            stack.push((lo, k));
        } else {
            done.push((lo, hi));
        }
    }
    done.sort_unstable();
    done
}

/// Greedy merge of neighbouring pieces whose union still fits one line.
fn merge(
    run: &[Point],
    pieces: &[(usize, usize)],
    threshold: f64,
    merge_angle: f64,
) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &(lo, hi) in pieces {
        if let Some(last) = out.last_mut() {
            if mergeable(run, *last, (lo, hi), threshold, merge_angle) {
                last.1 = hi.max(last.1);
                continue;
            }
        }
        out.push((lo, hi));
    }
    out
}

fn mergeable(
    run: &[Point],
    a: (usize, usize),
    b: (usize, usize),
    threshold: f64,
    merge_angle: f64,
) -> bool {
    let lo = a.0.min(b.0);
    let hi = a.1.max(b.1).min(run.len().saturating_sub(1));
    if hi <= lo {
        return true;
    }
    let union = &run[lo..=hi];
    let Some(line) = Line::fit(union) else {
        return true;
    };
    let mut res: Vec<f64> = union.iter().map(|p| line.distance(*p)).collect();
    // the value a full sort would put there (one value per place in a total order)
    let at = ((res.len() - 1) as f64 * 0.9).floor() as usize;
    let p90 = *res.select_nth_unstable_by(at, |x, y| x.total_cmp(y)).1;
    if p90 > threshold {
        return false;
    }
    // Direction check, with the tolerance widened by each piece's own angular uncertainty
    // (σθ ≈ σ·√(12/n)/length, σ at least threshold/2.5): short, noisy pieces have no
    // reliable direction, and pieces of fewer than five points none at all.
    let direction = |lo: usize, hi: usize| -> Option<(Line, f64)> {
        // Only the piece's points that fit the union: stray points must not tilt it.
        let pts: Vec<Point> = run[lo..=hi]
            .iter()
            .copied()
            .filter(|p| line.distance(*p) <= threshold)
            .collect();
        let pts = pts.as_slice();
        if pts.len() < 5 {
            return None;
        }
        let line = Line::fit(pts)?;
        let (tmin, tmax) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                let t = line.project(*p);
                (a.min(t), b.max(t))
            });
        let sigma = safe_div(
            line.rms(pts).max(threshold / 2.5) * (12.0 / pts.len() as f64).sqrt(),
            tmax - tmin,
            f64::INFINITY,
        );
        Some((line, sigma))
    };
    let last = run.len() - 1;
    match (
        direction(a.0.min(last), a.1.min(last)),
        direction(b.0.min(last), hi),
    ) {
        (Some((la, sa)), Some((lb, sb))) => {
            line_angle_between(&la, &lb) <= merge_angle.max(0.0) + 3.0 * (sa + sb)
        }
        _ => true,
    }
}

/// Robust total-least-squares fit of one piece.
fn fit_piece(points: &[Point], threshold: f64) -> Option<FittedSegment> {
    let mut line = Line::fit(points)?;
    let mut inliers: Vec<Point> = points.to_vec();
    for _ in 0..2 {
        let kept: Vec<Point> = points
            .iter()
            .copied()
            .filter(|p| line.distance(*p) <= threshold)
            .collect();
        if kept.len() < 2 {
            break;
        }
        match Line::fit(&kept) {
            Some(l) => {
                line = l;
                inliers = kept;
            }
            None => break,
        }
    }
    // Orient along the order of the points.
    let (first, last) = (inliers.first()?, inliers.last()?);
    if line.project(*last) < line.project(*first) {
        line = line.reversed();
    }
    let (mut tmin, mut tmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &inliers {
        let t = line.project(*p);
        tmin = tmin.min(t);
        tmax = tmax.max(t);
    }
    let rms = line.rms(&inliers);
    Some(FittedSegment {
        segment: Segment::new(line.at(tmin), line.at(tmax)),
        points: inliers.len(),
        rms: safe_div(rms, 1.0, 0.0),
    })
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Rng;
    use super::*;

    fn wall(from: Point, to: Point, step: f64, sigma: f64, rng: &mut Rng) -> Vec<Point> {
        let d = to - from;
        let n = (d.norm() / step).round() as usize;
        let normal = Vector::new(-d.y, d.x) / d.norm();
        (0..=n)
            .map(|i| from + d * (i as f64 / n as f64) + normal * rng.gauss(sigma))
            .collect()
    }

    #[test]
    fn line_fit_is_orthogonal() {
        // A steep line: ordinary least squares on y(x) would fail, TLS does not.
        let pts: Vec<Point> = (0..10)
            .map(|i| Point::new(1.0 + 1e-3 * (i % 2) as f64, i as f64))
            .collect();
        let l = Line::fit(&pts).unwrap();
        assert!(l.direction.x.abs() < 1e-3);
        assert!(Line::fit(&[Point::new(1.0, 1.0); 5]).is_none());
        assert!(Line::fit(&[]).is_none());
        assert!(Line::through(Point::origin(), Point::origin()).is_none());
    }

    #[test]
    fn straight_noisy_wall_is_one_segment() {
        let mut rng = Rng::new(1);
        let pts = wall(
            Point::new(0.0, 1.0),
            Point::new(4.0, 1.0),
            0.04,
            0.02,
            &mut rng,
        );
        let segs = extract_segments(&pts, &SegmentParams::default());
        assert_eq!(segs.len(), 1, "{segs:?}");
        let s = segs[0];
        assert!(s.segment.angle().abs() < 0.02);
        assert!((s.segment.a - Point::new(0.0, 1.0)).norm() < 0.08);
        assert!((s.segment.b - Point::new(4.0, 1.0)).norm() < 0.08);
        assert!(s.rms < 0.03 && s.points > 90);
    }

    #[test]
    fn corner_splits_into_two() {
        let mut rng = Rng::new(2);
        let mut pts = wall(
            Point::new(0.0, 0.0),
            Point::new(3.0, 0.0),
            0.04,
            0.015,
            &mut rng,
        );
        pts.extend(wall(
            Point::new(3.0, 0.04),
            Point::new(3.0, 2.0),
            0.04,
            0.015,
            &mut rng,
        ));
        let segs = extract_segments(&pts, &SegmentParams::default());
        assert_eq!(segs.len(), 2, "{segs:?}");
        assert!(segs[0].segment.angle().abs() < 0.03);
        assert!((segs[1].segment.angle() - std::f64::consts::FRAC_PI_2).abs() < 0.03);
    }

    #[test]
    fn outliers_are_skipped_not_split() {
        let mut rng = Rng::new(3);
        let mut pts = wall(
            Point::new(0.0, 0.0),
            Point::new(3.0, 0.0),
            0.05,
            0.01,
            &mut rng,
        );
        pts[20] = Point::new(pts[20].x, 0.9);
        pts[40] = Point::new(pts[40].x, -0.15); // close enough not to be a gap
        let segs = extract_segments(&pts, &SegmentParams::default());
        assert_eq!(segs.len(), 1, "{segs:?}");
        assert!(segs[0].segment.angle().abs() < 0.01);
        assert!(segs[0].segment.length() > 2.9);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let p = SegmentParams::default();
        assert!(extract_segments(&[], &p).is_empty());
        assert!(extract_segments(&[Point::new(1.0, 1.0); 50], &p).is_empty());
        assert!(extract_segments(&[Point::new(f64::NAN, 0.0)], &p).is_empty());
        let zero = SegmentParams {
            distance_threshold: 0.0,
            min_points: 0,
            max_gap: 0.0,
            min_length: 0.0,
            merge_angle: 0.0,
            max_outlier_run: 0,
        };
        let pts: Vec<Point> = (0..20).map(|i| Point::new(i as f64, 0.0)).collect();
        let _ = extract_segments(&pts, &zero);
    }
}

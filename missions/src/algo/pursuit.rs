//! Trajectory controller: pure pursuit for the car-like cart (kinematic bicycle model, pose at
//! the rear axle), forwards or in reverse.
//!
//! Each [`PurePursuit::command`] call
//!
//! 1. advances the *progress*: the closest point of the path to the cart, searched only a
//!    little ahead of the previous one, so the controller never skips ahead where a path
//!    passes near itself and never goes back;
//! 2. picks the *lookahead point* [`PursuitParams::lookahead`] metres further along the path
//!    (beyond the end, on the extension of the last leg, so the cart settles onto the final
//!    leg instead of swerving towards the end point);
//! 3. steers on the arc through it: curvature κ = 2·y / d² (y the point's lateral offset in
//!    the direction of motion, d its distance), steering φ = atan(±L·κ) clamped to
//!    [`PursuitParams::max_steer`] (the sign flips in reverse, where the heading turns the
//!    other way for the same steering);
//! 4. sets the speed: cruise, reduced in tight curves and linearly to
//!    [`PursuitParams::min_speed`] over the last [`PursuitParams::slow_down_distance`] metres;
//!    negative in reverse.
//!
//! The path is driven until the cart is within [`PursuitParams::position_tolerance`] of the
//! last waypoint (and, if set, within [`PursuitParams::heading_tolerance`] of the final
//! heading); having passed the end without that, it reports [`PursuitStatus::Overshot`].

use super::planner::Path;
use super::{safe_div, Command, DEFAULT_MAX_STEER, DEFAULT_WHEELBASE};
use crate::geom::{wrap_angle, Point, Pose, Vector};
use serde::{Deserialize, Serialize};

/// Parameters of the trajectory controller.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PursuitParams {
    /// Lookahead distance along the path, metres. Default 0.8.
    pub lookahead: f64,
    /// Cruise speed (magnitude), m/s. Default 0.4.
    pub speed: f64,
    /// Speed (magnitude) near the end of the path, m/s. Default 0.05.
    pub min_speed: f64,
    /// Distance before the end over which the speed ramps down, metres. Default 1.0.
    pub slow_down_distance: f64,
    /// Curve slow-down: the speed is divided by 1 + this × |curvature|, metres. Default 0.5.
    pub curvature_slowdown: f64,
    /// Wheelbase, metres. Default [`DEFAULT_WHEELBASE`].
    pub wheelbase: f64,
    /// Steering limit, radians. Default [`DEFAULT_MAX_STEER`].
    pub max_steer: f64,
    /// Arrival tolerance on the position of the last waypoint, metres. Default 0.08.
    pub position_tolerance: f64,
    /// Arrival tolerance on the final heading (the path's `goal_heading`, else the direction
    /// of the last leg — reversed when driving in reverse), radians; `None` (default)
    /// ignores the heading.
    pub heading_tolerance: Option<f64>,
    /// Drive the path backwards. Default false.
    pub reverse: bool,
}

impl Default for PursuitParams {
    fn default() -> Self {
        PursuitParams {
            lookahead: 0.8,
            speed: 0.4,
            min_speed: 0.05,
            slow_down_distance: 1.0,
            curvature_slowdown: 0.5,
            wheelbase: DEFAULT_WHEELBASE,
            max_steer: DEFAULT_MAX_STEER,
            position_tolerance: 0.08,
            heading_tolerance: None,
            reverse: false,
        }
    }
}

/// Where the cart is with respect to the path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PursuitStatus {
    /// Still driving.
    Tracking,
    /// At the end, within the tolerances.
    Arrived,
    /// Past the end without meeting the tolerances: the path was not driven.
    Overshot,
}

/// The pure pursuit controller; keeps the progress along the path between calls.
#[derive(Clone, Debug, PartialEq)]
pub struct PurePursuit {
    /// Parameters.
    pub params: PursuitParams,
    path: Path,
    pts: Vec<Point>,
    cum: Vec<f64>,
    seg: usize,
    s: f64,
}

impl PurePursuit {
    /// A controller with no path yet (it stands still until [`PurePursuit::command`] gets one).
    pub fn new(params: PursuitParams) -> Self {
        PurePursuit {
            params,
            path: Path::default(),
            pts: Vec::new(),
            cum: vec![0.0],
            seg: 0,
            s: 0.0,
        }
    }

    /// A controller already following `path`.
    pub fn with_path(params: PursuitParams, path: Path) -> Self {
        let mut pp = PurePursuit::new(params);
        pp.set_path(path);
        pp
    }

    /// Follow `path` from its beginning.
    pub fn set_path(&mut self, path: Path) {
        let mut pts: Vec<Point> = path
            .waypoints
            .iter()
            .copied()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .collect();
        pts.dedup_by(|a, b| (*a - *b).norm() < 1e-9);
        let mut cum = vec![0.0];
        for w in pts.windows(2) {
            let last = *cum.last().unwrap_or(&0.0);
            cum.push(last + (w[1] - w[0]).norm());
        }
        self.path = path;
        self.pts = pts;
        self.cum = cum;
        self.seg = 0;
        self.s = 0.0;
    }

    /// Resume at `along` metres along the path (a progress saved earlier), as if driven so
    /// far: the progress only ever moves forward from there.
    pub fn resume_at(&mut self, along: f64) {
        let along = along.clamp(0.0, self.total());
        self.seg = self
            .cum
            .partition_point(|&c| c <= along)
            .saturating_sub(1)
            .min(self.pts.len().saturating_sub(2));
        self.s = along;
    }

    /// The path being followed.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Distance driven along the path so far (the progress), metres.
    pub fn progress(&self) -> f64 {
        self.s
    }

    /// Length of the path still ahead of the progress, metres.
    pub fn remaining(&self) -> f64 {
        (self.total() - self.s).max(0.0)
    }

    fn total(&self) -> f64 {
        *self.cum.last().unwrap_or(&0.0)
    }

    fn point_at(&self, s: f64) -> Point {
        match self.pts.len() {
            0 => Point::origin(),
            1 => self.pts[0],
            n => {
                let total = self.total();
                if s >= total {
                    let dir = (self.pts[n - 1] - self.pts[n - 2]) / (total - self.cum[n - 2]);
                    return self.pts[n - 1] + dir * (s - total);
                }
                let k = self.cum.partition_point(|&c| c <= s).clamp(1, n - 1) - 1;
                let len = self.cum[k + 1] - self.cum[k];
                let t = safe_div(s - self.cum[k], len, 0.0).clamp(0.0, 1.0);
                self.pts[k] + (self.pts[k + 1] - self.pts[k]) * t
            }
        }
    }

    /// Advance the progress to the closest point ahead (within a search window).
    fn update_progress(&mut self, p: Point) {
        let n = self.pts.len();
        if n < 2 {
            return;
        }
        let window = self.s + 2.0 * self.params.lookahead.abs() + 1.0;
        let (mut best_d, mut best) = (f64::INFINITY, (self.seg, self.s));
        let mut k = self.seg;
        while k + 1 < n && self.cum[k] <= window {
            let (a, b) = (self.pts[k], self.pts[k + 1]);
            let d = b - a;
            let len = self.cum[k + 1] - self.cum[k];
            let t = safe_div((p - a).dot(&d), len * len, 0.0).clamp(0.0, 1.0);
            let dist = (p - (a + d * t)).norm();
            if dist < best_d - 1e-12 {
                best_d = dist;
                best = (k, self.cum[k] + t * len);
            }
            k += 1;
        }
        if best.1 >= self.s {
            self.seg = best.0;
            self.s = best.1;
        }
    }

    /// Signed along-path position of `p` beyond the last waypoint (positive once past it).
    fn beyond_end(&self, p: Point) -> f64 {
        let n = self.pts.len();
        if n < 2 {
            return 0.0;
        }
        let dir = (self.pts[n - 1] - self.pts[n - 2]) / (self.total() - self.cum[n - 2]);
        (p - self.pts[n - 1]).dot(&dir)
    }

    fn final_heading(&self) -> Option<f64> {
        if let Some(h) = self.path.goal_heading {
            return Some(h);
        }
        let n = self.pts.len();
        if n < 2 {
            return None;
        }
        let d = self.pts[n - 1] - self.pts[n - 2];
        let a = d.y.atan2(d.x);
        Some(if self.params.reverse {
            wrap_angle(a + std::f64::consts::PI)
        } else {
            a
        })
    }

    /// Tracking, arrived or overshot, for the cart at `pose`.
    pub fn status(&self, pose: &Pose) -> PursuitStatus {
        let Some(end) = self.pts.last() else {
            return PursuitStatus::Arrived;
        };
        let p = pose.point();
        let at_end = (p - end).norm() <= self.params.position_tolerance;
        let heading_ok = match (self.params.heading_tolerance, self.final_heading()) {
            (Some(tol), Some(h)) => wrap_angle(pose.theta - h).abs() <= tol,
            _ => true,
        };
        if at_end && heading_ok {
            return PursuitStatus::Arrived;
        }
        if self.pts.len() == 1 {
            // At the point with the wrong heading: a single point cannot fix that.
            return if at_end {
                PursuitStatus::Overshot
            } else {
                PursuitStatus::Tracking
            };
        }
        let on_last = self.seg + 2 >= self.pts.len();
        if on_last && self.beyond_end(p) > 0.0 {
            return PursuitStatus::Overshot;
        }
        PursuitStatus::Tracking
    }

    /// True once the cart has arrived at the end of the path.
    pub fn finished(&self, pose: &Pose) -> bool {
        self.status(pose) == PursuitStatus::Arrived
    }

    /// Distance from `pose` to the path (its closest leg), metres; 0 without a path.
    pub fn cross_track_error(&self, pose: &Pose) -> f64 {
        let p = pose.point();
        match self.pts.len() {
            0 => 0.0,
            1 => (p - self.pts[0]).norm(),
            _ => self
                .pts
                .windows(2)
                .map(|w| crate::geom::Segment::new(w[0], w[1]).distance_to(p))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// The command for the cart at `pose` following `path` (a path different from the
    /// current one restarts from its beginning). Stops once the status is not
    /// [`PursuitStatus::Tracking`].
    pub fn command(&mut self, pose: &Pose, path: &Path) -> Command {
        if *path != self.path {
            self.set_path(path.clone());
        }
        let p = pose.point();
        self.update_progress(p);
        if self.status(pose) != PursuitStatus::Tracking {
            return Command::STOP;
        }
        let pr = &self.params;
        let lookahead = if pr.lookahead.is_finite() {
            pr.lookahead.abs().max(0.05)
        } else {
            0.8
        };
        let target = if self.pts.len() == 1 {
            self.pts[0]
        } else {
            self.point_at(self.s + lookahead)
        };
        let dir_sign = if pr.reverse { -1.0 } else { 1.0 };
        let motion = pose.theta
            + if pr.reverse {
                std::f64::consts::PI
            } else {
                0.0
            };
        let m = Vector::new(motion.cos(), motion.sin());
        let to = target - p;
        let dx = to.dot(&m);
        let dy = m.perp(&to);
        let d2 = dx * dx + dy * dy;
        let curvature = safe_div(2.0 * dy, d2, 0.0);
        let max_steer = pr.max_steer.abs();
        let wheelbase = if pr.wheelbase.is_finite() && pr.wheelbase > 0.0 {
            pr.wheelbase
        } else {
            DEFAULT_WHEELBASE
        };
        let steer = (dir_sign * wheelbase * curvature)
            .atan()
            .clamp(-max_steer, max_steer);

        let remaining = if self.pts.len() == 1 {
            to.norm()
        } else {
            (self.total() - self.s).max(0.0)
        };
        let cruise = pr.speed.abs();
        let floor = pr.min_speed.abs().min(cruise);
        let ramp = safe_div(remaining, pr.slow_down_distance, 1.0).clamp(0.0, 1.0);
        let achievable = curvature.abs().min(max_steer.tan() / wheelbase);
        let speed =
            (cruise * ramp / (1.0 + pr.curvature_slowdown.max(0.0) * achievable)).max(floor);
        Command::new(dir_sign * speed, steer)
    }
}

#[cfg(test)]
mod tests {
    use super::super::bicycle_step;
    use super::*;

    fn drive(pp: &mut PurePursuit, path: &Path, mut pose: Pose, steps: usize) -> (Pose, f64) {
        let mut worst: f64 = 0.0;
        for _ in 0..steps {
            let c = pp.command(&pose, path);
            if c.is_stop() {
                break;
            }
            pose = bicycle_step(&pose, c, pp.params.wheelbase, 0.02);
            worst = worst.max(pp.cross_track_error(&pose));
        }
        (pose, worst)
    }

    #[test]
    fn straight_path_forwards() {
        let path = Path::new(vec![Point::new(0.0, 0.0), Point::new(5.0, 0.0)]);
        let mut pp = PurePursuit::new(PursuitParams::default());
        let (end, worst) = drive(&mut pp, &path, Pose::new(0.0, 0.3, 0.2), 5000);
        assert!(pp.finished(&end), "{end:?}");
        assert!((end.point() - Point::new(5.0, 0.0)).norm() < 0.1);
        assert!(worst < 0.5);
    }

    #[test]
    fn straight_path_in_reverse() {
        let path = Path::new(vec![Point::new(0.0, 0.0), Point::new(-4.0, 0.0)]);
        let params = PursuitParams {
            reverse: true,
            heading_tolerance: Some(0.1),
            ..PursuitParams::default()
        };
        let mut pp = PurePursuit::new(params);
        let (end, worst) = drive(&mut pp, &path, Pose::new(0.0, 0.2, 0.1), 5000);
        assert!(pp.finished(&end), "{end:?}");
        assert!(end.theta.abs() < 0.1);
        assert!(worst < 0.4);
        // Driving backwards: the last command had a negative speed.
        let mut pp2 = PurePursuit::new(params);
        assert!(pp2.command(&Pose::new(0.0, 0.0, 0.0), &path).speed < 0.0);
    }

    #[test]
    fn overshoot_is_reported() {
        let path = Path::new(vec![Point::new(0.0, 0.0), Point::new(2.0, 0.0)]);
        let mut pp = PurePursuit::new(PursuitParams::default());
        let _ = pp.command(&Pose::new(1.9, 0.0, 0.0), &path);
        let far = Pose::new(2.5, 0.5, 0.0);
        let _ = pp.command(&far, &path);
        assert_eq!(pp.status(&far), PursuitStatus::Overshot);
        assert!(pp.command(&far, &path).is_stop());
    }

    #[test]
    fn degenerate_paths() {
        let mut pp = PurePursuit::new(PursuitParams::default());
        let pose = Pose::new(0.0, 0.0, 0.0);
        assert!(pp.command(&pose, &Path::default()).is_stop());
        assert!(pp.finished(&pose));
        let one = Path::new(vec![Point::new(2.0, 0.0)]);
        assert!(pp.command(&pose, &one).speed > 0.0);
        let dup = Path::new(vec![Point::new(1.0, 1.0); 4]);
        let _ = pp.command(&pose, &dup);
        let zero = PursuitParams {
            lookahead: 0.0,
            wheelbase: 0.0,
            slow_down_distance: 0.0,
            ..PursuitParams::default()
        };
        let mut pz = PurePursuit::new(zero);
        let c = pz.command(
            &pose,
            &Path::new(vec![Point::origin(), Point::new(1.0, 1.0)]),
        );
        assert!(c.speed.is_finite() && c.steer.is_finite());
    }
}

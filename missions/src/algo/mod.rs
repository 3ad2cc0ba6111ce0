//! The robot's algorithms as pure, deterministic functions: no actors, no async, no I/O.
//! The operations (ultrasonic, segment extractor, wall sensor, docking-spot detector, path
//! planner, trajectory controller, wall follower, collision avoidance) wrap them.
//!
//! - [`segments`] — split-and-merge line extraction from ordered sonar points, with total
//!   least squares refits;
//! - [`wall`] — "the wall": the longest collinear set of segments near the cart;
//! - [`track`] — tracking the followed wall: refit to what is seen now, extent kept;
//! - [`dock`] — a docking spot (a rectangular recess of given breadth and depth) in the wall;
//! - [`planner`] — A* on an inflated occupancy grid, line-of-sight shortcutting and a straight
//!   final approach along the goal heading;
//! - [`pursuit`] — pure pursuit trajectory controller for car-like kinematics, forwards or in
//!   reverse;
//! - [`follow`] — wall (v1) and corridor (v2) following control law;
//! - [`localize`] — map matching: sonar segments on the map's walls correct the drifting
//!   odometry (heading, and the offset across each wall seen);
//! - [`sweep`] — which sonar echoes trace a wall (seen sideways, over the last metres
//!   driven), for the localizer;
//! - [`avoid`] — collision avoidance with four modes, including the controlled stop;
//! - [`clearance`] — the clearance guard: would the next centimetres of a command bring the
//!   cart's outline onto an echo?
//!
//! # Conventions
//!
//! World coordinates in metres, angles in radians (counter-clockwise from +x). The cart is the
//! thesis' car-like cart: a steered front axle and a driven rear axle, footprint 1.0 m × 0.6 m.
//! Its [`Pose`] is the midpoint of the rear axle (the reference point of the kinematic bicycle
//! model, see [`bicycle_step`]); [`DEFAULT_WHEELBASE`] and [`DEFAULT_MAX_STEER`] describe it.
//! Commands are [`Command`]s: signed speed (negative = reverse) and steering angle.
//!
//! # Example
//!
//! A cart drives along a wall at y = 1 m, which lies on its left:
//!
//! ```
//! use marie_missions::algo::{follow, segments, wall};
//! use marie_missions::geom::{Point, Pose};
//!
//! // Sonar points along the wall y = 1.0, ordered as the cart passed them.
//! let points: Vec<Point> = (0..60).map(|i| Point::new(i as f64 * 0.05, 1.0)).collect();
//! let segs = segments::extract_segments(&points, &segments::SegmentParams::default());
//! assert_eq!(segs.len(), 1);
//!
//! let pose = Pose::new(1.0, 0.2, 0.0);
//! let lines: Vec<_> = segs.iter().map(|s| s.segment).collect();
//! let w = wall::sense_wall(&lines, &pose, &wall::WallParams::default()).unwrap();
//! assert_eq!(w.side, wall::Side::Left);
//! assert!((w.distance - 0.8).abs() < 1e-6);
//!
//! // 0.8 m from the wall, asked for 0.6 m: steer left, towards it.
//! let cmd = follow::follow_command(&w, None, &follow::FollowParams::default());
//! assert!(cmd.steer > 0.0 && cmd.speed > 0.0);
//! ```

pub mod avoid;
pub mod clearance;
pub mod dock;
pub mod follow;
pub mod localize;
pub mod parking;
pub mod planner;
pub mod pursuit;
pub mod segments;
pub mod sweep;
pub mod track;
pub mod wall;

use crate::geom::{wrap_angle, Pose};
use serde::{Deserialize, Serialize};

pub use segments::Line;

/// Wheelbase of the thesis-like cart (rear axle to front axle), metres: 0.7.
pub const DEFAULT_WHEELBASE: f64 = 0.7;
/// Steering limit of the thesis-like cart, radians: 0.5 (≈ 29°, turning radius ≈ 1.28 m).
pub const DEFAULT_MAX_STEER: f64 = 0.5;

/// A drive command for the car-like cart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Command {
    /// Speed of the rear-axle midpoint, m/s; negative drives backwards.
    pub speed: f64,
    /// Steering angle of the front wheels, radians; positive turns left when driving forwards.
    pub steer: f64,
}

impl Command {
    /// Standing still, wheels straight.
    pub const STOP: Command = Command {
        speed: 0.0,
        steer: 0.0,
    };

    /// A command.
    pub fn new(speed: f64, steer: f64) -> Self {
        Command { speed, steer }
    }

    /// True when the command does not move the cart.
    pub fn is_stop(&self) -> bool {
        self.speed == 0.0
    }
}

/// One Euler step of the kinematic bicycle model the controllers assume:
/// x' = v cos θ, y' = v sin θ, θ' = v / L · tan φ, with the pose at the rear axle.
///
/// A non-positive or non-finite `wheelbase` leaves the heading unchanged.
pub fn bicycle_step(pose: &Pose, command: Command, wheelbase: f64, dt: f64) -> Pose {
    let v = command.speed;
    let omega = if wheelbase.is_finite() && wheelbase > 0.0 {
        v / wheelbase * command.steer.tan()
    } else {
        0.0
    };
    Pose {
        x: pose.x + v * pose.theta.cos() * dt,
        y: pose.y + v * pose.theta.sin() * dt,
        theta: wrap_angle(pose.theta + omega * dt),
    }
}

/// `x / y`, or `fallback` when `y` is (nearly) zero or the result is not finite.
pub(crate) fn safe_div(x: f64, y: f64, fallback: f64) -> f64 {
    if y.abs() < 1e-12 {
        return fallback;
    }
    let r = x / y;
    if r.is_finite() {
        r
    } else {
        fallback
    }
}

/// Deterministic random numbers for the tests: the simulation's seeded generator
/// ([`crate::sim::Rng`], xoshiro256** from `rand_xoshiro`), under the names the tests use.
#[cfg(test)]
pub(crate) mod test_rng {
    /// The seeded generator.
    pub(crate) struct Rng(crate::sim::Rng);

    impl Rng {
        pub(crate) fn new(seed: u64) -> Self {
            Rng(crate::sim::Rng::new(seed))
        }

        /// Uniform in [0, 1).
        pub(crate) fn uniform(&mut self) -> f64 {
            self.0.uniform()
        }

        /// Normal with standard deviation `sigma`.
        pub(crate) fn gauss(&mut self, sigma: f64) -> f64 {
            self.0.gaussian(sigma)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bicycle_drives_straight_and_turns() {
        let mut p = Pose::new(0.0, 0.0, 0.0);
        for _ in 0..50 {
            p = bicycle_step(&p, Command::new(1.0, 0.0), 0.7, 0.02);
        }
        assert!((p.x - 1.0).abs() < 1e-9 && p.y.abs() < 1e-12);
        let q = bicycle_step(&p, Command::new(1.0, 0.3), 0.7, 0.1);
        assert!(q.theta > 0.0);
        let r = bicycle_step(&p, Command::new(-1.0, 0.3), 0.7, 0.1);
        assert!(r.theta < 0.0 && r.x < p.x);
        let s = bicycle_step(&p, Command::new(1.0, 0.3), 0.0, 0.1);
        assert_eq!(s.theta, p.theta);
    }

    #[test]
    fn safe_division_guards() {
        assert_eq!(safe_div(1.0, 0.0, 7.0), 7.0);
        assert_eq!(safe_div(1.0, 2.0, 7.0), 0.5);
        assert_eq!(safe_div(f64::MAX, 1e-300, 3.0), 3.0);
    }
}

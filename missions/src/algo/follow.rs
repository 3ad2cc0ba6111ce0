//! Wall following control law (the wall follower's algorithm): v1 follows one wall at a
//! distance; v2 can also keep to the middle of a corridor.
//!
//! In terms of the distance travelled s, with n the distance to the wall and β the angle of
//! the direction of motion towards the wall (relative to the wall's direction):
//! dn/ds = −sin β and dβ/ds = κ, the path's curvature towards the wall. The law is a cascade
//!
//! - desired approach angle β* = clamp(atan(k_d · (n − n*)), ±[`FollowParams::max_approach_angle`]);
//! - curvature κ = k_h · (β* − β), steering φ = atan(±L · κ) clamped to
//!   [`FollowParams::max_steer`],
//!
//! which for small angles is the linear system e'' + k_h e' + k_h k_d e = 0 (critically damped
//! for k_h = 4 k_d, the defaults). It holds forwards and backwards: reversing flips the sign
//! of β measured from the heading, not the steering needed to turn towards the wall. In
//! corridor mode n* is the middle between the followed wall and the opposite one.

use super::wall::WallEstimate;
use super::{Command, DEFAULT_MAX_STEER, DEFAULT_WHEELBASE};
use serde::{Deserialize, Serialize};

/// What to follow.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum FollowMode {
    /// Keep [`FollowParams::distance`] from the wall (v1 behaviour).
    #[default]
    Wall,
    /// Keep to the middle between the wall and the opposite, parallel wall; without an
    /// opposite wall, behave as [`FollowMode::Wall`].
    Corridor,
}

/// Parameters of the wall follower.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FollowParams {
    /// Distance to keep from the wall (cart reference point to wall line), metres.
    /// Default 0.6.
    pub distance: f64,
    /// Wall or corridor (v2 only). Default [`FollowMode::Wall`].
    pub mode: FollowMode,
    /// Speed, m/s; negative follows the wall backwards. Default 0.3.
    pub speed: f64,
    /// Distance gain k_d, 1/m. Default 0.8.
    pub distance_gain: f64,
    /// Heading gain k_h, 1/m (curvature per radian). Default 3.2.
    pub heading_gain: f64,
    /// Steepest approach angle to the wall, radians. Default 0.5.
    pub max_approach_angle: f64,
    /// Wheelbase, metres. Default [`DEFAULT_WHEELBASE`].
    pub wheelbase: f64,
    /// Steering limit, radians. Default [`DEFAULT_MAX_STEER`].
    pub max_steer: f64,
    /// [`is_aligned`] tolerance on the distance, metres. Default 0.05.
    pub distance_tolerance: f64,
    /// [`is_aligned`] tolerance on the angle to the wall, radians. Default 0.05.
    pub angle_tolerance: f64,
}

impl Default for FollowParams {
    fn default() -> Self {
        FollowParams {
            distance: 0.6,
            mode: FollowMode::Wall,
            speed: 0.3,
            distance_gain: 0.8,
            heading_gain: 3.2,
            max_approach_angle: 0.5,
            wheelbase: DEFAULT_WHEELBASE,
            max_steer: DEFAULT_MAX_STEER,
            distance_tolerance: 0.05,
            angle_tolerance: 0.05,
        }
    }
}

/// The opposite wall to use, if the mode and the geometry allow it.
fn corridor_wall<'a>(
    wall: &WallEstimate,
    opposite: Option<&'a WallEstimate>,
    params: &FollowParams,
) -> Option<&'a WallEstimate> {
    match params.mode {
        FollowMode::Wall => None,
        FollowMode::Corridor => opposite.filter(|o| o.side != wall.side),
    }
}

/// Distance error n − n*, metres: positive when the cart is too far from `wall`.
pub fn distance_error(
    wall: &WallEstimate,
    opposite: Option<&WallEstimate>,
    params: &FollowParams,
) -> f64 {
    match corridor_wall(wall, opposite, params) {
        Some(o) => 0.5 * (wall.distance - o.distance),
        None => wall.distance - params.distance,
    }
}

/// The steering command that follows `wall` (and in corridor mode centres between it and
/// `opposite`, which must be on the other side) at [`FollowParams::speed`].
pub fn follow_command(
    wall: &WallEstimate,
    opposite: Option<&WallEstimate>,
    params: &FollowParams,
) -> Command {
    let e = distance_error(wall, opposite, params);
    let speed = if params.speed.is_finite() {
        params.speed
    } else {
        0.0
    };
    let sv = if speed < 0.0 { -1.0 } else { 1.0 };
    let side = wall.side.sign();
    // Angle of the motion towards the wall.
    let beta = -wall.angle * side * sv;
    let max_approach = params.max_approach_angle.abs();
    let beta_star = (params.distance_gain * e)
        .atan()
        .clamp(-max_approach, max_approach);
    let kappa = params.heading_gain * (beta_star - beta);
    let wheelbase = if params.wheelbase.is_finite() && params.wheelbase > 0.0 {
        params.wheelbase
    } else {
        DEFAULT_WHEELBASE
    };
    let max_steer = params.max_steer.abs();
    let steer = (side * wheelbase * kappa)
        .atan()
        .clamp(-max_steer, max_steer);
    let steer = if steer.is_finite() { steer } else { 0.0 };
    Command::new(speed, steer)
}

/// True when the cart runs parallel to the wall at the requested distance (or mid-corridor),
/// within [`FollowParams::distance_tolerance`] and [`FollowParams::angle_tolerance`].
pub fn is_aligned(
    wall: &WallEstimate,
    opposite: Option<&WallEstimate>,
    params: &FollowParams,
) -> bool {
    distance_error(wall, opposite, params).abs() <= params.distance_tolerance
        && wall.angle.abs() <= params.angle_tolerance
}

#[cfg(test)]
mod tests {
    use super::super::bicycle_step;
    use super::super::wall::{sense_wall, Side, WallParams};
    use super::*;
    use crate::geom::{Point, Pose, Segment};

    fn run(params: &FollowParams, start: Pose, walls: &[Segment], secs: f64) -> Pose {
        let mut pose = start;
        let wp = WallParams::default();
        for _ in 0..(secs / 0.02) as usize {
            let left = sense_wall(
                walls,
                &pose,
                &WallParams {
                    side: Some(Side::Left),
                    ..wp
                },
            )
            .unwrap();
            let right = sense_wall(
                walls,
                &pose,
                &WallParams {
                    side: Some(Side::Right),
                    ..wp
                },
            );
            let c = follow_command(&left, right.as_ref(), params);
            pose = bicycle_step(&pose, c, params.wheelbase, 0.02);
        }
        pose
    }

    fn wall_y(y: f64) -> Segment {
        Segment::new(Point::new(-50.0, y), Point::new(50.0, y))
    }

    #[test]
    fn converges_forwards_and_backwards() {
        let walls = [wall_y(1.0)];
        let p = FollowParams::default();
        let end = run(&p, Pose::new(0.0, -0.2, 0.1), &walls, 40.0);
        assert!((1.0 - end.y - 0.6).abs() < 0.02, "{end:?}");
        assert!(end.theta.abs() < 0.02);
        let back = FollowParams { speed: -0.3, ..p };
        let end = run(&back, Pose::new(0.0, 0.7, -0.15), &walls, 40.0);
        assert!((1.0 - end.y - 0.6).abs() < 0.02, "{end:?}");
        assert!(end.x < -5.0);
    }

    #[test]
    fn corridor_mode_centres() {
        let walls = [wall_y(1.0), wall_y(-1.4)];
        let p = FollowParams {
            mode: FollowMode::Corridor,
            ..FollowParams::default()
        };
        let end = run(&p, Pose::new(0.0, 0.5, 0.0), &walls, 40.0);
        assert!((end.y + 0.2).abs() < 0.03, "{end:?}");
    }
}

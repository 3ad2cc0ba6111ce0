//! The clearance guard: would the cart's next few centimetres bring its outline onto
//! something the sonars hear right now?
//!
//! A planned manoeuvre keeps its clearance from the walls *on the map, at the estimated
//! pose*; parking leaves only a few centimetres of it, and the pose the plan is driven with
//! is off by about as much (the odometry drifts through the turns, and the localizer has
//! little to match there). The sonars measure the clearance directly, so the cart checks it
//! before every command, as the thesis' cart had to: each echo puts a surface somewhere on
//! the arc of its range across its beam cone (its [`Echo::half_angle`], as the sensor reports it);
//! the footprint is moved [`GuardParams::reach`] metres ahead along the command (the
//! kinematic bicycle model), and the guard trips when it would come nearer than
//! [`GuardParams::margin`] to any such point *and* nearer than it is now — an echo close
//! beside a cart driving parallel to a wall does not stop it.
//!
//! The guard only looks at what the sonars hear: a surface seen by no beam (a corner between
//! two cones, an echo lost at a grazing angle) goes unnoticed, which is why it complements the
//! plan's clearance rather than replacing it.

use super::parking::Footprint;
use super::{bicycle_step, Command};
use crate::geom::{Point, Pose};
use nalgebra::Isometry2;
use serde::{Deserialize, Serialize};

/// Points placed on each echo's arc.
const ARC_POINTS: usize = 7;

/// Steps the footprint is moved in over [`GuardParams::reach`].
const REACH_STEPS: usize = 4;

/// One echo, in the cart's frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Echo {
    /// The sensor's pose on the cart (cart frame: rear-axle centre, x forward); its heading
    /// is the beam's axis.
    pub mount: Pose,
    /// Half the beam's opening angle, radians.
    pub half_angle: f64,
    /// Measured range, metres (non-finite or negative: no echo, ignored).
    pub range: f64,
}

/// Parameters of the guard.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GuardParams {
    /// How near (m) the outline may come to an echo. Default 0.02: about two sonar noise σ
    /// above touching, below the parking planner's own clearance.
    pub margin: f64,
    /// How far ahead (m) along the command the footprint is checked. Default 0.04: more than
    /// the cart travels between two control steps at parking speed.
    pub reach: f64,
    /// Wheelbase of the bicycle model, m.
    pub wheelbase: f64,
}

impl Default for GuardParams {
    fn default() -> Self {
        GuardParams {
            margin: 0.02,
            reach: 0.04,
            wheelbase: super::DEFAULT_WHEELBASE,
        }
    }
}

/// Why the guard tripped.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trip {
    /// The clearance now, metres.
    pub clearance: f64,
    /// The least clearance over the reach ahead, metres.
    pub ahead: f64,
    /// The echo point that comes nearest, cart frame.
    pub point: Point,
}

/// The points an echo may have come from: its range's arc across the beam, cart frame.
fn arc(echo: &Echo) -> impl Iterator<Item = Point> + '_ {
    let usable = echo.range.is_finite() && echo.range >= 0.0 && echo.half_angle.is_finite();
    let n = if usable { ARC_POINTS } else { 0 };
    (0..n).map(move |k| {
        let t = k as f64 / (ARC_POINTS - 1) as f64;
        let a = echo.mount.theta + echo.half_angle * (2.0 * t - 1.0);
        echo.mount.point() + crate::geom::Vector::new(a.cos(), a.sin()) * echo.range
    })
}

/// Distance from `p` (cart frame) to the outline of `footprint` at the pose whose transform
/// is `pose` (cart frame; made once per pose, not per point); 0 inside.
fn distance(footprint: &Footprint, pose: &Isometry2<f64>, p: Point) -> f64 {
    let local = pose.inverse_transform_point(&p);
    let dx = (-footprint.rear - local.x)
        .max(local.x - footprint.front)
        .max(0.0);
    let dy = (local.y.abs() - footprint.half_width).max(0.0);
    dx.hypot(dy)
}

/// Check `command` against `echoes`: `Some` when following it for [`GuardParams::reach`]
/// metres would bring the footprint nearer than the margin to an echo, and nearer than it is
/// now. A command that does not move never trips.
pub fn check(
    echoes: &[Echo],
    footprint: &Footprint,
    command: Command,
    params: &GuardParams,
) -> Option<Trip> {
    if command.is_stop() || !command.speed.is_finite() {
        return None;
    }
    let here = Pose::default();
    let step = params.reach.max(0.0) / REACH_STEPS as f64;
    let unit = Command::new(command.speed.signum(), command.steer);
    let path: Vec<Isometry2<f64>> = (1..=REACH_STEPS)
        .scan(here, |pose, _| {
            *pose = bicycle_step(pose, unit, params.wheelbase, step);
            Some(pose.isometry())
        })
        .collect();
    let here = here.isometry();
    let mut worst: Option<Trip> = None;
    for p in echoes.iter().flat_map(arc) {
        let now = distance(footprint, &here, p);
        let ahead = path
            .iter()
            .map(|pose| distance(footprint, pose, p))
            .fold(f64::INFINITY, f64::min);
        let closing = ahead < now - 1e-6;
        if closing && ahead < params.margin && worst.is_none_or(|w| ahead < w.ahead) {
            worst = Some(Trip {
                clearance: now,
                ahead,
                point: p,
            });
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::algo::parking::tests::cart;

    fn echo(x: f64, y: f64, deg: f64, range: f64) -> Echo {
        Echo {
            mount: Pose::new(x, y, deg.to_radians()),
            half_angle: 8f64.to_radians(), // a narrow beam
            range,
        }
    }

    #[test]
    fn a_wall_just_behind_stops_reversing_but_not_driving_away() {
        let rear = [echo(-0.15, 0.0, 180.0, 0.03)];
        let p = GuardParams::default();
        let trip = check(&rear, &cart(), Command::new(-0.1, 0.0), &p).expect("trips");
        assert!(
            trip.ahead < p.margin && trip.clearance > trip.ahead,
            "{trip:?}"
        );
        assert!(check(&rear, &cart(), Command::new(0.1, 0.0), &p).is_none());
        assert!(check(&rear, &cart(), Command::STOP, &p).is_none());
        // far enough: passes
        let far = [echo(-0.15, 0.0, 180.0, 0.2)];
        assert!(check(&far, &cart(), Command::new(-0.3, 0.0), &p).is_none());
    }

    #[test]
    fn a_wall_close_alongside_passes_straight_but_trips_a_turn_into_it() {
        // the back wall of a recess 2 cm from the cart's left side
        let side = [echo(0.0, 0.3, 90.0, 0.02), echo(0.65, 0.3, 90.0, 0.02)];
        let p = GuardParams::default();
        assert!(check(&side, &cart(), Command::new(-0.1, 0.0), &p).is_none());
        assert!(check(&side, &cart(), Command::new(0.1, 0.0), &p).is_none());
        // backing with the wheels turned right swings the rear to the left, into the wall
        assert!(check(&side, &cart(), Command::new(-0.1, -0.4), &p).is_some());
        // and so does the tail swinging out in a forward turn away from it
        assert!(check(&side, &cart(), Command::new(0.1, -0.4), &p).is_some());
        // a wall 0.2 m away leaves room for all of these
        let away = [echo(0.0, 0.3, 90.0, 0.2), echo(0.65, 0.3, 90.0, 0.2)];
        for steer in [-0.4, 0.0, 0.4] {
            for speed in [-0.1, 0.1] {
                assert!(check(&away, &cart(), Command::new(speed, steer), &p).is_none());
            }
        }
    }

    #[test]
    fn lost_echoes_are_ignored() {
        let none = [
            echo(0.85, 0.0, 0.0, f64::INFINITY),
            echo(0.85, 0.0, 0.0, f64::NAN),
        ];
        assert!(check(
            &none,
            &cart(),
            Command::new(0.3, 0.0),
            &GuardParams::default()
        )
        .is_none());
    }
}

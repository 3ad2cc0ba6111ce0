//! Collision avoidance (the collision-avoidance operation's algorithm), with four modes as in
//! the thesis ("collision avoidance can be set to 4 different modes", 8.7.3); the controlled
//! stop, "a special instance of the collision avoidance" (3.3.2), is one of them.
//!
//! Only sonars looking in the direction of travel count: those mounted within
//! [`AvoidParams::sector_half_angle`] of straight ahead when the command drives forwards, of
//! straight back when it reverses; a command with zero speed has no direction and always
//! passes. The nearest such echo is *the obstacle*; its distance is the sonar range
//! (the sensors sit on the cart's outline) and its bearing the sensor's mount angle.
//!
//! | mode | obstacle within `slow_range` | obstacle within `stop_range` |
//! |------|------------------------------|------------------------------|
//! | [`AvoidMode::Off`] | pass | pass |
//! | [`AvoidMode::Warn`] | pass, report [`AvoidDecision::Warn`] | same |
//! | [`AvoidMode::SlowDown`] | scale the speed down, [`AvoidDecision::Slow`] | stand still while it stays, [`AvoidDecision::Hold`] |
//! | [`AvoidMode::ControlledStop`] | scale the speed down | stop for good, [`AvoidDecision::Stopped`] |
//!
//! The speed scale falls linearly from 1 at `slow_range` to [`AvoidParams::min_speed_factor`]
//! at `stop_range`. [`CollisionAvoidance`] latches a controlled stop until reset; the bare
//! [`avoid`] function is memoryless.

use super::Command;
use crate::geom::{wrap_angle, Point};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How the cart responds to obstacles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AvoidMode {
    /// No avoidance: every command passes unchanged.
    Off,
    /// Monitor only: commands pass unchanged, obstacles within `slow_range` are reported.
    Warn,
    /// Slow down near obstacles and hold (stand still) while one is within `stop_range`;
    /// drive on when it is gone.
    #[default]
    SlowDown,
    /// Slow down near obstacles and stop when one is within `stop_range`: the controlled stop
    /// that ends a manoeuvre (e.g. backing into a corner), reported as
    /// [`AvoidDecision::Stopped`].
    ControlledStop,
}

/// One sonar reading, in the cart's frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarReading {
    /// Where the sensor sits on the cart (cart frame, metres).
    pub position: Point,
    /// Direction the sensor looks in, radians, 0 = straight ahead, counter-clockwise.
    pub angle: f64,
    /// Measured range, metres; `f64::INFINITY` for no echo. Negative or NaN ranges are
    /// ignored.
    pub range: f64,
}

impl SonarReading {
    /// A reading from a sensor at the cart's reference point.
    pub fn new(angle: f64, range: f64) -> Self {
        SonarReading {
            position: Point::origin(),
            angle,
            range,
        }
    }
}

/// Parameters of the collision avoidance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AvoidParams {
    /// Mode. Default [`AvoidMode::SlowDown`].
    pub mode: AvoidMode,
    /// Obstacles closer than this stop (or hold) the cart, metres. Default 0.4.
    pub stop_range: f64,
    /// Obstacles closer than this slow the cart (or are reported), metres. Default 1.2.
    pub slow_range: f64,
    /// Speed factor just outside `stop_range`, in [0, 1]. Default 0.25.
    pub min_speed_factor: f64,
    /// Half-width of the sector of sonars that count, around the direction of travel,
    /// radians. Default 0.7 (≈ 40°).
    pub sector_half_angle: f64,
}

impl Default for AvoidParams {
    fn default() -> Self {
        AvoidParams {
            mode: AvoidMode::SlowDown,
            stop_range: 0.4,
            slow_range: 1.2,
            min_speed_factor: 0.25,
            sector_half_angle: 0.7,
        }
    }
}

/// What collision avoidance does with a command.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum AvoidDecision {
    /// Nothing in the way (or avoidance off): the command, unchanged.
    Pass(Command),
    /// Warn mode: the command unchanged, and the obstacle.
    Warn {
        /// The command, unchanged.
        command: Command,
        /// Distance to the obstacle, metres.
        distance: f64,
        /// Bearing of the obstacle in the cart frame, radians.
        bearing: f64,
    },
    /// The command with its speed scaled down.
    Slow {
        /// The slowed command.
        command: Command,
        /// Distance to the obstacle, metres.
        distance: f64,
        /// Bearing of the obstacle in the cart frame, radians.
        bearing: f64,
    },
    /// Slow-down mode, obstacle within stop range: stand still until it is gone.
    Hold {
        /// Distance to the obstacle, metres.
        distance: f64,
        /// Bearing of the obstacle in the cart frame, radians.
        bearing: f64,
    },
    /// Controlled stop: the cart stops; the operation reports it.
    Stopped {
        /// Distance to the obstacle, metres.
        distance: f64,
        /// Bearing of the obstacle in the cart frame, radians.
        bearing: f64,
    },
}

impl AvoidDecision {
    /// The command to send to the cart.
    pub fn command(&self) -> Command {
        match *self {
            AvoidDecision::Pass(c)
            | AvoidDecision::Warn { command: c, .. }
            | AvoidDecision::Slow { command: c, .. } => c,
            AvoidDecision::Hold { .. } | AvoidDecision::Stopped { .. } => Command::STOP,
        }
    }

    /// The obstacle (distance, bearing) that shaped the decision, if any.
    pub fn obstacle(&self) -> Option<(f64, f64)> {
        match *self {
            AvoidDecision::Pass(_) => None,
            AvoidDecision::Warn {
                distance, bearing, ..
            }
            | AvoidDecision::Slow {
                distance, bearing, ..
            }
            | AvoidDecision::Hold { distance, bearing }
            | AvoidDecision::Stopped { distance, bearing } => Some((distance, bearing)),
        }
    }

    /// True for a controlled stop.
    pub fn is_stopped(&self) -> bool {
        matches!(self, AvoidDecision::Stopped { .. })
    }
}

/// The nearest obstacle in the direction of travel of `command`, as (distance, bearing).
pub fn nearest_ahead(
    readings: &[SonarReading],
    command: Command,
    params: &AvoidParams,
) -> Option<(f64, f64)> {
    if !(command.speed.is_finite() && command.speed != 0.0) {
        return None;
    }
    let travel = if command.speed > 0.0 { 0.0 } else { PI };
    let half = params.sector_half_angle.abs();
    readings
        .iter()
        .filter(|r| r.range >= 0.0 && r.range.is_finite() && r.angle.is_finite())
        .filter(|r| wrap_angle(r.angle - travel).abs() <= half)
        .map(|r| (r.range, wrap_angle(r.angle)))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
}

/// Decide what to do with `command` given the sonar `readings` (memoryless).
pub fn avoid(readings: &[SonarReading], command: Command, params: &AvoidParams) -> AvoidDecision {
    if params.mode == AvoidMode::Off {
        return AvoidDecision::Pass(command);
    }
    let Some((distance, bearing)) = nearest_ahead(readings, command, params) else {
        return AvoidDecision::Pass(command);
    };
    let stop = params.stop_range.max(0.0);
    let slow = params.slow_range.max(stop);
    if distance > slow {
        return AvoidDecision::Pass(command);
    }
    match params.mode {
        AvoidMode::Off => AvoidDecision::Pass(command),
        AvoidMode::Warn => AvoidDecision::Warn {
            command,
            distance,
            bearing,
        },
        AvoidMode::SlowDown | AvoidMode::ControlledStop if distance <= stop => {
            if params.mode == AvoidMode::SlowDown {
                AvoidDecision::Hold { distance, bearing }
            } else {
                AvoidDecision::Stopped { distance, bearing }
            }
        }
        AvoidMode::SlowDown | AvoidMode::ControlledStop => {
            let min = params.min_speed_factor.clamp(0.0, 1.0);
            let frac = if slow - stop > 1e-9 {
                ((distance - stop) / (slow - stop)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let factor = min + (1.0 - min) * frac;
            AvoidDecision::Slow {
                command: Command::new(command.speed * factor, command.steer),
                distance,
                bearing,
            }
        }
    }
}

/// Collision avoidance with a latched controlled stop: once stopped, it stays stopped (in
/// every mode) until [`CollisionAvoidance::reset`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CollisionAvoidance {
    /// Parameters (the mode may change between steps).
    pub params: AvoidParams,
    stopped: Option<(f64, f64)>,
}

impl CollisionAvoidance {
    /// A fresh, not stopped, avoidance.
    pub fn new(params: AvoidParams) -> Self {
        CollisionAvoidance {
            params,
            stopped: None,
        }
    }

    /// Filter one command.
    pub fn step(&mut self, readings: &[SonarReading], command: Command) -> AvoidDecision {
        if let Some((distance, bearing)) = self.stopped {
            return AvoidDecision::Stopped { distance, bearing };
        }
        let d = avoid(readings, command, &self.params);
        if let AvoidDecision::Stopped { distance, bearing } = d {
            self.stopped = Some((distance, bearing));
        }
        d
    }

    /// The latched stop (distance, bearing), if any.
    pub fn stopped(&self) -> Option<(f64, f64)> {
        self.stopped
    }

    /// Release the latched stop.
    pub fn reset(&mut self) {
        self.stopped = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(front: f64, back: f64) -> Vec<SonarReading> {
        vec![
            SonarReading::new(0.0, front),
            SonarReading::new(0.5, f64::INFINITY),
            SonarReading::new(PI / 2.0, 0.2), // beside the cart: never counts
            SonarReading::new(PI, back),
            SonarReading::new(-PI + 0.3, f64::INFINITY),
        ]
    }

    #[test]
    fn modes() {
        let fwd = Command::new(0.4, 0.1);
        let mut p = AvoidParams::default();
        assert_eq!(avoid(&ring(3.0, 0.1), fwd, &p), AvoidDecision::Pass(fwd));
        let d = avoid(&ring(0.8, 3.0), fwd, &p);
        assert!(matches!(d, AvoidDecision::Slow { .. }));
        assert!(d.command().speed < 0.4 && d.command().speed > 0.1);
        assert_eq!(d.command().steer, 0.1);
        assert!(matches!(
            avoid(&ring(0.3, 3.0), fwd, &p),
            AvoidDecision::Hold { .. }
        ));
        p.mode = AvoidMode::ControlledStop;
        let d = avoid(&ring(0.3, 3.0), fwd, &p);
        assert_eq!(
            d,
            AvoidDecision::Stopped {
                distance: 0.3,
                bearing: 0.0
            }
        );
        assert!(d.command().is_stop());
        p.mode = AvoidMode::Warn;
        assert!(matches!(
            avoid(&ring(0.3, 3.0), fwd, &p),
            AvoidDecision::Warn { command, .. } if command == fwd
        ));
        p.mode = AvoidMode::Off;
        assert_eq!(avoid(&ring(0.0, 0.0), fwd, &p), AvoidDecision::Pass(fwd));
    }

    #[test]
    fn direction_of_travel_decides() {
        let p = AvoidParams {
            mode: AvoidMode::ControlledStop,
            ..AvoidParams::default()
        };
        let back = Command::new(-0.3, 0.0);
        assert_eq!(avoid(&ring(0.1, 3.0), back, &p), AvoidDecision::Pass(back));
        let d = avoid(&ring(3.0, 0.35), back, &p);
        assert!(d.is_stopped());
        assert_eq!(d.obstacle(), Some((0.35, PI)));
        let still = Command::new(0.0, 0.2);
        assert_eq!(
            avoid(&ring(0.0, 0.0), still, &p),
            AvoidDecision::Pass(still)
        );
        let bad = [
            SonarReading::new(0.0, f64::NAN),
            SonarReading::new(0.0, -1.0),
        ];
        assert_eq!(
            avoid(&bad, Command::new(1.0, 0.0), &p),
            AvoidDecision::Pass(Command::new(1.0, 0.0))
        );
    }

    #[test]
    fn controlled_stop_latches() {
        let mut ca = CollisionAvoidance::new(AvoidParams {
            mode: AvoidMode::ControlledStop,
            ..AvoidParams::default()
        });
        let fwd = Command::new(0.4, 0.0);
        assert!(ca.step(&ring(0.2, 3.0), fwd).is_stopped());
        assert!(ca.step(&ring(5.0, 5.0), fwd).is_stopped());
        ca.reset();
        assert_eq!(ca.step(&ring(5.0, 5.0), fwd), AvoidDecision::Pass(fwd));
    }
}

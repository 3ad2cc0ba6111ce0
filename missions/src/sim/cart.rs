//! The virtual cart: car-like kinematics (a steered front axle and a driven rear axle, the
//! thesis' steering and drive motors) and the actuators' dynamics.

use crate::geom::{wrap_angle, Pose};
use crate::world::CartSpec;

/// Steering below this (radians) is integrated as a straight line.
const STRAIGHT: f64 = 1e-9;

/// One step of the kinematic bicycle model, integrated exactly for constant `speed` and
/// `steer` over `dt`:
///
/// x' = v cos θ, y' = v sin θ, θ' = v / L · tan φ
///
/// `pose` is the rear-axle centre, `wheelbase` is L. With constant inputs the rear axle drives
/// a circle of radius L / tan φ, which this reproduces to rounding.
pub fn bicycle_step(pose: &Pose, speed: f64, steer: f64, wheelbase: f64, dt: f64) -> Pose {
    let ds = speed * dt;
    let curvature = steer.tan() / wheelbase;
    if !(curvature.is_finite() && ds.is_finite()) {
        return *pose;
    }
    let dtheta = ds * curvature;
    if dtheta.abs() < STRAIGHT {
        // straight (or nearly): the midpoint heading keeps it second-order accurate
        let mid = pose.theta + dtheta / 2.0;
        return Pose::new(
            pose.x + ds * mid.cos(),
            pose.y + ds * mid.sin(),
            pose.theta + dtheta,
        );
    }
    let radius = 1.0 / curvature;
    let theta1 = pose.theta + dtheta;
    Pose::new(
        pose.x + radius * (theta1.sin() - pose.theta.sin()),
        pose.y - radius * (theta1.cos() - pose.theta.cos()),
        wrap_angle(theta1),
    )
}

/// The drive and steering actuators: the speed follows its target with a first-order lag,
/// the steering angle with a rate limit; both stay within the cart's limits.
#[derive(Clone, Debug, PartialEq)]
pub struct Drive {
    spec: CartSpec,
    speed: f64,
    steer: f64,
}

impl Drive {
    /// A drive at rest, wheels straight.
    pub fn new(spec: CartSpec) -> Self {
        Drive {
            spec,
            speed: 0.0,
            steer: 0.0,
        }
    }

    /// The cart's limits.
    pub fn spec(&self) -> &CartSpec {
        &self.spec
    }

    /// Actual speed, m/s (negative: backwards).
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Actual steering angle, radians (positive: to the left).
    pub fn steer(&self) -> f64 {
        self.steer
    }

    /// Clamp a commanded speed to the limits (non-finite → 0).
    pub fn clamp_speed(&self, speed: f64) -> f64 {
        if speed.is_finite() {
            speed.clamp(-self.spec.max_speed, self.spec.max_speed)
        } else {
            0.0
        }
    }

    /// Clamp a commanded steering angle to the limits (non-finite → 0).
    pub fn clamp_steer(&self, steer: f64) -> f64 {
        if steer.is_finite() {
            steer.clamp(-self.spec.max_steer, self.spec.max_steer)
        } else {
            0.0
        }
    }

    /// Stop the wheels at once (collision, emergency stop).
    pub fn halt(&mut self) {
        self.speed = 0.0;
    }

    /// Let the actuators move towards `speed` and `steer` (clamped) for `dt` seconds.
    pub fn update(&mut self, dt: f64, speed: f64, steer: f64) {
        if !(dt > 0.0 && dt.is_finite()) {
            return;
        }
        let speed = self.clamp_speed(speed);
        let steer = self.clamp_steer(steer);
        let tau = self.spec.speed_time_constant;
        self.speed = if tau > 0.0 {
            let next = self.speed + (speed - self.speed) * (1.0 - (-dt / tau).exp());
            // settle exactly rather than creep forever
            if (next - speed).abs() < 1e-9 {
                speed
            } else {
                next
            }
        } else {
            speed
        };
        let max_delta = self.spec.max_steer_rate * dt;
        self.steer += (steer - self.steer).clamp(-max_delta, max_delta);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn straight_and_quarter_circle() {
        let p = bicycle_step(&Pose::new(0.0, 0.0, 0.0), 1.0, 0.0, 0.7, 2.0);
        assert!((p.x - 2.0).abs() < 1e-12 && p.y.abs() < 1e-12);
        // radius 1: L = tan φ
        let phi = (0.7f64).atan();
        let p = bicycle_step(&Pose::new(0.0, 0.0, 0.0), 1.0, phi, 0.7, PI / 2.0);
        assert!(
            (p.x - 1.0).abs() < 1e-9 && (p.y - 1.0).abs() < 1e-9,
            "{p:?}"
        );
        assert!((p.theta - PI / 2.0).abs() < 1e-9);
    }

    #[test]
    fn actuators_lag_and_rate_limit() {
        let spec = CartSpec::default();
        let mut d = Drive::new(spec);
        d.update(spec.speed_time_constant, 10.0, 1.0);
        // one time constant: 1 - 1/e of the clamped target
        assert!((d.speed() - spec.max_speed * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        assert!((d.steer() - spec.max_steer_rate * spec.speed_time_constant).abs() < 1e-12);
        for _ in 0..100 {
            d.update(0.1, f64::NAN, 1.0);
        }
        assert_eq!(d.speed(), 0.0);
        assert!((d.steer() - spec.max_steer).abs() < 1e-12);
    }
}

//! The sensor-based controller (1513): aligns the cart with the followed wall, backs along
//! it, or cruises straight ahead.

use super::follow::{follow_params, follow_step};
use super::{stop_cart, CONTROL_PERIOD};
use crate::algo::follow::{FollowMode, FollowParams};
use crate::hardware::CartClient;
use crate::ops::{cart, cart_err};
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use std::time::Duration;

marie_actors::choice! {
    /// What the sensor-based controller does.
    pub enum SensorBasedMode {
        /// Align with the followed wall, then finish.
        Align = "align",
        /// Back along the followed wall until suspended.
        Back = "back",
        /// Cruise straight ahead until suspended.
        Cruise = "cruise",
    }
}

marie_actors::params! {
    /// The sensor-based controller's parameters.
    pub struct SensorBasedControllerParams {
        /// align with the wall (finishes), back along it, or cruise straight ahead (until
        /// suspended)
        pub mode: SensorBasedMode = SensorBasedMode::Align;
        /// distance kept from the wall
        pub distance: f64 = 0.6, range(0.3, 3.0), unit("m");
        /// speed, forwards when aligning, backwards when backing
        pub speed: f64 = 0.25, range(0.05, 1.0), unit("m/s");
        /// distance error within which the cart counts as aligned
        pub tolerance: f64 = 0.1, range(0.01, 1.0), unit("m");
    }
}

marie_actors::flags! {
    /// What the sensor-based controller reports.
    pub enum SensorBasedControllerFlag {
        /// the cart runs along the wall at the requested distance
        Aligned = "aligned",
    }
}

/// The sensor-based controller: aligns the cart with the followed wall (finishing with
/// `aligned` once it has held the distance and heading for a moment), backs along it until
/// suspended — the corner mission's last two stages —, or cruises straight ahead until
/// suspended (so that a sonar robot, which sees walls only by moving along them, can find
/// one).
#[derive(Debug, Default)]
pub struct SensorBasedController {
    cart: Option<CartClient>,
    aligned_steps: u32,
}

/// Control steps the alignment must hold before it counts.
const ALIGNED_STEPS: u32 = 6;

/// Heading error (rad) within which the cart counts as parallel to the wall.
const ALIGN_ANGLE_TOLERANCE: f64 = 0.08;

impl Operation for SensorBasedController {
    fn identity(&self) -> Identity {
        Identity::new(
            "sensor-based-controller",
            1513,
            "1.0.0",
            "aligns with or backs along the followed wall",
        )
    }

    fn parameters(&self) -> ParamSchema {
        SensorBasedControllerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        SensorBasedControllerFlag::decls()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.aligned_steps = 0;
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: SensorBasedControllerParams = ctx.params().read()?;
        let speed = p.speed;
        if p.mode == SensorBasedMode::Cruise {
            let status = cart(&mut self.cart, ctx)?
                .status()
                .await
                .map_err(cart_err)?;
            if status.collided {
                return Err(OpError::failed("the cart collided while cruising"));
            }
            cart(&mut self.cart, ctx)?
                .drive(speed, 0.0)
                .map_err(cart_err)?;
            return Ok(Step::Continue);
        }
        let back = p.mode == SensorBasedMode::Back;
        let tolerance = p.tolerance;
        let params = FollowParams {
            distance_tolerance: tolerance,
            angle_tolerance: ALIGN_ANGLE_TOLERANCE,
            ..follow_params(
                p.distance,
                FollowMode::Wall,
                if back { -speed } else { speed },
            )
        };
        let (aligned, _) = follow_step(ctx, &mut self.cart, &params).await?;
        if back {
            return Ok(Step::Continue);
        }
        self.aligned_steps = if aligned { self.aligned_steps + 1 } else { 0 };
        if self.aligned_steps >= ALIGNED_STEPS {
            stop_cart(&mut self.cart, ctx)?;
            return Ok(Step::finish(SensorBasedControllerFlag::Aligned));
        }
        Ok(Step::Continue)
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        stop_cart(&mut self.cart, ctx)
    }
}

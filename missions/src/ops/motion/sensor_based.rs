//! The sensor-based controller (1513): aligns the cart with the followed wall, backs along
//! it, or cruises straight ahead.

use super::follow::{follow_params, follow_step};
use super::{stop_cart, CONTROL_PERIOD};
use crate::algo::follow::{FollowMode, FollowParams};
use crate::hardware::CartClient;
use crate::ops::{cart, cart_err};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_actors::flags::{FlagDecl, StatusFlags};
use marie_actors::property::{ParamDecl, ParamSchema};
use std::time::Duration;

/// The sensor-based controller: aligns the cart with the followed wall (finishing with
/// `aligned` once it has held the distance and heading for a moment), backs along it until
/// suspended — the corner mission's last two stages —, or cruises straight ahead until
/// suspended (so that a sonar robot, which sees walls only by moving along them, can find
/// one).
#[derive(Default)]
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
        ParamSchema::new(vec![
            ParamDecl::choice("mode", &["align", "back", "cruise"], "align")
                .describe("align with the wall (finishes), back along it, or cruise straight ahead (until suspended)"),
            ParamDecl::float("distance", 0.6)
                .range(0.3, 3.0)
                .unit("m")
                .describe("distance kept from the wall"),
            ParamDecl::float("speed", 0.25)
                .range(0.05, 1.0)
                .unit("m/s")
                .describe("speed, forwards when aligning, backwards when backing"),
            ParamDecl::float("tolerance", 0.1)
                .range(0.01, 1.0)
                .unit("m")
                .describe("distance error within which the cart counts as aligned"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "aligned",
            "the cart runs along the wall at the requested distance",
        )]
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.aligned_steps = 0;
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let mode = p.text("mode")?;
        let speed = p.f64("speed")?;
        if mode == "cruise" {
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
        let back = mode == "back";
        let tolerance = p.f64("tolerance")?;
        let params = FollowParams {
            distance_tolerance: tolerance,
            angle_tolerance: ALIGN_ANGLE_TOLERANCE,
            ..follow_params(
                p.f64("distance")?,
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
            return Ok(Step::Finish(StatusFlags(1)));
        }
        Ok(Step::Continue)
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        stop_cart(&mut self.cart, ctx)
    }
}

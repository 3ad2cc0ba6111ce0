//! Collision avoidance (1519): watches the sonars in the direction of travel and acts on the
//! cart — four modes, one of them the thesis' controlled stop.

use super::{cart, cart_err};
use crate::algo::avoid::{avoid, AvoidDecision, AvoidMode, AvoidParams, SonarReading};
use crate::algo::Command;
use crate::hardware::CartClient;
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use std::time::Duration;

marie_actors::choice! {
    /// What collision avoidance does about obstacles ahead (see [`CollisionAvoidance`]).
    pub enum AvoidanceMode {
        /// Nothing.
        Off = "off",
        /// Raise `obstacle`.
        Warn = "warn",
        /// Cap the speed near obstacles, hold the cart while one is within the stop range.
        SlowDown = "slow-down",
        /// Slow near an obstacle and stop for good within the stop range.
        ControlledStop = "controlled-stop",
    }
}

marie_actors::params! {
    /// Collision avoidance's parameters.
    pub struct CollisionAvoidanceParams {
        /// what to do about obstacles ahead
        pub mode: AvoidanceMode = AvoidanceMode::SlowDown;
        /// obstacles nearer than this stop the cart
        pub stop_range: f64 = AvoidParams::default().stop_range, range(0.05, 5.0), unit("m");
        /// obstacles nearer than this slow the cart
        pub slow_range: f64 = AvoidParams::default().slow_range, range(0.05, 10.0), unit("m");
    }
}

marie_actors::flags! {
    /// What collision avoidance reports.
    pub enum CollisionAvoidanceFlag {
        /// an obstacle is near in the direction of travel
        Obstacle = "obstacle",
        /// the controlled stop halted the cart before an obstacle
        Stopped = "stopped",
    }
}

/// Collision avoidance. Modes:
/// - `off`: does nothing;
/// - `warn`: raises `obstacle` when something is within the slow range ahead;
/// - `slow-down`: caps the cart's speed near obstacles and holds it (emergency stop) while one
///   is within the stop range, releasing when it is gone;
/// - `controlled-stop`: slows near an obstacle and stops for good within the stop range,
///   finishing with `stopped` — the end of a manoeuvre such as backing into a corner.
#[derive(Debug, Default)]
pub struct CollisionAvoidance {
    cart: Option<CartClient>,
    holding: bool,
    capped: bool,
}

impl Operation for CollisionAvoidance {
    fn identity(&self) -> Identity {
        Identity::new(
            "collision-avoidance",
            1519,
            "1.0.0",
            "slows or stops the cart before obstacles",
        )
    }

    fn parameters(&self) -> ParamSchema {
        CollisionAvoidanceParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        CollisionAvoidanceFlag::decls()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(100)
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.holding = false;
        self.capped = false;
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: CollisionAvoidanceParams = ctx.params().read()?;
        let params = AvoidParams {
            mode: match p.mode {
                AvoidanceMode::Off => AvoidMode::Off,
                AvoidanceMode::Warn => AvoidMode::Warn,
                AvoidanceMode::SlowDown => AvoidMode::SlowDown,
                AvoidanceMode::ControlledStop => AvoidMode::ControlledStop,
            },
            stop_range: p.stop_range,
            slow_range: p.slow_range,
            ..AvoidParams::default()
        };
        if params.mode == AvoidMode::Off {
            return Ok(Step::Continue);
        }
        let cart = cart(&mut self.cart, ctx)?.clone();
        let status = cart.status().await.map_err(cart_err)?;
        let scan = cart.scan().await.map_err(cart_err)?;
        let readings: Vec<SonarReading> = scan
            .readings
            .iter()
            .filter_map(|r| {
                let mount = scan.mounts.get(r.sensor)?;
                Some(SonarReading {
                    position: mount.point(),
                    angle: mount.theta,
                    range: r.range.unwrap_or(f64::INFINITY),
                })
            })
            .collect();
        // judge by the commanded direction: a cart held by the stop has speed 0
        let (speed, steer) = status.commanded;
        let decision = avoid(&readings, Command::new(speed, steer), &params);
        match decision {
            AvoidDecision::Stopped { distance, .. } => {
                cart.emergency_stop(true).map_err(cart_err)?;
                tracing::info!(distance, "controlled stop");
                return Ok(Step::finish(
                    CollisionAvoidanceFlag::Obstacle | CollisionAvoidanceFlag::Stopped,
                ));
            }
            AvoidDecision::Hold { .. } => {
                cart.emergency_stop(true).map_err(cart_err)?;
                self.holding = true;
                ctx.raise(CollisionAvoidanceFlag::Obstacle);
            }
            AvoidDecision::Slow { command, .. } => {
                self.release_hold(&cart)?;
                cart.speed_cap(Some(command.speed.abs()))
                    .map_err(cart_err)?;
                self.capped = true;
                ctx.raise(CollisionAvoidanceFlag::Obstacle);
            }
            AvoidDecision::Warn { .. } => ctx.raise(CollisionAvoidanceFlag::Obstacle),
            AvoidDecision::Pass(_) => {
                self.release_hold(&cart)?;
                if self.capped {
                    cart.speed_cap(None).map_err(cart_err)?;
                    self.capped = false;
                }
            }
        }
        Ok(Step::Continue)
    }

    async fn suspend(&mut self, _ctx: &mut OpContext) -> Result<(), OpError> {
        // a controlled stop stays in force (it ended the manoeuvre); a hold or cap is lifted
        if let Some(cart) = self.cart.clone() {
            self.release_hold(&cart)?;
            if self.capped {
                cart.speed_cap(None).map_err(cart_err)?;
                self.capped = false;
            }
        }
        Ok(())
    }
}

impl CollisionAvoidance {
    fn release_hold(&mut self, cart: &CartClient) -> Result<(), OpError> {
        if self.holding {
            cart.emergency_stop(false).map_err(cart_err)?;
            self.holding = false;
        }
        Ok(())
    }
}

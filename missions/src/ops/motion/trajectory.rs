//! The trajectory controller (1511): drives the planned path with pure pursuit, leg by leg,
//! each command checked by the clearance guard against what the sonars hear.

use super::{footprint_of, stop_cart, CONTROL_PERIOD};
use crate::algo::clearance::{check, Echo, GuardParams, Trip};
use crate::algo::parking::Footprint;
use crate::algo::planner::Path;
use crate::algo::pursuit::{PurePursuit, PursuitParams, PursuitStatus};
use crate::geom::Pose;
use crate::hardware::CartClient;
use crate::ops::records::{LegRecord, ProgressRecord, PATH, PROGRESS};
use crate::ops::{cart, cart_err, dm_err, located, newest, newest_with_seq};
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::PARAMETER;
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use std::time::Duration;

marie_actors::params! {
    /// The trajectory controller's parameters.
    pub struct TrajectoryControllerParams {
        /// cruise speed
        pub speed: f64 = PursuitParams::default().speed, range(0.05, 2.0), unit("m/s");
        /// pure-pursuit lookahead distance
        pub lookahead: f64 = PursuitParams::default().lookahead, range(0.1, 5.0), unit("m");
        /// how close to the end counts as arrived
        pub position_tolerance: f64 = PursuitParams::default().position_tolerance.max(0.1),
            range(0.01, 2.0), unit("m");
        /// heading error accepted at the end (0: not checked)
        pub heading_tolerance: f64 = 0.0, range(0.0, 180.0), unit("deg");
    }
}

marie_actors::flags! {
    /// What the trajectory controller reports.
    pub enum TrajectoryControllerFlag {
        /// the planned path was driven to its end
        Driven = "path-driven",
    }
}

/// Drives the newest planned path with pure pursuit, leg by leg (changing direction between
/// legs); finishes by itself with `path-driven`.
#[derive(Debug, Default)]
pub struct TrajectoryController {
    cart: Option<CartClient>,
    params: Option<PursuitParams>,
    legs: Vec<LegRecord>,
    pursuit: Option<(PurePursuit, Path)>,
    /// Sequence number of the path record being driven.
    path_seq: u64,
    /// Index of the leg being driven.
    leg: usize,
    /// Progress saved last: `(leg, along)`.
    saved: Option<(usize, f64)>,
    /// Straightening after the clearance guard stopped the last, backing leg in its tail.
    settling: bool,
}

/// How much further along than the saved progress the controller saves again, m.
const PROGRESS_STEP: f64 = 0.1;

impl TrajectoryController {
    /// Start the next leg; false when none is left.
    fn next_leg(&mut self) -> bool {
        let (Some(params), false) = (self.params, self.legs.is_empty()) else {
            return false;
        };
        if self.pursuit.is_some() {
            self.leg += 1;
        }
        let leg = self.legs.remove(0);
        let mut path = Path::new(leg.waypoints);
        if let Some(h) = leg.goal_heading {
            path = path.with_heading(h);
        }
        let params = PursuitParams {
            reverse: leg.reverse,
            ..params
        };
        self.pursuit = Some((PurePursuit::with_path(params, path.clone()), path));
        true
    }

    /// The clearance guard stopped the cart on the last, backing leg within [`parked_zone`] of
    /// its end: the cart is in the spot, its heading still swinging, and backing on would
    /// touch the spot's wall. So it pulls forward [`SETTLE_LENGTH`] along the leg's end line,
    /// as a driver straightens a car the parking sensor stopped. False (finish where it
    /// stands) when it has done so already or the leg was not a backing one.
    fn settle(&mut self, pose: &Pose) -> bool {
        let Some((pursuit, path)) = &self.pursuit else {
            return false;
        };
        let (Some(params), Some(heading)) = (self.params, path.goal_heading) else {
            return false;
        };
        if self.settling || !pursuit.params.reverse {
            return false;
        }
        // along the leg's own end line (the spot's middle), from abreast of the cart: pulling
        // forward along its tilted heading would take its front out across the opening
        let Some(&end) = path.waypoints.last() else {
            return false;
        };
        let dir = Pose::new(end.x, end.y, heading).heading();
        let abreast = end + dir * (pose.point() - end).dot(&dir);
        let path = Path::new(vec![abreast, abreast + dir * SETTLE_LENGTH]).with_heading(heading);
        let params = PursuitParams {
            reverse: false,
            ..params
        };
        self.pursuit = Some((PurePursuit::with_path(params, path.clone()), path));
        self.settling = true;
        true
    }

    /// Save the progress in the parameter DM once it moved on enough since the last save.
    fn save_progress(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        let Some((pursuit, _)) = &self.pursuit else {
            return Ok(());
        };
        let along = pursuit.progress();
        let due = match self.saved {
            Some((leg, saved)) => leg != self.leg || along >= saved + PROGRESS_STEP,
            None => true,
        };
        if due {
            let record = ProgressRecord {
                path_seq: self.path_seq,
                leg: self.leg,
                along,
            };
            ctx.dm(PARAMETER)?
                .put_kind(PROGRESS, &record)
                .map_err(dm_err(PARAMETER))?;
            self.saved = Some((self.leg, along));
        }
        Ok(())
    }
}

impl Operation for TrajectoryController {
    fn identity(&self) -> Identity {
        Identity::new(
            "trajectory-controller",
            1511,
            "1.0.0",
            "drives the planned path",
        )
    }

    fn parameters(&self) -> ParamSchema {
        TrajectoryControllerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        TrajectoryControllerFlag::decls()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let (path_seq, record) = newest_with_seq(ctx, PARAMETER, PATH)
            .await?
            .ok_or_else(|| OpError::failed("no planned path in the parameter DM"))?;
        let p: TrajectoryControllerParams = ctx.params().read()?;
        let heading_tol = p.heading_tolerance;
        self.params = Some(PursuitParams {
            speed: p.speed,
            lookahead: p.lookahead,
            position_tolerance: p.position_tolerance,
            heading_tolerance: (heading_tol > 0.0).then(|| heading_tol.to_radians()),
            ..PursuitParams::default()
        });
        self.legs = record.legs;
        self.pursuit = None;
        self.path_seq = path_seq;
        self.leg = 0;
        self.saved = None;
        self.settling = false;
        // a predecessor that crashed on this path left its progress behind: resume there
        let progress = match ctx.resumed() {
            true => newest(ctx, PARAMETER, PROGRESS).await?,
            false => None,
        };
        let resume = progress.filter(|p| p.path_seq == path_seq && p.leg < self.legs.len());
        if let Some(p) = resume {
            self.legs.drain(..p.leg);
        }
        if !self.next_leg() {
            return Err(OpError::failed("the planned path has no legs"));
        }
        if let (Some(p), Some((pursuit, _))) = (resume, self.pursuit.as_mut()) {
            self.leg = p.leg;
            pursuit.resume_at(p.along);
            self.saved = Some((p.leg, p.along));
            tracing::info!(
                leg = p.leg,
                along = p.along,
                "resuming the path where it was left"
            );
        }
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let status = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?;
        if status.collided {
            return Err(OpError::failed(format!(
                "the cart collided at ({:.2}, {:.2})",
                status.pose.x, status.pose.y
            )));
        }
        let pose = located(ctx, &status.odometry).await?;
        let Some((pursuit, path)) = self.pursuit.as_mut() else {
            return Err(OpError::failed("activated without a path"));
        };
        match pursuit.status(&pose) {
            PursuitStatus::Arrived => {
                stop_cart(&mut self.cart, ctx)?;
                if self.next_leg() {
                    return Ok(Step::Continue);
                }
                return Ok(Step::finish(TrajectoryControllerFlag::Driven));
            }
            PursuitStatus::Overshot => {
                stop_cart(&mut self.cart, ctx)?;
                return Err(OpError::failed(format!(
                    "overshot the end of the path at ({:.2}, {:.2}, {:.0}°)",
                    pose.x,
                    pose.y,
                    pose.theta.to_degrees()
                )));
            }
            PursuitStatus::Tracking => {}
        }
        let cmd = pursuit.command(&pose, path);
        let remaining = pursuit.remaining();
        let last_leg = self.legs.is_empty();
        let footprint = footprint_of(&status);
        if let Some(trip) = guard(&mut self.cart, ctx, &footprint, cmd).await? {
            if last_leg && (self.settling || remaining <= parked_zone(path)) {
                if self.settle(&pose) {
                    tracing::info!(
                        clearance = trip.clearance,
                        remaining,
                        "stopped in the spot by the sonar: straightening forwards"
                    );
                    return Ok(Step::Continue);
                }
                tracing::info!(
                    clearance = trip.clearance,
                    remaining,
                    "the sonar says the spot's end is reached: stopped there"
                );
                return Ok(Step::finish(TrajectoryControllerFlag::Driven));
            }
            return Err(OpError::failed(format!(
                "stopped {remaining:.2} m before the end of leg {}: the sonar hears something \
                 {:.3} m from the cart's outline, which the path would bring nearer",
                self.leg, trip.clearance
            )));
        }
        cart(&mut self.cart, ctx)?
            .drive(cmd.speed, cmd.steer)
            .map_err(cart_err)?;
        self.save_progress(ctx)?;
        Ok(Step::Continue)
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        stop_cart(&mut self.cart, ctx)
    }
}

/// On the last leg `path`, how near its end (m) a stop by the clearance guard means the
/// cart is in the spot: the manoeuvre's straight tail (as planned: [`Path::straight_end`])
/// and the last [`ARC_END`] of the arc before it, where the cart is between the spot's ends
/// and only its heading still settles.
fn parked_zone(path: &Path) -> f64 {
    path.straight_end() + ARC_END
}

/// The end of a parking arc that still counts as in the spot, m.
const ARC_END: f64 = 0.2;

/// How far ahead of where the clearance guard stopped it the cart aims when it straightens
/// in the spot, m (it ends within the position tolerance of that, so it moves about 0.25 m):
/// room to turn the heading by the ten-odd degrees a backing manoeuvre leaves, and within the
/// room the manoeuvre left ahead of the cart (its goal slides deep into the spot).
const SETTLE_LENGTH: f64 = 0.35;

/// Check `cmd` with the clearance guard against the cart's current sonar scan; when it
/// trips, the cart is halted at once (wheels stopped without the drive's lag; the emergency
/// stop, which collision avoidance may hold, is left alone) and the trip returned.
async fn guard(
    slot: &mut Option<CartClient>,
    ctx: &OpContext,
    footprint: &Footprint,
    cmd: crate::algo::Command,
) -> Result<Option<Trip>, OpError> {
    if cmd.is_stop() {
        return Ok(None);
    }
    let cart = cart(slot, ctx)?.clone();
    let scan = cart.scan().await.map_err(cart_err)?;
    let echoes: Vec<Echo> = scan
        .readings
        .iter()
        .filter_map(|r| {
            Some(Echo {
                mount: *scan.mounts.get(r.sensor)?,
                half_angle: r.half_angle,
                range: r.range?,
            })
        })
        .collect();
    let Some(trip) = check(&echoes, footprint, cmd, &GuardParams::default()) else {
        return Ok(None);
    };
    cart.halt().map_err(cart_err)?;
    tracing::info!(
        clearance = trip.clearance,
        ahead = trip.ahead,
        x = trip.point.x,
        y = trip.point.y,
        "clearance guard: stopped before an echo"
    );
    Ok(Some(trip))
}

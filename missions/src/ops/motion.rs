//! Motion: the path planner (1515), the trajectory controller (1511), the wall follower
//! (1514, versions 1 and 2), the sensor-based controller (1513).
//!
//! Controllers command the virtual cart directly (it is hardware, not an operation) and stop
//! it when suspended.

use super::perception::wall_from;
use super::records::{
    DockRecord, LegRecord, PathRecord, ProgressRecord, SegmentSet, WallRecord, DOCK, MAP, PATH,
    PROGRESS, SEGMENTS, WALL,
};
use super::{cart, cart_err, dm_err, located, newest, newest_with_seq};
use crate::algo::clearance::{check, Echo, GuardParams, Trip};
use crate::algo::follow::{follow_command, is_aligned, FollowMode, FollowParams};
use crate::algo::parking::{plan_parking, Footprint, ParkError, ParkParams};
use crate::algo::planner::{plan, Bounds, Path, PlannerParams};
use crate::algo::pursuit::{PurePursuit, PursuitParams, PursuitStatus};
use crate::algo::wall::{sense_wall, WallParams};
use crate::geom::{Point, Pose, Segment, Vector};
use crate::hardware::CartClient;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_actors::flags::{FlagDecl, StatusFlags};
use marie_actors::property::{ParamDecl, ParamSchema};
use std::time::Duration;

/// Control period of every controller.
const CONTROL_PERIOD: Duration = Duration::from_millis(50);

fn stop_cart(slot: &mut Option<CartClient>, ctx: &OpContext) -> Result<(), OpError> {
    cart(slot, ctx)?.drive(0.0, 0.0).map_err(cart_err)
}

/// Plans a collision-free path from the cart to a goal on the world map and stores it in the
/// parameter DM; finishes with `path-planned`, fails when there is no path.
#[derive(Default)]
pub struct PathPlanner {
    cart: Option<CartClient>,
}

impl Operation for PathPlanner {
    fn identity(&self) -> Identity {
        Identity::new(
            "path-planner",
            1515,
            "1.0.0",
            "plans a collision-free path on the world map",
        )
    }

    fn parameters(&self) -> ParamSchema {
        let d = PlannerParams::default();
        ParamSchema::new(vec![
            ParamDecl::choice("target", &["dock", "pose"], "dock")
                .describe("plan to the detected dock, or to the pose given below"),
            ParamDecl::float("x", 0.0)
                .range(-1e4, 1e4)
                .unit("m")
                .describe("goal x (target = pose)"),
            ParamDecl::float("y", 0.0)
                .range(-1e4, 1e4)
                .unit("m")
                .describe("goal y (target = pose)"),
            ParamDecl::float("heading", 0.0)
                .range(-360.0, 360.0)
                .unit("deg")
                .describe("goal heading (target = pose)"),
            ParamDecl::float("inflation", d.inflation)
                .range(0.0, 5.0)
                .unit("m")
                .describe("clearance kept from walls"),
            ParamDecl::float("resolution", d.resolution)
                .range(0.01, 1.0)
                .unit("m")
                .describe("grid cell size"),
            ParamDecl::float("approach", d.approach_distance)
                .range(0.0, 10.0)
                .unit("m")
                .describe("straight final approach along the goal heading"),
            ParamDecl::bool("reverse", false).describe("the path is to be driven backwards"),
            ParamDecl::float("park_radius", ParkParams::default().min_radius)
                .range(0.5, 10.0)
                .unit("m")
                .describe(
                    "tightest arc of a parking manoeuvre (target = dock): above the cart's \
                     turning radius, the trajectory controller has steering to spare to \
                     correct its errors",
                ),
            ParamDecl::float("park_tail", ParkParams::default().tail)
                .range(0.0, 5.0)
                .unit("m")
                .describe("straight end of a parking manoeuvre, to settle the heading on"),
            ParamDecl::float("park_clearance", ParkParams::default().clearance)
                .range(0.0, 1.0)
                .unit("m")
                .describe(
                    "clearance every pose of a parking manoeuvre keeps from the walls: a margin \
                     for the controller's tracking error and the pose's",
                ),
            ParamDecl::float("park_shallow", 0.0)
                .range(-0.5, 0.5)
                .unit("m")
                .describe(
                    "the parked cart's goal, this far from the spot's middle towards its \
                     opening: backing along an S, the cart overshoots towards the spot's back \
                     wall while its heading still swings",
                ),
            ParamDecl::float("park_settle", ParkParams::default().settle)
                .range(0.0, 2.0)
                .unit("m")
                .describe(
                    "a parking manoeuvre ends with this long a forward run along the spot, \
                     which straightens the heading the backing left swinging (0: none)",
                ),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "path-planned",
            "a path is stored in the parameter DM",
        )]
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let params = PlannerParams {
            inflation: p.f64("inflation")?,
            resolution: p.f64("resolution")?,
            approach_distance: p.f64("approach")?,
            reverse: p.bool("reverse")?,
            ..PlannerParams::default()
        };
        let target = p.text("target")?.to_string();
        let shallow = p.f64("park_shallow")?;
        let shape = ParkParams {
            min_radius: p.f64("park_radius")?,
            tail: p.f64("park_tail")?,
            clearance: p.f64("park_clearance")?,
            settle: p.f64("park_settle")?,
            ..ParkParams::default()
        };
        let pose_goal = Pose::new(p.f64("x")?, p.f64("y")?, p.f64("heading")?.to_radians());
        let map: Vec<Segment> = newest(ctx, "world", MAP)
            .await?
            .ok_or_else(|| OpError::failed("no map in the world DM"))?;
        let status = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?;
        let start = located(ctx, &status.odometry).await?;
        if target == "dock" {
            let dock: DockRecord = newest(ctx, "world", DOCK)
                .await?
                .ok_or_else(|| OpError::failed("no dock in the world DM to plan to"))?;
            let legs = parking_legs(&start, &dock, &status, &map, shape, shallow)?;
            ctx.dm("parameter")?
                .store(PATH, Some("planned"), None, &PathRecord { legs })
                .await
                .map_err(dm_err("parameter"))?;
            return Ok(Step::Finish(StatusFlags(1)));
        }
        let goal = pose_goal;
        let bounds =
            Bounds::around(&map, 1.0).ok_or_else(|| OpError::failed("the world map is empty"))?;
        let path = plan(&map, &start, &goal, &bounds, &params).map_err(|e| {
            OpError::failed(format!(
                "no path from ({:.2}, {:.2}) to ({:.2}, {:.2}): {e}",
                start.x, start.y, goal.x, goal.y
            ))
        })?;
        let record = PathRecord {
            legs: vec![LegRecord {
                waypoints: path.waypoints.clone(),
                goal_heading: path.goal_heading,
                reverse: params.reverse,
            }],
        };
        ctx.dm("parameter")?
            .store(PATH, Some("planned"), None, &record)
            .await
            .map_err(dm_err("parameter"))?;
        Ok(Step::Finish(StatusFlags(1)))
    }

    async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Finish(StatusFlags(1)))
    }
}

/// Step by which a parking goal that fits nowhere is moved out towards the spot's opening, m.
const GOAL_NUDGE: f64 = 0.02;

/// How many such steps are tried (at most [`GOAL_NUDGE`] × this out of the measured centre).
const GOAL_NUDGES: usize = 6;

/// The parking manoeuvre into `dock` from `start`: the footprint from the cart's own
/// geometry, the goal allowed to slide as deep into the spot as its breadth leaves room for;
/// `shape` gives the arcs and the tail; the goal lies `shallow` metres from the spot's middle
/// towards its opening.
fn parking_legs(
    start: &Pose,
    dock: &DockRecord,
    status: &crate::hardware::CartStatus,
    map: &[Segment],
    shape: ParkParams,
    shallow: f64,
) -> Result<Vec<LegRecord>, OpError> {
    // the map as the cart's pose sees it: moved along the wall so that its recess lies where
    // the sonar found the dock (the pose along a wall drifts with the odometry)
    let seen_map: Vec<Segment>;
    let map = match crate::algo::dock::offset_to_map(&dock.corners, dock.breadth, map) {
        Some(v) => {
            tracing::info!(
                dx = v.x,
                dy = v.y,
                "the dock lies this far from the map's recess: the manoeuvre is checked against the map moved onto it"
            );
            seen_map = map.iter().map(|s| Segment::new(s.a - v, s.b - v)).collect();
            &seen_map[..]
        }
        None => map,
    };
    let footprint = footprint_of(status);
    let length = footprint.rear + footprint.front;
    let params = ParkParams {
        slide: ((dock.breadth - length) / 2.0 - 0.15).max(0.0),
        ..shape
    };
    // arcs of the preferred radius and wider first; only when none fits, the tighter ones
    // down to the cart's turning circle (less steering to spare, but a spot reached)
    let tight = ParkParams {
        min_radius: ParkParams::default().min_radius.min(params.min_radius),
        max_radius: params.min_radius - 0.05,
        ..params
    };
    // the goal moved `shallow` from the spot's middle towards its opening
    let c = &dock.corners;
    let opening = Point::new((c[0].x + c[1].x) / 2.0, (c[0].y + c[1].y) / 2.0);
    let back = Point::new((c[2].x + c[3].x) / 2.0, (c[2].y + c[3].y) / 2.0);
    let out = (opening - back)
        .try_normalize(1e-9)
        .unwrap_or_else(Vector::zeros);
    let attempt = |goal: &Pose| {
        plan_parking(start, goal, &footprint, map, &params).or_else(|e| match e {
            ParkError::Blocked { .. } if tight.max_radius >= tight.min_radius => {
                plan_parking(start, goal, &footprint, map, &tight).map_err(|_| ParkError::Blocked {
                    min: tight.min_radius,
                    max: params.max_radius,
                })
            }
            e => Err(e),
        })
    };
    // the spot's depth is measured by sonar to a few centimetres: a goal that leaves the cart
    // no clearance from the back wall on the map is moved out towards the opening, a little
    // at a time
    let mut result = Err(ParkError::Invalid("no goal tried".into()));
    for k in 0..=GOAL_NUDGES {
        let out_by = shallow + GOAL_NUDGE * k as f64;
        let goal = Pose::new(
            dock.park.x + out.x * out_by,
            dock.park.y + out.y * out_by,
            dock.park.theta,
        );
        match attempt(&goal) {
            Ok(legs) => {
                result = Ok(legs);
                break;
            }
            Err(e) if k == 0 => result = Err(e),
            Err(_) => {}
        }
    }
    let legs = result.map_err(|e| {
        OpError::failed(format!(
            "no parking manoeuvre from ({:.2}, {:.2}) into the dock at ({:.2}, {:.2}): {e}",
            start.x, start.y, dock.park.x, dock.park.y
        ))
    })?;
    Ok(legs
        .into_iter()
        .map(|l| LegRecord {
            waypoints: l.waypoints,
            goal_heading: Some(l.heading),
            reverse: l.reverse,
        })
        .collect())
}

/// The cart's own outline about its reference point, from its status (its size and where its
/// rear axle sits: the cart's geometry, not where it is).
fn footprint_of(status: &crate::hardware::CartStatus) -> Footprint {
    let c = &status.footprint;
    let length = (c[1] - c[0]).norm();
    let width = (c[2] - c[1]).norm();
    let rear = length / 2.0 - status.axle_to_centre;
    Footprint {
        rear,
        front: length - rear,
        half_width: width / 2.0,
    }
}

/// Drives the newest planned path with pure pursuit, leg by leg (changing direction between
/// legs); finishes by itself with `path-driven`.
#[derive(Default)]
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
            ctx.dm("parameter")?
                .put(PROGRESS, Some("driven"), None, &record)
                .map_err(dm_err("parameter"))?;
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
        let d = PursuitParams::default();
        ParamSchema::new(vec![
            ParamDecl::float("speed", d.speed)
                .range(0.05, 2.0)
                .unit("m/s")
                .describe("cruise speed"),
            ParamDecl::float("lookahead", d.lookahead)
                .range(0.1, 5.0)
                .unit("m")
                .describe("pure-pursuit lookahead distance"),
            ParamDecl::float("position_tolerance", d.position_tolerance.max(0.1))
                .range(0.01, 2.0)
                .unit("m")
                .describe("how close to the end counts as arrived"),
            ParamDecl::float("heading_tolerance", 0.0)
                .range(0.0, 180.0)
                .unit("deg")
                .describe("heading error accepted at the end (0: not checked)"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "path-driven",
            "the planned path was driven to its end",
        )]
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let (path_seq, record): (u64, PathRecord) = newest_with_seq(ctx, "parameter", PATH)
            .await?
            .ok_or_else(|| OpError::failed("no planned path in the parameter DM"))?;
        let p = ctx.params();
        let heading_tol = p.f64("heading_tolerance")?;
        self.params = Some(PursuitParams {
            speed: p.f64("speed")?,
            lookahead: p.f64("lookahead")?,
            position_tolerance: p.f64("position_tolerance")?,
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
        let progress: Option<ProgressRecord> = match ctx.resumed() {
            true => newest(ctx, "parameter", PROGRESS).await?,
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
                return Ok(Step::Finish(StatusFlags(1)));
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
                return Ok(Step::Finish(StatusFlags(1)));
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

/// How far the cart may run past the last seen end of the wall before the follower gives up,
/// m: more than a docking spot's breadth, which looks like the wall's end until its far side
/// is seen.
const WALL_END_MARGIN: f64 = 3.5;

fn follow_params(distance: f64, mode: FollowMode, speed: f64) -> FollowParams {
    FollowParams {
        distance,
        mode,
        speed,
        ..FollowParams::default()
    }
}

/// One control step of wall following: reads the wall, steers the cart, and fails once the
/// cart has run past the end of the wall seen so far. Returns whether the cart is aligned,
/// and its pose.
async fn follow_step(
    ctx: &mut OpContext,
    slot: &mut Option<CartClient>,
    params: &FollowParams,
) -> Result<(bool, Pose), OpError> {
    let status = cart(slot, ctx)?.status().await.map_err(cart_err)?;
    if status.collided {
        return Err(OpError::failed(
            "the cart collided while following the wall",
        ));
    }
    let Some(wall) = newest::<WallRecord>(ctx, "world", WALL).await? else {
        return Err(OpError::failed("no wall in the world DM to follow"));
    };
    let now = super::correction(ctx).await?;
    let pose = now.compose(status.odometry);
    let Some(est) = wall_from(&wall.segment_under(&now), &pose) else {
        return Err(OpError::failed("the wall record is degenerate"));
    };
    // progress along the wall, in the direction of travel
    let Some(dir) = (est.line.b - est.line.a).try_normalize(1e-9) else {
        return Err(OpError::failed("the wall record is degenerate"));
    };
    let travel = if params.speed < 0.0 { -1.0 } else { 1.0 };
    let end = if travel > 0.0 { est.line.b } else { est.line.a };
    let past_end = (pose.point() - end).dot(&(dir * travel));
    if past_end > WALL_END_MARGIN {
        return Err(OpError::failed(format!(
            "the wall ended {past_end:.1} m behind the cart at ({:.2}, {:.2})",
            end.x, end.y
        )));
    }
    let opposite = if params.mode == FollowMode::Corridor {
        newest::<SegmentSet>(ctx, "feature", SEGMENTS)
            .await?
            .and_then(|set| {
                sense_wall(
                    &set.segments,
                    &pose,
                    &WallParams {
                        side: Some(est.side.opposite()),
                        ..WallParams::default()
                    },
                )
            })
    } else {
        None
    };
    let cmd = follow_command(&est, opposite.as_ref(), params);
    cart(slot, ctx)?
        .drive(cmd.speed, cmd.steer)
        .map_err(cart_err)?;
    Ok((is_aligned(&est, opposite.as_ref(), params), pose))
}

/// How long a wall follower may see the cart make no progress before it gives up: something
/// (an obstacle, the collision avoidance's stop) keeps it from following the wall.
const STALL_TIME: Duration = Duration::from_secs(15);

/// How far the cart must move to count as progress, m.
const STALL_DISTANCE: f64 = 0.1;

/// What both wall followers do with the cart: a follow step and a stall check per control
/// step, stop on suspension.
#[derive(Default)]
struct Follower {
    cart: Option<CartClient>,
    stall: Stall,
}

impl Follower {
    /// A new activation: the stall check starts afresh.
    fn activate(&mut self) -> Result<Step, OpError> {
        self.stall = Stall::default();
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext, params: &FollowParams) -> Result<Step, OpError> {
        let (_, pose) = follow_step(ctx, &mut self.cart, params).await?;
        self.stall.check(pose, ctx.now())?;
        Ok(Step::Continue)
    }

    fn suspend(&mut self, ctx: &OpContext) -> Result<(), OpError> {
        stop_cart(&mut self.cart, ctx)
    }
}

/// Watches that a follower's cart keeps moving.
#[derive(Default)]
struct Stall {
    /// Where and when the cart last made progress.
    anchor: Option<(Pose, Duration)>,
}

impl Stall {
    /// Record the cart at `pose` at `now`; an error once it has not moved for [`STALL_TIME`].
    fn check(&mut self, pose: Pose, now: Duration) -> Result<(), OpError> {
        match self.anchor {
            Some((at, since)) if (pose.point() - at.point()).norm() < STALL_DISTANCE => {
                if now.saturating_sub(since) >= STALL_TIME {
                    return Err(OpError::failed(format!(
                        "the cart has made no progress along the wall for {:.0} s, blocked at ({:.2}, {:.2})",
                        STALL_TIME.as_secs_f64(),
                        pose.x,
                        pose.y
                    )));
                }
            }
            _ => self.anchor = Some((pose, now)),
        }
        Ok(())
    }
}

/// The wall follower, version 1: keeps the cart at `distance` from the followed wall, driving
/// forwards, until suspended. One parameter.
#[derive(Default)]
pub struct WallFollowerV1 {
    follower: Follower,
}

/// Forward speed of the wall followers.
const FOLLOW_SPEED: f64 = 0.3;

impl Operation for WallFollowerV1 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            "1.0.0",
            "follows a wall at a distance",
        )
    }

    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::float("distance", 0.6)
            .range(0.3, 3.0)
            .unit("m")
            .describe("distance kept from the wall")])
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let params = follow_params(
            ctx.params().f64("distance")?,
            FollowMode::Wall,
            FOLLOW_SPEED,
        );
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
    }
}

/// The wall follower, version 2: like version 1, and it can also keep to the middle of a
/// corridor. Two parameters: same kind and id as version 1, another schema.
#[derive(Default)]
pub struct WallFollowerV2 {
    follower: Follower,
}

impl Operation for WallFollowerV2 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            "2.0.0",
            "follows a wall at a distance, or a corridor's middle",
        )
    }

    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("distance", 0.6)
                .range(0.3, 3.0)
                .unit("m")
                .describe("distance kept from the wall (wall mode)"),
            ParamDecl::choice("mode", &["wall", "corridor"], "wall")
                .describe("follow one wall, or the middle between two"),
        ])
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let mode = match p.text("mode")? {
            "corridor" => FollowMode::Corridor,
            _ => FollowMode::Wall,
        };
        let params = follow_params(p.f64("distance")?, mode, FOLLOW_SPEED);
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
    }
}

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

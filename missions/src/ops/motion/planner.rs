//! The path planner (1515): a collision-free path to the goal, or the parking manoeuvre into
//! the detected docking spot, stored in the parameter DM.

use super::footprint_of;
use crate::algo::parking::{plan_parking, ParkError, ParkParams};
use crate::algo::planner::{plan, Bounds, PlannerParams};
use crate::geom::{Point, Pose, Segment, Vector};
use crate::hardware::CartClient;
use crate::ops::records::{DockRecord, LegRecord, PathRecord, DOCK, MAP, PATH};
use crate::ops::{cart, cart_err, dm_err, located, newest};
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::{PARAMETER, WORLD};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;

marie_actors::choice! {
    /// Where the path planner plans to.
    pub enum PlanTarget {
        /// The dock the docking detector found: a parking manoeuvre into it.
        Dock = "dock",
        /// The pose given by the parameters `x`, `y` and `heading`.
        Pose = "pose",
    }
}

marie_actors::params! {
    /// The path planner's parameters.
    pub struct PathPlannerParams {
        /// plan to the detected dock, or to the pose given below
        pub target: PlanTarget = PlanTarget::Dock;
        /// goal x (target = pose)
        pub x: f64 = 0.0, range(-1e4, 1e4), unit("m");
        /// goal y (target = pose)
        pub y: f64 = 0.0, range(-1e4, 1e4), unit("m");
        /// goal heading (target = pose)
        pub heading: f64 = 0.0, range(-360.0, 360.0), unit("deg");
        /// clearance kept from walls
        pub inflation: f64 = PlannerParams::default().inflation, range(0.0, 5.0), unit("m");
        /// grid cell size
        pub resolution: f64 = PlannerParams::default().resolution, range(0.01, 1.0), unit("m");
        /// straight final approach along the goal heading
        pub approach: f64 = PlannerParams::default().approach_distance,
            range(0.0, 10.0), unit("m");
        /// the path is to be driven backwards
        pub reverse: bool = false;
        /// tightest arc of a parking manoeuvre (target = dock): above the cart's turning
        /// radius, the trajectory controller has steering to spare to correct its errors
        pub park_radius: f64 = ParkParams::default().min_radius, range(0.5, 10.0), unit("m");
        /// straight end of a parking manoeuvre, to settle the heading on
        pub park_tail: f64 = ParkParams::default().tail, range(0.0, 5.0), unit("m");
        /// clearance every pose of a parking manoeuvre keeps from the walls: a margin for
        /// the controller's tracking error and the pose's
        pub park_clearance: f64 = ParkParams::default().clearance, range(0.0, 1.0), unit("m");
        /// the parked cart's goal, this far from the spot's middle towards its opening:
        /// backing along an S, the cart overshoots towards the spot's back wall while its
        /// heading still swings
        pub park_shallow: f64 = 0.0, range(-0.5, 0.5), unit("m");
        /// a parking manoeuvre ends with this long a forward run along the spot, which
        /// straightens the heading the backing left swinging (0: none)
        pub park_settle: f64 = ParkParams::default().settle, range(0.0, 2.0), unit("m");
    }
}

marie_actors::flags! {
    /// What the path planner reports.
    pub enum PathPlannerFlag {
        /// a path is stored in the parameter DM
        Planned = "path-planned",
    }
}

/// Plans a collision-free path from the cart to a goal on the world map and stores it in the
/// parameter DM; finishes with `path-planned`, fails when there is no path.
#[derive(Debug, Default)]
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
        PathPlannerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        PathPlannerFlag::decls()
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: PathPlannerParams = ctx.params().read()?;
        let params = PlannerParams {
            inflation: p.inflation,
            resolution: p.resolution,
            approach_distance: p.approach,
            reverse: p.reverse,
            ..PlannerParams::default()
        };
        let shallow = p.park_shallow;
        let shape = ParkParams {
            min_radius: p.park_radius,
            tail: p.park_tail,
            clearance: p.park_clearance,
            settle: p.park_settle,
            ..ParkParams::default()
        };
        let pose_goal = Pose::new(p.x, p.y, p.heading.to_radians());
        let map = newest(ctx, WORLD, MAP)
            .await?
            .ok_or_else(|| OpError::failed("no map in the world DM"))?;
        let status = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?;
        let start = located(ctx, &status.odometry).await?;
        if p.target == PlanTarget::Dock {
            let dock = newest(ctx, WORLD, DOCK)
                .await?
                .ok_or_else(|| OpError::failed("no dock in the world DM to plan to"))?;
            let legs = parking_legs(&start, &dock, &status, &map, shape, shallow)?;
            ctx.dm(PARAMETER)?
                .store_kind(PATH, &PathRecord { legs })
                .await
                .map_err(dm_err(PARAMETER))?;
            return Ok(Step::finish(PathPlannerFlag::Planned));
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
        ctx.dm(PARAMETER)?
            .store_kind(PATH, &record)
            .await
            .map_err(dm_err(PARAMETER))?;
        Ok(Step::finish(PathPlannerFlag::Planned))
    }

    async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::finish(PathPlannerFlag::Planned))
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

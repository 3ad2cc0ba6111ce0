//! The simulated robot as a node's [`Robot`]: the plug between `marie-missions` and a node.
//!
//! A [`SimRobot`] is a world and a seed. Plugged into a node it stores the world's walls in
//! the world datamanager as the a-priori map ([`records::MAP`]: class `map`, sub1 `walls`, a
//! `Vec<Segment>`) before any operation runs, starts the virtual cart in that world (when the
//! node runs the cart's drivers), and judges every run by the world: its judgement
//! ([`RobotReport`]: the cart's final pose, its collisions, the seed and the world's
//! verdict) is the run's `judged` event and so the report's robot section, and a mission the
//! dispatcher calls a success fails when the cart did not end in the world's goal area.
//! [`SimRobot::picture`] draws a run after it; while it runs, the robot tells the node's
//! event bus the same things as they happen ([`crate::telemetry`]: the world
//! when a run starts, the cart's pose, echoes, planned paths, the followed wall, the dock).
//! On a node that runs the cart but no dispatcher (a cluster's cart node), it tells the
//! world and the cart's poses from the node's start, since no run starts there.
//!
//! ```no_run
//! use marie_cluster::node::{Node, NodeConfig, NodeOptions, RunOptions};
//! use marie_missions::robot::{RobotReport, SimRobot};
//! use marie_missions::world::World;
//! use std::sync::Arc;
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let world = World::load("missions/worlds/lab.toml")?;
//! let robot = Arc::new(SimRobot::new(world.clone(), 7));
//! let catalog = marie_missions::catalog();
//! let config = NodeConfig::everything("solo", &catalog);
//! let options = NodeOptions::with_catalog(catalog).with_robot(robot.clone());
//! let node = Node::start(config, options).await?;
//! let mission = node.load_mission(std::path::Path::new("missions/docking.toml")).await?;
//! let report = node.run(mission, RunOptions::new()).await?;
//! let cart = RobotReport::of(&report);
//! println!("{:?} at {:?}: {:?}", report.outcome, cart.final_pose, cart.judgement);
//! std::fs::write("run.svg", robot.picture(&report).await.render(&world, 50.0))?;
//! node.shutdown().await;
//! # Ok(()) }
//! ```

use crate::geom::{Point, Pose};
use crate::hardware::{CartClient, CartError, CartStatus};
use crate::ops::records::{self, DockRecord, EchoScan, PathRecord, SegmentSet, WallRecord};
use crate::picture::Picture;
pub use crate::robot_report::RobotReport;
use crate::telemetry::{self, PoseSampler};
use crate::world::{Judgement, World};
use marie_cluster::node::{AprioriRecord, BoxFuture, Robot, RunJudgement};
use marie_dm::{self as dm, DmClient, DmError, DmSpec, Query};
use marie_supervision::{ChildSpec, Restart};
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::EventBus;
use marie_vocabulary::fence::{obeyed_late, Obeyed};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::Outcome;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use tokio::task::JoinHandle;

/// The most sonar echo points [`SimRobot::picture`] draws; more are thinned out evenly.
pub const MAX_PICTURE_ECHOES: usize = 5000;

/// The seed of a simulation when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// The source name the picture reads datamanagers as.
const SOURCE: &str = "robot";

/// The simulated robot: the world it drives in, the seed of its noise, and whether this node
/// runs its drivers (the virtual cart).
#[derive(Clone, Debug)]
pub struct SimRobot {
    world: World,
    seed: u64,
    drivers: bool,
    telemetry: Telemetry,
}

/// What the robot's live events need across runs (shared by its clones).
#[derive(Clone, Debug, Default)]
struct Telemetry {
    /// Raised once the first run's world is published: the cart's poses follow it.
    live: Arc<AtomicBool>,
}

impl SimRobot {
    /// A robot in `world` with noise seeded by `seed`, running its cart.
    pub fn new(world: World, seed: u64) -> Self {
        SimRobot {
            world,
            seed,
            drivers: true,
            telemetry: Telemetry::default(),
        }
    }

    /// Whether the node runs the cart's drivers (another node may run them).
    pub fn with_drivers(mut self, drivers: bool) -> Self {
        self.drivers = drivers;
        self
    }

    /// The world it drives in.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The seed of its noise.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// echo point stored in the feature datamanager (thinned out evenly to at most
    /// [`MAX_PICTURE_ECHOES`]), the newest extracted segments, the newest followed wall and
    /// detected dock (world datamanager), and the newest planned path (parameter
    /// datamanager), captioned `mission — outcome — seed N`.
    ///
    /// Whatever cannot be had — the cart does not answer, a
    /// datamanager fails, a record does not decode — is left out with a warning.
    pub async fn picture(&self, report: &RunReport) -> Picture {
        let robot = self;
        let outcome = match report.outcome {
            Outcome::Succeeded => "succeeded",
            Outcome::Failed => "failed",
        };
        let mut picture = Picture {
            caption: format!(
                "{} — {outcome} — seed {}",
                report.mission,
                RobotReport::of(report).seed.unwrap_or(robot.seed)
            ),
            ..Picture::default()
        };
        match CartClient::lookup() {
            Ok(cart) => {
                match cart.trace().await {
                    Ok(trace) => picture.path = trace.iter().map(|t| t.pose.point()).collect(),
                    Err(e) => tracing::warn!("picture without the driven path: {e}"),
                }
                match cart.status().await {
                    Ok(status) => picture.footprint = Some(status.footprint),
                    Err(e) => tracing::warn!("picture without the final footprint: {e}"),
                }
            }
            Err(e) => tracing::warn!("picture without the cart's path and footprint: {e}"),
        }
        if picture.footprint.is_none() {
            if let Some([x, y, theta]) = RobotReport::of(report).final_pose {
                let pose = Pose::new(x, y, theta);
                picture.footprint = Some(robot.world.cart.footprint(&pose));
            }
        }

        let feature = dm_client(dm::FEATURE);
        let scans: Vec<EchoScan> = decoded(&feature, Query::class(records::SONAR.class())).await;
        let echoes: Vec<Point> = scans.iter().flat_map(EchoScan::points).collect();
        picture.sonar = thin_out(echoes, MAX_PICTURE_ECHOES);
        if let Some(set) = newest::<SegmentSet>(&feature, records::SEGMENTS.class()).await {
            picture.segments = set.segments;
        }
        let world = dm_client(dm::WORLD);
        if let Some(wall) = newest::<WallRecord>(&world, records::WALL.class()).await {
            picture.wall = Some(wall.segment);
        }
        if let Some(dock) = newest::<DockRecord>(&world, records::DOCK.class()).await {
            picture.dock = Some(dock.corners);
        }
        let parameter = dm_client(dm::PARAMETER);
        if let Some(path) = newest::<PathRecord>(&parameter, records::PATH.class()).await {
            picture.planned = path.waypoints();
        }
        picture
    }
}

impl Robot for SimRobot {
    fn describe(&self) -> String {
        format!("world {} (seed {})", self.world.name, self.seed)
    }

    fn apriori(&self) -> Vec<AprioriRecord> {
        match records::MAP.record(&self.world.segments()) {
            Ok(record) => vec![AprioriRecord {
                datamanager: dm::WORLD.name.to_string(),
                record,
            }],
            Err(e) => {
                tracing::error!("the map of world {} does not encode: {e}", self.world.name);
                Vec::new()
            }
        }
    }

    fn drivers(&self, clock: &SharedClock, events: &EventBus) -> Vec<ChildSpec> {
        if !self.drivers {
            return Vec::new();
        }
        let (clock, world, seed) = (clock.clone(), self.world.clone(), self.seed);
        let poses = PoseSampler::new(events.clone(), self.telemetry.live.clone());
        vec![
            ChildSpec::worker("cart", move |sup| {
                let (clock, world, poses) = (clock.clone(), world.clone(), poses.clone());
                async move {
                    crate::spawn_cart_sampled(clock, &world, seed, Some(sup), Some(poses)).await
                }
            })
            .with_restart(Restart::Temporary),
        ]
    }

    fn run_starting<'a>(&'a self, events: &'a EventBus) -> BoxFuture<'a, Vec<JoinHandle<()>>> {
        Box::pin(async move {
            events.publish(telemetry::world_event(&self.world));
            self.telemetry.live.store(true, Ordering::Relaxed);
            telemetry::tap_records(events.clone()).await
        })
    }

    /// A node that runs the cart but no dispatcher draws the robot without runs: the world
    /// now and again (for viewers that join later), then the cart's poses from now on. The
    /// records' taps stay with the dispatcher's node (see [`crate::telemetry`]). A node
    /// without the cart tells nothing.
    fn dispatched_elsewhere(&self, events: &EventBus) -> Vec<JoinHandle<()>> {
        if !self.drivers {
            return Vec::new();
        }
        // the world is published before this returns, so before the poses it frames
        let world = telemetry::repeat_world(events.clone(), &self.world);
        self.telemetry.live.store(true, Ordering::Relaxed);
        vec![world]
    }

    fn judge<'a>(&'a self, run: &'a RunReport) -> BoxFuture<'a, RunJudgement> {
        Box::pin(async move {
            let status = match CartClient::lookup() {
                Ok(cart) => cart.status().await,
                Err(e) => Err(e),
            };
            judge(self, run, status.map(FinalState::from))
        })
    }
}

/// A client of datamanager `spec`'s current incarnation.
fn dm_client(spec: DmSpec) -> Result<DmClient, DmError> {
    DmClient::lookup(spec.name, SOURCE)
}

/// What the cart says of its state at a run's end.
struct FinalState {
    pose: Pose,
    collisions: u32,
    judgement: Judgement,
    /// Commands of replaced incarnations it refused, by operation (its fencing).
    refused_by: BTreeMap<String, u64>,
    /// The seed it drove with, if it says (the cart may run on another node, with that
    /// node's seed).
    seed: Option<u64>,
    /// What it obeyed, by operation and epoch.
    obeyed: Vec<Obeyed>,
}

impl From<CartStatus> for FinalState {
    fn from(s: CartStatus) -> FinalState {
        FinalState {
            pose: s.pose,
            collisions: s.collisions,
            judgement: s.judgement,
            refused_by: s.refused_by,
            seed: s.seed,
            obeyed: s.obeyed,
        }
    }
}

/// Judge `run`, which the dispatcher ended: what the cart said of its final state (or why
/// it did not tell), the seed, the world's verdict, which overrules a success outside the
/// goal, and whether the cart obeyed an epoch after `run` had bound a newer one.
fn judge(robot: &SimRobot, run: &RunReport, status: Result<FinalState, CartError>) -> RunJudgement {
    let (outcome, reason) = (run.outcome, run.reason.as_str());
    let mut said = RobotReport {
        seed: Some(robot.seed),
        ..RobotReport::default()
    };
    let (mut outcome, mut reason) = (outcome, reason.to_string());
    let has_goal = robot.world.goal.is_some();
    match status {
        Ok(status) => {
            // the seed the cart drove with: its node's, which a run joined to a cluster
            // does not choose
            said.seed = status.seed.or(said.seed);
            let (pose, judgement) = (status.pose, status.judgement);
            said.final_pose = Some([pose.x, pose.y, pose.theta]);
            said.collisions = Some(u64::from(status.collisions));
            said.inside_goal = has_goal.then_some(judgement.inside_goal);
            said.judgement = Some(judgement.to_string());
            said.refused_commands = Some(status.refused_by);
            let late = obeyed_late(&run.bound_epochs, &status.obeyed);
            for l in &late {
                tracing::warn!("fencing failed: {l}");
            }
            said.obeyed_late = Some(late);
            if has_goal && outcome == Outcome::Succeeded && !judgement.success {
                outcome = Outcome::Failed;
                reason = format!("the cart did not end in the goal area: {judgement}");
            }
        }
        Err(e) => {
            tracing::warn!("cannot judge the run: {e}");
            if has_goal && outcome == Outcome::Succeeded {
                outcome = Outcome::Failed;
                reason = format!("cannot judge the run in world `{}`: {e}", robot.world.name);
            }
        }
    }
    RunJudgement {
        outcome,
        reason,
        robot: said.section(),
    }
}

/// Every record of `query`, decoded as `T`; records that do not decode, or a datamanager that
/// does not answer, are skipped with a warning.
async fn decoded<T: dm::PayloadType>(client: &Result<DmClient, DmError>, query: Query) -> Vec<T> {
    let class = query.class.clone().unwrap_or_default();
    let selected = match client {
        Ok(client) => client.select(query).await,
        Err(e) => Err(e.clone()),
    };
    let records = match selected {
        Ok(records) => records,
        Err(e) => {
            tracing::warn!(class = %class, "picture without `{class}` records: {e}");
            return Vec::new();
        }
    };
    let mut skipped = 0usize;
    let mut first_error = None;
    let out = records
        .iter()
        .filter_map(|r| match r.decode::<T>() {
            Ok(v) => Some(v),
            Err(e) => {
                skipped += 1;
                first_error.get_or_insert(e);
                None
            }
        })
        .collect();
    if let Some(e) = first_error {
        tracing::warn!(
            class = %class,
            "picture skips {skipped} `{class}` record(s) that do not decode: {e}"
        );
    }
    out
}

/// The newest record of `class`, decoded; `None` when there is none or it does not decode.
async fn newest<T: dm::PayloadType>(client: &Result<DmClient, DmError>, class: &str) -> Option<T> {
    decoded(client, Query::class(class).newest(1)).await.pop()
}

/// At most `max` of `points`, taking every k-th.
fn thin_out(points: Vec<Point>, max: usize) -> Vec<Point> {
    if points.len() <= max {
        return points;
    }
    let k = points.len().div_ceil(max.max(1));
    points.into_iter().step_by(k).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(outcome: Outcome) -> RunReport {
        let reason = match outcome {
            Outcome::Succeeded => "",
            Outcome::Failed => "the dispatcher's reason",
        };
        RunReport::new("m", outcome, reason)
    }

    fn robot(world: &str) -> SimRobot {
        SimRobot::new(World::builtin(world).expect("a shipped world"), 9)
    }

    fn at(robot: &SimRobot, pose: Pose, collisions: u32) -> Result<FinalState, CartError> {
        Ok(FinalState {
            pose,
            collisions,
            judgement: robot.world.judge(pose, collisions),
            refused_by: BTreeMap::new(),
            seed: None,
            obeyed: Vec::new(),
        })
    }

    /// `r` judged by `robot` as the node does: its outcome, reason and robot section.
    fn judged(r: &mut RunReport, robot: &SimRobot, status: Result<FinalState, CartError>) {
        let j = judge(robot, r, status);
        (r.outcome, r.reason, r.robot) = (j.outcome, j.reason, j.robot);
    }

    /// What the cart said, read back from the report.
    fn cart(r: &RunReport) -> RobotReport {
        RobotReport::of(r)
    }

    #[test]
    fn a_success_outside_the_goal_is_a_failure() {
        let lab = robot("lab");
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &lab, at(&lab, lab.world.start, 0));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(
            r.reason
                .starts_with("the cart did not end in the goal area: failure: outside"),
            "{}",
            r.reason
        );
        assert_eq!(
            cart(&r).final_pose,
            Some([12.5, 1.5, lab.world.start.theta])
        );
        assert_eq!(
            (cart(&r).collisions, cart(&r).seed, cart(&r).inside_goal),
            (Some(0), Some(9), Some(false))
        );
    }

    #[test]
    fn a_success_in_the_goal_stays_one_but_a_collision_fails_it() {
        let lab = robot("lab");
        let parked = Pose::new(4.9, -0.4, 0.0);
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &lab, at(&lab, parked, 0));
        assert_eq!(
            (r.outcome, cart(&r).inside_goal),
            (Outcome::Succeeded, Some(true))
        );
        assert!(cart(&r)
            .judgement
            .as_deref()
            .is_some_and(|j| j.starts_with("success")));
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &lab, at(&lab, parked, 2));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(r.reason.contains("2 collision(s)"), "{}", r.reason);
    }

    #[test]
    fn a_cart_on_another_node_names_the_seed_it_drove_with() {
        // this process's robot has seed 9; the cart, on another node, drove with 4
        let lab = robot("lab");
        let mut r = report(Outcome::Succeeded);
        let status = at(&lab, lab.world.start, 0).map(|s| FinalState { seed: Some(4), ..s });
        judged(&mut r, &lab, status);
        assert_eq!(cart(&r).seed, Some(4));
    }

    #[test]
    fn a_failure_keeps_the_dispatchers_reason() {
        let lab = robot("lab");
        let mut r = report(Outcome::Failed);
        judged(&mut r, &lab, at(&lab, lab.world.start, 0));
        assert_eq!(r.reason, "the dispatcher's reason");
        assert_eq!(cart(&r).collisions, Some(0));
    }

    #[test]
    fn a_world_without_a_goal_never_fails_a_run_on_its_own() {
        let nodock = robot("nodock");
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &nodock, at(&nodock, nodock.world.start, 1));
        assert_eq!(r.outcome, Outcome::Succeeded);
        assert_eq!((cart(&r).inside_goal, cart(&r).collisions), (None, Some(1)));
        assert!(cart(&r).judgement.is_some());
        // nor does a cart that does not answer
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &nodock, Err(CartError::Unreachable));
        assert_eq!(
            (r.outcome, cart(&r).final_pose, cart(&r).seed),
            (Outcome::Succeeded, None, Some(9))
        );
    }

    #[test]
    fn an_unanswering_cart_fails_a_run_that_needs_judging() {
        let lab = robot("lab");
        let mut r = report(Outcome::Succeeded);
        judged(&mut r, &lab, Err(CartError::NotFound));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(
            r.reason.contains("no virtual cart is running"),
            "{}",
            r.reason
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_cart_dispatched_from_elsewhere_tells_its_world_again_and_again_then_poses() {
        use marie_vocabulary::clock::ManualClock;
        use marie_vocabulary::events::EventKind;
        let bus = EventBus::new("cart", Arc::new(ManualClock::new()));
        let mut sub = bus.subscribe();
        let lab = robot("lab");
        assert!(!lab.telemetry.live.load(Ordering::Relaxed));
        let tasks = lab.dispatched_elsewhere(&bus);
        // the world before this returned, and the poses live after it
        let first = sub.drain();
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].kind, telemetry::world_event(&lab.world));
        assert!(lab.telemetry.live.load(Ordering::Relaxed));
        // then again every period, for viewers that come later
        tokio::time::sleep(telemetry::WORLD_REPEAT * 3 + std::time::Duration::from_millis(1)).await;
        let again = sub.drain();
        assert_eq!(again.len(), 3);
        assert!(again
            .iter()
            .all(|e| matches!(&e.kind, EventKind::Robot { what, .. } if what == telemetry::WORLD)));
        tasks.iter().for_each(JoinHandle::abort);
        // a node without the cart tells nothing
        let elsewhere = robot("lab").with_drivers(false);
        assert!(elsewhere.dispatched_elsewhere(&bus).is_empty());
        assert!(sub.drain().is_empty());
        assert!(!elsewhere.telemetry.live.load(Ordering::Relaxed));
    }

    #[test]
    fn echo_points_are_thinned_out_evenly() {
        let points: Vec<Point> = (0..12_001).map(|i| Point::new(f64::from(i), 0.0)).collect();
        let thin = thin_out(points.clone(), 5000);
        assert!(thin.len() <= 5000 && thin.len() >= 4000, "{}", thin.len());
        assert_eq!(thin[1].x, 3.0);
        assert_eq!(thin_out(points[..10].to_vec(), 5000).len(), 10);
    }
}

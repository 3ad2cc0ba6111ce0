//! The embedded node: datamanagers, operations and a dispatcher in one process, no network.
//!
//! This is the default way to run marie (DESIGN.md §2). It starts a supervision tree (see
//! [`Node`]): the thesis' three datamanagers (world 1203, feature 1201, parameter 1202) and
//! the operations of the [`marie_missions`] catalogue under their supervisors, each
//! publishing itself in the registry, then runs missions against them, each on a dispatcher
//! of its own. A crashed operation is restarted by its supervisor and the dispatcher rebinds
//! to the new instance; [`Node::run_with_faults`] injects faults to test exactly that.
//!
//! # With a simulated robot
//!
//! Given a [`World`] ([`NodeOptions::world`]), the node also starts the robot: the virtual
//! cart in that world and the robot's operations ([`marie_missions::robot_operations`]), and
//! stores the world's walls in the world datamanager as the a-priori map (class
//! [`records::MAP`], sub1 `walls`, a `Vec<Segment>`) before any mission runs. A run is then
//! judged by the world too ([`Node::run`]): the report gets the cart's final pose, its
//! collisions, the seed and the world's verdict, and a mission the dispatcher calls a success
//! fails when the cart did not end in the world's goal area.
//!
//! ```no_run
//! use marie::node::{Node, NodeOptions};
//! use marie::missions::world::World;
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let world = World::load("missions/worlds/lab.toml")?;
//! let node = Node::start(NodeOptions {
//!     world: Some(world.clone()),
//!     seed: 7,
//!     ..NodeOptions::default()
//! })
//! .await?;
//! let mission = node.load_mission(std::path::Path::new("missions/docking.toml")).await?;
//! let report = node.run(mission, None).await?;
//! println!("{:?} at {:?}: {:?}", report.outcome, report.final_pose, report.judgement);
//! if let Some(picture) = node.picture(&report).await {
//!     std::fs::write("run.svg", picture.render(&world, 50.0))?;
//! }
//! node.shutdown().await;
//! # Ok(()) }
//! ```

mod tree;

use crate::faults::{FaultPlan, Injector, RunView};
use marie_actors::clock::{RealClock, ScaledClock, SharedClock};
use marie_actors::dispatcher::mission::{Diagnostics, Mission, ParsedMission};
use marie_actors::dispatcher::{
    self, DispatchError, DispatchEvent, DispatcherArgs, DispatcherMsg, Outcome, RegistryCatalog,
    RunReport,
};
use marie_actors::dm::{self, DmClient, DmError, DmSpec, Query};
use marie_actors::eo::EoError;
use marie_actors::eo::HostOptions;
use marie_missions::geom::{Point, Pose};
use marie_missions::hardware::{CartClient, CartError};
use marie_missions::ops::records::{
    self, DockRecord, EchoScan, PathRecord, SegmentSet, WallRecord,
};
use marie_missions::picture::Picture;
use marie_missions::world::{Judgement, World};
use marie_supervision::{
    ChildSpec, Restart, Shutdown, Supervisor, SupervisorError, SupervisorRef, SupervisorSpec,
};
use ractor::ActorRef;
use serde::de::DeserializeOwned;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use tree::{abort_on_give_up, datamanagers, DATAMANAGERS, OPERATIONS};

/// The seed of a simulation when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// The most sonar echo points [`Node::picture`] draws; more are thinned out evenly.
pub const MAX_PICTURE_ECHOES: usize = 5000;

/// The source name the node stores records under (the a-priori map).
const NODE_SOURCE: &str = "node";

/// How to start a node.
#[derive(Clone, Debug)]
pub struct NodeOptions {
    /// Clock speed: 1.0 is real time.
    pub speed: f64,
    /// Start the built-in operations of the mission catalogue.
    pub builtin_operations: bool,
    /// The world a simulated robot drives in. With one, the node starts the virtual cart and
    /// the robot's operations and stores the world's walls as the a-priori map; without one
    /// (the default) no robot runs.
    pub world: Option<World>,
    /// Seed of the simulation's noise (sonar, odometry): the same world, seed and mission
    /// give the same run. Used only with a world; default [`DEFAULT_SEED`].
    pub seed: u64,
    /// Restart intensity of the operation supervisor: more than this many restarts within
    /// [`NodeOptions::operation_period`] and it gives up (the running mission comes to a
    /// full stop naming the operation; the node then starts the operations afresh).
    /// Default [`DEFAULT_OPERATION_RESTARTS`].
    pub operation_restarts: usize,
    /// The window of [`NodeOptions::operation_restarts`]; default
    /// [`DEFAULT_OPERATION_PERIOD`].
    pub operation_period: Duration,
}

/// Default restart intensity of the operation supervisor (restarts per period).
pub const DEFAULT_OPERATION_RESTARTS: usize = 5;

/// Default window of the operation supervisor's restart intensity.
pub const DEFAULT_OPERATION_PERIOD: Duration = Duration::from_secs(10);

/// How long an operation gets to stop before it is killed.
const OPERATION_SHUTDOWN: Duration = Duration::from_secs(1);

impl Default for NodeOptions {
    fn default() -> Self {
        NodeOptions {
            speed: 1.0,
            builtin_operations: true,
            world: None,
            seed: DEFAULT_SEED,
            operation_restarts: DEFAULT_OPERATION_RESTARTS,
            operation_period: DEFAULT_OPERATION_PERIOD,
        }
    }
}

/// Why a node could not do what was asked.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// An actor did not start.
    #[error("could not start {what}: {source}")]
    Spawn {
        /// What was being started.
        what: String,
        /// Why.
        source: ractor::SpawnErr,
    },
    /// The node's supervision tree did not start or refused a request.
    #[error("node supervisor: {0}")]
    Supervisor(#[from] SupervisorError),
    /// An operation did not answer while the mission was checked.
    #[error(transparent)]
    Operation(#[from] EoError),
    /// The mission is malformed or inconsistent.
    #[error("{0}")]
    Mission(Diagnostics),
    /// The dispatcher failed.
    #[error(transparent)]
    Dispatch(#[from] DispatchError),
    /// A datamanager refused or did not answer a request of the node itself.
    #[error("datamanager request failed: {0}")]
    Datamanager(#[from] DmError),
}

/// The simulated robot of a node: the world it drives in and the seed of its noise.
#[derive(Clone, Debug)]
struct Robot {
    world: World,
    seed: u64,
}

/// A running embedded node: the supervision tree of DESIGN.md §2.
///
/// ```text
/// node (one_for_one)
///  ├─ datamanagers (one_for_one) ── feature 1201, parameter 1202, world 1203
///  ├─ cart                          (with a world; temporary: a simulation is not restarted)
///  ├─ operations (one_for_one) ──── one EO host per operation instance
///  └─ dispatcher-N                  (temporary, one per run)
/// ```
pub struct Node {
    clock: SharedClock,
    root: SupervisorRef,
    robot: Option<Robot>,
    runs: AtomicU64,
}

impl Node {
    /// Start the node's supervision tree: the datamanagers, (optionally) the built-in
    /// operations, and with a [`NodeOptions::world`] the simulated robot, after storing the
    /// world's walls as the a-priori map.
    pub async fn start(options: NodeOptions) -> Result<Node, NodeError> {
        let clock: SharedClock = if (options.speed - 1.0).abs() < f64::EPSILON {
            RealClock::shared()
        } else {
            Arc::new(ScaledClock::new(options.speed))
        };
        let world = options.world.clone();
        let mut children = vec![ChildSpec::supervisor(
            DATAMANAGERS,
            SupervisorSpec::one_for_one().with_intensity(3, Duration::from_secs(5)),
            datamanagers(&clock, world.as_ref()),
        )];
        let mut factories = Vec::new();
        if options.builtin_operations {
            factories.extend(marie_missions::builtin_operations());
        }
        if let Some(world) = &world {
            let (clock, world, seed) = (clock.clone(), world.clone(), options.seed);
            children.push(
                ChildSpec::worker("cart", move |sup| {
                    let (clock, world) = (clock.clone(), world.clone());
                    async move { marie_missions::spawn_cart(clock, &world, seed, Some(sup)).await }
                })
                .with_restart(Restart::Temporary),
            );
            factories.extend(marie_missions::robot_operations());
        }
        let options_host = HostOptions::with_clock(clock.clone());
        let operations = factories
            .into_iter()
            .map(|f| {
                let opts = options_host.clone();
                ChildSpec::worker(f.key(), move |sup| (f.start)(opts.clone(), Some(sup)))
                    .with_shutdown(Shutdown::Timeout(OPERATION_SHUTDOWN))
            })
            .collect();
        children.push(ChildSpec::supervisor(
            OPERATIONS,
            SupervisorSpec::one_for_one()
                .with_intensity(options.operation_restarts, options.operation_period),
            operations,
        ));
        let (root, _) = Supervisor::start(
            None,
            SupervisorSpec::one_for_one().with_intensity(3, Duration::from_secs(30)),
            children,
        )
        .await?;
        Ok(Node {
            clock,
            root,
            robot: world.map(|world| Robot {
                world,
                seed: options.seed,
            }),
            runs: AtomicU64::new(0),
        })
    }

    /// The node's root supervisor (for introspection: `which_children`, events).
    pub fn supervisor(&self) -> &SupervisorRef {
        &self.root
    }

    /// The supervisor of the node's operations, as it is now (it is a new actor after it
    /// was restarted).
    pub async fn operation_supervisor(&self) -> Result<SupervisorRef, NodeError> {
        self.child_supervisor(OPERATIONS).await
    }

    /// The supervisor of the node's datamanagers, as it is now.
    pub async fn datamanager_supervisor(&self) -> Result<SupervisorRef, NodeError> {
        self.child_supervisor(DATAMANAGERS).await
    }

    async fn child_supervisor(&self, id: &str) -> Result<SupervisorRef, NodeError> {
        self.root
            .which_children()
            .await?
            .into_iter()
            .find(|c| c.id == id)
            .and_then(|c| c.state.actor().cloned())
            .and_then(SupervisorRef::from_cell)
            .ok_or_else(|| NodeError::Supervisor(SupervisorError::NotFound(id.to_string())))
    }

    /// The node's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// The world the node's simulated robot drives in; `None` when no robot runs.
    pub fn world(&self) -> Option<&World> {
        self.robot.as_ref().map(|r| &r.world)
    }

    /// The seed of the node's simulation; `None` when no robot runs.
    pub fn seed(&self) -> Option<u64> {
        self.robot.as_ref().map(|r| r.seed)
    }

    /// A client of the node's datamanager `spec` (its current incarnation), storing as the
    /// node.
    fn dm(&self, spec: DmSpec) -> Result<DmClient, DmError> {
        DmClient::lookup(spec.name, NODE_SOURCE)
    }

    /// Read, parse and check a mission against the operations running now.
    pub async fn load_mission(&self, path: &Path) -> Result<Mission, NodeError> {
        let parsed = Mission::parse_file(path).map_err(NodeError::Mission)?;
        self.check_mission(&parsed).await
    }

    /// Check a parsed mission against the operations running now (stage 2 of
    /// [`marie_actors::dispatcher::mission`]).
    pub async fn check_mission(&self, parsed: &ParsedMission) -> Result<Mission, NodeError> {
        let catalog = RegistryCatalog::gather(parsed.ops()).await?;
        parsed.validate(&catalog).map_err(NodeError::Mission)
    }

    /// Run a mission; progress events go to `events`.
    ///
    /// With a simulated robot the run is judged by the world too: the report gets the cart's
    /// final pose, its collisions, the seed, whether it ended inside the goal area and the
    /// world's verdict; a mission the dispatcher calls a success is a failure when the world
    /// has a goal area and its verdict is a failure (footprint not inside the goal, heading
    /// off, or a collision). A world without a goal area never fails a run on its own. The
    /// [`DispatchEvent::Ended`] event carries the outcome after this judgement.
    pub async fn run(
        &self,
        mission: Mission,
        events: Option<mpsc::UnboundedSender<DispatchEvent>>,
    ) -> Result<RunReport, NodeError> {
        self.run_with_faults(mission, events, FaultPlan::default())
            .await
    }

    /// [`Node::run`], injecting the faults of `plan` while the mission runs (fault-injection
    /// tests of self-healing). The report lists what was injected in `faults`.
    pub async fn run_with_faults(
        &self,
        mission: Mission,
        events: Option<mpsc::UnboundedSender<DispatchEvent>>,
        plan: FaultPlan,
    ) -> Result<RunReport, NodeError> {
        // Pass every event on as it comes, but hold back `Ended` until the world has judged.
        let (inner, mut rx) = mpsc::unbounded_channel();
        let (stop, mut stopped) = tokio::sync::oneshot::channel::<()>();
        let outer = events.clone();
        // what the fault injector knows of the run: bindings, the running action
        let (view_tx, view) = tokio::sync::watch::channel(RunView::default());
        let forwarder = tokio::spawn(async move {
            let pass = |evt: DispatchEvent| {
                view_tx.send_modify(|v| v.observe(&evt));
                if let Some(outer) = &outer {
                    if !matches!(evt, DispatchEvent::Ended { .. }) {
                        let _ = outer.send(evt);
                    }
                }
            };
            loop {
                tokio::select! {
                    evt = rx.recv() => match evt {
                        Some(evt) => pass(evt),
                        None => break,
                    },
                    _ = &mut stopped => {
                        // the dispatcher emits every event before it reports
                        while let Ok(evt) = rx.try_recv() {
                            pass(evt);
                        }
                        break;
                    }
                }
            }
        });
        let injector = Injector::start(plan, self.clock.clone(), view);
        let result = self.dispatch(mission, inner).await;
        let faults = injector.finish();
        let _ = stop.send(());
        let _ = forwarder.await;
        let mut report = result?;
        report.faults = faults;
        if let Some(robot) = &self.robot {
            let status = match CartClient::lookup() {
                Ok(cart) => cart.status().await,
                Err(e) => Err(e),
            };
            let status = status.map(|s| (s.pose, s.collisions, s.judgement));
            judge(&mut report, robot, status);
        }
        if let Some(outer) = events {
            let _ = outer.send(DispatchEvent::Ended {
                outcome: report.outcome,
                reason: report.reason.clone(),
            });
        }
        Ok(report)
    }

    /// Run `mission` on a dispatcher started as a temporary child of the node's supervisor.
    /// Should the operation supervisor give up (restart intensity exceeded) during the run,
    /// the mission is aborted with a reason naming the operation that kept failing.
    async fn dispatch(
        &self,
        mission: Mission,
        events: mpsc::UnboundedSender<DispatchEvent>,
    ) -> Result<RunReport, NodeError> {
        let n = self.runs.fetch_add(1, Ordering::Relaxed);
        let args = DispatcherArgs {
            mission,
            clock: self.clock.clone(),
            events: Some(events),
        };
        let spec = ChildSpec::worker(format!("dispatcher-{n}"), move |sup| {
            let args = args.clone();
            async move {
                Ok(dispatcher::spawn_dispatcher(args, Some(sup))
                    .await?
                    .get_cell())
            }
        })
        .with_restart(Restart::Temporary)
        .with_shutdown(Shutdown::Timeout(Duration::from_secs(1)));
        // subscribe before the run starts, so no give-up goes unseen
        let give_ups = match self.operation_supervisor().await {
            Ok(sup) => Some(sup.subscribe().await?),
            Err(e) => {
                tracing::warn!("running without an operation supervisor: {e}");
                None
            }
        };
        let dispatcher: ActorRef<DispatcherMsg> = self.root.start_child(spec).await?.into();
        let guard = give_ups.map(|rx| tokio::spawn(abort_on_give_up(rx, dispatcher.clone())));
        let report = dispatcher::request_run(&dispatcher).await;
        if let Some(guard) = guard {
            guard.abort();
        }
        Ok(report?)
    }

    /// A picture of the robot's run, to render over [`Node::world`] with
    /// [`Picture::render`]: the driven path and final footprint (from the cart), every sonar
    /// echo point stored in the feature datamanager (thinned out evenly to at most
    /// [`MAX_PICTURE_ECHOES`]), the newest extracted segments, the newest followed wall and
    /// detected dock (world datamanager), and the newest planned path (parameter
    /// datamanager), captioned `mission — outcome — seed N`.
    ///
    /// `None` when no robot runs. Whatever cannot be had — the cart does not answer, a
    /// datamanager fails, a record does not decode — is left out with a warning.
    pub async fn picture(&self, report: &RunReport) -> Option<Picture> {
        let robot = self.robot.as_ref()?;
        let outcome = match report.outcome {
            Outcome::Succeeded => "succeeded",
            Outcome::Failed => "failed",
        };
        let mut picture = Picture {
            caption: format!("{} — {outcome} — seed {}", report.mission, robot.seed),
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
            if let Some([x, y, theta]) = report.final_pose {
                let pose = Pose::new(x, y, theta);
                picture.footprint = Some(robot.world.cart.footprint(&pose));
            }
        }

        let feature = self.dm(dm::FEATURE);
        let scans: Vec<EchoScan> = decoded(&feature, Query::class(records::SONAR)).await;
        let echoes: Vec<Point> = scans
            .iter()
            .flat_map(|s| s.echoes.iter().map(|e| e.point))
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .collect();
        picture.sonar = thin_out(echoes, MAX_PICTURE_ECHOES);
        if let Some(set) = newest::<SegmentSet>(&feature, records::SEGMENTS).await {
            picture.segments = set.segments;
        }
        let world = self.dm(dm::WORLD);
        if let Some(wall) = newest::<WallRecord>(&world, records::WALL).await {
            picture.wall = Some(wall.segment);
        }
        if let Some(dock) = newest::<DockRecord>(&world, records::DOCK).await {
            picture.dock = Some(dock.corners);
        }
        let parameter = self.dm(dm::PARAMETER);
        if let Some(path) = newest::<PathRecord>(&parameter, records::PATH).await {
            picture.planned = path.waypoints();
        }
        Some(picture)
    }

    /// Stop the node's supervision tree, children in reverse start order, and wait for it.
    pub async fn shutdown(self) {
        self.root.stop().await;
    }
}

/// Fill the robot's part of `report` from the cart's final pose, collisions and the world's
/// judgement of them (or why the cart did not tell), and let the world overrule a success.
fn judge(report: &mut RunReport, robot: &Robot, status: Result<(Pose, u32, Judgement), CartError>) {
    report.seed = Some(robot.seed);
    let has_goal = robot.world.goal.is_some();
    let (pose, collisions, judgement) = match status {
        Ok(status) => status,
        Err(e) => {
            tracing::warn!("cannot judge the run: {e}");
            if has_goal && report.succeeded() {
                report.outcome = Outcome::Failed;
                report.reason =
                    format!("cannot judge the run in world `{}`: {e}", robot.world.name);
            }
            return;
        }
    };
    report.final_pose = Some([pose.x, pose.y, pose.theta]);
    report.collisions = Some(u64::from(collisions));
    report.inside_goal = has_goal.then_some(judgement.inside_goal);
    report.judgement = Some(judgement.to_string());
    if has_goal && report.succeeded() && !judgement.success {
        report.outcome = Outcome::Failed;
        report.reason = format!("the cart did not end in the goal area: {judgement}");
    }
}

/// Every record of `query`, decoded as `T`; records that do not decode, or a datamanager that
/// does not answer, are skipped with a warning.
async fn decoded<T: DeserializeOwned>(client: &Result<DmClient, DmError>, query: Query) -> Vec<T> {
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
async fn newest<T: DeserializeOwned>(client: &Result<DmClient, DmError>, class: &str) -> Option<T> {
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
        RunReport {
            mission: "m".into(),
            outcome,
            reason: match outcome {
                Outcome::Succeeded => String::new(),
                Outcome::Failed => "the dispatcher's reason".into(),
            },
            status: 0,
            flags: Vec::new(),
            actions: Vec::new(),
            rebinds: Vec::new(),
            duration_ms: 0,
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            faults: Vec::new(),
        }
    }

    fn robot(world: &str) -> Robot {
        Robot {
            world: World::builtin(world).expect("a shipped world"),
            seed: 9,
        }
    }

    fn at(robot: &Robot, pose: Pose, collisions: u32) -> Result<(Pose, u32, Judgement), CartError> {
        Ok((pose, collisions, robot.world.judge(pose, collisions)))
    }

    #[test]
    fn a_success_outside_the_goal_is_a_failure() {
        let lab = robot("lab");
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &lab, at(&lab, lab.world.start, 0));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(
            r.reason
                .starts_with("the cart did not end in the goal area: failure: outside"),
            "{}",
            r.reason
        );
        assert_eq!(r.final_pose, Some([12.5, 1.5, lab.world.start.theta]));
        assert_eq!(
            (r.collisions, r.seed, r.inside_goal),
            (Some(0), Some(9), Some(false))
        );
    }

    #[test]
    fn a_success_in_the_goal_stays_one_but_a_collision_fails_it() {
        let lab = robot("lab");
        let parked = Pose::new(4.9, -0.4, 0.0);
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &lab, at(&lab, parked, 0));
        assert_eq!((r.outcome, r.inside_goal), (Outcome::Succeeded, Some(true)));
        assert!(r
            .judgement
            .as_deref()
            .is_some_and(|j| j.starts_with("success")));
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &lab, at(&lab, parked, 2));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(r.reason.contains("2 collision(s)"), "{}", r.reason);
    }

    #[test]
    fn a_failure_keeps_the_dispatchers_reason() {
        let lab = robot("lab");
        let mut r = report(Outcome::Failed);
        judge(&mut r, &lab, at(&lab, lab.world.start, 0));
        assert_eq!(r.reason, "the dispatcher's reason");
        assert_eq!(r.collisions, Some(0));
    }

    #[test]
    fn a_world_without_a_goal_never_fails_a_run_on_its_own() {
        let nodock = robot("nodock");
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &nodock, at(&nodock, nodock.world.start, 1));
        assert_eq!(r.outcome, Outcome::Succeeded);
        assert_eq!((r.inside_goal, r.collisions), (None, Some(1)));
        assert!(r.judgement.is_some());
        // nor does a cart that does not answer
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &nodock, Err(CartError::Unreachable));
        assert_eq!(
            (r.outcome, r.final_pose, r.seed),
            (Outcome::Succeeded, None, Some(9))
        );
    }

    #[test]
    fn an_unanswering_cart_fails_a_run_that_needs_judging() {
        let lab = robot("lab");
        let mut r = report(Outcome::Succeeded);
        judge(&mut r, &lab, Err(CartError::NotFound));
        assert_eq!(r.outcome, Outcome::Failed);
        assert!(
            r.reason.contains("no virtual cart is running"),
            "{}",
            r.reason
        );
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

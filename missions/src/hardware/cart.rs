//! The virtual cart actor: steps the simulation on the node's clock and serves commands and
//! sensor readings.
//!
//! # Invariants
//! - Physics advances only on the cart's own ticks, by the clock time elapsed since the last
//!   one (in steps of at most [`CartArgs::period`]), so the cart moves at clock speed whether
//!   the clock is real, scaled or virtual.
//! - Commands take effect at the next physics step; readings reflect the last one.
//! - A drive command holds for [`COMMAND_HOLD`]: a controller that stops renewing it (hung,
//!   crashed, cut off from the cart) leaves a cart that brakes to a stop, as a real cart's
//!   motor controller does — rather than one that drives on blind until a stand-in takes
//!   over. Controllers renew theirs every control period.

use crate::geom::{Point, Pose};
use crate::sim::{Simulation, SonarReading, TracePoint};
use crate::telemetry::PoseSampler;
use crate::world::Judgement;
use marie_vocabulary::clock::{cast_after, SharedClock};
use marie_vocabulary::fence::{spawn_keeper, Fence, FenceTable, Obeyed, ObeyedLog};
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::rpc::CallResult;
use ractor::{Actor, ActorProcessingErr, ActorRef, SpawnErr, SupervisionEvent};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

/// How long a drive command holds without being renewed; then the cart brakes (steering
/// kept). Six of the controllers' 50 ms control periods.
pub(super) const COMMAND_HOLD: Duration = Duration::from_millis(300);

/// Registry id of the virtual cart.
pub const CART_ID: u32 = 1401;
/// Registry name of the virtual cart.
pub const CART_NAME: &str = "virtual-cart";

/// One scan of every ultrasonic sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarScan {
    /// Simulated time, seconds.
    pub time: f64,
    /// The cart's own pose estimate when it scanned.
    pub odometry: Pose,
    /// One reading per sensor.
    pub readings: Vec<SonarReading>,
    /// Each sensor's mount in the cart frame (index = sensor), as the robot's own
    /// calibration knows it.
    pub mounts: Vec<Pose>,
}

/// What the cart knows about itself (and, for judging, the simulation's ground truth).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartStatus {
    /// Simulated time, seconds.
    pub time: f64,
    /// True pose (ground truth).
    pub pose: Pose,
    /// The cart's own estimate.
    pub odometry: Pose,
    /// Current speed, m/s.
    pub speed: f64,
    /// Current steering angle, rad.
    pub steer: f64,
    /// Collisions so far.
    pub collisions: u32,
    /// Latched after a collision.
    pub collided: bool,
    /// Emergency stop engaged.
    pub emergency_stop: bool,
    /// Speed cap in force, m/s.
    pub speed_cap: Option<f64>,
    /// The last commanded `(speed, steer)`, before the cap.
    pub commanded: (f64, f64),
    /// Distance from the rear axle (the pose's reference point) to the footprint's centre, m.
    pub axle_to_centre: f64,
    /// The footprint's corners (ground truth).
    pub footprint: [Point; 4],
    /// The run judged against the world's goal area, as things stand.
    pub judgement: Judgement,
    /// Commands refused because they came from a replaced incarnation of an operation.
    pub refused: u64,
    /// Those commands by operation name (only operations with at least one).
    #[serde(default)]
    pub refused_by: BTreeMap<String, u64>,
    /// The seed of the simulation's noise: the cart's node's (a run joined to a cluster
    /// reports this one, not its own). `None` from a node that does not say.
    #[serde(default)]
    pub seed: Option<u64>,
    /// The commands the cart obeyed, by operation and epoch, with the first and the last
    /// one's time on its node's clock ([`ObeyedLog`]; the latest epochs of each operation):
    /// checked against when each epoch was bound, it shows whether a replaced incarnation
    /// was ever obeyed ([`marie_vocabulary::fence::obeyed_late`]).
    #[serde(default)]
    pub obeyed: Vec<Obeyed>,
}

marie_vocabulary::remote_message! {
    /// Messages of the virtual cart.
    pub enum CartMsg {
        /// Command the drive motor (m/s, negative backwards) and steering (rad, left positive).
        Drive {
            /// Speed, m/s.
            speed: f64,
            /// Steering angle, rad.
            steer: f64,
            /// Who commands, under which epoch: an older epoch of an operation than
            /// one the cart has obeyed is refused.
            fence: Fence,
        },
        /// Stop now: the drive commanded to 0 and the wheels stopped without the drive's
        /// lag, the emergency stop left as it is (another operation may hold it).
        Halt {
            /// Who commands, under which epoch: an older epoch of an operation than
            /// one the cart has obeyed is refused.
            fence: Fence,
        },
        /// Engage or release the emergency stop.
        EmergencyStop {
            /// Engage.
            on: bool,
            /// Who commands, under which epoch: an older epoch of an operation than
            /// one the cart has obeyed is refused.
            fence: Fence,
        },
        /// Cap the speed (both directions) at `max` m/s, or lift the cap with `None`; the
        /// capped command applies at once. Used by collision avoidance to slow the cart down
        /// whatever operation is driving it.
        SpeedCap {
            /// The cap, m/s.
            max: Option<f64>,
            /// Who commands, under which epoch: an older epoch of an operation than
            /// one the cart has obeyed is refused.
            fence: Fence,
        },
        /// Read every ultrasonic sensor.
        Scan {} -> SonarScan,
        /// Odometry, ground truth, collisions, judgement.
        Status {} -> CartStatus,
        /// The driven path so far.
        Trace {} -> Vec<TracePoint>,
        /// Put the cart back at rest at the world's start pose, its collisions and path
        /// started anew ([`Simulation::restart`]), between the runs of a cluster kept up;
        /// answers the status from there.
        Restart {} -> CartStatus,
    }
    local {
        /// Time for the next physics step.
        Tick {},
    }
}

/// Start-up arguments of the cart.
pub struct CartArgs {
    /// The simulation (world, seed) to drive.
    pub sim: Simulation,
    /// The node's clock.
    pub clock: SharedClock,
    /// Physics period, clock time.
    pub period: Duration,
    /// Publishes the cart's pose on the node's event bus as it drives (sampled on the
    /// physics ticks); `None`: the cart tells nobody.
    pub poses: Option<PoseSampler>,
}

impl std::fmt::Debug for CartArgs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CartArgs")
            .field("period", &self.period)
            .finish_non_exhaustive()
    }
}

/// The virtual cart actor.
#[derive(Debug)]
pub struct VirtualCart;

/// State of the cart actor.
pub struct CartState {
    sim: Simulation,
    clock: SharedClock,
    period: Duration,
    last: Duration,
    command: (f64, f64),
    /// Clock time of the last drive command.
    commanded_at: Duration,
    cap: Option<f64>,
    /// The newest epoch of each operation that commanded the cart, shared with its fence
    /// keeper (a dispatcher announces new epochs there before their first command).
    fences: Arc<Mutex<FenceTable>>,
    /// What it obeyed, by operation and epoch.
    obeyed: ObeyedLog,
    poses: Option<PoseSampler>,
}

impl std::fmt::Debug for CartState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CartState")
            .field("period", &self.period)
            .field("command", &self.command)
            .finish_non_exhaustive()
    }
}

impl CartState {
    /// Whether a command under `fence` is obeyed: not when it comes from a replaced
    /// incarnation of its operation (then it changes nothing, and is counted).
    fn admit(&mut self, fence: &Fence) -> bool {
        let mut fences = self.fences.lock().unwrap_or_else(|e| e.into_inner());
        match fences.admit(fence) {
            Ok(()) => {
                self.obeyed.record(fence, self.clock.now());
                true
            }
            Err(stale) => {
                // a replaced controller commands at its step rate: warn at the 1st, 2nd,
                // 4th, 8th… refusal of each operation, not at every one
                let n = fences.refused_by().get(&stale.operation).copied();
                if n.is_some_and(u64::is_power_of_two) {
                    tracing::warn!("cart command refused ({} so far): {stale}", n.unwrap_or(0));
                } else {
                    tracing::debug!("cart command refused: {stale}");
                }
                false
            }
        }
    }

    fn advance(&mut self) {
        let now = self.clock.now();
        let mut elapsed = now.saturating_sub(self.last);
        self.last = now;
        // cap a long stall (a loaded machine in real time) so the cart cannot jump through walls
        elapsed = elapsed.min(Duration::from_secs(1));
        while !elapsed.is_zero() {
            let dt = elapsed.min(self.period);
            self.sim.step(dt.as_secs_f64());
            elapsed -= dt;
        }
    }

    /// Brake when the drive command was not renewed within [`COMMAND_HOLD`].
    fn watchdog(&mut self) {
        let stale = self.clock.now().saturating_sub(self.commanded_at) > COMMAND_HOLD;
        if stale && self.command.0 != 0.0 {
            tracing::debug!(
                speed = self.command.0,
                "drive command not renewed within {COMMAND_HOLD:?}: braking"
            );
            self.command.0 = 0.0;
            self.apply_command();
        }
    }

    fn apply_command(&mut self) {
        let (speed, steer) = self.command;
        let speed = match self.cap {
            Some(cap) => speed.clamp(-cap.abs(), cap.abs()),
            None => speed,
        };
        self.sim.command(speed, steer);
    }

    fn status(&self) -> CartStatus {
        let fences = self.fences.lock().unwrap_or_else(|e| e.into_inner());
        CartStatus {
            time: self.sim.time(),
            pose: self.sim.pose(),
            odometry: self.sim.odometry(),
            speed: self.sim.speed(),
            steer: self.sim.steer(),
            collisions: self.sim.collisions(),
            collided: self.sim.is_collided(),
            emergency_stop: self.sim.is_emergency_stopped(),
            speed_cap: self.cap,
            commanded: self.command,
            axle_to_centre: self.sim.world().cart.center_offset(),
            footprint: self.sim.footprint(),
            judgement: self.sim.judge(),
            refused: fences.refused(),
            refused_by: fences.refused_by().clone(),
            seed: Some(self.sim.seed()),
            obeyed: self.obeyed.entries(),
        }
    }
}

fn schedule(myself: &ActorRef<CartMsg>, clock: &SharedClock, period: Duration) {
    cast_after(clock, period, myself, CartMsg::Tick {});
}

impl Actor for VirtualCart {
    type Msg = CartMsg;
    type State = CartState;
    type Arguments = CartArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<CartMsg>,
        args: CartArgs,
    ) -> Result<CartState, ActorProcessingErr> {
        registry::publish(ModuleKind::Hardware, CART_ID, CART_NAME, myself.get_cell())?;
        let fences = Arc::new(Mutex::new(FenceTable::default()));
        spawn_keeper(fences.clone(), myself.get_cell()).await?;
        let period = args.period.max(Duration::from_millis(1));
        schedule(&myself, &args.clock, period);
        Ok(CartState {
            last: args.clock.now(),
            sim: args.sim,
            clock: args.clock,
            period,
            command: (0.0, 0.0),
            commanded_at: Duration::ZERO,
            cap: None,
            fences,
            obeyed: ObeyedLog::default(),
            poses: args.poses,
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<CartMsg>,
        msg: CartMsg,
        state: &mut CartState,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            CartMsg::Tick {} => {
                state.advance();
                state.watchdog();
                if let Some(poses) = &mut state.poses {
                    poses.sample(state.sim.time(), &state.sim.pose());
                }
                schedule(&myself, &state.clock, state.period);
            }
            CartMsg::Drive { fence, .. }
            | CartMsg::Halt { fence }
            | CartMsg::SpeedCap { fence, .. }
            | CartMsg::EmergencyStop { fence, .. }
                if !state.admit(&fence) => {}
            CartMsg::Halt { .. } => {
                state.advance();
                state.command = (0.0, 0.0);
                state.commanded_at = state.clock.now();
                state.sim.halt();
            }
            CartMsg::Drive { speed, steer, .. } => {
                state.advance();
                state.command = (speed, steer);
                state.commanded_at = state.clock.now();
                state.apply_command();
            }
            CartMsg::SpeedCap { max, .. } => {
                state.advance();
                state.cap = max.filter(|m| m.is_finite());
                state.apply_command();
            }
            CartMsg::EmergencyStop { on, .. } => {
                state.advance();
                state.sim.emergency_stop(on);
            }
            CartMsg::Scan { reply } => {
                state.advance();
                let readings = state.sim.sonar_scan();
                let _ = reply.send(SonarScan {
                    time: state.sim.time(),
                    odometry: state.sim.odometry(),
                    readings,
                    mounts: state.sim.world().sonars.iter().map(|m| m.pose()).collect(),
                });
            }
            CartMsg::Status { reply } => {
                state.advance();
                let _ = reply.send(state.status());
            }
            CartMsg::Trace { reply } => {
                let _ = reply.send(state.sim.trace().to_vec());
            }
            CartMsg::Restart { reply } => {
                state.advance();
                state.sim.restart();
                // what held before holds no more: a controller of the next run commands anew
                state.command = (0.0, 0.0);
                state.commanded_at = state.clock.now();
                state.cap = None;
                state.obeyed.clear();
                tracing::info!("the cart is back at rest at the world's start");
                let _ = reply.send(state.status());
            }
        }
        Ok(())
    }

    /// The only linked child is the cart's fence keeper: should it stop, the cart fails
    /// with it (its supervisor restarts both) rather than go on deaf to announced epochs.
    async fn handle_supervisor_evt(
        &self,
        _myself: ActorRef<CartMsg>,
        event: SupervisionEvent,
        _state: &mut CartState,
    ) -> Result<(), ActorProcessingErr> {
        match event {
            SupervisionEvent::ActorTerminated(who, _, reason) => Err(format!(
                "the cart's fence keeper {} stopped: {reason:?}",
                who.get_id()
            )
            .into()),
            SupervisionEvent::ActorFailed(who, error) => {
                Err(format!("the cart's fence keeper {} failed: {error}", who.get_id()).into())
            }
            _ => Ok(()),
        }
    }
}

/// Spawn the virtual cart; it publishes itself before this returns.
pub async fn spawn_cart(args: CartArgs) -> Result<(ActorRef<CartMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn(None, VirtualCart, args).await
}

/// Spawn the virtual cart linked to `supervisor`.
pub async fn spawn_cart_linked(
    args: CartArgs,
    supervisor: ractor::ActorCell,
) -> Result<(ActorRef<CartMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn_linked(None, VirtualCart, args, supervisor).await
}

/// Why the cart did not answer.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CartError {
    /// No cart in the registry.
    #[error("no virtual cart is running")]
    NotFound,
    /// The cart did not answer in time, though the instance called still runs (as far as
    /// this node knows).
    #[error("the virtual cart did not answer")]
    Unreachable,
    /// The instance called stopped before it answered: the cart's node was lost or cut
    /// off from this one mid-call (its session closed), or the cart restarted. A new
    /// instance may be published by now.
    #[error("the virtual cart was lost before it answered")]
    Gone,
}

/// A typed handle to the cart.
#[derive(Clone, Debug)]
pub struct CartClient {
    actor: ActorRef<CartMsg>,
    fence: Fence,
}

impl CartClient {
    /// A handle to `actor`.
    pub fn new(actor: ActorRef<CartMsg>) -> Self {
        CartClient {
            actor,
            fence: Fence::default(),
        }
    }

    /// Send commands under `fence` (an operation's, from
    /// [`marie_actors::eo::OpContext::fence`]); without one they are unfenced.
    pub fn set_fence(&mut self, fence: Fence) {
        self.fence = fence;
    }

    /// The fence its commands carry.
    pub fn fence(&self) -> &Fence {
        &self.fence
    }

    /// The cart found in the registry.
    pub fn lookup() -> Result<Self, CartError> {
        registry::lookup(ModuleKind::Hardware, CART_NAME)
            .into_iter()
            .next()
            .map(|i| CartClient::new(i.actor.into()))
            .ok_or(CartError::NotFound)
    }

    /// True while the cart actor runs.
    pub fn is_alive(&self) -> bool {
        self.actor.get_status() <= ractor::ActorStatus::Running
    }

    /// Command speed and steering.
    pub fn drive(&self, speed: f64, steer: f64) -> Result<(), CartError> {
        self.actor
            .cast(CartMsg::Drive {
                speed,
                steer,
                fence: self.fence.clone(),
            })
            .map_err(|_| self.failed())
    }

    /// Cap the speed, or lift the cap.
    pub fn speed_cap(&self, max: Option<f64>) -> Result<(), CartError> {
        self.actor
            .cast(CartMsg::SpeedCap {
                max,
                fence: self.fence.clone(),
            })
            .map_err(|_| self.failed())
    }

    /// Stop now, leaving the emergency stop as it is ([`CartMsg::Halt`]).
    pub fn halt(&self) -> Result<(), CartError> {
        self.actor
            .cast(CartMsg::Halt {
                fence: self.fence.clone(),
            })
            .map_err(|_| self.failed())
    }

    /// Engage or release the emergency stop.
    pub fn emergency_stop(&self, on: bool) -> Result<(), CartError> {
        self.actor
            .cast(CartMsg::EmergencyStop {
                on,
                fence: self.fence.clone(),
            })
            .map_err(|_| self.failed())
    }

    async fn call<T: Send + 'static>(
        &self,
        make: impl FnOnce(ractor::RpcReplyPort<T>) -> CartMsg,
    ) -> Result<T, CartError> {
        match self.actor.call(make, Some(Duration::from_secs(5))).await {
            Ok(CallResult::Success(v)) => Ok(v),
            _ => Err(self.failed()),
        }
    }

    /// Why a message to the cart went unanswered: [`CartError::Gone`] when the instance
    /// called has stopped by now — a partition that outlasts the failure detector's
    /// deadline closes the session, and a call waiting on it ends only at its own deadline,
    /// when the cart may be back under a new instance —, [`CartError::Unreachable`]
    /// otherwise.
    fn failed(&self) -> CartError {
        if self.is_alive() {
            CartError::Unreachable
        } else {
            CartError::Gone
        }
    }

    /// Read every sonar.
    pub async fn scan(&self) -> Result<SonarScan, CartError> {
        self.call(|reply| CartMsg::Scan { reply }).await
    }

    /// The cart's status.
    pub async fn status(&self) -> Result<CartStatus, CartError> {
        self.call(|reply| CartMsg::Status { reply }).await
    }

    /// The driven path.
    pub async fn trace(&self) -> Result<Vec<TracePoint>, CartError> {
        self.call(|reply| CartMsg::Trace { reply }).await
    }

    /// Put the cart back at rest at the world's start pose ([`CartMsg::Restart`]); its
    /// status from there.
    pub async fn restart(&self) -> Result<CartStatus, CartError> {
        self.call(|reply| CartMsg::Restart { reply }).await
    }
}

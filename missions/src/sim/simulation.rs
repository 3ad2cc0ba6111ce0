//! The simulation: one virtual cart in one world, advanced by explicit time steps.

use super::cart::{bicycle_step, Drive};
use super::rng::Rng;
use super::sonar::{read_sensor, SonarReading};
use crate::geom::Pose;
use crate::world::{Judgement, World, WorldGeometry};
use serde::{Deserialize, Serialize};

/// Longest internal integration step, seconds.
const MAX_SUBSTEP: f64 = 0.02;
/// Farthest the cart may move in one internal step at top speed, metres (no tunnelling).
const MAX_SUBSTEP_DISTANCE: f64 = 0.02;
/// Longest `dt` one call to [`Simulation::step`] integrates; longer ones are cut to it.
pub const MAX_STEP: f64 = 3600.0;
/// Bisection rounds that place a colliding cart at its last free pose (≈ 0.1 % of a step).
const CONTACT_BISECTIONS: u32 = 10;
/// Trace sampling: a new sample after this distance (m) or heading change (rad).
const TRACE_DISTANCE: f64 = 0.05;
const TRACE_ANGLE: f64 = 0.035;
/// The trace is thinned (every other sample dropped, spacing doubled) beyond this length.
const TRACE_CAP: usize = 20_000;

/// Random sub-streams of one seed.
const STREAM_SONAR: u64 = 1;
const STREAM_ODOMETRY: u64 = 2;

/// One sample of the driven path.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TracePoint {
    /// Simulated time, seconds.
    pub time: f64,
    /// True pose of the cart (rear-axle centre).
    pub pose: Pose,
}

/// One collision: the footprint touched a wall or an obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CollisionEvent {
    /// Simulated time, seconds.
    pub time: f64,
    /// Where the cart was stopped: its last pose before the contact.
    pub pose: Pose,
    /// The speed it hit with, m/s.
    pub speed: f64,
}

/// A virtual cart driving in a world: car-like kinematics, emergency stop, collisions with
/// walls and obstacles, odometry, ultrasonic sensors. Deterministic: the same world, seed and
/// sequence of calls give bit-identical results.
///
/// - **Pose**: the rear-axle centre (see [`crate::world::CartSpec`]).
/// - **Commands** ([`command`](Self::command)): speed (m/s, negative = backwards) and steering
///   angle (rad, positive = left), clamped to the cart's limits; the speed follows with the
///   cart's first-order lag, the steering with its rate limit.
/// - **Emergency stop** ([`emergency_stop`](Self::emergency_stop)): while on, the wheels are
///   stopped at once and held, whatever the command; the steering is held too. Commands given
///   meanwhile are kept: on release the cart follows the latest one again.
/// - **Collisions**: after every internal step (≤ 20 ms, ≤ 2 cm) the footprint is tested
///   against the walls and obstacles. On contact the cart is put back at its last free pose
///   (found by bisection, so it stops within millimetres of the wall), stopped, the collision
///   is counted, and the cart is **latched**: it does not move in the direction it hit in.
///   The latch clears when a command asks for the opposite direction (backing away), or on
///   [`clear_collision`](Self::clear_collision). One contact episode counts once.
/// - **Odometry** ([`odometry`](Self::odometry)): the cart's own pose estimate, integrated
///   from its wheels, drifting as a real cart's does (the world's
///   [`crate::world::SimSettings`]; by default 1 % of distance and 0.5° of heading per metre,
///   1σ). `odometry_distance_sigma` draws one distance scale error per run (a miscalibrated
///   wheel); `odometry_heading_sigma` draws one heading drift rate per run (a steering offset:
///   radians per metre driven, its sign following the direction of travel), and
///   `odometry_heading_walk` adds a heading random walk (σ per √metre driven: wheel slip). A
///   zero sigma turns its error off.
#[derive(Clone, Debug)]
pub struct Simulation {
    world: World,
    geometry: WorldGeometry,
    seed: u64,
    time: f64,
    drive: Drive,
    pose: Pose,
    odometry: Pose,
    odometry_scale: f64,
    /// Systematic heading drift of the odometry, rad per metre driven (signed with travel).
    odometry_drift: f64,
    command_speed: f64,
    command_steer: f64,
    emergency: bool,
    /// Direction (±1) the cart hit in, while latched.
    latched: Option<f64>,
    collisions: u32,
    events: Vec<CollisionEvent>,
    trace: Vec<TracePoint>,
    trace_spacing: f64,
    sonar_rng: Rng,
    odometry_rng: Rng,
}

impl Simulation {
    /// A simulation of `world` with the cart at rest at its start pose. `seed` fixes all the
    /// noise. The collision geometry is built here, once. A hand-made world with an invalid
    /// cart falls back to the default cart.
    pub fn new(world: &World, seed: u64) -> Self {
        let mut world = world.clone();
        if !world.cart.is_valid() {
            world.cart = crate::world::CartSpec::default();
        }
        let geometry = WorldGeometry::new(&world);
        let mut odometry_rng = Rng::stream(seed, STREAM_ODOMETRY);
        let odometry_scale = 1.0 + odometry_rng.gaussian(world.sim.odometry_distance_sigma);
        let odometry_drift = odometry_rng.gaussian(world.sim.odometry_heading_sigma);
        let start = start_pose(&world);
        Simulation {
            drive: Drive::new(world.cart),
            geometry,
            seed,
            time: 0.0,
            pose: start,
            odometry: start,
            odometry_scale,
            odometry_drift,
            command_speed: 0.0,
            command_steer: 0.0,
            emergency: false,
            latched: None,
            collisions: 0,
            events: Vec::new(),
            trace: vec![TracePoint {
                time: 0.0,
                pose: start,
            }],
            trace_spacing: TRACE_DISTANCE,
            sonar_rng: Rng::stream(seed, STREAM_SONAR),
            odometry_rng,
            world,
        }
    }

    /// Put the cart back at rest at the world's start pose, as [`Simulation::new`] left it:
    /// no collision counted or latched, its path starting there anew, no command, the
    /// emergency stop released, the odometry at the start pose. Time goes on, and so does
    /// the noise (a run after this is no replay of the first). Why: a simulation kept
    /// running between runs — a cluster's cart — has its cart where the last run left it, as
    /// a real cart would; a user may rather start the next run as the first one started.
    pub fn restart(&mut self) {
        let start = start_pose(&self.world);
        self.drive = Drive::new(self.world.cart);
        self.pose = start;
        self.odometry = start;
        self.command_speed = 0.0;
        self.command_steer = 0.0;
        self.emergency = false;
        self.latched = None;
        self.collisions = 0;
        self.events.clear();
        self.trace = vec![TracePoint {
            time: self.time,
            pose: start,
        }];
    }

    /// The world simulated.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The collision geometry, for callers that cast their own rays.
    pub fn geometry(&self) -> &WorldGeometry {
        &self.geometry
    }

    /// The seed this run was started with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Simulated time since the start, seconds.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Command the drive: `speed` m/s (negative: backwards), `steer` radians (positive: left).
    /// Clamped to the cart's limits; non-finite values count as 0. Kept until the next command.
    pub fn command(&mut self, speed: f64, steer: f64) {
        self.command_speed = self.drive.clamp_speed(speed);
        self.command_steer = self.drive.clamp_steer(steer);
    }

    /// The current command (speed, steer), clamped.
    pub fn commanded(&self) -> (f64, f64) {
        (self.command_speed, self.command_steer)
    }

    /// Command a stop and stop the wheels at once (without the drive's lag), leaving the
    /// emergency stop as it is.
    pub fn halt(&mut self) {
        self.command(0.0, 0.0);
        self.drive.halt();
    }

    /// Engage (`true`) or release (`false`) the emergency stop. Engaging stops the wheels at
    /// once.
    pub fn emergency_stop(&mut self, on: bool) {
        self.emergency = on;
        if on {
            self.drive.halt();
        }
    }

    /// True while the emergency stop is engaged.
    pub fn is_emergency_stopped(&self) -> bool {
        self.emergency
    }

    /// Advance the simulation by `dt` seconds (cut to [`MAX_STEP`]; a `dt` that is not a
    /// positive number does nothing). Internally split into steps of at most 20 ms and 2 cm.
    pub fn step(&mut self, dt: f64) {
        if !(dt > 0.0 && dt.is_finite()) {
            return;
        }
        let dt = dt.min(MAX_STEP);
        let by_time = dt / MAX_SUBSTEP;
        let by_distance = dt * self.world.cart.max_speed / MAX_SUBSTEP_DISTANCE;
        let n = by_time.max(by_distance).ceil().max(1.0) as u64;
        let h = dt / n as f64;
        for _ in 0..n {
            self.substep(h);
        }
    }

    fn substep(&mut self, h: f64) {
        let mut target = if self.emergency {
            0.0
        } else {
            self.command_speed
        };
        if let Some(direction) = self.latched {
            if target != 0.0 && target.signum() != direction {
                self.latched = None;
            } else {
                target = 0.0;
            }
        }
        if self.emergency {
            self.drive.halt();
        } else {
            self.drive.update(h, target, self.command_steer);
        }
        if self.latched.is_some() {
            self.drive.halt();
        }
        let (v, phi) = (self.drive.speed(), self.drive.steer());
        let wheelbase = self.world.cart.wheelbase;
        if v != 0.0 {
            let next = bicycle_step(&self.pose, v, phi, wheelbase, h);
            if self.geometry.footprint_collides(&self.world.cart, &next) {
                let (mut free, mut hit) = (0.0, 1.0);
                for _ in 0..CONTACT_BISECTIONS {
                    let mid = (free + hit) / 2.0;
                    let p = bicycle_step(&self.pose, v, phi, wheelbase, h * mid);
                    if self.geometry.footprint_collides(&self.world.cart, &p) {
                        hit = mid;
                    } else {
                        free = mid;
                    }
                }
                let stop = bicycle_step(&self.pose, v, phi, wheelbase, h * free);
                self.advance_odometry(v, phi, h * free);
                self.pose = stop;
                self.collisions = self.collisions.saturating_add(1);
                self.latched = Some(v.signum());
                self.drive.halt();
                self.events.push(CollisionEvent {
                    time: self.time + h * free,
                    pose: stop,
                    speed: v,
                });
                self.time += h;
                self.sample_trace(true);
                return;
            }
            self.advance_odometry(v, phi, h);
            self.pose = next;
        }
        self.time += h;
        self.sample_trace(false);
    }

    fn advance_odometry(&mut self, v: f64, phi: f64, dt: f64) {
        let measured = v * self.odometry_scale;
        let mut odo = bicycle_step(&self.odometry, measured, phi, self.world.cart.wheelbase, dt);
        let ds = measured * dt;
        let walk_sigma = self.world.sim.odometry_heading_walk;
        let walk = if walk_sigma > 0.0 && walk_sigma.is_finite() {
            self.odometry_rng.gaussian(walk_sigma * ds.abs().sqrt())
        } else {
            0.0
        };
        let drift = self.odometry_drift * ds;
        if drift != 0.0 || walk != 0.0 {
            odo = Pose::new(odo.x, odo.y, odo.theta + drift + walk);
        }
        self.odometry = odo;
    }

    fn sample_trace(&mut self, force: bool) {
        let Some(last) = self.trace.last() else {
            self.trace.push(TracePoint {
                time: self.time,
                pose: self.pose,
            });
            return;
        };
        let moved = (self.pose.point() - last.pose.point()).norm();
        let turned = crate::geom::wrap_angle(self.pose.theta - last.pose.theta).abs();
        if force || moved >= self.trace_spacing || turned >= TRACE_ANGLE {
            self.trace.push(TracePoint {
                time: self.time,
                pose: self.pose,
            });
            if self.trace.len() > TRACE_CAP {
                let mut i = 0;
                self.trace.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.trace_spacing *= 2.0;
            }
        }
    }

    /// True pose of the cart (rear-axle centre).
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The cart's own pose estimate from its wheels (see the type's docs).
    pub fn odometry(&self) -> Pose {
        self.odometry
    }

    /// Actual speed, m/s.
    pub fn speed(&self) -> f64 {
        self.drive.speed()
    }

    /// Actual steering angle, radians.
    pub fn steer(&self) -> f64 {
        self.drive.steer()
    }

    /// The footprint's corners at the current pose.
    pub fn footprint(&self) -> [crate::geom::Point; 4] {
        self.world.cart.footprint(&self.pose)
    }

    /// Collisions counted so far.
    pub fn collisions(&self) -> u32 {
        self.collisions
    }

    /// Every collision so far, in order.
    pub fn collision_events(&self) -> &[CollisionEvent] {
        &self.events
    }

    /// True while the cart is latched after a collision (see the type's docs).
    pub fn is_collided(&self) -> bool {
        self.latched.is_some()
    }

    /// Release the collision latch: the cart may move in any direction again (a new contact
    /// counts as a new collision).
    pub fn clear_collision(&mut self) {
        self.latched = None;
    }

    /// The driven path: the start pose, then a sample every 5 cm or 2° (and at every
    /// collision). Very long runs are thinned to at most 20 000 samples.
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }

    /// Read every ultrasonic sensor once, in the world's order.
    pub fn sonar_scan(&mut self) -> Vec<SonarReading> {
        let mut out = Vec::with_capacity(self.world.sonars.len());
        for (i, mount) in self.world.sonars.iter().enumerate() {
            out.push(read_sensor(
                &self.geometry,
                &self.world.sim,
                &mut self.sonar_rng,
                &self.pose,
                i,
                mount,
                self.time,
            ));
        }
        out
    }

    /// Read one ultrasonic sensor; `None` when there is no sensor `sensor`.
    pub fn sonar_read(&mut self, sensor: usize) -> Option<SonarReading> {
        let mount = self.world.sonars.get(sensor)?;
        Some(read_sensor(
            &self.geometry,
            &self.world.sim,
            &mut self.sonar_rng,
            &self.pose,
            sensor,
            mount,
            self.time,
        ))
    }

    /// Judge the run so far: the current pose and collision count against the world's goal.
    pub fn judge(&self) -> Judgement {
        self.world.judge(self.pose, self.collisions)
    }
}

/// Where the cart starts in `world`: its start pose, or the origin when that is not finite
/// (a hand-made world).
fn start_pose(world: &World) -> Pose {
    if world.start.x.is_finite() && world.start.y.is_finite() && world.start.theta.is_finite() {
        world.start
    } else {
        Pose::default()
    }
}

//! The simulated robot: a virtual cart with car-like kinematics, an emergency stop, collision
//! detection and ultrasonic sensors, in a [`World`](crate::world::World).
//!
//! A plain, synchronous library — no actors, no clock of its own: the caller advances the
//! time with [`Simulation::step`]. Given the same world, seed and sequence of calls, a run is
//! bit-for-bit repeatable (see [`Rng`]).
//!
//! - [`cart`]: the kinematic bicycle model ([`bicycle_step`]) and the actuators ([`Drive`]).
//! - [`sonar`]: beams as cones of parry2d ray casts; oblique rays are lost ([`SonarReading`]).
//! - [`simulation`]: the [`Simulation`] that ties them to a world.
//! - [`rng`]: the seeded random numbers.
//!
//! # Example
//!
//! Drive along the lab's wall for two seconds, then look around:
//!
//! ```
//! use marie_missions::sim::Simulation;
//! use marie_missions::world::World;
//!
//! let world = World::builtin("lab").unwrap();
//! let mut sim = Simulation::new(&world, 42);
//! sim.command(0.4, 0.0); // 0.4 m/s straight ahead (the cart faces -x)
//! for _ in 0..100 {
//!     sim.step(0.02);
//! }
//! assert!(sim.pose().x < world.start.x - 0.5);
//! assert_eq!(sim.collisions(), 0);
//!
//! let scan = sim.sonar_scan();
//! assert_eq!(scan.len(), world.sonars.len());
//! // the left side sensors see the wall about 1.2 m away
//! let left = scan[3].range.unwrap();
//! assert!((left - 1.2).abs() < 0.1, "{left}");
//!
//! sim.emergency_stop(true);
//! sim.step(1.0);
//! assert_eq!(sim.speed(), 0.0);
//! assert!(!sim.judge().success); // not parked in the dock
//! ```

pub mod cart;
pub mod rng;
pub mod simulation;
pub mod sonar;

pub use cart::{bicycle_step, Drive};
pub use rng::Rng;
pub use simulation::{CollisionEvent, Simulation, TracePoint, MAX_STEP};
pub use sonar::{read_sensor, SonarReading};

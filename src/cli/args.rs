//! Flags and value parsers shared by several verbs.

use std::path::PathBuf;

/// The simulated robot a mission runs with.
#[derive(clap::Args, Debug)]
pub struct RobotArgs {
    /// World file the simulated robot drives in; overrides the mission's `world`. Without
    /// either, no robot is started.
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Seed of the simulation's noise (same world, seed and mission: same run).
    #[arg(long, value_name = "N", default_value_t = marie::node::DEFAULT_SEED)]
    pub seed: u64,
}

/// `--speed max`: as fast as the CPU allows.
pub const MAX_SPEED: f64 = f64::INFINITY;

/// The slowest `--speed`: a hundredth of real time (slower is a stall, not a run).
pub const SLOWEST: f64 = 0.01;

/// The fastest `--speed` factor; beyond it a factor means `max` and should say so.
pub const FASTEST: f64 = 1_000_000.0;

/// `--speed X|max`: X a factor of real time from [`SLOWEST`] to [`FASTEST`].
pub fn parse_speed(s: &str) -> Result<f64, String> {
    if s == "max" {
        return Ok(MAX_SPEED);
    }
    match s.parse::<f64>() {
        Ok(x) if (SLOWEST..=FASTEST).contains(&x) => Ok(x),
        _ => Err(format!(
            "expected a factor of real time from {SLOWEST} to {FASTEST}, or `max`, got {s:?}"
        )),
    }
}

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

/// `--speed max`: virtual time, as fast as the CPU allows.
pub const MAX_SPEED: f64 = f64::INFINITY;

/// `--speed X|max`.
pub fn parse_speed(s: &str) -> Result<f64, String> {
    if s == "max" {
        return Ok(MAX_SPEED);
    }
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("expected a positive number or `max`, got {s:?}")),
    }
}

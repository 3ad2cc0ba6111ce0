//! Flags and value parsers shared by several verbs.

use marie_missions::embedded::EmbeddedOptions;
use std::path::{Path, PathBuf};

/// What the embedded node hosts, and the simulated robot a mission runs with.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct RobotArgs {
    /// World file the simulated robot drives in; overrides the node config's and the
    /// mission's `world`. Without any, no robot is started.
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Seed of the simulation's noise (same world, seed and mission: same run); default: the
    /// node config's, else 1.
    #[arg(long, value_name = "N", value_parser = parse_seed, allow_hyphen_values = true)]
    pub seed: Option<u64>,
    /// Host exactly what this node config says (`missions/nodes/*.toml`); default: a built-in
    /// node that hosts every operation, the three datamanagers and the robot.
    #[arg(long, value_name = "FILE")]
    pub node: Option<PathBuf>,
    /// The node's data directory (`marie run --data-dir`; not a flag of the other verbs,
    /// whose nodes live only as long as one request).
    #[arg(skip)]
    pub data_dir: Option<PathBuf>,
}

impl RobotArgs {
    /// The embedded node's options, for a mission whose world is `mission_world`.
    pub(crate) fn options(&self, mission_world: Option<&Path>) -> EmbeddedOptions {
        EmbeddedOptions {
            node: self.node.clone(),
            world: self.world.clone(),
            mission_world: mission_world.map(Path::to_path_buf),
            seed: self.seed,
            data_dir: self.data_dir.clone(),
            ..EmbeddedOptions::default()
        }
    }
}

/// A seed (`--seed`, `--chaos`): a whole number from 0 to 2^64 - 1. A negative one is read as
/// a value (not as a flag) so that the message says what is wrong with it.
pub(crate) fn parse_seed(s: &str) -> Result<u64, BadSeed> {
    s.parse::<u64>().map_err(|_| BadSeed { got: s.to_string() })
}

/// A seed that is not one ([`parse_seed`]).
#[derive(Debug, thiserror::Error)]
#[error("expected a whole number from 0 to {}, got {got:?}", u64::MAX)]
pub(crate) struct BadSeed {
    got: String,
}

/// `--speed max`: as fast as the CPU allows.
pub(crate) const MAX_SPEED: f64 = f64::INFINITY;

/// The slowest `--speed`: a hundredth of real time (slower is a stall, not a run).
pub(crate) const SLOWEST: f64 = 0.01;

/// The fastest `--speed` factor; beyond it a factor means `max` and should say so.
pub(crate) const FASTEST: f64 = 1_000_000.0;

/// `--speed X|max`: X a factor of real time from [`SLOWEST`] to [`FASTEST`].
pub(crate) fn parse_speed(s: &str) -> Result<f64, BadSpeed> {
    if s == "max" {
        return Ok(MAX_SPEED);
    }
    match s.parse::<f64>() {
        Ok(x) if (SLOWEST..=FASTEST).contains(&x) => Ok(x),
        _ => Err(BadSpeed { got: s.to_string() }),
    }
}

/// A `--speed` that is not one ([`parse_speed`]).
#[derive(Debug, thiserror::Error)]
#[error(
    "expected a factor of real time from {} to {}, or `max`, got {got:?}",
    SLOWEST,
    FASTEST
)]
pub(crate) struct BadSpeed {
    got: String,
}

/// `--speed` of a cluster member (`node`, `up`): a factor within
/// [`marie::cluster::layout::SPEED_RANGE`]; `max` is refused (a cluster runs on the wall clock).
pub(crate) fn parse_cluster_speed(s: &str) -> Result<f64, BadClusterSpeed> {
    match s.parse::<f64>() {
        Ok(x) => Ok(marie::cluster::layout::cluster_speed(x)?),
        Err(_) => Err(BadClusterSpeed::NotANumber { got: s.to_string() }),
    }
}

/// A cluster member's `--speed` that is not one ([`parse_cluster_speed`]).
#[derive(Debug, thiserror::Error)]
pub(crate) enum BadClusterSpeed {
    /// A number outside the cluster's range.
    #[error(transparent)]
    OutOfRange(#[from] marie::cluster::layout::SpeedError),
    /// Not a number.
    #[error("{}, got {got:?}", marie::cluster::layout::speed_expected())]
    NotANumber {
        /// As written.
        got: String,
    },
}

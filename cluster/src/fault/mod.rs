//! Fault injection: kill, panic or hang an operation, on purpose, to test self-healing.
//!
//! It lives with the node (not in `marie-supervision`, which knows no operation): a fault
//! is aimed at an operation found in the registry, and a [`plan::FaultPlan`] injects faults
//! on a run's mission clock.
//!
//! Tests of embedding applications and the CLI (`marie run --fault kill:NAME@SECS`,
//! `--chaos SEED`, `marie kill NAME|ID`) use the same three faults:
//!
//! * **kill** — the instance's actor is killed (`ActorCell::kill`): no cooperation needed,
//!   its supervisor sees an abnormal exit;
//! * **panic** — the instance's host panics in its message handler
//!   ([`marie_actors::eo::Fault::Panic`]);
//! * **hang** — the instance's host stops answering
//!   ([`marie_actors::eo::Fault::Hang`]); only a kill ends it, which is what a dispatcher does
//!   when the operation misses its answer deadline.
//!
//! ```
//! use marie_cluster::fault::{FaultKind, FaultSpec};
//! use std::time::Duration;
//! let spec: FaultSpec = "panic:wall-sensor@12.5".parse().unwrap();
//! assert_eq!(spec.kind, FaultKind::Panic);
//! assert_eq!(spec.target, "wall-sensor");
//! assert_eq!(spec.at, Duration::from_millis(12_500));
//! assert!("explode:wall-sensor@1".parse::<FaultSpec>().is_err());
//! ```

pub mod plan;
mod target;

pub use plan::FaultPlan;

use marie_actors::eo::{EoClient, Fault};
use marie_actors::registry::{self, Instance, ModuleKind};
use ractor::ActorId;
use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// What to do to an operation: one type shared with the run report and the event stream.
pub use marie_actors::eo::FaultKind;

/// The latest mission time a fault may be planned for: a day (no mission may wait longer).
pub const MAX_FAULT_SECS: f64 = 86_400.0;

/// A fault to inject into operation `target` (a name or a numeric id) at `at` after the
/// mission started: `KIND:TARGET@SECONDS`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FaultSpec {
    /// What to do.
    pub kind: FaultKind,
    /// Operation name or id.
    pub target: String,
    /// When, in mission clock time since the run began.
    pub at: Duration,
}

impl fmt::Display for FaultSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}@{}", self.kind, self.target, self.at.as_secs_f64())
    }
}

impl FromStr for FaultSpec {
    type Err = FaultError;

    fn from_str(s: &str) -> Result<Self, FaultError> {
        let syntax = || {
            FaultError::Syntax(format!(
                "`{s}` is not a fault: expected KIND:NAME@SECONDS, e.g. kill:wall-sensor@12"
            ))
        };
        let (kind, rest) = s.split_once(':').ok_or_else(syntax)?;
        let (target, at) = rest.rsplit_once('@').ok_or_else(syntax)?;
        let kind: FaultKind = kind
            .trim()
            .parse()
            .map_err(|e: marie_actors::eo::UnknownFault| FaultError::Syntax(e.to_string()))?;
        let target = target.trim();
        if target.is_empty() {
            return Err(FaultError::Syntax(format!(
                "`{s}` names no operation before `@`"
            )));
        }
        let secs: f64 = at.trim().parse().map_err(|_| {
            FaultError::Syntax(format!("`{at}` in `{s}` is not a number of seconds"))
        })?;
        if !secs.is_finite() || !(0.0..=MAX_FAULT_SECS).contains(&secs) {
            return Err(FaultError::Syntax(format!(
                "the time in `{s}` must be a number of seconds from 0 to {MAX_FAULT_SECS}"
            )));
        }
        Ok(FaultSpec {
            kind,
            target: target.to_string(),
            at: Duration::from_secs_f64(secs),
        })
    }
}

/// Why a fault could not be injected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultError {
    /// A fault spec that does not parse.
    #[error("{0}")]
    Syntax(String),
    /// No live operation has that name or id.
    #[error("no operation `{0}` is running")]
    NotFound(String),
    /// The operation's actor is gone.
    #[error("operation `{0}` could not be reached")]
    Unreachable(String),
}

/// What was done, to whom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Injected {
    /// The fault.
    pub kind: FaultKind,
    /// The operation's name.
    pub name: String,
    /// The instance that got it.
    pub actor: ActorId,
}

/// Inject `kind` into the first live instance of operation `target` (name or id).
pub fn inject(kind: FaultKind, target: &str) -> Result<Injected, FaultError> {
    let inst = registry::lookup(ModuleKind::Operation, target)
        .into_iter()
        .next()
        .ok_or_else(|| FaultError::NotFound(target.to_string()))?;
    inject_into(kind, &inst)
}

/// Inject `kind` into the instance `inst`.
pub fn inject_into(kind: FaultKind, inst: &Instance) -> Result<Injected, FaultError> {
    let client = EoClient::from_cell(inst.actor.clone());
    let unreachable = |_| FaultError::Unreachable(inst.name.clone());
    match kind {
        // a remote instance's local stand-in would die alone: ask the instance itself
        FaultKind::Kill if !inst.actor.get_id().is_local() => {
            client.inject(Fault::Kill).map_err(unreachable)?
        }
        FaultKind::Kill => inst.actor.kill(),
        FaultKind::Panic => client.inject(Fault::Panic).map_err(unreachable)?,
        FaultKind::Hang => client.inject(Fault::Hang).map_err(unreachable)?,
    }
    tracing::warn!(fault = %kind, op = %inst.name, actor = %inst.actor.get_id(), "fault injected");
    Ok(Injected {
        kind,
        name: inst.name.clone(),
        actor: inst.actor.get_id(),
    })
}

/// Random faults for `--chaos SEED`: at random gaps, kill a random operation among those
/// given. Deterministic for a seed (the same gaps and picks, given the same candidates).
#[derive(Clone, Debug)]
pub struct Chaos {
    rng: Xoshiro256StarStar,
    /// Shortest gap between two kills.
    pub min_gap: Duration,
    /// Longest gap between two kills.
    pub max_gap: Duration,
}

impl Chaos {
    /// Chaos seeded by `seed`, with kills every 4 to 12 seconds.
    pub fn new(seed: u64) -> Chaos {
        Chaos {
            rng: Xoshiro256StarStar::seed_from_u64(seed),
            min_gap: Duration::from_secs(4),
            max_gap: Duration::from_secs(12),
        }
    }

    /// Use gaps between `min` and `max`.
    pub fn with_gaps(mut self, min: Duration, max: Duration) -> Chaos {
        self.min_gap = min.min(max);
        self.max_gap = max.max(min);
        self
    }

    /// The time until the next kill.
    pub fn next_gap(&mut self) -> Duration {
        let span = self.max_gap.saturating_sub(self.min_gap).as_secs_f64();
        self.min_gap + Duration::from_secs_f64(span * unit(self.rng.next_u64()))
    }

    /// Pick one of `candidates` (`None` if there are none).
    pub fn pick<'a, T>(&mut self, candidates: &'a [T]) -> Option<&'a T> {
        if candidates.is_empty() {
            return None;
        }
        let i = (self.rng.next_u64() % candidates.len() as u64) as usize;
        candidates.get(i)
    }
}

/// A uniform draw in [0, 1) from 64 random bits (the top 53, as many as an f64 holds).
fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_print_back() {
        for text in [
            "kill:ultrasonic@0",
            "hang:1512@3.25",
            "panic:wall-follower@120",
        ] {
            let spec: FaultSpec = text.parse().unwrap();
            assert_eq!(spec.to_string(), text);
        }
    }

    #[test]
    fn bad_specs_say_what_is_wrong() {
        let cases = [
            ("kill", "expected KIND:NAME@SECONDS"),
            ("kill:x", "expected KIND:NAME@SECONDS"),
            ("melt:x@1", "unknown fault `melt`"),
            ("kill:@1", "names no operation"),
            ("kill:x@soon", "`soon` in `kill:x@soon` is not a number"),
            ("kill:x@-1", "from 0 to 86400"),
            ("kill:x@inf", "from 0 to 86400"),
            ("kill:x@1e300", "from 0 to 86400"),
            ("kill:x@nan", "from 0 to 86400"),
        ];
        for (text, want) in cases {
            let err = text.parse::<FaultSpec>().unwrap_err().to_string();
            assert!(err.contains(want), "{text}: {err}");
        }
    }

    #[test]
    fn chaos_is_deterministic_and_stays_within_its_gaps() {
        let mut a = Chaos::new(7);
        let mut b = Chaos::new(7);
        let names = ["a", "b", "c"];
        for _ in 0..100 {
            let gap = a.next_gap();
            assert_eq!(gap, b.next_gap());
            assert!(gap >= a.min_gap && gap <= a.max_gap);
            assert_eq!(a.pick(&names), b.pick(&names));
        }
        assert_eq!(a.pick::<&str>(&[]), None);
    }
}

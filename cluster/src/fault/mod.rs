//! Fault injection: kill, panic or hang an operation or a datamanager, stop or freeze a
//! node's process, or cut the network between nodes, on purpose, to test self-healing.
//!
//! Every source of faults — a run's plan (`marie run --fault KIND:TARGET@SECS`), seeded
//! chaos (`--chaos SEED`), `marie kill`, the monitor's page — takes one road:
//!
//! 1. the kind is a [`FaultKind`] (`marie_vocabulary::run`, the one vocabulary the events and
//!    reports share), and says what it aims at: an operation or a node;
//! 2. the target is parsed once into a [`Target`] (`NAME`, `ID`, `NAME#VERSION`, an actor
//!    id, `NAME/NODE[/ADDRESS]`, a node's name, or two groups of nodes `A,B|C,D`), carried
//!    in the [`FaultSpec`] with, for a fault that lasts (a freeze, a cut), its duration;
//! 3. an [`Injector`] resolves it — against the registry, the bindings of the run it follows
//!    (a name means the instance the mission bound, through rebinds) and the node processes
//!    this process may stop, freeze or cut apart ([`NodeProcesses`], with a
//!    [`NodeNetwork`]) — does it, and publishes what became of it on the node's event bus
//!    (`fault_injected`, or `fault_not_injected` and why; `fault_healed` when a lasting one
//!    is undone), so the run's report, an events file and the monitor all hold it.
//!
//! It lives with the node, not in `marie-supervision` (which knows no operation).
//!
//! ```
//! use marie_vocabulary::run::FaultKind;
//! use marie_cluster::fault::{FaultSpec, Target};
//! use std::time::Duration;
//! let spec: FaultSpec = "panic:wall-sensor@12.5".parse().unwrap();
//! assert_eq!(spec.kind, FaultKind::Panic);
//! assert_eq!(spec.target, Target::Bound("wall-sensor".into()));
//! assert_eq!(spec.at, Duration::from_millis(12_500));
//! let stop: FaultSpec = "stop-node:wf-a@20".parse().unwrap();
//! assert_eq!(stop.target, Target::Node("wf-a".into()));
//! let freeze: FaultSpec = "freeze-node:wf-a@20+5".parse().unwrap();
//! assert_eq!(freeze.lasting, Some(Duration::from_secs(5)));
//! let cut: FaultSpec = "partition:cart,features|operations@30+3".parse().unwrap();
//! assert_eq!(cut.target.to_string(), "cart,features|operations");
//! assert!("freeze-node:wf-a@20".parse::<FaultSpec>().is_err(), "a freeze says how long");
//! assert!("explode:wall-sensor@1".parse::<FaultSpec>().is_err());
//! ```

mod chaos;
mod inject;
mod network;
mod node_chaos;
mod plan;
mod processes;
mod resolve;
mod target;

pub use chaos::Chaos;
pub use inject::{inject_into, Injected, Injector};
pub use network::NodeNetwork;
pub use node_chaos::{NodeChaos, NodeStrike, Struck, DEFAULT_MAX_GAP, DEFAULT_MIN_GAP};
pub(crate) use plan::{FaultPlan, PlanRun};
pub use processes::NodeProcesses;
pub use resolve::{find, Hit, RunBindings};
pub use target::{Target, TargetError};

use marie_vocabulary::run::{FaultKind, UnknownFault};
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// The latest mission time a fault may be planned for: a day (no mission may wait longer).
pub const MAX_FAULT_SECS: f64 = 86_400.0;

/// A fault to inject at `at` after the mission started: `KIND:TARGET@SECONDS`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FaultSpec {
    /// What to do.
    pub kind: FaultKind,
    /// What to do it to (of the kind's [`Aim`](marie_vocabulary::run::Aim)).
    pub target: Target,
    /// When, in mission clock time since the run began.
    pub at: Duration,
    /// For a kind that [lasts](FaultKind::lasts) (a freeze, a cut): for how long, in
    /// mission clock time (`@T+D`); `None` for the others.
    pub lasting: Option<Duration>,
}

impl fmt::Display for FaultSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}@{}", self.kind, self.target, self.at.as_secs_f64())?;
        match self.lasting {
            Some(d) => write!(f, "+{}", d.as_secs_f64()),
            None => Ok(()),
        }
    }
}

impl FromStr for FaultSpec {
    type Err = FaultError;

    /// `KIND:TARGET@SECONDS`, and `+SECONDS` for a kind that lasts: the kind, then a
    /// target of what the kind aims at, then a time from 0 to [`MAX_FAULT_SECS`] (and a
    /// duration above 0 up to it) — each checked here, once.
    fn from_str(s: &str) -> Result<Self, FaultError> {
        let syntax = || {
            FaultError::Syntax(format!(
                "`{s}` is not a fault: expected KIND:TARGET@SECONDS, e.g. \
                 kill:wall-follower@12 (TARGET: NAME, ID, NAME#VERSION, NAME/NODE or an \
                 actor id like 0.42; a node's name for stop-node; freeze-node:NODE@T+D and \
                 partition:A,B|C,D@T+D last D seconds)"
            ))
        };
        let (kind, rest) = s.split_once(':').ok_or_else(syntax)?;
        let (target, when) = rest.rsplit_once('@').ok_or_else(syntax)?;
        let kind: FaultKind = kind
            .trim()
            .parse()
            .map_err(|e: UnknownFault| FaultError::Syntax(e.to_string()))?;
        let (at, lasting) = match when.split_once('+') {
            Some((at, lasting)) => (at, Some(lasting)),
            None => (when, None),
        };
        let seconds = |text: &str, what: &str, min_exclusive: bool| {
            let secs: f64 = text.trim().parse().map_err(|_| {
                FaultError::Syntax(format!("`{text}` in `{s}` is not a number of seconds"))
            })?;
            let low_ok = if min_exclusive {
                secs > 0.0
            } else {
                secs >= 0.0
            };
            if !secs.is_finite() || !low_ok || secs > MAX_FAULT_SECS {
                return Err(FaultError::Syntax(format!(
                    "the {what} in `{s}` must be a number of seconds of mission time from \
                     {} to {MAX_FAULT_SECS}",
                    if min_exclusive { "above 0" } else { "0" }
                )));
            }
            Ok(Duration::from_secs_f64(secs))
        };
        let at = seconds(at, "time", false)?;
        let lasting = match (lasting, kind.lasts()) {
            (Some(d), true) => Some(seconds(d, "duration", true)?),
            (None, false) => None,
            (None, true) => {
                return Err(FaultError::Syntax(format!(
                    "`{s}`: a {kind} lasts a while: say how long, as {kind}:TARGET@SECONDS+SECONDS"
                )))
            }
            (Some(_), false) => {
                return Err(FaultError::Syntax(format!(
                    "`{s}`: a {kind} does not last a while: no +SECONDS (only freeze-node and \
                     partition take one)"
                )))
            }
        };
        let target = Target::parse(target.trim(), kind.aim())?;
        Ok(FaultSpec {
            kind,
            target,
            at,
            lasting,
        })
    }
}

/// Why a fault was not injected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultError {
    /// A fault spec that does not parse.
    #[error("{0}")]
    Syntax(String),
    /// The target names nothing to hit (or several).
    #[error(transparent)]
    Target(#[from] TargetError),
    /// The kind aims at something other than the target names (`stop-node` of an
    /// operation).
    #[error("a {kind} fault aims at {wants}, and `{target}` is not one")]
    Mismatch {
        /// The fault.
        kind: FaultKind,
        /// What the kind aims at.
        wants: &'static str,
        /// The target, as written.
        target: String,
    },
    /// The operation's (or datamanager's) actor could not be reached.
    #[error("`{0}` could not be reached")]
    Unreachable(String),
    /// The node's process could not be signalled, or the network cut.
    #[error("cannot {kind} {node} (pid {pid}): {why}")]
    Signal {
        /// The fault.
        kind: FaultKind,
        /// The node.
        node: String,
        /// Its process.
        pid: u32,
        /// What the OS said.
        why: String,
    },
    /// The network between two groups of nodes could not be cut.
    #[error("cannot cut {cut} apart: {why}")]
    Network {
        /// The cut, as written (`A,B|C,D`).
        cut: String,
        /// What went wrong.
        why: String,
    },
}

impl FaultError {
    /// Whether the fault's target named nothing that runs (a 404 to the monitor's page; a
    /// stale target, as opposed to one that cannot be written or names several).
    pub fn is_not_found(&self) -> bool {
        matches!(self, FaultError::Target(t) if t.is_not_found())
    }
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
            "kill:wall-follower#2.0.0@20",
            "kill:wall-follower/wf-b@20",
            "stop-node:wf-a@20",
            "freeze-node:wf-a@20+5",
            "freeze-node:wf-a@0+0.5",
            "partition:cart,features|operations,spare@30.5+3",
        ] {
            let spec: FaultSpec = text.parse().unwrap();
            assert_eq!(spec.to_string(), text);
        }
    }

    #[test]
    fn bad_specs_say_what_is_wrong() {
        let cases = [
            ("kill", "expected KIND:TARGET@SECONDS"),
            ("kill:x", "expected KIND:TARGET@SECONDS"),
            ("melt:x@1", "unknown fault `melt`"),
            ("kill:@1", "is not a fault target"),
            ("kill:x@soon", "`soon` in `kill:x@soon` is not a number"),
            ("kill:x@-1", "from 0 to 86400"),
            ("kill:x@inf", "from 0 to 86400"),
            ("kill:x@1e300", "from 0 to 86400"),
            ("kill:x@nan", "from 0 to 86400"),
            ("stop-node:wf-a#1.0.0@1", "is not a node's name"),
            ("kill:wall follower@1", "is not a fault target"),
            ("freeze-node:wf-a@1", "say how long"),
            ("partition:a|b@1", "say how long"),
            ("kill:x@1+2", "does not last a while"),
            ("freeze-node:wf-a@1+0", "from above 0"),
            ("freeze-node:wf-a@1+x", "`x` in"),
            ("partition:a|a@1+1", "is not a cut"),
            ("partition:a@1+1", "is not a cut"),
        ];
        for (text, want) in cases {
            let err = text.parse::<FaultSpec>().unwrap_err().to_string();
            assert!(err.contains(want), "{text}: {err}");
        }
    }
}

//! The faults marie injects on purpose, as one vocabulary: what `--fault`, `--chaos`,
//! `marie kill` and the monitor's page ask for, what an operation's host commits, and what
//! the run's events and report record.
//!
//! Adding a kind is a variant here (its name, what it aims at) plus its behaviour where it
//! is done: an operation's host for the operation kinds (`eo/host.rs`), the node-process
//! table and the private network of `marie up` for the node kinds (`marie_cluster::fault`).
//! Everything that parses, offers, resolves, publishes and reports faults reads this enum.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// What is done, on purpose, to test self-healing. Serialized as its [`name`](Self::name)
/// (`kill`, `panic`, `hang`, `slow`, `stop-node`, `freeze-node`, `partition`) — stable
/// names, read back by reports and event files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// Kill the operation instance's actor: no cooperation needed, its supervisor sees an
    /// abnormal exit.
    Kill,
    /// Make the instance's host panic in its message handler: its supervisor sees a
    /// failure.
    Panic,
    /// Make the instance's host stop answering: only a kill ends it, which is what a
    /// dispatcher does once the operation misses its answer deadline.
    Hang,
    /// Make the instance slow: from then on each of its steps comes
    /// [`SLOW_FACTOR`](Self::SLOW_FACTOR) times
    /// later than its period says (a starved or overloaded operation). It keeps answering,
    /// so nothing replaces it: what suffers is the control it gives, until a restart.
    Slow,
    /// Kill a node's process (`SIGKILL`, as a crash would): its peers lose it, their
    /// failure detectors declare it down, the dispatcher rebinds to survivors. Only a
    /// process that started the node can do it (`marie up`).
    StopNode,
    /// Freeze a node's process (`SIGSTOP`) for a while, then let it go on (`SIGCONT`): a
    /// node that stops answering without closing a socket (a stalled host, a long GC
    /// pause). Its peers' failure detectors declare it down past their deadline; when it
    /// wakes, its old sessions and epochs are fenced. Only `marie up` can do it.
    FreezeNode,
    /// Cut two groups of nodes apart for a while, both ways, then heal: every packet
    /// between them vanishes, as behind a cut cable, while each group goes on talking
    /// within itself. Only `marie up` can do it, on a cluster it started in a private
    /// network of namespaces.
    Partition,
}

/// What a fault aims at: a module instance (an operation, or a datamanager for the kinds
/// that [hit one](FaultKind::hits_datamanager)) or a node's process.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Aim {
    /// An operation instance (named as `NAME`, `ID`, `NAME#VERSION`, an actor id, or an
    /// instance on a node) — or a datamanager, named the same ways.
    Operation,
    /// A node, by name.
    Node,
    /// Two groups of nodes, by name: the two sides of a cut.
    Cut,
}

impl FaultKind {
    /// How many times its period a [`FaultKind::Slow`] instance waits between two steps.
    pub const SLOW_FACTOR: u32 = 5;

    /// Every kind, in a stable order.
    pub const ALL: [FaultKind; 7] = [
        FaultKind::Kill,
        FaultKind::Panic,
        FaultKind::Hang,
        FaultKind::Slow,
        FaultKind::StopNode,
        FaultKind::FreezeNode,
        FaultKind::Partition,
    ];

    /// The stable name: the serialized form and what `--fault` accepts.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Kill => "kill",
            FaultKind::Panic => "panic",
            FaultKind::Hang => "hang",
            FaultKind::Slow => "slow",
            FaultKind::StopNode => "stop-node",
            FaultKind::FreezeNode => "freeze-node",
            FaultKind::Partition => "partition",
        }
    }

    /// What it aims at.
    pub fn aim(self) -> Aim {
        match self {
            FaultKind::Kill | FaultKind::Panic | FaultKind::Hang | FaultKind::Slow => {
                Aim::Operation
            }
            FaultKind::StopNode | FaultKind::FreezeNode => Aim::Node,
            FaultKind::Partition => Aim::Cut,
        }
    }

    /// Whether it lasts a while and is then undone (a freeze is thawed, a cut healed): a
    /// plan gives its duration (`@T+D`); the page and `marie kill` use
    /// [`DEFAULT_LASTING`](Self::DEFAULT_LASTING).
    pub fn lasts(self) -> bool {
        matches!(self, FaultKind::FreezeNode | FaultKind::Partition)
    }

    /// How long a [lasting](Self::lasts) fault lasts when nobody said: 5 s, past the
    /// default failure detector's deadline, so the peers declare the node down.
    pub const DEFAULT_LASTING: std::time::Duration = std::time::Duration::from_secs(5);

    /// Whether a datamanager can suffer it: a kill, a panic or a hang hit a datamanager
    /// as they hit an operation (its supervisor restarts it); a slow step means nothing to
    /// a module without steps, and a node's kind aims at a node.
    pub fn hits_datamanager(self) -> bool {
        matches!(self, FaultKind::Kill | FaultKind::Panic | FaultKind::Hang)
    }

    /// The kinds that aim at `aim`, in [`ALL`](Self::ALL)'s order.
    pub fn aiming_at(aim: Aim) -> impl Iterator<Item = FaultKind> {
        FaultKind::ALL.into_iter().filter(move |k| k.aim() == aim)
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fault name that is none of [`FaultKind::ALL`] (e.g. in a `--fault` spec).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown fault `{0}` (expected {names})", names = names())]
pub struct UnknownFault(pub String);

/// `kill, panic, hang, slow, stop-node, freeze-node or partition`.
fn names() -> String {
    let names: Vec<&str> = FaultKind::ALL.iter().map(|k| k.name()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.join(""),
    }
}

impl FromStr for FaultKind {
    type Err = UnknownFault;

    /// Parse a name a user typed (a command-line flag); reports and events are read with
    /// serde instead.
    fn from_str(s: &str) -> Result<Self, UnknownFault> {
        FaultKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| UnknownFault(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_display_and_serialize_alike() {
        for kind in FaultKind::ALL {
            assert_eq!(kind.to_string().parse::<FaultKind>(), Ok(kind));
            let json = serde_json::to_string(&kind).unwrap();
            assert_eq!(json, format!("\"{kind}\""));
            assert_eq!(serde_json::from_str::<FaultKind>(&json).unwrap(), kind);
            let bytes = rmp_serde::to_vec_named(&kind).unwrap();
            assert_eq!(rmp_serde::from_slice::<FaultKind>(&bytes).unwrap(), kind);
        }
        assert_eq!(
            "boom".parse::<FaultKind>().unwrap_err().to_string(),
            "unknown fault `boom` (expected kill, panic, hang, slow, stop-node, freeze-node or \
             partition)"
        );
    }

    #[test]
    fn each_kind_aims_at_an_operation_a_node_or_a_cut() {
        let ops: Vec<FaultKind> = FaultKind::aiming_at(Aim::Operation).collect();
        assert_eq!(
            ops,
            [
                FaultKind::Kill,
                FaultKind::Panic,
                FaultKind::Hang,
                FaultKind::Slow
            ]
        );
        let nodes: Vec<FaultKind> = FaultKind::aiming_at(Aim::Node).collect();
        assert_eq!(nodes, [FaultKind::StopNode, FaultKind::FreezeNode]);
        let cuts: Vec<FaultKind> = FaultKind::aiming_at(Aim::Cut).collect();
        assert_eq!(cuts, [FaultKind::Partition]);
        let lasting: Vec<FaultKind> = FaultKind::ALL.into_iter().filter(|k| k.lasts()).collect();
        assert_eq!(lasting, [FaultKind::FreezeNode, FaultKind::Partition]);
    }
}

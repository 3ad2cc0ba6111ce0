//! What a fault hits, as a user writes it: a [`Target`], parsed once — from `--fault`,
//! `marie kill`, `marie props` or the monitor's page — and carried in the fault spec.

use marie_vocabulary::run::Aim;
use std::fmt;

/// The instance (or node) a fault hits, as written after `KIND:` in a fault spec.
///
/// | written | hits |
/// |---|---|
/// | `NAME` or `ID` (`wall-follower`, `1514`) | the instance the mission bound for that operation (after a rebind, its stand-in); when the mission binds none, the only instance running |
/// | `NAME#VERSION` or `ID#VERSION` (`wall-follower#2.0.0`) | the instance with exactly that version |
/// | an actor id (`0.42`: an operation's `address` in a run's report; a run is repeatable, so it is the same in the next run of that mission, world and seed) | that instance |
/// | `NAME/NODE` (`wall-follower/wf-b`) | the instance of that operation on that node (the only one there) |
/// | `NAME/NODE/ADDRESS` (`wall-follower/wf-b/3.41`) | the instance on that node whose actor has that address's pid — the same pid from every process, where the `N.` of an address differs (how the monitor's page names an instance) |
/// | a node's name, for a fault that aims at a node (`stop-node:wf-a`, `freeze-node:wf-a`) | that node's process |
/// | two groups of node names, for a cut (`partition:cart,features|operations`) | the network between the two groups |
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// The instance the mission bound (name or id).
    Bound(String),
    /// The instance of an operation (name or id) with a version.
    Version {
        /// Operation name or id.
        operation: String,
        /// Its exact version, e.g. `2.0.0`.
        version: String,
    },
    /// An instance by actor id, as this process numbers the nodes.
    Actor(String),
    /// The instance of an operation on a node.
    OnNode {
        /// Operation name or id.
        operation: String,
        /// The node's name.
        node: String,
        /// Its address as some process saw it (`N.PID`): compared by the pid.
        address: Option<String>,
    },
    /// A node, by name (for a fault that aims at a node).
    Node(String),
    /// Two groups of nodes, by name, for a cut between them (`A,B|C,D`): disjoint, neither
    /// empty.
    Cut {
        /// One side.
        a: Vec<String>,
        /// The other side.
        b: Vec<String>,
    },
}

impl Target {
    /// Parse a target of a fault that aims at `aim` (see [`Target`]).
    pub fn parse(s: &str, aim: Aim) -> Result<Target, TargetError> {
        let syntax = || TargetError::Syntax(s.to_string(), aim);
        match aim {
            Aim::Node => plain(s)
                .then(|| Target::Node(s.to_string()))
                .ok_or_else(syntax),
            Aim::Operation => Target::parse_operation(s).ok_or_else(syntax),
            Aim::Cut => Target::parse_cut(s).ok_or_else(syntax),
        }
    }

    /// The cut of `node` from every other of `nodes` (the page's *cut off*, the node
    /// chaos's partition).
    pub fn cut_off(node: &str, nodes: &[String]) -> Target {
        Target::Cut {
            a: vec![node.to_string()],
            b: nodes.iter().filter(|n| *n != node).cloned().collect(),
        }
    }

    /// `A,B|C,D`: two non-empty groups of node names, none in both, none twice.
    fn parse_cut(s: &str) -> Option<Target> {
        let (a, b) = s.split_once('|')?;
        let group = |g: &str| -> Option<Vec<String>> {
            let names: Vec<String> = g.split(',').map(|n| n.trim().to_string()).collect();
            names.iter().all(|n| node_name(n)).then_some(names)
        };
        let (a, b) = (group(a)?, group(b)?);
        let mut all: Vec<&String> = a.iter().chain(&b).collect();
        all.sort();
        let distinct = all.windows(2).all(|w| w[0] != w[1]);
        distinct.then_some(Target::Cut { a, b })
    }

    fn parse_operation(s: &str) -> Option<Target> {
        if let Some((operation, version)) = s.split_once('#') {
            let version_ok = !version.is_empty()
                && version
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '+'));
            return (plain(operation) && version_ok).then(|| Target::Version {
                operation: operation.to_string(),
                version: version.to_string(),
            });
        }
        if let Some((operation, rest)) = s.split_once('/') {
            let (node, address) = match rest.split_once('/') {
                Some((node, address)) => (node, Some(address)),
                None => (rest, None),
            };
            let address_ok = address.is_none_or(actor_id);
            return (plain(operation) && node_name(node) && address_ok).then(|| Target::OnNode {
                operation: operation.to_string(),
                node: node.to_string(),
                address: address.map(str::to_string),
            });
        }
        if s.contains('.') {
            return actor_id(s).then(|| Target::Actor(s.to_string()));
        }
        plain(s).then(|| Target::Bound(s.to_string()))
    }

    /// The operation (name or id) the target names, if it names one.
    pub fn operation(&self) -> Option<&str> {
        match self {
            Target::Bound(op)
            | Target::Version { operation: op, .. }
            | Target::OnNode { operation: op, .. } => Some(op),
            Target::Actor(_) | Target::Node(_) | Target::Cut { .. } => None,
        }
    }

    /// What the target aims at.
    pub fn aim(&self) -> Aim {
        match self {
            Target::Node(_) => Aim::Node,
            Target::Cut { .. } => Aim::Cut,
            _ => Aim::Operation,
        }
    }
}

/// A name or id: letters, digits, `-` and `_`.
fn plain(t: &str) -> bool {
    !t.is_empty()
        && t.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
}

/// A node's name: [`plain`], also with `.` and `@` (`n1@host`).
fn node_name(t: &str) -> bool {
    !t.is_empty()
        && t.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '@'))
}

/// An actor id: `N.PID`.
fn actor_id(t: &str) -> bool {
    let digits = |t: &str| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit());
    t.split_once('.')
        .is_some_and(|(node, pid)| digits(node) && digits(pid))
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Bound(op) | Target::Actor(op) | Target::Node(op) => f.write_str(op),
            Target::Version { operation, version } => write!(f, "{operation}#{version}"),
            Target::OnNode {
                operation,
                node,
                address: None,
            } => write!(f, "{operation}/{node}"),
            Target::OnNode {
                operation,
                node,
                address: Some(address),
            } => write!(f, "{operation}/{node}/{address}"),
            Target::Cut { a, b } => write!(f, "{}|{}", a.join(","), b.join(",")),
        }
    }
}

/// Why a fault's target names nothing to hit.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TargetError {
    /// Not a target of a fault that aims at that.
    #[error("{}", syntax(.0, *.1))]
    Syntax(String, Aim),
    /// No instance of that operation (or datamanager) runs.
    #[error("no operation `{0}` is running (running: {1})")]
    NotRunning(String, String),
    /// No instance of that operation has that version.
    #[error("no instance of `{operation}` has version {version} (running: {running})")]
    NoVersion {
        /// Operation name or id.
        operation: String,
        /// The version asked for.
        version: String,
        /// The versions that run.
        running: String,
    },
    /// No operation or datamanager instance has that actor id.
    #[error("no operation instance {0} is running (running: {1})")]
    NoActor(String, String),
    /// Several instances run and no mission binds one of them.
    #[error(
        "{count} instances of `{operation}` run and no mission binds one: name one as {choices}"
    )]
    Ambiguous {
        /// Operation name or id.
        operation: String,
        /// How many run.
        count: usize,
        /// How to name each.
        choices: String,
    },
    /// The instance the mission bound is gone and no stand-in is bound yet.
    #[error("the instance of `{0}` the mission bound is gone and no stand-in is bound yet")]
    Gone(String),
    /// The instance an address named is gone (it was replaced).
    #[error("{0} is no longer running")]
    NoLongerRunning(String),
    /// No instance of the operation runs on that node.
    #[error("no instance of `{operation}` runs on {node}{elsewhere}")]
    NotOnNode {
        /// Operation name or id.
        operation: String,
        /// The node asked for.
        node: String,
        /// Where it runs instead (` (it runs on a, b)`), or nothing.
        elsewhere: String,
    },
    /// This process cannot do that fault to that node: it did not start its process, or
    /// has stopped it already.
    #[error("no node process `{node}` to stop, freeze or cut off here ({why})")]
    NoProcess {
        /// The node asked for.
        node: String,
        /// What this process can stop, or why it can stop none.
        why: String,
    },
    /// The nodes do not run in a network that can be cut.
    #[error(
        "the nodes do not run in a network marie can cut: `marie up` starts its nodes in a \
         private network of namespaces when a partition is planned (--fault partition:…, \
         --chaos-nodes) or the page may inject faults, and that needs root and `ip`"
    )]
    NoNetwork,
}

impl TargetError {
    /// Whether the target names nothing that runs (as opposed to a target that cannot be
    /// written, or names several).
    pub fn is_not_found(&self) -> bool {
        matches!(
            self,
            TargetError::NotRunning(..)
                | TargetError::NoVersion { .. }
                | TargetError::NoActor(..)
                | TargetError::Gone(_)
                | TargetError::NoLongerRunning(_)
                | TargetError::NotOnNode { .. }
                | TargetError::NoProcess { .. }
                | TargetError::NoNetwork
        )
    }
}

fn syntax(s: &str, aim: Aim) -> String {
    match aim {
        Aim::Operation => format!(
            "`{s}` is not a fault target: expected NAME, ID, NAME#VERSION, NAME/NODE or an \
             actor id like 0.42"
        ),
        Aim::Node => format!("`{s}` is not a node's name"),
        Aim::Cut => {
            format!("`{s}` is not a cut: expected two groups of node names, A,B|C,D, none in both")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse_and_print_back() {
        let on = |op: &str, node: &str, address: Option<&str>| Target::OnNode {
            operation: op.into(),
            node: node.into(),
            address: address.map(str::to_string),
        };
        for (text, want) in [
            ("wall-follower", Target::Bound("wall-follower".into())),
            ("1514", Target::Bound("1514".into())),
            (
                "wall-follower#2.0.0",
                Target::Version {
                    operation: "wall-follower".into(),
                    version: "2.0.0".into(),
                },
            ),
            ("0.42", Target::Actor("0.42".into())),
            ("wall-follower/wf-b", on("wall-follower", "wf-b", None)),
            (
                "wall-follower/wf-b/3.41",
                on("wall-follower", "wf-b", Some("3.41")),
            ),
        ] {
            let t = Target::parse(text, Aim::Operation).unwrap();
            assert_eq!(t, want);
            assert_eq!(t.to_string(), text);
            assert_eq!(t.aim(), Aim::Operation);
        }
        let node = Target::parse("wf-a", Aim::Node).unwrap();
        assert_eq!(node, Target::Node("wf-a".into()));
        assert_eq!((node.to_string().as_str(), node.aim()), ("wf-a", Aim::Node));
        for bad in [
            "", "#1.0.0", "x#", "0.", ".4", "1.2.3", "a b", "x@1", "x:y", "x/", "/n", "x/n/4",
            "x/n/a.b",
        ] {
            assert!(
                matches!(
                    Target::parse(bad, Aim::Operation),
                    Err(TargetError::Syntax(..))
                ),
                "{bad:?}"
            );
        }
        for bad in ["", "a b", "wf-a/x", "x#1"] {
            assert!(
                matches!(Target::parse(bad, Aim::Node), Err(TargetError::Syntax(..))),
                "{bad:?}"
            );
        }
        let cut = Target::parse("cart,features|operations", Aim::Cut).unwrap();
        assert_eq!(
            cut,
            Target::Cut {
                a: vec!["cart".into(), "features".into()],
                b: vec!["operations".into()]
            }
        );
        assert_eq!(
            (cut.to_string().as_str(), cut.aim()),
            ("cart,features|operations", Aim::Cut)
        );
        for bad in [
            "", "a", "a|", "|b", "a,|b", "a|a", "a,b|c,a", "a,a|b", "a|b|c", "a b|c",
        ] {
            assert!(
                matches!(Target::parse(bad, Aim::Cut), Err(TargetError::Syntax(..))),
                "{bad:?}"
            );
        }
    }
}

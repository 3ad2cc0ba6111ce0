//! Mission files: task trees in TOML, checked before anything runs.
//!
//! A mission (thesis 3.2.4.1) is a set of *actions*. Each action names the operations to run
//! together, the parameters to send each one, the operations whose finishing ends the action,
//! and the *condition* under which it may run: a set of flags of the 32-bit status word that
//! must all be set. The dispatcher combines the flags the operations report into that word and
//! runs the next action whose condition is implied by it; once the `success` flags are all
//! set the mission has succeeded. Control keys and groups (issue 24, "missions that
//! recover") add retries, timeouts, recoveries, reactive conditions, fallbacks and parallels:
//! a behaviour tree over the actions ([`Mission::control`]; see
//! [Control](#control-behaviour-tree-semantics)).
//!
//! Checking happens in two stages, and each reports *every* problem it finds, sorted by
//! position, as `file:line:column: message` ([`Diagnostics`]):
//!
//! 1. [`ParsedMission::parse`] — syntax and structure, no knowledge of operations needed: TOML
//!    syntax; required keys; unknown keys anywhere (with the accepted ones); value types; flag
//!    bits in `0..=31` and each used once; flag names in `initial`, `success`, `when`,
//!    `while` and `unless` declared in `[flags]` (and no flag both in `while` and `unless`);
//!    action and group names unique among both; every action has operations; `ends_on` names
//!    operations of its action; deadlines and timeouts positive and finite, backoffs zero or
//!    more; parameter values of a TOML type that no parameter type holds (datetimes); a retry
//!    of at least one attempt; a group of a known kind with children; `children` and
//!    `on_failure` naming actions or groups (with the closest name, or the names there are);
//!    each item the child of one group at most; no group containing itself, no recovery
//!    leading back to what it recovers; a reactive group with `while` or `unless`; parallel
//!    thresholds from 1 to the number of children, and only on a parallel; a tree at most 32
//!    levels deep and of at most 10 000 nodes.
//! 2. [`ParsedMission::validate`] — against the operations a [`Catalog`] offers: every
//!    operation exists; every supplied parameter is declared, writable, of the right type and
//!    in range ([`ParamDecl::check`](marie_vocabulary::property::ParamDecl::check)); every flag a
//!    condition (`when`, `while`) or `success` needs is set in `initial` or declared by some
//!    operation of the mission ([`FlagDecl`](marie_vocabulary::status::FlagDecl)) — a typo or an
//!    impossible condition is caught here; no two children of a parallel run one operation;
//!    in a mission with control keys, no top-level item waits for a flag that only its own
//!    operations (a group's: those run inside it) raise.
//!
//! [`Mission::load`] does both for a file. Nothing here panics on any input.
//!
//! # Format
//!
//! ```toml
//! [mission]
//! name = "demo"              # required
//! description = "..."        # optional
//! success = ["counted"]      # flags that must all be set at the end
//! initial = []               # flags set before the first action (optional)
//! deadline_s = 60.0          # optional: deadline of the whole mission, in seconds
//! rebind_deadline_s = 10.0   # optional: how long a lost operation may stay unbound (default 10)
//! world = "worlds/lab.toml"  # optional: the world to run in, relative to this file
//!
//! [flags]                    # flag name -> bit of the status word (0..=31, each bit once)
//! counted = 0
//! summed = 1
//!
//! [[action]]
//! name = "count"             # required, unique
//! when = []                  # runs when all these flags are set (default: none needed)
//! ends_on = ["counter"]      # operations whose finishing ends the action
//!                            #   (default: every operation of the action)
//! end_mode = "any"           # "any" (default): the first ender to finish ends the action;
//!                            # "all": every ender must finish
//! deadline_s = 10.0          # optional, default 30
//!
//! [action.ops.counter]       # an operation, by name or by id as a quoted key ("1512"),
//! limit = 10                 #   and the parameters the mission sets
//! [action.ops.ticker]        # an operation with all parameters at their defaults
//!
//! [requires]                 # optional: the versions the mission accepts (semver)
//! counter = "^1"
//!
//! [pin]                      # optional: the version an operation runs on for the whole
//! ticker = "1.0.0"           #   mission ("1.0.0": exactly; or a requirement, "~1.0"): its
//!                            #   binding never moves to a newer version that appears
//! ```
//!
//! With control keys and groups (all optional; a file without them means what it always
//! did):
//!
//! ```toml
//! [[action]]
//! name = "follow-wall"
//! when = ["wall-found"]      # at the top level, what it waits for; inside a group (or as a
//!                            #   recovery), a guard: it fails at once unless all are set
//! retry = { attempts = 3, backoff_s = 2.0 }
//!                            # attempts in all, the first included (at least 1), and the
//!                            #   wait between a failure and the next attempt (default 0)
//! timeout_s = 40.0           # halted, and failed, once it has run this long (> 0)
//! on_failure = "back-off"    # an action or group run after each failure, before a retry
//! while = ["wall-found"]     # flags that must all stay set while it runs
//! unless = ["obstacle"]      # flags none of which may become set while it runs
//! [action.ops.wall-follower]
//!
//! [[action]]
//! name = "back-off"          # a recovery: it runs after a failure, not scheduled itself
//! [action.ops.reverse]
//!
//! [[group]]                  # a construct over actions and groups
//! name = "look"              # required, unique among actions and groups
//! kind = "parallel"          # required: "sequence", "fallback", "parallel" or "reactive"
//! children = ["sonar", "camera"]
//!                            # required: actions and groups, in order, each the child of
//!                            #   one group at most (a child is not scheduled itself)
//! success = 1                # "parallel" only: how many must succeed (default: all)
//! failure = 2                # "parallel" only: how many failing make it fail (default 1)
//! # when, retry, timeout_s, on_failure, while, unless: as for an action. A "reactive" group
//! # is a sequence whose own `while`/`unless` (one at least) hold while any child runs.
//! ```
//!
//! The tree ([`Mission::control`]): at its root the thesis' schedule of every item (action
//! or group) that is neither a child of a group nor any item's `on_failure`, in file order,
//! each waiting for its `when`. An item is, from the inside out: the action, or the group's
//! construct over its children's trees; a reactive sequence of it alone for its
//! `while`/`unless` (not for a reactive group, whose own they are); its timeout; its
//! recovery; its retry; and, below the top level, the guard of its `when`. So a retry's
//! every attempt has its own timeout, and its recovery runs between a failure and the next
//! attempt. A recovery named by several items is in the tree once for each.
//!
//! Where several instances of an operation run, the dispatcher chooses one by their
//! properties ([`selection`](super::selection)): the schema that takes what the mission
//! supplies most exactly, a version `[requires]` accepts, one not in use, on its own node,
//! up longest; the run report's `selection` says why each other candidate lost or was
//! rejected. A stand-in after a failure must be one the mission could have chosen.
//!
//! `world` names the world file a simulated robot runs the mission in; a relative path is
//! resolved against the directory of the mission file ([`Mission::world`]). To this crate it
//! is only a path: nothing here reads it, and a mission without one runs without a world. The
//! `marie` command loads it (its `--world` flag overrides it).
//!
//! Parameters the mission omits are not filled in here: the dispatcher leaves them at the
//! operation's declared defaults. Supplied values are canonicalized (an integer given for a
//! float parameter becomes a float). Flags an operation declares but `[flags]` does not name
//! are allowed; the dispatcher ignores them.
//!
//! # Control: behaviour-tree semantics
//!
//! The tree is ticked whenever something changes — an action ended, the status word
//! changed, a timeout or a backoff is due — and each node answers *running*, *succeeded* or
//! *failed* ([`tree`](super::tree), the pure machine that runs it). A node that succeeded or
//! failed stays so (until a retry above it starts a new attempt).
//!
//! | construct | written as | status | BehaviorTree.CPP v4 |
//! |---|---|---|---|
//! | action | `[[action]]` | running once started, until it ends: succeeded when its `ends_on` operations finished; failed when one failed or its `deadline_s` passed | an action node |
//! | sequence | `kind = "sequence"` | its children one after another; failed at the first that fails (the rest never start); succeeded when all did | `Sequence` |
//! | fallback | `kind = "fallback"` | its children one after another until one succeeds (then succeeded); failed when all failed | `Fallback` |
//! | parallel | `kind = "parallel"` | every child at once; succeeded once `success` of them succeeded, failed once `failure` failed; the children still running are halted then | `Parallel` (`success_count`, `failure_count`) |
//! | reactive | `kind = "reactive"`; `while`/`unless` on any item | a sequence whose conditions are re-checked at every tick while a child runs: once a `while` flag is cleared or an `unless` flag set, the running child is halted and it fails; a condition that does not hold at the start fails it at once | `ReactiveSequence` with a condition first |
//! | timeout | `timeout_s` | as its child, until it has run `timeout_s`: then the child is halted and it fails | `Timeout` |
//! | recovery | `on_failure` | as its child when it succeeds; when it fails, the recovery runs, and then it fails, whatever the recovery did | Nav2's `RecoveryNode`, split in two (below) |
//! | retry | `retry` | its child again after a failure, `attempts` in all; succeeded at the first success, failed when the last attempt failed | `RetryUntilSuccessful` |
//! | guard | `when` below the top level | failed at once when the flags are not all set; else as the item | a `Sequence` of a condition and the item |
//! | schedule | the top level | the thesis' dispatching: again and again, the first item not yet done whose `when` the status word implies runs, one at a time; failed at the first failure, or when nothing can run | — |
//!
//! **Halting.** Halting a node halts every action running under it: the action's
//! operations are suspended, and the dispatcher waits for their reports — bounded by its
//! suspension grace, 5 s — before it starts any other action. The halts a tick decides come
//! before its starts, so no two actions of a sequence ever run at once, not even while one
//! is being halted.
//!
//! **Retries.** `attempts` counts every attempt, the first included: `attempts = 3` runs the
//! item at most three times, and `attempts = 1` is the item alone. After a failure its
//! recovery (`on_failure`) runs — after every failed attempt, the last one too — then
//! `backoff_s` passes, then the next attempt starts afresh (every node below at rest again,
//! its timeout restarted). A recovery that fails does not stop the retry.
//!
//! **Where marie differs, and why.**
//! - *Conditions are flags of the status word*, re-checked at every tick — not condition
//!   nodes running code. The operations report them anyway, so checking costs nothing and
//!   has no side effect, and a file can be checked before it runs (every flag declared,
//!   raised by some operation or set initially).
//! - *The thesis' schedule is at the root*, where BehaviorTree.CPP has one tree ticked from
//!   the top: a mission without control keys is exactly the thesis' ([`Control::thesis`])
//!   and runs as it always did, and `when` keeps its meaning at the top level.
//! - *A halt completes before anything else starts.* BehaviorTree.CPP halts a node by a
//!   synchronous call in the process; marie's actions are operations on other nodes, whose
//!   suspension takes messages, so the dispatcher waits for them (within the grace) rather
//!   than let two actions drive the robot at once.
//! - *A recovery is not a retry.* Nav2's `RecoveryNode` retries its first child after its
//!   second succeeds and fails when the recovery fails; marie's `on_failure` runs the
//!   recovery and fails, and `retry` (the same key as everywhere) does the trying again —
//!   a recovery without a retry runs once, and a failed recovery still leads to the next
//!   attempt.
//! - *A retry waits* `backoff_s` between attempts, where `RetryUntilSuccessful` retries at
//!   once: a robot's retry usually needs the world to change.
//! - *The children of a parallel may not share an operation* (checked): an operation serves
//!   one action at a time.
//!
//! ```
//! use marie_actors::dispatcher::mission::{OpInfo, ParsedMission, StaticCatalog};
//! use marie_actors::dispatcher::tree::Node;
//! use marie_vocabulary::status::FlagDecl;
//! use std::time::Duration;
//!
//! let src = r#"
//! [mission]
//! name = "find"
//! success = ["wall-found"]
//! [flags]
//! wall-found = 0
//!
//! [[action]]
//! name = "find-wall"
//! retry = { attempts = 3, backoff_s = 2.0 }
//! on_failure = "back-off"
//! [action.ops.wall-sensor]
//!
//! [[action]]
//! name = "back-off"
//! [action.ops.reverse]
//! "#;
//! let catalog = StaticCatalog::new([
//!     OpInfo::new("wall-sensor", 1512, "1.0.0")
//!         .flags(vec![FlagDecl::new("wall-found", "a wall is in range")]),
//!     OpInfo::new("reverse", 1601, "1.0.0"),
//! ]);
//! let mission = ParsedMission::parse(src, None)?.validate(&catalog)?;
//! let Node::Schedule(top) = &mission.control.root else { panic!("a schedule") };
//! assert_eq!(top.len(), 1); // back-off runs only as find-wall's recovery
//! assert_eq!(
//!     top[0].node,
//!     Node::Retry {
//!         child: Box::new(Node::Recover {
//!             child: Box::new(Node::Action(0)),
//!             recovery: Box::new(Node::Action(1)),
//!         }),
//!         attempts: 3,
//!         backoff: Duration::from_secs(2),
//!     }
//! );
//! assert_eq!(mission.control.label(1), "retry(find-wall)");
//!
//! // a recovery that leads back to what it recovers is refused where it is named
//! let bad = src.replace("on_failure = \"back-off\"", "on_failure = \"find-wall\"");
//! let err = ParsedMission::parse(&bad, None).unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "<mission>:11:14: action `find-wall` names itself in `on_failure` (a recovery cannot be what it recovers)"
//! );
//! # Ok::<(), marie_actors::dispatcher::mission::Diagnostics>(())
//! ```
//!
//! # Example
//!
//! ```
//! use marie_actors::dispatcher::mission::{EndMode, OpInfo, ParsedMission, StaticCatalog};
//! use marie_vocabulary::status::{FlagDecl, StatusFlags};
//! use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
//! use std::time::Duration;
//!
//! let src = r#"
//! [mission]
//! name = "demo"
//! success = ["summed"]
//!
//! [flags]
//! counted = 0
//! summed = 1
//!
//! [[action]]
//! name = "count"
//! ends_on = ["counter"]
//! deadline_s = 10
//! [action.ops.counter]
//! limit = 10
//! [action.ops.ticker]
//!
//! [[action]]
//! name = "sum"
//! when = ["counted"]
//! [action.ops."7"]
//! scale = 2
//! "#;
//!
//! let catalog = StaticCatalog::new([
//!     OpInfo::new("counter", 5, "1.0.0")
//!         .params(ParamSchema::new(vec![ParamDecl::int("limit", 3).range(1.0, 100.0)]))
//!         .flags(vec![FlagDecl::new("counted", "reached the limit")]),
//!     OpInfo::new("ticker", 6, "1.0.0"),
//!     OpInfo::new("adder", 7, "2.1.0")
//!         .params(ParamSchema::new(vec![ParamDecl::float("scale", 1.0)]))
//!         .flags(vec![FlagDecl::new("summed", "sum stored")]),
//! ]);
//!
//! let mission = ParsedMission::parse(src, None)?.validate(&catalog)?;
//! assert_eq!(mission.flags["summed"], 1);
//! assert_eq!(mission.success, StatusFlags(0b10));
//! let count = &mission.actions[0];
//! assert_eq!(count.ends_on, ["counter"]);
//! assert_eq!(count.deadline, Duration::from_secs(10));
//! assert_eq!(count.ops[0].params["limit"], Value::Int(10));
//! assert!(count.ops[1].params.is_empty()); // ticker: defaults, filled in by the dispatcher
//! let sum = &mission.actions[1];
//! assert_eq!((sum.when, sum.end_mode), (StatusFlags(0b01), EndMode::Any));
//! assert_eq!(sum.ends_on, ["7"]); // default: every operation
//! assert_eq!(sum.ops[0].name, "adder");
//! assert_eq!(sum.ops[0].params["scale"], Value::Float(2.0)); // canonicalized
//! assert_eq!(mission.ops().collect::<Vec<_>>(), ["counter", "ticker", "7"]);
//!
//! // A typo is reported with its position and what was expected.
//! let bad = src.replace("limit = 10", "limt = 10");
//! let err = ParsedMission::parse(&bad, None)?.validate(&catalog).unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "<mission>:15:1: unknown parameter `limt` of operation `counter` (expected one of: limit)"
//! );
//! # Ok::<(), marie_actors::dispatcher::mission::Diagnostics>(())
//! ```

mod builder;
mod control;
pub(crate) mod op_info;
pub(crate) mod operations;
mod parse;
mod parsed;
mod structure;
mod validate;

pub use builder::{ActionBuilder, GroupBuilder, MissionBuilder, BUILT};
pub use control::{Control, Recovery};
pub use marie_vocabulary::diagnostic::{Diagnostic, Diagnostics, LineIndex, Pos};
pub use op_info::OpInfo;
pub use operations::{Catalog, StaticCatalog};
pub use parsed::GroupKind;

use super::checked::CheckedChoices;
use marie_vocabulary::property::ParamMap;
use marie_vocabulary::status::StatusFlags;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How the operations an action ends on end it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EndMode {
    /// The first of them to finish ends the action (`end_mode = "any"`, the default).
    #[default]
    Any,
    /// All of them must finish (`end_mode = "all"`).
    All,
}

impl fmt::Display for EndMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EndMode::Any => "any",
            EndMode::All => "all",
        })
    }
}

/// One operation of an action, resolved against the catalog.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpRun {
    /// The key as written in the file (`[action.ops.<key>]`): a name or a numeric id.
    pub key: String,
    /// The operation's canonical name.
    pub name: String,
    /// The operation's numeric id.
    pub id: u32,
    /// The parameters the mission supplies, canonicalized by
    /// [`ParamDecl::check`](marie_vocabulary::property::ParamDecl::check). Omitted parameters are not
    /// here: the dispatcher leaves them at the declared defaults.
    pub params: ParamMap,
}

/// One validated action of a mission.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Action {
    /// Unique name.
    pub name: String,
    /// Condition: the action may run when the status word implies these flags.
    pub when: StatusFlags,
    /// The operations it runs, in file order.
    pub ops: Vec<OpRun>,
    /// Keys (into `ops`) of the operations whose finishing ends the action; never empty.
    pub ends_on: Vec<String>,
    /// Whether any or all of `ends_on` must finish.
    pub end_mode: EndMode,
    /// How long the action may take (`deadline_s`, default 30 s).
    pub deadline: Duration,
}

impl Action {
    /// The operation written as `key`.
    pub fn op(&self, key: &str) -> Option<&OpRun> {
        self.ops.iter().find(|o| o.key == key)
    }

    /// True when the operation written as `key` ends the action.
    pub fn ends_on(&self, key: &str) -> bool {
        self.ends_on.iter().any(|k| k == key)
    }
}

/// A mission that passed both stages: ready for the dispatcher.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mission {
    /// The mission's name.
    pub name: String,
    /// What it is for (may be empty).
    pub description: String,
    /// The file it was loaded from, if any.
    pub path: Option<PathBuf>,
    /// Flag names and their bits in the status word.
    pub flags: BTreeMap<String, u8>,
    /// Flags set before the first action.
    pub initial: StatusFlags,
    /// Flags that must all be set for the mission to succeed.
    pub success: StatusFlags,
    /// Deadline of the whole mission.
    pub deadline: Option<Duration>,
    /// How long an operation whose instance died may stay without a live compatible
    /// instance before the mission comes to a full stop (`rebind_deadline_s`, default
    /// [`DEFAULT_REBIND_DEADLINE`]).
    #[serde(default = "default_rebind_deadline")]
    pub rebind_deadline: Duration,
    /// The actions, in file order.
    pub actions: Vec<Action>,
    /// How the actions are controlled: the thesis' schedule ([`Control::thesis`]) unless
    /// the file says otherwise.
    pub control: Control,
    /// The world file the mission names (`world = "..."` in `[mission]`), resolved against the
    /// mission file's directory; `None` when it names none. Just a path: this crate never
    /// reads it.
    #[serde(default)]
    pub world: Option<PathBuf>,
    /// The versions the mission accepts, by operation name (`[requires]`): only an
    /// instance of a matching version is chosen, or stands in after a failure.
    #[serde(default)]
    pub requires: BTreeMap<String, semver::VersionReq>,
    /// The versions operations run on for the whole mission, by operation name (`[pin]`):
    /// a pinned binding never moves to a newer version, and a stand-in must match too.
    pub pins: BTreeMap<String, semver::VersionReq>,
    /// The choices the check against the running instances made, handed to the dispatcher
    /// so that the run selects once ([`Mission::checked`]). Never serialized.
    #[serde(skip)]
    pub(crate) checked: CheckedChoices,
}

/// How long a lost operation may stay unbound when the mission does not say.
pub const DEFAULT_REBIND_DEADLINE: Duration = Duration::from_secs(10);

fn default_rebind_deadline() -> Duration {
    DEFAULT_REBIND_DEADLINE
}

impl Mission {
    /// Both stages on a file: read, parse ([`ParsedMission::parse_file`]), and validate
    /// against `catalog`.
    pub fn load<C: Catalog + ?Sized>(path: &Path, catalog: &C) -> Result<Mission, Diagnostics> {
        ParsedMission::parse_file(path)?.validate(catalog)
    }

    /// The name of the flag on bit `bit`.
    pub fn flag_name(&self, bit: u8) -> Option<&str> {
        self.flags
            .iter()
            .find(|(_, b)| **b == bit)
            .map(|(n, _)| n.as_str())
    }

    /// The names of the flags set in `flags`, lowest bit first; a bit without a name shows as
    /// `#<bit>`.
    pub fn flags_to_names(&self, flags: StatusFlags) -> Vec<String> {
        flags
            .bits()
            .map(|b| {
                self.flag_name(b)
                    .map_or_else(|| format!("#{b}"), str::to_string)
            })
            .collect()
    }

    /// The task tree as a run announces it ([`EventKind::RunStarted`](marie_vocabulary::events::EventKind::RunStarted)):
    /// each action's name, condition flags by name, operations and the keys it ends on.
    pub fn plan(&self) -> Vec<marie_vocabulary::events::ActionPlan> {
        self.actions
            .iter()
            .map(|a| marie_vocabulary::events::ActionPlan {
                name: a.name.clone(),
                when: self.flags_to_names(a.when),
                ops: a.ops.iter().map(|o| o.name.clone()).collect(),
                ends_on: a.ends_on.clone(),
            })
            .collect()
    }

    /// The operation keys the mission uses, each once, in order of first use.
    pub fn ops(&self) -> impl Iterator<Item = &str> + '_ {
        let mut seen = BTreeSet::new();
        self.actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .map(|o| o.key.as_str())
            .filter(move |k| seen.insert(*k))
    }

    /// The canonical names of the operations the mission uses, each once, in order of first
    /// use (`ops` may name one operation by name in one action and by id in another).
    pub fn operation_names(&self) -> Vec<&str> {
        let mut seen = BTreeSet::new();
        self.actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .map(|o| o.name.as_str())
            .filter(|n| seen.insert(*n))
            .collect()
    }

    /// Each operation the mission uses, once, in order of first use: the key its
    /// instances are looked up under (its name if an action names it so, else the id the
    /// first action uses) and what the mission needs of it ([`Mission::need`]).
    pub(crate) fn operation_needs(&self) -> Vec<(&str, super::selection::Need)> {
        self.operation_names()
            .into_iter()
            .map(|name| {
                let keys = || {
                    self.actions
                        .iter()
                        .flat_map(|a| &a.ops)
                        .filter(move |o| o.name == name)
                        .map(|o| o.key.as_str())
                };
                let key = keys()
                    .find(|k| *k == name)
                    .or_else(|| keys().next())
                    .unwrap_or(name);
                (key, self.need(name))
            })
            .collect()
    }

    /// The choices its check against the running instances made, one per operation:
    /// the dispatcher binds them as they are unless an instance changed since (see
    /// [`crate::dispatcher::CheckedChoices`]). Empty for a mission validated against a
    /// [`StaticCatalog`] or read back from JSON — its run selects every operation.
    pub fn checked(&self) -> &CheckedChoices {
        &self.checked
    }

    /// The mission without its check's choices: its run selects every operation among
    /// the instances that run then, as if it had not been checked.
    pub fn unchecked(mut self) -> Mission {
        self.checked = CheckedChoices::default();
        self
    }

    /// What the mission needs of operation `name`: the parameters each action supplies to
    /// it and the versions it accepts (what [`selection`](super::selection) chooses an
    /// instance by).
    pub fn need(&self, name: &str) -> super::selection::Need {
        let mut need = super::selection::Need::new(name);
        need.version = self.requires.get(name).cloned();
        need.pin = self.pins.get(name).cloned();
        need.supplied = self
            .actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .filter(|o| o.name == name)
            .map(|o| o.params.clone())
            .collect();
        need
    }
}

/// A mission that passed stage 1 (syntax and structure) but has not been checked against the
/// available operations yet. Call [`ParsedMission::validate`].
#[derive(Clone, Debug)]
pub struct ParsedMission {
    pub(crate) file: String,
    pub(crate) path: Option<PathBuf>,
    pub(crate) name: String,
    pub(crate) description: String,
    pub(crate) flags: BTreeMap<String, u8>,
    pub(crate) initial: Vec<parsed::FlagRef>,
    pub(crate) success: Vec<parsed::FlagRef>,
    pub(crate) deadline: Option<Duration>,
    pub(crate) rebind_deadline: Option<Duration>,
    pub(crate) world: Option<PathBuf>,
    /// Where the file names the world.
    pub(crate) world_at: Option<Pos>,
    pub(crate) actions: Vec<parsed::ParsedAction>,
    /// The `[[group]]`s, in file order.
    pub(crate) groups: Vec<parsed::ParsedGroup>,
    /// Every action and group, in file order.
    pub(crate) items: Vec<parsed::Item>,
    /// `[requires]`: version requirements by operation key, where written.
    pub(crate) requires: Vec<(String, semver::VersionReq, Pos)>,
    /// `[pin]`: the versions operations run on for the whole mission, by key, where written.
    pub(crate) pins: Vec<(String, semver::VersionReq, Pos)>,
}

impl ParsedMission {
    /// Stage 1: parse mission text and check its syntax and structure. `path` is used in
    /// diagnostics (`<mission>` without one) and kept in the mission.
    pub fn parse(src: &str, path: Option<&Path>) -> Result<ParsedMission, Diagnostics> {
        parse::parse(src, path)
    }

    /// Stage 1 on a file. An unreadable file is one diagnostic at 1:1 naming the file and the
    /// OS error; text that is not UTF-8 is reported at the first invalid byte.
    pub fn parse_file(path: &Path) -> Result<ParsedMission, Diagnostics> {
        let src = marie_vocabulary::diagnostic::read_source(path, "mission")?;
        ParsedMission::parse(&src, Some(path))
    }

    /// Stage 2: check the mission against the operations `catalog` offers and build the
    /// [`Mission`]. Reports every problem, sorted by position.
    pub fn validate<C: Catalog + ?Sized>(&self, catalog: &C) -> Result<Mission, Diagnostics> {
        validate::validate(self, catalog)
    }

    /// The mission's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The file it was parsed from, if any.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// Flag names and their bits.
    pub fn flags(&self) -> &BTreeMap<String, u8> {
        &self.flags
    }

    /// The world file the mission names, resolved against the mission file's directory (see
    /// [`Mission::world`]).
    pub fn world(&self) -> Option<&Path> {
        self.world.as_deref()
    }

    /// A diagnostic at the line that names the world, saying `message` — the first line of
    /// an error about the world file, so that it points at what named it. `None` when the
    /// mission names no world.
    pub fn world_diagnostic(&self, message: impl Into<String>) -> Option<Diagnostic> {
        let at = self.world_at?;
        Some(Diagnostic::at(&self.file, at, message))
    }

    /// What the mission needs of the operation written as `key`: the parameters each
    /// action supplies (as written, not yet checked) and the versions it accepts — what a
    /// catalog chooses the instance to validate against by.
    pub fn need(&self, key: &str) -> super::selection::Need {
        let mut need = super::selection::Need::new(key);
        need.version = self
            .requires
            .iter()
            .find(|(k, _, _)| k == key)
            .map(|(_, r, _)| r.clone());
        need.pin = self
            .pins
            .iter()
            .find(|(k, _, _)| k == key)
            .map(|(_, r, _)| r.clone());
        need.supplied = self
            .actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .filter(|o| o.key == key)
            .map(|o| {
                o.params
                    .iter()
                    .map(|p| (p.name.clone(), p.value.clone()))
                    .collect()
            })
            .collect();
        need
    }

    /// A diagnostic saying `message` at the first place the mission runs the operation
    /// written as `key` (or at its `[requires]` entry, when it has one).
    pub fn op_diagnostic(&self, key: &str, message: impl Into<String>) -> Diagnostic {
        let at = self
            .requires
            .iter()
            .find(|(k, _, _)| k == key)
            .map(|(_, _, at)| *at)
            .or_else(|| {
                self.actions
                    .iter()
                    .flat_map(|a| a.ops.iter())
                    .find(|o| o.key == key)
                    .map(|o| o.at)
            })
            .unwrap_or_default();
        Diagnostic::at(&self.file, at, message)
    }

    /// The operation keys (names or ids, as written) the mission uses, each once, in order of
    /// first use — what a catalog must be able to answer for.
    pub fn ops(&self) -> impl Iterator<Item = &str> + '_ {
        let mut seen = BTreeSet::new();
        self.actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .map(|o| o.key.as_str())
            .filter(move |k| seen.insert(*k))
    }
}

#[cfg(test)]
mod control_tests;

/// How a mission's source is named in diagnostics.
pub(crate) fn display_path(path: Option<&Path>) -> String {
    path.map_or_else(|| "<mission>".to_string(), |p| p.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
    use marie_vocabulary::status::FlagDecl;

    fn catalog() -> StaticCatalog {
        StaticCatalog::new([
            OpInfo::new("counter", 1512, "1.0.0")
                .params(ParamSchema::new(vec![ParamDecl::float("gain", 1.0)]))
                .flags(vec![FlagDecl::new("counted", "done")]),
            OpInfo::new("counter", 1512, "2.0.0"),
        ])
    }

    #[test]
    fn static_catalog_finds_by_name_or_id_first_match_wins() {
        let c = catalog();
        assert_eq!(
            c.operation("counter").map(|o| o.version),
            Some("1.0.0".into())
        );
        assert_eq!(c.operation("1512").map(|o| o.name), Some("counter".into()));
        assert_eq!(c.operation("01512"), None);
        assert_eq!(c.names(), ["counter"]);
    }

    #[test]
    fn one_operation_by_name_and_by_id_in_one_action_is_rejected() {
        let src = "[mission]\nname = \"m\"\n[[action]]\nname = \"a\"\n\
                   [action.ops.counter]\n[action.ops.\"1512\"]\n";
        let err = ParsedMission::parse(src, None)
            .and_then(|p| p.validate(&catalog()))
            .unwrap_err();
        assert_eq!(err.len(), 1);
        assert_eq!((err.0[0].line, err.0[0].column), (6, 13));
    }

    #[test]
    fn mission_helpers() {
        let src = "[mission]\nname = \"m\"\nsuccess = [\"counted\"]\n[flags]\ncounted = 3\n\
                   [[action]]\nname = \"a\"\n[action.ops.\"1512\"]\n\
                   [[action]]\nname = \"b\"\n[action.ops.\"1512\"]\ngain = 2\n\
                   [[action]]\nname = \"c\"\n[action.ops.counter]\n";
        let m = ParsedMission::parse(src, None)
            .and_then(|p| p.validate(&catalog()))
            .unwrap_or_else(|d| panic!("{d}"));
        assert_eq!(m.ops().collect::<Vec<_>>(), ["1512", "counter"]);
        assert_eq!(m.operation_names(), ["counter"]);
        assert_eq!(m.actions[1].ops[0].params["gain"], Value::Float(2.0));
        assert_eq!(m.flag_name(3), Some("counted"));
        assert_eq!(m.flags_to_names(StatusFlags(0b1001)), ["#0", "counted"]);
    }

    #[test]
    fn a_pin_is_an_exact_version_or_a_requirement_and_must_name_an_operation_that_runs() {
        let mission = |pin: &str| {
            let src = format!(
                "[mission]\nname = \"m\"\n[[action]]\nname = \"a\"\n\
                 [action.ops.counter]\n[pin]\n{pin}\n"
            );
            ParsedMission::parse(&src, None).and_then(|p| p.validate(&catalog()))
        };
        let m = mission("counter = \"1.0.0\"").unwrap_or_else(|d| panic!("{d}"));
        assert_eq!(m.pins["counter"].to_string(), "=1.0.0");
        let need = m.need("counter");
        assert_eq!(need.pin.map(|p| p.to_string()).as_deref(), Some("=1.0.0"));
        let m = mission("counter = \"~1.0\"").unwrap_or_else(|d| panic!("{d}"));
        assert_eq!(m.pins["counter"].to_string(), "~1.0");
        let err = mission("counter = \"one\"").unwrap_err().to_string();
        assert!(
            err.contains("neither a version nor a version requirement"),
            "{err}"
        );
        let err = mission("ticker = \"1.0.0\"").unwrap_err().to_string();
        assert!(
            err.contains("`[pin]` names operation `ticker`, which no action runs"),
            "{err}"
        );
    }

    #[test]
    fn end_mode_reads_and_writes_as_in_the_file() {
        assert_eq!(EndMode::default(), EndMode::Any);
        assert_eq!(EndMode::All.to_string(), "all");
        assert_eq!(
            serde_json::to_string(&EndMode::All).ok().as_deref(),
            Some("\"all\"")
        );
    }
}

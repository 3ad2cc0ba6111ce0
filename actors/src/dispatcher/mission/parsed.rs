//! The parts of a [`ParsedMission`](super::ParsedMission): its actions, groups, flags named and
//! control keys, every name resolved and every position kept for the messages of stage 2.
//!
//! They are what the parser ([`parse`](super::parse)) makes and what everything after it reads
//! — the checks of [`structure`](super::structure) and [`validate`](super::validate), the tree
//! of [`control`](super::control) — so they stand apart from both, and neither imports the
//! other for them.

use super::EndMode;
use marie_vocabulary::diagnostic::Pos;
use marie_vocabulary::property::Value;
use std::collections::BTreeMap;
use std::time::Duration;

/// A flag named in `initial`, `success` or `when`, resolved to its bit.
#[derive(Clone, Debug)]
pub(crate) struct FlagRef {
    pub(crate) name: String,
    pub(crate) bit: u8,
    pub(crate) at: Pos,
    /// The field it was named in, e.g. `action.when`.
    pub(crate) field: &'static str,
}

/// One supplied parameter, converted but not yet checked against a schema.
#[derive(Clone, Debug)]
pub(crate) struct ParsedParam {
    pub(crate) name: String,
    /// Position of the parameter's key.
    pub(crate) at: Pos,
    pub(crate) value: Value,
    /// Position of the value and of every nested value, by path (`pose.x`, `gains[1]`).
    pub(crate) value_at: BTreeMap<String, Pos>,
}

/// One `[action.ops.<key>]` table.
#[derive(Clone, Debug)]
pub(crate) struct ParsedOp {
    pub(crate) key: String,
    pub(crate) at: Pos,
    pub(crate) params: Vec<ParsedParam>,
}

/// One `[[action]]`, structurally sound.
#[derive(Clone, Debug)]
pub(crate) struct ParsedAction {
    pub(crate) name: String,
    /// Where its name is written.
    pub(crate) at: Pos,
    pub(crate) when: Vec<FlagRef>,
    pub(crate) ops: Vec<ParsedOp>,
    pub(crate) ends_on: Vec<String>,
    pub(crate) end_mode: EndMode,
    pub(crate) deadline: Duration,
    pub(crate) control: ParsedControl,
}

/// An action or a group of a mission, by its index among the mission's actions or groups.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Item {
    /// `actions[i]`.
    Action(usize),
    /// `groups[i]`.
    Group(usize),
}

/// A name in `children` or `on_failure`, resolved to the item it names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ItemRef {
    pub(crate) item: Item,
    /// Where the name is written.
    pub(crate) at: Pos,
}

/// `retry = { attempts = 3, backoff_s = 2.0 }`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Retry {
    /// Attempts in all, the first included (at least 1).
    pub(crate) attempts: u32,
    /// Time between a failure and the next attempt.
    pub(crate) backoff: Duration,
}

/// The control keys of an `[[action]]` or a `[[group]]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct ParsedControl {
    pub(crate) retry: Option<Retry>,
    pub(crate) timeout: Option<Duration>,
    pub(crate) on_failure: Option<ItemRef>,
    /// `while`: flags that must all stay set while it runs.
    pub(crate) while_: Vec<FlagRef>,
    /// `unless`: flags none of which may become set while it runs.
    pub(crate) unless: Vec<FlagRef>,
}

impl ParsedControl {
    /// True when it has reactive conditions (`while` or `unless`).
    pub(crate) fn reactive(&self) -> bool {
        !(self.while_.is_empty() && self.unless.is_empty())
    }

    /// True when no control key is given.
    pub(crate) fn is_empty(&self) -> bool {
        self.retry.is_none()
            && self.timeout.is_none()
            && self.on_failure.is_none()
            && self.while_.is_empty()
            && self.unless.is_empty()
    }
}

/// What a `[[group]]` does with its children (`kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupKind {
    /// In order; fails at the first failure.
    Sequence,
    /// In order until one succeeds.
    Fallback,
    /// All at once, with thresholds.
    Parallel,
    /// A sequence whose `while`/`unless` are re-checked while a child runs.
    Reactive,
}

impl GroupKind {
    /// The kinds as the file writes them, for messages.
    pub(crate) const NAMES: &'static str =
        "\"sequence\", \"fallback\", \"parallel\" or \"reactive\"";

    /// The kind the file's word names.
    pub(crate) fn parse(word: &str) -> Option<GroupKind> {
        match word {
            "sequence" => Some(GroupKind::Sequence),
            "fallback" => Some(GroupKind::Fallback),
            "parallel" => Some(GroupKind::Parallel),
            "reactive" => Some(GroupKind::Reactive),
            _ => None,
        }
    }

    /// The kind as the file writes it.
    pub fn word(self) -> &'static str {
        match self {
            GroupKind::Sequence => "sequence",
            GroupKind::Fallback => "fallback",
            GroupKind::Parallel => "parallel",
            GroupKind::Reactive => "reactive",
        }
    }
}

/// One `[[group]]`, structurally sound.
#[derive(Clone, Debug)]
pub(crate) struct ParsedGroup {
    pub(crate) name: String,
    /// Where its name is written.
    pub(crate) at: Pos,
    pub(crate) kind: GroupKind,
    pub(crate) children: Vec<ItemRef>,
    pub(crate) when: Vec<FlagRef>,
    pub(crate) control: ParsedControl,
    /// Parallel: how many children must succeed (default: all).
    pub(crate) success: usize,
    /// Parallel: how many failures make it fail (default 1).
    pub(crate) failure: usize,
}

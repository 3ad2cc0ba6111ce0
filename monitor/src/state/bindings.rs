//! The bindings: which instance serves each operation of the mission (address, node,
//! version), and its history of losses and rebinds — what the page's bindings panel draws.
//!
//! Built from the events that name instances: the self-configuration's choices
//! ([`EventKind::Selected`]: the candidates,
//! their schemas and flags — the properties a click opens), the start-up binding, each
//! action's activations, and the losses and rebinds.

use marie_vocabulary::events::{BoundOp, EventKind, OpStarted};
use marie_vocabulary::run::{Candidate, Choice};
use marie_vocabulary::run::{LossCause, RebindRecord};
use serde::Serialize;
use std::collections::BTreeMap;

/// At most this many history entries per binding (the oldest go first).
pub const HISTORY_LIMIT: usize = 100;

/// One step of a binding's history.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum BindingStep {
    /// Its instance was lost.
    Lost {
        /// Event time, ms of the node's clock.
        at_ms: u64,
        /// Why, as text.
        cause: String,
    },
    /// It was bound again.
    Rebound {
        /// Event time, ms of the node's clock.
        at_ms: u64,
        /// Why the old instance was left, as text.
        cause: String,
        /// Old address.
        from: String,
        /// New address.
        to: String,
        /// Old node.
        from_node: String,
        /// New node.
        to_node: String,
        /// Time without an instance, ms.
        downtime_ms: u64,
    },
    /// No stand-in came in time: the run stopped.
    GaveUp {
        /// Event time, ms of the node's clock.
        at_ms: u64,
        /// Why it was lost, as text.
        cause: String,
        /// How long the dispatcher waited, ms.
        waited_ms: u64,
    },
}

/// One operation's binding.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BindingView {
    /// Operation name.
    pub operation: String,
    /// The bound instance's actor address (unknown until chosen or activated).
    pub address: Option<String>,
    /// The node it runs on.
    pub node: Option<String>,
    /// Its version.
    pub version: Option<String>,
    /// The binding's epoch (its commands' fencing token; 0 until known).
    pub epoch: u64,
    /// How many times it was rebound: the binding's incarnation is this plus one.
    pub rebinds: u32,
    /// `bound`, `lost` (looking for a stand-in) or `gave_up`.
    pub status: &'static str,
    /// The candidates of the latest choice: address, node, version, schema, flags and
    /// verdict each.
    pub candidates: Vec<Candidate>,
    /// Losses, rebinds, giving up; the latest [`HISTORY_LIMIT`].
    pub history: Vec<BindingStep>,
}

/// Every binding, by operation name.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Bindings(pub BTreeMap<String, BindingView>);

impl Bindings {
    fn of(&mut self, operation: &str) -> &mut BindingView {
        self.0
            .entry(operation.to_string())
            .or_insert_with(|| BindingView {
                operation: operation.to_string(),
                status: "bound",
                ..BindingView::default()
            })
    }

    /// Take the run's choices, bindings, losses and rebinds in (at `at_ms`); other events
    /// pass by.
    pub fn apply(&mut self, at_ms: u64, kind: &EventKind) {
        match kind {
            EventKind::RunStarted { .. } => self.clear(),
            EventKind::Selected { choice } => self.selected(choice),
            EventKind::Bound { operations } => self.bound(operations),
            EventKind::ActionStarted { operations, .. } => self.activated(operations),
            EventKind::Lost { operation, cause } => self.lost(at_ms, operation, cause),
            EventKind::Rebound(r) => self.rebound(at_ms, r),
            EventKind::RebindGaveUp {
                operation,
                cause,
                waited_ms,
            } => self.gave_up(at_ms, operation, cause, *waited_ms),
            _ => {}
        }
    }

    /// A run starts: bindings of an earlier run are forgotten.
    pub fn clear(&mut self) {
        self.0.clear();
    }

    /// The self-configuration chose (or found none).
    pub fn selected(&mut self, choice: &Choice) {
        let b = self.of(&choice.operation);
        b.candidates = choice.candidates.clone();
        if let Some(c) = choice.chosen() {
            b.address = Some(c.address.clone());
            b.node = Some(c.node.clone());
            b.version = Some(c.version.clone());
        }
    }

    /// Every operation was bound at the start.
    pub fn bound(&mut self, ops: &[BoundOp]) {
        for op in ops {
            let b = self.of(&op.name);
            b.node = Some(op.node.clone());
            b.version = Some(op.version.clone());
            b.epoch = op.epoch;
            b.status = "bound";
        }
    }

    /// An action activated these instances.
    pub fn activated(&mut self, ops: &[OpStarted]) {
        for op in ops {
            let b = self.of(&op.name);
            b.address = Some(op.address.clone());
            b.node = Some(op.node.clone());
            b.version = Some(op.version.clone());
        }
    }

    /// An instance was lost.
    pub fn lost(&mut self, at_ms: u64, operation: &str, cause: &LossCause) {
        let b = self.of(operation);
        b.status = "lost";
        push(
            &mut b.history,
            BindingStep::Lost {
                at_ms,
                cause: cause.to_string(),
            },
        );
    }

    /// A lost operation is bound again.
    pub fn rebound(&mut self, at_ms: u64, r: &RebindRecord) {
        let b = self.of(&r.operation);
        b.status = "bound";
        b.rebinds += 1;
        b.address = Some(r.to.clone());
        b.epoch = r.epoch.max(b.epoch);
        if !r.to_node.is_empty() {
            b.node = Some(r.to_node.clone());
        }
        // the stand-in's version, when the choice of it named it
        if let Some(c) = b.candidates.iter().find(|c| c.address == r.to) {
            b.version = Some(c.version.clone());
        }
        push(
            &mut b.history,
            BindingStep::Rebound {
                at_ms,
                cause: r.cause.to_string(),
                from: r.from.clone(),
                to: r.to.clone(),
                from_node: r.from_node.clone(),
                to_node: r.to_node.clone(),
                downtime_ms: r.downtime_ms,
            },
        );
    }

    /// No stand-in came in time.
    pub fn gave_up(&mut self, at_ms: u64, operation: &str, cause: &LossCause, waited_ms: u64) {
        let b = self.of(operation);
        b.status = "gave_up";
        push(
            &mut b.history,
            BindingStep::GaveUp {
                at_ms,
                cause: cause.to_string(),
                waited_ms,
            },
        );
    }
}

fn push(history: &mut Vec<BindingStep>, step: BindingStep) {
    if history.len() >= HISTORY_LIMIT {
        history.remove(0);
    }
    history.push(step);
}

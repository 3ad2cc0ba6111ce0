//! Whose word a run is: the one dispatcher that speaks for it at a time.

use super::{Event, EventKind};

/// Follows which node's dispatcher speaks for a run — the node of its `run_started`, then
/// the `to` of each `takeover` — and tells whether an event is that dispatcher's word. What
/// another node's dispatcher says of the run (one fenced off, woken from a freeze or back
/// from a partition) is not: the report does not fold it, the live lines do not print it.
///
/// ```
/// use marie_vocabulary::events::{DispatcherVoice, Event, EventKind};
/// let at = |node: &str, kind| Event { at_ms: 0, node: node.into(), kind };
/// let mut voice = DispatcherVoice::default();
/// let start = EventKind::RunStarted { mission: "m".into(), actions: vec![], success: vec![] };
/// assert!(voice.hears(&at("a", start)));
/// let lost = || EventKind::Lost { operation: "op".into(), cause: marie_vocabulary::run::LossCause::Gone };
/// assert!(voice.hears(&at("a", lost())));
/// let takeover = EventKind::Takeover {
///     run: "r".into(), from: "a".into(), to: "b".into(), term: 2, gap_ms: 1,
///     since_checkpoint_ms: 1, unix_ms: 1,
/// };
/// assert!(voice.hears(&at("b", takeover)));
/// assert!(!voice.hears(&at("a", lost())), "a was replaced");
/// assert_eq!(voice.node(), Some("b"));
/// ```
#[derive(Clone, Debug, Default)]
pub struct DispatcherVoice {
    node: Option<String>,
}

impl DispatcherVoice {
    /// Take `event` into account; true unless it is a dispatcher's word about the run
    /// ([`EventKind::is_dispatch`]) from a node that does not speak for it. A
    /// `run_started`, a `takeover` and a `dispatcher_fenced` are always heard.
    pub fn hears(&mut self, event: &Event) -> bool {
        match &event.kind {
            EventKind::RunStarted { .. } => self.node = Some(event.node.clone()),
            EventKind::Takeover { to, .. } => self.node = Some(to.clone()),
            EventKind::DispatcherFenced { .. } => {}
            kind if kind.is_dispatch() => {
                return self.node.as_ref().is_none_or(|n| *n == event.node);
            }
            _ => {}
        }
        true
    }

    /// The node that speaks for the run, once one does.
    pub fn node(&self) -> Option<&str> {
        self.node.as_deref()
    }
}

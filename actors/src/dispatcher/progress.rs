//! Live progress lines: a compact view of the dispatcher's events on the bus, for printers
//! written against [`DispatchEvent`], and a relay that feeds them from a bus.
//!
//! Subscribers need only the bus ([`crate::events`]); this view exists so that a live-line
//! printer need not know every [`EventKind`].

use super::loss::LossCause;
use super::report::{Outcome, RebindRecord};
use crate::events::{BusError, EventBus, EventKind};
use crate::flags::StatusFlags;
use tokio::sync::{mpsc, oneshot};

/// Progress of a run, for live lines: the dispatcher's events on the bus, in the shape
/// printers of live output were written against ([`DispatchEvent::from_kind`]).
#[derive(Clone, Debug, PartialEq)]
pub enum DispatchEvent {
    /// An instance was chosen for an operation (or none fit): every candidate's verdict.
    Selected(super::selection::Choice),
    /// All operations were found and bound.
    Bound {
        /// `(operation, version, node)` for each binding.
        operations: Vec<(String, String, String)>,
    },
    /// An action started.
    ActionStarted {
        /// Action name.
        action: String,
        /// Its operations.
        operations: Vec<String>,
    },
    /// An action ended.
    ActionEnded {
        /// Action name.
        action: String,
        /// Status word after it, as names.
        flags: Vec<String>,
        /// Status word after it.
        status: StatusFlags,
    },
    /// A bound operation's instance was lost; the dispatcher looks for a stand-in.
    Lost {
        /// Operation name.
        operation: String,
        /// What happened to it.
        cause: LossCause,
    },
    /// A lost operation is bound again.
    Rebound(RebindRecord),
    /// The mission ended.
    Ended {
        /// Outcome.
        outcome: Outcome,
        /// Reason of a failure.
        reason: String,
    },
}

impl DispatchEvent {
    /// The live-line view of an event of the bus; `None` for kinds live lines do not show.
    pub fn from_kind(kind: &EventKind) -> Option<DispatchEvent> {
        Some(match kind {
            EventKind::Selected { choice } => DispatchEvent::Selected(choice.clone()),
            EventKind::Bound { operations } => DispatchEvent::Bound {
                operations: operations
                    .iter()
                    .map(|o| (o.name.clone(), o.version.clone(), o.node.clone()))
                    .collect(),
            },
            EventKind::ActionStarted {
                action, operations, ..
            } => DispatchEvent::ActionStarted {
                action: action.clone(),
                operations: operations.iter().map(|o| o.key.clone()).collect(),
            },
            EventKind::ActionEnded {
                action,
                flags,
                status,
                ..
            } => DispatchEvent::ActionEnded {
                action: action.clone(),
                flags: flags.clone(),
                status: StatusFlags(*status),
            },
            EventKind::Lost { operation, cause } => DispatchEvent::Lost {
                operation: operation.clone(),
                cause: cause.clone(),
            },
            EventKind::Rebound(r) => DispatchEvent::Rebound(r.clone()),
            EventKind::RunEnded {
                outcome, reason, ..
            } => DispatchEvent::Ended {
                outcome: *outcome,
                reason: reason.clone(),
            },
            _ => return None,
        })
    }
}

/// Feeds the [`DispatchEvent`]s of a bus to a channel, as they are published, until
/// [`finish`](ProgressRelay::finish)ed.
pub struct ProgressRelay {
    stop: Option<oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<()>,
}

impl ProgressRelay {
    /// Start relaying what `bus` publishes from now on to `to`.
    pub fn start(bus: &EventBus, to: mpsc::UnboundedSender<DispatchEvent>) -> ProgressRelay {
        let mut sub = bus.subscribe();
        let (stop, mut stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let pass = |kind: &EventKind| {
                if let Some(evt) = DispatchEvent::from_kind(kind) {
                    let _ = to.send(evt);
                }
            };
            loop {
                tokio::select! {
                    biased;
                    received = sub.recv() => match received {
                        Ok(event) => pass(&event.kind),
                        Err(BusError::Lagged { missed }) => {
                            tracing::warn!(missed, "live lines fell behind the event bus")
                        }
                        Err(BusError::Closed) => break,
                    },
                    _ = &mut stopped => {
                        for event in sub.drain() {
                            pass(&event.kind);
                        }
                        break;
                    }
                }
            }
        });
        ProgressRelay {
            stop: Some(stop),
            task,
        }
    }

    /// Relay what was published before this call, then stop.
    pub async fn finish(mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        let _ = (&mut self.task).await;
    }
}

impl Drop for ProgressRelay {
    fn drop(&mut self) {
        self.task.abort();
    }
}

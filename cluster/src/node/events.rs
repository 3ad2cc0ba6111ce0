//! The node's supervisors on its event bus: every supervisor event of the node's tree,
//! translated into plain [`EventKind`]s (the supervision crate knows no bus), so that the
//! live lines, the `--events` file and a remote monitor see restarts and give-ups as they
//! happen.

use super::tree::DATAMANAGERS;
use marie_dm::{DmClient, DmMsg};
use marie_supervision::{RestartCause, SupervisorEvent, SupervisorRef};
use marie_vocabulary::events::{EventBus, EventKind};
use ractor::rpc::CallResult;
use ractor::ActorRef;
use tokio::sync::broadcast::{self, error::RecvError};
use tokio::task::JoinHandle;

/// The bus form of a supervisor event of supervisor `supervisor`; `None` for the
/// bookkeeping steps nobody outside needs (scheduled restarts, deletions, the final stop).
pub(crate) fn translate(supervisor: &str, event: &SupervisorEvent) -> Option<EventKind> {
    let supervisor = supervisor.to_string();
    Some(match event {
        SupervisorEvent::ChildStarted { id, actor } => EventKind::ChildStarted {
            supervisor,
            child: id.clone(),
            actor: actor.get_id().to_string(),
        },
        SupervisorEvent::ChildExited { id, reason, .. } => EventKind::ChildExited {
            supervisor,
            child: id.clone(),
            reason: reason.to_string(),
        },
        SupervisorEvent::ChildRestarted {
            id,
            new,
            cause,
            restarts,
            ..
        } => EventKind::ChildRestarted {
            supervisor,
            child: id.clone(),
            actor: new.get_id().to_string(),
            restarts: *restarts,
            reason: match cause {
                RestartCause::Exited(reason) => reason.to_string(),
                RestartCause::Sibling(sibling) => format!("restarted with `{sibling}`"),
                RestartCause::Manual => "restarted on request".to_string(),
            },
        },
        SupervisorEvent::RestartFailed { id, error } => EventKind::ChildExited {
            supervisor,
            child: id.clone(),
            reason: format!("restart failed: {error}"),
        },
        SupervisorEvent::IntensityExceeded {
            max_restarts,
            period,
        } => EventKind::SupervisorGaveUp {
            supervisor,
            reason: format!(
                "more than {max_restarts} restarts within {:.1}s",
                period.as_secs_f64()
            ),
        },
        SupervisorEvent::ChildShutdown { .. }
        | SupervisorEvent::RestartScheduled { .. }
        | SupervisorEvent::ChildIgnored { .. }
        | SupervisorEvent::ChildDeleted { .. }
        | SupervisorEvent::Stopped { .. } => return None,
    })
}

/// Publish the events of `root` and of every supervisor below it on `bus`, following
/// supervisors that are restarted (a restart is a new actor with a new event stream). The
/// returned tasks end when their supervisors stop.
pub(crate) async fn bridge_supervisors(
    bus: &EventBus,
    root: &SupervisorRef,
) -> Vec<JoinHandle<()>> {
    let mut tasks = Vec::new();
    if let Ok(children) = root.which_children().await {
        for child in children {
            let Some(sup) = child
                .state
                .actor()
                .cloned()
                .and_then(SupervisorRef::from_cell)
            else {
                continue;
            };
            if let Ok(rx) = sup.subscribe().await {
                if child.id == DATAMANAGERS {
                    // the datamanagers started before the bridge: their recoveries now,
                    // before the node's start returns (a run tells them again: `Node::run`)
                    if let Ok(dms) = sup.which_children().await {
                        for dm in dms {
                            if let Some(actor) = dm.state.actor() {
                                tell_start(bus, actor.clone()).await;
                            }
                        }
                    }
                }
                tasks.push(spawn_relay(bus, child.id, rx, false));
            }
        }
    }
    if let Ok(rx) = root.subscribe().await {
        tasks.push(spawn_relay(bus, "node".to_string(), rx, true));
    }
    tasks
}

/// Relay the events of supervisor `name` until it stops. The root's (`follow`) also start
/// relaying each child supervisor it (re)starts: a restart is a new actor with a new stream.
async fn relay(
    bus: EventBus,
    name: String,
    mut rx: broadcast::Receiver<SupervisorEvent>,
    follow: bool,
) {
    loop {
        match rx.recv().await {
            Ok(event) => {
                if let Some(kind) = translate(&name, &event) {
                    bus.publish(kind);
                }
                if name == DATAMANAGERS {
                    match &event {
                        SupervisorEvent::ChildStarted { actor, .. }
                        | SupervisorEvent::ChildRestarted { new: actor, .. } => {
                            tell_recovery(&bus, actor.clone())
                        }
                        _ => {}
                    }
                }
                if follow {
                    if let Some((id, sub)) = child_supervisor(&event).await {
                        spawn_relay(&bus, id, sub, false);
                    }
                }
            }
            Err(RecvError::Lagged(missed)) => {
                tracing::warn!(supervisor = %name, missed, "supervisor events lost on the bus");
            }
            Err(RecvError::Closed) => return,
        }
    }
}

/// The name and event stream of the child `event` (re)started, if it is a supervisor.
async fn child_supervisor(
    event: &SupervisorEvent,
) -> Option<(String, broadcast::Receiver<SupervisorEvent>)> {
    let (id, cell) = match event {
        SupervisorEvent::ChildStarted { id, actor } => (id, actor),
        SupervisorEvent::ChildRestarted { id, new, .. } => (id, new),
        _ => return None,
    };
    let sub = SupervisorRef::from_cell(cell.clone())?
        .subscribe()
        .await
        .ok()?;
    Some((id.clone(), sub))
}

/// Ask the datamanager `actor` what it started from, and publish it: what it read back
/// from its journal (`dm_recovered`), or the records its previous incarnation left it
/// (`dm_inherited`).
fn tell_recovery(bus: &EventBus, actor: ractor::ActorCell) {
    let bus = bus.clone();
    tokio::spawn(async move { tell_start(&bus, actor).await });
}

/// [`tell_recovery`], awaited: whether the datamanager could be asked. (`ReplicaStats`: a
/// replica's own numbers — a follower sends a `Stats` on to its leader.)
pub(crate) async fn tell_start(bus: &EventBus, actor: ractor::ActorCell) -> bool {
    let actor: ActorRef<DmMsg> = actor.into();
    let deadline = Some(DmClient::DEFAULT_TIMEOUT);
    let Ok(CallResult::Success(stats)) = actor
        .call(|reply| DmMsg::ReplicaStats { reply }, deadline)
        .await
    else {
        return false;
    };
    if let Some(kind) = started_from(stats) {
        bus.publish(kind);
    }
    true
}

/// The event that tells what a datamanager whose stats are `stats` started from, if it
/// started from anything.
fn started_from(stats: marie_dm::DmStats) -> Option<EventKind> {
    if let Some(r) = stats.recovery {
        return Some(EventKind::DmRecovered {
            dm: stats.name,
            records: r.records,
            bytes: r.bytes,
            ms: r.millis,
            dropped_bytes: r.dropped_bytes,
            dropped_records: r.dropped_records,
            torn: r.torn,
        });
    }
    stats.inherited.map(|i| EventKind::DmInherited {
        dm: stats.name,
        records: i.records,
        refused: i.refused,
    })
}

/// Relay a supervisor's events in a task of their own (a plain function, so that the root's
/// relay may start relays of its children).
fn spawn_relay(
    bus: &EventBus,
    name: String,
    rx: broadcast::Receiver<SupervisorEvent>,
    follow: bool,
) -> JoinHandle<()> {
    tokio::spawn(relay(bus.clone(), name, rx, follow))
}

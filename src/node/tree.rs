//! The node's supervision tree: what its supervisors start, and how a run learns that the
//! operation supervisor gave up.

use marie_actors::clock::SharedClock;
use marie_actors::dispatcher::DispatcherMsg;
use marie_actors::dm::{self, DmArgs, DmClient, DmConfig};
use marie_missions::ops::records;
use marie_missions::world::World;
use marie_supervision::{ChildSpec, SupervisorEvent};
use ractor::{ActorRef, SpawnErr};
use std::sync::Arc;
use tokio::sync::broadcast;

use super::NODE_SOURCE;

/// Abort `dispatcher`'s mission if the operation supervisor gives up, naming the operation
/// whose exits made it give up.
pub(super) async fn abort_on_give_up(
    mut events: broadcast::Receiver<SupervisorEvent>,
    dispatcher: ActorRef<DispatcherMsg>,
) {
    let mut exits: Vec<String> = Vec::new();
    loop {
        match events.recv().await {
            Ok(SupervisorEvent::ChildExited { id, reason, .. }) => {
                exits.push(format!("{id} ({reason})"));
            }
            Ok(SupervisorEvent::RestartFailed { id, error }) => {
                exits.push(format!("{id} (restart failed: {error})"));
            }
            Ok(SupervisorEvent::IntensityExceeded {
                max_restarts,
                period,
            }) => {
                let recent: Vec<String> =
                    exits.iter().rev().take(max_restarts + 1).cloned().collect();
                let mut culprits: Vec<&str> = recent
                    .iter()
                    .map(|e| e.split(' ').next().unwrap_or_default())
                    .collect();
                culprits.sort_unstable();
                culprits.dedup();
                let reason = format!(
                    "the operation supervisor gave up: more than {max_restarts} restarts within {:.1}s, of {} (last exit: {})",
                    period.as_secs_f64(),
                    culprits.join(", "),
                    recent.first().map(String::as_str).unwrap_or("unknown"),
                );
                let _ = dispatcher.cast(DispatcherMsg::Abort { reason });
                return;
            }
            Ok(_) => {}
            Err(broadcast::error::RecvError::Lagged(_)) => {}
            Err(broadcast::error::RecvError::Closed) => return,
        }
    }
}

/// Child id of the datamanager supervisor in the node's tree.
pub(super) const DATAMANAGERS: &str = "datamanagers";

/// Child id of the operation supervisor in the node's tree.
pub(super) const OPERATIONS: &str = "operations";

/// The datamanagers' child specs. With a world, the world datamanager's start stores the
/// world's walls as the a-priori map before it counts as started, so the map is there before
/// any operation looks for it — and is there again after a restart.
pub(super) fn datamanagers(clock: &SharedClock, world: Option<&World>) -> Vec<ChildSpec> {
    let map = world.map(|w| Arc::new(w.segments()));
    [dm::FEATURE, dm::PARAMETER, dm::WORLD]
        .into_iter()
        .map(|spec| {
            let clock = clock.clone();
            let map = map.clone().filter(|_| spec.name == dm::WORLD.name);
            ChildSpec::worker(spec.name, move |sup| {
                let (clock, map) = (clock.clone(), map.clone());
                async move {
                    let (actor, _) = dm::spawn_datamanager_linked(
                        DmArgs {
                            id: spec.id,
                            name: spec.name.to_string(),
                            clock,
                            config: DmConfig::default(),
                        },
                        sup,
                    )
                    .await?;
                    if let Some(map) = map {
                        DmClient::new(actor.clone(), NODE_SOURCE)
                            .store(records::MAP, Some("walls"), None, &*map)
                            .await
                            .map_err(|e| SpawnErr::StartupFailed(Box::new(e)))?;
                    }
                    Ok(actor.get_cell())
                }
            })
        })
        .collect()
}

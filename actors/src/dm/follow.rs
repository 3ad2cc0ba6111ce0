//! Finding a datamanager's next instance: after a crash its supervisor starts a new one
//! under the same name (and, with copies, a copy is promoted elsewhere).

use crate::registry::{self, Instance, ModuleKind};
use ractor::{ActorId, ActorStatus};
use std::time::Duration;

/// A live instance published as `dm` (name or id) other than `gone`, local ones first.
pub(crate) fn published(dm: &str, gone: Option<ActorId>) -> Option<Instance> {
    registry::lookup(ModuleKind::Datamanager, dm)
        .into_iter()
        .find(|i| Some(i.actor.get_id()) != gone && i.actor.get_status() <= ActorStatus::Running)
}

/// [`published`], or the first such instance the registry publishes within `within` (on the
/// runtime's timer). `None` if none comes.
pub(crate) async fn next_instance(
    dm: &str,
    gone: Option<ActorId>,
    within: Duration,
) -> Option<Instance> {
    // watching first, then looking: an instance published in between is in one or the other
    let Ok(mut watch) = registry::watch(Some(ModuleKind::Datamanager)).await else {
        return published(dm, gone);
    };
    if let Some(found) = published(dm, gone) {
        return Some(found);
    }
    tokio::time::timeout(within, async {
        while let Some(event) = watch.next().await {
            if let registry::RegistryEvent::Joined(i) = event {
                if i.answers_to(dm) && Some(i.actor.get_id()) != gone {
                    return Some(i);
                }
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
}

//! Finding a module's next instance: after a crash its supervisor starts a new one under the
//! same name (a datamanager with copies may instead be promoted elsewhere), and a module on
//! a node that was cut off is published again once the node is back.

use super::{Instance, ModuleKind};
use ractor::{ActorId, ActorStatus};
use std::time::Duration;

/// A live instance of `kind` published as `key` (name or id) other than `gone`, local ones
/// first.
pub fn published(kind: ModuleKind, key: &str, gone: Option<ActorId>) -> Option<Instance> {
    super::lookup(kind, key)
        .into_iter()
        .find(|i| Some(i.actor.get_id()) != gone && i.actor.get_status() <= ActorStatus::Running)
}

/// [`published`], or the first instance the registry publishes as `key` within `within` (on
/// the runtime's timer) — `gone` too, if it is published again meanwhile: a replicated
/// datamanager's replica that stepped down and is elected leader again is the same actor,
/// and its publication is news. `None` if none comes.
pub async fn next_instance(
    kind: ModuleKind,
    key: &str,
    gone: Option<ActorId>,
    within: Duration,
) -> Option<Instance> {
    // watching first, then looking: an instance published in between is in one or the other
    let Ok(mut watch) = super::watch(Some(kind)).await else {
        return published(kind, key, gone);
    };
    if let Some(found) = published(kind, key, gone) {
        return Some(found);
    }
    tokio::time::timeout(within, async {
        while let Some(event) = watch.next().await {
            if let super::RegistryEvent::Joined(i) = event {
                if i.answers_to(key) {
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

//! Finding a datamanager's next instance: after a crash its supervisor starts a new one
//! under the same name (and, with replicas, a replica is promoted elsewhere) — the registry's
//! follow, for datamanagers.

use marie_vocabulary::registry::{follow, Instance, ModuleKind};
use ractor::ActorId;
use std::time::Duration;

/// A live instance published as `dm` (name or id) other than `gone`, local ones first.
pub(crate) fn published(dm: &str, gone: Option<ActorId>) -> Option<Instance> {
    follow::published(ModuleKind::Datamanager, dm, gone)
}

/// [`published`], or else `gone` itself if it is published and alive (a replicated
/// datamanager's replica that stepped down — it refused or timed out a request meanwhile —
/// and was elected leader again is the same actor), or the first instance the registry
/// publishes within `within` (on the runtime's timer). `None` if none comes.
pub(crate) async fn next_instance(
    dm: &str,
    gone: Option<ActorId>,
    within: Duration,
) -> Option<Instance> {
    if let Some(found) = published(dm, gone).or_else(|| published(dm, None)) {
        return Some(found);
    }
    follow::next_instance(ModuleKind::Datamanager, dm, gone, within).await
}

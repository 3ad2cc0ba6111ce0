//! The registry bridge: joins and leaves of the location table, published onto a bus.

use super::{EventBus, EventKind, ModuleInfo};
use crate::registry::{self, ModuleKind, RegistryEvent};

/// A running bridge from the registry to a bus; dropping it ends the bridge (and its
/// registry watch).
pub struct RegistryBridge {
    task: tokio::task::JoinHandle<()>,
}

impl std::fmt::Debug for RegistryBridge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RegistryBridge")
            .field("running", &!self.task.is_finished())
            .finish()
    }
}

impl Drop for RegistryBridge {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Publish every join and leave of modules of `kind` (or of every kind, with `None`) onto
/// `bus` as [`EventKind::Joined`] / [`EventKind::Left`], from the moment this returns until
/// the returned bridge is dropped.
pub async fn bridge_registry(
    bus: EventBus,
    kind: Option<ModuleKind>,
) -> Result<RegistryBridge, ractor::SpawnErr> {
    let mut watch = registry::watch(kind).await?;
    let task = tokio::spawn(async move {
        while let Some(event) = watch.next().await {
            bus.publish(match &event {
                RegistryEvent::Joined(inst) => EventKind::Joined(ModuleInfo::from(inst)),
                RegistryEvent::Left(inst) => EventKind::Left(ModuleInfo::from(inst)),
            });
        }
    });
    Ok(RegistryBridge { task })
}

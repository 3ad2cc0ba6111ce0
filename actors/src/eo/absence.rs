//! How long an operation waits for a module it needs that is gone (a datamanager failing
//! over or restarting, the cart's node cut off) before its activation fails, and what the
//! failure says.
//!
//! A module is waited for [`DATAMANAGER_RETURN`](super::DATAMANAGER_RETURN): a failover or
//! a restart is over long before. A replicated datamanager that lost its majority needs a
//! node of its replicas back — restarted by `marie up`, systemd or a container runtime —,
//! so it is waited for longer, up to [`MAJORITY_WAIT`] in all; the failure then names it
//! and the nodes it misses, which "not reachable" alone would not.

use marie_dm::{MAJORITY_WAIT, VIEW_TIMEOUT};
use marie_vocabulary::registry::{follow::next_instance, ModuleKind};

/// Wait for `module` (of `kind`) to be published again; `Err` with the reason the
/// activation fails for when it is not (`reason`: why it was found gone).
pub(super) async fn wait_for_module(
    kind: ModuleKind,
    module: &str,
    reason: String,
) -> Result<(), String> {
    let first = super::DATAMANAGER_RETURN;
    if next_instance(kind, module, None, first).await.is_some() {
        return Ok(());
    }
    let not_back = format!("{reason} (not back within {first:?})");
    if kind != ModuleKind::Datamanager {
        return Err(not_back);
    }
    let Some(lost) = marie_dm::without_leader(module, VIEW_TIMEOUT).await else {
        return Err(not_back);
    };
    let rest = MAJORITY_WAIT.saturating_sub(first);
    tracing::warn!(dm = %module, %lost, "waiting for the datamanager's majority to come back");
    if next_instance(kind, module, None, rest).await.is_some() {
        tracing::info!(dm = %module, "the datamanager's majority is back");
        return Ok(());
    }
    Err(match marie_dm::without_leader(module, VIEW_TIMEOUT).await {
        Some(lost) => format!("{lost} (for {} s)", MAJORITY_WAIT.as_secs()),
        None => not_back,
    })
}

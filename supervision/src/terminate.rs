//! Stopping one child by its shutdown spec.

use std::time::Duration;

use ractor::ActorCell;

use crate::child::Shutdown;
use crate::exit::SHUTDOWN;

/// How long to wait for a killed child to finish. A kill interrupts the child at its next
/// `.await`; only an actor stuck in blocking code outlives it, and no one can stop that one —
/// the supervisor logs it and moves on rather than hang the whole tree.
const KILL_GRACE: Duration = Duration::from_secs(5);

/// Stop `child` as `shutdown` says and wait until it has stopped. Returns whether it had to be
/// killed. Waits on the child's own stop notification rather than on its supervision event,
/// so it also works for a child that unlinked itself; and it waits even when someone else
/// stopped the child first (ractor then refuses a second stop request).
pub(crate) async fn shutdown_child(child: &ActorCell, shutdown: Shutdown) -> bool {
    match shutdown {
        Shutdown::BrutalKill => {
            kill(child).await;
            true
        }
        Shutdown::Timeout(timeout) => {
            child.stop(Some(SHUTDOWN.to_string()));
            if child.wait(Some(timeout)).await.is_ok() {
                false
            } else {
                tracing::warn!(
                    child = %child.get_id(),
                    ?timeout,
                    "child did not stop within its shutdown timeout; killing it"
                );
                kill(child).await;
                true
            }
        }
        Shutdown::Infinity => {
            child.stop(Some(SHUTDOWN.to_string()));
            let _ = child.wait(None).await;
            false
        }
    }
}

async fn kill(child: &ActorCell) {
    child.kill();
    if child.wait(Some(KILL_GRACE)).await.is_err() {
        tracing::error!(
            child = %child.get_id(),
            "killed child still runs after {KILL_GRACE:?} (blocked in synchronous code?); \
             giving up on it"
        );
    }
}

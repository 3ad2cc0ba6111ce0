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

/// Stop many children at once, each as its shutdown says, and wait until all have stopped
/// (simple-one-for-one instances, which have no order among them). Every child is asked to
/// stop (or killed) first; then each is waited for until its own deadline, counted from the
/// common start; the stragglers are killed together and waited for. Returns, per child,
/// whether it had to be killed. Costs one pass over the children, however many there are,
/// instead of one shutdown after the other.
pub(crate) async fn shutdown_together(children: &[(ActorCell, Shutdown)]) -> Vec<bool> {
    let started = tokio::time::Instant::now();
    for (child, shutdown) in children {
        match shutdown {
            Shutdown::BrutalKill => child.kill(),
            Shutdown::Timeout(_) | Shutdown::Infinity => child.stop(Some(SHUTDOWN.to_string())),
        }
    }
    let mut killed = vec![false; children.len()];
    let mut stragglers = Vec::new();
    for (i, (child, shutdown)) in children.iter().enumerate() {
        match shutdown {
            Shutdown::BrutalKill => {
                killed[i] = true;
                stragglers.push(i);
            }
            Shutdown::Timeout(timeout) => {
                let left =
                    (started + *timeout).saturating_duration_since(tokio::time::Instant::now());
                if child.wait(Some(left)).await.is_err() {
                    tracing::warn!(
                        child = %child.get_id(),
                        ?timeout,
                        "child did not stop within its shutdown timeout; killing it"
                    );
                    child.kill();
                    killed[i] = true;
                    stragglers.push(i);
                }
            }
            Shutdown::Infinity => {
                let _ = child.wait(None).await;
            }
        }
    }
    let grace_end = tokio::time::Instant::now() + KILL_GRACE;
    for i in stragglers {
        let child = &children[i].0;
        let left = grace_end.saturating_duration_since(tokio::time::Instant::now());
        if child.wait(Some(left)).await.is_err() {
            tracing::error!(
                child = %child.get_id(),
                "killed child still runs after {KILL_GRACE:?} (blocked in synchronous code?); \
                 giving up on it"
            );
        }
    }
    killed
}

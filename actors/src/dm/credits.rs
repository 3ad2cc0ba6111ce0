//! Flow control of `Put`s to a datamanager on another node: a window of credits.
//!
//! A `Put` is a cast: the producer never waits, and ractor_cluster's remote tell has no flow
//! control — a sensor on one node can enqueue millions of records a second while the
//! datamanager's node drains a few hundred thousand, and both the session between them and
//! the datamanager's mailbox grow without bound. So a client's puts to a *remote*
//! datamanager spend credits: at most [`WINDOW`] may be unacknowledged. Once half the window
//! is spent, the client asks the datamanager for its stats (a call, which the datamanager
//! answers only after every earlier message of the same sender: one session, one mailbox, in
//! order); the answer gives back the credits spent before the ask. With no credit left, a
//! put is refused at once with [`DmError::Busy`] — a high-rate producer drops that sample, as
//! a sensor would, instead of queueing it. Memory in flight is bounded by the window on
//! both sides. Local puts are not metered: the datamanager runs on the producer's own
//! runtime.
//!
//! Clones of a client share its credits (one producer, one window).

use super::error::DmError;
use super::messages::DmMsg;
use ractor::ActorRef;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Unacknowledged puts a client may have in flight to a remote datamanager.
pub const WINDOW: usize = 1024;

/// How long an acknowledgement may take before the credits it would return are asked for
/// again (by the next put).
const ACK_TIMEOUT: Duration = Duration::from_secs(5);

/// The credits of one producer towards one datamanager.
#[derive(Debug, Default)]
pub(crate) struct Credits {
    in_flight: AtomicUsize,
    acking: AtomicBool,
}

impl Credits {
    /// Spend a credit for a put to `actor`, asking for an acknowledgement when half the
    /// window is spent; `Busy` when none is left.
    pub(crate) fn spend(
        self: &Arc<Self>,
        actor: &ActorRef<DmMsg>,
        dm: &str,
    ) -> Result<(), DmError> {
        let spent = self.in_flight.fetch_add(1, Ordering::AcqRel) + 1;
        if spent > WINDOW {
            self.in_flight.fetch_sub(1, Ordering::AcqRel);
            self.ask_ack(actor);
            return Err(DmError::Busy {
                dm: dm.to_string(),
                window: WINDOW as u64,
            });
        }
        if spent >= WINDOW / 2 {
            self.ask_ack(actor);
        }
        Ok(())
    }

    /// A put that was counted but could not be sent gives its credit back.
    pub(crate) fn refund(&self) {
        self.in_flight.fetch_sub(1, Ordering::AcqRel);
    }

    /// Puts in flight now (for tests and stats).
    pub(crate) fn in_flight(&self) -> usize {
        self.in_flight.load(Ordering::Acquire)
    }

    /// Unless one is under way, ask `actor` for an acknowledgement of the puts spent so far
    /// and give their credits back when it comes.
    fn ask_ack(self: &Arc<Self>, actor: &ActorRef<DmMsg>) {
        if self.acking.swap(true, Ordering::AcqRel) {
            return;
        }
        let spent = self.in_flight.load(Ordering::Acquire);
        let (credits, actor) = (self.clone(), actor.clone());
        tokio::spawn(async move {
            let answered = actor
                .call(|reply| DmMsg::Stats { reply }, Some(ACK_TIMEOUT))
                .await
                .is_ok_and(|r| r.is_success());
            if answered {
                credits.in_flight.fetch_sub(spent, Ordering::AcqRel);
            } else {
                tracing::debug!("a datamanager did not acknowledge puts: credits held");
            }
            credits.acking.store(false, Ordering::Release);
        });
    }
}

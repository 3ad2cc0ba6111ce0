//! What a datamanager at durability `memory` leaves to its next incarnation: its records
//! survive the datamanager's crash, not its process's.
//!
//! An Erlang ETS table dies with the process that owns it unless it names an *heir*, which
//! then gets the table. A memory datamanager's store is the same: the actor's state dies
//! with the actor (ractor drops it after a panic or a kill, and runs no `post_stop` then), so
//! a restarted datamanager used to start empty — on the embedded node, a killed `feature`
//! datamanager took every sonar reading and segment with it, and the docking mission
//! ended. Now the arguments a supervisor restarts it with carry an [`Heir`]: when the state
//! is dropped — however the actor ended — its store, its producers' table and its fences
//! are handed to the heir (`Drop` of the state, the one step every ending runs), and the
//! next incarnation started from the same arguments takes them at its start.
//!
//! # A crash in the middle of a mutation
//! A panic while the store is half-updated (a record in its class but not yet in the time
//! index, a removal half done) must not hand a corrupt store to the heir. Proving every
//! mutation free of panics half-way is a promise no one can keep as the store grows, so
//! the heir checks instead: it rebuilds the store from the records themselves
//! ([`Store::rebuilt`]) — every index, count and bound re-derived, in seq order, through
//! the same path a journal's replay takes, a record that does not fit refused and counted.
//! A rebuild costs a pass over the records once per crash, nothing on the path of a put.
//! The producers' table and the fences are plain maps whose every update is one insert: at
//! worst the last put before the panic is not noted, and its retry is stored twice.
//!
//! # Why not a journal in a temporary directory
//! It would also survive the process — which nothing asks of `memory` — and cost every put
//! of every embedded run an encoding and a write. What `memory` can honestly promise is
//! what this gives: the datamanager's crash loses nothing; its process's loses everything.
//!
//! # The hand-over
//! Ractor reports an actor's end to its supervisor before it drops the state, so on a
//! runtime with several threads the next incarnation may start while its predecessor's
//! state still exists. The heir knows: its slot is `Held` while an incarnation holds the
//! estate, and a start waits (at most [`LEAVE_WAIT`]) for the predecessor to leave it.

use super::producers::Producers;
use super::store::Store;
use marie_vocabulary::fence::FenceTable;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::sync::Notify;

/// How long a start waits for its predecessor's state to be dropped (it is dropped right
/// after the predecessor's end is reported: microseconds, unless two incarnations of the
/// same arguments run at once).
pub(crate) const LEAVE_WAIT: Duration = Duration::from_secs(5);

/// Where a memory datamanager's records wait for its next incarnation (see the module
/// docs): one per datamanager, shared by the clones of its [`DmArgs`](super::DmArgs) — a
/// supervisor restarts a datamanager with clones of the same arguments, so the restarted
/// one is the heir. Ignored by a datamanager that keeps a journal (it reads its journal
/// back instead).
#[derive(Clone, Default)]
pub struct Heir(Arc<Slot>);

impl std::fmt::Debug for Heir {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match &*self.0.lock() {
            Left::Nothing => "nothing",
            Left::Held => "held",
            Left::Estate(_) => "left",
        };
        f.debug_tuple("Heir").field(&what).finish()
    }
}

#[derive(Default)]
struct Slot {
    left: Mutex<Left>,
    gone: Notify,
}

impl Slot {
    fn lock(&self) -> MutexGuard<'_, Left> {
        self.left.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// What the slot holds.
#[derive(Default)]
enum Left {
    /// No incarnation ever held it.
    #[default]
    Nothing,
    /// An incarnation holds the estate (alive, or its state not yet dropped).
    Held,
    /// The last incarnation left this.
    Estate(Box<Estate>),
}

/// What a memory datamanager leaves: everything it would read back from a journal.
pub(crate) struct Estate {
    pub(crate) store: Store,
    pub(crate) producers: Producers,
    pub(crate) fences: FenceTable,
}

/// What a memory datamanager's start took from its previous incarnation (its
/// [`DmStats`](super::DmStats)' `inherited`, told as `dm_inherited`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Inherited {
    /// Records it holds after it took them.
    pub records: u64,
    /// Records the check of what it took refused (a store left half-updated by a crash in
    /// the middle of a change).
    pub refused: u64,
}

/// What an incarnation starts with, from its heir.
pub(crate) struct Inheritance {
    /// The estate, its store rebuilt; `None` when nothing was left (the first start).
    pub(crate) estate: Option<Estate>,
    /// Records the rebuild refused (a corrupt store left by a crash half-way).
    pub(crate) refused: u64,
}

impl Heir {
    /// An heir that holds nothing yet.
    pub fn new() -> Heir {
        Heir::default()
    }

    /// Take what the predecessor left — waiting for it to leave if it still holds the
    /// estate — with its store rebuilt and checked; the slot is held from now on.
    pub(crate) async fn inherit(&self, dm: &str) -> Inheritance {
        let deadline = tokio::time::Instant::now() + LEAVE_WAIT;
        loop {
            // registered before the look, so a leave between the look and the wait wakes it
            let gone = self.0.gone.notified();
            {
                let mut left = self.0.lock();
                match std::mem::replace(&mut *left, Left::Held) {
                    Left::Nothing => return Inheritance::nothing(),
                    Left::Estate(estate) => {
                        drop(left);
                        return Inheritance::of(dm, *estate);
                    }
                    Left::Held => {}
                }
            }
            if tokio::time::timeout_at(deadline, gone).await.is_err() {
                tracing::warn!(dm, "the previous incarnation still holds the records after {LEAVE_WAIT:?}: starting empty");
                return Inheritance::nothing();
            }
        }
    }

    /// Leave `estate` to the next incarnation.
    pub(crate) fn leave(&self, estate: Estate) {
        *self.0.lock() = Left::Estate(Box::new(estate));
        self.0.gone.notify_waiters();
    }
}

impl Inheritance {
    pub(crate) fn nothing() -> Inheritance {
        Inheritance {
            estate: None,
            refused: 0,
        }
    }

    /// `estate` with its store rebuilt from its records (see the module docs).
    fn of(dm: &str, estate: Estate) -> Inheritance {
        let Estate {
            store,
            producers,
            fences,
        } = estate;
        let (store, refused) = store.rebuilt();
        if refused > 0 {
            tracing::warn!(
                dm,
                refused,
                "the inherited store was inconsistent: records refused by its rebuild"
            );
        }
        tracing::info!(
            dm,
            records = store.len(),
            "records inherited from the previous incarnation"
        );
        Inheritance {
            estate: Some(Estate {
                store,
                producers,
                fences,
            }),
            refused,
        }
    }
}

//! Which start of a replica an actor is: a number drawn when the replica's actor is spawned,
//! carried in the actor's name, so that every replica reads it off the replicas' groups.
//!
//! A replica cannot tell a peer that was lost from a new session to it by the actor it
//! finds in the peer's group: ractor_cluster gives a remote actor an id of the session it
//! came through (`ActorId::Remote { node_id, pid }`, `node_id` counted afresh for every
//! session), so a session dialled anew to a live peer — a duplicate closed after its twin
//! authenticated, a re-dial after a reset connection — shows the same actor under another
//! id, after a moment out of the group. Its `pid` stays, but a node's process started again
//! numbers its actors from the start and may hand the new replica the old one's. A start's
//! own random number does not repeat: the datamanager's actor is spawned under the name
//! `{dm}/{node}#{incarnation}` (its group's name, then 16 hex digits), and ractor_cluster
//! sends every actor's name with it when it tells a peer of the actor, so the stand-in of a
//! remote replica carries it — on the leader and on a follower alike, with no message of
//! the protocol needed. A replica actor of a build before this has no such name: its
//! incarnation is unknown, and any other actor of it counts as another start.

use ractor::ActorCell;
use std::hash::{BuildHasher, Hash, Hasher};

/// One start of a replica's actor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Incarnation(u64);

impl Incarnation {
    /// A fresh one: random (the standard library's per-process random keys), mixed with
    /// this process's id, the time and a count of the incarnations drawn in it — two starts
    /// of a replica draw the same with a chance of 2^-64.
    pub(crate) fn draw() -> Incarnation {
        static DRAWN: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        std::process::id().hash(&mut h);
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or_default()
            .hash(&mut h);
        DRAWN
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            .hash(&mut h);
        Incarnation(h.finish())
    }

    /// The name a replica whose group is `group` is spawned under, in this incarnation.
    pub(crate) fn actor_name(self, group: &str) -> String {
        format!("{group}#{:016x}", self.0)
    }

    /// The incarnation an actor's name carries (`None`: it carries none, as a replica of
    /// an older build).
    pub(crate) fn of_name(name: &str) -> Option<Incarnation> {
        let (_, hex) = name.rsplit_once('#')?;
        if hex.len() != 16 {
            return None;
        }
        u64::from_str_radix(hex, 16).ok().map(Incarnation)
    }

    /// The incarnation of the replica `cell` is (or stands in for, a remote one's).
    pub(crate) fn of(cell: &ActorCell) -> Option<Incarnation> {
        cell.get_name().as_deref().and_then(Incarnation::of_name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_incarnation_is_read_back_from_the_name_it_gives_and_each_start_draws_another() {
        let a = Incarnation::draw();
        let name = a.actor_name("feature/spare");
        assert!(name.starts_with("feature/spare#"), "{name}");
        assert_eq!(Incarnation::of_name(&name), Some(a));
        assert_ne!(Incarnation::draw(), a);
        // names of actors that are no replica of this build carry none
        for other in [
            "feature/spare",
            "feature/spare#",
            "x#12",
            "feature/spare#zzzzzzzzzzzzzzzz",
        ] {
            assert_eq!(Incarnation::of_name(other), None, "{other}");
        }
    }
}

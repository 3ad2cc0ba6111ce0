//! Who each registered actor is: a process-local index from actor id to (kind, id, name), so
//! that a lookup reads one `pg` group and this map instead of every group of the table.
//!
//! `pg` keeps the memberships (and syncs them between nodes); this index only names the
//! members. Local publications enter it at once; a member it does not know yet (a remote
//! module that just joined) makes the next lookup rebuild it from the entry groups
//! (`eo/ID/NAME`), which also drops the ids of actors that have gone. Entries of dead actors
//! are harmless meanwhile: a lookup consults the index only for the group's live members;
//! a withdrawn actor leaves it at once, and once the index has doubled since it was last
//! built (restarts publish new ids) the next publication rebuilds it, so it stays within
//! twice the live table.
//!
//! # Invariant
//! A lookup's cost grows with the instances of the name asked for, not with the table,
//! while the index knows them (`benches/registry.rs` times this path with 1000 instances
//! published); a member it does not know costs one rebuild, a scan of the table.

use super::{parse_entry, ModuleKind, SCOPE};
use ractor::{pg, ActorId};
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{OnceLock, RwLock};

/// What the registry knows of one actor.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Entry {
    pub(super) kind: ModuleKind,
    pub(super) id: u32,
    pub(super) name: String,
}

fn index() -> &'static RwLock<HashMap<ActorId, Entry>> {
    static INDEX: OnceLock<RwLock<HashMap<ActorId, Entry>>> = OnceLock::new();
    INDEX.get_or_init(Default::default)
}

/// Size of the index when it was last rebuilt.
static BUILT: AtomicUsize = AtomicUsize::new(0);

/// Below this size the index is never rebuilt for its size alone.
const SMALL: usize = 256;

/// Record a local publication; rebuild first when dead actors may have doubled the index.
pub(super) fn insert(actor: ActorId, entry: Entry) {
    let len = index().read().unwrap_or_else(|e| e.into_inner()).len();
    if len >= 2 * BUILT.load(Ordering::Relaxed).max(SMALL) {
        rebuild();
    }
    index()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .insert(actor, entry);
}

/// Forget a withdrawn actor.
pub(super) fn remove(actor: &ActorId) {
    index()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .remove(actor);
}

/// The entries of `actors`, in order: `None` for one the index does not know.
pub(super) fn entries(actors: &[ActorId]) -> Vec<Option<Entry>> {
    let idx = index().read().unwrap_or_else(|e| e.into_inner());
    actors.iter().map(|a| idx.get(a).cloned()).collect()
}

/// Rebuild the index from the entry groups: every member of every `KIND/ID/NAME` group.
pub(super) fn rebuild() {
    let scope = SCOPE.to_string();
    let mut fresh = HashMap::new();
    for group in pg::which_scoped_groups(&scope) {
        let Some((kind, id, name)) = parse_entry(&group) else {
            continue;
        };
        for actor in pg::get_scoped_members(&scope, &group) {
            fresh.insert(
                actor.get_id(),
                Entry {
                    kind,
                    id,
                    name: name.to_string(),
                },
            );
        }
    }
    BUILT.store(fresh.len(), Ordering::Relaxed);
    *index().write().unwrap_or_else(|e| e.into_inner()) = fresh;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn len() -> usize {
        index().read().unwrap_or_else(|e| e.into_inner()).len()
    }

    #[test]
    fn publications_of_actors_that_are_gone_do_not_pile_up() {
        // actors that published and died without withdrawing (a crash): in no group any
        // more, as each restart's predecessor
        for pid in 0..3000u64 {
            insert(
                ActorId::Local(1_000_000 + pid),
                Entry {
                    kind: ModuleKind::Operation,
                    id: 1,
                    name: "gone".into(),
                },
            );
        }
        // the index was rebuilt whenever it doubled: within twice the live table (the
        // other tests of this process publish far fewer than SMALL)
        assert!(len() < 4 * SMALL, "{} entries", len());
        remove(&ActorId::Local(1_000_000 + 2999));
        assert!(entries(&[ActorId::Local(1_000_000 + 2999)])[0].is_none());
    }
}

//! Who each registered actor is: a process-local index from actor id to (kind, id, name), so
//! that a lookup reads one `pg` group and this map instead of every group of the table.
//!
//! `pg` keeps the memberships (and syncs them between nodes); this index only names the
//! members. Local publications enter it at once; a member it does not know yet (a remote
//! module that just joined) makes the next lookup rebuild it from the entry groups
//! (`eo/ID/NAME`), which also drops the ids of actors that have gone. Entries of dead actors
//! are harmless meanwhile: a lookup consults the index only for the group's live members.
//!
//! # Invariant
//! A lookup's cost grows with the instances of the name asked for, not with the table
//! (`benches/registry.rs`: 1000 instances published).

use super::{parse_entry, ModuleKind, SCOPE};
use ractor::{pg, ActorId};
use std::collections::HashMap;
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

/// Record a local publication.
pub(super) fn insert(actor: ActorId, entry: Entry) {
    index()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .insert(actor, entry);
}

/// The entries of `actors`, in order; `None` if any is unknown.
pub(super) fn entries(actors: &[ActorId]) -> Option<Vec<Entry>> {
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
    *index().write().unwrap_or_else(|e| e.into_inner()) = fresh;
}

//! The location table: a cluster-wide directory of live modules, built on ractor's `pg`.
//!
//! Every module (operation, datamanager, dispatcher) *publishes itself* when it starts
//! ([`publish`]) under its kind, numeric id and name; `pg` removes it when the actor dies, so a
//! stale entry cannot exist (the thesis left stale entries to the operator, 8.6). [`lookup`]
//! returns **every** live instance with its location and lets the caller choose (thesis 8.5);
//! [`watch`] streams joins and leaves; [`list`] prints the table like the thesis' start-up log.
//!
//! `pg` is the only directory ractor_cluster synchronizes between nodes, so the same calls see
//! remote modules once a node has joined a cluster.
//!
//! # Invariant
//! One `pg` group holds actors of one message type only (`eo/…` groups hold `EoMsg` actors,
//! `dm/…` groups `DmMsg` actors), because a message of the wrong type sent to a remote actor is
//! dropped without a word.
//!
//! ```
//! # use marie_vocabulary::registry::{self, ModuleKind};
//! # async fn demo() {
//! for inst in registry::lookup(ModuleKind::Operation, "wall-follower") {
//!     println!("{} on {}", inst.name, inst.node);
//! }
//! # }
//! ```

pub mod follow;
mod index;
mod verdicts;
mod watch;

pub use verdicts::{declare_down, declare_up, is_declared_down};
pub use watch::{watch, RegistryEvent, Watch};

use ractor::{pg, ActorCell, ActorId};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::fmt;
use std::sync::{OnceLock, RwLock};

/// The `pg` scope of the location table.
pub const SCOPE: &str = "marie";

/// What kind of module an entry is; each kind speaks one message type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ModuleKind {
    /// An elementary operation hosted by an EO host (`EoMsg`).
    Operation,
    /// A datamanager (`DmMsg`).
    Datamanager,
    /// An action dispatcher.
    Dispatcher,
    /// A (virtual) hardware module such as the cart; hardware-bound modules stay on the
    /// robot's node (thesis 8.7.1). Each hardware kind speaks its own message type.
    Hardware,
}

impl ModuleKind {
    /// The group prefix of this kind.
    pub fn prefix(self) -> &'static str {
        match self {
            ModuleKind::Operation => "eo",
            ModuleKind::Datamanager => "dm",
            ModuleKind::Dispatcher => "ad",
            ModuleKind::Hardware => "hw",
        }
    }

    fn from_prefix(p: &str) -> Option<ModuleKind> {
        match p {
            "eo" => Some(ModuleKind::Operation),
            "dm" => Some(ModuleKind::Datamanager),
            "ad" => Some(ModuleKind::Dispatcher),
            "hw" => Some(ModuleKind::Hardware),
            _ => None,
        }
    }

    /// How the thesis' start-up log names the kind (`EO`, `DM`, `AD`, `HW`).
    pub fn label(self) -> &'static str {
        match self {
            ModuleKind::Operation => "EO",
            ModuleKind::Datamanager => "DM",
            ModuleKind::Dispatcher => "AD",
            ModuleKind::Hardware => "HW",
        }
    }
}

impl fmt::Display for ModuleKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

/// A registry error.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum RegistryError {
    /// Module names are single words of letters, digits, `-`, `_` and `.`.
    #[error("invalid module name {0:?}: use letters, digits, '-', '_' or '.'")]
    InvalidName(String),
}

/// One live instance of a module and where it runs.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Kind of module.
    pub kind: ModuleKind,
    /// Numeric id (e.g. 1512).
    pub id: u32,
    /// Module name (e.g. `wall-follower`).
    pub name: String,
    /// Name of the node it runs on.
    pub node: String,
    /// The actor.
    pub actor: ActorCell,
}

impl Instance {
    /// The actor's id (node-qualified for remote actors).
    pub fn actor_id(&self) -> ActorId {
        self.actor.get_id()
    }

    /// Whether `key` names it: its name or its numeric id in decimal, as [`lookup`] takes.
    pub fn answers_to(&self, key: &str) -> bool {
        let key = key.trim();
        self.name == key || self.id.to_string() == key
    }

    /// True when the actor runs in this process.
    pub fn is_local(&self) -> bool {
        self.actor.get_id().is_local()
    }
}

fn check_name(name: &str) -> Result<(), RegistryError> {
    let ok = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        && !name.chars().all(|c| c.is_ascii_digit());
    if ok {
        Ok(())
    } else {
        Err(RegistryError::InvalidName(name.to_string()))
    }
}

fn entry_group(kind: ModuleKind, id: u32, name: &str) -> String {
    format!("{}/{}/{}", kind.prefix(), id, name)
}

fn key_group(kind: ModuleKind, key: &str) -> String {
    format!("{}/{}", kind.prefix(), key)
}

/// Parse an entry group `eo/1512/wall-follower` into its parts.
fn parse_entry(group: &str) -> Option<(ModuleKind, u32, &str)> {
    let mut parts = group.splitn(3, '/');
    let kind = ModuleKind::from_prefix(parts.next()?)?;
    let id = parts.next()?.parse().ok()?;
    let name = parts.next()?;
    Some((kind, id, name))
}

/// Publish `actor` as an instance of module `name` / `id`. Call it from the actor's
/// `pre_start` or `post_start`; the entry disappears when the actor dies.
pub fn publish(
    kind: ModuleKind,
    id: u32,
    name: &str,
    actor: ActorCell,
) -> Result<(), RegistryError> {
    check_name(name)?;
    for group in [
        key_group(kind, name),
        key_group(kind, &id.to_string()),
        entry_group(kind, id, name),
    ] {
        pg::join_scoped(SCOPE.to_string(), group, vec![actor.clone()]);
    }
    index::insert(
        actor.get_id(),
        index::Entry {
            kind,
            id,
            name: name.to_string(),
        },
    );
    tracing::debug!(%kind, id, name, actor = %actor.get_id(), "published");
    Ok(())
}

/// Withdraw `actor` from the table before it dies (e.g. while it shuts down).
pub fn unpublish(kind: ModuleKind, id: u32, name: &str, actor: &ActorCell) {
    for group in [
        key_group(kind, name),
        key_group(kind, &id.to_string()),
        entry_group(kind, id, name),
    ] {
        pg::leave_scoped(SCOPE.to_string(), group, vec![actor.clone()]);
    }
    index::remove(&actor.get_id());
}

/// Every live instance of a module, by name (`wall-follower`) or numeric id (`1512`),
/// local and remote. The order is stable: local instances first, then by actor id.
pub fn lookup(kind: ModuleKind, name_or_id: &str) -> Vec<Instance> {
    let key = name_or_id.trim();
    let by_key = pg::get_scoped_members(&SCOPE.to_string(), &key_group(kind, key));
    if by_key.is_empty() {
        return Vec::new();
    }
    // name the members from the index; a member it does not know yet (a remote module that
    // just joined) rebuilds it once; one in no entry group yet (between its key group and
    // its entry group) is not listed
    let ids: Vec<ActorId> = by_key.iter().map(ActorCell::get_id).collect();
    let mut entries = index::entries(&ids);
    if entries.iter().any(Option::is_none) {
        index::rebuild();
        entries = index::entries(&ids);
    }
    let mut out: Vec<Instance> = by_key
        .into_iter()
        .zip(entries)
        .filter_map(|(actor, e)| Some((actor, e?)))
        .filter(|(_, e)| e.kind == kind)
        .map(|(actor, e)| Instance {
            kind,
            id: e.id,
            name: e.name,
            node: node_name_of(&actor.get_id()),
            actor,
        })
        .collect();
    sort_instances(&mut out);
    out
}

fn sort_instances(v: &mut [Instance]) {
    v.sort_by_key(|i| {
        let id = i.actor.get_id();
        (i.kind, i.id, !id.is_local(), id.node(), id.pid())
    });
}

/// Every live instance of every module, sorted by kind, id and location.
pub fn list() -> Vec<Instance> {
    list_kind(None)
}

/// Every live instance of one kind of module, sorted by id and location.
pub fn list_of(kind: ModuleKind) -> Vec<Instance> {
    list_kind(Some(kind))
}

fn list_kind(kind: Option<ModuleKind>) -> Vec<Instance> {
    let scope = SCOPE.to_string();
    let mut out = Vec::new();
    for group in pg::which_scoped_groups(&scope) {
        let Some((k, id, name)) = parse_entry(&group) else {
            continue;
        };
        if kind.is_some_and(|want| want != k) {
            continue;
        }
        for actor in pg::get_scoped_members(&scope, &group) {
            out.push(Instance {
                kind: k,
                id,
                name: name.to_string(),
                node: node_name_of(&actor.get_id()),
                actor,
            });
        }
    }
    sort_instances(&mut out);
    out
}

/// Render the table like the thesis' start-up log, one line per instance:
/// `EO found 1: ID: 1511 node: local addr: 0.12 name: trajectory-controller`.
/// Numbering restarts per kind.
pub fn render_listing(instances: &[Instance]) -> String {
    let mut out = String::new();
    let mut counts: HashMap<ModuleKind, usize> = HashMap::new();
    for inst in instances {
        let n = counts.entry(inst.kind).or_default();
        out.push_str(&format!(
            "{} found {}: ID: {} node: {} addr: {} name: {}\n",
            inst.kind,
            n,
            inst.id,
            inst.node,
            inst.actor.get_id(),
            inst.name
        ));
        *n += 1;
    }
    out
}

fn node_names() -> &'static RwLock<(String, HashMap<u64, String>)> {
    static NAMES: OnceLock<RwLock<(String, HashMap<u64, String>)>> = OnceLock::new();
    NAMES.get_or_init(|| RwLock::new(("local".to_string(), HashMap::new())))
}

/// Name this process' node (default `local`). The cluster layer sets it at start-up.
pub fn set_local_node_name(name: impl Into<String>) {
    node_names().write().unwrap_or_else(|e| e.into_inner()).0 = name.into();
}

/// The name of this process' node.
pub fn local_node_name() -> String {
    node_names()
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .0
        .clone()
}

/// Record the name of the peer node behind ractor's per-session `node_id`. The cluster layer
/// calls this when a session authenticates; node ids change on every reconnect.
pub fn set_peer_node_name(node_id: u64, name: impl Into<String>) {
    node_names()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .1
        .insert(node_id, name.into());
}

/// The node an actor runs on, by name where known.
pub fn node_name_of(id: &ActorId) -> String {
    let names = node_names().read().unwrap_or_else(|e| e.into_inner());
    if id.is_local() {
        names.0.clone()
    } else {
        names
            .1
            .get(&id.node())
            .cloned()
            .unwrap_or_else(|| format!("node-{}", id.node()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_words() {
        assert!(check_name("wall-follower").is_ok());
        assert!(check_name("a/b").is_err());
        assert!(check_name("").is_err());
        assert!(check_name("1512").is_err());
    }

    #[test]
    fn entry_groups_parse_back() {
        let g = entry_group(ModuleKind::Operation, 1512, "wall-follower");
        assert_eq!(
            parse_entry(&g),
            Some((ModuleKind::Operation, 1512, "wall-follower"))
        );
        assert_eq!(parse_entry("eo/wall-follower"), None);
    }
}

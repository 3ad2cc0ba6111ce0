//! The operations a mission may use, as validation sees them: each one's identity,
//! parameter declarations and flags ([`OpInfo`]), looked up by name or id in a [`Catalog`] —
//! the live registry's ([`crate::dispatcher::RegistryCatalog`]) or a fixed list
//! ([`StaticCatalog`]).

use super::Mission;
use crate::dispatcher::CheckedChoices;
use crate::eo::{Identity, Operation};
use crate::property::ParamSchema;
use crate::status::FlagDecl;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What validation needs to know about one operation: identity, parameter declarations and
/// the flags it can raise.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpInfo {
    /// Canonical name, e.g. `wall-follower`.
    pub name: String,
    /// Numeric id, e.g. 1512.
    pub id: u32,
    /// Semantic version.
    pub version: String,
    /// Parameter declarations.
    pub schema: ParamSchema,
    /// Flags the operation can raise, by name.
    pub flags: Vec<FlagDecl>,
}

impl OpInfo {
    /// An operation without parameters or flags; add them with [`OpInfo::params`] and
    /// [`OpInfo::flags`].
    pub fn new(name: impl Into<String>, id: u32, version: impl Into<String>) -> Self {
        OpInfo {
            name: name.into(),
            id,
            version: version.into(),
            schema: ParamSchema::default(),
            flags: Vec::new(),
        }
    }

    /// From an operation's identity, parameters and flags.
    pub fn from_identity(identity: &Identity, schema: ParamSchema, flags: Vec<FlagDecl>) -> Self {
        OpInfo {
            name: identity.name.clone(),
            id: identity.id,
            version: identity.version.to_string(),
            schema,
            flags,
        }
    }

    /// What `op` declares about itself.
    pub fn of<O: Operation>(op: &O) -> Self {
        OpInfo::from_identity(&op.identity(), op.parameters(), op.flags())
    }

    /// With these parameter declarations.
    pub fn params(mut self, schema: ParamSchema) -> Self {
        self.schema = schema;
        self
    }

    /// With these flags.
    pub fn flags(mut self, flags: Vec<FlagDecl>) -> Self {
        self.flags = flags;
        self
    }

    /// True when `key` names this operation: its name or its id in decimal.
    pub fn matches(&self, key: &str) -> bool {
        self.name == key || self.id.to_string() == key
    }
}

/// The operations a mission may use.
pub trait Catalog {
    /// The operation a mission key (a name or a numeric id such as `"1512"`) refers to.
    fn operation(&self, key: &str) -> Option<OpInfo>;
    /// The names of every available operation, for "available: ..." hints.
    fn names(&self) -> Vec<String>;
    /// The choices made among running instances while this catalog was gathered, for the
    /// validated `mission` to carry to its dispatcher ([`Mission::checked`]): none unless
    /// the catalog asked the running instances (`RegistryCatalog::for_mission`).
    fn checked(&self, mission: &Mission) -> CheckedChoices {
        let _ = mission;
        CheckedChoices::default()
    }
}

/// A fixed list of operations, looked up by name or by id: for tests and for checking a
/// mission without a running system.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StaticCatalog {
    ops: Vec<OpInfo>,
}

impl StaticCatalog {
    /// A catalog of `ops`. When two match one key the first wins.
    pub fn new(ops: impl IntoIterator<Item = OpInfo>) -> Self {
        StaticCatalog {
            ops: ops.into_iter().collect(),
        }
    }

    /// Add an operation.
    pub fn insert(&mut self, op: OpInfo) {
        self.ops.push(op);
    }

    /// The operations, in insertion order.
    pub fn iter(&self) -> std::slice::Iter<'_, OpInfo> {
        self.ops.iter()
    }
}

impl Catalog for StaticCatalog {
    fn operation(&self, key: &str) -> Option<OpInfo> {
        self.ops.iter().find(|o| o.matches(key)).cloned()
    }

    fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.ops.iter().map(|o| o.name.clone()).collect();
        names.sort();
        names.dedup();
        names
    }
}

/// A map from name to operation is a catalog too; keys that are ids are matched against the
/// operations' ids.
impl Catalog for BTreeMap<String, OpInfo> {
    fn operation(&self, key: &str) -> Option<OpInfo> {
        self.get(key)
            .or_else(|| self.values().find(|o| o.matches(key)))
            .cloned()
    }

    fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.values().map(|o| o.name.clone()).collect();
        names.sort();
        names.dedup();
        names
    }
}

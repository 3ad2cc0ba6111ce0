//! The operations a mission may use, as validation sees them ([`OpInfo`]), looked up by
//! name or id in a [`Catalog`] —
//! the live registry's ([`crate::dispatcher::RegistryCatalog`]) or a fixed list
//! ([`StaticCatalog`]).

use super::op_info::OpInfo;
use super::Mission;
use crate::dispatcher::CheckedChoices;
use std::collections::BTreeMap;

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

//! One operation as a mission's validation and the dispatcher's selection see it: identity,
//! parameter declarations and flags. A file of its own because both sides use it — the
//! catalogs validation asks and the candidates selection ranks — and neither should reach
//! the other through it.

use crate::declare::Migrations;
use crate::eo::{Identity, Operation};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use serde::{Deserialize, Serialize};

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
    /// How parameters of its older versions map onto its own (a rename): what a mission
    /// written for an older version supplies reaches it through these.
    #[serde(default, skip_serializing_if = "Migrations::is_empty")]
    pub migrations: Migrations,
    /// Its node's config pins the version of a binding to it (`pin = true` on its
    /// `[[operation]]`, [`crate::eo::HostOptions::pinned`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub pinned: bool,
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
            migrations: Migrations::default(),
            pinned: false,
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
            migrations: Migrations::default(),
            pinned: false,
        }
    }

    /// What `op` declares about itself.
    pub fn of<O: Operation>(op: &O) -> Self {
        OpInfo::from_identity(&op.identity(), op.parameters(), op.flags())
            .migrations(op.migrations())
    }

    /// From what an operation declares (an instance of a factory, [`crate::eo::Declared`]).
    pub fn from_declared(declared: crate::eo::Declared) -> Self {
        OpInfo::from_identity(&declared.identity, declared.schema, declared.flags)
            .migrations(declared.migrations)
    }

    /// With these migrations.
    pub fn migrations(mut self, migrations: Migrations) -> Self {
        self.migrations = migrations;
        self
    }

    /// What the mission `supplied` reaches this operation as: mapped by its migrations (a
    /// parameter an older version called otherwise, under its name here).
    pub fn migrated(
        &self,
        supplied: &marie_vocabulary::property::ParamMap,
    ) -> marie_vocabulary::property::ParamMap {
        self.migrations.apply(supplied, &self.schema)
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

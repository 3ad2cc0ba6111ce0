//! One operation as a mission's validation and the dispatcher's selection see it: identity,
//! parameter declarations and flags. A file of its own because both sides use it — the
//! catalogs validation asks and the candidates selection ranks — and neither should reach
//! the other through it.

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

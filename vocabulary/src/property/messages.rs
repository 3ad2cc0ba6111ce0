//! Property interface messages (thesis ch. 6, appendix A).
//!
//! Any module may ask an operation about itself. The EO host answers every request from the
//! operation's declaration and its own bookkeeping, so an operation author writes no property
//! code; `marie_actors::eo::Operation::property` adds operation-specific properties.

use super::schema::{ParamDecl, ParamType};
use super::value::{ParamMap, Value};
use crate::status::FlagDecl;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A property group of the thesis (table A-1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Group {
    /// Name, id, version.
    Identification,
    /// Node, address, alive.
    Location,
    /// Parameter count, up-time, in-use.
    General,
    /// Parameter descriptors, previous and current values, declared flags.
    Specific,
}

/// The thesis' five predefined collections, one request each (A.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Collection {
    /// (name, id, host, port): where to reach the module.
    Address,
    /// (parameter names, count, types).
    Signature,
    /// (names, defaults, min, max).
    Limits,
    /// (names, previous values).
    Previous,
    /// (names, current values).
    Current,
}

/// What is asked.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PropertyRequest {
    /// A whole group.
    Group(Group),
    /// A predefined collection.
    Collection(Collection),
    /// One property by name: a standard one (see [`STANDARD_PROPERTIES`]), `param.NAME` for
    /// one parameter's current value, or an operation-specific one.
    Get(String),
}

/// Names [`PropertyRequest::Get`] always answers.
pub const STANDARD_PROPERTIES: &[&str] = &[
    "name",
    "id",
    "version",
    "description",
    "node",
    "address",
    "alive",
    "param_count",
    "uptime_ms",
    "in_use",
    "activations",
    "epoch",
];

/// Identification group. Its strings are shared (`Arc<str>`): identity never changes, and
/// every identification request answers a copy, which is then a reference-count bump instead
/// of three allocations.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identification {
    /// Module name, e.g. `wall-follower`.
    pub name: Arc<str>,
    /// Numeric id, e.g. 1512.
    pub id: u32,
    /// Semantic version, e.g. `2.0.0`.
    pub version: Arc<str>,
    /// One line about what it does.
    pub description: Arc<str>,
}

/// Location group.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Location {
    /// Node name.
    pub node: String,
    /// Actor address on that node.
    pub address: String,
    /// The answering module is alive by construction; kept for the thesis' "existence".
    pub alive: bool,
}

/// General group.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct General {
    /// Number of declared parameters.
    pub param_count: usize,
    /// Time since the host started, in milliseconds of its clock.
    pub uptime_ms: u64,
    /// True while an activation is running.
    pub in_use: bool,
    /// How many times it was activated.
    pub activations: u64,
    /// Highest command epoch accepted.
    pub epoch: u64,
    /// How long the operation may take to answer any command, in milliseconds of its clock
    /// (`marie_actors::eo::Operation::deadline`). A dispatcher that gets no answer within it treats
    /// the operation as hung: it kills it and handles it as crashed.
    #[serde(default = "default_deadline_ms")]
    pub deadline_ms: u64,
}

/// The general property `deadline_ms` of an operation that declares no deadline of its own
/// (and of an older peer's answer that lacks the field).
pub const DEFAULT_DEADLINE_MS: u64 = 2_000;

fn default_deadline_ms() -> u64 {
    DEFAULT_DEADLINE_MS
}

/// Specific group: the parameter descriptors (names, types, defaults, min, max, step, unit,
/// description, read-only), previous and current values, and the flags it can raise.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Specific {
    /// Parameter descriptors, in declaration order.
    pub params: Vec<ParamDecl>,
    /// Values before the last successful parameterization.
    pub previous: ParamMap,
    /// Current values.
    pub current: ParamMap,
    /// Flags the operation can raise; bit `i` of its reports is `flags[i]`.
    pub flags: Vec<FlagDecl>,
}

/// Address collection.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Address {
    /// Module name.
    pub name: String,
    /// Numeric id.
    pub id: u32,
    /// Node (the thesis' host).
    pub node: String,
    /// Actor address (the thesis' port).
    pub address: String,
}

/// Signature collection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Signature {
    /// Parameter count.
    pub count: usize,
    /// Names and types, in declaration order.
    pub params: Vec<(String, ParamType)>,
}

/// One entry of the limits collection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limit {
    /// Parameter name.
    pub name: String,
    /// Default value.
    pub default: Value,
    /// Minimum, for numbers.
    pub min: Option<f64>,
    /// Maximum, for numbers.
    pub max: Option<f64>,
}

/// A property answer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PropertyReply {
    /// Identification group.
    Identification(Identification),
    /// Location group.
    Location(Location),
    /// General group.
    General(General),
    /// Specific group.
    Specific(Specific),
    /// Address collection.
    Address(Address),
    /// Signature collection.
    Signature(Signature),
    /// Limits collection.
    Limits(Vec<Limit>),
    /// Previous-values collection.
    Previous(ParamMap),
    /// Current-values collection.
    Current(ParamMap),
    /// A single property.
    Value(Value),
    /// The module has no property of that name.
    NotFound(String),
}

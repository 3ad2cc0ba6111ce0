//! The property interface: what an operation can tell about itself.
//!
//! [`schema`] declares parameters ([`ParamDecl`]) and validates updates atomically;
//! [`value`] holds parameter values and [`from_value`] reads them as Rust types;
//! [`messages`] are the requests and replies that any module sends an operation (thesis
//! ch. 6). The EO host answers them for every operation.
//!
//! ```
//! use marie_vocabulary::property::{ParamDecl, ParamSchema, Value, param_map};
//! let schema = ParamSchema::new(vec![ParamDecl::float("distance", 0.5).range(0.1, 2.0).unit("m")]);
//! let current = schema.defaults();
//! // one bad value rejects the whole update, with a reason per value
//! let err = schema.apply(&current, &param_map([("distance", Value::Float(3.0))]), false).unwrap_err();
//! assert_eq!(err[0].name, "distance");
//! ```

pub mod from_value;
pub mod messages;
pub mod schema;
pub mod value;

pub use from_value::FromValue;
pub use messages::{
    Address, Collection, General, Group, Identification, Limit, Location, PropertyReply,
    PropertyRequest, Signature, Specific, DEFAULT_DEADLINE_MS, STANDARD_PROPERTIES,
};
pub use schema::{ParamDecl, ParamSchema, ParamType, RejectReason, Rejection};
pub use value::{param_map, ParamMap, Value};

//! Parameter declarations and atomic validation.
//!
//! An operation declares its parameters once ([`ParamDecl`]); everything else — defaults for a
//! mission that omits them, range checks on reparameterization, the property interface's
//! specific group, mission checking before a run — is derived from that declaration. The
//! descriptor holds what ROS 2's `ParameterDescriptor` holds (type, range, step, description,
//! read-only) plus the thesis' defaults and units.

use super::value::{ParamMap, Value};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// The type of a parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ParamType {
    /// `true` / `false`.
    Bool,
    /// Signed integer; ranges from the declaration's `min` / `max` / `step`.
    Int,
    /// Floating point; integers are accepted and converted.
    Float,
    /// Free text.
    Text,
    /// One of a fixed set of words (e.g. `wall` | `corridor`).
    Choice(Vec<String>),
    /// An array whose elements all match `item` (its name is ignored), with a length bound.
    Array {
        /// Declaration of every element.
        item: Box<ParamDecl>,
        /// Smallest accepted length.
        min_len: usize,
        /// Largest accepted length.
        max_len: usize,
    },
    /// A nested structure: every field is declared.
    Struct(Vec<ParamDecl>),
}

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamType::Bool => write!(f, "bool"),
            ParamType::Int => write!(f, "int"),
            ParamType::Float => write!(f, "float"),
            ParamType::Text => write!(f, "text"),
            ParamType::Choice(words) => write!(f, "one of {}", words.join("|")),
            ParamType::Array { item, .. } => write!(f, "array of {}", item.ty),
            ParamType::Struct(fields) => {
                write!(f, "struct {{")?;
                for (i, d) in fields.iter().enumerate() {
                    if i > 0 {
                        write!(f, ", ")?;
                    }
                    write!(f, "{}: {}", d.name, d.ty)?;
                }
                write!(f, "}}")
            }
        }
    }
}

/// The declaration of one parameter (or of one field of a struct parameter).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamDecl {
    /// Name, unique within its operation (or struct).
    pub name: String,
    /// Type.
    pub ty: ParamType,
    /// Value used when a mission omits the parameter. Must pass the declaration's own checks.
    pub default: Value,
    /// Inclusive lower bound for numbers.
    #[serde(default)]
    pub min: Option<f64>,
    /// Inclusive upper bound for numbers.
    #[serde(default)]
    pub max: Option<f64>,
    /// Granularity for numbers: accepted values are `min + k * step` (or `k * step` without a
    /// minimum).
    #[serde(default)]
    pub step: Option<f64>,
    /// Unit, e.g. `m`, `m/s`, `deg`.
    #[serde(default)]
    pub unit: Option<String>,
    /// One sentence for people.
    #[serde(default)]
    pub description: String,
    /// Set once at start-up; reparameterization rejects it.
    #[serde(default)]
    pub read_only: bool,
}

impl ParamDecl {
    /// A declaration with the given name, type and default; refine with the builder methods.
    pub fn new(name: impl Into<String>, ty: ParamType, default: impl Into<Value>) -> Self {
        ParamDecl {
            name: name.into(),
            ty,
            default: default.into(),
            min: None,
            max: None,
            step: None,
            unit: None,
            description: String::new(),
            read_only: false,
        }
    }

    /// A float parameter.
    pub fn float(name: impl Into<String>, default: f64) -> Self {
        Self::new(name, ParamType::Float, default)
    }

    /// An integer parameter.
    pub fn int(name: impl Into<String>, default: i64) -> Self {
        Self::new(name, ParamType::Int, default)
    }

    /// A bool parameter.
    pub fn bool(name: impl Into<String>, default: bool) -> Self {
        Self::new(name, ParamType::Bool, default)
    }

    /// A text parameter.
    pub fn text(name: impl Into<String>, default: impl Into<String>) -> Self {
        Self::new(name, ParamType::Text, Value::Text(default.into()))
    }

    /// A choice among `words`, defaulting to `default`.
    pub fn choice(name: impl Into<String>, words: &[&str], default: &str) -> Self {
        Self::new(
            name,
            ParamType::Choice(words.iter().map(|w| w.to_string()).collect()),
            Value::Text(default.to_string()),
        )
    }

    /// Inclusive numeric range.
    pub fn range(mut self, min: f64, max: f64) -> Self {
        self.min = Some(min);
        self.max = Some(max);
        self
    }

    /// Numeric granularity.
    pub fn step(mut self, step: f64) -> Self {
        self.step = Some(step);
        self
    }

    /// Unit of measure.
    pub fn unit(mut self, unit: impl Into<String>) -> Self {
        self.unit = Some(unit.into());
        self
    }

    /// Description.
    pub fn describe(mut self, text: impl Into<String>) -> Self {
        self.description = text.into();
        self
    }

    /// Mark read-only.
    pub fn read_only(mut self) -> Self {
        self.read_only = true;
        self
    }

    /// Check `value` against this declaration, returning the value in canonical form (an
    /// integer given for a float becomes a float). `path` names the value in errors.
    pub fn check(&self, path: &str, value: &Value) -> Result<Value, Rejection> {
        let wrong_type = || Rejection {
            name: path.to_string(),
            reason: RejectReason::WrongType {
                expected: self.ty.to_string(),
                got: value.kind().to_string(),
            },
        };
        match (&self.ty, value) {
            (ParamType::Bool, Value::Bool(_)) | (ParamType::Text, Value::Text(_)) => {
                Ok(value.clone())
            }
            (ParamType::Int, Value::Int(i)) => {
                self.check_number(path, *i as f64)?;
                Ok(value.clone())
            }
            (ParamType::Float, Value::Float(_) | Value::Int(_)) => {
                let x = value.as_f64().unwrap_or_default();
                if !x.is_finite() {
                    return Err(Rejection::new(path, RejectReason::NotFinite));
                }
                self.check_number(path, x)?;
                Ok(Value::Float(x))
            }
            (ParamType::Choice(words), Value::Text(s)) => {
                if words.iter().any(|w| w == s) {
                    Ok(value.clone())
                } else {
                    Err(Rejection::new(
                        path,
                        RejectReason::NotAChoice {
                            got: s.clone(),
                            choices: words.clone(),
                        },
                    ))
                }
            }
            (
                ParamType::Array {
                    item,
                    min_len,
                    max_len,
                },
                Value::Array(items),
            ) => {
                if items.len() < *min_len || items.len() > *max_len {
                    return Err(Rejection::new(
                        path,
                        RejectReason::BadLength {
                            len: items.len(),
                            min: *min_len,
                            max: *max_len,
                        },
                    ));
                }
                items
                    .iter()
                    .enumerate()
                    .map(|(i, v)| item.check(&format!("{path}[{i}]"), v))
                    .collect::<Result<Vec<_>, _>>()
                    .map(Value::Array)
            }
            (ParamType::Struct(fields), Value::Struct(given)) => {
                for name in given.keys() {
                    if !fields.iter().any(|f| &f.name == name) {
                        return Err(Rejection::new(
                            format!("{path}.{name}"),
                            RejectReason::UnknownName,
                        ));
                    }
                }
                // A struct value is complete: omitted fields take their defaults.
                let mut out = BTreeMap::new();
                for f in fields {
                    let sub = format!("{path}.{}", f.name);
                    let v = match given.get(&f.name) {
                        Some(v) => f.check(&sub, v)?,
                        None => f.default.clone(),
                    };
                    out.insert(f.name.clone(), v);
                }
                Ok(Value::Struct(out))
            }
            _ => Err(wrong_type()),
        }
    }

    fn check_number(&self, path: &str, x: f64) -> Result<(), Rejection> {
        let out_of_range = || {
            Rejection::new(
                path,
                RejectReason::OutOfRange {
                    value: x,
                    min: self.min,
                    max: self.max,
                },
            )
        };
        if self.min.is_some_and(|m| x < m) || self.max.is_some_and(|m| x > m) {
            return Err(out_of_range());
        }
        if let Some(step) = self.step.filter(|s| *s > 0.0) {
            let k = (x - self.min.unwrap_or(0.0)) / step;
            if (k - k.round()).abs() > 1e-9 * k.abs().max(1.0) {
                return Err(Rejection::new(
                    path,
                    RejectReason::OffStep { value: x, step },
                ));
            }
        }
        Ok(())
    }
}

/// Why one value was refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum RejectReason {
    /// No parameter (or field) of that name is declared.
    #[error("unknown parameter")]
    UnknownName,
    /// The value has another type.
    #[error("expected {expected}, got {got}")]
    WrongType {
        /// Declared type.
        expected: String,
        /// Kind of the value given.
        got: String,
    },
    /// A number outside the declared range.
    #[error("{value} is out of range [{}, {}]", fmt_bound(*min, "-inf"), fmt_bound(*max, "+inf"))]
    OutOfRange {
        /// Value given.
        value: f64,
        /// Declared minimum.
        min: Option<f64>,
        /// Declared maximum.
        max: Option<f64>,
    },
    /// A number not on the declared step grid.
    #[error("{value} is not a multiple of the step {step}")]
    OffStep {
        /// Value given.
        value: f64,
        /// Declared step.
        step: f64,
    },
    /// NaN or infinity.
    #[error("not a finite number")]
    NotFinite,
    /// A word not among the choices.
    #[error("{got:?} is not one of {}", choices.join("|"))]
    NotAChoice {
        /// Word given.
        got: String,
        /// Accepted words.
        choices: Vec<String>,
    },
    /// An array of the wrong length.
    #[error("length {len} is outside [{min}, {max}]")]
    BadLength {
        /// Length given.
        len: usize,
        /// Smallest accepted.
        min: usize,
        /// Largest accepted.
        max: usize,
    },
    /// The parameter is read-only.
    #[error("read-only")]
    ReadOnly,
}

fn fmt_bound(b: Option<f64>, none: &str) -> String {
    b.map_or_else(|| none.to_string(), |b| b.to_string())
}

/// A refused value: which one (a path such as `pose.x` or `points[2]`) and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{name}: {reason}")]
pub struct Rejection {
    /// Path of the refused value.
    pub name: String,
    /// Why.
    pub reason: RejectReason,
}

impl Rejection {
    /// A rejection of `name` for `reason`.
    pub fn new(name: impl Into<String>, reason: RejectReason) -> Self {
        Rejection {
            name: name.into(),
            reason,
        }
    }
}

/// Every parameter an operation declares, in declaration order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ParamSchema {
    /// The declarations.
    pub params: Vec<ParamDecl>,
}

impl ParamSchema {
    /// A schema from declarations.
    pub fn new(params: Vec<ParamDecl>) -> Self {
        ParamSchema { params }
    }

    /// The declaration named `name`.
    pub fn get(&self, name: &str) -> Option<&ParamDecl> {
        self.params.iter().find(|d| d.name == name)
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// True when the operation has no parameters.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// The parameters' names, in declaration order.
    ///
    /// ```
    /// use marie_vocabulary::property::{ParamDecl, ParamSchema};
    /// let s = ParamSchema::new(vec![ParamDecl::int("litres", 10), ParamDecl::float("rate", 1.0)]);
    /// assert_eq!(s.names(), ["litres", "rate"]);
    /// ```
    pub fn names(&self) -> Vec<&str> {
        self.params.iter().map(|d| d.name.as_str()).collect()
    }

    /// The defaults of every parameter.
    pub fn defaults(&self) -> ParamMap {
        self.params
            .iter()
            .map(|d| (d.name.clone(), d.default.clone()))
            .collect()
    }

    /// Check a declaration set for mistakes an author can make: duplicate names and defaults
    /// that fail their own declaration. Returns every problem found.
    pub fn self_check(&self) -> Vec<String> {
        let mut problems = Vec::new();
        for (i, d) in self.params.iter().enumerate() {
            if self.params[..i].iter().any(|o| o.name == d.name) {
                problems.push(format!("parameter {:?} is declared twice", d.name));
            }
            if let Err(r) = d.check(&d.name, &d.default) {
                problems.push(format!("default of {r}"));
            }
        }
        problems
    }

    /// Validate an update against this schema, all or nothing.
    ///
    /// `current` is the full current set; `update` the values to change. With
    /// `allow_read_only` (start-up configuration) read-only parameters may be set. On success
    /// returns the new full set; otherwise every rejected value with its reason, and nothing
    /// changes.
    pub fn apply(
        &self,
        current: &ParamMap,
        update: &ParamMap,
        allow_read_only: bool,
    ) -> Result<ParamMap, Vec<Rejection>> {
        let mut next = current.clone();
        let mut rejected = Vec::new();
        for (name, value) in update {
            let Some(decl) = self.get(name) else {
                rejected.push(Rejection::new(name, RejectReason::UnknownName));
                continue;
            };
            if decl.read_only && !allow_read_only {
                rejected.push(Rejection::new(name, RejectReason::ReadOnly));
                continue;
            }
            match decl.check(name, value) {
                Ok(v) => {
                    next.insert(name.clone(), v);
                }
                Err(r) => rejected.push(r),
            }
        }
        if rejected.is_empty() {
            Ok(next)
        } else {
            Err(rejected)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::property::value::param_map;

    fn schema() -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("distance", 0.5).range(0.1, 2.0).unit("m"),
            ParamDecl::int("count", 4).range(0.0, 100.0).step(2.0),
            ParamDecl::choice("mode", &["wall", "corridor"], "wall"),
            ParamDecl::int("serial", 7).read_only(),
            ParamDecl::new(
                "pose",
                ParamType::Struct(vec![
                    ParamDecl::float("x", 0.0).range(-10.0, 10.0),
                    ParamDecl::float("y", 0.0),
                ]),
                Value::Struct(
                    [
                        ("x".to_string(), Value::Float(0.0)),
                        ("y".into(), Value::Float(0.0)),
                    ]
                    .into(),
                ),
            ),
            ParamDecl::new(
                "gains",
                ParamType::Array {
                    item: Box::new(ParamDecl::float("item", 1.0).range(0.0, 5.0)),
                    min_len: 1,
                    max_len: 3,
                },
                Value::Array(vec![Value::Float(1.0)]),
            ),
        ])
    }

    #[test]
    fn defaults_pass_their_own_declaration() {
        assert!(
            schema().self_check().is_empty(),
            "{:?}",
            schema().self_check()
        );
    }

    #[test]
    fn apply_is_all_or_nothing_with_a_reason_per_value() {
        let s = schema();
        let cur = s.defaults();
        let upd = param_map([
            ("distance", Value::Float(1.0)),
            ("count", Value::Int(3)),
            ("nope", Value::Bool(true)),
            ("serial", Value::Int(1)),
            ("mode", Value::Text("hall".into())),
        ]);
        let err = s.apply(&cur, &upd, false).unwrap_err();
        let names: Vec<_> = err.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, vec!["count", "mode", "nope", "serial"]);
        assert!(matches!(err[0].reason, RejectReason::OffStep { .. }));
        assert!(matches!(err[2].reason, RejectReason::UnknownName));
        assert!(matches!(err[3].reason, RejectReason::ReadOnly));
    }

    #[test]
    fn nested_values_are_checked_by_path() {
        let s = schema();
        let bad = param_map([(
            "pose",
            Value::Struct([("x".to_string(), Value::Float(11.0))].into()),
        )]);
        let err = s.apply(&s.defaults(), &bad, false).unwrap_err();
        assert_eq!(err[0].name, "pose.x");
        let bad = param_map([(
            "gains",
            Value::Array(vec![Value::Int(1), Value::Float(9.0)]),
        )]);
        let err = s.apply(&s.defaults(), &bad, false).unwrap_err();
        assert_eq!(err[0].name, "gains[1]");
        let ok = param_map([("distance", Value::Int(1))]);
        let next = s.apply(&s.defaults(), &ok, false).unwrap();
        assert_eq!(next["distance"], Value::Float(1.0));
    }
}

//! Parameter migrations: how a parameter of an operation's older versions maps onto this
//! version's, so a binding can move to a newer version at an action boundary (issue 44)
//! with the parameters a mission wrote for the older one.
//!
//! Two changes between versions touch a mission's parameters:
//!
//! - **A rename** (`distance` → `wall_distance`) is declared: [`Migrations::rename`]. A
//!   supplied parameter this version does not declare, but declares a rename of, is sent
//!   under its new name — at a move, at a rebind, at the start. A rename without a
//!   declaration leaves the old name unknown to the new schema: the newer version cannot
//!   take the mission, so a binding does not move to it (`binding_upgrade_refused`) and
//!   `marie check` refuses the mission.
//! - **A range change** needs no declaration: the new schema's range decides. A supplied
//!   value outside it is *refused*, never clamped. Clamping would run the robot with a value
//!   nobody wrote (a wall distance of 2.8 m quietly become 2.5 m), mid-mission, on the
//!   strength of a version the mission's author never saw; refused, the operator hears of
//!   it at `marie check` — before anything runs — and at run time the binding simply stays
//!   on the version that takes the value.
//!
//! An operation declares its migrations with [`Operation::migrations`]; its host answers
//! them through the property interface (`Get("migrations")`, [`Migrations::PROPERTY`]), so
//! a dispatcher of another build learns them from the instance itself. A build that does not
//! know the property answers `NotFound`: no migrations.
//!
//! [`Operation::migrations`]: crate::eo::Operation::migrations
//!
//! ```
//! use marie_actors::declare::Migrations;
//! use marie_vocabulary::property::{param_map, ParamDecl, ParamSchema, Value};
//!
//! let schema = ParamSchema::new(vec![ParamDecl::float("wall_distance", 0.6)]);
//! let migrations = Migrations::new().rename("distance", "wall_distance");
//! let sent = migrations.apply(&param_map([("distance", Value::Float(0.8))]), &schema);
//! assert_eq!(sent, param_map([("wall_distance", Value::Float(0.8))]));
//! ```

use marie_vocabulary::property::{ParamMap, ParamSchema, Value};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A parameter an older version called `from`, called `to` in this one.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rename {
    /// Its name in older versions.
    pub from: String,
    /// Its name in this version.
    pub to: String,
}

/// How parameters of an operation's older versions map onto this version's.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Migrations {
    /// The renames, in declaration order.
    pub renames: Vec<Rename>,
}

/// Why a [`Migrations`] value read from an instance is not one.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the `migrations` property is not a list of renames {{from, to}}: {0}")]
pub struct MigrationsError(String);

impl Migrations {
    /// The property an operation's host answers its migrations under.
    pub const PROPERTY: &'static str = "migrations";

    /// No migrations.
    pub fn new() -> Self {
        Migrations::default()
    }

    /// With parameter `from` of older versions renamed `to` in this one.
    pub fn rename(mut self, from: impl Into<String>, to: impl Into<String>) -> Self {
        self.renames.push(Rename {
            from: from.into(),
            to: to.into(),
        });
        self
    }

    /// True when nothing is declared.
    pub fn is_empty(&self) -> bool {
        self.renames.is_empty()
    }

    /// `supplied` (parameters written for an older or for this version) as this version,
    /// declared by `schema`, takes them: a name the schema does not declare but a rename
    /// maps is sent under its new name; every other name as it is (an unknown one is then
    /// refused by the schema, as before). A value supplied under both names keeps the new
    /// name's.
    pub fn apply(&self, supplied: &ParamMap, schema: &ParamSchema) -> ParamMap {
        let mut out = ParamMap::new();
        let mut renamed = Vec::new();
        for (name, value) in supplied {
            let to = self
                .renames
                .iter()
                .find(|r| r.from == *name && schema.get(name).is_none());
            match to {
                Some(r) => renamed.push((r.to.clone(), value.clone())),
                None => {
                    out.insert(name.clone(), value.clone());
                }
            }
        }
        for (name, value) in renamed {
            out.entry(name).or_insert(value);
        }
        out
    }

    /// What is wrong with these migrations for an operation declaring `schema`: a rename
    /// to a parameter it does not declare, from one it still declares, or of one name twice.
    pub fn problems(&self, schema: &ParamSchema) -> Vec<String> {
        let mut problems = Vec::new();
        for (i, r) in self.renames.iter().enumerate() {
            if schema.get(&r.to).is_none() {
                problems.push(format!(
                    "migration renames `{}` to `{}`, which it does not declare",
                    r.from, r.to
                ));
            }
            if schema.get(&r.from).is_some() {
                problems.push(format!(
                    "migration renames `{}`, which it still declares",
                    r.from
                ));
            }
            if self.renames[..i].iter().any(|o| o.from == r.from) {
                problems.push(format!("migration renames `{}` twice", r.from));
            }
        }
        problems
    }

    /// As the property interface carries it: a list of `{from, to}` structs.
    pub fn to_value(&self) -> Value {
        Value::Array(
            self.renames
                .iter()
                .map(|r| {
                    Value::Struct(BTreeMap::from([
                        ("from".to_string(), Value::Text(r.from.clone())),
                        ("to".to_string(), Value::Text(r.to.clone())),
                    ]))
                })
                .collect(),
        )
    }

    /// Read back what [`Migrations::to_value`] made.
    pub fn from_value(value: &Value) -> Result<Self, MigrationsError> {
        let Value::Array(items) = value else {
            return Err(MigrationsError(format!("a {}", value.kind())));
        };
        let mut out = Migrations::new();
        for item in items {
            let text = |key: &str| match item {
                Value::Struct(fields) => match fields.get(key) {
                    Some(Value::Text(t)) => Ok(t.clone()),
                    _ => Err(MigrationsError(format!("an item without a text `{key}`"))),
                },
                other => Err(MigrationsError(format!(
                    "an item that is a {}",
                    other.kind()
                ))),
            };
            out = out.rename(text("from")?, text("to")?);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::property::{param_map, ParamDecl};

    fn v1_1() -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("wall_distance", 0.6).range(0.3, 2.5),
            ParamDecl::float("speed", 0.3),
        ])
    }

    #[test]
    fn a_declared_rename_maps_an_old_name_and_leaves_new_and_unknown_names() {
        let m = Migrations::new().rename("distance", "wall_distance");
        let old = param_map([
            ("distance", Value::Float(0.8)),
            ("speed", Value::Float(0.2)),
        ]);
        assert_eq!(
            m.apply(&old, &v1_1()),
            param_map([
                ("wall_distance", Value::Float(0.8)),
                ("speed", Value::Float(0.2))
            ])
        );
        // written for this version already: nothing to map
        let new = param_map([("wall_distance", Value::Float(0.9))]);
        assert_eq!(m.apply(&new, &v1_1()), new);
        // both: the new name's value wins
        let both = param_map([
            ("distance", Value::Float(0.8)),
            ("wall_distance", Value::Float(0.9)),
        ]);
        assert_eq!(m.apply(&both, &v1_1()), new);
        // without the migration the old name stays, for the schema to refuse
        let none = Migrations::new().apply(&old, &v1_1());
        assert!(none.contains_key("distance"));
        assert!(v1_1().apply(&v1_1().defaults(), &none, false).is_err());
        // a value out of the new range is not clamped: the schema refuses it
        let far = m.apply(&param_map([("distance", Value::Float(2.8))]), &v1_1());
        assert_eq!(far, param_map([("wall_distance", Value::Float(2.8))]));
        assert!(v1_1().apply(&v1_1().defaults(), &far, false).is_err());
    }

    #[test]
    fn migrations_travel_as_a_property_value_and_a_bad_one_is_refused() {
        let m = Migrations::new()
            .rename("distance", "wall_distance")
            .rename("v", "speed");
        assert_eq!(Migrations::from_value(&m.to_value()), Ok(m));
        assert_eq!(
            Migrations::from_value(&Value::Array(vec![])),
            Ok(Migrations::new())
        );
        assert!(Migrations::from_value(&Value::Int(3)).is_err());
        assert!(Migrations::from_value(&Value::Array(vec![Value::Int(3)])).is_err());
    }

    #[test]
    fn a_rename_to_an_undeclared_or_from_a_still_declared_parameter_is_a_problem() {
        let bad = Migrations::new()
            .rename("distance", "gap")
            .rename("speed", "wall_distance")
            .rename("distance", "wall_distance");
        let problems = bad.problems(&v1_1()).join("\n");
        for want in [
            "renames `distance` to `gap`, which it does not declare",
            "renames `speed`, which it still declares",
            "renames `distance` twice",
        ] {
            assert!(problems.contains(want), "{want:?} not in:\n{problems}");
        }
        let good = Migrations::new().rename("distance", "wall_distance");
        assert!(good.problems(&v1_1()).is_empty());
    }
}

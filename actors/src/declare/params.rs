//! Typed parameters: one declaration gives the schema, the defaults, a typed read and a key
//! per parameter.
//!
//! [`params!`](crate::params) declares a struct whose fields are an operation's parameters;
//! [`DeclaredParams`] is what it implements. Each parameter's Rust type decides its
//! [`ParamType`](marie_vocabulary::property::ParamType) through [`ParamValue`]: `f64` is a float, `i64`
//! an int, `bool` a bool, `String` text, and an enum declared with
//! [`choice!`](crate::choice) a choice among its words. A [`Param<T>`] names one parameter
//! with its type, so code that sets or reads one value (a mission builder, a client) cannot
//! misspell the name or give a value of the wrong type.

use marie_vocabulary::property::{FromValue, ParamDecl, ParamMap, ParamSchema, Value};
use std::fmt;
use std::marker::PhantomData;

/// A Rust type a parameter can have: how it is declared and how it converts to a [`Value`]
/// (and, as every [`FromValue`], from one).
///
/// Implemented for `f64`, `i64`, `bool`, `String`, and for every enum declared with
/// [`choice!`](crate::choice).
///
/// ```
/// use marie_actors::declare::ParamValue;
/// use marie_vocabulary::property::{FromValue, ParamDecl, Value};
/// assert_eq!(<f64 as ParamValue>::decl("gain", 0.5), ParamDecl::float("gain", 0.5));
/// assert_eq!(i64::from_value(&Value::Int(3)), Some(3));
/// assert_eq!(f64::from_value(&Value::Int(3)), Some(3.0)); // ints convert to floats
/// assert_eq!(bool::from_value(&Value::Int(3)), None);
/// assert_eq!("wall".to_string().into_value(), Value::Text("wall".into()));
/// ```
pub trait ParamValue: FromValue {
    /// The declaration of a parameter `name` of this type defaulting to `default`, without
    /// range, unit or description.
    fn decl(name: &str, default: Self) -> ParamDecl;

    /// This value as a [`Value`].
    fn into_value(self) -> Value;

    /// Why `value`, which [`FromValue::from_value`] refused, is not one of this type.
    fn mismatch(value: &Value) -> String {
        format!("expected {}, found {}", Self::EXPECTED, value.kind())
    }
}

impl ParamValue for f64 {
    fn decl(name: &str, default: f64) -> ParamDecl {
        ParamDecl::float(name, default)
    }
    fn into_value(self) -> Value {
        Value::Float(self)
    }
}

impl ParamValue for i64 {
    fn decl(name: &str, default: i64) -> ParamDecl {
        ParamDecl::int(name, default)
    }
    fn into_value(self) -> Value {
        Value::Int(self)
    }
}

impl ParamValue for bool {
    fn decl(name: &str, default: bool) -> ParamDecl {
        ParamDecl::bool(name, default)
    }
    fn into_value(self) -> Value {
        Value::Bool(self)
    }
}

impl ParamValue for String {
    fn decl(name: &str, default: String) -> ParamDecl {
        ParamDecl::text(name, default)
    }
    fn into_value(self) -> Value {
        Value::Text(self)
    }
}

/// A value that can be given for a parameter of type `T`: a `T` itself, or a `&str` for a
/// `String`.
///
/// It is a trait of its own, not `Into<T>`, so that an integer literal given for an `i64`
/// parameter is an `i64` (with `Into` it would be an `i32`, and `1_000_000_000_000` would not
/// compile).
///
/// ```
/// use marie_actors::declare::IntoParam;
/// let n: i64 = 1_000_000_000_000.into_param();
/// let s: String = "wall".into_param();
/// assert_eq!((n, s.as_str()), (1_000_000_000_000, "wall"));
/// ```
pub trait IntoParam<T> {
    /// The value as a `T`.
    fn into_param(self) -> T;
}

impl<T: ParamValue> IntoParam<T> for T {
    fn into_param(self) -> T {
        self
    }
}

impl IntoParam<String> for &str {
    fn into_param(self) -> String {
        self.to_string()
    }
}

/// A value that did not have the type its parameter declares (or was missing): the
/// parameter's name and what was wrong. An operation's `?` turns it into
/// [`OpError::Param`](crate::eo::OpError::Param).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("parameter {name}: {problem}")]
pub struct ParamError {
    /// The parameter's name.
    pub name: String,
    /// What is wrong, e.g. `expected int, found text`.
    pub problem: String,
}

/// The typed name of one parameter: its name and, in the type, the Rust type of its value.
///
/// [`params!`](crate::params) gives one per field as an associated function of the same
/// name (`CollatzParams::start()`); it can also be made by hand for an operation declared
/// the old way.
///
/// ```
/// use marie_actors::declare::{Param, ParamMapExt};
/// use marie_vocabulary::property::{ParamMap, Value};
///
/// const START: Param<i64> = Param::new("start");
/// let update = ParamMap::new().with(START, 97);
/// assert_eq!(update["start"], Value::Int(97));
/// assert_eq!(START.decode(&update["start"]), Ok(97));
/// assert!(START.decode(&Value::Text("97".into())).is_err());
/// // START.pair(97.5) does not compile: the value must be an i64
/// ```
pub struct Param<T> {
    name: &'static str,
    ty: PhantomData<fn() -> T>,
}

impl<T> Param<T> {
    /// The key of parameter `name` with values of type `T`.
    pub const fn new(name: &'static str) -> Param<T> {
        Param {
            name,
            ty: PhantomData,
        }
    }

    /// The parameter's name.
    pub const fn name(&self) -> &'static str {
        self.name
    }
}

impl<T: ParamValue> Param<T> {
    /// `value` as this parameter's value, or why it is not one.
    pub fn decode(&self, value: &Value) -> Result<T, ParamError> {
        T::from_value(value).ok_or_else(|| ParamError {
            name: self.name.to_string(),
            problem: T::mismatch(value),
        })
    }

    /// This parameter's value in `map`, or why there is none of its type.
    pub fn read(&self, map: &ParamMap) -> Result<T, ParamError> {
        match map.get(self.name) {
            Some(v) => self.decode(v),
            None => Err(ParamError {
                name: self.name.to_string(),
                problem: "not declared".to_string(),
            }),
        }
    }

    /// The name and `value` as a pair for [`marie_vocabulary::property::param_map`].
    pub fn pair(&self, value: impl IntoParam<T>) -> (&'static str, Value) {
        (self.name, value.into_param().into_value())
    }
}

// By hand: derives would demand `T: Clone` etc. of the phantom type.
impl<T> Clone for Param<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Param<T> {}
impl<T> PartialEq for Param<T> {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}
impl<T> Eq for Param<T> {}
impl<T> fmt::Debug for Param<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Param<{}>({:?})", std::any::type_name::<T>(), self.name)
    }
}

/// Typed building of a [`ParamMap`] (an update, a mission's values): `.with(key, value)`.
///
/// ```
/// use marie_actors::declare::{Param, ParamMapExt};
/// use marie_vocabulary::property::{param_map, ParamMap, Value};
///
/// const GAIN: Param<f64> = Param::new("gain");
/// const MODE: Param<String> = Param::new("mode");
/// let mut update = ParamMap::new().with(GAIN, 0.5).with(MODE, "wall");
/// update.set(GAIN, 0.25);
/// assert_eq!(update, param_map([("gain", Value::Float(0.25)), ("mode", "wall".into())]));
/// ```
pub trait ParamMapExt: Sized {
    /// The map with `key` set to `value`.
    fn with<T: ParamValue>(self, key: Param<T>, value: impl IntoParam<T>) -> Self;

    /// Set `key` to `value`.
    fn set<T: ParamValue>(&mut self, key: Param<T>, value: impl IntoParam<T>);
}

impl ParamMapExt for ParamMap {
    fn with<T: ParamValue>(mut self, key: Param<T>, value: impl IntoParam<T>) -> Self {
        self.set(key, value);
        self
    }

    fn set<T: ParamValue>(&mut self, key: Param<T>, value: impl IntoParam<T>) {
        self.insert(key.name.to_string(), value.into_param().into_value());
    }
}

/// A set of parameters declared once, as a struct: its schema, its defaults (`Default`), and
/// a typed read of an operation's current values. [`params!`](crate::params) implements it.
///
/// ```
/// use marie_actors::declare::DeclaredParams;
/// use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
///
/// marie_actors::params! {
///     /// How far to walk.
///     pub struct Walk {
///         /// metres to go
///         pub distance: f64 = 1.5, range(0.0, 10.0), unit("m");
///     }
/// }
/// assert_eq!(
///     Walk::schema(),
///     ParamSchema::new(vec![ParamDecl::float("distance", 1.5)
///         .range(0.0, 10.0)
///         .unit("m")
///         .describe("metres to go")]),
/// );
/// let map = Walk { distance: 2.0 }.to_map();
/// assert_eq!(map["distance"], Value::Float(2.0));
/// assert_eq!(Walk::from_map(&map), Ok(Walk { distance: 2.0 }));
/// ```
pub trait DeclaredParams: Default {
    /// The declarations, in field order: what [`crate::eo::Operation::parameters`] returns.
    fn schema() -> ParamSchema;

    /// The parameters from a full set of values (an operation's current ones); an error
    /// names the first parameter that is missing or of another type.
    fn from_map(map: &ParamMap) -> Result<Self, ParamError>;

    /// Every parameter's value, by name: a full update.
    fn to_map(&self) -> ParamMap;
}

/// A number a [`params!`](crate::params) `range` or `step` accepts: a float or an int (an
/// integer literal is an `i64` here, so a large one compiles).
#[doc(hidden)]
pub trait Bound {
    /// The number as a bound of a declaration.
    fn bound(self) -> f64;
}

impl Bound for f64 {
    fn bound(self) -> f64 {
        self
    }
}

impl Bound for i64 {
    fn bound(self) -> f64 {
        self as f64
    }
}

/// Declare an operation's parameters as a struct.
///
/// ```text
/// params! {
///     /// doc of the struct
///     pub struct Name {
///         /// description (the doc comment becomes the declaration's description)
///         pub field: Type = default, option, option(args), ...;
///         ...
///     }
/// }
/// ```
///
/// Each field is one parameter, named as the field, of the field's type ([`ParamValue`]:
/// `f64`, `i64`, `bool`, `String`, or an enum from [`choice!`](crate::choice)), with the
/// default after `=` (a `&str` is fine for a `String`). The options that may follow are the
/// builder methods of [`ParamDecl`]: `range(min, max)`, `step(s)` (numbers, ints or floats),
/// `unit("m")`, `describe("...")` (instead of the doc comment), `read_only`.
///
/// It generates the struct (deriving `Clone`, `Debug`, `PartialEq`; add others with
/// attributes), `Default` with the declared defaults, [`DeclaredParams`], and per field an
/// associated function of the field's name returning its [`Param`] key.
///
/// ```
/// use marie_actors::declare::{DeclaredParams, ParamMapExt};
/// use marie_vocabulary::property::{ParamDecl, ParamMap, ParamSchema};
///
/// marie_actors::choice! {
///     /// What to follow.
///     pub enum Follow { Wall = "wall", Corridor = "corridor" }
/// }
///
/// marie_actors::params! {
///     /// The wall follower's parameters.
///     pub struct FollowParams {
///         /// distance to keep
///         pub distance: f64 = 0.5, range(0.1, 2.0), unit("m");
///         /// sonar readings per decision
///         pub readings: i64 = 4, range(1, 16), step(1);
///         pub follow: Follow = Follow::Wall, describe("wall or corridor");
///         /// log each decision
///         pub verbose: bool = false;
///         pub label: String = "left", read_only;
///     }
/// }
///
/// assert_eq!(
///     FollowParams::schema(),
///     ParamSchema::new(vec![
///         ParamDecl::float("distance", 0.5).range(0.1, 2.0).unit("m").describe("distance to keep"),
///         ParamDecl::int("readings", 4).range(1.0, 16.0).step(1.0).describe("sonar readings per decision"),
///         ParamDecl::choice("follow", &["wall", "corridor"], "wall").describe("wall or corridor"),
///         ParamDecl::bool("verbose", false).describe("log each decision"),
///         ParamDecl::text("label", "left").read_only(),
///     ]),
/// );
/// assert_eq!(FollowParams::default().readings, 4);
/// assert_eq!(FollowParams::distance().name(), "distance");
/// let update = ParamMap::new().with(FollowParams::follow(), Follow::Corridor);
/// assert_eq!(update["follow"], "corridor".into());
/// ```
///
/// A misspelt parameter is a compile error, not a failure when the operation runs:
///
/// ```compile_fail
/// marie_actors::params! {
///     pub struct P {
///         /// first number
///         pub start: i64 = 27;
///     }
/// }
/// let _ = P::strat();
/// ```
///
/// So is a value of the wrong type:
///
/// ```compile_fail
/// use marie_actors::declare::ParamMapExt;
/// marie_actors::params! {
///     pub struct P {
///         /// first number
///         pub start: i64 = 27;
///     }
/// }
/// let _ = marie_vocabulary::property::ParamMap::new().with(P::start(), "27");
/// ```
#[macro_export]
macro_rules! params {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $fvis:vis $field:ident : $ty:ty = $default:expr
                    $(, $opt:ident $(( $($arg:expr),* $(,)? ))?)* ;
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq)]
        $vis struct $name {
            $(
                $(#[doc = $doc])*
                $fvis $field: $ty,
            )*
        }

        impl ::core::default::Default for $name {
            fn default() -> Self {
                $name {
                    $(
                        $field: $crate::declare::IntoParam::<$ty>::into_param($default),
                    )*
                }
            }
        }

        impl $name {
            $(
                #[doc = ::core::concat!("The key of parameter `", ::core::stringify!($field), "`.")]
                #[allow(dead_code)]
                $vis const fn $field() -> $crate::declare::Param<$ty> {
                    $crate::declare::Param::new(::core::stringify!($field))
                }
            )*
        }

        impl $crate::declare::DeclaredParams for $name {
            fn schema() -> $crate::__private::property::ParamSchema {
                let defaults = <$name as ::core::default::Default>::default();
                $crate::__private::property::ParamSchema::new(::std::vec![
                    $({
                        let decl = <$ty as $crate::declare::ParamValue>::decl(
                            ::core::stringify!($field),
                            defaults.$field,
                        )
                        .describe(::core::concat!($($doc),*).trim_ascii());
                        $(
                            let decl = $crate::__param_option!(decl, $opt $(( $($arg),* ))?);
                        )*
                        decl
                    },)*
                ])
            }

            fn from_map(
                map: &$crate::__private::property::ParamMap,
            ) -> ::core::result::Result<Self, $crate::declare::ParamError> {
                ::core::result::Result::Ok($name {
                    $(
                        $field: $crate::declare::Param::<$ty>::new(::core::stringify!($field))
                            .read(map)?,
                    )*
                })
            }

            fn to_map(&self) -> $crate::__private::property::ParamMap {
                let mut map = $crate::__private::property::ParamMap::new();
                $(
                    map.insert(
                        ::core::stringify!($field).to_string(),
                        $crate::declare::ParamValue::into_value(
                            ::core::clone::Clone::clone(&self.$field),
                        ),
                    );
                )*
                map
            }
        }
    };
}

/// One option of a [`params!`](crate::params) field, applied to its declaration.
#[doc(hidden)]
#[macro_export]
macro_rules! __param_option {
    ($decl:ident, range($min:expr, $max:expr)) => {
        $decl.range(
            $crate::declare::Bound::bound($min),
            $crate::declare::Bound::bound($max),
        )
    };
    ($decl:ident, step($step:expr)) => {
        $decl.step($crate::declare::Bound::bound($step))
    };
    ($decl:ident, $method:ident $(( $($arg:expr),* ))?) => {
        $decl.$method($($($arg),*)?)
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eo::{OpError, Params};
    use marie_vocabulary::property::{param_map, ParamType};

    crate::choice! {
        /// Test choice.
        enum Beams { Narrow = "narrow", All = "all" }
    }

    crate::params! {
        /// The segment extractor's parameters, as `missions` declares them by hand.
        struct Extract {
            /// how far back echoes are used
            pub window: f64 = 8.0, range(0.5, 120.0), unit("s");
            /// fewest echoes a segment needs
            pub min_points: i64 = 4, range(2, 1000);
            /// which sonar beams to fit: a wide beam's echo is placed on its axis, so its
            /// points sit nearer than the wall they came from
            pub beams: Beams = Beams::Narrow;
            /// only echoes heard since this activation
            pub fresh: bool = false;
            pub label: String = "seg", read_only, describe("a name");
        }
    }

    fn by_hand() -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("window", 8.0)
                .range(0.5, 120.0)
                .unit("s")
                .describe("how far back echoes are used"),
            ParamDecl::int("min_points", 4)
                .range(2.0, 1000.0)
                .describe("fewest echoes a segment needs"),
            ParamDecl::choice("beams", &["narrow", "all"], "narrow").describe(
                "which sonar beams to fit: a wide beam's echo is placed on its axis, so its \
                 points sit nearer than the wall they came from",
            ),
            ParamDecl::bool("fresh", false).describe("only echoes heard since this activation"),
            ParamDecl::text("label", "seg")
                .read_only()
                .describe("a name"),
        ])
    }

    #[test]
    fn the_declared_schema_is_the_hand_built_one() {
        assert_eq!(Extract::schema(), by_hand());
        assert!(Extract::schema().self_check().is_empty());
        assert_eq!(
            Extract::schema().get("beams").map(|d| &d.ty),
            Some(&ParamType::Choice(vec!["narrow".into(), "all".into()]))
        );
    }

    #[test]
    fn defaults_are_the_declared_ones_and_round_trip() {
        let d = Extract::default();
        assert_eq!(
            (d.window, d.min_points, d.beams, d.fresh, d.label.as_str()),
            (8.0, 4, Beams::Narrow, false, "seg")
        );
        assert_eq!(d.to_map(), by_hand().defaults());
        assert_eq!(Extract::from_map(&by_hand().defaults()), Ok(d));
    }

    #[test]
    fn a_typed_read_names_the_missing_or_mistyped_parameter() {
        let schema = by_hand();
        let mut values = schema.defaults();
        values.remove("fresh");
        let err = Params::new(values).read::<Extract>().unwrap_err();
        assert_eq!(
            err,
            OpError::Param {
                name: "fresh".into(),
                problem: "not declared".into()
            }
        );
        let values = schema
            .defaults()
            .with(Param::<String>::new("min_points"), "4");
        let err = Params::new(values).read::<Extract>().unwrap_err();
        assert_eq!(
            err.to_string(),
            "parameter min_points: expected int, found text"
        );
        let values = schema
            .defaults()
            .with(Param::<String>::new("beams"), "both");
        let err = Params::new(values).read::<Extract>().unwrap_err();
        assert_eq!(
            err.to_string(),
            "parameter beams: expected one of narrow|all, found \"both\""
        );
    }

    #[test]
    fn keys_name_their_parameter_and_check_the_value_type() {
        assert_eq!(Extract::min_points().name(), "min_points");
        let update = ParamMap::new()
            .with(Extract::window(), 2.5)
            .with(Extract::min_points(), 1_000_000_000_000)
            .with(Extract::beams(), Beams::All)
            .with(Extract::label(), "x");
        assert_eq!(
            update,
            param_map([
                ("window", Value::Float(2.5)),
                ("min_points", Value::Int(1_000_000_000_000)),
                ("beams", Value::Text("all".into())),
                ("label", Value::Text("x".into())),
            ])
        );
        assert_eq!(
            param_map([Extract::fresh().pair(true)]),
            param_map([("fresh", Value::Bool(true))])
        );
        // the host checks the values against the declaration, which the key's type matches
        let rejected = by_hand().apply(&by_hand().defaults(), &update, true);
        assert_eq!(rejected.unwrap_err()[0].name, "min_points"); // out of range
        let update = update.with(Extract::min_points(), 12);
        let current = by_hand()
            .apply(&by_hand().defaults(), &update, true)
            .unwrap();
        let p = Params::new(current);
        assert_eq!(p.value(Extract::min_points()), Ok(12));
        assert_eq!(p.value(Extract::beams()), Ok(Beams::All));
        assert_eq!(p.value(Extract::window()), Ok(2.5));
    }
}

//! Reading a [`Value`] as a Rust type.
//!
//! Properties and parameter values travel as [`Value`]s (a small tree: the property interface
//! must carry any declared type across nodes). Code that knows which type it expects — an
//! embedder reading a parameter through `marie_actors::eo::OperationHandle::value` — wants that
//! type back, or an error saying what came instead. [`FromValue`] is that one conversion, in
//! one place, with the name of the expected type for the error.
//!
//! ```
//! use marie_vocabulary::property::{FromValue, Value};
//! assert_eq!(f64::from_value(&Value::Int(2)), Some(2.0)); // integers widen to floats
//! assert_eq!(i64::from_value(&Value::Float(2.0)), None); // floats never narrow
//! assert_eq!(String::from_value(&Value::Text("wall".into())), Some("wall".to_string()));
//! assert_eq!(<Vec<bool>>::from_value(&Value::Array(vec![true.into()])), Some(vec![true]));
//! ```

use super::value::Value;

/// A type a [`Value`] can be read as.
///
/// Implemented for `f64` (a float, or an integer, converted), `i64`, `bool`, `String` (text,
/// also choices), `Vec<T>` (an array whose every element reads as `T`) and [`Value`] itself.
/// Implement it for a type of your own to read a struct parameter as that type:
///
/// ```
/// use marie_vocabulary::property::{FromValue, Value};
///
/// #[derive(Debug, PartialEq)]
/// struct Point { x: f64, y: f64 }
///
/// impl FromValue for Point {
///     const EXPECTED: &'static str = "a point {x, y}";
///     fn from_value(value: &Value) -> Option<Point> {
///         let fields = value.as_struct()?;
///         Some(Point { x: f64::from_value(fields.get("x")?)?, y: f64::from_value(fields.get("y")?)? })
///     }
/// }
///
/// let v = Value::Struct([("x".to_string(), 1.0.into()), ("y".to_string(), 2.0.into())].into());
/// assert_eq!(Point::from_value(&v), Some(Point { x: 1.0, y: 2.0 }));
/// ```
pub trait FromValue: Sized {
    /// What the type is called in an error about a value that is not one (`"float"`,
    /// `"text"`, ...).
    ///
    /// ```
    /// use marie_vocabulary::property::FromValue;
    /// assert_eq!(<f64 as FromValue>::EXPECTED, "float");
    /// ```
    const EXPECTED: &'static str;

    /// The value as `Self`, or `None` if it is of another kind.
    ///
    /// ```
    /// use marie_vocabulary::property::{FromValue, Value};
    /// assert_eq!(bool::from_value(&Value::Bool(true)), Some(true));
    /// assert_eq!(bool::from_value(&Value::Text("yes".into())), None);
    /// ```
    fn from_value(value: &Value) -> Option<Self>;
}

impl FromValue for f64 {
    const EXPECTED: &'static str = "float";
    fn from_value(value: &Value) -> Option<f64> {
        value.as_f64()
    }
}

impl FromValue for i64 {
    const EXPECTED: &'static str = "int";
    fn from_value(value: &Value) -> Option<i64> {
        value.as_i64()
    }
}

impl FromValue for bool {
    const EXPECTED: &'static str = "bool";
    fn from_value(value: &Value) -> Option<bool> {
        value.as_bool()
    }
}

impl FromValue for String {
    const EXPECTED: &'static str = "text";
    fn from_value(value: &Value) -> Option<String> {
        value.as_str().map(str::to_string)
    }
}

impl FromValue for Value {
    const EXPECTED: &'static str = "any value";
    fn from_value(value: &Value) -> Option<Value> {
        Some(value.clone())
    }
}

impl<T: FromValue> FromValue for Vec<T> {
    const EXPECTED: &'static str = "array";
    fn from_value(value: &Value) -> Option<Vec<T>> {
        value.as_array()?.iter().map(T::from_value).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_type_reads_its_own_kind_only() {
        assert_eq!(f64::from_value(&Value::Float(0.5)), Some(0.5));
        assert_eq!(f64::from_value(&Value::Text("0.5".into())), None);
        assert_eq!(i64::from_value(&Value::Int(-3)), Some(-3));
        assert_eq!(bool::from_value(&Value::Bool(true)), Some(true));
        assert_eq!(bool::from_value(&Value::Int(1)), None);
        assert_eq!(String::from_value(&Value::Bool(true)), None);
        assert_eq!(
            <Vec<i64>>::from_value(&Value::Array(vec![Value::Int(1), Value::Float(2.0)])),
            None,
            "one element of another kind refuses the array"
        );
        assert_eq!(
            Value::from_value(&Value::Int(7)),
            Some(Value::Int(7)),
            "a Value reads as itself"
        );
    }
}

//! The shape of a MessagePack value: its kind at every place and the keys of its maps,
//! which is what an older peer's decoder relies on.
//!
//! Read with serde's self-describing path (rmp-serde's `deserialize_any`), so no MessagePack
//! value crate is needed. [`breaks`] says where a newer encoding lost a key of an older one
//! or changed a kind.

use serde::de::{Deserializer, MapAccess, SeqAccess, Visitor};
use std::fmt;

/// A MessagePack value reduced to what compatibility depends on.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Shape {
    Nil,
    Bool,
    Int(i128),
    Float,
    Str(String),
    Bin(Vec<u8>),
    Array(Vec<Shape>),
    Map(Vec<(String, Shape)>),
}

impl Shape {
    /// Read the shape of MessagePack bytes.
    pub(crate) fn of(bytes: &[u8]) -> Result<Shape, String> {
        rmp_serde::from_slice(bytes).map_err(|e| format!("not MessagePack: {e}"))
    }

    /// The shape of a JSON document (a run report): the same kinds, JSON's numbers read as
    /// integers when they have no fraction.
    pub(crate) fn of_json(bytes: &[u8]) -> Result<Shape, String> {
        serde_json::from_slice(bytes).map_err(|e| format!("not JSON: {e}"))
    }

    /// The shape of an envelope frame, its payload read as a value in its place (the
    /// payload's fields are what the receiving node decodes).
    pub(crate) fn of_envelope(bytes: &[u8]) -> Result<Shape, String> {
        let mut shape = Shape::of(bytes)?;
        if let Shape::Map(entries) = &mut shape {
            for (key, value) in entries.iter_mut() {
                if let (true, Shape::Bin(payload)) = (key == "payload", &*value) {
                    *value = Shape::of(payload)?;
                }
            }
        }
        Ok(shape)
    }

    fn kind(&self) -> &'static str {
        match self {
            Shape::Nil => "nil",
            Shape::Bool => "bool",
            Shape::Int(_) => "integer",
            Shape::Float => "float",
            Shape::Str(_) => "string",
            Shape::Bin(_) => "binary",
            Shape::Array(_) => "array",
            Shape::Map(_) => "map",
        }
    }

    /// A map key as text (maps keyed by numbers keep their number).
    fn as_key(&self) -> String {
        match self {
            Shape::Str(s) => s.clone(),
            Shape::Int(n) => n.to_string(),
            other => format!("<{}>", other.kind()),
        }
    }
}

/// What an older encoding has that a newer one lost: a key gone (renamed or removed) or a
/// kind changed, each named by its path (`epoch`, `query.class`, `fences[0].epoch`).
pub(crate) fn breaks(old: &Shape, new: &Shape) -> Vec<String> {
    let mut out = Vec::new();
    walk(old, new, "", &mut out);
    out
}

/// What a newer encoding has that an older one has not: keys added.
pub(crate) fn additions(old: &Shape, new: &Shape) -> Vec<String> {
    let mut out = Vec::new();
    walk(new, old, "", &mut out);
    out.retain(|b| b.starts_with("field"));
    out.iter()
        .map(|b| b.replace(" is gone", " is new"))
        .collect()
}

fn walk(old: &Shape, new: &Shape, path: &str, out: &mut Vec<String>) {
    match (old, new) {
        // None then Some (or back) is one field, not a change of kind: serde reads both
        (Shape::Nil, _) | (_, Shape::Nil) => {}
        (Shape::Map(old), Shape::Map(new)) => {
            for (key, value) in old {
                let at = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                match new.iter().find(|(k, _)| k == key) {
                    Some((_, now)) => walk(value, now, &at, out),
                    None => out.push(format!("field `{at}` is gone")),
                }
            }
        }
        (Shape::Array(old), Shape::Array(new)) => {
            for (i, (a, b)) in old.iter().zip(new).enumerate() {
                walk(a, b, &format!("{path}[{i}]"), out);
            }
        }
        (a, b) if a.kind() != b.kind() => {
            let at = if path.is_empty() { "the value" } else { path };
            out.push(format!("`{at}` was {}, is now {}", a.kind(), b.kind()));
        }
        _ => {}
    }
}

impl<'de> serde::Deserialize<'de> for Shape {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Shape, D::Error> {
        d.deserialize_any(ShapeVisitor)
    }
}

struct ShapeVisitor;

impl<'de> Visitor<'de> for ShapeVisitor {
    type Value = Shape;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a MessagePack value")
    }
    fn visit_unit<E>(self) -> Result<Shape, E> {
        Ok(Shape::Nil)
    }
    fn visit_none<E>(self) -> Result<Shape, E> {
        Ok(Shape::Nil)
    }
    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Shape, D::Error> {
        d.deserialize_any(ShapeVisitor)
    }
    fn visit_bool<E>(self, _: bool) -> Result<Shape, E> {
        Ok(Shape::Bool)
    }
    fn visit_i64<E>(self, v: i64) -> Result<Shape, E> {
        Ok(Shape::Int(v.into()))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Shape, E> {
        Ok(Shape::Int(v.into()))
    }
    fn visit_f64<E>(self, _: f64) -> Result<Shape, E> {
        Ok(Shape::Float)
    }
    fn visit_str<E>(self, v: &str) -> Result<Shape, E> {
        Ok(Shape::Str(v.to_string()))
    }
    fn visit_bytes<E>(self, v: &[u8]) -> Result<Shape, E> {
        Ok(Shape::Bin(v.to_vec()))
    }
    fn visit_newtype_struct<D: Deserializer<'de>>(self, d: D) -> Result<Shape, D::Error> {
        // rmp-serde reads a MessagePack extension as a newtype of (type, bytes)
        d.deserialize_any(ShapeVisitor)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut a: A) -> Result<Shape, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = a.next_element::<Shape>()? {
            items.push(item);
        }
        Ok(Shape::Array(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut a: A) -> Result<Shape, A::Error> {
        let mut entries = Vec::new();
        while let Some((key, value)) = a.next_entry::<Shape, Shape>()? {
            entries.push((key.as_key(), value));
        }
        Ok(Shape::Map(entries))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Serialize;

    #[derive(Serialize)]
    struct Old {
        epoch: u64,
        name: String,
        tags: Vec<Inner>,
    }
    #[derive(Serialize)]
    struct Inner {
        seq: u64,
    }
    #[derive(Serialize)]
    struct New {
        epoch: String,
        title: String,
        tags: Vec<Inner2>,
        added: bool,
    }
    #[derive(Serialize)]
    struct Inner2 {
        sequence: u64,
    }

    #[test]
    fn a_renamed_a_retyped_and_a_nested_field_are_named() {
        let old = rmp_serde::to_vec_named(&Old {
            epoch: 1,
            name: "a".into(),
            tags: vec![Inner { seq: 1 }],
        })
        .unwrap();
        let new = rmp_serde::to_vec_named(&New {
            epoch: "1".into(),
            title: "a".into(),
            tags: vec![Inner2 { sequence: 1 }],
            added: true,
        })
        .unwrap();
        let (old, new) = (Shape::of(&old).unwrap(), Shape::of(&new).unwrap());
        assert_eq!(
            breaks(&old, &new),
            vec![
                "`epoch` was integer, is now string".to_string(),
                "field `name` is gone".into(),
                "field `tags[0].seq` is gone".into(),
            ]
        );
        assert!(additions(&old, &new).contains(&"field `added` is new".to_string()));
        assert!(breaks(&old, &old).is_empty());
    }
}

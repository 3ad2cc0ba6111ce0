//! [`Name`]: a record's class, sub-class or source, shared by every record that carries it.
//!
//! A datamanager keeps each name once (interned), and a select used to copy it into a fresh
//! `String` for each record it handed out — three allocations per record, freed again by the
//! reader a moment later: in a docking run, where operations look at the last seconds of
//! sonar scans at every step, that was about 7 % of all instructions. A [`Name`] is the
//! interned name itself (an `Arc<str>`): handing it out costs a reference count.
//!
//! It reads as the `&str` it holds (`Deref`, comparisons with `str`, `&str` and `String`,
//! `Display`), is made from either with `into()`, and travels as a plain string: the wire
//! format is that of a `String`.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::borrow::Borrow;
use std::fmt;
use std::ops::Deref;
use std::sync::Arc;

/// A class, sub-class or source name of a record, shared rather than copied.
#[derive(Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Name(Arc<str>);

impl Name {
    /// The name as a string slice.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The shared name a store keeps.
    pub(crate) fn shared(name: &Arc<str>) -> Name {
        Name(name.clone())
    }
}

impl Deref for Name {
    type Target = str;
    fn deref(&self) -> &str {
        &self.0
    }
}

impl AsRef<str> for Name {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl Borrow<str> for Name {
    fn borrow(&self) -> &str {
        &self.0
    }
}

impl From<&str> for Name {
    fn from(s: &str) -> Name {
        Name(Arc::from(s))
    }
}

impl From<String> for Name {
    fn from(s: String) -> Name {
        Name(Arc::from(s))
    }
}

impl From<&String> for Name {
    fn from(s: &String) -> Name {
        Name(Arc::from(s.as_str()))
    }
}

impl From<Arc<str>> for Name {
    fn from(s: Arc<str>) -> Name {
        Name(s)
    }
}

impl From<Name> for String {
    fn from(n: Name) -> String {
        String::from(&*n.0)
    }
}

impl fmt::Display for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&*self.0, f)
    }
}

impl fmt::Debug for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&*self.0, f)
    }
}

impl PartialEq<str> for Name {
    fn eq(&self, other: &str) -> bool {
        *self.0 == *other
    }
}

impl PartialEq<&str> for Name {
    fn eq(&self, other: &&str) -> bool {
        *self.0 == **other
    }
}

impl PartialEq<String> for Name {
    fn eq(&self, other: &String) -> bool {
        *self.0 == **other
    }
}

impl PartialEq<Name> for str {
    fn eq(&self, other: &Name) -> bool {
        *self == *other.0
    }
}

impl PartialEq<Name> for &str {
    fn eq(&self, other: &Name) -> bool {
        **self == *other.0
    }
}

impl PartialEq<Name> for String {
    fn eq(&self, other: &Name) -> bool {
        **self == *other.0
    }
}

impl Serialize for Name {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.0)
    }
}

impl<'de> Deserialize<'de> for Name {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Name, D::Error> {
        String::deserialize(deserializer).map(Name::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_reads_compares_and_travels_as_a_string() {
        let n = Name::from("sonar");
        assert_eq!(n, "sonar");
        assert_eq!("sonar", n);
        assert_eq!(n, String::from("sonar"));
        assert_eq!(n.as_str(), "sonar");
        assert_eq!(n.len(), 5);
        assert_eq!(format!("{n} {n:?}"), "sonar \"sonar\"");
        assert_eq!(String::from(n.clone()), "sonar");
        let as_string = marie_vocabulary::wire::encode(&"sonar").unwrap();
        assert_eq!(marie_vocabulary::wire::encode(&n).unwrap(), as_string);
        assert_eq!(
            marie_vocabulary::wire::decode::<Name>(&as_string).unwrap(),
            n
        );
        assert_eq!(serde_json::to_string(&n).unwrap(), "\"sonar\"");
        let some: Option<Name> = Some("front".into());
        assert_eq!(some.as_deref(), Some("front"));
    }

    #[test]
    fn clones_share_the_name() {
        let n = Name::from("ultrasonic");
        let m = n.clone();
        assert!(Arc::ptr_eq(&n.0, &m.0));
    }
}

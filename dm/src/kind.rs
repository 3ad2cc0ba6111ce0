//! Record kinds: a class, its sub-classes and the payload type, declared once.
//!
//! Producer and consumer of a datamanager record agree on three strings and a type: the
//! class, the sub-classes, and what the payload decodes to. Written at each call
//! (`store("wall", Some("followed"), None, &wall)` here, `Query::class("wall").sub1("followed")`
//! and `select_typed::<WallRecord>` there) any of them can drift apart unnoticed. A
//! [`RecordKind<T>`] constant holds all of them, and the `*_kind` methods of [`DmClient`]
//! take it: the class cannot be misspelt (a wrong constant name does not compile) and the
//! payload's type is checked on both sides. The names are checked when the constant is
//! evaluated, so an empty or over-long class is a compile error too.

use crate::{DmClient, DmError, NewRecord, PayloadType, Query, Record, RecordHeader, MAX_NAME_LEN};
use serde::Serialize;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

/// What records of one kind are: class, optional sub-classes, and payload type `T`.
///
/// ```
/// use marie_dm::{Query, RecordKind};
/// use serde::{Deserialize, Serialize};
///
/// #[derive(Debug, PartialEq, Serialize, Deserialize)]
/// struct Wall { distance: f64 }
///
/// const FOLLOWED: RecordKind<Wall> = RecordKind::new("wall").with_sub1("followed");
/// assert_eq!(FOLLOWED.query(), Query::class("wall").sub1("followed"));
/// let record = FOLLOWED.record(&Wall { distance: 0.4 }).unwrap();
/// assert_eq!((record.class.as_str(), record.sub1.as_deref()), ("wall", Some("followed")));
/// // FOLLOWED.record(&0.4) does not compile: the payload is a Wall
/// ```
///
/// A bad name in a constant does not compile:
///
/// ```compile_fail
/// use marie_dm::RecordKind;
/// const NAMELESS: RecordKind<f64> = RecordKind::new("");
/// let _ = NAMELESS.query();
/// ```
pub struct RecordKind<T> {
    class: &'static str,
    sub1: Option<&'static str>,
    sub2: Option<&'static str>,
    payload: PhantomData<fn() -> T>,
}

/// Panic (a compile error in a constant) unless `name` is a valid record name: non-empty, at
/// most [`MAX_NAME_LEN`] bytes, no control characters (C0, DEL, C1) — what
/// [`NewRecord::validate`] checks.
const fn check(name: &str) {
    let b = name.as_bytes();
    assert!(
        !b.is_empty(),
        "a record class or sub-class must not be empty"
    );
    assert!(
        b.len() <= MAX_NAME_LEN,
        "a record class or sub-class is at most 255 bytes"
    );
    let mut i = 0;
    while i < b.len() {
        let c0 = b[i] < 0x20 || b[i] == 0x7f;
        // C1 controls U+0080..=U+009F are 0xC2 0x80..=0x9F in UTF-8
        let c1 = b[i] == 0xc2 && i + 1 < b.len() && b[i + 1] >= 0x80 && b[i + 1] <= 0x9f;
        assert!(
            !c0 && !c1,
            "a record class or sub-class must not contain control characters"
        );
        i += 1;
    }
}

impl<T> RecordKind<T> {
    /// Records of `class`, without sub-classes.
    ///
    /// # Panics
    /// On a name a datamanager refuses (empty, over [`MAX_NAME_LEN`] bytes, with control
    /// characters) — in a constant, that is a compile error.
    pub const fn new(class: &'static str) -> RecordKind<T> {
        check(class);
        RecordKind {
            class,
            sub1: None,
            sub2: None,
            payload: PhantomData,
        }
    }

    /// The kind with first sub-class `sub1`.
    ///
    /// # Panics
    /// On a bad name, as [`RecordKind::new`].
    pub const fn with_sub1(mut self, sub1: &'static str) -> RecordKind<T> {
        check(sub1);
        self.sub1 = Some(sub1);
        self
    }

    /// The kind with second sub-class `sub2`.
    ///
    /// # Panics
    /// On a bad name, or without a first sub-class (a datamanager refuses such a record).
    pub const fn with_sub2(mut self, sub2: &'static str) -> RecordKind<T> {
        check(sub2);
        assert!(self.sub1.is_some(), "a second sub-class needs a first one");
        self.sub2 = Some(sub2);
        self
    }

    /// The class.
    pub const fn class(&self) -> &'static str {
        self.class
    }

    /// The first sub-class, if the kind has one.
    pub const fn sub1(&self) -> Option<&'static str> {
        self.sub1
    }

    /// The second sub-class, if the kind has one.
    pub const fn sub2(&self) -> Option<&'static str> {
        self.sub2
    }

    /// `query` restricted to records of this kind (its class and sub-classes replace any the
    /// query names).
    pub fn narrow(&self, mut query: Query) -> Query {
        query.class = Some(self.class.to_string());
        query.sub1 = self.sub1.map(str::to_string);
        query.sub2 = self.sub2.map(str::to_string);
        query
    }

    /// Every record of this kind: add criteria with the [`Query`] builder.
    pub fn query(&self) -> Query {
        self.narrow(Query::all())
    }

    /// Whether `header` (or a [`Record`]'s) is of this kind's class and sub-classes.
    pub fn is(&self, header: &RecordHeader) -> bool {
        header.class == self.class
            && header.sub1.as_deref() == self.sub1
            && header.sub2.as_deref() == self.sub2
    }
}

impl<T: Serialize> RecordKind<T> {
    /// A record of this kind with `value` as payload (no source yet: a [`DmClient`] fills in
    /// its own), e.g. for [`DmClient::put_batch`].
    pub fn record(&self, value: &T) -> Result<NewRecord, DmError> {
        let mut record = NewRecord::encode(self.class, value)?;
        record.sub1 = self.sub1.map(str::to_string);
        record.sub2 = self.sub2.map(str::to_string);
        Ok(record)
    }
}

impl<T: PayloadType> RecordKind<T> {
    /// The payload of `record` as this kind's type.
    pub fn decode(&self, record: &Record) -> Result<T, DmError> {
        record.decode()
    }
}

// By hand: derives would demand `T: Clone` etc. of the payload type.
impl<T> Clone for RecordKind<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for RecordKind<T> {}
impl<T> PartialEq for RecordKind<T> {
    fn eq(&self, other: &Self) -> bool {
        (self.class, self.sub1, self.sub2) == (other.class, other.sub1, other.sub2)
    }
}
impl<T> Eq for RecordKind<T> {}
impl<T> fmt::Debug for RecordKind<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "RecordKind<{}>({}",
            std::any::type_name::<T>(),
            self.class
        )?;
        for sub in [self.sub1, self.sub2].into_iter().flatten() {
            write!(f, "/{sub}")?;
        }
        write!(f, ")")
    }
}

/// Typed storing and selecting by [`RecordKind`].
///
/// ```
/// use marie_vocabulary::clock::RealClock;
/// use marie_dm::{self as dm, DmClient, RecordKind};
///
/// const RANGE: RecordKind<f64> = RecordKind::new("sonar").with_sub1("front");
///
/// # #[tokio::main(flavor = "current_thread")] async fn main() -> Result<(), dm::DmError> {
/// let mut args = dm::FEATURE.args(RealClock::shared());
/// args.name = "feature-kind-doc".into(); // registry names are process-wide
/// let (actor, handle) = dm::spawn_datamanager(args).await.unwrap();
/// let client = DmClient::new(actor.clone(), "sonar-driver");
/// client.store_kind(RANGE, &1.5).await?;
/// client.put_kind(RANGE, &1.25)?;
/// let (header, newest) = client.newest_kind(RANGE).await?.unwrap();
/// assert_eq!((header.seq, newest), (2, 1.25));
/// let all = client.select_kind(RANGE, dm::Query::all().oldest(10)).await?;
/// assert_eq!(all.iter().map(|(_, r)| *r).collect::<Vec<_>>(), [1.5, 1.25]);
/// actor.stop(None);
/// handle.await.unwrap();
/// # Ok(()) }
/// ```
impl DmClient {
    /// Store `value` as a record of `kind`. Returns its seq.
    pub async fn store_kind<T: Serialize>(
        &self,
        kind: RecordKind<T>,
        value: &T,
    ) -> Result<u64, DmError> {
        self.store_raw(kind.record(value)?).await
    }

    /// Store `value` as a record of `kind` without waiting for the datamanager (see
    /// [`DmClient::put`]).
    pub fn put_kind<T: Serialize>(&self, kind: RecordKind<T>, value: &T) -> Result<(), DmError> {
        self.put_raw(kind.record(value)?)
    }

    /// The records of `kind` that `query` selects (its class and sub-classes are the
    /// kind's), oldest first, decoded. One payload that does not decode fails the answer.
    pub async fn select_kind<T: PayloadType>(
        &self,
        kind: RecordKind<T>,
        query: Query,
    ) -> Result<Vec<(RecordHeader, T)>, DmError> {
        self.select_typed(kind.narrow(query)).await
    }

    /// [`select_kind`](Self::select_kind), each value shared rather than copied: records
    /// read in the datamanager's process are decoded once, and every reader of one gets the
    /// same value (a large payload — a scan of echoes — read by several operations).
    pub async fn select_kind_shared<T: PayloadType>(
        &self,
        kind: RecordKind<T>,
        query: Query,
    ) -> Result<Vec<(RecordHeader, Arc<T>)>, DmError> {
        self.select(kind.narrow(query))
            .await?
            .into_iter()
            .map(|r| {
                let shared = r.decode_shared()?;
                Ok((r.into_parts().0, shared))
            })
            .collect()
    }

    /// The newest record of `kind`, decoded; `None` when there is none.
    pub async fn newest_kind<T: PayloadType>(
        &self,
        kind: RecordKind<T>,
    ) -> Result<Option<(RecordHeader, T)>, DmError> {
        Ok(self.select_kind(kind, Query::all().newest(1)).await?.pop())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Payload;
    use std::time::Duration;

    const SEGMENTS: RecordKind<Vec<(f64, f64)>> = RecordKind::new("segments")
        .with_sub1("current")
        .with_sub2("narrow");

    #[test]
    fn a_kind_makes_the_record_and_query_a_hand_written_call_would() {
        let by_hand = NewRecord::encode("segments", &vec![(0.0, 1.0)])
            .unwrap()
            .with_sub1("current")
            .with_sub2("narrow");
        assert_eq!(SEGMENTS.record(&vec![(0.0, 1.0)]).unwrap(), by_hand);
        assert_eq!(
            SEGMENTS.query().newest(3),
            Query::class("segments")
                .sub1("current")
                .sub2("narrow")
                .newest(3)
        );
        // the kind's names replace a query's
        assert_eq!(
            SEGMENTS.narrow(Query::class("walls").sub1("old")),
            SEGMENTS.query()
        );
        let shown = format!("{SEGMENTS:?}");
        assert!(shown.starts_with("RecordKind<"), "{shown}");
        assert!(shown.ends_with("(segments/current/narrow)"), "{shown}");
    }

    #[test]
    fn a_kind_recognizes_its_records() {
        let rec = |class: &str, sub1: Option<&str>, sub2: Option<&str>| Record {
            seq: 1,
            timestamp: Duration::ZERO,
            source: "s".into(),
            class: class.into(),
            sub1: sub1.map(Into::into),
            sub2: sub2.map(Into::into),
            payload: Payload::default(),
        };
        assert!(SEGMENTS.is(&rec("segments", Some("current"), Some("narrow")).header()));
        assert!(!SEGMENTS.is(&rec("segments", Some("current"), None).header()));
        assert!(!SEGMENTS.is(&rec("segment", Some("current"), Some("narrow")).header()));
    }

    #[test]
    fn names_a_datamanager_refuses_are_refused_when_the_kind_is_made() {
        let valid = |name: &'static str| std::panic::catch_unwind(|| check(name)).is_ok();
        for name in ["sonar", "vorn-ä", "x"] {
            assert!(valid(name), "{name}");
            let rec = NewRecord::new(name, Payload::default()).with_source("s");
            assert!(rec.validate().is_ok());
        }
        let long: &'static str = Box::leak("x".repeat(MAX_NAME_LEN + 1).into_boxed_str());
        for name in ["", "a\nb", "a\u{7f}", "a\u{85}b", long] {
            assert!(!valid(name), "{name:?}");
            let rec = NewRecord::new(name, Payload::default()).with_source("s");
            assert!(rec.validate().is_err(), "{name:?}");
        }
        let no_sub1 = std::panic::catch_unwind(|| RecordKind::<u8>::new("c").with_sub2("d"));
        assert!(no_sub1.is_err());
    }
}

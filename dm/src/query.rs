//! Queries: the one powerful select of the thesis' DM (3.2.5.2).
//!
//! A [`Query`] combines any of: class, first and second sub-class, source, an inclusive
//! sequence-number range, an inclusive time range, and a limit to the newest or oldest N
//! matches. Every criterion left out matches everything. Answers are always oldest-first.
//!
//! ```
//! use marie_dm::Query;
//! use std::time::Duration;
//! let q = Query::class("sonar").sub1("front").seq_from(10).newest(5);
//! let recent = Query::all().time_from(Duration::from_secs(3)).source("ultrasonic");
//! # let _ = (q, recent);
//! ```

use super::record::Record;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Which end of the matches a limited query keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Take {
    /// The N newest matches (still returned oldest-first).
    Newest(usize),
    /// The N oldest matches.
    Oldest(usize),
}

/// What to select (or delete, or wait for). Build it with [`Query::all`] or [`Query::class`]
/// and the builder methods.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Query {
    /// Records of this class.
    pub class: Option<String>,
    /// Records whose first sub-class is this.
    pub sub1: Option<String>,
    /// Records whose second sub-class is this.
    pub sub2: Option<String>,
    /// Records from this producer.
    pub source: Option<String>,
    /// Records with `seq >= seq_from`.
    pub seq_from: Option<u64>,
    /// Records with `seq <= seq_to`.
    pub seq_to: Option<u64>,
    /// Records with `timestamp >= time_from`.
    pub time_from: Option<Duration>,
    /// Records with `timestamp <= time_to`.
    pub time_to: Option<Duration>,
    /// Keep only the newest or oldest N matches.
    pub take: Option<Take>,
}

impl Query {
    /// Every record.
    pub fn all() -> Query {
        Query::default()
    }

    /// Records of `class`.
    pub fn class(class: impl Into<String>) -> Query {
        Query::all().in_class(class)
    }

    /// Restrict to `class`.
    pub fn in_class(mut self, class: impl Into<String>) -> Query {
        self.class = Some(class.into());
        self
    }

    /// Restrict to the first sub-class `sub1`.
    pub fn sub1(mut self, sub1: impl Into<String>) -> Query {
        self.sub1 = Some(sub1.into());
        self
    }

    /// Restrict to the second sub-class `sub2`.
    pub fn sub2(mut self, sub2: impl Into<String>) -> Query {
        self.sub2 = Some(sub2.into());
        self
    }

    /// Restrict to records stored by `source`.
    pub fn source(mut self, source: impl Into<String>) -> Query {
        self.source = Some(source.into());
        self
    }

    /// Only sequence numbers `>= seq`.
    pub fn seq_from(mut self, seq: u64) -> Query {
        self.seq_from = Some(seq);
        self
    }

    /// Only sequence numbers `<= seq`.
    pub fn seq_to(mut self, seq: u64) -> Query {
        self.seq_to = Some(seq);
        self
    }

    /// Only sequence numbers in `from..=to`.
    pub fn seq_range(self, from: u64, to: u64) -> Query {
        self.seq_from(from).seq_to(to)
    }

    /// Only time stamps `>= t`.
    pub fn time_from(mut self, t: Duration) -> Query {
        self.time_from = Some(t);
        self
    }

    /// Only time stamps `<= t`.
    pub fn time_to(mut self, t: Duration) -> Query {
        self.time_to = Some(t);
        self
    }

    /// Only time stamps in `from..=to`.
    pub fn time_range(self, from: Duration, to: Duration) -> Query {
        self.time_from(from).time_to(to)
    }

    /// Keep the `n` newest matches (returned oldest-first). Replaces [`Query::oldest`].
    pub fn newest(mut self, n: usize) -> Query {
        self.take = Some(Take::Newest(n));
        self
    }

    /// Keep the `n` oldest matches. Replaces [`Query::newest`].
    pub fn oldest(mut self, n: usize) -> Query {
        self.take = Some(Take::Oldest(n));
        self
    }

    /// Whether `record` meets every criterion (the newest/oldest limit is not a criterion of
    /// one record and is ignored here).
    pub fn matches(&self, record: &Record) -> bool {
        self.matches_parts(
            record.seq,
            record.timestamp,
            &record.source,
            &record.class,
            record.sub1.as_deref(),
            record.sub2.as_deref(),
        )
    }

    /// [`Query::matches`] on the fields of a record, however they are held.
    pub(crate) fn matches_parts(
        &self,
        seq: u64,
        timestamp: Duration,
        source: &str,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
    ) -> bool {
        fn same(want: &Option<String>, have: Option<&str>) -> bool {
            match want {
                None => true,
                Some(w) => have == Some(w.as_str()),
            }
        }
        self.seq_from.is_none_or(|s| seq >= s)
            && self.seq_to.is_none_or(|s| seq <= s)
            && self.time_from.is_none_or(|t| timestamp >= t)
            && self.time_to.is_none_or(|t| timestamp <= t)
            && same(&self.class, Some(class))
            && same(&self.sub1, sub1)
            && same(&self.sub2, sub2)
            && same(&self.source, Some(source))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Payload;

    fn rec(seq: u64, class: &str, sub1: Option<&str>, sub2: Option<&str>, src: &str) -> Record {
        Record {
            seq,
            timestamp: Duration::from_secs(seq),
            source: src.into(),
            class: class.into(),
            sub1: sub1.map(Into::into),
            sub2: sub2.map(Into::into),
            payload: Payload::default(),
        }
    }

    #[test]
    fn each_criterion_filters() {
        let r = rec(5, "sonar", Some("front"), Some("narrow"), "us");
        assert!(Query::all().matches(&r));
        assert!(Query::class("sonar").matches(&r));
        assert!(!Query::class("segment").matches(&r));
        assert!(Query::all().sub1("front").matches(&r));
        assert!(!Query::all().sub1("rear").matches(&r));
        assert!(Query::all().sub2("narrow").matches(&r));
        assert!(!Query::all().sub2("wide").matches(&r));
        assert!(Query::all().source("us").matches(&r));
        assert!(!Query::all().source("other").matches(&r));
        assert!(Query::all().seq_range(5, 5).matches(&r));
        assert!(!Query::all().seq_from(6).matches(&r));
        assert!(!Query::all().seq_to(4).matches(&r));
        let t = Duration::from_secs(5);
        assert!(Query::all().time_range(t, t).matches(&r));
        assert!(!Query::all()
            .time_from(t + Duration::from_nanos(1))
            .matches(&r));
        assert!(!Query::all()
            .time_to(t - Duration::from_nanos(1))
            .matches(&r));
        assert!(
            Query::all().newest(0).matches(&r),
            "limits are not criteria"
        );
        let plain = rec(6, "sonar", None, None, "us");
        assert!(!Query::all().sub1("front").matches(&plain));
    }

    #[test]
    fn builder_and_wire() {
        let q = Query::class("sonar").sub1("front").seq_from(10).newest(5);
        assert_eq!(q.class.as_deref(), Some("sonar"));
        assert_eq!(q.take, Some(Take::Newest(5)));
        assert_eq!(q.clone().oldest(2).take, Some(Take::Oldest(2)));
        let bytes = marie_vocabulary::wire::encode(&q).unwrap();
        assert_eq!(marie_vocabulary::wire::decode::<Query>(&bytes).unwrap(), q);
        // missing fields default, so a newer peer can add criteria
        let sparse =
            marie_vocabulary::wire::encode(&serde_json::json!({ "class": "sonar" })).unwrap();
        assert_eq!(
            marie_vocabulary::wire::decode::<Query>(&sparse).unwrap(),
            Query::class("sonar")
        );
    }
}

//! The protocol versions a node speaks, and the one two nodes agree on.
//!
//! A node speaks a range of protocol versions, `oldest..=newest`: its own and, when the
//! build can, the one before — so that a cluster is upgraded one node at a time, with two
//! builds side by side. Two nodes agree on the highest version both speak; nodes whose
//! ranges do not meet refuse each other. A beat of a build before ranges names none: its
//! envelope's version is its range ([`ProtocolRange::single`]).
//!
//! ```
//! use marie_vocabulary::wire::ProtocolRange;
//! let new: ProtocolRange = "2-3".parse().unwrap();
//! let old = ProtocolRange::single(2);
//! assert_eq!(new.agree(&old), Some(2));
//! assert_eq!(new.agree(&ProtocolRange::single(4)), None);
//! assert_eq!(new.to_string(), "2..=3");
//! ```

use super::envelope::{OLDEST_PROTOCOL, PROTOCOL_VERSION};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The protocol versions `oldest..=newest` a node speaks (never empty: `oldest <= newest`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ProtocolRange {
    /// The oldest version it speaks.
    pub oldest: u16,
    /// The newest: its own.
    pub newest: u16,
}

/// A range that does not parse (`LO-HI`, `N`, `LO..=HI`, with `LO <= HI`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0:?} is no protocol range: expected N, LO-HI or LO..=HI with LO <= HI")]
pub struct RangeError(pub String);

impl ProtocolRange {
    /// What this build speaks: [`OLDEST_PROTOCOL`]`..=`[`PROTOCOL_VERSION`].
    pub const fn this_build() -> ProtocolRange {
        ProtocolRange {
            oldest: OLDEST_PROTOCOL,
            newest: PROTOCOL_VERSION,
        }
    }

    /// One version alone (what a beat of a build before ranges speaks).
    pub const fn single(version: u16) -> ProtocolRange {
        ProtocolRange {
            oldest: version,
            newest: version,
        }
    }

    /// `oldest..=newest`; `None` if `oldest > newest`.
    pub fn new(oldest: u16, newest: u16) -> Option<ProtocolRange> {
        (oldest <= newest).then_some(ProtocolRange { oldest, newest })
    }

    /// Whether `version` is in the range.
    pub fn speaks(&self, version: u16) -> bool {
        (self.oldest..=self.newest).contains(&version)
    }

    /// The version two nodes of these ranges use: the highest both speak; `None` when the
    /// ranges do not meet.
    pub fn agree(&self, other: &ProtocolRange) -> Option<u16> {
        let high = self.newest.min(other.newest);
        (high >= self.oldest.max(other.oldest)).then_some(high)
    }
}

impl Default for ProtocolRange {
    fn default() -> Self {
        ProtocolRange::this_build()
    }
}

impl fmt::Display for ProtocolRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..={}", self.oldest, self.newest)
    }
}

impl std::str::FromStr for ProtocolRange {
    type Err = RangeError;

    fn from_str(s: &str) -> Result<Self, RangeError> {
        let bad = || RangeError(s.to_string());
        let num = |t: &str| t.trim().parse::<u16>().map_err(|_| bad());
        let (lo, hi) = match s.split_once("..=").or_else(|| s.split_once('-')) {
            Some((lo, hi)) => (num(lo)?, num(hi)?),
            None => (num(s)?, num(s)?),
        };
        ProtocolRange::new(lo, hi).ok_or_else(bad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_nodes_agree_on_the_highest_version_both_speak() {
        let r = |lo, hi| ProtocolRange::new(lo, hi).unwrap();
        assert_eq!(r(2, 3).agree(&r(2, 2)), Some(2));
        assert_eq!(r(2, 2).agree(&r(2, 3)), Some(2));
        assert_eq!(r(2, 3).agree(&r(3, 4)), Some(3));
        assert_eq!(r(2, 3).agree(&r(2, 3)), Some(3));
        assert_eq!(r(1, 5).agree(&r(3, 3)), Some(3));
        // ranges that do not meet, on either side
        assert_eq!(r(2, 2).agree(&r(4, 4)), None);
        assert_eq!(r(4, 4).agree(&r(2, 3)), None);
        assert_eq!(r(3, 4).agree(&r(1, 2)), None);
    }

    #[test]
    fn ranges_parse_in_three_forms_and_refuse_the_rest() {
        assert_eq!("2-3".parse(), Ok(ProtocolRange::new(2, 3).unwrap()));
        assert_eq!("2..=3".parse(), Ok(ProtocolRange::new(2, 3).unwrap()));
        assert_eq!("4".parse(), Ok(ProtocolRange::single(4)));
        for bad in ["3-2", "", "x", "2-", "-3", "2..3", "70000"] {
            let err = bad.parse::<ProtocolRange>().unwrap_err();
            assert!(err.to_string().contains("no protocol range"), "{err}");
        }
    }

    #[test]
    fn this_build_speaks_its_own_version() {
        let r = ProtocolRange::this_build();
        assert!(r.speaks(PROTOCOL_VERSION) && r.speaks(OLDEST_PROTOCOL));
        assert!(!r.speaks(PROTOCOL_VERSION + 1));
        assert_eq!(
            r.agree(&ProtocolRange::single(PROTOCOL_VERSION)),
            Some(PROTOCOL_VERSION)
        );
    }
}

//! The 32-bit status word of the eo-interface.
//!
//! An operation reports a [`StatusFlags`] when it finishes (thesis 3.2.5.1). Bits in an
//! operation's report are *local*: bit `i` is the `i`-th flag the operation declares (see
//! `marie_actors::eo::Operation::flags`). The dispatcher translates them by name into the mission's
//! global status word, whose bits the mission file assigns. This keeps an operation's meaning
//! independent of which mission uses it.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::ops::{BitAnd, BitOr, BitOrAssign, Not};

/// A 32-bit set of status flags.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct StatusFlags(pub u32);

impl StatusFlags {
    /// No flag set.
    pub const EMPTY: StatusFlags = StatusFlags(0);

    /// The word with only bit `bit` set. Bits above 31 are rejected with `None`.
    pub fn bit(bit: u8) -> Option<StatusFlags> {
        (bit < 32).then(|| StatusFlags(1 << bit))
    }

    /// True when every bit of `other` is set in `self` (the thesis' "implied by").
    pub fn implies(self, other: StatusFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// True when bit `bit` is set.
    pub fn has_bit(self, bit: u8) -> bool {
        bit < 32 && self.0 & (1 << bit) != 0
    }

    /// The set bits, lowest first.
    pub fn bits(self) -> impl Iterator<Item = u8> {
        (0u8..32).filter(move |b| self.has_bit(*b))
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl fmt::Debug for StatusFlags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "StatusFlags({:#010x})", self.0)
    }
}

impl fmt::Display for StatusFlags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#010x}", self.0)
    }
}

impl BitOr for StatusFlags {
    type Output = StatusFlags;
    fn bitor(self, rhs: StatusFlags) -> StatusFlags {
        StatusFlags(self.0 | rhs.0)
    }
}

impl BitOrAssign for StatusFlags {
    fn bitor_assign(&mut self, rhs: StatusFlags) {
        self.0 |= rhs.0;
    }
}

impl BitAnd for StatusFlags {
    type Output = StatusFlags;
    fn bitand(self, rhs: StatusFlags) -> StatusFlags {
        StatusFlags(self.0 & rhs.0)
    }
}

impl Not for StatusFlags {
    type Output = StatusFlags;
    fn not(self) -> StatusFlags {
        StatusFlags(!self.0)
    }
}

/// A flag an operation can raise: its name (matched against the mission's `[flags]` table) and
/// what it means.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FlagDecl {
    /// Name used by missions, e.g. `wall-found`.
    pub name: String,
    /// One line for people reading properties.
    pub description: String,
}

impl FlagDecl {
    /// A flag declaration.
    pub fn new(name: impl Into<String>, description: impl Into<String>) -> Self {
        FlagDecl {
            name: name.into(),
            description: description.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn implication_is_subset() {
        let status = StatusFlags(0b1011);
        assert!(status.implies(StatusFlags(0b0011)));
        assert!(status.implies(StatusFlags::EMPTY));
        assert!(!status.implies(StatusFlags(0b0100)));
    }

    #[test]
    fn bit_rejects_out_of_range() {
        assert_eq!(StatusFlags::bit(31), Some(StatusFlags(1 << 31)));
        assert_eq!(StatusFlags::bit(32), None);
        assert_eq!(StatusFlags(0b101).bits().collect::<Vec<_>>(), vec![0, 2]);
    }
}

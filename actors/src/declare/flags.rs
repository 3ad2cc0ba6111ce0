//! Typed status flags: an enum whose variants are an operation's flags.
//!
//! An operation reports its flags as bits of a [`StatusFlags`] word in its own order: bit `i`
//! means the `i`-th flag of [`Operation::flags`](crate::eo::Operation::flags), and the
//! dispatcher maps it by that flag's name to the mission's word. Written by hand, the
//! declaration (`vec![FlagDecl::new("wall-found", ..)]`) and the bit an operation sets
//! (`StatusFlags(1)`) are two facts kept in step by the author; declared with
//! [`flags!`](crate::flags!), the variant *is* the flag: its position in the enum is its bit
//! and its declaration, so `Step::Finish(WallFlag::Found.into())` cannot name a bit that
//! means something else.

use marie_vocabulary::status::{FlagDecl, StatusFlags};

/// An enum of an operation's flags, in declaration order. [`flags!`](crate::flags!)
/// implements it.
///
/// ```
/// use marie_actors::declare::DeclaredFlags;
/// use marie_vocabulary::status::{FlagDecl, StatusFlags};
///
/// marie_actors::flags! {
///     /// What the walk reports.
///     pub enum Walk {
///         /// the goal is reached
///         Arrived = "arrived",
///         /// something is in the way
///         Blocked = "blocked",
///     }
/// }
/// assert_eq!(Walk::decls(), vec![
///     FlagDecl::new("arrived", "the goal is reached"),
///     FlagDecl::new("blocked", "something is in the way"),
/// ]);
/// assert_eq!(Walk::Blocked.index(), 1);
/// assert_eq!(StatusFlags::from(Walk::Blocked), StatusFlags(0b10));
/// assert_eq!(Walk::from_name("arrived"), Some(Walk::Arrived));
/// ```
pub trait DeclaredFlags: Copy + Into<StatusFlags> + 'static {
    /// Every flag, in declaration order (bit `i` is `ALL[i]`).
    const ALL: &'static [Self];

    /// The flag's position, which is its bit in the operation's reports.
    fn index(self) -> u8;

    /// The name missions use, e.g. `reached-one`.
    fn name(self) -> &'static str;

    /// The one-line description.
    fn description(self) -> &'static str;

    /// The declarations, in order: what [`Operation::flags`](crate::eo::Operation::flags)
    /// returns.
    fn decls() -> Vec<FlagDecl> {
        Self::ALL
            .iter()
            .map(|f| FlagDecl::new(f.name(), f.description()))
            .collect()
    }

    /// The flag named `name`.
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|f| f.name() == name)
    }

    /// The flags set in `status` (an operation's own word).
    fn set_in(status: StatusFlags) -> Vec<Self> {
        Self::ALL
            .iter()
            .copied()
            .filter(|f| status.has_bit(f.index()))
            .collect()
    }
}

/// Declare an operation's flags as an enum.
///
/// ```text
/// flags! {
///     /// doc
///     pub enum Name {
///         /// description (the doc comment becomes the flag's description)
///         Variant = "mission-name",
///         ...
///     }
/// }
/// ```
///
/// It generates the enum (deriving `Clone`, `Copy`, `Debug`, `PartialEq`, `Eq`, `Hash`),
/// [`DeclaredFlags`], `From<Name> for StatusFlags` (bit `i` for the `i`-th variant: the bit
/// the dispatcher maps to that flag's name), and `|` between flags and status words, so
/// `A | B`, `status | A` and `ctx.raise(A)` all work. More than 32 flags is a compile error.
///
/// ```
/// use marie_actors::declare::DeclaredFlags;
/// use marie_vocabulary::status::StatusFlags;
///
/// marie_actors::flags! {
///     /// What the docking detector reports.
///     pub enum Dock {
///         /// a docking spot was found
///         Found = "dock-found",
///         /// the search gave up
///         Lost = "dock-lost",
///         /// the spot is too narrow
///         Narrow = "dock-narrow",
///     }
/// }
/// let both: StatusFlags = Dock::Found | Dock::Narrow;
/// assert_eq!(both, StatusFlags(0b101));
/// assert_eq!(both | Dock::Lost, StatusFlags(0b111));
/// assert_eq!(Dock::set_in(both), vec![Dock::Found, Dock::Narrow]);
/// assert_eq!(Dock::Lost.name(), "dock-lost");
/// assert_eq!(Dock::Lost.to_string(), "dock-lost");
/// ```
///
/// A misspelt flag is a compile error:
///
/// ```compile_fail
/// marie_actors::flags! {
///     pub enum Dock {
///         /// a docking spot was found
///         Found = "dock-found",
///     }
/// }
/// let _: marie_vocabulary::status::StatusFlags = Dock::Fuond.into();
/// ```
#[macro_export]
macro_rules! flags {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $variant:ident = $flag:literal
            ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        #[repr(u8)]
        $vis enum $name {
            $(
                $(#[doc = $doc])*
                $variant,
            )*
        }

        const _: () = ::core::assert!(
            <$name as $crate::declare::DeclaredFlags>::ALL.len() <= 32,
            "an operation declares at most 32 flags"
        );

        impl $crate::declare::DeclaredFlags for $name {
            const ALL: &'static [Self] = &[$($name::$variant),*];

            fn index(self) -> u8 {
                self as u8
            }

            fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $flag,)*
                }
            }

            fn description(self) -> &'static str {
                match self {
                    $($name::$variant => ::core::concat!($($doc),*).trim_ascii(),)*
                }
            }
        }

        impl ::core::convert::From<$name> for $crate::__private::status::StatusFlags {
            fn from(flag: $name) -> Self {
                $crate::__private::status::StatusFlags(1 << (flag as u32))
            }
        }

        impl ::core::ops::BitOr for $name {
            type Output = $crate::__private::status::StatusFlags;
            fn bitor(self, rhs: $name) -> $crate::__private::status::StatusFlags {
                $crate::__private::status::StatusFlags::from(self) | $crate::__private::status::StatusFlags::from(rhs)
            }
        }

        impl ::core::ops::BitOr<$name> for $crate::__private::status::StatusFlags {
            type Output = $crate::__private::status::StatusFlags;
            fn bitor(self, rhs: $name) -> $crate::__private::status::StatusFlags {
                self | $crate::__private::status::StatusFlags::from(rhs)
            }
        }

        impl ::core::ops::BitOr<$crate::__private::status::StatusFlags> for $name {
            type Output = $crate::__private::status::StatusFlags;
            fn bitor(self, rhs: $crate::__private::status::StatusFlags) -> $crate::__private::status::StatusFlags {
                $crate::__private::status::StatusFlags::from(self) | rhs
            }
        }

        impl ::core::fmt::Display for $name {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                f.write_str($crate::declare::DeclaredFlags::name(*self))
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::flags! {
        /// The docking detector's flags.
        enum Dock {
            /// a docking spot was found
            Found = "dock-found",
            /// the search gave up
            Lost = "dock-lost",
            /// the spot is
            /// too narrow
            Narrow = "dock-narrow",
        }
    }

    #[test]
    fn each_flag_is_the_bit_of_its_declaration() {
        // the dispatcher maps bit i of a report to the name of `flags()[i]`
        let decls = Dock::decls();
        assert_eq!(
            decls,
            vec![
                FlagDecl::new("dock-found", "a docking spot was found"),
                FlagDecl::new("dock-lost", "the search gave up"),
                FlagDecl::new("dock-narrow", "the spot is too narrow"),
            ]
        );
        for (i, flag) in Dock::ALL.iter().enumerate() {
            let word = StatusFlags::from(*flag);
            assert_eq!(word.bits().collect::<Vec<_>>(), [i as u8], "{flag:?}");
            assert_eq!(decls[i].name, flag.name());
            assert_eq!(Dock::from_name(flag.name()), Some(*flag));
        }
    }

    #[test]
    fn flags_combine_into_one_word() {
        assert_eq!(Dock::Found | Dock::Lost, StatusFlags(0b011));
        assert_eq!(StatusFlags::EMPTY | Dock::Narrow, StatusFlags(0b100));
        assert_eq!(Dock::Narrow | StatusFlags(0b001), StatusFlags(0b101));
        assert_eq!(Dock::set_in(StatusFlags(0b110)), [Dock::Lost, Dock::Narrow]);
        assert!((Dock::Found | Dock::Narrow).implies(Dock::Narrow.into()));
    }
}

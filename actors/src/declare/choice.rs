//! Choice parameters as enums.
//!
//! A choice parameter ([`ParamType::Choice`](marie_vocabulary::property::ParamType::Choice)) holds one
//! of a fixed set of words. Read as text, every comparison (`beams == "narrow"`) is a string
//! an author can misspell and no compiler checks; declared with [`choice!`](crate::choice),
//! the words are the variants of an enum, the declaration lists them, and a `match` on the
//! value is checked for exhaustiveness.

/// Declare an enum whose variants are the words of a choice parameter.
///
/// ```text
/// choice! {
///     /// doc
///     pub enum Name { Variant = "word", ... }
/// }
/// ```
///
/// It generates the enum (deriving `Clone`, `Copy`, `Debug`, `PartialEq`, `Eq`, `Hash`), its
/// [`ParamValue`](crate::declare::ParamValue) (so it can be the type of a
/// [`params!`](crate::params) field, declared with
/// [`ParamDecl::choice`](marie_vocabulary::property::ParamDecl::choice)), `WORDS` (the words in
/// declaration order), `as_str` and `Display`.
///
/// ```
/// use marie_actors::declare::ParamValue;
/// use marie_vocabulary::property::{FromValue, ParamDecl, Value};
///
/// marie_actors::choice! {
///     /// Which sonar beams to use.
///     pub enum Beams {
///         /// only narrow beams
///         Narrow = "narrow",
///         /// every beam
///         All = "all",
///     }
/// }
///
/// assert_eq!(Beams::WORDS, &["narrow", "all"]);
/// assert_eq!(Beams::decl("beams", Beams::Narrow), ParamDecl::choice("beams", &["narrow", "all"], "narrow"));
/// assert_eq!(Beams::from_value(&Value::Text("all".into())), Some(Beams::All));
/// assert_eq!(Beams::from_value(&Value::Text("wide".into())), None);
/// assert_eq!(Beams::All.into_value(), Value::Text("all".into()));
/// assert_eq!(Beams::Narrow.to_string(), "narrow");
/// ```
#[macro_export]
macro_rules! choice {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $(
                $(#[$vmeta:meta])*
                $variant:ident = $word:literal
            ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $name {
            $(
                $(#[$vmeta])*
                $variant,
            )*
        }

        impl $name {
            /// The words of the choice, in declaration order.
            #[allow(dead_code)]
            $vis const WORDS: &'static [&'static str] = &[$($word),*];

            /// The word of this variant.
            #[allow(dead_code)]
            $vis const fn as_str(self) -> &'static str {
                match self {
                    $($name::$variant => $word,)*
                }
            }
        }

        impl ::core::fmt::Display for $name {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl $crate::__private::property::FromValue for $name {
            const EXPECTED: &'static str = "choice";

            fn from_value(value: &$crate::__private::property::Value) -> ::core::option::Option<Self> {
                match value.as_str()? {
                    $($word => ::core::option::Option::Some($name::$variant),)*
                    _ => ::core::option::Option::None,
                }
            }
        }

        impl $crate::declare::ParamValue for $name {
            fn decl(name: &str, default: Self) -> $crate::__private::property::ParamDecl {
                $crate::__private::property::ParamDecl::choice(name, Self::WORDS, default.as_str())
            }

            fn into_value(self) -> $crate::__private::property::Value {
                $crate::__private::property::Value::Text(self.as_str().to_string())
            }

            fn mismatch(value: &$crate::__private::property::Value) -> ::std::string::String {
                match value {
                    $crate::__private::property::Value::Text(_) => {
                        ::std::format!("expected one of {}, found {}", Self::WORDS.join("|"), value)
                    }
                    _ => ::std::format!(
                        "expected one of {}, found {}",
                        Self::WORDS.join("|"),
                        value.kind()
                    ),
                }
            }
        }
    };
}

//! The rules of `docs/compatibility.md`, checked: what a node of one build reads of a
//! message a node of another build sent (ractor's remote messages, [`remote_message!`]
//! enums: a variant travels as its name, its fields as a MessagePack map).
//!
//! [`remote_message!`]: crate::remote_message

use ractor::Message;

/// The messages as the older build declares them.
mod old {
    crate::remote_message! {
        /// Old.
        pub(super) enum Msg {
            /// A cast.
            Add { n: u64 },
        }
    }
}

/// The same messages as the newer build declares them.
mod new {
    crate::remote_message! {
        /// New.
        pub(super) enum Msg {
            /// A cast, fields more: an `Option` (a variant's fields take no `#[serde]`
            /// attribute: the enum derives no serde) and a struct whose fields have
            /// defaults.
            Add {
                n: u64,
                note: Option<String>,
                more: super::More,
            },
            /// A variant the older build lacks.
            Reset {},
        }
    }
}

/// A struct a variant carries, whose fields may be missing.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default, PartialEq)]
#[serde(default)]
struct More {
    label: String,
}

/// A field added without a default (and not an `Option`).
mod strict {
    crate::remote_message! {
        /// Strict.
        pub(super) enum Msg {
            /// A cast, one field more, no default.
            Add { n: u64, label: String },
        }
    }
}

/// A field retyped.
mod retyped {
    crate::remote_message! {
        /// Retyped.
        pub(super) enum Msg {
            /// `n` is text now.
            Add { n: String },
        }
    }
}

#[test]
fn a_field_added_is_ignored_by_the_older_build() {
    let wire = new::Msg::Add {
        n: 7,
        note: Some("y".into()),
        more: More { label: "x".into() },
    }
    .serialize()
    .unwrap();
    assert!(matches!(
        old::Msg::deserialize(wire),
        Ok(old::Msg::Add { n: 7 })
    ));
}

#[test]
fn a_variants_field_missing_decodes_only_as_an_option() {
    let wire = old::Msg::Add { n: 7 }.serialize().unwrap();
    // `more` (a struct, however defaulted its own fields) is missing: no decode
    assert!(new::Msg::deserialize(wire).is_err());
    mod optional {
        crate::remote_message! {
            /// A field added as an `Option`.
            pub(super) enum Msg {
                /// A cast.
                Add { n: u64, note: Option<String> },
            }
        }
    }
    let wire = old::Msg::Add { n: 7 }.serialize().unwrap();
    match optional::Msg::deserialize(wire) {
        Ok(optional::Msg::Add { n, note }) => assert_eq!((n, note), (7, None)),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_structs_field_missing_reads_as_its_default() {
    #[derive(serde::Serialize)]
    struct OldMore {}
    let more: More = super::decode(&super::encode(&OldMore {}).unwrap()).unwrap();
    assert_eq!(more, More::default());
}

#[test]
fn a_field_missing_without_a_default_does_not_decode() {
    let wire = old::Msg::Add { n: 7 }.serialize().unwrap();
    assert!(strict::Msg::deserialize(wire).is_err());
}

#[test]
fn a_variant_the_older_build_lacks_does_not_decode_there() {
    let wire = new::Msg::Reset {}.serialize().unwrap();
    assert!(old::Msg::deserialize(wire).is_err());
}

#[test]
fn a_retyped_field_does_not_decode() {
    let wire = old::Msg::Add { n: 7 }.serialize().unwrap();
    assert!(retyped::Msg::deserialize(wire).is_err());
}

/// A plain serde struct (a record's payload, a frame's payload, an event) the same way.
#[test]
fn structs_follow_the_same_rules() {
    #[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
    struct Old {
        n: u64,
    }
    #[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
    struct New {
        n: u64,
        #[serde(default)]
        label: String,
    }
    #[derive(serde::Deserialize, Debug)]
    struct Renamed {
        #[serde(default)]
        count: u64,
    }
    let new = super::encode(&New {
        n: 3,
        label: "x".into(),
    })
    .unwrap();
    assert_eq!(super::decode::<Old>(&new).unwrap(), Old { n: 3 });
    let old = super::encode(&Old { n: 3 }).unwrap();
    assert_eq!(
        super::decode::<New>(&old).unwrap(),
        New {
            n: 3,
            label: String::new()
        }
    );
    // a field renamed with a default reads as the default: the value is lost in silence,
    // which is why a rename is a new protocol version
    assert_eq!(super::decode::<Renamed>(&old).unwrap().count, 0);
}

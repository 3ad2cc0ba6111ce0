//! An event as a peer agreed on an older protocol version reads it.
//!
//! A node sends a peer only what the protocol version agreed with it says
//! (`docs/compatibility.md`): a field a newer version added is left out of a frame for a
//! peer agreed on the version before it. A field added with a default is read by the older
//! build anyway (it ignores what it does not know), so leaving it out is not for decoding's
//! sake but for the rule's: what crosses to a peer is what its version defines — a version
//! that adds a field whose absence would be misread is handled here too, in one place.
//!
//! This build's own protocol version adds nothing to the one before it: an event is sent as
//! it is. The next build's (feature `next-protocol`, version 3) adds the version a module's
//! node speaks to its `joined`/`left` event ([`ModuleInfo::speaks`](super::ModuleInfo)).

use super::Event;
use std::borrow::Cow;

impl Event {
    /// The event as protocol version `version` defines it: itself when that version knows
    /// every field it has, else a copy without the fields added after `version`.
    ///
    /// ```
    /// use marie_vocabulary::events::{Event, EventKind};
    /// use marie_vocabulary::wire::{OLDEST_PROTOCOL, PROTOCOL_VERSION};
    /// let e = Event { at_ms: 1, node: "a".into(), kind: EventKind::NodeFrozen { silent_ms: 9 } };
    /// assert_eq!(*e.spoken_at(OLDEST_PROTOCOL), e);
    /// assert_eq!(*e.spoken_at(PROTOCOL_VERSION), e);
    /// ```
    pub fn spoken_at(&self, version: u16) -> Cow<'_, Event> {
        let _ = version;
        #[cfg(feature = "next-protocol")]
        if version < 3 {
            if let super::EventKind::Joined(m) | super::EventKind::Left(m) = &self.kind {
                if m.speaks.is_some() {
                    let mut older = self.clone();
                    if let super::EventKind::Joined(m) | super::EventKind::Left(m) = &mut older.kind
                    {
                        m.speaks = None;
                    }
                    return Cow::Owned(older);
                }
            }
        }
        Cow::Borrowed(self)
    }
}

#[cfg(all(test, feature = "next-protocol"))]
mod tests {
    use super::super::{EventKind, ModuleInfo};
    use super::*;
    use crate::registry::ModuleKind;

    fn joined(speaks: Option<u16>) -> Event {
        Event {
            at_ms: 5,
            node: "next".into(),
            kind: EventKind::Joined(ModuleInfo {
                speaks,
                ..ModuleInfo::new(ModuleKind::Operation, "wall-follower", 3, "next", "0.9")
            }),
        }
    }

    /// The keys of the `joined` map in the event's MessagePack encoding.
    fn keys(event: &Event) -> String {
        let json: serde_json::Value =
            rmp_serde::from_slice::<serde_json::Value>(&crate::wire::encode(event).unwrap())
                .unwrap();
        json["kind"].to_string()
    }

    #[test]
    fn a_peer_agreed_on_2_gets_no_field_of_3() {
        let e = joined(Some(3));
        assert!(keys(&e).contains("speaks"), "{}", keys(&e));
        let at2 = e.spoken_at(2);
        assert!(!keys(&at2).contains("speaks"), "{}", keys(&at2));
        assert_eq!(*at2, joined(None));
        // the rest is the same event
        assert!(matches!(e.spoken_at(3), Cow::Borrowed(_)));
        assert!(matches!(joined(None).spoken_at(2), Cow::Borrowed(_)));
    }

    #[test]
    fn a_frame_of_2_reads_as_3_with_the_field_absent() {
        let at2 = crate::wire::encode(&*joined(Some(3)).spoken_at(2)).unwrap();
        let read: Event = crate::wire::decode(&at2).unwrap();
        assert_eq!(read, joined(None));
    }
}

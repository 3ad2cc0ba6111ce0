//! The protocol version a frame for a peer is encoded at: what the node agreed on with it.
//!
//! The heartbeat agrees with each peer on the highest version both speak and keeps it in
//! the session table; whatever else a node encodes for a peer in its own frames — the relay
//! forwarding its events to a watcher — asks an [`Agreement`] for that version, so that a
//! node of the next build sends a peer of the build before frames that build reads, and
//! what that version defines and nothing more (`Event::spoken_at`).

use super::sessions::Sessions;
use marie_vocabulary::wire::{ProtocolRange, OLDEST_PROTOCOL, PROTOCOL_VERSION};

/// The versions agreed with a transport's peers, to encode a frame for one of them.
#[derive(Clone)]
pub struct Agreement {
    sessions: Option<Sessions>,
    protocol: ProtocolRange,
}

impl std::fmt::Debug for Agreement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Agreement")
            .field("protocol", &self.protocol)
            .finish_non_exhaustive()
    }
}

impl Agreement {
    /// The agreement of a transport whose heartbeat claims `protocol`.
    pub(crate) fn new(sessions: Sessions, protocol: ProtocolRange) -> Agreement {
        Agreement {
            sessions: Some(sessions),
            protocol,
        }
    }

    /// No transport to ask: every frame at this build's oldest version, which every peer
    /// that speaks with this build reads (a process of one node, tests).
    pub fn none() -> Agreement {
        Agreement {
            sessions: None,
            protocol: ProtocolRange::this_build(),
        }
    }

    /// The version of a frame for the node behind ractor's session number `session`: the
    /// one agreed with it, this node's oldest before its first beat (as the heartbeat
    /// does) — and never one this build cannot encode, whatever range it claims
    /// (`--protocol-range` is for tests).
    pub fn for_session(&self, session: u64) -> u16 {
        let agreed = self
            .sessions
            .as_ref()
            .and_then(|s| s.name_of(session))
            .and_then(|name| self.sessions.as_ref().and_then(|s| s.agreed(&name)));
        clamp(agreed.unwrap_or(self.protocol.oldest))
    }
}

/// `version` within what this build encodes, [`OLDEST_PROTOCOL`]`..=`[`PROTOCOL_VERSION`].
fn clamp(version: u16) -> u16 {
    version.clamp(OLDEST_PROTOCOL, PROTOCOL_VERSION)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_peer_not_heard_yet_gets_the_oldest_version() {
        let a = Agreement::new(Sessions::new("me"), ProtocolRange::this_build());
        assert_eq!(a.for_session(7), OLDEST_PROTOCOL);
        assert_eq!(Agreement::none().for_session(7), OLDEST_PROTOCOL);
    }

    #[test]
    fn a_claimed_range_never_makes_a_version_this_build_cannot_encode() {
        assert_eq!(clamp(PROTOCOL_VERSION + 2), PROTOCOL_VERSION);
        assert_eq!(clamp(OLDEST_PROTOCOL.saturating_sub(1)), OLDEST_PROTOCOL);
        let far = ProtocolRange::single(PROTOCOL_VERSION + 2);
        assert_eq!(
            Agreement::new(Sessions::new("me"), far).for_session(1),
            PROTOCOL_VERSION
        );
    }
}

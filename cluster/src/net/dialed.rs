//! The sessions this node dialed, opened and ended: what tells a dialer that the session it
//! dialed is gone before it became ready.
//!
//! `ractor_cluster::client_connect` returns as soon as the connection is handed to the node
//! server, before the handshake; it names no session. Every way the dialed session can then
//! be turned away — the peer refuses it as a duplicate (around a restart both nodes dial
//! each other and ractor_cluster keeps one session: `NotOk`, `session_election_lost`,
//! `duplicate_connection`), the handshake fails (`auth_fail`), the peer closes the socket
//! (`tcp_session_closed`), this node refuses it — stops its `NodeSession`, and the node
//! server tells `node_session_disconnected`. A session that never became ready changes no
//! peer, so a dialer that waited only for its peer to be ready waited out its whole timeout
//! (2 s) before the next dial. [`OwnDial`] picks the dialer's session out of the
//! [`Dialed`] news so that it can stop waiting when that one ends.

/// News of a session this node dialed (an outgoing one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Dialed {
    /// The node server opened a session on a connection this node dialed.
    Opened {
        /// ractor's number for the session.
        session: u64,
        /// The address dialed (`ip:port`, the connection's peer address).
        to: String,
    },
    /// That session ended (whether or not it was ever ready).
    Ended {
        /// ractor's number for the session.
        session: u64,
    },
}

/// One dial's session among the [`Dialed`] news heard since just before the dial: the first
/// session opened to the address dialed. (Dials to one address never overlap — the
/// transport's `dialing` set — so that one is this dial's.)
#[derive(Debug)]
pub(crate) struct OwnDial {
    to: String,
    session: Option<u64>,
}

impl OwnDial {
    /// The session of a dial to `to` (`ip:port`), not opened yet.
    pub(crate) fn new(to: String) -> Self {
        OwnDial { to, session: None }
    }

    /// Hear `news`: true when it is the end of this dial's session.
    pub(crate) fn ended(&mut self, news: &Dialed) -> bool {
        match news {
            Dialed::Opened { session, to } if self.session.is_none() && *to == self.to => {
                self.session = Some(*session);
                false
            }
            Dialed::Ended { session } => self.session == Some(*session),
            Dialed::Opened { .. } => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opened(session: u64, to: &str) -> Dialed {
        Dialed::Opened {
            session,
            to: to.into(),
        }
    }

    #[test]
    fn only_the_end_of_the_first_session_opened_to_the_address_dialed_ends_the_dial() {
        let mut dial = OwnDial::new("127.0.0.1:7100".into());
        // another session ends before this dial's is opened: not this dial's
        assert!(!dial.ended(&Dialed::Ended { session: 3 }));
        // a session opened to another address, and its end
        assert!(!dial.ended(&opened(4, "127.0.0.1:7200")));
        assert!(!dial.ended(&Dialed::Ended { session: 4 }));
        // this dial's session, then a later one to the same address (not this dial's)
        assert!(!dial.ended(&opened(5, "127.0.0.1:7100")));
        assert!(!dial.ended(&opened(6, "127.0.0.1:7100")));
        assert!(!dial.ended(&Dialed::Ended { session: 6 }));
        assert!(dial.ended(&Dialed::Ended { session: 5 }));
    }
}

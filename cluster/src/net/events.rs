//! The transport's news — peers up, lost, declared down or refused, this node frozen — as
//! [`NetEvent`]s: plain data, told by the sessions and the heartbeat, put on the node's
//! event bus by [`publish_on`](super::publish_on).

use marie_vocabulary::run::Build;
use marie_vocabulary::wire::envelope::speaks;
use marie_vocabulary::wire::ProtocolRange;
use std::time::Duration;

/// What a refusal of another protocol says to do.
pub const UPGRADE_ADVICE: &str =
    "upgrade the cluster one build at a time: a build speaks its own protocol and the one before";

/// What the transport tells of its peers, as it happens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NetEvent {
    /// A peer's first session became ready: its modules are in the registry.
    PeerUp {
        /// Its node name.
        peer: String,
        /// The address it listens on.
        address: String,
    },
    /// A peer's last ready session ended (it left, its connection broke, or it was declared
    /// down): its modules have left the registry.
    PeerLost {
        /// Its node name.
        peer: String,
        /// The address it listened on.
        address: String,
    },
    /// A peer stayed silent past the deadline and was declared down.
    PeerDown {
        /// Its node name.
        peer: String,
        /// How long it had been silent.
        silent: Duration,
    },
    /// This node itself was frozen (stopped, starved) past its peers' deadline: they have
    /// declared it down and replaced its operations, so it must rejoin as a new
    /// incarnation. Found by its own ticks (one came more than its deadline late) or told
    /// by a peer's heartbeat once back; once per freeze.
    Frozen {
        /// How long it was frozen: the gap between its own ticks, or the silence the peer
        /// that told it measured.
        silent: Duration,
    },
    /// A peer speaks no protocol version this node speaks and was refused.
    PeerRefused {
        /// Its node name.
        peer: String,
        /// The protocol versions it speaks.
        theirs: ProtocolRange,
        /// Those this node speaks.
        ours: ProtocolRange,
        /// Its build, as its beat named it (`None` from a build that does not say).
        their_build: Option<Build>,
        /// This node's build.
        our_build: Build,
    },
    /// An incoming connection was refused before it became a session: with TLS on, it
    /// presented no valid certificate (none, one of another CA, one naming another
    /// address) or no handshake in time; or its node failed the cookie challenge on
    /// several connections in a row.
    ConnectionRefused {
        /// Where it came from.
        from: std::net::SocketAddr,
        /// Why.
        reason: String,
    },
    /// This node refused the node it dialed before a session: with TLS on, that node's
    /// certificate does not chain to the CA or names another address. Told once until a
    /// session with that address is ready or the reason changes (the dial is retried).
    DialRefused {
        /// The address dialed.
        to: std::net::SocketAddr,
        /// Why.
        reason: String,
    },
    /// A peer this node dialed refused it at authentication, on several connections in a
    /// row: their cookies differ. Told once per such run of refusals.
    RefusedBy {
        /// The peer's node name.
        peer: String,
        /// The address it listens on.
        address: String,
        /// Why.
        reason: String,
    },
}

impl std::fmt::Display for NetEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NetEvent::PeerUp { peer, address } => write!(f, "sees {peer} at {address}"),
            NetEvent::PeerLost { peer, address } => write!(f, "lost {peer} at {address}"),
            NetEvent::PeerDown { peer, silent } => write!(
                f,
                "declared {peer} down: no heartbeat for {} ms",
                silent.as_millis()
            ),
            NetEvent::Frozen { silent } => write!(
                f,
                "was frozen for {} ms: its peers have declared it down",
                silent.as_millis()
            ),
            NetEvent::PeerRefused {
                peer,
                theirs,
                ours,
                their_build,
                our_build,
            } => {
                let their_build = their_build
                    .as_ref()
                    .map_or_else(|| "a build that does not say".to_string(), Build::to_string);
                write!(
                    f,
                    "refused {peer}: it speaks {} (build {their_build}), this node speaks {} \
                     (build {our_build}); {UPGRADE_ADVICE}",
                    speaks(theirs.oldest, theirs.newest),
                    speaks(ours.oldest, ours.newest),
                )
            }
            NetEvent::ConnectionRefused { from, reason } => {
                write!(f, "refused a connection from {from}: {reason}")
            }
            NetEvent::DialRefused { to, reason } => {
                write!(f, "refused the node it dialed at {to}: {reason}")
            }
            NetEvent::RefusedBy {
                peer,
                address,
                reason,
            } => write!(f, "was refused by {peer} at {address}: {reason}"),
        }
    }
}

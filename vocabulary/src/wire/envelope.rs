//! The versioned envelope of cluster frames: `{ version, kind, payload }` in MessagePack.
//!
//! A node refuses a frame whose protocol version it does not speak (outside
//! [`OLDEST_PROTOCOL`]`..=`[`PROTOCOL_VERSION`]), with an error naming both, instead of
//! misreading it; payloads are decoded only after that check. No input makes it panic:
//! bytes that are not an envelope are an [`EnvelopeError`].
//!
//! Two nodes agree on one version per peer ([`ProtocolRange::agree`](super::ProtocolRange)),
//! and a frame for a peer carries the agreed one ([`Envelope::at`]). What may change within
//! a protocol version and what needs a new one is written in `docs/compatibility.md`: in
//! short, a field added with `#[serde(default)]` is compatible; a renamed, retyped or
//! re-meant field or variant, or a new variant an older node would have to understand, is
//! a new protocol version.
//!
//! ```
//! use marie_vocabulary::wire::envelope::{Envelope, PROTOCOL_VERSION};
//! let frame = Envelope::new("heartbeat", &42u64).unwrap().to_bytes().unwrap();
//! let back = Envelope::from_bytes(&frame).unwrap();
//! assert_eq!(back.version, PROTOCOL_VERSION);
//! assert_eq!(back.payload::<u64>().unwrap(), 42);
//! ```

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// The protocol version this build speaks. Raise it when a message or frame changes in a
/// way older nodes would misread or drop (a renamed or retyped field or variant, a field with
/// another meaning, a variant they must understand); a struct's field added with
/// `#[serde(default)]` or as an `Option`, or a `remote_message!` variant's field added as an
/// `Option`, does not need one. The rules, each with its test: `docs/compatibility.md`.
///
/// 2: one fault vocabulary (`Inject` carries a `FaultKind`), the dispatcher answers a run
/// with its outcome, fault events carry no run time of their own.
///
/// 3 (feature `next-protocol` only: the second build the two-build tests run beside this
/// one): a module's `joined`/`left` event names the newest protocol version of its node
/// (`ModuleInfo::speaks`), which a frame for a peer agreed on 2 leaves out.
#[cfg(not(feature = "next-protocol"))]
pub const PROTOCOL_VERSION: u16 = 2;
/// The protocol version this build speaks: 3, the next build's (see the doc of the
/// default build's constant).
#[cfg(feature = "next-protocol")]
pub const PROTOCOL_VERSION: u16 = 3;

/// The oldest protocol version this build speaks. A build speaks its own version and, when
/// it can, the one before, so that a cluster is upgraded one node at a time. This build
/// speaks 2 alone: version 1's fault vocabulary (`Inject` without a `FaultKind`) and runs
/// answered without their outcome are gone from this build's code, so it could only
/// misread a node of 1. The next protocol version's build (feature `next-protocol`) keeps
/// it at 2: it speaks 2..=3.
pub const OLDEST_PROTOCOL: u16 = 2;

/// Why a frame was refused.
#[derive(Debug, thiserror::Error)]
pub enum EnvelopeError {
    /// The bytes are not an envelope.
    #[error("malformed frame: {0}")]
    Malformed(String),
    /// A protocol version this node does not speak.
    #[error("frame of protocol version {got}, this node speaks {}", speaks(*oldest, *ours))]
    Version {
        /// Version of the frame.
        got: u16,
        /// The newest version this node speaks ([`PROTOCOL_VERSION`]).
        ours: u16,
        /// The oldest ([`OLDEST_PROTOCOL`]).
        oldest: u16,
    },
    /// The payload is not of the expected type.
    #[error("payload of `{kind}` does not decode: {reason}")]
    Payload {
        /// Kind of frame.
        kind: String,
        /// Decoder's message.
        reason: String,
    },
}

/// `protocol version N`, or `protocol versions LO..=HI`: how errors and events name what a
/// node speaks.
pub fn speaks(oldest: u16, newest: u16) -> String {
    if oldest == newest {
        format!("protocol version {newest}")
    } else {
        format!("protocol versions {oldest}..={newest}")
    }
}

/// One frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// Protocol version of the sender.
    pub version: u16,
    /// What the payload is.
    pub kind: String,
    /// MessagePack payload.
    #[serde(with = "bytes")]
    pub payload: Vec<u8>,
}

/// Payload bytes as a MessagePack `bin` (compact), accepting an array of u8 too.
mod bytes {
    use serde::{Deserializer, Serializer};

    pub(super) fn serialize<S: Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(v)
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Vec<u8>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("bytes")
            }
            fn visit_bytes<E>(self, v: &[u8]) -> Result<Vec<u8>, E> {
                Ok(v.to_vec())
            }
            fn visit_byte_buf<E>(self, v: Vec<u8>) -> Result<Vec<u8>, E> {
                Ok(v)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<Vec<u8>, A::Error> {
                let mut out = Vec::new();
                while let Some(b) = a.next_element::<u8>()? {
                    out.push(b);
                }
                Ok(out)
            }
        }
        d.deserialize_bytes(V)
    }
}

impl Envelope {
    /// Wrap `payload` as a frame of `kind`, at this build's protocol version.
    pub fn new<T: Serialize>(kind: &str, payload: &T) -> Result<Self, EnvelopeError> {
        Envelope::at(PROTOCOL_VERSION, kind, payload)
    }

    /// Wrap `payload` as a frame of `kind` at protocol `version`: the one agreed with the
    /// peer it is for.
    pub fn at<T: Serialize>(version: u16, kind: &str, payload: &T) -> Result<Self, EnvelopeError> {
        Ok(Envelope {
            version,
            kind: kind.to_string(),
            payload: rmp_serde::to_vec_named(payload)
                .map_err(|e| EnvelopeError::Malformed(e.to_string()))?,
        })
    }

    /// Encode the frame.
    pub fn to_bytes(&self) -> Result<Vec<u8>, EnvelopeError> {
        rmp_serde::to_vec_named(self).map_err(|e| EnvelopeError::Malformed(e.to_string()))
    }

    /// Decode a frame and check that this build speaks its version.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, EnvelopeError> {
        let env: Envelope =
            rmp_serde::from_slice(bytes).map_err(|e| EnvelopeError::Malformed(e.to_string()))?;
        if !(OLDEST_PROTOCOL..=PROTOCOL_VERSION).contains(&env.version) {
            return Err(EnvelopeError::Version {
                got: env.version,
                ours: PROTOCOL_VERSION,
                oldest: OLDEST_PROTOCOL,
            });
        }
        Ok(env)
    }

    /// [`Envelope::from_bytes`] for a frame from `peer`: a refused frame is logged as a
    /// warning naming the peer (dropped with a warning, never a panic).
    pub fn from_peer(peer: &str, bytes: &[u8]) -> Result<Self, EnvelopeError> {
        Envelope::from_bytes(bytes).inspect_err(
            |e| tracing::warn!(%peer, error = %e, len = bytes.len(), "frame from a peer refused"),
        )
    }

    /// Decode the payload.
    pub fn payload<T: DeserializeOwned>(&self) -> Result<T, EnvelopeError> {
        rmp_serde::from_slice(&self.payload).map_err(|e| EnvelopeError::Payload {
            kind: self.kind.clone(),
            reason: e.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Beat {
        node: String,
        seq: u64,
        tags: Vec<String>,
    }

    fn beat() -> Beat {
        Beat {
            node: "a@localhost".into(),
            seq: 7,
            tags: vec!["x".into(), "y".into()],
        }
    }

    #[test]
    fn a_frame_round_trips() {
        let frame = Envelope::new("heartbeat", &beat())
            .unwrap()
            .to_bytes()
            .unwrap();
        let env = Envelope::from_peer("b@localhost", &frame).unwrap();
        assert_eq!(
            (env.version, env.kind.as_str()),
            (PROTOCOL_VERSION, "heartbeat")
        );
        assert_eq!(env.payload::<Beat>().unwrap(), beat());
    }

    #[test]
    fn a_frame_of_another_version_is_refused_naming_both_versions() {
        let mut env = Envelope::new("x", &"hello").unwrap();
        env.version = PROTOCOL_VERSION + 8;
        let bytes = env.to_bytes().unwrap();
        let err = Envelope::from_peer("old@localhost", &bytes).unwrap_err();
        assert!(
            matches!(err, EnvelopeError::Version { got, ours, .. } if got == PROTOCOL_VERSION + 8 && ours == PROTOCOL_VERSION)
        );
        let text = err.to_string();
        assert!(text.contains(&(PROTOCOL_VERSION + 8).to_string()), "{text}");
        assert!(
            text.contains(&format!(
                "speaks {}",
                speaks(OLDEST_PROTOCOL, PROTOCOL_VERSION)
            )),
            "{text}"
        );
    }

    #[test]
    fn a_frame_at_the_agreed_version_carries_it_and_every_spoken_version_reads() {
        for version in OLDEST_PROTOCOL..=PROTOCOL_VERSION {
            let bytes = Envelope::at(version, "x", &1u8)
                .unwrap()
                .to_bytes()
                .unwrap();
            assert_eq!(Envelope::from_bytes(&bytes).unwrap().version, version);
        }
        let older = Envelope::at(OLDEST_PROTOCOL - 1, "x", &1u8).unwrap();
        assert!(matches!(
            Envelope::from_bytes(&older.to_bytes().unwrap()),
            Err(EnvelopeError::Version { got, .. }) if got == OLDEST_PROTOCOL - 1
        ));
    }

    #[test]
    fn garbage_and_cut_frames_are_refused() {
        let bytes = Envelope::new("x", &"hello").unwrap().to_bytes().unwrap();
        assert!(matches!(
            Envelope::from_bytes(&[0xc1, 0x00, 0x17]),
            Err(EnvelopeError::Malformed(_))
        ));
        assert!(Envelope::from_bytes(&[]).is_err());
        for cut in 0..bytes.len() {
            assert!(Envelope::from_bytes(&bytes[..cut]).is_err());
        }
    }

    #[test]
    fn payload_of_the_wrong_type_is_an_error() {
        let env = Envelope::new("n", &"text").unwrap();
        assert!(matches!(
            env.payload::<u64>(),
            Err(EnvelopeError::Payload { .. })
        ));
    }

    /// A small deterministic generator (xorshift64*), so the fuzz loop needs no dependency
    /// and a failure repeats.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }

        fn below(&mut self, n: usize) -> usize {
            (self.next() % n.max(1) as u64) as usize
        }
    }

    #[test]
    fn mangled_frames_never_panic() {
        let good = Envelope::new("heartbeat", &beat())
            .unwrap()
            .to_bytes()
            .unwrap();
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut refused, mut read) = (0, 0);
        for _ in 0..20_000 {
            let mut bytes = good.clone();
            for _ in 0..=rng.below(4) {
                match rng.below(5) {
                    0 => {
                        let i = rng.below(bytes.len());
                        if let Some(b) = bytes.get_mut(i) {
                            *b ^= 1 << rng.below(8);
                        }
                    }
                    1 => {
                        let i = rng.below(bytes.len());
                        if let Some(b) = bytes.get_mut(i) {
                            *b = rng.next() as u8;
                        }
                    }
                    2 => bytes.truncate(rng.below(bytes.len() + 1)),
                    3 => {
                        let i = rng.below(bytes.len() + 1);
                        bytes.insert(i, rng.next() as u8);
                    }
                    _ => bytes = (0..rng.below(64)).map(|_| rng.next() as u8).collect(),
                }
            }
            // whatever the bytes, an answer and no panic; a frame that reads may still
            // carry a payload that does not
            match Envelope::from_bytes(&bytes) {
                Ok(env) => {
                    read += 1;
                    let _ = env.payload::<Beat>();
                }
                Err(_) => refused += 1,
            }
        }
        assert!(refused > 0 && refused + read == 20_000);
    }
}

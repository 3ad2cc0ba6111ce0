//! The versioned envelope of cluster frames: `{ version, kind, payload }` in MessagePack.
//!
//! A node refuses a frame whose version it does not speak, with an error naming both
//! versions, instead of misreading it; payloads are decoded only after that check.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// The wire version this build speaks.
pub const WIRE_VERSION: u16 = 1;

/// Why a frame was refused.
#[derive(Debug, thiserror::Error)]
pub enum EnvelopeError {
    /// The bytes are not an envelope.
    #[error("malformed frame: {0}")]
    Malformed(String),
    /// Another wire version.
    #[error("frame of wire version {got}, this node speaks {WIRE_VERSION}")]
    Version {
        /// Version of the frame.
        got: u16,
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

/// One frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// Wire version of the sender.
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

    pub fn serialize<S: Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(v)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Vec<u8>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
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
    /// Wrap `payload` as a frame of `kind`.
    pub fn new<T: Serialize>(kind: &str, payload: &T) -> Result<Self, EnvelopeError> {
        Ok(Envelope {
            version: WIRE_VERSION,
            kind: kind.to_string(),
            payload: rmp_serde::to_vec_named(payload)
                .map_err(|e| EnvelopeError::Malformed(e.to_string()))?,
        })
    }

    /// Encode the frame.
    pub fn to_bytes(&self) -> Result<Vec<u8>, EnvelopeError> {
        rmp_serde::to_vec_named(self).map_err(|e| EnvelopeError::Malformed(e.to_string()))
    }

    /// Decode a frame and check its version.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, EnvelopeError> {
        let env: Envelope =
            rmp_serde::from_slice(bytes).map_err(|e| EnvelopeError::Malformed(e.to_string()))?;
        if env.version != WIRE_VERSION {
            return Err(EnvelopeError::Version { got: env.version });
        }
        Ok(env)
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

    #[test]
    fn other_versions_and_garbage_are_refused() {
        let mut env = Envelope::new("x", &"hello").unwrap();
        env.version = 9;
        let bytes = rmp_serde::to_vec_named(&env).unwrap();
        assert!(matches!(
            Envelope::from_bytes(&bytes),
            Err(EnvelopeError::Version { got: 9 })
        ));
        assert!(matches!(
            Envelope::from_bytes(&[0xc1, 0x00, 0x17]),
            Err(EnvelopeError::Malformed(_))
        ));
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
}

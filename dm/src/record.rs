//! Records: what a datamanager stores.
//!
//! A producer hands the DM a [`NewRecord`] — its own name as `source`, a class, up to two
//! sub-classes and an opaque MessagePack [`Payload`]. The DM adds the header fields the thesis
//! names (3.2.5.2): a sequence number (strictly increasing per DM, from 1) and a time stamp
//! from its clock, and hands the result back as a [`Record`].

use super::error::DmError;
use super::name::Name;
use super::packed::Packed;
use super::shared::{decode_bytes, PayloadType, Shared};
use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::sync::Arc;
use std::time::Duration;

/// Longest class, sub-class or source name, in bytes.
pub const MAX_NAME_LEN: usize = 255;

/// An opaque MessagePack value that producer and consumer agree on.
///
/// It travels as MessagePack `bin` (one length prefix, not one tag per byte) and also reads a
/// sequence of bytes, so JSON or a peer that wrote an array of `u8` can be decoded too.
///
/// # Decoded once in the datamanager's process
/// A payload a producer made, or one that came from another node, is its bytes. A payload a
/// datamanager hands out in its own process is shared with the store and with every other
/// reader of the same record, together with the value the first typed read decoded: later
/// reads of that type take the value instead of decoding again (see
/// [`PayloadType`](super::PayloadType)). What a read returns is what decoding the bytes
/// returns, wherever the record was read; only the cost differs.
#[derive(Clone, Default)]
pub struct Payload(Repr);

#[derive(Clone)]
enum Repr {
    /// Bytes of its own: a producer's, or a peer's.
    Owned(Vec<u8>),
    /// A stored record's bytes, shared with its readers, with the value decoded once.
    Shared(Arc<Shared>),
}

impl Default for Repr {
    fn default() -> Repr {
        Repr::Owned(Vec::new())
    }
}

impl Payload {
    /// Encode `value` as MessagePack (a map with field names, so fields can be added later).
    pub fn encode<T: Serialize + ?Sized>(value: &T) -> Result<Payload, DmError> {
        marie_vocabulary::wire::encode(value)
            .map(Payload::from_bytes)
            .map_err(|e| DmError::Encode(e.to_string()))
    }

    /// Decode the payload as a `T` — or, for a stored record read in its datamanager's
    /// process, a clone of the value an earlier read of the same type decoded.
    pub fn decode<T: PayloadType>(&self) -> Result<T, DmError> {
        match &self.0 {
            Repr::Owned(bytes) => decode_bytes(bytes),
            Repr::Shared(shared) => shared.value::<T>().map(Arc::unwrap_or_clone),
        }
    }

    /// The payload as a `T` shared with the other readers of the record in this process: no
    /// copy of the value, for a reader that only looks at it. Decoded as
    /// [`Payload::decode`] decodes.
    pub fn decode_shared<T: PayloadType>(&self) -> Result<Arc<T>, DmError> {
        match &self.0 {
            Repr::Owned(bytes) => decode_bytes(bytes).map(Arc::new),
            Repr::Shared(shared) => shared.value::<T>(),
        }
    }

    /// Wrap bytes that are already MessagePack.
    pub fn from_bytes(bytes: Vec<u8>) -> Payload {
        Payload(Repr::Owned(bytes))
    }

    /// A stored record's payload to hand out: `shared` with the store and the other readers.
    pub(crate) fn shared(shared: Arc<Shared>) -> Payload {
        Payload(Repr::Shared(shared))
    }

    /// The raw bytes.
    pub fn as_bytes(&self) -> &[u8] {
        match &self.0 {
            Repr::Owned(bytes) => bytes,
            Repr::Shared(shared) => shared.bytes(),
        }
    }

    /// Size in bytes.
    pub fn len(&self) -> usize {
        self.as_bytes().len()
    }

    /// True for an empty payload.
    pub fn is_empty(&self) -> bool {
        self.as_bytes().is_empty()
    }

    /// The raw bytes, by value (a copy, for a payload shared with other readers).
    pub fn into_bytes(self) -> Vec<u8> {
        match self.into_owned_bytes() {
            Ok(bytes) => bytes,
            Err(shared) => shared.bytes().to_vec(),
        }
    }

    /// The payload as a store keeps it ([`Packed`]): its own buffer kept as it is if large,
    /// copied inline if small; a payload shared with readers is copied.
    pub(crate) fn into_packed(self) -> Packed {
        match self.into_owned_bytes() {
            Ok(data) => Packed::from_vec(data),
            Err(shared) => Packed::copy_of(shared.bytes()),
        }
    }

    /// The bytes if they are the payload's own, else what they are shared in.
    pub(crate) fn into_owned_bytes(self) -> Result<Vec<u8>, Arc<Shared>> {
        match self.0 {
            Repr::Owned(bytes) => Ok(bytes),
            Repr::Shared(shared) => Err(shared),
        }
    }
}

/// Payloads are equal when their bytes are (a kept decoded value is a cache of them).
impl PartialEq for Payload {
    fn eq(&self, other: &Payload) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl Eq for Payload {}

impl std::hash::Hash for Payload {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.as_bytes().hash(state);
    }
}

impl fmt::Debug for Payload {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Payload({} bytes)", self.len())
    }
}

impl Serialize for Payload {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_bytes(self.as_bytes())
    }
}

impl<'de> Deserialize<'de> for Payload {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct BytesVisitor;

        impl<'de> Visitor<'de> for BytesVisitor {
            type Value = Payload;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("bytes or a sequence of u8")
            }

            fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Payload, E> {
                Ok(Payload::from_bytes(v.to_vec()))
            }

            fn visit_byte_buf<E: de::Error>(self, v: Vec<u8>) -> Result<Payload, E> {
                Ok(Payload::from_bytes(v))
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Payload, A::Error> {
                // Cap the pre-allocation: the hint comes from the peer.
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(64 * 1024));
                while let Some(b) = seq.next_element::<u8>()? {
                    out.push(b);
                }
                Ok(Payload::from_bytes(out))
            }
        }

        deserializer.deserialize_byte_buf(BytesVisitor)
    }
}

/// A record as a producer hands it to a datamanager: everything except the header fields
/// the DM fills in.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct NewRecord {
    /// The producer's name (a [`super::DmClient`] fills in its own).
    pub source: String,
    /// The record's class, e.g. `sonar`.
    pub class: String,
    /// First sub-class level, e.g. `front`.
    pub sub1: Option<String>,
    /// Second sub-class level (requires `sub1`), e.g. `narrow`.
    pub sub2: Option<String>,
    /// The MessagePack payload.
    pub payload: Payload,
    /// The epoch of the producer's binding (a [`super::DmClient`] of an activation fills it
    /// in): a record of an older epoch than the newest the DM has seen from the same source
    /// is refused ([`marie_vocabulary::fence`]). 0: unfenced.
    pub epoch: u64,
    /// The producer's id (a [`super::DmClient`] fills in its own, random): with
    /// `producer_seq`, what makes a retried put idempotent. 0: none.
    pub producer: u64,
    /// The producer's own number for this record (1, 2, 3, …): a record the datamanager
    /// has already stored under the same producer and number is not stored again
    /// (`producers`). 0: none.
    pub producer_seq: u64,
}

impl NewRecord {
    /// About the bytes it takes in a message: its payload and names (what cuts a batch of
    /// records into frames below ractor_cluster's 16 MiB, [`super::outbox::frames`], and a
    /// snapshot into parts).
    pub(crate) fn wire_bytes(&self) -> usize {
        self.payload.len()
            + self.class.len()
            + self.source.len()
            + self.sub1.as_ref().map_or(0, String::len)
            + self.sub2.as_ref().map_or(0, String::len)
    }

    /// A record of `class` with `payload`, no sub-classes and no source yet.
    pub fn new(class: impl Into<String>, payload: Payload) -> NewRecord {
        NewRecord {
            class: class.into(),
            payload,
            ..Default::default()
        }
    }

    /// A record of `class` whose payload is `value` encoded as MessagePack.
    pub fn encode<T: Serialize + ?Sized>(
        class: impl Into<String>,
        value: &T,
    ) -> Result<NewRecord, DmError> {
        Ok(NewRecord::new(class, Payload::encode(value)?))
    }

    /// Set the first sub-class.
    pub fn with_sub1(mut self, sub1: impl Into<String>) -> NewRecord {
        self.sub1 = Some(sub1.into());
        self
    }

    /// Set the second sub-class (the record also needs a first one).
    pub fn with_sub2(mut self, sub2: impl Into<String>) -> NewRecord {
        self.sub2 = Some(sub2.into());
        self
    }

    /// Set the producer's name.
    pub fn with_source(mut self, source: impl Into<String>) -> NewRecord {
        self.source = source.into();
        self
    }

    /// Check the names: class and source non-empty, every name at most [`MAX_NAME_LEN`] bytes
    /// without control characters, and `sub2` only together with `sub1`.
    pub fn validate(&self) -> Result<(), DmError> {
        check_name("class", &self.class)?;
        check_name("source", &self.source)?;
        if let Some(s) = &self.sub1 {
            check_name("sub1", s)?;
        }
        if let Some(s) = &self.sub2 {
            check_name("sub2", s)?;
            if self.sub1.is_none() {
                return Err(DmError::InvalidRecord(
                    "a second sub-class needs a first one".to_string(),
                ));
            }
        }
        Ok(())
    }
}

/// Control characters: C0 and DEL are single bytes; C1 (U+0080–U+009F) is only possible in
/// non-ASCII text. (Byte scan first: this runs on every stored record.)
fn has_control(value: &str) -> bool {
    let (mut c0, mut wide) = (false, false);
    for &b in value.as_bytes() {
        c0 |= b < 0x20 || b == 0x7f;
        wide |= b >= 0x80;
    }
    c0 || (wide && value.chars().any(char::is_control))
}

/// Check one name of a record; `field` names it in the error.
pub(crate) fn check_name(field: &str, value: &str) -> Result<(), DmError> {
    let reason = if value.is_empty() {
        "must not be empty"
    } else if value.len() > MAX_NAME_LEN {
        "is longer than 255 bytes"
    } else if has_control(value) {
        "must not contain control characters"
    } else {
        return Ok(());
    };
    let mut shown: String = value.chars().take(64).collect();
    if shown.len() < value.len() {
        shown.push('…');
    }
    Err(DmError::InvalidName {
        field: field.to_string(),
        value: shown,
        reason: reason.to_string(),
    })
}

/// A stored record: the header the DM filled in, the producer's classification and payload.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Record {
    /// Sequence number: per DM, strictly increasing from 1, never reused.
    pub seq: u64,
    /// When the DM stored it, on the DM's clock. Non-decreasing with `seq`.
    pub timestamp: Duration,
    /// The producer's name.
    pub source: Name,
    /// The producer's class.
    pub class: Name,
    /// First sub-class level.
    pub sub1: Option<Name>,
    /// Second sub-class level.
    pub sub2: Option<Name>,
    /// The MessagePack payload.
    pub payload: Payload,
}

impl Record {
    /// Decode the payload as a `T` (see [`Payload::decode`]: decoded once for every
    /// reader in the datamanager's process).
    pub fn decode<T: PayloadType>(&self) -> Result<T, DmError> {
        self.payload.decode()
    }

    /// The payload as a `T` shared with its other readers in this process, without a copy
    /// ([`Payload::decode_shared`]).
    pub fn decode_shared<T: PayloadType>(&self) -> Result<Arc<T>, DmError> {
        self.payload.decode_shared()
    }

    /// Everything but the payload.
    pub fn header(&self) -> RecordHeader {
        RecordHeader {
            seq: self.seq,
            timestamp: self.timestamp,
            source: self.source.clone(),
            class: self.class.clone(),
            sub1: self.sub1.clone(),
            sub2: self.sub2.clone(),
        }
    }

    /// Split into the header and the payload without copying.
    pub fn into_parts(self) -> (RecordHeader, Payload) {
        (
            RecordHeader {
                seq: self.seq,
                timestamp: self.timestamp,
                source: self.source,
                class: self.class,
                sub1: self.sub1,
                sub2: self.sub2,
            },
            self.payload,
        )
    }
}

/// A record without its payload, e.g. beside a decoded value from
/// [`super::DmClient::select_typed`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecordHeader {
    /// Sequence number.
    pub seq: u64,
    /// Time stamp on the DM's clock.
    pub timestamp: Duration,
    /// The producer's name.
    pub source: Name,
    /// The producer's class.
    pub class: Name,
    /// First sub-class level.
    pub sub1: Option<Name>,
    /// Second sub-class level.
    pub sub2: Option<Name>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packed::INLINE;

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct Echo {
        range_m: f64,
        beam: String,
    }

    #[test]
    fn a_payload_is_packed_inline_when_small_whether_its_own_or_shared() {
        for n in [0, 1, INLINE, INLINE + 1, 10_000] {
            let data: Vec<u8> = (0..n).map(|i| (i % 251) as u8).collect();
            let own = Payload::from_bytes(data.clone()).into_packed();
            let shared = Payload::shared(Arc::new(Shared::new(&data))).into_packed();
            for packed in [own, shared] {
                assert_eq!(packed.as_bytes(), &data[..], "{n} bytes");
                assert_eq!(matches!(packed, Packed::Inline { .. }), n <= INLINE, "{n}");
            }
        }
    }

    #[test]
    fn payload_round_trips_typed_values() {
        let v = Echo {
            range_m: 1.25,
            beam: "narrow".into(),
        };
        let p = Payload::encode(&v).unwrap();
        assert_eq!(p.decode::<Echo>().unwrap(), v);
        assert!(matches!(p.decode::<u32>(), Err(DmError::Decode(_))));
    }

    #[test]
    fn payload_travels_as_bin_and_reads_sequences() {
        let p = Payload::from_bytes(vec![1, 2, 3]);
        let bytes = marie_vocabulary::wire::encode(&p).unwrap();
        assert_eq!(bytes, vec![0xc4, 3, 1, 2, 3]); // msgpack bin8
        assert_eq!(
            marie_vocabulary::wire::decode::<Payload>(&bytes).unwrap(),
            p
        );
        let as_array = marie_vocabulary::wire::encode(&vec![1u8, 2, 3]).unwrap();
        assert_eq!(
            marie_vocabulary::wire::decode::<Payload>(&as_array).unwrap(),
            p
        );
        let json = serde_json::to_string(&p).unwrap();
        assert_eq!(serde_json::from_str::<Payload>(&json).unwrap(), p);
        assert!(marie_vocabulary::wire::decode::<Payload>(&[0xc1]).is_err());
    }

    #[test]
    fn record_round_trips() {
        let r = Record {
            seq: 7,
            timestamp: Duration::from_millis(1500),
            source: "ultrasonic".into(),
            class: "sonar".into(),
            sub1: Some("front".into()),
            sub2: None,
            payload: Payload::encode(&3u8).unwrap(),
        };
        let bytes = marie_vocabulary::wire::encode(&r).unwrap();
        assert_eq!(marie_vocabulary::wire::decode::<Record>(&bytes).unwrap(), r);
        let (h, p) = r.clone().into_parts();
        assert_eq!(h, r.header());
        assert_eq!(p, r.payload);
    }

    #[test]
    fn validation_names_the_field() {
        let ok = NewRecord::new("sonar", Payload::default()).with_source("us");
        assert!(ok.validate().is_ok());
        let e = NewRecord::new("", Payload::default())
            .with_source("us")
            .validate();
        assert!(matches!(e, Err(DmError::InvalidName { ref field, .. }) if field == "class"));
        let e = NewRecord::new("sonar", Payload::default()).validate();
        assert!(matches!(e, Err(DmError::InvalidName { ref field, .. }) if field == "source"));
        let e = ok.clone().with_sub1("a\nb").validate();
        assert!(matches!(e, Err(DmError::InvalidName { ref field, .. }) if field == "sub1"));
        let e = ok.clone().with_sub1("a\u{85}b").validate(); // C1 control
        assert!(matches!(e, Err(DmError::InvalidName { ref field, .. }) if field == "sub1"));
        assert!(ok.clone().with_sub1("vorn-ä").validate().is_ok());
        let e = ok.clone().with_sub2("narrow").validate();
        assert!(matches!(e, Err(DmError::InvalidRecord(_))));
        let long = "x".repeat(MAX_NAME_LEN + 1);
        let e = NewRecord::new(long, Payload::default())
            .with_source("us")
            .validate();
        assert!(
            matches!(e, Err(DmError::InvalidName { ref value, .. }) if value.chars().count() == 65)
        );
    }
}

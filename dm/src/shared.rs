//! A stored record's payload as the readers in the datamanager's own process get it: the
//! bytes shared, not copied, and the value decoded from them kept beside them.
//!
//! Records read in the same process used to be decoded from bytes on every read — a
//! localizer that looks at the last second of sonar scans at every step decoded each scan
//! dozens of times, and a profile of a docking run spent most of its time in rmp-serde.
//! Now the first select that hands a record out wraps a copy of its bytes in a [`Shared`]
//! (kept by the store beside the record), and every later select hands out the same
//! [`Arc`]. The first typed read decodes the bytes and keeps the value; every later read of
//! the same type, by anyone in the process, takes that value instead of decoding again.
//!
//! What a read returns does not change: the value is the one decoding the bytes gives —
//! exactly what a reader on another node gets from the same bytes — only computed once. A
//! read as another type than the first reader's decodes the bytes as before (and fails as
//! before if they are not of that type); the kept value is never handed out as a type it is
//! not (`Any` checks the type).

use super::error::DmError;
use super::packed::Packed;
use serde::de::DeserializeOwned;
use std::any::Any;
use std::sync::{Arc, OnceLock};

/// A type a record's payload can be read as, and kept decoded for every reader in the
/// process: `Clone` so that each reader gets its own value from the one decoded, `Send +
/// Sync + 'static` so that the decoded value can be shared between tasks and threads. Every
/// owned data type that derives `Clone` and `Deserialize` is one.
pub trait PayloadType: DeserializeOwned + Clone + Send + Sync + 'static {}

impl<T: DeserializeOwned + Clone + Send + Sync + 'static> PayloadType for T {}

/// Decode MessagePack bytes as a `T` (the one decoding every read goes through).
pub(crate) fn decode_bytes<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, DmError> {
    marie_vocabulary::wire::decode(bytes).map_err(|e| DmError::Decode(e.to_string()))
}

/// The bytes of a stored record's payload and, once a reader asked, the value decoded from
/// them.
pub(crate) struct Shared {
    bytes: Packed,
    decoded: OnceLock<Arc<dyn Any + Send + Sync>>,
}

impl Shared {
    /// A copy of `bytes`, not yet decoded.
    pub(crate) fn new(bytes: &[u8]) -> Shared {
        Shared {
            bytes: Packed::copy_of(bytes),
            decoded: OnceLock::new(),
        }
    }

    /// The MessagePack bytes.
    pub(crate) fn bytes(&self) -> &[u8] {
        self.bytes.as_bytes()
    }

    /// The payload as a `T`: the kept value if it is a `T`, else decoded from the bytes (and
    /// kept, if nothing was kept yet).
    pub(crate) fn value<T: PayloadType>(&self) -> Result<Arc<T>, DmError> {
        if let Some(kept) = self.decoded.get() {
            return match Arc::clone(kept).downcast::<T>() {
                Ok(value) => Ok(value),
                // first read as another type: decode as a read without a kept value would
                Err(_) => decode_bytes::<T>(self.bytes()).map(Arc::new),
            };
        }
        let value = Arc::new(decode_bytes::<T>(self.bytes())?);
        // a reader racing this one may have kept its value first: either is the bytes' value
        let _ = self.decoded.set(value.clone());
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct Echo {
        range: f64,
        beam: String,
    }

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct Range {
        range: f64,
    }

    fn echo() -> Echo {
        Echo {
            range: 1.5,
            beam: "narrow".into(),
        }
    }

    #[test]
    fn the_first_read_decodes_and_later_reads_share_the_value() {
        let shared = Shared::new(&marie_vocabulary::wire::encode(&echo()).unwrap());
        let a = shared.value::<Echo>().unwrap();
        let b = shared.value::<Echo>().unwrap();
        assert_eq!(*a, echo());
        assert!(Arc::ptr_eq(&a, &b), "decoded once");
    }

    #[test]
    fn a_read_as_another_type_decodes_the_bytes_as_before() {
        let shared = Shared::new(&marie_vocabulary::wire::encode(&echo()).unwrap());
        shared.value::<Echo>().unwrap();
        // a compatible type reads what decoding gives (fields it lacks are skipped) ...
        assert_eq!(*shared.value::<Range>().unwrap(), Range { range: 1.5 });
        // ... and a wrong one is the decoding error it always was, never the kept value
        assert!(matches!(shared.value::<u32>(), Err(DmError::Decode(_))));
        assert!(matches!(
            shared.value::<Vec<String>>(),
            Err(DmError::Decode(_))
        ));
        // the first type read is still the one kept
        let (a, b) = (
            shared.value::<Echo>().unwrap(),
            shared.value::<Echo>().unwrap(),
        );
        assert!(Arc::ptr_eq(&a, &b));
    }

    #[test]
    fn a_failed_read_keeps_nothing() {
        let shared = Shared::new(&marie_vocabulary::wire::encode(&echo()).unwrap());
        assert!(shared.value::<u32>().is_err());
        assert_eq!(*shared.value::<Echo>().unwrap(), echo());
        let (a, b) = (
            shared.value::<Echo>().unwrap(),
            shared.value::<Echo>().unwrap(),
        );
        assert!(Arc::ptr_eq(&a, &b));
    }
}

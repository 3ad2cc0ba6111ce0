//! How the [`Store`](super::Store) keeps a record's payload: small ones inside the record's
//! own slot, larger ones on the heap.
//!
//! A datamanager at its retention bound drops one old record for every new one. Were every
//! payload its own heap allocation, each store would free a block allocated a whole retention
//! window ago — memory long gone from the cache — and the allocator would later walk those
//! cold blocks again to merge them. Sensor records (an echo, an odometry reading) are a few
//! dozen bytes, so they are copied into the record's slot in the class's deque, which is
//! reused as a ring: storing and dropping them touches no allocator at all. The producer's
//! buffer is freed at once, while it is still warm.

/// Payloads up to this many bytes are kept inline (a MessagePack map of two or three short
/// numeric fields fits).
pub(crate) const INLINE: usize = 46;

/// A stored payload.
pub(crate) enum Packed {
    /// `len` bytes in `bytes[..len]`.
    Inline { len: u8, bytes: [u8; INLINE] },
    /// A larger payload, in its own allocation.
    Heap(Vec<u8>),
}

impl Packed {
    /// Keep `data` as it is: inline if small, else the buffer itself (no copy).
    pub(crate) fn from_vec(data: Vec<u8>) -> Packed {
        if data.len() > INLINE {
            Packed::Heap(data)
        } else {
            Packed::copy_of(&data)
        }
    }

    /// A copy of `data`: inline if small, else in its own allocation.
    pub(crate) fn copy_of(data: &[u8]) -> Packed {
        if data.len() <= INLINE {
            let mut bytes = [0u8; INLINE];
            bytes[..data.len()].copy_from_slice(data);
            Packed::Inline {
                len: data.len() as u8,
                bytes,
            }
        } else {
            Packed::Heap(data.to_vec())
        }
    }

    /// The stored bytes.
    pub(crate) fn as_bytes(&self) -> &[u8] {
        match self {
            Packed::Inline { len, bytes } => &bytes[..usize::from(*len)],
            Packed::Heap(data) => data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_payloads_are_inline_and_large_ones_on_the_heap() {
        for n in [0, 1, INLINE - 1, INLINE, INLINE + 1, 10_000] {
            let data: Vec<u8> = (0..n).map(|i| (i % 251) as u8).collect();
            let packed = Packed::from_vec(data.clone());
            assert_eq!(packed.as_bytes(), &data[..], "{n} bytes");
            assert_eq!(Packed::copy_of(&data).as_bytes(), &data[..], "{n} bytes");
            assert_eq!(matches!(packed, Packed::Inline { .. }), n <= INLINE, "{n}");
        }
    }

    #[test]
    fn a_packed_payload_is_no_larger_than_a_vec_and_its_block() {
        // the slot costs 48 bytes; a Vec costs 24 plus a heap block of at least 32
        assert!(std::mem::size_of::<Packed>() <= 48);
    }
}

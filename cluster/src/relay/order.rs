//! A watcher's side of the numbering: each forwarder's stream taken in order, what it
//! already has dropped (a forwarder resends its backlog to a watcher that comes back), and
//! the gaps — events a forwarder no longer held — counted.

use std::collections::HashMap;

/// At most this many streams are followed (a node's forwarder is one stream; a node
/// process started again is a new one); past it the one heard from least recently is
/// forgotten.
const STREAMS_KEPT: usize = 256;

/// What to do with a numbered event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Admit {
    /// Take it; `missed` events of its stream before it will never come.
    Take {
        /// How many.
        missed: u64,
    },
    /// Already taken: drop it.
    Duplicate,
}

#[derive(Debug)]
struct Heard {
    /// The last number taken.
    last: u64,
    /// When it was last heard from, in admissions.
    at: u64,
}

/// Where each stream stands.
#[derive(Debug, Default)]
pub(super) struct Order {
    streams: HashMap<u64, Heard>,
    admissions: u64,
}

impl Order {
    /// Event `seq` of `stream` has come. The first event of a stream is taken whatever its
    /// number (this watcher came in the middle of it).
    pub(super) fn admit(&mut self, stream: u64, seq: u64) -> Admit {
        self.admissions += 1;
        let at = self.admissions;
        if let Some(heard) = self.streams.get_mut(&stream) {
            if seq <= heard.last {
                return Admit::Duplicate;
            }
            let missed = seq - heard.last - 1;
            *heard = Heard { last: seq, at };
            return Admit::Take { missed };
        }
        if self.streams.len() >= STREAMS_KEPT {
            if let Some(oldest) = self
                .streams
                .iter()
                .min_by_key(|(_, h)| h.at)
                .map(|(s, _)| *s)
            {
                self.streams.remove(&oldest);
            }
        }
        self.streams.insert(stream, Heard { last: seq, at });
        Admit::Take { missed: 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_stream_is_taken_in_order_once_and_its_gaps_counted() {
        let mut o = Order::default();
        let take = |missed| Admit::Take { missed };
        assert_eq!(o.admit(1, 40), take(0), "joined in the middle");
        assert_eq!(o.admit(1, 41), take(0));
        assert_eq!(o.admit(2, 3), take(0), "another stream");
        // a resent backlog: what was taken is dropped, the rest taken in order
        assert_eq!(o.admit(1, 39), Admit::Duplicate);
        assert_eq!(o.admit(1, 41), Admit::Duplicate);
        assert_eq!(o.admit(1, 42), take(0));
        // the backlog had lost 43 and 44
        assert_eq!(o.admit(1, 45), take(2));
        assert_eq!(o.admit(2, 4), take(0));
    }

    #[test]
    fn the_stream_heard_from_least_recently_is_forgotten_past_the_limit() {
        let mut o = Order::default();
        for stream in 0..STREAMS_KEPT as u64 {
            o.admit(stream, 10);
        }
        o.admit(0, 11); // stream 1 is now the least recent
        o.admit(9999, 1);
        assert_eq!(o.streams.len(), STREAMS_KEPT);
        assert_eq!(o.admit(0, 11), Admit::Duplicate, "kept");
        assert_eq!(
            o.admit(1, 5),
            Admit::Take { missed: 0 },
            "forgotten: new again"
        );
    }
}

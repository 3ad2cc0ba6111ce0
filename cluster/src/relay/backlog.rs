//! The frames of a forwarder's latest events, kept for a watcher that comes back.

use std::collections::VecDeque;

/// At most this many events are kept for watchers out of reach: a node that wakes from a
/// freeze publishes a few dozen (that it was frozen, the peers it lost and sees again, the
/// restart of its operations); a cart node's poses, ten a second, fill it in a minute and
/// a half.
pub const BACKLOG_EVENTS: usize = 1024;
/// … and at most this many bytes of their frames (a robot's `world` event is the biggest,
/// a few kB).
pub const BACKLOG_BYTES: usize = 4 << 20;

/// Numbered frames, oldest first, within [`BACKLOG_EVENTS`] and [`BACKLOG_BYTES`]: a new
/// one pushes the oldest out.
#[derive(Debug)]
pub(super) struct Backlog {
    frames: VecDeque<(u64, Vec<u8>)>,
    bytes: usize,
    max_events: usize,
    max_bytes: usize,
}

impl Default for Backlog {
    fn default() -> Self {
        Backlog::with_bounds(BACKLOG_EVENTS, BACKLOG_BYTES)
    }
}

impl Backlog {
    /// A backlog of at most `max_events` frames and `max_bytes` bytes (the newest frame is
    /// kept even when alone it is bigger).
    pub(super) fn with_bounds(max_events: usize, max_bytes: usize) -> Backlog {
        Backlog {
            frames: VecDeque::new(),
            bytes: 0,
            max_events: max_events.max(1),
            max_bytes,
        }
    }

    /// Keep frame `seq` (numbers only grow), dropping the oldest past the bounds.
    pub(super) fn push(&mut self, seq: u64, frame: Vec<u8>) {
        self.bytes += frame.len();
        self.frames.push_back((seq, frame));
        while self.frames.len() > self.max_events
            || (self.bytes > self.max_bytes && self.frames.len() > 1)
        {
            if let Some((_, old)) = self.frames.pop_front() {
                self.bytes -= old.len();
            }
        }
    }

    /// The frames kept from number `from` on, in order.
    pub(super) fn since(&self, from: u64) -> impl Iterator<Item = (u64, &Vec<u8>)> {
        let first = self.frames.partition_point(|(seq, _)| *seq < from);
        self.frames.range(first..).map(|(seq, frame)| (*seq, frame))
    }

    /// Keep nothing (no watcher is known any more).
    pub(super) fn clear(&mut self) {
        self.frames.clear();
        self.bytes = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seqs(b: &Backlog, from: u64) -> Vec<u64> {
        b.since(from).map(|(s, _)| s).collect()
    }

    #[test]
    fn the_oldest_frames_go_past_either_bound() {
        let mut b = Backlog::with_bounds(3, 100);
        for seq in 1..=5 {
            b.push(seq, vec![0; 10]);
        }
        assert_eq!(seqs(&b, 0), [3, 4, 5]);
        assert_eq!(seqs(&b, 4), [4, 5]);
        assert_eq!(seqs(&b, 6), Vec::<u64>::new());
        // two of 46 bytes leave no room for a third in 100; a bigger one is kept alone
        b.push(6, vec![0; 46]);
        b.push(7, vec![0; 46]);
        assert_eq!(seqs(&b, 0), [6, 7]);
        b.push(8, vec![0; 500]);
        assert_eq!(seqs(&b, 0), [8]);
        b.clear();
        assert_eq!(seqs(&b, 0), Vec::<u64>::new());
        b.push(9, vec![0; 46]);
        b.push(10, vec![0; 46]);
        assert_eq!(seqs(&b, 0), [9, 10], "the byte count started over");
    }
}

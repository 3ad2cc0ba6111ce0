//! The failure detector's bookkeeping: when each peer was last heard from, and which are
//! overdue. Pure (time is passed in), so its rules are tested without processes.
//!
//! # Invariants
//! - A peer is judged only while a session with it is ready; its silence counts from the
//!   later of its last heartbeat and the moment its session became ready.
//! - When the detector itself was frozen (a tick came more than a deadline late: the
//!   process was stopped, or starved), nobody is declared down on that tick and every
//!   silence restarts: the silence was this node's, not its peers'.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Smallest deadline accepted: below it, a loaded 2-core machine's scheduling alone would
/// declare healthy peers down.
pub const MIN_DEADLINE: Duration = Duration::from_millis(300);
/// Default deadline: 1.2 s of silence, which with the check every period (240 ms) declares
/// a peer down within 1.5 s of its last heartbeat.
pub const DEFAULT_DEADLINE: Duration = Duration::from_millis(1200);
/// Heartbeats per deadline: a peer is declared down only after this many beats in a row
/// went missing.
pub const BEATS_PER_DEADLINE: u32 = 5;

/// How often heartbeats go out and how long a peer may stay silent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeartbeatConfig {
    /// Time between two heartbeats to each peer.
    pub period: Duration,
    /// A peer silent this long is declared down.
    pub deadline: Duration,
}

impl Default for HeartbeatConfig {
    fn default() -> Self {
        HeartbeatConfig::with_deadline(DEFAULT_DEADLINE)
    }
}

impl HeartbeatConfig {
    /// A deadline, with [`BEATS_PER_DEADLINE`] heartbeats in it.
    pub fn with_deadline(deadline: Duration) -> Self {
        HeartbeatConfig {
            period: deadline / BEATS_PER_DEADLINE,
            deadline,
        }
    }

    /// Check the deadline and period against each other.
    pub fn validate(&self) -> Result<(), HeartbeatError> {
        if self.deadline < MIN_DEADLINE {
            return Err(HeartbeatError::DeadlineTooShort {
                deadline: self.deadline,
                min: MIN_DEADLINE,
            });
        }
        if self.period.is_zero() {
            return Err(HeartbeatError::ZeroPeriod {
                deadline: self.deadline,
            });
        }
        if self.period * 2 > self.deadline {
            return Err(HeartbeatError::PeriodTooLong {
                period: self.period,
                deadline: self.deadline,
            });
        }
        Ok(())
    }
}

/// Heartbeat settings that cannot work ([`HeartbeatConfig::validate`]), with the durations
/// a caller needs to correct them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HeartbeatError {
    /// The deadline is below [`MIN_DEADLINE`]: scheduling delays alone would declare
    /// healthy peers down.
    #[error(
        "the heartbeat deadline must be at least {} ms, got {} ms",
        .min.as_millis(),
        .deadline.as_millis()
    )]
    DeadlineTooShort {
        /// The deadline given.
        deadline: Duration,
        /// The smallest accepted ([`MIN_DEADLINE`]).
        min: Duration,
    },
    /// The period is zero: heartbeats would go out without pause.
    #[error(
        "the heartbeat period (0 ms) must be positive and at most half the deadline \
         ({} ms): one lost beat must not declare a peer down",
        .deadline.as_millis()
    )]
    ZeroPeriod {
        /// The deadline given.
        deadline: Duration,
    },
    /// The period is more than half the deadline: one lost beat would declare a peer down.
    #[error(
        "the heartbeat period ({} ms) must be positive and at most half the deadline \
         ({} ms): one lost beat must not declare a peer down",
        .period.as_millis(),
        .deadline.as_millis()
    )]
    PeriodTooLong {
        /// The period given.
        period: Duration,
        /// The deadline given.
        deadline: Duration,
    },
}

/// When each ready peer was last heard from.
#[derive(Debug)]
pub struct Detector {
    deadline: Duration,
    last_heard: BTreeMap<String, Instant>,
    last_tick: Option<Instant>,
    /// How long this detector itself was frozen, once, until taken.
    frozen: Option<Duration>,
}

impl Detector {
    /// A detector declaring peers down after `deadline` of silence.
    pub fn new(deadline: Duration) -> Self {
        Detector {
            deadline,
            last_heard: BTreeMap::new(),
            last_tick: None,
            frozen: None,
        }
    }

    /// A heartbeat from `peer` arrived at `now`.
    pub fn heard(&mut self, peer: &str, now: Instant) {
        if let Some(t) = self.last_heard.get_mut(peer) {
            *t = (*t).max(now);
        }
    }

    /// A tick at `now` with `ready` the peers that have a ready session: starts counting
    /// for new ones, forgets the gone ones, and gives the overdue ones with their silence.
    pub fn tick(&mut self, ready: &[String], now: Instant) -> Vec<(String, Duration)> {
        self.last_heard.retain(|p, _| ready.contains(p));
        for p in ready {
            self.last_heard.entry(p.clone()).or_insert(now);
        }
        let gap = self
            .last_tick
            .map(|t| now.saturating_duration_since(t))
            .filter(|gap| *gap > self.deadline);
        self.last_tick = Some(now);
        if let Some(gap) = gap {
            self.frozen = Some(gap);
            for t in self.last_heard.values_mut() {
                *t = now;
            }
            return Vec::new();
        }
        self.last_heard
            .iter()
            .filter_map(|(p, t)| {
                let silent = now.saturating_duration_since(*t);
                (silent > self.deadline).then(|| (p.clone(), silent))
            })
            .collect()
    }

    /// How long this detector was frozen (the process stopped or starved longer than a
    /// deadline: its peers have declared it down), once; `None` otherwise.
    pub fn take_freeze(&mut self) -> Option<Duration> {
        self.frozen.take()
    }

    /// `peer` was declared down (its sessions are closing): judge it afresh when it is back.
    pub fn forget(&mut self, peer: &str) {
        self.last_heard.remove(peer);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn peers(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_peer_that_beats_is_never_overdue() {
        let t0 = Instant::now();
        let mut d = Detector::new(MS(1500));
        for i in 0..20 {
            let now = t0 + MS(300 * i);
            d.heard("a", now);
            assert!(d.tick(&peers(&["a"]), now).is_empty());
        }
    }

    #[test]
    fn a_silent_peer_is_overdue_after_the_deadline_counted_from_its_session() {
        let t0 = Instant::now();
        let mut d = Detector::new(MS(1500));
        assert!(d.tick(&peers(&["a"]), t0).is_empty());
        for i in 1..=5 {
            assert!(d.tick(&peers(&["a"]), t0 + MS(300 * i)).is_empty());
        }
        let overdue = d.tick(&peers(&["a"]), t0 + MS(1800));
        assert_eq!(overdue, vec![("a".to_string(), MS(1800))]);
    }

    #[test]
    fn a_forgotten_or_gone_peer_is_judged_afresh() {
        let t0 = Instant::now();
        let mut d = Detector::new(MS(1000));
        d.tick(&peers(&["a", "b"]), t0);
        d.forget("a");
        // b's session went; a's is back: both count from now
        d.tick(&peers(&["a"]), t0 + MS(900));
        assert!(d.tick(&peers(&["a", "b"]), t0 + MS(1800)).is_empty());
        assert_eq!(d.tick(&peers(&["a", "b"]), t0 + MS(2000)).len(), 1);
    }

    #[test]
    fn a_detector_that_was_frozen_declares_nobody_down() {
        let t0 = Instant::now();
        let mut d = Detector::new(MS(1000));
        d.tick(&peers(&["a"]), t0);
        // this process slept 5 s: its peers' silence is its own
        assert!(d.tick(&peers(&["a"]), t0 + MS(5000)).is_empty());
        assert_eq!(d.take_freeze(), Some(MS(5000)));
        assert_eq!(d.take_freeze(), None);
        assert!(d.tick(&peers(&["a"]), t0 + MS(5500)).is_empty());
        assert_eq!(d.tick(&peers(&["a"]), t0 + MS(6100)).len(), 1);
    }

    #[test]
    fn heartbeat_settings_are_checked() {
        assert!(HeartbeatConfig::default().validate().is_ok());
        assert_eq!(HeartbeatConfig::default().period, MS(240));
        assert!(HeartbeatConfig::with_deadline(MS(300)).validate().is_ok());
        assert!(HeartbeatConfig::with_deadline(MS(299)).validate().is_err());
        let too_slow = HeartbeatConfig {
            period: MS(800),
            deadline: MS(1500),
        };
        assert!(too_slow.validate().is_err());
    }

    #[test]
    fn a_bad_heartbeat_setting_is_matched_by_its_kind_and_keeps_its_text() {
        let short = HeartbeatConfig::with_deadline(MS(299))
            .validate()
            .unwrap_err();
        assert_eq!(
            short,
            HeartbeatError::DeadlineTooShort {
                deadline: MS(299),
                min: MIN_DEADLINE
            }
        );
        assert_eq!(
            short.to_string(),
            "the heartbeat deadline must be at least 300 ms, got 299 ms"
        );
        let too_slow = HeartbeatConfig {
            period: MS(800),
            deadline: MS(1500),
        };
        let err = too_slow.validate().unwrap_err();
        assert!(
            matches!(err, HeartbeatError::PeriodTooLong { period, .. } if period == MS(800)),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "the heartbeat period (800 ms) must be positive and at most half the deadline \
             (1500 ms): one lost beat must not declare a peer down"
        );
        let zero = HeartbeatConfig {
            period: MS(0),
            deadline: MS(1500),
        };
        let err = zero.validate().unwrap_err();
        assert_eq!(err, HeartbeatError::ZeroPeriod { deadline: MS(1500) });
        assert!(err
            .to_string()
            .starts_with("the heartbeat period (0 ms) must be positive"));
    }
}

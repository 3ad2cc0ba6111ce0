//! The failure detector's bookkeeping: when each peer was last heard from, and which are
//! overdue. Pure (time is passed in), so its rules are tested without processes.
//!
//! # Invariants
//! - A peer is judged only while a session with it is ready; its silence counts from the
//!   later of its last heartbeat and the moment its session became ready.
//! - When the detector itself was frozen (a tick came more than a deadline late: the
//!   process was stopped, or starved), nobody is declared down on that tick and every
//!   silence restarts: the silence was this node's, not its peers'. A tick late by less
//!   counts towards the peers' silences only as long as a beat period: the rest was this
//!   node's own stall (the peers' beats of that time wait unread), so a node woken from a
//!   freeze a little shorter than its deadline does not declare its peers down.
//! - Its own timer gap cannot tell a node whether its peers declared it down: their
//!   deadlines may be shorter than its own, and they count from its last beat, up to a
//!   period before its last tick. So each node's beats carry a [`DownNotice`] for every
//!   peer it declared down, until that peer has been back for two deadlines; a node that
//!   finds itself (its life) in a peer's notice, about a beat after the last freeze it
//!   found, and did not itself declare that peer down since that beat (both were cut off
//!   from each other: a partition), takes itself as frozen — once per freeze, however many
//!   peers tell it.

use serde::{Deserialize, Serialize};
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

/// A beat's number in its sender's stream, and the sender's life: a number drawn when its
/// detector was made, which tells its processes apart (a node killed and started again
/// numbers its beats from 1 again).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BeatId {
    /// The sender's life (0: a build that sends none).
    pub life: u64,
    /// The beat's number.
    pub seq: u64,
}

/// A node's word that it declared `node` down, carried by its beats until `node` has been
/// back for a while: the node it names learns that it was silent past a peer's deadline
/// even when it did not notice it had stopped (its own timer gap was shorter than its own
/// deadline: frozen just past the peer's deadline, or its deadline longer than the peer's).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DownNotice {
    /// The node declared down.
    pub node: String,
    /// Its life, as its last beat heard said.
    pub life: u64,
    /// The last of its beats heard before it was declared down.
    pub seq: u64,
    /// How long it had been silent, in ms.
    pub silent_ms: u64,
}

/// What the detector knows of a peer that has a ready session.
#[derive(Clone, Copy, Debug)]
struct Judged {
    /// When its session became ready (as far as the ticks saw).
    since: Instant,
    /// When it was last heard from (or `since`), less this node's own stalls.
    heard: Instant,
    /// When its last beat really came (or `since`): unlike `heard`, not moved on when this
    /// node finds it was frozen — a woken node has heard nobody lately.
    beat: Instant,
}

/// Whom a node reaches ([`Detector::reach`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Reach {
    /// The peers heard from lately.
    pub fresh: Vec<String>,
    /// How many peers it ever heard from.
    pub known: usize,
}

impl Reach {
    /// True if the fresh peers and this node are a majority of all it knows, itself
    /// included: a node cut off, or just woken from a freeze, is not.
    pub fn majority(&self) -> bool {
        (self.fresh.len() + 1) * 2 > self.known + 1
    }
}

/// When each ready peer was last heard from; which peers this node declared down, to tell
/// them; and whether this node itself was frozen, seen from its own ticks or told by a peer.
#[derive(Debug)]
pub struct Detector {
    deadline: Duration,
    /// The longest time between two ticks that counts towards a peer's silence: beyond
    /// it, this node did not run (stopped, starved) and could not hear anybody.
    stall: Duration,
    judged: BTreeMap<String, Judged>,
    /// The last beat heard from each peer (one entry per peer name ever heard).
    beats: BTreeMap<String, BeatId>,
    last_tick: Option<Instant>,
    /// How long this detector itself was frozen, once, until taken.
    frozen: Option<Duration>,
    /// This node's life ([`BeatId::life`]).
    life: u64,
    /// Beats sent so far.
    sent: u64,
    /// The first beat after this node last found it was frozen: a notice about an earlier
    /// beat is about a freeze already dealt with.
    awake_from: u64,
    /// The peers this node declared down, with the number of its own last beat then.
    declared: BTreeMap<String, u64>,
    /// The notices this node's beats carry, by the peer declared down.
    notices: BTreeMap<String, DownNotice>,
}

impl Detector {
    /// A detector judging peers as `config` says, for a node whose life is `life` (drawn
    /// anew by each process: see [`BeatId::life`]; not 0).
    pub fn new(config: HeartbeatConfig, life: u64) -> Self {
        Detector {
            deadline: config.deadline,
            stall: config.period,
            judged: BTreeMap::new(),
            beats: BTreeMap::new(),
            last_tick: None,
            frozen: None,
            life,
            sent: 0,
            awake_from: 0,
            declared: BTreeMap::new(),
            notices: BTreeMap::new(),
        }
    }

    /// This node's life.
    pub fn life(&self) -> u64 {
        self.life
    }

    /// The next beat's number (the beat is about to be sent).
    pub fn beat(&mut self) -> u64 {
        self.sent += 1;
        self.sent
    }

    /// The notices this node's beats carry now: the peers it declared down and that have
    /// not been back for two deadlines since.
    pub fn notices(&self) -> Vec<DownNotice> {
        self.notices.values().cloned().collect()
    }

    /// Beat `beat` of `peer` arrived at `now`.
    pub fn heard(&mut self, peer: &str, beat: BeatId, now: Instant) {
        // a peer of another life was started again: it has nothing to learn of the old one
        if self.notices.get(peer).is_some_and(|n| n.life != beat.life) {
            self.notices.remove(peer);
        }
        // kept whether or not the peer is judged yet: its first beat may come before the
        // tick that sees its session ready, and be its last before a freeze
        self.beats.insert(peer.to_string(), beat);
        if let Some(j) = self.judged.get_mut(peer) {
            j.heard = j.heard.max(now);
            j.beat = j.beat.max(now);
        }
    }

    /// `peer`'s beat carries `notice`, that it declared this node down: gives how long it
    /// found this node silent if this node must take itself as frozen — the notice names
    /// this life, is about a silence after the last freeze this node found, and this node
    /// did not itself declare `peer` down after the notice's beat (then both were cut off
    /// from each other, a partition, not this node stopped). Once per freeze.
    pub fn told(&mut self, peer: &str, notice: &DownNotice) -> Option<Duration> {
        if self.life == 0 || notice.life != self.life || notice.seq < self.awake_from {
            return None;
        }
        if self.declared.get(peer).is_some_and(|&d| d >= notice.seq) {
            return None;
        }
        self.awake_from = self.sent + 1;
        Some(Duration::from_millis(notice.silent_ms))
    }

    /// Whom this node reaches at `now`: the ready peers whose last beat came within
    /// `within` (a freeze of this node does not make them fresh), of all it ever heard.
    pub fn reach(&self, within: Duration, now: Instant) -> Reach {
        Reach {
            fresh: self
                .judged
                .iter()
                .filter(|(_, j)| now.saturating_duration_since(j.beat) <= within)
                .map(|(p, _)| p.clone())
                .collect(),
            known: self.beats.len(),
        }
    }

    /// A tick at `now` with `ready` the peers that have a ready session: starts counting
    /// for new ones, forgets the gone ones, and gives the overdue ones with their silence
    /// (each then also gets a notice, until it has been back for two deadlines).
    pub fn tick(&mut self, ready: &[String], now: Instant) -> Vec<(String, Duration)> {
        self.judged.retain(|p, _| ready.contains(p));
        for p in ready {
            self.judged.entry(p.clone()).or_insert(Judged {
                since: now,
                heard: now,
                beat: now,
            });
        }
        let back_for = self.deadline * 2;
        let judged = &self.judged;
        self.notices.retain(|p, _| {
            judged
                .get(p)
                .is_none_or(|j| now.saturating_duration_since(j.since) < back_for)
        });
        let gap = self.last_tick.map(|t| now.saturating_duration_since(t));
        self.last_tick = Some(now);
        match gap {
            Some(gap) if gap > self.deadline => {
                self.frozen = Some(gap);
                self.awake_from = self.sent + 1;
                for j in self.judged.values_mut() {
                    j.heard = now;
                }
                return Vec::new();
            }
            // this node stalled: the peers' beats of that time wait unread, so its
            // length beyond a normal tick is nobody's silence but this node's
            Some(gap) if gap > self.stall => {
                let own = gap - self.stall;
                for j in self.judged.values_mut() {
                    j.heard = (j.heard + own).min(now);
                }
            }
            _ => {}
        }
        let overdue: Vec<(String, Duration)> = self
            .judged
            .iter()
            .filter_map(|(p, j)| {
                let silent = now.saturating_duration_since(j.heard);
                (silent > self.deadline).then(|| (p.clone(), silent))
            })
            .collect();
        for (p, silent) in &overdue {
            self.declared.insert(p.clone(), self.sent);
            // judged afresh when it is back (its sessions are closing)
            self.judged.remove(p);
            if let Some(beat) = self.beats.get(p).copied() {
                self.notices.insert(
                    p.clone(),
                    DownNotice {
                        node: p.clone(),
                        life: beat.life,
                        seq: beat.seq,
                        silent_ms: silent.as_millis().try_into().unwrap_or(u64::MAX),
                    },
                );
            }
        }
        overdue
    }

    /// How long this detector was frozen (the process stopped or starved longer than a
    /// deadline: its peers have declared it down), once; `None` otherwise.
    pub fn take_freeze(&mut self) -> Option<Duration> {
        self.frozen.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn peers(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    /// A detector with `deadline_ms` (a beat every fifth of it), of a node of life `life`.
    fn detector(deadline_ms: u64, life: u64) -> Detector {
        Detector::new(HeartbeatConfig::with_deadline(MS(deadline_ms)), life)
    }

    fn beat(life: u64, seq: u64) -> BeatId {
        BeatId { life, seq }
    }

    /// Tick every `step_ms` from `from_ms` to `to_ms` after `t0`, `ready` the peers, the
    /// peers of `beating` heard before each tick: every peer given as overdue, with when.
    fn tick_through(
        d: &mut Detector,
        t0: Instant,
        (from_ms, to_ms, step_ms): (u64, u64, u64),
        ready: &[&str],
        beating: &[&str],
    ) -> Vec<(u64, String)> {
        let mut overdue = Vec::new();
        for at in (from_ms..=to_ms).step_by(step_ms as usize) {
            let now = t0 + MS(at);
            for p in beating {
                d.heard(p, beat(1, at), now);
            }
            overdue.extend(d.tick(&peers(ready), now).into_iter().map(|(p, _)| (at, p)));
        }
        overdue
    }

    #[test]
    fn a_peer_that_beats_is_never_overdue() {
        let t0 = Instant::now();
        let mut d = detector(1500, 7);
        for i in 0..20 {
            let now = t0 + MS(300 * i);
            d.heard("a", beat(1, i), now);
            assert!(d.tick(&peers(&["a"]), now).is_empty());
        }
    }

    #[test]
    fn the_peers_heard_within_a_while_are_those_still_beating() {
        let t0 = Instant::now();
        let mut d = detector(1200, 7);
        let both = peers(&["a", "b"]);
        assert!(d.tick(&both, t0).is_empty());
        // a goes on beating, b falls silent after 200 ms (cut off)
        d.heard("b", beat(1, 1), t0 + MS(200));
        for i in 1..=8 {
            let now = t0 + MS(100 * i);
            d.heard("a", beat(1, i), now);
            assert!(d.tick(&both, now).is_empty());
        }
        let now = t0 + MS(800);
        assert_eq!(d.reach(MS(600), now).fresh, ["a", "b"]);
        assert_eq!(d.reach(MS(500), now).fresh, ["a"]);
        assert_eq!(d.reach(MS(500), now).known, 2);
        assert!(d.reach(MS(600), now).majority());
        // this node frozen for 2 s: woken, it has heard nobody lately
        let woken = t0 + MS(2800);
        assert!(d.tick(&both, woken).is_empty());
        assert_eq!(d.reach(MS(600), woken).fresh, Vec::<String>::new());
        assert!(!d.reach(MS(600), woken).majority());
        // a peer whose session is gone is not heard from at all, even beating
        d.heard("a", beat(1, 9), woken + MS(100));
        d.tick(&peers(&["b"]), woken + MS(100));
        assert_eq!(
            d.reach(MS(600), woken + MS(100)).fresh,
            Vec::<String>::new()
        );
    }

    #[test]
    fn a_silent_peer_is_overdue_after_the_deadline_counted_from_its_session() {
        let t0 = Instant::now();
        let mut d = detector(1500, 7);
        assert!(d.tick(&peers(&["a"]), t0).is_empty());
        for i in 1..=5 {
            assert!(d.tick(&peers(&["a"]), t0 + MS(300 * i)).is_empty());
        }
        let overdue = d.tick(&peers(&["a"]), t0 + MS(1800));
        assert_eq!(overdue, vec![("a".to_string(), MS(1800))]);
    }

    #[test]
    fn a_gone_or_declared_peer_is_judged_afresh() {
        let t0 = Instant::now();
        let mut d = detector(1000, 7);
        let both = &["a", "b"];
        assert!(tick_through(&mut d, t0, (0, 500, 100), both, both).is_empty());
        // b's session went: it is not judged
        assert!(tick_through(&mut d, t0, (600, 900, 100), &["a"], &["a"]).is_empty());
        // b is back at 1000, silent: counted from then, overdue once past the deadline
        let overdue = tick_through(&mut d, t0, (1000, 2100, 100), both, &["a"]);
        assert_eq!(overdue, vec![(2100, "b".to_string())]);
        // declared down, its session still closing: judged afresh from the next tick
        let overdue = tick_through(&mut d, t0, (2200, 3300, 100), both, &["a"]);
        assert_eq!(overdue, vec![(3300, "b".to_string())]);
    }

    #[test]
    fn a_detector_that_was_frozen_declares_nobody_down() {
        let t0 = Instant::now();
        let mut d = detector(1000, 7);
        d.tick(&peers(&["a"]), t0);
        // this process slept 5 s: its peers' silence is its own
        assert!(d.tick(&peers(&["a"]), t0 + MS(5000)).is_empty());
        assert_eq!(d.take_freeze(), Some(MS(5000)));
        assert_eq!(d.take_freeze(), None);
        let overdue = tick_through(&mut d, t0, (5100, 6100, 100), &["a"], &[]);
        assert_eq!(overdue, vec![(6100, "a".to_string())]);
    }

    #[test]
    fn a_stall_shorter_than_the_deadline_is_this_nodes_silence_not_its_peers() {
        let t0 = Instant::now();
        // a deadline of 1200 ms, a beat every 240 ms, judged every 60 ms
        let mut d = detector(1200, 7);
        for at in (0..=900).step_by(60) {
            if at % 240 == 0 {
                d.heard("a", beat(1, at), t0 + MS(at));
            }
            assert!(d.tick(&peers(&["a"]), t0 + MS(at)).is_empty());
        }
        // a was last heard at 720; this node stops after its tick at 900 for 1150 ms, a bit
        // less than its deadline: 1330 ms after a's last beat, while a's beats wait unread
        assert!(d.tick(&peers(&["a"]), t0 + MS(2050)).is_empty());
        assert_eq!(d.take_freeze(), None);
        d.heard("a", beat(1, 2050), t0 + MS(2060));
        assert!(tick_through(&mut d, t0, (2120, 2600, 60), &["a"], &[]).is_empty());
        // a peer silent while this node runs is still overdue after the deadline
        let overdue = tick_through(&mut d, t0, (2660, 3500, 60), &["a"], &[]);
        assert_eq!(overdue.first(), Some(&(3320, "a".to_string())));
    }

    #[test]
    fn a_peer_declared_down_is_told_so_until_it_has_been_back_two_deadlines() {
        let t0 = Instant::now();
        let mut d = detector(600, 7);
        d.tick(&peers(&["x", "y"]), t0);
        d.heard("x", beat(1, 10), t0 + MS(50));
        d.heard("y", beat(1, 3), t0 + MS(50));
        let overdue = tick_through(&mut d, t0, (60, 720, 60), &["x", "y"], &["y"]);
        assert_eq!(overdue, vec![(660, "x".to_string())]);
        let notice = DownNotice {
            node: "x".to_string(),
            life: 1,
            seq: 10,
            silent_ms: 610,
        };
        assert_eq!(d.notices(), vec![notice.clone()]);
        // told while it is away, and for two deadlines after it is back
        tick_through(&mut d, t0, (780, 3000, 60), &["y"], &["y"]);
        assert_eq!(d.notices(), vec![notice.clone()]);
        tick_through(&mut d, t0, (3060, 4200, 60), &["x", "y"], &["x", "y"]);
        assert_eq!(d.notices(), vec![notice]);
        tick_through(&mut d, t0, (4260, 4260, 60), &["x", "y"], &["x", "y"]);
        assert_eq!(d.notices(), vec![]);
        // declared down again, then started again (another life): the new process has
        // nothing to learn of the one declared down
        tick_through(&mut d, t0, (4320, 5100, 60), &["x", "y"], &["y"]);
        assert_eq!(d.notices().len(), 1);
        d.heard("x", beat(99, 1), t0 + MS(5110));
        assert_eq!(d.notices(), vec![]);
    }

    #[test]
    fn a_peer_heard_only_before_its_session_was_judged_is_told_too() {
        let t0 = Instant::now();
        let mut d = detector(600, 7);
        // its first beat came before the tick that saw it ready; then it froze
        d.heard("x", beat(42, 1), t0);
        let overdue = tick_through(&mut d, t0, (10, 730, 60), &["x"], &[]);
        assert_eq!(overdue, vec![(670, "x".to_string())]);
        assert_eq!(
            d.notices(),
            vec![DownNotice {
                node: "x".to_string(),
                life: 42,
                seq: 1,
                silent_ms: 660,
            }]
        );
    }

    #[test]
    fn a_node_told_it_was_declared_down_takes_itself_as_frozen_once_per_freeze() {
        let notice = |life, seq| DownNotice {
            node: "x".to_string(),
            life,
            seq,
            silent_ms: 700,
        };
        // x's deadline is longer than its peers': its own ticks do not show a short freeze
        let mut x = detector(3000, 42);
        for _ in 0..10 {
            x.beat();
        }
        assert_eq!(x.told("p", &notice(41, 10)), None, "another life's notice");
        assert_eq!(x.told("p", &notice(42, 10)), Some(MS(700)));
        // the same freeze, told again or by another peer
        assert_eq!(x.told("p", &notice(42, 10)), None);
        assert_eq!(x.told("q", &notice(42, 9)), None);
        // a later freeze
        for _ in 0..10 {
            x.beat();
        }
        assert_eq!(x.told("q", &notice(42, 15)), Some(MS(700)));
        assert_eq!(x.take_freeze(), None, "told, not a tick's gap");
    }

    #[test]
    fn a_node_that_declared_its_peer_down_too_was_cut_off_not_frozen() {
        let t0 = Instant::now();
        let notice = |seq| DownNotice {
            node: "x".to_string(),
            life: 42,
            seq,
            silent_ms: 700,
        };
        let mut x = detector(600, 42);
        for at in (0..=300).step_by(60) {
            if at % 120 == 0 {
                x.beat();
            }
            x.tick(&peers(&["p"]), t0 + MS(at));
        }
        // cut off: p stops hearing x after x's beat 3, x declares p down after it too
        let overdue = tick_through(&mut x, t0, (360, 720, 60), &["p"], &[]);
        assert_eq!(overdue, vec![(660, "p".to_string())]);
        assert_eq!(x.told("p", &notice(3)), None);
        // later, x's beats reach p again, then x is frozen: that notice is news
        for _ in 0..5 {
            x.beat();
        }
        assert_eq!(x.told("p", &notice(7)), Some(MS(700)));
    }

    #[test]
    fn a_node_that_found_its_freeze_by_its_ticks_is_not_told_it_again() {
        let t0 = Instant::now();
        let mut x = detector(600, 42);
        x.tick(&peers(&["p"]), t0);
        for _ in 0..4 {
            x.beat();
        }
        x.tick(&peers(&["p"]), t0 + MS(3000));
        assert_eq!(x.take_freeze(), Some(MS(3000)));
        let notice = DownNotice {
            node: "x".to_string(),
            life: 42,
            seq: 4,
            silent_ms: 650,
        };
        assert_eq!(x.told("p", &notice), None);
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

//! The replication protocol of a datamanager's replicas as a pure state machine: Raft with
//! pre-votes and leader stickiness, and its members changed one at a time while it runs
//! (`members`: a configuration is a log entry, in use once appended; a replica added
//! catches up as a learner before it votes), with time passed in.
//!
//! The datamanager actor feeds it what arrives (a message, a tick, a durable write, a peer
//! that came or went) and carries out what it returns ([`Out`]): persist the term and vote,
//! send, journal, truncate, apply committed entries, publish or withdraw itself. Keeping
//! the protocol here, without an actor, a clock or a disk, lets the tests run thousands of
//! seeded schedules of lost messages, partitions and crashes against its invariants:
//!
//! - at most one leader per term, and a leader's term is persisted before it is used;
//! - an entry is committed only once a majority holds it durably, and a leader commits
//!   by counting only entries of its own term (Raft's figure 8);
//! - a committed entry is never truncated, and every replica applies the same entries in the
//!   same order;
//! - a replica votes only for a log at least as up to date as its own, once per term;
//! - a read is answered only by a leader no other can have replaced yet (`lease`);
//! - a replica uses the newest configuration in its log; a leader appends one only when the
//!   one before is committed and an entry of its own term is, so two configurations in use
//!   at once always share a majority's replica; only voters count for a commit, a vote or a
//!   lease.

use super::lease::{self, Contact, Read};
use super::members::{Change, ChangeError, Members};
use super::msg::{Ops, ReplicaMsg};
use super::op::{Op, OpBody};
use super::tail::{Tail, KEEP_BYTES};
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// The protocol's clocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    /// How often a leader sends to a replica it has nothing else to send (a heartbeat).
    pub heartbeat: Duration,
    /// How long a replica goes without hearing from a leader before it campaigns (plus a
    /// random part of up to half of it), and how long a leader goes without hearing from a
    /// majority before it steps down.
    pub election: Duration,
    /// How long a leader answers reads from its own store after a majority last followed it
    /// (its lease, `lease`); a follower votes for no other replica for [`Timing::guard`]
    /// after it last heard a leader. Below the heartbeat, reads always wait for a round.
    pub lease: Duration,
}

/// The guard's margin over the lease: an eighth, for clocks that run at different rates
/// (monotonic clocks drift by well under 0.1 %; the margin also holds a `tick` late by
/// 100 ms).
const DRIFT: u32 = 8;

impl Timing {
    /// How long a follower refuses to vote for another replica after it last heard from a
    /// leader: the lease and a margin for clock drift, so that a leader's lease ends, on any
    /// clock, before anyone can be elected in its place.
    pub fn guard(&self) -> Duration {
        self.lease + self.lease / DRIFT
    }
}

impl Default for Timing {
    fn default() -> Timing {
        // The node's failure detector declares a lost node within 1.2 s and closes its
        // sessions; a replica that sees the leader leave campaigns at once. The election
        // timeout is the backstop (a leader hung with its node alive), not the fast path.
        // The lease's guard (1.0125 s) ends before the detector's deadline (1.2 s), so it
        // does not slow the failover of a lost node; only a datamanager that crashed on a
        // live node (its replicas see it leave at once) waits for it.
        Timing {
            heartbeat: Duration::from_millis(100),
            election: Duration::from_millis(2500),
            lease: Duration::from_millis(900),
        }
    }
}

/// Entries a leader sends in one `Append` at most.
const OPS_PER_APPEND: usize = 4096;
/// Entries a leader has in flight to one replica at most.
const INFLIGHT: u64 = 65_536;
/// Applied entries a replica keeps in memory to catch a lagging replica up (beyond them, or
/// beyond [`KEEP_BYTES`](tail::KEEP_BYTES), a snapshot is sent).
pub(crate) const TAIL_KEEP: usize = 16_384;

/// A time on this replica's clock as an `Append` carries it (0 reads as none: a clock's
/// first instant is never a send time that matters).
fn nanos(t: Duration) -> u64 {
    u64::try_from(t.as_nanos()).unwrap_or(u64::MAX)
}

/// What the actor must do, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Out {
    /// Persist the term and the vote before anything after this is sent.
    Persist,
    /// Send `msg` to the replica on node `to`.
    Send(String, ReplicaMsg),
    /// Drop the (uncommitted) entries from this seq on: from the journal too.
    Truncate(u64),
    /// Journal the entries from this seq to the last (they are in [`Core::op`]); tell
    /// [`Core::durable`] when they are durable.
    Journal(u64, u64),
    /// Apply the committed entries from this seq to that one, in order ([`Core::op`]).
    Apply(u64, u64),
    /// This replica is the leader now: publish it under the datamanager's name.
    Lead,
    /// This replica was the leader and is not any more (a newer term, or it lost its
    /// majority): it must stop answering as one.
    StepDown(String),
    /// Send the replica on node `to` a snapshot of the committed store (it needs entries this
    /// replica no longer holds). The snapshot ends at seq `.1` of term `.2`; its
    /// configuration is [`Core::committed_members`].
    Install(String, u64, u64),
    /// A configuration was committed: the replicas were `was` and are `now`.
    Reconfigured {
        /// The configuration committed before.
        was: Members,
        /// The one committed now.
        now: Members,
    },
    /// A configuration without this replica was committed: it is out (a leader handed its
    /// role on and stepped down first). It campaigns no more.
    Removed,
}

#[derive(Clone, Debug)]
pub(crate) struct Progress {
    /// The next seq to send.
    next: u64,
    /// The highest seq known held (durably) by the replica as here.
    matched: u64,
    /// When the replica last answered in this term.
    acked: Option<Duration>,
    /// When something was last sent to it.
    sent: Option<Duration>,
    /// Sending one `Append` at a time until one is accepted (after a refusal).
    probing: bool,
    /// A snapshot was sent at this time and is not acknowledged yet.
    installing: Option<Duration>,
    /// The send time of the newest `Append` of this term it said it took in (`lease`).
    echo: Option<Duration>,
}

impl Progress {
    /// A replica a new leader (or a new configuration) starts sending to: from `next`, one
    /// append at a time until it answers.
    fn fresh(next: u64) -> Progress {
        Progress {
            next,
            matched: 0,
            acked: None,
            sent: None,
            probing: true,
            installing: None,
            echo: None,
        }
    }

    /// Its answer to an `Append` (or a snapshot): `ok`, it holds the log up to `last`;
    /// refused, it lacks entries before `last + 1` — sent again from there, one at a time.
    fn answered(&mut self, ok: bool, last: u64) {
        if ok {
            self.matched = self.matched.max(last);
            self.next = self.next.max(last + 1);
            self.probing = false;
        } else {
            let n = (last + 1).max(self.matched + 1);
            if n < self.next || self.installing.is_some() {
                self.next = n;
            }
            self.probing = true;
            self.sent = None;
        }
        self.installing = None;
    }
}

/// On a leader, what it knows of the replica on `peer`: a member's, or an outsider's.
fn progress_mut<'a>(role: &'a mut Role, peer: &str) -> Option<&'a mut Progress> {
    match role {
        Role::Leader {
            peers, outsiders, ..
        } => match peers.get_mut(peer) {
            Some(pr) => Some(pr),
            None => outsiders.get_mut(peer),
        },
        _ => None,
    }
}

#[derive(Clone, Debug)]
enum Role {
    Follower,
    Candidate {
        pre: bool,
        votes: BTreeSet<String>,
    },
    Leader {
        peers: BTreeMap<String, Progress>,
        /// Replicas it met that no configuration it holds names — removed while their node
        /// was away, they started again believing they are replicas —, each being sent the
        /// log (or a snapshot) up to the committed configuration without it, so that it
        /// learns it is out ([`Core::outsider_seen`]). They count for nothing.
        outsiders: BTreeMap<String, Progress>,
        since: Duration,
        /// Its no-op's seq: once it is applied, the store holds what its predecessors
        /// committed.
        first: u64,
    },
}

/// The protocol state of one replica.
#[derive(Clone, Debug)]
pub(crate) struct Core {
    me: String,
    /// The configurations its log holds: the newest committed first, then those appended
    /// after it (not committed yet). The last is the one in use ([`Core::members`]).
    configs: Vec<(u64, Members)>,
    /// The other replicas of every configuration it holds: who a leader sends to.
    others: Vec<String>,
    /// The seq of the first configuration naming this replica that it took in (0: the one
    /// it was started with); `None` while it holds none (a replica added, catching up).
    joined_at: Option<u64>,
    /// It took in the commit of a configuration without it: it is out.
    removed: bool,
    /// The latest time it was given (a tick, a message): when a commit, which is told no
    /// time, sends a replica removed its last word.
    clock: Duration,
    timing: Timing,
    term: u64,
    voted_for: Option<String>,
    /// (seq, term) of the entry just before `tail` (0, 0: the log's start).
    base: (u64, u64),
    tail: Tail,
    commit: u64,
    applied: u64,
    /// The last entry known durable here, as (seq, term).
    durable: (u64, u64),
    /// The highest seq this replica knows to match the current leader's log.
    verified: u64,
    /// The seq up to which every replica holds the log durably, as the leader last told
    /// (see [`Core::held_everywhere`]).
    held: u64,
    role: Role,
    leader: Option<String>,
    /// When this replica last heard from the current leader.
    heard: Option<Duration>,
    /// When it last took in a leader's word, kept through a failure detector's word and a
    /// new term: it votes for nobody else until the lease's guard after it (`lease`).
    contact: Contact,
    /// The send time (leader's clock, ns) of the newest `Append` taken in from the current
    /// leader in this term, echoed in every answer (0: none).
    echo: u64,
    /// On a leader: when it last sent a round to confirm it still leads (for reads).
    confirming: Option<Duration>,
    /// Reads answered by a leader at once, unchecked, and votes given without the guard
    /// (stale reads possible): for the checker's control run and the read bench only.
    unchecked_reads: bool,
    deadline: Duration,
    visible: BTreeSet<String>,
    rng: u64,
    /// Applied entries kept in memory ([`TAIL_KEEP`]; less in tests).
    keep: usize,
    /// Bytes of entries kept in memory ([`KEEP_BYTES`](tail::KEEP_BYTES)).
    keep_bytes: usize,
    /// The configured leader: it campaigns first.
    preferred: bool,
    /// The configured leader's node (the first member as configured).
    preferred_member: String,
    /// On a leader that is not the preferred replica: when it last asked that replica to take
    /// over (`TimeoutNow`), and its last seq then. For a while after, the other replicas get
    /// nothing past that seq (see [`Core::hand_over`]).
    handed: Option<(Duration, u64)>,
}

/// What a replica recovered from its disk.
#[derive(Clone, Debug, Default)]
pub(crate) struct Restored {
    /// Its term and vote.
    pub(crate) term: u64,
    /// Its vote in that term.
    pub(crate) voted_for: Option<String>,
    /// (seq, term) of its last committed entry.
    pub(crate) committed: (u64, u64),
    /// Its entries after it, not known committed.
    pub(crate) tail: Vec<Op>,
    /// Committed (applied) entries its journal still holds, ending with `committed`: kept
    /// to catch a lagging replica up without a snapshot, should it become the leader.
    pub(crate) applied: Tail,
    /// (seq, term) of the entry just before the first of `applied` (unused when empty).
    pub(crate) before: (u64, u64),
    /// The newest committed configuration it held, and its seq (`None`: the one it is
    /// started with — a cluster file's — is in use).
    pub(crate) members: Option<(u64, Members)>,
}

impl Core {
    /// A replica `me` of a datamanager kept on `members` (node names, `me` among them), with
    /// what its journal held, at `now`. `eager`: campaign soon (the configured leader).
    pub(crate) fn new(
        me: &str,
        members: &[String],
        timing: Timing,
        restored: Restored,
        eager: bool,
        now: Duration,
    ) -> Core {
        let preferred_member = members.first().cloned().unwrap_or_default();
        let genesis = Members::new(members.iter().cloned(), Vec::<String>::new());
        let config = restored.members.clone().unwrap_or((0, genesis));
        let seed = me
            .bytes()
            .fold(0x9E37_79B9_7F4A_7C15u64, |h, b| {
                (h ^ b as u64).wrapping_mul(0x100_0000_01B3)
            })
            .wrapping_add(now.as_nanos() as u64)
            | 1;
        let durable_last = restored
            .tail
            .last()
            .map_or(restored.committed, |o| (o.seq, o.term));
        // the applied entries it still has, if they end where the committed ones do
        let (base, mut tail) = match restored.applied.back() {
            Some(last) if (last.seq, last.term) == restored.committed => {
                (restored.before, restored.applied)
            }
            _ => (restored.committed, Tail::default()),
        };
        tail.extend(restored.tail);
        let mut core = Core {
            me: me.to_string(),
            configs: vec![config],
            others: Vec::new(),
            joined_at: None,
            removed: false,
            clock: now,
            timing,
            term: restored.term,
            voted_for: restored.voted_for,
            base,
            tail,
            commit: restored.committed.0,
            applied: restored.committed.0,
            durable: durable_last,
            verified: 0,
            held: 0,
            role: Role::Follower,
            leader: None,
            heard: None,
            // a replica with a term behind it may have answered a leader just before it
            // stopped: it keeps the guard from its start
            contact: if restored.term > 0 {
                Contact::restarted(now)
            } else {
                Contact::default()
            },
            echo: 0,
            confirming: None,
            unchecked_reads: false,
            deadline: now,
            visible: BTreeSet::new(),
            rng: seed,
            keep: TAIL_KEEP,
            keep_bytes: KEEP_BYTES,
            preferred: eager,
            preferred_member,
            handed: None,
        };
        core.deadline = if eager {
            now + timing.heartbeat
        } else {
            now + core.election_timeout()
        };
        core.restore_members();
        core
    }

    /// The configurations its log holds beyond the committed one it was started with, and
    /// whether it is (still) one of the replicas.
    fn restore_members(&mut self) {
        let base = self.configs[0].0;
        let logged: Vec<(u64, Members)> = self
            .tail
            .range(0..self.tail.len())
            .filter(|o| o.seq > base)
            .filter_map(|o| match &o.body {
                OpBody::Members(m) => Some((o.seq, m.clone())),
                _ => None,
            })
            .collect();
        self.configs.extend(logged);
        let settled = self.configs[1..]
            .iter()
            .take_while(|(s, _)| *s <= self.commit)
            .count();
        self.configs.drain(..settled);
        self.joined_at = self
            .configs
            .iter()
            .find(|(_, m)| m.contains(&self.me))
            .map(|(s, _)| *s);
        // started again after its removal was committed: it stays out
        self.removed = self.joined_at.is_none() && self.configs[0].0 > 0;
        self.reconfigured();
    }

    /// A replica started to join a running datamanager (added as a learner by its leader):
    /// until its log says otherwise, it takes itself for a learner of the configured voters —
    /// it never campaigns, and it answers the leader that sends to it.
    pub(crate) fn joining(mut self) -> Core {
        if self.configs.len() == 1 && self.configs[0].0 == 0 && !self.removed {
            let m = &self.configs[0].1;
            if !m.contains(&self.me) {
                self.configs[0].1 = Members::new(m.voters.clone(), [self.me.clone()]);
                // not a configuration of its log: a removal before its own addition is no
                // removal of it
                self.joined_at = None;
                self.reconfigured();
            }
        }
        self
    }

    /// Keep at most `n` applied entries in memory (beyond them a lagging replica is sent a
    /// snapshot).
    pub(crate) fn with_tail_keep(mut self, n: usize) -> Core {
        self.keep = n.max(1);
        self
    }

    /// Answer every read at once while it leads, and vote without the lease's guard
    /// (`true`): the protocol as it was before leases, stale reads possible. For the
    /// checker's control run and the read bench only.
    pub(crate) fn with_unchecked_reads(mut self, unchecked: bool) -> Core {
        self.unchecked_reads = unchecked;
        self
    }

    /// Keep at most `bytes` of applied entries in memory ([`KEEP_BYTES`](tail::KEEP_BYTES); less in tests).
    #[cfg(test)]
    pub(crate) fn with_tail_bytes(mut self, bytes: usize) -> Core {
        self.keep_bytes = bytes;
        self
    }

    // ---- what it is --------------------------------------------------------------------

    /// The protocol's clocks.
    pub(crate) fn timing(&self) -> Timing {
        self.timing
    }

    /// Its node.
    pub(crate) fn me(&self) -> &str {
        &self.me
    }

    /// The current term.
    pub(crate) fn term(&self) -> u64 {
        self.term
    }

    /// Its vote in the current term.
    pub(crate) fn voted_for(&self) -> Option<&str> {
        self.voted_for.as_deref()
    }

    /// Whether it is the leader.
    pub(crate) fn is_leader(&self) -> bool {
        matches!(self.role, Role::Leader { .. })
    }

    /// The leader it follows (itself if it is one), if it knows one.
    pub(crate) fn leader(&self) -> Option<&str> {
        self.leader.as_deref()
    }

    /// The committed seq.
    pub(crate) fn commit(&self) -> u64 {
        self.commit
    }

    /// The last seq handed to [`Out::Apply`].
    pub(crate) fn applied(&self) -> u64 {
        self.applied
    }

    /// (seq, term) of its last entry.
    pub(crate) fn last(&self) -> (u64, u64) {
        self.tail.back().map_or(self.base, |o| (o.seq, o.term))
    }

    /// The term of the entry `seq`, if it is still held (or is the one before the tail).
    pub(crate) fn term_at(&self, seq: u64) -> Option<u64> {
        if seq == self.base.0 {
            return Some(self.base.1);
        }
        if seq < self.base.0 {
            return None;
        }
        self.op(seq).map(|o| o.term)
    }

    /// The entry `seq`, if it is in memory.
    pub(crate) fn op(&self, seq: u64) -> Option<&Op> {
        let i = seq.checked_sub(self.base.0 + 1)?;
        self.tail.get(usize::try_from(i).ok()?)
    }

    /// The entries from `from` to `to` that are in memory.
    pub(crate) fn ops(&self, from: u64, to: u64) -> impl Iterator<Item = &Op> {
        let start = from.saturating_sub(self.base.0 + 1) as usize;
        let end = to.saturating_sub(self.base.0) as usize;
        self.tail
            .range(start.min(self.tail.len())..end.min(self.tail.len()))
    }

    /// How far each replica is behind the leader's last entry (on the leader).
    pub(crate) fn lag(&self) -> BTreeMap<String, u64> {
        self.lacking_up_to(self.last().0)
    }

    /// How many committed entries each other replica lacks (on the leader): 0 for one that
    /// holds all of them, however many newer entries are still in flight to it — the
    /// measure of a replica caught up under a steady stream of writes, where the lag to the
    /// last entry is rarely 0 for all at once.
    pub(crate) fn lacking_committed(&self) -> BTreeMap<String, u64> {
        self.lacking_up_to(self.commit())
    }

    /// How many entries up to `seq` each other replica lacks (on the leader; empty on
    /// another replica).
    fn lacking_up_to(&self, seq: u64) -> BTreeMap<String, u64> {
        match &self.role {
            Role::Leader { peers, .. } => peers
                .iter()
                .map(|(p, pr)| (p.clone(), seq.saturating_sub(pr.matched)))
                .collect(),
            _ => BTreeMap::new(),
        }
    }

    /// The configuration in use: the newest in its log, committed or not.
    pub(crate) fn members(&self) -> &Members {
        &self.configs[self.configs.len() - 1].1
    }

    /// The newest committed configuration it holds, and its seq (0: the one it was
    /// started with): what a snapshot of its store carries.
    pub(crate) fn committed_members(&self) -> (u64, &Members) {
        (self.configs[0].0, &self.configs[0].1)
    }

    /// Whether a configuration was appended and is not committed yet.
    pub(crate) fn change_pending(&self) -> bool {
        self.configs.len() > 1
    }

    /// Whether it took in the commit of a configuration without it.
    pub(crate) fn is_removed(&self) -> bool {
        self.removed
    }

    fn majority(&self) -> usize {
        self.members().majority()
    }

    /// Whether this replica votes (campaigns, counts for a commit).
    fn votes(&self) -> bool {
        !self.removed && self.members().is_voter(&self.me)
    }

    fn peers(&self) -> impl Iterator<Item = &String> {
        self.others.iter()
    }

    /// The other replicas' nodes, of every configuration it holds.
    pub(crate) fn others(&self) -> Vec<String> {
        self.others.clone()
    }

    /// The configurations changed: who it sends to and counts as reachable, and on a
    /// leader whom it keeps track of.
    fn reconfigured(&mut self) {
        let mut others: Vec<String> = self
            .configs
            .iter()
            .flat_map(|(_, m)| m.all())
            .filter(|n| **n != self.me)
            .cloned()
            .collect();
        others.sort();
        others.dedup();
        self.visible.retain(|v| others.contains(v));
        let next = self.last().0 + 1;
        if let Role::Leader {
            peers, outsiders, ..
        } = &mut self.role
        {
            peers.retain(|p, _| others.contains(p));
            for o in &others {
                // an outsider added (a replica started to join, met before its addition):
                // what it was sent counts — a snapshot on its way is not sent twice
                let met = outsiders.remove(o);
                peers
                    .entry(o.clone())
                    .or_insert_with(|| met.unwrap_or_else(|| Progress::fresh(next)));
            }
        }
        self.others = others;
    }

    /// Configuration `m` was appended to its log at `seq`: in use from now on.
    fn logged_members(&mut self, seq: u64, m: Members) {
        if m.contains(&self.me) {
            self.joined_at.get_or_insert(seq);
            self.removed = false;
        }
        self.configs.push((seq, m));
    }

    /// Its log was cut from `seq` on: the configurations appended there are undone.
    fn cut_members(&mut self, seq: u64) {
        let keep = 1 + self.configs[1..]
            .iter()
            .take_while(|(s, _)| *s < seq)
            .count();
        if keep < self.configs.len() {
            self.configs.truncate(keep);
            if self.joined_at.is_some_and(|j| j >= seq) {
                self.joined_at = None;
            }
            self.reconfigured();
        }
    }

    /// The commit passed configurations: the newest of them is the committed one. A leader
    /// removed hands its role to the most up-to-date voter and steps down.
    fn settle_members(&mut self, out: &mut Vec<Out>) {
        let settled = self.configs[1..]
            .iter()
            .take_while(|(s, _)| *s <= self.commit)
            .count();
        if settled == 0 {
            return;
        }
        let was = self.configs[0].1.clone();
        self.configs.drain(..settled);
        let (seq, now) = self.configs[0].clone();
        if self.is_leader() {
            // the replicas removed get a last word, with the commit: so they know they are
            // out (the leader sends them nothing more)
            let gone: Vec<String> = self
                .others
                .iter()
                .filter(|o| !self.configs.iter().any(|(_, m)| m.contains(o)))
                .cloned()
                .collect();
            for g in gone {
                self.send_to(&g, self.clock, true, &mut Vec::new(), out);
            }
        }
        let out_now = !now.contains(&self.me) && self.joined_at.is_some_and(|j| j < seq);
        if out_now && !self.removed {
            if self.is_leader() {
                self.hand_off(out);
                self.step_down("it was removed from the replicas", out);
            }
            self.removed = true;
        }
        self.reconfigured();
        out.push(Out::Reconfigured { was, now });
        if out_now {
            out.push(Out::Removed);
        }
    }

    /// A leader removed: ask the voter that holds the most of its log to campaign now.
    fn hand_off(&self, out: &mut Vec<Out>) {
        let Role::Leader { peers, .. } = &self.role else {
            return;
        };
        let voters = &self.configs[0].1;
        if let Some((best, _)) = peers
            .iter()
            .filter(|(p, _)| voters.is_voter(p))
            .max_by_key(|(_, pr)| pr.matched)
        {
            out.push(Out::Send(
                best.clone(),
                ReplicaMsg::TimeoutNow {
                    term: self.term,
                    from: self.me.clone(),
                },
            ));
        }
    }

    /// The latest time a majority of the voters followed this leader (`lease`): itself
    /// among them if it votes.
    fn anchor(&self, peers: &BTreeMap<String, Progress>, now: Duration) -> Option<Duration> {
        let m = self.members();
        let echoes = peers
            .iter()
            .filter(|(p, _)| m.is_voter(p))
            .map(|(_, pr)| pr.echo);
        // `confirmed` counts the leader itself: one more from the others if it does not vote
        let needed = m.majority() + usize::from(!m.is_voter(&self.me));
        lease::confirmed(echoes, needed, now)
    }

    // ---- changes of members -------------------------------------------------------------

    /// Change the replicas by one (`change`), on the leader: the new configuration is
    /// appended (and journaled: see `out`) and in use at once; its seq, which the caller
    /// waits to see committed. Refused unless this is the leader, an entry of its term is
    /// committed, no other change is under way (a configuration not committed, or a learner
    /// not yet promoted — but removing that learner, which cancels its addition), and a
    /// majority of the voters that would remain answers it.
    pub(crate) fn change(
        &mut self,
        change: &Change,
        now: Duration,
        out: &mut Vec<Out>,
    ) -> Result<u64, ChangeError> {
        let Role::Leader { peers, first, .. } = &self.role else {
            return Err(ChangeError::NotLeader);
        };
        if self.commit < *first {
            return Err(ChangeError::NotReady);
        }
        if let Some((seq, m)) = self.configs.get(1) {
            return Err(ChangeError::Pending(format!(
                "the configuration at seq {seq} ({m}) is not committed yet"
            )));
        }
        let current = self.members();
        if let Some(l) = current.learners.first() {
            if *change != Change::Remove(l.clone()) {
                let lag = peers
                    .get(l)
                    .map_or(self.last().0, |p| self.last().0.saturating_sub(p.matched));
                return Err(ChangeError::Pending(format!(
                    "{l} is catching up as a learner (lag {lag}); remove it to cancel"
                )));
            }
        }
        let node = change.node();
        if node.is_empty() || node.len() > crate::MAX_NAME_LEN || node.contains(char::is_whitespace)
        {
            return Err(ChangeError::InvalidNode(node.to_string()));
        }
        let next = current.changed(change)?;
        if matches!(change, Change::Remove(n) if current.is_voter(n)) {
            let election = self.timing.election;
            let live: Vec<String> = next
                .voters
                .iter()
                .filter(|v| {
                    **v == self.me
                        || peers.get(*v).is_some_and(|p| {
                            p.acked.is_some_and(|t| now.saturating_sub(t) < election)
                        })
                })
                .cloned()
                .collect();
            if live.len() < next.majority() {
                return Err(ChangeError::NoMajority {
                    node: node.to_string(),
                    remain: next.voters.clone(),
                    live,
                });
            }
        }
        let seq = self.append_members(next, out);
        self.replicate(now, out);
        Ok(seq)
    }

    /// The leader appends configuration `m` as its next entry (journaled: `out`).
    fn append_members(&mut self, m: Members, out: &mut Vec<Out>) -> u64 {
        let seq = self.last().0 + 1;
        self.tail.push_back(Op {
            seq,
            term: self.term,
            body: OpBody::Members(m.clone()),
        });
        self.logged_members(seq, m);
        self.reconfigured();
        out.push(Out::Journal(seq, seq));
        seq
    }

    /// A learner that holds everything committed is promoted to a voter (by the leader, if
    /// no other change is under way).
    fn promote_if_caught_up(&mut self, from: &str, out: &mut Vec<Out>) {
        let Role::Leader { peers, first, .. } = &self.role else {
            return;
        };
        let caught_up = peers.get(from).is_some_and(|p| p.matched >= self.commit);
        if !caught_up
            || !self.members().is_learner(from)
            || self.configs.len() > 1
            || self.commit < *first
            || self.removed
        {
            return;
        }
        let next = self.members().promoted(from);
        self.append_members(next, out);
    }

    fn random(&mut self, below: u64) -> u64 {
        // xorshift64*: enough to spread the replicas' timeouts
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D) % below.max(1)
    }

    fn election_timeout(&mut self) -> Duration {
        let half = self.timing.election.as_millis() as u64 / 2;
        self.timing.election + Duration::from_millis(self.random(half + 1))
    }

    // ---- the leader's side --------------------------------------------------------------

    /// Append `body` as the leader's next entry (its seq is the record's); `None` if this
    /// replica is not the leader. The actor journals it and calls [`Core::replicate`] once it
    /// has gathered a batch.
    pub(crate) fn propose(&mut self, body: OpBody) -> Option<&Op> {
        if !self.is_leader() {
            return None;
        }
        let seq = self.last().0 + 1;
        if let OpBody::Members(m) = &body {
            self.logged_members(seq, m.clone());
        }
        self.tail.push_back(Op {
            seq,
            term: self.term,
            body,
        });
        self.reconfigured();
        self.tail.back()
    }

    /// Send each replica what it lacks (or a heartbeat, if it is due).
    pub(crate) fn replicate(&mut self, now: Duration, out: &mut Vec<Out>) {
        let Role::Leader {
            peers, outsiders, ..
        } = &self.role
        else {
            return;
        };
        let names: Vec<String> = peers.keys().chain(outsiders.keys()).cloned().collect();
        let mut shared = Vec::new();
        for peer in names {
            self.send_to(&peer, now, false, &mut shared, out);
        }
    }

    /// Send `peer` what it lacks (or a heartbeat). `shared`: the entries sent to other
    /// replicas in this round, by the seq they start at.
    fn send_to(
        &mut self,
        peer: &str,
        now: Duration,
        force: bool,
        shared: &mut Vec<(u64, Ops)>,
        out: &mut Vec<Out>,
    ) {
        let (last, base, commit, term) = (self.last().0, self.base, self.commit, self.term);
        let held = self.held_everywhere();
        let commit_term = self.term_at(commit).unwrap_or(0);
        let (heartbeat, election) = (self.timing.heartbeat, self.timing.election);
        // while the preferred replica takes over, the others get nothing it may lack
        let last = match self.handed {
            Some((at, upto))
                if peer != self.preferred_member && now.saturating_sub(at) < election / 4 =>
            {
                last.min(upto)
            }
            _ => last,
        };
        let Some(pr) = progress_mut(&mut self.role, peer) else {
            return;
        };
        if let Some(at) = pr.installing {
            // its parts count as heartbeats; sent again if unanswered for long
            if now.saturating_sub(at) < 2 * election {
                return;
            }
            pr.installing = None;
        }
        if pr.next <= base.0 {
            // the entries it needs are gone from memory: a snapshot of the committed store
            pr.installing = Some(now);
            pr.sent = Some(now);
            pr.next = commit + 1;
            pr.probing = true;
            out.push(Out::Install(peer.to_string(), commit, commit_term));
            return;
        }
        let due = pr.sent.is_none_or(|t| now.saturating_sub(t) >= heartbeat);
        let has_new = pr.next <= last && pr.next - 1 - pr.matched.min(pr.next - 1) < INFLIGHT;
        // probing: one append at a time, until one is taken; else as much as there is
        let go = if pr.probing {
            force || due
        } else {
            force || due || has_new
        };
        if !go {
            return;
        }
        let prev_seq = pr.next - 1;
        let n = if has_new {
            (last - prev_seq).min(OPS_PER_APPEND as u64) as usize
        } else {
            0
        };
        let start = (pr.next - base.0 - 1) as usize;
        // the replicas that lack the same entries share them (encoded once when sent)
        let ops = match shared
            .iter()
            .find(|(at, o)| *at == prev_seq + 1 && o.len() == n)
        {
            Some((_, o)) => o.clone(),
            None => {
                let o = Ops::encode(self.tail.range(start..start + n));
                shared.push((prev_seq + 1, o.clone()));
                o
            }
        };
        let prev_term = if prev_seq == base.0 {
            base.1
        } else {
            self.tail[(prev_seq - base.0 - 1) as usize].term
        };
        let Some(pr) = progress_mut(&mut self.role, peer) else {
            return;
        };
        pr.sent = Some(now);
        if !pr.probing {
            pr.next += n as u64;
        }
        out.push(Out::Send(
            peer.to_string(),
            ReplicaMsg::Append {
                term,
                leader: self.me.clone(),
                prev_seq,
                prev_term,
                ops,
                commit,
                at: nanos(now),
                held,
            },
        ));
    }

    fn on_append_ack(
        &mut self,
        from: &str,
        (ok, last, at): (bool, u64, u64),
        now: Duration,
        out: &mut Vec<Out>,
    ) {
        let Role::Leader {
            peers, outsiders, ..
        } = &mut self.role
        else {
            return;
        };
        let Some(pr) = peers.get_mut(from) else {
            if let Some(pr) = outsiders.get_mut(from) {
                // an outsider being told: only how far it holds the log matters
                pr.answered(ok, last);
                self.told_outsider(from, now, out);
            }
            return;
        };
        pr.acked = Some(now);
        if at > 0 {
            // it took in an `Append` of this term sent then: it follows this leader since
            pr.echo = pr.echo.max(Some(Duration::from_nanos(at)));
        }
        pr.answered(ok, last);
        if ok {
            let caught_up = pr.matched >= self.last().0;
            self.advance_commit(out);
            self.promote_if_caught_up(from, out);
            if caught_up
                && from == self.preferred_member
                && self.me != self.preferred_member
                && self.members().is_voter(from)
                && !self.change_pending()
            {
                self.hand_over(now, out);
            }
        }
        self.send_to(from, now, false, &mut Vec::new(), out);
    }

    /// Ask the preferred replica, as up to date as this leader, to take over — at most once
    /// per election timeout (if it cannot win, this leader goes on).
    ///
    /// This leader goes on taking writes meanwhile, but for a quarter of an election
    /// timeout the other replicas get none past its last seq now (Raft stops taking writes
    /// instead): else a replica that got one the preferred replica had not yet would refuse it
    /// its vote, this leader would step down at its campaign all the same, and the next
    /// leader would hand over again — a round of failed hand-overs, one every ~0.8 s, seen
    /// in the failover bench. The preferred replica commits them with this one meanwhile.
    fn hand_over(&mut self, now: Duration, out: &mut Vec<Out>) {
        if self
            .handed
            .is_some_and(|(t, _)| now.saturating_sub(t) < self.timing.election)
        {
            return;
        }
        self.handed = Some((now, self.last().0));
        out.push(Out::Send(
            self.preferred_member.clone(),
            ReplicaMsg::TimeoutNow {
                term: self.term,
                from: self.me.clone(),
            },
        ));
    }

    fn advance_commit(&mut self, out: &mut Vec<Out>) {
        let Role::Leader { peers, .. } = &self.role else {
            return;
        };
        // the voters only, itself if it votes (a leader removing itself does not)
        let m = self.members();
        let mut held: Vec<u64> = peers
            .iter()
            .filter(|(p, _)| m.is_voter(p))
            .map(|(_, pr)| pr.matched)
            .collect();
        if m.is_voter(&self.me) {
            held.push(self.durable_here());
        }
        held.sort_unstable_by(|a, b| b.cmp(a));
        let Some(&n) = held.get(self.majority() - 1) else {
            return;
        };
        if n > self.commit && self.term_at(n) == Some(self.term) {
            self.commit = n;
            self.apply(out);
        }
    }

    /// The seq up to which every replica holds the log durably: on a leader, the least of
    /// what its peers matched and of what is durable here; on another replica, what the
    /// leader last told. No replica can need an entry up to it from memory: the tail drops
    /// them ([`Core::trim`]), so that replicas that all keep up keep next to nothing there.
    /// The entries it keeps in memory, and the bytes they take.
    pub(crate) fn tail_held(&self) -> (usize, usize) {
        (self.tail.len(), self.tail.bytes())
    }

    fn held_everywhere(&self) -> u64 {
        match &self.role {
            Role::Leader { peers, .. } => peers
                .values()
                .map(|p| p.matched)
                .chain([self.durable_here()])
                .min()
                .unwrap_or(0),
            _ => self.held,
        }
    }

    /// The last seq durable here that is still this replica's entry.
    fn durable_here(&self) -> u64 {
        if self.term_at(self.durable.0) == Some(self.durable.1) {
            self.durable.0
        } else {
            0
        }
    }

    // ---- reads ---------------------------------------------------------------------------

    /// What a read asked at `asked` may do at `now` (see `lease`): answered from the store
    /// while the lease holds, or once a majority followed this leader since `asked`; refused
    /// on a replica that is not the leader, or after an election timeout of waiting.
    pub(crate) fn read(&self, asked: Duration, now: Duration) -> Read {
        let Role::Leader { peers, first, .. } = &self.role else {
            return Read::Refuse;
        };
        if self.unchecked_reads {
            return Read::Serve;
        }
        if self.applied >= *first {
            if let Some(anchor) = self.anchor(peers, now) {
                // after a hand-over the voters skip their guard: no lease for the term
                let leased = self.handed.is_none() && now < anchor + self.timing.lease;
                if leased || anchor >= asked {
                    return Read::Serve;
                }
            }
        }
        if now.saturating_sub(asked) >= self.timing.election {
            Read::Refuse
        } else {
            Read::Wait
        }
    }

    /// A read asked at `asked` waits: unless a round went out since, send every replica an
    /// `Append` now — their answers confirm this leader ([`Core::read`]). One round at a time
    /// (until it is answered, or for a heartbeat): reads that come meanwhile wait for the
    /// next, not a round each.
    pub(crate) fn confirm(&mut self, asked: Duration, now: Duration, out: &mut Vec<Out>) {
        let Role::Leader { peers, .. } = &self.role else {
            return;
        };
        if let Some(t) = self.confirming {
            let answered = self.anchor(peers, now).is_some_and(|anchor| anchor >= t);
            if t >= asked || !answered && now.saturating_sub(t) < self.timing.heartbeat {
                return;
            }
        }
        self.confirming = Some(now);
        let names: Vec<String> = peers.keys().cloned().collect();
        let mut shared = Vec::new();
        for peer in names {
            self.send_to(&peer, now, true, &mut shared, out);
        }
    }

    /// The earliest time from `now` on that this replica may vote for a replica other than
    /// the leader it last heard (itself included): after the lease's guard. (With reads
    /// unchecked there is no lease to guard.)
    fn unguarded(&self, now: Duration) -> Duration {
        if self.unchecked_reads {
            return now;
        }
        self.contact
            .until(self.timing.guard())
            .map_or(now, |u| u.max(now))
    }

    /// Whether it must refuse `candidate` its vote at `now` for the lease's guard.
    fn barred(&self, candidate: &str, now: Duration) -> bool {
        !self.unchecked_reads && self.contact.bars(candidate, now, self.timing.guard())
    }

    // ---- everyone ------------------------------------------------------------------------

    /// The entries up to `seq` (of `term`) are durable here (the journal said so).
    pub(crate) fn durable(&mut self, seq: u64, term: u64, out: &mut Vec<Out>) {
        if self.term_at(seq) != Some(term) || seq < self.durable.0 && self.durable_here() != 0 {
            return;
        }
        self.durable = (seq, term);
        if self.is_leader() {
            self.advance_commit(out);
        } else if let Some(leader) = self.leader.clone() {
            if leader != self.me {
                out.push(self.held_ack(leader));
            }
        }
    }

    /// Tell `leader` how far this replica holds its log, durably.
    fn held_ack(&self, leader: String) -> Out {
        Out::Send(
            leader,
            ReplicaMsg::AppendAck {
                term: self.term,
                from: self.me.clone(),
                ok: true,
                last: self.durable_here().min(self.verified),
                at: self.echo,
            },
        )
    }

    fn apply(&mut self, out: &mut Vec<Out>) {
        let upto = self.commit.min(self.last().0);
        if upto > self.applied {
            out.push(Out::Apply(self.applied + 1, upto));
            self.applied = upto;
        }
        self.settle_members(out);
    }

    /// Drop the applied entries every replica holds ([`Core::held_everywhere`]), and the
    /// oldest applied entries beyond what it keeps in memory (a replica that still needs
    /// them gets a snapshot). Called once the actor has carried out the [`Out`]s that name
    /// entries: they may name these.
    ///
    /// Why the first: the bound alone let every replica of a datamanager that never lags
    /// hold its last [`TAIL_KEEP`] entries (up to [`KEEP_BYTES`](tail::KEEP_BYTES)) for
    /// good — a copy of the store's newest records no replica would ever ask for. On a
    /// kept-up cluster the nodes' memory grew with every run until each datamanager's tail
    /// was full (the soak's replica nodes, 31 MiB to 98–135 MiB over 20–30 runs).
    pub(crate) fn trim(&mut self) {
        let held = self.held_everywhere().min(self.applied);
        let keep_from = if let Role::Leader { peers, .. } = &self.role {
            peers
                .values()
                .map(|p| p.matched)
                .min()
                .unwrap_or(self.applied)
        } else {
            self.applied
        };
        let (keep, keep_bytes, applied) = (self.keep, self.keep_bytes, self.applied);
        let over = |len: usize, bytes: usize, k: usize| len > keep * k || bytes > keep_bytes * k;
        let dropped = self.tail.drop_front_while(|op, len, bytes| {
            op.seq <= held
                || over(len, bytes, 1)
                    && op.seq <= applied
                    && (op.seq <= keep_from || over(len, bytes, 2))
        });
        if let Some(last) = dropped {
            self.base = last;
        }
    }

    /// A message from another replica.
    pub(crate) fn receive(&mut self, msg: ReplicaMsg, now: Duration, out: &mut Vec<Out>) {
        self.clock = self.clock.max(now);
        match msg {
            ReplicaMsg::Append {
                term,
                leader,
                prev_seq,
                prev_term,
                ops,
                commit,
                at,
                held,
            } => {
                if term >= self.term {
                    // a fact of the log's prefix, true whoever told it last
                    self.held = self.held.max(held);
                }
                self.on_append(
                    (term, leader, at),
                    (prev_seq, prev_term),
                    ops.into_vec(),
                    commit,
                    now,
                    out,
                )
            }
            ReplicaMsg::AppendAck {
                term,
                from,
                ok,
                last,
                at,
            } => {
                if term > self.term && self.stranger(&from) {
                    self.outsider_of_newer_term(&from, term);
                } else if term > self.term {
                    self.adopt(term, out);
                } else if term == self.term {
                    self.on_append_ack(&from, (ok, last, at), now, out);
                }
            }
            ReplicaMsg::Vote {
                term,
                candidate,
                pre,
                ..
            } if self.is_leader() && self.stranger(&candidate) => {
                self.on_outsider_vote(term, candidate, pre, now, out)
            }
            ReplicaMsg::Vote {
                term,
                candidate,
                last_seq,
                last_term,
                pre,
                transfer,
            } => self.on_vote(
                term,
                candidate,
                (last_term, last_seq),
                (pre, transfer),
                now,
                out,
            ),
            ReplicaMsg::TimeoutNow { term, from } => {
                // from this term's leader only: campaign at once, no pre-vote
                if term == self.term
                    && self.leader.as_deref() == Some(from.as_str())
                    && !self.is_leader()
                    && self.votes()
                {
                    self.campaign_as(false, true, now, out);
                }
            }
            ReplicaMsg::VoteAck {
                term,
                asked,
                from,
                granted,
                pre,
            } => self.on_vote_ack(term, asked, from, granted, pre, now, out),
            ReplicaMsg::Install { .. } => {
                // the actor takes snapshots in: see `install_from`
            }
        }
    }

    /// A snapshot part from `leader` in `term`, of a snapshot ending at `seq`: whether to
    /// take it in (else the answer is in `out`). Taking it in counts as hearing from the
    /// leader. A snapshot this replica has committed past already is not taken: its own
    /// committed entries are the same, and newer.
    pub(crate) fn install_from(
        &mut self,
        term: u64,
        leader: &str,
        seq: u64,
        now: Duration,
        out: &mut Vec<Out>,
    ) -> bool {
        if term < self.term {
            out.push(Out::Send(
                leader.to_string(),
                ReplicaMsg::AppendAck {
                    term: self.term,
                    from: self.me.clone(),
                    ok: false,
                    last: self.last().0,
                    at: self.echo,
                },
            ));
            return false;
        }
        self.follow(term, leader, now, out);
        if seq <= self.commit {
            self.verified = self.verified.max(self.commit);
            out.push(Out::Send(
                leader.to_string(),
                ReplicaMsg::AppendAck {
                    term: self.term,
                    from: self.me.clone(),
                    ok: true,
                    last: self.commit.min(self.durable_here().max(self.applied)),
                    at: self.echo,
                },
            ));
            return false;
        }
        true
    }

    /// A snapshot ending at (`seq`, `term`) was taken in and journaled: the log starts
    /// after it, and the configuration is the snapshot's (`members`, with its seq; `None`
    /// from a leader that sent none: the newest this replica held up to `seq`). The actor
    /// calls [`Core::durable`] once the journal has it. A configuration without this replica,
    /// newer than the one it joined: it is out ([`Out::Removed`], as at a commit) — an
    /// outsider told so by a snapshot.
    pub(crate) fn installed(
        &mut self,
        seq: u64,
        term: u64,
        members: Option<(u64, Members)>,
        out: &mut Vec<Out>,
    ) {
        self.tail.clear();
        self.base = (seq, term);
        self.commit = seq;
        self.applied = seq;
        self.verified = seq;
        self.durable = (0, 0);
        let keep = 1 + self.configs[1..]
            .iter()
            .take_while(|(s, _)| *s <= seq)
            .count();
        self.configs.truncate(keep);
        let newest = self.configs.pop().expect("one configuration at least");
        let (at, m) = members.unwrap_or(newest);
        let out_now = !m.contains(&self.me) && self.joined_at.is_some_and(|j| j < at);
        if m.contains(&self.me) {
            self.joined_at.get_or_insert(at);
            self.removed = false;
        }
        self.configs = vec![(at, m)];
        self.reconfigured();
        if out_now && !self.removed {
            self.removed = true;
            out.push(Out::Removed);
        }
    }

    /// Become a follower of `leader` in `term` (adopting a higher term).
    fn follow(&mut self, term: u64, leader: &str, now: Duration, out: &mut Vec<Out>) {
        if term > self.term {
            self.adopt(term, out);
        }
        if self.is_leader() {
            // two leaders in one term cannot happen: a bug, said loudly
            tracing::error!(term, me = %self.me, other = leader, "two leaders in one term");
            // (the reason reaches the `dm_fenced` event: its words stay)
            self.step_down("another leader in its term", out);
        }
        if self.leader.as_deref() != Some(leader) {
            self.verified = 0;
            self.echo = 0;
        }
        self.role = Role::Follower;
        self.leader = Some(leader.to_string());
        self.heard = Some(now);
        self.contact.heard(leader, now);
        self.deadline = now + self.election_timeout();
    }

    /// A newer term: follow it (no vote given in it yet).
    fn adopt(&mut self, term: u64, out: &mut Vec<Out>) {
        self.term = term;
        self.voted_for = None;
        self.leader = None;
        self.verified = 0;
        self.echo = 0;
        if self.is_leader() {
            self.step_down("a newer term", out);
        }
        self.role = Role::Follower;
        out.push(Out::Persist);
    }

    fn step_down(&mut self, why: &str, out: &mut Vec<Out>) {
        if self.is_leader() {
            self.role = Role::Follower;
            self.leader = None;
            out.push(Out::StepDown(why.to_string()));
        }
    }

    fn on_append(
        &mut self,
        (term, leader, at): (u64, String, u64),
        (prev_seq, prev_term): (u64, u64),
        ops: Vec<Op>,
        commit: u64,
        now: Duration,
        out: &mut Vec<Out>,
    ) {
        let refuse = |core: &Core, last: u64, out: &mut Vec<Out>| {
            out.push(Out::Send(
                leader.clone(),
                ReplicaMsg::AppendAck {
                    term: core.term,
                    from: core.me.clone(),
                    ok: false,
                    last,
                    at: core.echo,
                },
            ));
        };
        if term < self.term {
            refuse(self, self.last().0, out);
            return;
        }
        self.follow(term, &leader, now, out);
        self.echo = self.echo.max(at);
        let last = self.last().0;
        if prev_seq > last {
            refuse(self, last, out);
            return;
        }
        if prev_seq >= self.base.0 && prev_seq > self.commit {
            if self.term_at(prev_seq) != Some(prev_term) {
                // from the first entry of the conflicting term (never below the commit)
                let bad = self.term_at(prev_seq);
                let mut hint = prev_seq - 1;
                while hint > self.commit && hint > self.base.0 && self.term_at(hint) == bad {
                    hint -= 1;
                }
                refuse(self, hint.max(self.commit), out);
                return;
            }
        } else if prev_seq > self.commit && prev_seq < self.base.0 {
            refuse(self, self.commit, out);
            return;
        }
        let new_last = prev_seq + ops.len() as u64;
        let mut first_new = None;
        let mut reconfigured = false;
        for op in ops {
            let seq = op.seq;
            if seq <= self.last().0 {
                if seq <= self.commit || self.term_at(seq) == Some(op.term) {
                    continue;
                }
                // a conflicting uncommitted entry: it and all after it go
                let keep = (seq - self.base.0 - 1) as usize;
                self.tail.truncate(keep);
                self.cut_members(seq);
                if self.durable.0 >= seq {
                    self.durable = (0, 0);
                }
                out.push(Out::Truncate(seq));
            }
            if seq != self.last().0 + 1 {
                // not contiguous: a malformed append; take nothing more from it
                tracing::warn!(
                    seq,
                    last = self.last().0,
                    "replica: an append out of order; ignored"
                );
                break;
            }
            first_new.get_or_insert(seq);
            if let OpBody::Members(m) = &op.body {
                self.logged_members(seq, m.clone());
                reconfigured = true;
            }
            self.tail.push_back(op);
        }
        if reconfigured {
            self.reconfigured();
        }
        if let Some(first) = first_new {
            out.push(Out::Journal(first, self.last().0));
        }
        self.verified = self.verified.max(new_last.min(self.last().0));
        let upto = commit.min(self.verified);
        if upto > self.commit {
            self.commit = upto;
            self.apply(out);
        }
        if first_new.is_none() {
            // nothing new to make durable: answer now (it also says this replica is alive)
            out.push(self.held_ack(leader));
        }
    }

    // ---- elections -----------------------------------------------------------------------

    /// Whether it heard from a live leader within the election timeout (then it neither
    /// votes for another nor takes its term: a replica that was cut off cannot unseat it).
    fn sticky(&self, now: Duration) -> bool {
        match &self.role {
            Role::Leader { .. } => true,
            _ => {
                self.leader.is_some()
                    && self
                        .heard
                        .is_some_and(|t| now.saturating_sub(t) < self.timing.election)
            }
        }
    }

    fn on_vote(
        &mut self,
        term: u64,
        candidate: String,
        last: (u64, u64),
        (pre, transfer): (bool, bool),
        now: Duration,
        out: &mut Vec<Out>,
    ) {
        let (my_seq, my_term) = self.last();
        let up_to_date = last >= (my_term, my_seq);
        let answer = |core: &Core, granted: bool, out: &mut Vec<Out>| {
            out.push(Out::Send(
                candidate.clone(),
                ReplicaMsg::VoteAck {
                    term: core.term,
                    asked: term,
                    from: core.me.clone(),
                    granted,
                    pre,
                },
            ));
        };
        let sticky = self.sticky(now) && self.leader.as_deref() != Some(candidate.as_str());
        // the guard holds even once the failure detector spoke: a leader it followed may
        // still answer reads on its lease (`lease`); a hand-over's election skips both
        if !transfer && (sticky || self.barred(&candidate, now)) {
            answer(self, false, out);
            return;
        }
        if pre {
            self.campaign_soon_if_behind(up_to_date, now);
            answer(self, term > self.term && up_to_date, out);
            return;
        }
        if term < self.term {
            answer(self, false, out);
            return;
        }
        if term > self.term {
            self.adopt(term, out);
        }
        self.campaign_soon_if_behind(up_to_date, now);
        let free = self.voted_for.as_deref().is_none_or(|v| v == candidate);
        let granted = free && up_to_date;
        if granted && self.voted_for.is_none() {
            self.voted_for = Some(candidate.clone());
            out.push(Out::Persist);
            self.deadline = now + self.election_timeout();
        }
        answer(self, granted, out);
    }

    /// A candidate less up to date than this replica asked for its vote, and this replica knows
    /// no leader (also after taking the candidate's term): campaign soon rather than at its
    /// election timeout. Else nobody may win until that timeout (2.5 s and more): when this
    /// replica's own campaign was refused by one that had not yet seen the leader go
    /// (stickiness), or when the candidate took this replica's term from a leader that then
    /// went (a hand-over to a replica that lacked an entry, the leader frozen at once: this
    /// replica's failure detector then names a node that is no longer its leader).
    fn campaign_soon_if_behind(&mut self, up_to_date: bool, now: Duration) {
        if !up_to_date && self.leader.is_none() && !self.is_leader() {
            let soon = self.unguarded(now) + self.rank_delay(None);
            self.deadline = self.deadline.min(soon);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn on_vote_ack(
        &mut self,
        term: u64,
        asked: u64,
        from: String,
        granted: bool,
        pre: bool,
        now: Duration,
        out: &mut Vec<Out>,
    ) {
        if term > self.term && !granted && !self.stranger(&from) {
            self.adopt(term, out);
            return;
        }
        let expected = if pre { self.term + 1 } else { self.term };
        let majority = self.majority();
        let Role::Candidate { pre: p, votes } = &mut self.role else {
            return;
        };
        if *p != pre || asked != expected || !granted {
            return;
        }
        if !self.configs[self.configs.len() - 1].1.is_voter(&from) {
            // a learner's (or a removed replica's) vote counts for nothing
            return;
        }
        votes.insert(from);
        if votes.len() < majority {
            return;
        }
        if pre {
            self.campaign(false, now, out);
        } else {
            self.lead(now, out);
        }
    }

    /// Ask every visible replica for its (pre-)vote.
    fn campaign(&mut self, pre: bool, now: Duration, out: &mut Vec<Out>) {
        self.campaign_as(pre, false, now, out);
    }

    /// [`Core::campaign`]; `transfer`: at the leader's word (voters ignore stickiness).
    fn campaign_as(&mut self, pre: bool, transfer: bool, now: Duration, out: &mut Vec<Out>) {
        if !pre {
            self.term += 1;
            self.voted_for = Some(self.me.clone());
            out.push(Out::Persist);
        }
        self.leader = None;
        self.role = Role::Candidate {
            pre,
            votes: BTreeSet::from([self.me.clone()]),
        };
        self.deadline = now + self.election_timeout();
        let (last_seq, last_term) = self.last();
        let term = if pre { self.term + 1 } else { self.term };
        let m = self.members();
        let peers: Vec<String> = self.peers().filter(|p| m.is_voter(p)).cloned().collect();
        for p in peers {
            out.push(Out::Send(
                p,
                ReplicaMsg::Vote {
                    term,
                    candidate: self.me.clone(),
                    last_seq,
                    last_term,
                    pre,
                    transfer,
                },
            ));
        }
        if self.majority() == 1 {
            if pre {
                self.campaign(false, now, out);
            } else {
                self.lead(now, out);
            }
        }
    }

    fn lead(&mut self, now: Duration, out: &mut Vec<Out>) {
        let next = self.last().0 + 1;
        let peers = self
            .peers()
            .map(|p| (p.clone(), Progress::fresh(next)))
            .collect();
        self.role = Role::Leader {
            peers,
            outsiders: BTreeMap::new(),
            since: now,
            first: next,
        };
        self.handed = None;
        self.confirming = None;
        self.leader = Some(self.me.clone());
        self.verified = 0;
        // a new leader's first entry: committing it commits everything before it
        self.tail.push_back(Op {
            seq: next,
            term: self.term,
            body: OpBody::Noop,
        });
        out.push(Out::Journal(next, next));
        out.push(Out::Lead);
        self.replicate(now, out);
    }

    /// Time passed: campaign, send heartbeats, or step down without a majority.
    pub(crate) fn tick(&mut self, now: Duration, out: &mut Vec<Out>) {
        self.clock = self.clock.max(now);
        match &self.role {
            Role::Leader { peers, since, .. } => {
                let m = self.members();
                let fresh = usize::from(m.is_voter(&self.me))
                    + peers
                        .iter()
                        .filter(|(p, pr)| {
                            m.is_voter(p)
                                && pr
                                    .acked
                                    .is_some_and(|t| now.saturating_sub(t) < self.timing.election)
                        })
                        .count();
                if fresh < self.majority() && now.saturating_sub(*since) >= self.timing.election {
                    self.step_down("it lost its majority", out);
                    self.deadline = now + self.election_timeout();
                    return;
                }
                self.replicate(now, out);
            }
            _ if now >= self.deadline => {
                if !self.votes() {
                    // a learner, or a replica removed: it never campaigns
                    self.deadline = now + self.election_timeout();
                } else if self.unguarded(now) > now {
                    // it may not vote for itself yet: a leader it followed may hold a lease
                    self.deadline = self.unguarded(now) + self.rank_delay(None);
                } else if self.visible_voters() + 1 >= self.majority() {
                    self.campaign(true, now, out);
                } else {
                    self.deadline = now + self.election_timeout();
                }
            }
            _ => {}
        }
    }

    /// The replica on `node` is reachable (it joined the replicas' group).
    pub(crate) fn peer_up(&mut self, node: &str, now: Duration, out: &mut Vec<Out>) {
        if node == self.me {
            return;
        }
        if !self.others.iter().any(|m| m == node) {
            self.outsider_seen(node, now, out);
            return;
        }
        self.visible.insert(node.to_string());
        if matches!(self.role, Role::Follower)
            && self.leader.is_none()
            && self.votes()
            && self.visible_voters() + 1 >= self.majority()
        {
            // a majority is reachable and no leader is known (a cluster starting): campaign
            // soon rather than after an election timeout — the configured leader at once,
            // the others a quarter of a timeout later, so that it rarely has to be handed
            // the role afterwards (its node may be busy starting)
            let grace = if self.preferred {
                Duration::ZERO
            } else {
                self.timing.election / 4
            };
            let soon = now + grace + self.rank_delay(None);
            self.deadline = self.deadline.min(soon);
        }
        if let Role::Leader { peers, .. } = &mut self.role {
            if let Some(pr) = peers.get_mut(node) {
                // one append at a time until it answers (what it has is unknown)
                pr.probing = true;
                pr.sent = None;
                pr.installing = None;
            }
            self.send_to(node, now, true, &mut Vec::new(), out);
        }
    }

    /// The replica on `node` is gone (its actor died, or its node was declared down). If it was
    /// the leader, campaign soon: the lower-ranked replicas first, so they rarely split.
    pub(crate) fn peer_down(&mut self, node: &str, now: Duration) {
        self.visible.remove(node);
        if let Role::Leader { outsiders, .. } = &mut self.role {
            outsiders.remove(node);
        }
        if self.leader.as_deref() == Some(node) && !self.is_leader() {
            self.leader = None;
            self.heard = None;
            let soon = self.unguarded(now) + self.rank_delay(Some(node));
            self.deadline = self.deadline.min(soon);
        }
    }

    /// Whether `node` keeps no replica in any configuration this replica holds (nor is it).
    fn stranger(&self, node: &str) -> bool {
        node != self.me && !self.others.iter().any(|o| o == node)
    }

    /// A replica on `node` that no configuration this one holds names was met: its actor
    /// appeared, or a message came from it. It was removed while its node was away (or its
    /// node started again on a wiped data directory) and believes it is one of the replicas;
    /// the last word a leader gives the replicas it removes, at the commit, reached only
    /// those present then. On a leader: it is sent the log — or a snapshot, the entries
    /// gone from memory — up to the committed configuration, which does not name it, with
    /// the commit, until it holds it: it then knows it is out (and says so in its journal).
    /// It counts for nothing meanwhile. Another replica leaves it to the leader.
    pub(crate) fn outsider_seen(&mut self, node: &str, now: Duration, out: &mut Vec<Out>) {
        if !self.stranger(node) {
            return;
        }
        let next = self.last().0 + 1;
        let Role::Leader { outsiders, .. } = &mut self.role else {
            return;
        };
        if outsiders.contains_key(node) {
            return;
        }
        tracing::debug!(me = %self.me, node, "replica: a replica no configuration names: sent the log up to the configuration without it");
        outsiders.insert(node.to_string(), Progress::fresh(next));
        self.send_to(node, now, true, &mut Vec::new(), out);
    }

    /// An outsider of a newer `term` (it campaigned while it was away) answered: this leader
    /// cannot tell it, and must not be deposed by it — it stays an outsider (its pre-votes
    /// fail: its log lacks what was committed without it).
    fn outsider_of_newer_term(&mut self, node: &str, term: u64) {
        if let Role::Leader { outsiders, .. } = &mut self.role {
            if outsiders.remove(node).is_some() {
                tracing::warn!(me = %self.me, node, term, "replica: an outsider of a newer term cannot be told it is out");
            }
        }
    }

    /// A replica no configuration names asks this leader for a vote (removed while it was
    /// away): refused, its term never taken (it must not depose this leader), and it is
    /// told it is out.
    fn on_outsider_vote(
        &mut self,
        asked: u64,
        candidate: String,
        pre: bool,
        now: Duration,
        out: &mut Vec<Out>,
    ) {
        out.push(Out::Send(
            candidate.clone(),
            ReplicaMsg::VoteAck {
                term: self.term,
                asked,
                from: self.me.clone(),
                granted: false,
                pre,
            },
        ));
        self.outsider_seen(&candidate, now, out);
    }

    /// An outsider answered: done once it holds the committed configuration (it took in
    /// the commit with it), else sent what it still lacks.
    fn told_outsider(&mut self, node: &str, now: Duration, out: &mut Vec<Out>) {
        let upto = self.configs[0].0;
        let Role::Leader { outsiders, .. } = &mut self.role else {
            return;
        };
        if outsiders.get(node).is_some_and(|pr| pr.matched >= upto) {
            tracing::debug!(me = %self.me, node, "replica: an outsider holds the configuration without it");
            outsiders.remove(node);
            return;
        }
        self.send_to(node, now, false, &mut Vec::new(), out);
    }

    /// The outsiders a leader is telling ([`Core::outsider_seen`]).
    #[cfg(test)]
    pub(crate) fn outsiders(&self) -> Vec<String> {
        match &self.role {
            Role::Leader { outsiders, .. } => outsiders.keys().cloned().collect(),
            _ => Vec::new(),
        }
    }

    /// The voters it reaches now (itself not counted).
    fn visible_voters(&self) -> usize {
        let m = self.members();
        self.visible.iter().filter(|v| m.is_voter(v)).count()
    }

    /// How long to wait before campaigning when no leader is known: the configured leader
    /// at once, the others by their rank among the members (but `gone`), 60 ms apart, with a
    /// little randomness, so that they rarely split the votes.
    fn rank_delay(&mut self, gone: Option<&str>) -> Duration {
        let rank = if self.preferred {
            0
        } else {
            1 + self
                .members()
                .voters
                .iter()
                .filter(|m| Some(m.as_str()) != gone)
                .position(|m| *m == self.me)
                .unwrap_or(0) as u64
        };
        Duration::from_millis(rank * 60 + self.random(30))
    }
}

#[cfg(test)]
mod tests;

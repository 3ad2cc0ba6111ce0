//! The lease's cases, on the simulated replicas of `tests`: a lease lapses without a
//! majority's word and comes back with it, a leader cut off stops answering before the
//! others can elect (and, without leases, answers stale reads), a read without a lease waits
//! for a round of answers or is refused, and a follower's guard outlasts its failure
//! detector's word and its own restart.

use super::*;

/// Every message delivered, time standing still.
fn all(_: &str, _: &str, _: &mut ReplicaMsg) -> bool {
    true
}

/// Settled replicas with a leader whose followers just answered its heartbeats.
fn settled(seed: u64, unchecked: bool) -> (Sim, String) {
    let mut sim = Sim::with_reads(seed, TAIL_KEEP, unchecked);
    sim.settle();
    let leader = sim.leader().expect("a leader");
    beat(&mut sim);
    (sim, leader)
}

/// A heartbeat round, every message delivered: time passes by a heartbeat.
fn beat(sim: &mut Sim) {
    sim.now += sim.timing.heartbeat;
    sim.tick_all();
    exchange(sim, &mut all);
}

fn read_now(sim: &mut Sim, m: &str) -> Read {
    let now = sim.now;
    sim.core(m).read(now, now)
}

#[test]
fn a_lease_lapses_without_a_majoritys_word_and_comes_back_with_it() {
    let (mut sim, leader) = settled(3, false);
    let sent = sim.now;
    assert_eq!(read_now(&mut sim, &leader), Read::Serve, "the lease holds");
    // from now on nothing reaches the leader
    let mut lapsed = None;
    while sim.now < sent + sim.timing.election {
        sim.now += Duration::from_millis(1);
        sim.tick_all();
        sim.wires.clear();
        if read_now(&mut sim, &leader) != Read::Serve {
            lapsed = Some(sim.now);
            break;
        }
    }
    let lapsed = lapsed.expect("the lease lapsed");
    assert!(
        lapsed <= sent + sim.timing.lease,
        "lapsed at {lapsed:?}, the last word was sent at {sent:?}"
    );
    assert_eq!(read_now(&mut sim, &leader), Read::Wait, "a read waits");
    let asked = sim.now;
    // a round of answers confirms it, and renews the lease
    let mut out = Vec::new();
    let now = sim.now;
    sim.core(&leader).confirm(asked, now, &mut out);
    sim.run(&leader, out);
    exchange(&mut sim, &mut all);
    let now = sim.now;
    assert_eq!(sim.core(&leader).read(asked, now), Read::Serve);
    assert_eq!(read_now(&mut sim, &leader), Read::Serve, "leased again");
}

#[test]
fn a_read_that_waits_an_election_timeout_for_the_replicas_word_is_refused() {
    let (mut sim, leader) = settled(5, false);
    sim.now += sim.timing.lease;
    let asked = sim.now;
    assert_eq!(read_now(&mut sim, &leader), Read::Wait);
    // its round is lost, and so is every later one
    let mut out = Vec::new();
    sim.core(&leader).confirm(asked, asked, &mut out);
    assert!(
        out.iter().filter(|o| matches!(o, Out::Send(..))).count() == 2,
        "a round to both followers: {out:?}"
    );
    let before = sim.now + sim.timing.election - Duration::from_millis(1);
    assert_eq!(sim.core(&leader).read(asked, before), Read::Wait);
    let after = asked + sim.timing.election;
    assert_eq!(sim.core(&leader).read(asked, after), Read::Refuse);
    // a follower refuses every read
    let follower = MEMBERS.iter().find(|m| **m != leader).unwrap();
    let now = sim.now;
    assert_eq!(sim.core(follower).read(now, now), Read::Refuse);
}

/// The leader cut off from both others, which see it go at once (a failure detector faster
/// than any: the worst case); time passes a millisecond at a time, the other side takes a
/// write as soon as it has a leader. When the old leader's reads stopped being answered,
/// when the others elected, and the stale reads the old leader answered.
fn cut_off(unchecked: bool) -> (Duration, Duration, Vec<String>) {
    let (mut sim, old) = settled(7, unchecked);
    let start = sim.now;
    sim.partition(&old);
    let mut stopped = None;
    let mut elected = None;
    while sim.now < start + 4 * sim.timing.election {
        sim.now += Duration::from_millis(1);
        sim.tick_all();
        exchange(&mut sim, &mut all);
        if let Some(new) = MEMBERS
            .iter()
            .find(|m| **m != old && sim.core(m).is_leader())
        {
            elected.get_or_insert(sim.now);
            sim.propose(new);
            exchange(&mut sim, &mut all);
        }
        sim.read_all();
        if stopped.is_none() && read_now(&mut sim, &old) != Read::Serve {
            stopped = Some(sim.now);
        }
    }
    let stopped = stopped.expect("the old leader stopped answering") - start;
    let elected = elected.expect("the others elected a leader") - start;
    (stopped, elected, sim.stale)
}

#[test]
fn a_cut_off_leader_stops_answering_reads_before_the_others_can_elect() {
    let (stopped, elected, stale) = cut_off(false);
    eprintln!("stopped answering {stopped:?} after the cut, a new leader {elected:?} after it");
    assert!(
        stopped < elected,
        "stopped {stopped:?}, elected {elected:?}"
    );
    assert!(stale.is_empty(), "{stale:#?}");
}

#[test]
fn without_leases_a_cut_off_leader_answers_stale_reads() {
    // the control: the protocol before leases — a new leader elected at once, the old one
    // answering until it sees it lost its majority
    let (stopped, elected, stale) = cut_off(true);
    assert!(
        stopped > elected,
        "stopped {stopped:?}, elected {elected:?}"
    );
    assert!(!stale.is_empty(), "the old leader answered no stale read");
}

#[test]
fn a_leader_without_a_lease_answers_a_read_after_a_round_of_the_replicas_word() {
    // a leader that asked the preferred replica to take over holds no lease for the rest of
    // its term (the voters skip their guard for that election): its reads wait for a round
    let mut sim = Sim::new(17, TAIL_KEEP);
    sim.settle();
    let (stand_in, _, _held) = a_hand_over_held(&mut sim);
    beat(&mut sim);
    sim.now += Duration::from_millis(1);
    let asked = sim.now;
    assert_eq!(read_now(&mut sim, &stand_in), Read::Wait, "no lease");
    let mut out = Vec::new();
    sim.core(&stand_in).confirm(asked, asked, &mut out);
    sim.run(&stand_in, out);
    exchange(&mut sim, &mut |_, _, m| {
        !matches!(m, ReplicaMsg::TimeoutNow { .. })
    });
    let now = sim.now;
    assert_eq!(sim.core(&stand_in).read(asked, now), Read::Serve);
    // a read asked after that round waits for the next one
    sim.now += Duration::from_millis(1);
    assert_eq!(read_now(&mut sim, &stand_in), Read::Wait);
}

#[test]
fn a_new_leader_answers_reads_once_its_own_entry_is_applied() {
    let mut sim = Sim::new(19, TAIL_KEEP);
    sim.settle();
    let old = sim.leader().unwrap();
    sim.crash(&old);
    // elected, with its no-op held back from the others: not applied, no read answered
    let new = elect(
        &mut sim,
        &mut |_, _, m| !matches!(m, ReplicaMsg::Append { ops, .. } if !ops.is_empty()),
    );
    assert!(sim.core(&new).applied() < sim.core(&new).last().0);
    sim.now += Duration::from_millis(1);
    assert_eq!(read_now(&mut sim, &new), Read::Wait);
    beat(&mut sim);
    assert_eq!(read_now(&mut sim, &new), Read::Serve);
}

/// A real vote for `candidate` in the next term asked of `voter` at `now`: granted?
fn vote(sim: &mut Sim, voter: &str, candidate: &str) -> bool {
    let (last_seq, last_term) = sim.core(candidate).last();
    let term = sim.core(voter).term().max(sim.core(candidate).term()) + 1;
    let mut out = Vec::new();
    let now = sim.now;
    let msg = ReplicaMsg::Vote {
        term,
        candidate: candidate.to_string(),
        last_seq,
        last_term,
        pre: false,
        transfer: false,
    };
    sim.core(voter).receive(msg, now, &mut out);
    out.iter().any(|o| {
        matches!(o, Out::Send(to, ReplicaMsg::VoteAck { granted: true, .. }) if to == candidate)
    })
}

#[test]
fn a_follower_votes_for_no_one_else_until_its_guard_passed_whatever_its_detector_says() {
    let (mut sim, leader) = settled(23, false);
    let heard = sim.now;
    let others: Vec<&str> = MEMBERS.iter().copied().filter(|m| *m != leader).collect();
    let (voter, candidate) = (others[0], others[1]);
    sim.now += Duration::from_millis(1);
    let now = sim.now;
    sim.core(voter).peer_down(&leader, now);
    assert!(
        !vote(&mut sim, voter, candidate),
        "refused within the guard"
    );
    sim.now = heard + sim.timing.guard();
    assert!(vote(&mut sim, voter, candidate), "granted once it passed");
}

#[test]
fn a_replica_started_again_votes_for_no_one_for_a_guard() {
    let (mut sim, leader) = settled(29, false);
    let others: Vec<&str> = MEMBERS.iter().copied().filter(|m| *m != leader).collect();
    let (voter, candidate) = (others[0], others[1]);
    sim.crash(voter);
    sim.crash(&leader);
    sim.now += sim.timing.election;
    sim.start(voter);
    let started = sim.now;
    assert!(!vote(&mut sim, voter, candidate), "refused after its start");
    sim.now = started + sim.timing.guard();
    assert!(
        vote(&mut sim, voter, candidate),
        "granted once the guard passed"
    );
}

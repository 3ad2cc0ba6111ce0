//! Changes of the replicas while they run, on the simulated replicas of `tests`: a replica
//! added catches up as a learner and is promoted, a learner counts for nothing, a replica
//! removed stops taking part, a leader removes itself, a change meets a leader's loss, one
//! change at a time, a stale configuration never elects a leader, a restarted replica
//! recovers the replicas from its log — and seeded schedules that change the replicas
//! among their faults.

use super::*;

fn all(_: &str, _: &str, _: &mut ReplicaMsg) -> bool {
    true
}

/// Time passes by `ms` in steps of 5 ms, every message delivered.
fn run_for(sim: &mut Sim, ms: u64) {
    for _ in 0..ms / 5 {
        sim.now += Duration::from_millis(5);
        sim.tick_all();
        exchange(sim, &mut all);
    }
}

/// Settled replicas a, b, c with `puts` entries committed; the leader.
fn three(seed: u64, puts: usize) -> (Sim, String) {
    let mut sim = Sim::new(seed, TAIL_KEEP);
    sim.settle();
    let leader = sim.leader().expect("a leader");
    for _ in 0..puts {
        sim.propose(&leader);
    }
    exchange(&mut sim, &mut all);
    (sim, leader)
}

/// Add a replica on `node` and run until the leader promotes it.
fn grow(sim: &mut Sim, node: &str) {
    sim.change(Change::Add(node.into())).expect("added");
    sim.add_node(node);
    for _ in 0..400 {
        run_for(sim, 5);
        let l = sim.leader().expect("a leader");
        if sim.core(&l).members().is_voter(node) && !sim.core(&l).change_pending() {
            return;
        }
    }
    panic!("{node} never promoted");
}

fn voters(sim: &mut Sim, m: &str) -> Vec<String> {
    sim.core(m).members().voters.clone()
}

#[test]
fn a_replica_added_catches_up_as_a_learner_then_votes() {
    let (mut sim, leader) = three(41, 50);
    let seq = sim.change(Change::Add("d".into())).expect("added");
    assert_eq!(
        sim.core(&leader).members().learners,
        ["d"],
        "in use once appended"
    );
    assert!(sim.core(&leader).change_pending());
    assert_eq!(
        sim.core(&leader).majority(),
        2,
        "a learner counts for nothing"
    );
    sim.add_node("d");
    // it starts empty, is sent the log, and is promoted once it holds what is committed
    run_for(&mut sim, 200);
    assert!(sim.core(&leader).commit() > seq);
    assert_eq!(voters(&mut sim, &leader), ["a", "b", "c", "d"]);
    assert_eq!(sim.core(&leader).majority(), 3);
    sim.settle();
    sim.check();
    assert_eq!(voters(&mut sim, "d"), ["a", "b", "c", "d"]);
    assert_eq!(
        sim.replicas["d"].disk.applied,
        sim.replicas["a"].disk.applied
    );
    assert!(sim.counts["reconfigured"] >= 2);
}

#[test]
fn a_learner_counts_for_no_commit_and_no_election() {
    let (mut sim, leader) = three(43, 10);
    sim.change(Change::Add("d".into())).expect("added");
    sim.add_node("d");
    // d never answers: it stays a learner, and the change stays under way
    let others: Vec<String> = MEMBERS
        .iter()
        .map(|m| m.to_string())
        .filter(|m| *m != leader)
        .collect();
    for o in &others {
        sim.crash(o);
    }
    let commit = sim.core(&leader).commit();
    sim.propose(&leader);
    run_for(&mut sim, 50);
    assert_eq!(
        sim.core(&leader).commit(),
        commit,
        "the leader and a learner are no majority of three voters"
    );
    assert!(sim.core("d").last().0 > commit, "though d holds the entry");
    // and d never campaigns, however long it hears nobody
    sim.crash(&leader);
    let term = sim.core("d").term();
    run_for(&mut sim, 2000);
    assert_eq!(sim.core("d").term(), term);
    assert!(!sim.core("d").is_leader());
}

#[test]
fn one_change_at_a_time() {
    let (mut sim, leader) = three(47, 5);
    sim.change(Change::Add("d".into())).expect("added");
    // before it is even committed
    assert!(matches!(
        sim.change(Change::Add("e".into())),
        Err(ChangeError::Pending(why)) if why.contains("not committed yet")
    ));
    exchange(&mut sim, &mut all);
    // committed, d not caught up (its node not started yet): still under way
    let refused = sim.change(Change::Remove("c".into())).unwrap_err();
    assert!(
        refused
            .to_string()
            .starts_with("a change is under way: d is catching up as a learner (lag "),
        "{refused}"
    );
    // removing the learner cancels its addition
    sim.change(Change::Remove("d".into())).expect("cancelled");
    exchange(&mut sim, &mut all);
    assert_eq!(
        *sim.core(&leader).members(),
        Members::new(["a", "b", "c"], Vec::<String>::new())
    );
    assert_eq!(
        sim.change(Change::Remove("a".into())).unwrap_err(),
        ChangeError::TooFew {
            node: "a".into(),
            left: 2
        }
    );
    assert_eq!(
        sim.change(Change::Add("a".into())).unwrap_err(),
        ChangeError::AlreadyMember("a".into())
    );
    assert_eq!(
        sim.change(Change::Add("no one".into())).unwrap_err(),
        ChangeError::InvalidNode("no one".into())
    );
    let follower = if leader == "b" { "c" } else { "b" };
    let now = sim.now;
    let mut out = Vec::new();
    assert_eq!(
        sim.core(follower)
            .change(&Change::Add("e".into()), now, &mut out),
        Err(ChangeError::NotLeader)
    );
}

#[test]
fn a_leader_just_elected_changes_nothing_until_an_entry_of_its_term_is_committed() {
    let mut sim = Sim::new(53, TAIL_KEEP);
    sim.settle();
    let old = sim.leader().unwrap();
    sim.crash(&old);
    // elected, and nobody's answer to its no-op arrives
    let new = elect(&mut sim, &mut |_, _, m| {
        !matches!(m, ReplicaMsg::AppendAck { .. })
    });
    assert!(sim.core(&new).commit() < sim.core(&new).last().0);
    assert_eq!(
        sim.change(Change::Add("d".into())),
        Err(ChangeError::NotReady)
    );
    run_for(&mut sim, 50);
    sim.change(Change::Add("d".into()))
        .expect("once its no-op is committed");
}

#[test]
fn a_replica_removed_takes_no_part_any_more() {
    let (mut sim, leader) = three(59, 20);
    grow(&mut sim, "d");
    let gone = if leader == "c" { "b" } else { "c" };
    sim.change(Change::Remove(gone.into())).expect("removed");
    run_for(&mut sim, 100);
    let mut rest: Vec<String> = ["a", "b", "c", "d"]
        .iter()
        .map(|m| m.to_string())
        .filter(|m| m != gone)
        .collect();
    rest.sort();
    assert_eq!(voters(&mut sim, &leader), rest);
    assert!(sim.core(gone).is_removed(), "it took in its removal");
    assert!(sim.counts["removed"] >= 1);
    // it campaigns no more, whatever it hears
    sim.partition(gone);
    let term = sim.core(gone).term();
    run_for(&mut sim, 2000);
    assert_eq!(sim.core(gone).term(), term);
    // and restarted from its disk it stays out
    sim.crash(gone);
    sim.start(gone);
    assert!(sim.core(gone).is_removed());
    assert!(!sim.core(gone).members().contains(gone));
    sim.heal();
    sim.settle();
    sim.check();
}

#[test]
fn a_leader_that_removes_itself_steps_down_once_that_is_committed_and_hands_its_role_on() {
    let (mut sim, leader) = three(61, 20);
    grow(&mut sim, "d");
    sim.change(Change::Remove(leader.clone())).expect("removed");
    // until it is committed the leader goes on, not counting itself
    assert!(sim.core(&leader).is_leader());
    assert_eq!(sim.core(&leader).majority(), 2);
    let lost = sim.now;
    for _ in 0..400 {
        run_for(&mut sim, 5);
        if sim.leader().is_some_and(|l| l != leader) {
            break;
        }
    }
    let next = sim.leader().expect("a leader among the others");
    assert_ne!(next, leader);
    assert!(
        sim.now - lost < sim.timing.election,
        "handed on at once, not after an election timeout ({:?})",
        sim.now - lost
    );
    assert!(sim.core(&leader).is_removed());
    assert!(!sim.core(&leader).is_leader());
    assert!(!voters(&mut sim, &next).contains(&leader));
    sim.propose(&next);
    sim.settle();
    sim.check();
}

#[test]
fn a_change_cut_by_a_leaders_loss_is_undone_or_finished_never_half() {
    for seed in 1..=20 {
        let (mut sim, leader) = three(seed * 131, 10);
        grow(&mut sim, "d");
        // the removal of d reaches one follower at most, then the leader is lost
        sim.change(Change::Remove("d".into())).expect("removed");
        let lucky = ["a", "b", "c"]
            .into_iter()
            .find(|m| *m != leader)
            .unwrap()
            .to_string();
        let reach = seed % 2 == 0;
        exchange(&mut sim, &mut |f, t, _| f != leader || reach && t == lucky);
        sim.crash(&leader);
        sim.settle();
        sim.check();
        let l = sim.leader().unwrap();
        let m = sim.core(&l).members().clone();
        // every replica in use agrees on the replicas
        for r in m.all().cloned().collect::<Vec<_>>() {
            if sim.replicas[&r].core.is_some() && r != leader {
                assert_eq!(*sim.core(&r).members(), m, "seed {seed}: {r}");
            }
        }
        assert!(m.voters.len() >= 3, "seed {seed}: {m}");
    }
}

#[test]
fn a_stale_configuration_never_wins() {
    // c is cut off while the others grow to five and remove it: back, it still believes in
    // {a, b, c} (a majority of which is any two) — it must not become leader, nor unseat one
    let (mut sim, _) = three(67, 10);
    let leader = sim.leader().unwrap();
    let outcast = if leader == "c" { "b" } else { "c" };
    sim.partition(outcast);
    grow(&mut sim, "d");
    grow(&mut sim, "e");
    sim.change(Change::Remove(outcast.into())).expect("removed");
    run_for(&mut sim, 100);
    let l = sim.leader().unwrap();
    let term = sim.core(&l).term();
    assert!(!voters(&mut sim, &l).contains(&outcast.to_string()));
    assert!(
        sim.core(outcast).members().is_voter(outcast),
        "its stale view"
    );
    sim.heal();
    run_for(&mut sim, 3000);
    assert!(!sim.core(outcast).is_leader());
    assert_eq!(
        sim.leader().as_deref(),
        Some(l.as_str()),
        "the leader stays"
    );
    assert_eq!(sim.core(&l).term(), term, "and its term");
    sim.settle();
    sim.check();
}

#[test]
fn a_replica_restarted_recovers_the_replicas_from_its_log_or_snapshot() {
    // with a small in-memory tail, some replicas take a snapshot carrying the configuration
    let mut sim = Sim::new(71, 16);
    sim.settle();
    let leader = sim.leader().unwrap();
    grow(&mut sim, "d");
    for _ in 0..100 {
        sim.propose(&leader);
    }
    sim.settle();
    let want = sim.core(&leader).members().clone();
    for m in ["a", "b", "c", "d"] {
        sim.crash(m);
        sim.start(m);
        assert_eq!(*sim.core(m).members(), want, "{m} restarted");
    }
    // a replica that lagged past the leader's memory and took a snapshot
    sim.crash("d");
    let l = elect(&mut sim, &mut all);
    for _ in 0..100 {
        sim.propose(&l);
    }
    exchange(&mut sim, &mut all);
    sim.start("d");
    sim.settle();
    assert!(sim.replicas["d"].disk.snap.0 > 0, "d took a snapshot");
    sim.crash("d");
    sim.start("d");
    assert_eq!(*sim.core("d").members(), want);
    sim.check();
}

#[test]
fn a_removal_that_would_leave_no_majority_answering_is_refused() {
    let (mut sim, leader) = three(73, 5);
    grow(&mut sim, "d");
    grow(&mut sim, "e");
    let others: Vec<String> = ["a", "b", "c", "d", "e"]
        .iter()
        .map(|m| m.to_string())
        .filter(|m| *m != leader)
        .collect();
    // two of the five down: removing a third voter leaves {leader, one live, two down}
    sim.crash(&others[0]);
    sim.crash(&others[1]);
    let election = sim.timing.election.as_millis() as u64;
    run_for(&mut sim, election + 50);
    let refused = sim.change(Change::Remove(others[2].clone())).unwrap_err();
    assert!(
        matches!(&refused, ChangeError::NoMajority { live, .. } if live.len() == 2),
        "{refused}"
    );
    // removing a replica that is down is what a replacement does: allowed
    sim.change(Change::Remove(others[0].clone()))
        .expect("removing a replica that is down");
}

#[test]
fn seeded_schedules_that_change_the_replicas_keep_every_invariant() {
    let mut counts = BTreeMap::new();
    let only: Option<u64> = std::env::var("SIM_SEED").ok().and_then(|s| s.parse().ok());
    for seed in 1..=60 {
        if only.is_some_and(|o| o != seed) {
            continue;
        }
        let keep = if seed % 2 == 0 { 16 } else { TAIL_KEEP };
        let mut sim = Sim::new(seed * 6007, keep);
        sim.changes = true;
        sim.harsh = seed % 3 == 0;
        for _ in 0..6000 {
            sim.step(true);
        }
        sim.settle();
        sim.check();
        // the replicas in use agree on who they are
        let l = sim.leader().unwrap();
        let m = sim.core(&l).members().clone();
        for r in m.all().cloned().collect::<Vec<_>>() {
            assert_eq!(*sim.core(&r).members(), m, "seed {seed}: {r}");
        }
        for (k, v) in sim.counts {
            *counts.entry(k).or_insert(0) += v;
        }
    }
    eprintln!("60 schedules with changes: {counts:?}");
    for what in ["changes", "reconfigured", "removed", "crashes", "installs"] {
        assert!(
            counts.get(what).copied().unwrap_or(0) >= 10,
            "{what}: {counts:?}"
        );
    }
}

#[test]
fn a_replica_removed_while_its_node_was_away_is_told_once_back_and_unseats_nobody() {
    // told by entries (the leader still holds them), and by a snapshot (it does not)
    for (keep, by) in [(TAIL_KEEP, "entries"), (16, "a snapshot")] {
        let mut sim = Sim::new(73, keep);
        sim.settle();
        let leader = sim.leader().unwrap();
        grow(&mut sim, "d");
        let gone = if leader == "c" { "b" } else { "c" };
        sim.crash(gone);
        sim.change(Change::Remove(gone.into())).expect("removed");
        run_for(&mut sim, 100);
        let l = sim.leader().unwrap();
        for _ in 0..100 {
            sim.propose(&l);
        }
        run_for(&mut sim, 100);
        assert!(!voters(&mut sim, &l).contains(&gone.to_string()));
        let term = sim.core(&l).term();
        let installs = sim.counts.get("installs").copied().unwrap_or(0);
        // back, its disk says it is a voter of the configuration before: nobody told it
        sim.start(gone);
        assert!(!sim.core(gone).is_removed(), "{by}");
        assert!(sim.core(gone).members().is_voter(gone), "{by}");
        run_for(&mut sim, 500);
        assert!(sim.core(gone).is_removed(), "told by {by}");
        assert!(!sim.core(gone).members().contains(gone), "{by}");
        assert!(sim.core(&l).outsiders().is_empty(), "{by}: done telling");
        if keep == 16 {
            assert!(sim.counts["installs"] > installs, "by a snapshot");
        }
        // it campaigns no more, and the leader keeps its role and its term
        run_for(&mut sim, 3000);
        assert_eq!(sim.leader().as_deref(), Some(l.as_str()), "{by}");
        assert_eq!(sim.core(&l).term(), term, "{by}: no term churn");
        // restarted from its disk, it stays out
        sim.crash(gone);
        sim.start(gone);
        assert!(sim.core(gone).is_removed(), "{by}: its journal says it");
        sim.settle();
        sim.check();
    }
}

#[test]
fn a_replicas_word_of_a_newer_term_from_outside_the_configuration_never_deposes_the_leader() {
    let (mut sim, leader) = three(79, 10);
    let term = sim.core(&leader).term();
    let now = sim.now;
    // a replica no configuration names, of a newer term, asks for a vote — even as if
    // at a leader's word
    let mut out = Vec::new();
    sim.core(&leader).receive(
        ReplicaMsg::Vote {
            term: term + 5,
            candidate: "x".into(),
            last_seq: 1_000,
            last_term: term + 4,
            pre: false,
            transfer: true,
        },
        now,
        &mut out,
    );
    assert!(sim.core(&leader).is_leader());
    assert_eq!(sim.core(&leader).term(), term);
    assert!(out.iter().any(|o| matches!(o,
        Out::Send(to, ReplicaMsg::VoteAck { granted: false, .. }) if to == "x")));
    assert!(
        out.iter().any(|o| matches!(o,
            Out::Send(to, ReplicaMsg::Append { term: t, .. }) if to == "x" && *t == term)),
        "it is told what the leader holds: {out:?}"
    );
    assert_eq!(sim.core(&leader).outsiders(), ["x"]);
    // it refuses the leader's word with its newer term: the leader goes on
    let mut out = Vec::new();
    sim.core(&leader).receive(
        ReplicaMsg::AppendAck {
            term: term + 5,
            from: "x".into(),
            ok: false,
            last: 0,
            at: 0,
        },
        now,
        &mut out,
    );
    assert!(sim.core(&leader).is_leader());
    assert_eq!(sim.core(&leader).term(), term);
    assert!(
        sim.core(&leader).outsiders().is_empty(),
        "it cannot be told"
    );
    // a member's newer term still counts
    let member = ["a", "b", "c"].into_iter().find(|m| *m != leader).unwrap();
    sim.core(&leader).receive(
        ReplicaMsg::AppendAck {
            term: term + 1,
            from: member.into(),
            ok: false,
            last: 0,
            at: 0,
        },
        now,
        &mut Vec::new(),
    );
    assert!(!sim.core(&leader).is_leader());
}

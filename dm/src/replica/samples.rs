//! One sample of every message the replicas of a replicated datamanager send each other,
//! for the compatibility corpus (`marie compat`): these types are the crate's own, so the
//! samples are built here. The matches below are exhaustive on purpose: a variant added to
//! [`ReplicaMsg`], [`InstallPart`] or [`OpBody`] does not compile until it has a sample.

use super::members::Members;
use super::msg::{InstallPart, Ops, ReplicaMsg};
use super::op::{Op, OpBody};
use crate::messages::DmMsg;
use crate::record::{NewRecord, Payload};

/// Every replica message as the `DmMsg::Replica` that carries it, named by its variant (and
/// the variant of what it carries: `Append` of each op, `Install` of each part).
pub fn samples() -> Vec<(String, DmMsg)> {
    let msgs = vec![
        append(),
        ReplicaMsg::AppendAck {
            term: 4,
            from: "beta".into(),
            ok: true,
            last: 12,
            at: 1_700,
        },
        ReplicaMsg::Vote {
            term: 5,
            candidate: "gamma".into(),
            last_seq: 12,
            last_term: 4,
            pre: true,
            transfer: false,
        },
        ReplicaMsg::TimeoutNow {
            term: 4,
            from: "alpha".into(),
        },
        ReplicaMsg::VoteAck {
            term: 5,
            asked: 5,
            from: "alpha".into(),
            granted: true,
            pre: true,
        },
        install(InstallPart::Records {
            first: true,
            records: vec![(11, 4, record())],
        }),
        install(InstallPart::Producers {
            producers: vec![(41, vec![(7, 11)])],
        }),
        install(InstallPart::End {
            records: 1,
            last_time_ns: 1_500_000_000,
            members: Some((9, members())),
        }),
    ];
    msgs.into_iter()
        .map(|m| {
            let name = name(&m);
            (name, DmMsg::Replica { msg: Box::new(m) })
        })
        .collect()
}

fn record() -> NewRecord {
    NewRecord {
        source: "wall-follower".into(),
        class: "feature".into(),
        sub1: Some("corner".into()),
        sub2: None,
        payload: Payload::from_bytes(vec![0x92, 0x01, 0xa1, 0x61]),
        epoch: 8,
        producer: 41,
        producer_seq: 7,
    }
}

fn members() -> Members {
    Members {
        voters: vec!["alpha".into(), "beta".into(), "gamma".into()],
        learners: vec!["delta".into()],
    }
}

/// An append carrying one op of every kind.
fn append() -> ReplicaMsg {
    let ops = [
        OpBody::Put {
            time_ns: 1_200_000_000,
            record: record(),
        },
        OpBody::Delete { seqs: vec![3, 4] },
        OpBody::Noop,
        OpBody::Members(members()),
    ];
    for body in &ops {
        // a new kind of op needs a place in the list above
        match body {
            OpBody::Put { .. } | OpBody::Delete { .. } | OpBody::Noop | OpBody::Members(_) => {}
        }
    }
    ReplicaMsg::Append {
        term: 4,
        leader: "alpha".into(),
        prev_seq: 8,
        prev_term: 4,
        ops: Ops::new(
            ops.into_iter()
                .zip(9..)
                .map(|(body, seq)| Op { seq, term: 4, body })
                .collect(),
        ),
        commit: 8,
        at: 1_650,
        held: 2,
    }
}

fn install(part: InstallPart) -> ReplicaMsg {
    ReplicaMsg::Install {
        term: 4,
        leader: "alpha".into(),
        last_seq: 11,
        last_term: 4,
        part,
    }
}

/// `Vote`, `Install-End`: the variant and, for an install, its part.
fn name(m: &ReplicaMsg) -> String {
    match m {
        ReplicaMsg::Append { .. } => "Append".into(),
        ReplicaMsg::AppendAck { .. } => "AppendAck".into(),
        ReplicaMsg::Vote { .. } => "Vote".into(),
        ReplicaMsg::TimeoutNow { .. } => "TimeoutNow".into(),
        ReplicaMsg::VoteAck { .. } => "VoteAck".into(),
        ReplicaMsg::Install { part, .. } => match part {
            InstallPart::Records { .. } => "Install-Records".into(),
            InstallPart::Producers { .. } => "Install-Producers".into(),
            InstallPart::End { .. } => "Install-End".into(),
        },
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_variant_has_a_sample() {
        let names: Vec<String> = super::samples().into_iter().map(|(n, _)| n).collect();
        assert_eq!(names.len(), 8, "{names:?}");
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
    }
}

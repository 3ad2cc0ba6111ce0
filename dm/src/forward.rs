//! Requests of the dm-interface that reach a replica not leading: a client holding it from
//! when it led (a leader that steps down is the same actor, `replicated`), or from before an
//! election. The replica sends each on to the leader it follows, which answers the caller
//! itself (a reply port crosses nodes as any call's does); while it knows none it can reach
//! — an election under way — it keeps them, in order, and sends them on (or, elected
//! itself, answers them) once there is one.
//!
//! Why on, and not back: a call refused with its reply port dropped reaches a caller on
//! another node only as its own deadline passing, and a put has no answer to send its
//! producer anywhere with (a producer that only puts, into a replica on its own node, lost
//! every put). Sent on, every request of a client keeps one road: its puts arrive at the
//! leader in order, and the credits' `Stats` after the puts it acknowledges; and the reads
//! are checked where they are answered (`reads`). A replica that knew no leader for an
//! election timeout refuses what it kept (`refuse`: a `DmClient` follows the name).
//!
//! A replica's own numbers, whatever its role, are `ReplicaStats`.

use super::messages::DmMsg;
use super::state::DatamanagerState;
use ractor::ActorRef;

impl DatamanagerState {
    /// A request of the dm-interface reached this replica, which does not lead: sent on to
    /// its leader, or kept until it knows one (see above).
    pub(crate) fn not_leader(&mut self, myself: &ActorRef<DmMsg>, msg: DmMsg) {
        let Some(replica) = self.storage.replica_mut() else {
            self.refuse(msg);
            return;
        };
        // behind those kept, if any: one road, in order
        let now = replica.now();
        replica.kept.push_back((now, msg));
        self.send_kept_on(myself);
    }

    /// Send the requests kept on to the leader, answer them if this replica leads now, or
    /// refuse those kept for an election timeout.
    pub(crate) fn send_kept_on(&mut self, myself: &ActorRef<DmMsg>) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        if replica.kept.is_empty() {
            return;
        }
        if replica.core.is_leader() {
            let kept: Vec<DmMsg> = replica.kept.drain(..).map(|(_, m)| m).collect();
            for msg in kept {
                self.on_request(myself, msg);
            }
            return;
        }
        if let Some(leader) = replica.leader_actor() {
            let kept: Vec<DmMsg> = replica.kept.drain(..).map(|(_, m)| m).collect();
            for msg in kept {
                match leader.send_message(msg) {
                    Ok(()) => {}
                    Err(ractor::MessagingErr::SendErr(msg)) => self.refuse(msg),
                    Err(e) => {
                        tracing::debug!(dm = %self.name, error = %e, "a request sent on to the leader was lost")
                    }
                }
            }
            return;
        }
        let (now, patience) = (replica.now(), replica.core.timing().election);
        let mut late = Vec::new();
        while replica
            .kept
            .front()
            .is_some_and(|(at, _)| now.saturating_sub(*at) >= patience)
        {
            late.extend(replica.kept.pop_front().map(|(_, m)| m));
        }
        if !late.is_empty() {
            tracing::debug!(dm = %self.name, requests = late.len(), "requests refused: no leader for an election timeout");
        }
        for msg in late {
            self.refuse(msg);
        }
    }
}

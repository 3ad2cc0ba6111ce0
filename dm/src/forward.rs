//! Requests of the dm-interface that reach a replica not leading: a client holding it from
//! when it led (a leader that steps down is the same actor, `replicated`), or from before an
//! election. The replica sends each on to the leader it follows, which answers the caller
//! itself (a reply port crosses nodes as any call's does); while it knows none it can reach
//! — an election under way — it keeps them, in order, and sends them on (or, elected
//! itself, answers them) once there is one (`replica::kept`).
//!
//! Why on, and not back: a call refused with its reply port dropped sends its caller to find
//! the leader by name and ask again, a round trip for nothing while this replica knows
//! where the leader is; and a put has no answer to send its producer anywhere with (a
//! producer that only puts, into a replica on its own node, lost every put). Sent on, every
//! request of a client keeps one road: its puts arrive at the leader in order, and the
//! credits' `Stats` after the puts it acknowledges; and the reads are checked where they
//! are answered (`reads`). A replica that knew no leader for an election timeout refuses
//! what it kept, oldest first (`refuse`: a `DmClient` follows the name).
//!
//! # A leader lost with requests sent on to it
//! A request sent on fares as if its client had sent it to that leader itself: if the
//! leader is lost with it — its node killed, frozen or cut off until declared down, its
//! actor dead, or deposed by a newer term — its reply port is dropped where it was (the
//! shim of a lost node's actor stops with the session, and its ports with it; a deposed
//! leader drops the ports it owed), and the caller hears so at once, on any node
//! (`marie_vocabulary::wire::NO_ANSWER`): a `DmClient` follows the datamanager's name to the
//! next leader and asks again there, within the failover, not at its own deadline. This
//! replica does not send such a request again itself, because only the client knows what
//! asking again may do: a store is stored once however often it comes (its producer's
//! number, `producers`), but a delete is not sent again (it may have been done), a wait
//! asks for what is left of it, and a credits' `Stats` answered by the next leader would
//! acknowledge puts the lost one never stored — dropped, it sends them again (`put_all`).
//! The road stays in order: a task awaits each call of its client, so nothing it sent after
//! a lost call is on its way when it asks again; the puts it sent before went to the lost
//! leader (lost with it, as puts to a lost leader are) or are kept here, before the call.
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
        replica.kept.keep(now, msg);
        self.send_kept_on(myself);
    }

    /// Send the requests kept on to the leader, answer them if this replica leads now, and
    /// refuse those kept for an election timeout.
    pub(crate) fn send_kept_on(&mut self, myself: &ActorRef<DmMsg>) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        if replica.kept.is_empty() {
            return;
        }
        if replica.core.is_leader() {
            for (_, msg) in replica.kept.take() {
                self.on_request(myself, msg);
            }
            return;
        }
        if let Some(leader) = replica.leader_actor() {
            let mut taken = replica.kept.take().into_iter();
            while let Some((at, msg)) = taken.next() {
                match leader.send_message(msg) {
                    Ok(()) => {}
                    Err(ractor::MessagingErr::SendErr(msg)) => {
                        // its actor is gone: this one and those behind it wait for the next
                        replica
                            .kept
                            .put_back(std::iter::once((at, msg)).chain(taken));
                        tracing::debug!(dm = %self.name, kept = replica.kept.len(), "the leader's actor is gone: requests kept for the next");
                        break;
                    }
                    Err(e) => {
                        // (its reply port dropped: a caller hears of it at once)
                        tracing::debug!(dm = %self.name, error = %e, "a request sent on to the leader was lost")
                    }
                }
            }
        }
        let (now, patience) = (replica.now(), replica.core.timing().election);
        let late = replica.kept.late(now, patience);
        if !late.is_empty() {
            tracing::debug!(dm = %self.name, requests = late.len(), "requests refused: no leader for an election timeout");
        }
        for msg in late {
            self.refuse(msg);
        }
    }
}

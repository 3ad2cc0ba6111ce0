//! Reads on a replicated datamanager: the leader answers one only when no other leader can
//! have acknowledged anything newer (`replica::lease`: while its lease holds, else once a
//! majority followed it since the read came), so a read never returns an older state than
//! a write acknowledged before it was asked.
//!
//! The reads are `Select`, `SelectPage`, `SelectWait`, `SelectWaitPage` and `Stats` (a
//! subscription is made of `Stats` and `SelectWait`s); a follower sends them on to its
//! leader (`forward`), where they are checked. A wait is checked when it comes: what
//! wakes it later is an entry committed after that, and its answer a state the log reached
//! then; it is dropped if its replica stops leading. A read that must wait is kept here, in
//! order, and answered at the first answer from the replicas that confirms the leader; one
//! that waited an election timeout (the leader would step down about then), or that reached
//! a replica not leading, is refused: its reply port is dropped, unanswered — a `DmClient`
//! then follows the datamanager's name to its leader and asks again there
//! ([`DmError::Unreachable`](super::DmError::Unreachable) if none is published within its
//! follow time); a raw `call` sees `CallResult::SenderError`.

use super::messages::DmMsg;
use super::replica::lease::Read;
use super::state::DatamanagerState;
use ractor::ActorRef;

impl DatamanagerState {
    /// A read: answered now, kept until the leader is confirmed, or refused (see above). A
    /// datamanager without replicas answers at once.
    pub(crate) fn read(&mut self, myself: &ActorRef<DmMsg>, msg: DmMsg) {
        let Some(replica) = self.leader_mut() else {
            self.answer_read(myself, msg);
            return;
        };
        let now = replica.now();
        match replica.core.read(now, now) {
            Read::Serve => self.answer_read(myself, msg),
            Read::Refuse => self.refuse(msg),
            Read::Wait => {
                tracing::trace!(dm = %replica.name, "a read waits for the replicas to confirm the leader");
                replica.reads.push_back((now, msg));
                let mut out = Vec::new();
                replica.core.confirm(now, now, &mut out);
                self.carry_out(myself, out);
            }
        }
    }

    /// Answer the reads kept that may be answered now, in order; refuse those that waited
    /// too long (and all of them once this replica no longer leads).
    pub(crate) fn serve_reads(&mut self, myself: &ActorRef<DmMsg>) {
        loop {
            let Some(replica) = self.storage.replica_mut() else {
                return;
            };
            let Some((asked, _)) = replica.reads.front() else {
                return;
            };
            let (asked, now) = (*asked, replica.now());
            let verdict = replica.core.read(asked, now);
            if verdict == Read::Wait {
                // the round in flight may have been sent before it came: the next one
                let mut out = Vec::new();
                replica.core.confirm(asked, now, &mut out);
                if !out.is_empty() {
                    self.carry_out(myself, out);
                }
                return;
            }
            let Some((_, msg)) = replica.reads.pop_front() else {
                return;
            };
            match verdict {
                Read::Serve => self.answer_read(myself, msg),
                _ => {
                    tracing::debug!(dm = %self.name, "a read refused: the leader was not confirmed in time");
                    self.refuse(msg);
                }
            }
        }
    }

    /// Drop every read waiting here and every wait filed: their callers follow the
    /// datamanager's name to its leader (this replica stopped leading).
    pub(crate) fn send_readers_on(&mut self) {
        if let Some(replica) = self.storage.replica_mut() {
            replica.reads.clear();
        }
        drop(self.waits.take_all());
    }

    /// Answer the read `msg` now.
    fn answer_read(&mut self, myself: &ActorRef<DmMsg>, msg: DmMsg) {
        match msg {
            DmMsg::Select { query, reply } => self.on_select(&query, reply),
            DmMsg::SelectPage {
                query,
                max_bytes,
                reply,
            } => self.on_select_page(&query, max_bytes, reply),
            DmMsg::SelectWait {
                query,
                timeout_ms,
                reply,
            } => self.on_select_wait(myself, *query, timeout_ms, reply),
            DmMsg::SelectWaitPage {
                query,
                timeout_ms,
                max_bytes,
                reply,
            } => self.on_select_wait_page(myself, *query, timeout_ms, max_bytes, reply),
            DmMsg::Stats { reply } => self.on_stats(myself, reply),
            other => {
                // (only reads come here: the actor's shell picks them)
                tracing::error!(dm = %self.name, msg = ?std::mem::discriminant(&other), "not a read: dropped");
            }
        }
    }
}

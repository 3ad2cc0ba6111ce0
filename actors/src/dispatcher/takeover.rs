//! A run that survives its dispatcher: recording the run's progress ([`super::checkpoint`])
//! and carrying a lost dispatcher's run on from its last checkpoint.
//!
//! A standby carries the run on ([`DispatcherState::carry_on`]) in this order: it stores
//! the checkpoint it read under its own term (which fences the old dispatcher off; not
//! stored within a bound, it leaves the run alone: it is cut off from the run's copies); binds
//! every operation — the instance the lost dispatcher held, if it still runs, else one
//! chosen as at the start, looked for a little while (a partition just healed: modules
//! rejoining the registry) — above the epochs the checkpoint recorded, and records them;
//! tells the bindings; and only then commands. The `takeover` is told as soon as the term
//! is stored: the run's word is the standby's from then on, whatever follows. The running action's
//! operations are *attached* ([`crate::eo::EoMsg::Attach`]): an activation still running
//! goes on undisturbed and reports to the new dispatcher, and one that ended while no
//! dispatcher listened is resumed ([`crate::eo::EoMsg::Resume`]), carrying on from what it
//! stored. The other operations get their last parameters at the new epoch, so every
//! operation the run holds refuses the old dispatcher's commands from then on.
//!
//! # Invariants
//! - Mission time carries on from the run's start: the time without a dispatcher counts
//!   (a cluster's nodes read one clock), so a takeover's cost shows in the run's duration.
//! - The action's own deadline keeps counting from when the action started; the mission's
//!   from when the run began.

use super::actor::{ActionState, Current, DispatcherState, End, Start, TakeOver};
use super::binding::Binding;
use super::candidates::{choose, examine_all, Prospect};
use super::checkpoint::{self, BindingCheckpoint, Checkpoint, CurrentCheckpoint, Superseded};
use super::healing::StartError;
use super::messages::DispatcherMsg;
use super::tree::Tree;
use crate::eo::EoError;
use marie_vocabulary::clock::Timer;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::Outcome;
use marie_vocabulary::status::StatusFlags;
use ractor::ActorRef;
use std::collections::BTreeSet;
use std::time::Duration;

/// How long a standby may take to store its term in the run datamanager before it leaves
/// the run alone.
const CLAIM_WITHIN: Duration = Duration::from_secs(3);
/// How long a standby keeps looking for an instance of an operation the run holds before
/// the run fails: right after a partition heals, a node's modules leave and rejoin the
/// registry while its sessions are redialled. Short: the dispatcher answers no desk's
/// `Alive` meanwhile.
const BIND_WITHIN: Duration = Duration::from_secs(2);
/// The pause between two looks.
const BIND_RETRY: Duration = Duration::from_millis(200);

/// Why a takeover fails the run it carries on: the run's reason says it in these words.
#[derive(Debug, thiserror::Error)]
pub(crate) enum TakeoverError {
    /// The registry cannot be watched (see [`StartError::Watch`]).
    #[error(transparent)]
    Watch(#[from] StartError),
    /// No instance of an operation the run holds answered within [`BIND_WITHIN`].
    #[error("taking the run over from {from}: no instance of operation `{operation}` answers")]
    Unbound {
        /// The node of the checkpoint's writer.
        from: String,
        /// The operation.
        operation: String,
    },
    /// The checkpoint's tree is not the mission's (another mission's run).
    #[error("taking the run over from {from}: its checkpoint's tree does not fit the mission")]
    TreeMisfit {
        /// The node of the checkpoint's writer.
        from: String,
    },
}

impl DispatcherState {
    /// The run's progress now, as a checkpoint (numbered by the writer).
    fn snapshot(&self, ended: Option<Outcome>) -> Option<Checkpoint> {
        let writer = self.checkpoints.as_ref()?;
        Some(Checkpoint {
            run: writer.run.clone(),
            term: writer.term,
            seq: 0,
            node: registry::local_node_name(),
            mission_hash: Checkpoint::hash_of(&self.mission),
            mission: self.mission.clone(),
            run_ms: self.elapsed_ms(),
            started_ms: self.started.as_millis() as u64,
            unix_ms: checkpoint::unix_ms(),
            status: self.status.0,
            done: self.done.clone(),
            generation: self.generation,
            live: self
                .live
                .values()
                .map(|c| CurrentCheckpoint {
                    index: c.index,
                    running: c.running.iter().cloned().collect(),
                    enders_done: c.enders_done.iter().cloned().collect(),
                    ending: c.ending(),
                    started_ms: c.started_ms,
                    launched: c.launched,
                    halted: c.end == End::Halted,
                    failure: match &c.end {
                        End::Failed(reason) => Some(reason.clone()),
                        _ => None,
                    },
                })
                .collect(),
            tree: self.tree.state(),
            pending: self.pending.clone(),
            failure: self.failure.clone(),
            bindings: self
                .bindings
                .values()
                .map(|b| BindingCheckpoint {
                    name: b.name.clone(),
                    node: b.node.clone(),
                    pid: b.actor_id().pid(),
                    epoch: b.epoch,
                    params: b.params.clone(),
                    lost: b.lost.is_some(),
                })
                .collect(),
            ended,
            writer: None,  // stamped by the writer
            watcher: None, // stamped by the writer
        })
    }

    /// Record the run's progress (and its end, `ended`); the receiver says when it is
    /// stored (`None`: the run is recorded nowhere).
    pub(super) fn record(
        &mut self,
        ended: Option<Outcome>,
    ) -> Option<tokio::sync::oneshot::Receiver<Result<(), Superseded>>> {
        let snapshot = self.snapshot(ended)?;
        Some(self.checkpoints.as_mut()?.write(snapshot))
    }

    /// Record the run's progress, without waiting for it to be stored (see the invariants
    /// of [`super::checkpoint`]).
    pub(super) fn checkpoint(&mut self) {
        drop(self.record(None));
    }

    /// Record the run's progress and wait until it is stored: `Err` when a newer term
    /// refused it — the dispatcher is then fenced off at once ([`Self::fenced`]): what it
    /// was about to command (an epoch it raised for this checkpoint) never goes out.
    pub(super) async fn checkpoint_now(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
    ) -> Result<(), Superseded> {
        let term = self.checkpoints.as_ref().map_or(0, |w| w.term);
        let Some(stored) = self.record(None) else {
            return Ok(());
        };
        match stored.await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(superseded)) => {
                self.fenced(myself, superseded.newer);
                Err(superseded)
            }
            // given up for want of the run datamanager's majority (the writer dropped the
            // job and told the dispatcher, which ends the run): nothing to command either
            Err(_) => Err(Superseded { newer: term + 1 }),
        }
    }

    /// The newer term that refused one of this dispatcher's checkpoints, if one did
    /// (see [`Checkpointer::superseded`](super::checkpoint::Checkpointer)).
    pub(super) fn superseded(&self) -> Option<Superseded> {
        self.checkpoints.as_ref()?.superseded()
    }

    /// Record the run's end; `Conclude` publishes it once it is stored. Without
    /// checkpoints, at once. False when the run is recorded and its end must wait.
    pub(super) fn checkpoint_end(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        outcome: Outcome,
        reason: &str,
    ) -> bool {
        let Some(stored) = self.record(Some(outcome)) else {
            return true;
        };
        let me = myself.clone();
        let reason = reason.to_string();
        ractor::concurrency::spawn(async move {
            match stored.await {
                Ok(Ok(())) => {
                    let _ = me.cast(DispatcherMsg::Conclude { outcome, reason });
                }
                // refused: the writer told the dispatcher it is fenced
                Ok(Err(_)) => {}
                // given up for want of the run datamanager's majority (the writer dropped
                // the job): the run ends all the same, with its own reason
                Err(_) => {
                    let _ = me.cast(DispatcherMsg::Conclude { outcome, reason });
                }
            }
        });
        false
    }

    /// A newer term refused a checkpoint: a standby carries the run on. Stop without
    /// ending the run (no `run_ended`, no answer: the run is not over) and without
    /// commanding anything more — not even a suspension: the operations are the newer
    /// dispatcher's, and an epoch this one raised (an adoption outbids the instance's
    /// epoch, which may be the successor's) was never stored. Once only: the refusal is
    /// seen by a waiting checkpoint, by [`Self::superseded`] before a message, and by the
    /// writer's [`DispatcherMsg::Fenced`].
    pub(super) fn fenced(&mut self, myself: &ActorRef<DispatcherMsg>, newer: u64) {
        let Some(writer) = &self.checkpoints else {
            return;
        };
        if self.fenced_by.is_some() {
            return;
        }
        self.fenced_by = Some(newer);
        let (run, term) = (writer.run.clone(), writer.term);
        tracing::warn!(%run, term, newer, "fenced off: a newer dispatcher carries the run on");
        self.ended = true;
        self.live.clear();
        self.wake = None;
        self.emit(EventKind::DispatcherFenced { run, term, newer });
        // dropping the reply port tells whoever waits that this dispatcher did not end it
        self.reply = None;
        myself.stop(None);
    }

    /// The run datamanager had no majority for [`MAJORITY_WAIT`](marie_dm::MAJORITY_WAIT)
    /// (`reason` names it and the nodes it misses): end the run as failed now, without
    /// waiting for its end to be stored — it cannot be — and store that end later, should
    /// the majority come back (see the invariants of [`super::checkpoint`]).
    pub(super) fn no_majority(&mut self, myself: &ActorRef<DispatcherMsg>, reason: String) {
        if self.ended {
            // its end was being stored: that wait concludes it (`checkpoint_end`)
            return;
        }
        tracing::warn!(%reason, "the run datamanager has no majority: the run ends");
        let end = self.snapshot(Some(Outcome::Failed));
        // without a writer, the end is concluded at once
        let writer = self.checkpoints.take();
        self.finish(myself, Outcome::Failed, reason);
        if let (Some(writer), Some(end)) = (writer, end) {
            writer.store_end_later(end);
        }
    }

    /// Carry on the run `take_over` holds the last checkpoint of (see the module docs):
    /// claim the run, tell it, bind its operations, restore where it stood, record the new
    /// epochs, and only then command.
    pub(super) async fn carry_on(&mut self, myself: &ActorRef<DispatcherMsg>, take_over: TakeOver) {
        let TakeOver { from, noticed } = take_over;
        let Some(term) = self.claim(myself, &from).await else {
            return;
        };
        self.tell_takeover(&from, term, noticed);
        self.carry_time_on(&from);
        if let Err(reason) = self.bind_held_operations(myself, &from).await {
            self.finish(myself, Outcome::Failed, reason.to_string());
            return;
        }
        if let Err(reason) = self.restore(&from) {
            self.finish(myself, Outcome::Failed, reason.to_string());
            return;
        }
        // the bindings' new epochs, before any command carries them
        if self.checkpoint_now(myself).await.is_err() {
            return;
        }
        self.command_again(myself, &from).await;
    }

    /// Store the checkpoint read under this dispatcher's term: the run is this
    /// dispatcher's once it is stored, and the term is returned. `None`: the run is not
    /// carried on — there is no run datamanager (the run fails), a newer term has it (the
    /// writer said so), or the run's copies did not take the term within [`CLAIM_WITHIN`]
    /// (this standby is cut off from them: what it read may be stale by the time it could
    /// store, so it leaves the run alone and stops).
    async fn claim(&mut self, myself: &ActorRef<DispatcherMsg>, from: &Checkpoint) -> Option<u64> {
        let Some(term) = self.checkpoints.as_ref().map(|w| w.term) else {
            self.finish(
                myself,
                Outcome::Failed,
                "a takeover needs a run datamanager to record the run in".into(),
            );
            return None;
        };
        tracing::info!(run = %from.run, from = %from.node, term, "taking the run over");
        let claim = Checkpoint {
            term,
            node: registry::local_node_name(),
            unix_ms: checkpoint::unix_ms(),
            ..from.clone()
        };
        let writer = self.checkpoints.as_mut()?;
        match tokio::time::timeout(CLAIM_WITHIN, writer.write(claim)).await {
            Ok(Ok(Ok(()))) => Some(term),
            Ok(_) => None, // refused: a newer term has the run (the writer said so)
            Err(_) => {
                tracing::warn!(run = %from.run, "the run's copies did not take this standby's term in time: leaving the run alone");
                self.ended = true;
                self.reply = None;
                myself.stop(None);
                None
            }
        }
    }

    /// Tell the takeover: the run is this dispatcher's from the claim on, so whoever
    /// follows the run listens to it (what it selects, binds, and how it ends) — also
    /// should it fail before its first command.
    fn tell_takeover(&mut self, from: &Checkpoint, term: u64, noticed: std::time::Instant) {
        let gap_ms = noticed.elapsed().as_millis() as u64;
        let unix_ms = checkpoint::unix_ms();
        self.emit(EventKind::Takeover {
            run: from.run.clone(),
            from: from.node.clone(),
            to: registry::local_node_name(),
            term,
            gap_ms,
            since_checkpoint_ms: unix_ms.saturating_sub(from.unix_ms),
            unix_ms,
        });
    }

    /// Mission time carries on from the run's start (the cluster's nodes read one clock);
    /// a clock behind the checkpoint's (another host, out of sync) carries on from the
    /// checkpoint. The status word, what is done and the action count carry on too.
    fn carry_time_on(&mut self, from: &Checkpoint) {
        let now = self.clock.now();
        let started = Duration::from_millis(from.started_ms);
        self.started = match now.saturating_sub(started) >= Duration::from_millis(from.run_ms) {
            true => started,
            false => now.saturating_sub(Duration::from_millis(from.run_ms)),
        };
        self.status = StatusFlags(from.status);
        self.done = from.done.clone();
        self.generation = from.generation;
    }

    /// Watch the registry, then bind every operation the checkpoint holds (see
    /// [`Self::bind_held`]), each looked for within [`BIND_WITHIN`]. `Err`: why the run
    /// fails.
    async fn bind_held_operations(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        from: &Checkpoint,
    ) -> Result<(), TakeoverError> {
        self.watch_registry(myself).await?;
        for held in &from.bindings {
            let looking = tokio::time::Instant::now();
            let found = loop {
                let last = looking.elapsed() >= BIND_WITHIN;
                match self.bind_held(held, last).await {
                    None if !last => tokio::time::sleep(BIND_RETRY).await,
                    found => break found,
                }
            };
            let Some(binding) = found else {
                return Err(TakeoverError::Unbound {
                    from: from.node.clone(),
                    operation: held.name.clone(),
                });
            };
            self.bindings.insert(held.name.clone(), binding);
        }
        Ok(())
    }

    /// Restore where the run stood: its tree, what is pending, its failure, and the actions
    /// that were live (each under a new generation). `Err`: why the run fails.
    fn restore(&mut self, from: &Checkpoint) -> Result<(), TakeoverError> {
        let Some(tree) = Tree::restore(self.mission.control.root.clone(), from.tree.clone()) else {
            return Err(TakeoverError::TreeMisfit {
                from: from.node.clone(),
            });
        };
        self.tree = tree;
        self.pending = from.pending.clone();
        self.failure = from.failure.clone();
        for c in &from.live {
            self.generation += 1;
            let current = Self::live_again(self.generation, c);
            self.live.insert(self.generation, current);
        }
        Ok(())
    }

    /// An action the checkpoint recorded as live, under `generation`.
    fn live_again(generation: u64, c: &CurrentCheckpoint) -> Current {
        let end = match (c.halted, &c.failure) {
            (true, _) => End::Halted,
            (false, Some(reason)) => End::Failed(reason.clone()),
            (false, None) => End::Done,
        };
        Current {
            generation,
            index: c.index,
            started_ms: c.started_ms,
            running: c.running.iter().cloned().collect::<BTreeSet<_>>(),
            enders_done: c.enders_done.iter().cloned().collect(),
            state: match c.ending {
                true => ActionState::Ending,
                false => ActionState::Running,
            },
            end,
            timer: None,
            // not launched: the lost dispatcher sent none of its commands (it sends them
            // once this was stored); the standby launches it
            launched: c.launched,
        }
    }

    /// Command the run again, its new epochs stored: tell the bindings, attach or command
    /// the operations ([`Self::command_after_takeover`]), watch the nodes, re-arm the
    /// mission's deadline, and tick the tree.
    async fn command_again(&mut self, myself: &ActorRef<DispatcherMsg>, from: &Checkpoint) {
        self.announce(None).await;
        self.emit_bound();
        self.command_after_takeover(myself, from);
        self.probe(myself);
        if let Some(deadline) = self.mission.deadline {
            let left = deadline.saturating_sub(Duration::from_millis(self.elapsed_ms()));
            self.timers.mission = Some(Timer::cast_after(
                &self.clock,
                left,
                myself,
                DispatcherMsg::MissionDeadline {},
            ));
        }
        // re-arms the tree's timers; starts what it started and nothing carried on
        self.tick(myself);
    }

    /// The instance to hold for `held`: the one the lost dispatcher held if it still
    /// answers, else the one a selection picks now; bound above the recorded epoch. A
    /// selection that finds none is told only on the `last` look.
    async fn bind_held(&mut self, held: &BindingCheckpoint, last: bool) -> Option<Binding> {
        let need = self.mission.need(&held.name);
        let found: Vec<_> = registry::lookup(ModuleKind::Operation, &held.name)
            .into_iter()
            .filter(|i| !registry::is_declared_down(&i.node))
            .collect();
        let mut examined: Vec<Prospect> =
            examine_all(&held.name, found, crate::eo::EoClient::DEFAULT_TIMEOUT).await;
        let same = examined
            .iter()
            .position(|c| c.node == held.node && c.client.actor().get_id().pid() == held.pid);
        let index = match same {
            Some(i) => i,
            None => {
                let choice = choose(&need, &examined);
                let index = choice.chosen_index();
                if index.is_some() || last {
                    self.emit(EventKind::Selected { choice });
                }
                index?
            }
        };
        let mut binding = Binding::new(examined.swap_remove(index), held.epoch + 1, need);
        binding.params = held.params.clone();
        Some(binding)
    }

    /// The takeover's commands: attach the running action's operations (or suspend them
    /// again if it was ending), give every other its last parameters at the new epoch.
    fn command_after_takeover(&mut self, myself: &ActorRef<DispatcherMsg>, from: &Checkpoint) {
        let since = |name: &str| {
            from.bindings
                .iter()
                .find(|b| b.name == name)
                .map_or(0, |b| b.epoch)
        };
        let mut running_names = BTreeSet::new();
        let mut unlaunched = Vec::new();
        let generations: Vec<u64> = self.live.keys().copied().collect();
        for generation in generations {
            let Some(cur) = self.live.get(&generation) else {
                continue;
            };
            if !cur.launched {
                unlaunched.push(generation);
                continue;
            }
            let (running, ending) = (cur.running.clone(), cur.ending());
            for key in &running {
                let Some(b) = self.binding(key) else { continue };
                running_names.insert(b.name.clone());
                let (name, epoch, incarnation) = (b.name.clone(), b.epoch, b.incarnation);
                let result = match ending {
                    true => b.client.suspend(epoch),
                    false => self.attach(myself, key, generation, incarnation, since(&name)),
                };
                if let Err(e) = result {
                    self.report_gone(myself, &name, incarnation, e);
                }
            }
            let elapsed = self.elapsed_ms();
            if let Some(cur) = self.live.get_mut(&generation) {
                let message = match ending {
                    true => DispatcherMsg::SuspendGrace { generation },
                    false => DispatcherMsg::ActionDeadline { generation },
                };
                let wait = match ending {
                    true => super::running::SUSPEND_GRACE,
                    false => {
                        let deadline = self.mission.actions[cur.index].deadline;
                        let ran = Duration::from_millis(elapsed.saturating_sub(cur.started_ms));
                        deadline.saturating_sub(ran)
                    }
                };
                cur.timer = Some(Timer::cast_after(&self.clock, wait, myself, message));
            }
        }
        self.restore_parameters(&running_names);
        for generation in unlaunched {
            match self.live.get(&generation).is_some_and(|c| c.ending()) {
                // ended before its commands went out: nothing to suspend
                true => self.end_action(myself, generation),
                false => self.launch(myself, generation),
            }
        }
    }

    /// Give every bound operation but `except` its last parameters at its new epoch: they
    /// refuse the lost dispatcher's commands from then on.
    fn restore_parameters(&self, except: &BTreeSet<String>) {
        for b in self.bindings.values() {
            if except.contains(&b.name) {
                continue;
            }
            let (client, params, epoch) = (b.client.clone(), b.params.clone(), b.epoch);
            let name = b.name.clone();
            ractor::concurrency::spawn(async move {
                if let Err(e) = client.parameterize(params, epoch).await {
                    tracing::warn!(op = %name, error = %e, "parameters not restored after the takeover");
                }
            });
        }
    }

    /// Attach the running activation of the operation written `key` (see
    /// [`crate::eo::EoMsg::Attach`]); its report comes back as `OpEnded`, or `Idle` when
    /// nothing ran to attach to.
    fn attach(
        &self,
        myself: &ActorRef<DispatcherMsg>,
        key: &str,
        generation: u64,
        incarnation: u64,
        since: u64,
    ) -> Result<(), EoError> {
        let Some(b) = self.binding(key) else {
            return Err(EoError::Gone(key.to_string()));
        };
        let rx = b.client.attach(b.epoch, since)?;
        super::running::forward_report(myself, rx, generation, key, incarnation);
        Ok(())
    }

    /// An attached operation had no activation running (it ended while no dispatcher
    /// listened): resume it, so it carries on from what it stored.
    pub(super) fn resume_idle(
        &self,
        myself: &ActorRef<DispatcherMsg>,
        key: &str,
        generation: u64,
        incarnation: u64,
    ) {
        let Some(b) = self.binding(key) else { return };
        let start = Start {
            generation,
            incarnation,
            epoch: b.epoch,
            resume: true,
        };
        let (name, params) = (b.name.clone(), b.params.clone());
        tracing::info!(op = %name, "nothing ran to attach to: resumed");
        if let Err(e) = self.activate(myself, key, start, params) {
            self.report_gone(myself, &name, incarnation, e);
        }
    }
}

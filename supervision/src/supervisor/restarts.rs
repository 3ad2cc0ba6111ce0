//! Restarts: what a child's exit means under the strategy and its restart type, the
//! restart queue (one start at a time, off the mailbox), what a finished start does, and
//! giving up when the intensity is exceeded.

use super::*;

impl SupervisorState {
    pub(super) async fn on_supervision_event(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        event: SupervisionEvent,
    ) -> Result<(), Escalation> {
        let Some((cell, reason)) = ExitReason::from_supervision_event(&event) else {
            return Ok(());
        };
        // release the child's final state now rather than at the end of the handler
        drop(event);
        let actor = cell.get_id();
        match self.by_actor.remove(&actor) {
            Some(key) => self.child_exited(myself, key, actor, reason).await,
            None => {
                if self.in_flight.is_some() {
                    self.early_exits.insert(actor, reason);
                } else {
                    tracing::trace!(supervisor = %myself.get_id(), %actor, "exit of a former child ignored");
                }
                Ok(())
            }
        }
    }

    /// The current incarnation of child `key` stopped by itself.
    pub(super) async fn child_exited(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        actor: ActorId,
        reason: ExitReason,
    ) -> Result<(), Escalation> {
        let Some(child) = self.children.get_mut(&key) else {
            return Ok(());
        };
        child.status = Status::Undefined;
        child.old = Some(actor);
        if let Some(backoff) = &self.spec.backoff {
            if child.started_at.elapsed() >= backoff.reset_after {
                child.consecutive = 0;
            }
        }
        let id = child.spec.id.clone();
        let restart = child.spec.restart;
        if reason.is_abnormal() {
            tracing::warn!(supervisor = %myself.get_id(), child = %id, %actor, %reason, "child exited abnormally");
        } else {
            tracing::info!(supervisor = %myself.get_id(), child = %id, %actor, %reason, "child exited");
        }
        self.emit(SupervisorEvent::ChildExited {
            id,
            actor,
            reason: reason.clone(),
        });
        if restart == Restart::Temporary {
            self.remove_child(key);
            return Ok(());
        }
        if !restart.restarts_after(&reason) {
            if self.is_simple() {
                // an instance that is not restarted has nothing left to keep (as in OTP):
                // a transient instance that finished is gone, not undefined
                self.remove_child(key);
            }
            return Ok(());
        }
        self.restart(myself, key, RestartCause::Exited(reason))
            .await
    }

    /// One restart round for child `key` (OTP's `restart/2`): count it, stop the siblings the
    /// strategy restarts with it (reverse order), then start them all in order — at once, or
    /// after the backoff delay.
    pub(super) async fn restart(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        cause: RestartCause,
    ) -> Result<(), Escalation> {
        if !self.intensity.record(self.epoch.elapsed()) {
            return Err(Escalation);
        }
        let Some(trigger) = self.children.get(&key).map(|c| c.spec.id.clone()) else {
            return Ok(());
        };
        let scope = self.spec.strategy.scope(&self.children, key);
        for &k in scope.iter().rev() {
            if k == key {
                continue;
            }
            self.stop_child(k).await;
            if self
                .children
                .get(&k)
                .is_some_and(|c| c.spec.restart == Restart::Temporary)
            {
                // a temporary sibling is stopped, not restarted
                self.remove_child(k);
            }
        }
        for &k in &scope {
            let generation = self.generation();
            let Some(child) = self.children.get_mut(&k) else {
                continue;
            };
            if k == key {
                if let Status::Pending = child.status {
                    self.pending.remove(&k);
                }
                child.cause = Some(cause.clone());
            } else {
                child.cause = Some(RestartCause::Sibling(trigger.clone()));
            }
            child.generation = generation;
            child.status = Status::Restarting;
        }

        let Some(child) = self.children.get_mut(&key) else {
            return Ok(());
        };
        let attempt = child.consecutive;
        child.consecutive = attempt.saturating_add(1);
        let generation = child.generation;
        let delay = match &self.spec.backoff {
            Some(backoff) => backoff.delay(attempt, &mut self.rng),
            None => Duration::ZERO,
        };
        if delay.is_zero() {
            self.release(myself, key);
        } else {
            tracing::debug!(supervisor = %myself.get_id(), child = %trigger, ?delay, attempt, "restart scheduled");
            self.emit(SupervisorEvent::RestartScheduled {
                id: trigger,
                delay,
                attempt,
            });
            let me = myself.clone();
            self.timers.retain(|t| !t.is_finished());
            self.timers.push(tokio::spawn(async move {
                tokio::time::sleep(delay).await;
                let _ = me.cast(SupervisorMsg::Internal(Internal(
                    InternalKind::BackoffDone { key, generation },
                )));
            }));
        }
        Ok(())
    }

    /// Queue the children of `key`'s restart round that wait for it, and start the queue.
    pub(super) fn release(&mut self, myself: &ActorRef<SupervisorMsg>, key: u64) {
        for k in self.spec.strategy.scope(&self.children, key) {
            if let Some(child) = self.children.get_mut(&k) {
                if let Status::Restarting = child.status {
                    child.status = Status::Pending;
                    self.pending.insert(k);
                }
            }
        }
        self.pump(myself);
    }

    /// Start the first queued child, unless a start is already running.
    pub(super) fn pump(&mut self, myself: &ActorRef<SupervisorMsg>) {
        if self.in_flight.is_some() {
            return;
        }
        let Some(key) = self.pending.pop_first() else {
            return;
        };
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        let token = self.next_token;
        self.next_token += 1;
        child.status = Status::Starting(token);
        self.in_flight = Some(token);
        let start = child.spec.start.clone();
        let timeout = child.spec.start_timeout;
        let me = myself.clone();
        let task = tokio::spawn(async move {
            let result = run_start(&start, me.get_cell(), timeout).await;
            // drop the start function (and the start parameters it holds) before reporting,
            // so that a temporary child's parameters are gone once its start is answered
            drop(start);
            let started = result.as_ref().ok().and_then(|s| s.actor().cloned());
            let done =
                SupervisorMsg::Internal(Internal(InternalKind::StartDone { token, key, result }));
            if me.cast(done).is_err() {
                // the supervisor is gone; do not leave its child behind
                if let Some(cell) = started {
                    cell.kill();
                }
            }
        });
        self.tasks.insert(token, task);
    }

    pub(super) async fn start_done(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        token: u64,
        key: u64,
        result: Result<ChildStart, StartError>,
    ) -> Result<(), Escalation> {
        self.tasks.remove(&token);
        let outcome = if self.in_flight == Some(token) {
            self.in_flight = None;
            let outcome = self.started(myself, key, result).await;
            // early exits can only belong to the start just reported
            self.early_exits.clear();
            outcome
        } else {
            if let Ok(ChildStart::Started(cell)) = result {
                tracing::debug!(supervisor = %myself.get_id(), actor = %cell.get_id(), "abandoned start finished; killing its actor");
                cell.kill();
            }
            Ok(())
        };
        if outcome.is_ok() {
            self.pump(myself);
        }
        outcome
    }

    /// The start of child `key` (the one awaited) finished.
    pub(super) async fn started(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        result: Result<ChildStart, StartError>,
    ) -> Result<(), Escalation> {
        let simple = self.is_simple();
        let Some(child) = self.children.get_mut(&key) else {
            if let Ok(ChildStart::Started(cell)) = result {
                cell.kill();
            }
            return Ok(());
        };
        let id = child.spec.id.clone();
        match result {
            Ok(ChildStart::Ignore) => {
                tracing::info!(supervisor = %myself.get_id(), child = %id, "child ignored its start");
                child.status = Status::Undefined;
                let first = child.cause.take().is_none();
                let waiter = child.waiter.take();
                let drop_it = simple || child.spec.restart == Restart::Temporary;
                self.emit(SupervisorEvent::ChildIgnored { id: id.clone() });
                if drop_it {
                    if first {
                        // a first start leaves no trace
                        self.forget_child(key);
                    } else {
                        self.remove_child(key);
                    }
                }
                if let Some(waiter) = waiter {
                    let _ = waiter.send(Err(SupervisorError::Ignored(id)));
                }
                Ok(())
            }
            Ok(ChildStart::Started(cell)) => {
                let actor = cell.get_id();
                child.status = Status::Running(cell.clone());
                child.started_at = Instant::now();
                if child.spec.restart == Restart::Temporary {
                    child.spec.start = forgotten_start();
                }
                let event = match child.cause.take() {
                    Some(cause) => {
                        child.restarts = child.restarts.saturating_add(1);
                        tracing::info!(supervisor = %myself.get_id(), child = %id, %actor, ?cause, "child restarted");
                        SupervisorEvent::ChildRestarted {
                            id: id.clone(),
                            old: child.old.take(),
                            new: cell.clone(),
                            cause,
                            restarts: child.restarts,
                        }
                    }
                    None => {
                        tracing::debug!(supervisor = %myself.get_id(), child = %id, %actor, "child started");
                        SupervisorEvent::ChildStarted {
                            id: id.clone(),
                            actor: cell.clone(),
                        }
                    }
                };
                if let Some(waiter) = child.waiter.take() {
                    let _ = waiter.send(Ok(cell.clone()));
                }
                self.by_actor.insert(actor, key);
                self.emit(event);
                if let Some(reason) = self.early_exits.remove(&actor) {
                    self.by_actor.remove(&actor);
                    return self.child_exited(myself, key, actor, reason).await;
                }
                ensure_linked(myself, &id, &cell);
                Ok(())
            }
            Err(reason) => {
                match child.cause.clone() {
                    None => {
                        // the first start of a dynamic child: it leaves no spec behind
                        let waiter = child.waiter.take();
                        self.forget_child(key);
                        if let Some(waiter) = waiter {
                            let _ = waiter.send(Err(SupervisorError::StartFailed { id, reason }));
                        }
                    }
                    Some(RestartCause::Manual) => {
                        child.status = Status::Undefined;
                        child.cause = None;
                        if let Some(waiter) = child.waiter.take() {
                            let _ = waiter.send(Err(SupervisorError::StartFailed { id, reason }));
                        }
                    }
                    Some(_) => {
                        tracing::warn!(supervisor = %myself.get_id(), child = %id, %reason, "restart failed; trying again");
                        child.status = Status::Restarting;
                        let generation = child.generation;
                        self.emit(SupervisorEvent::RestartFailed { id, error: reason });
                        // children queued behind it in the same round wait for its retry
                        let behind: Vec<u64> = match self.spec.strategy {
                            Strategy::OneForOne | Strategy::SimpleOneForOne => Vec::new(),
                            Strategy::RestForOne => self.pending.range(key..).copied().collect(),
                            Strategy::OneForAll => self.pending.iter().copied().collect(),
                        };
                        for k in behind {
                            self.pending.remove(&k);
                            if let Some(c) = self.children.get_mut(&k) {
                                c.status = Status::Restarting;
                            }
                        }
                        let _ =
                            myself.cast(SupervisorMsg::Internal(Internal(InternalKind::Retry {
                                key,
                                generation,
                            })));
                    }
                }
                Ok(())
            }
        }
    }

    /// The restart intensity was exceeded: stop everything and fail, escalating to the parent.
    pub(super) async fn give_up(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
    ) -> Result<(), ActorProcessingErr> {
        tracing::error!(
            supervisor = %myself.get_id(),
            max_restarts = self.spec.max_restarts,
            period = ?self.spec.period,
            "reached max restart intensity; stopping all children and giving up"
        );
        self.emit(SupervisorEvent::IntensityExceeded {
            max_restarts: self.spec.max_restarts,
            period: self.spec.period,
        });
        self.shutdown_all().await;
        self.emit(SupervisorEvent::Stopped {
            reason: REACHED_MAX_RESTART_INTENSITY.to_string(),
        });
        self.events = None;
        Err(Box::new(SupervisorError::ReachedMaxRestartIntensity))
    }
}

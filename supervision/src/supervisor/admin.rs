//! Child administration (OTP's `start_child`, `terminate_child`, `restart_child`,
//! `delete_child`, `which_children`, `count_children`, dynamic instances) and shutting
//! every child down.

use super::*;

impl SupervisorState {
    /// Stop child `key` by its shutdown spec if it runs, abandon its start if one is queued
    /// or running, and leave it undefined.
    pub(super) async fn stop_child(&mut self, key: u64) {
        let generation = self.generation();
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        child.generation = generation;
        let cell = match std::mem::replace(&mut child.status, Status::Undefined) {
            Status::Running(cell) => cell,
            Status::Starting(token) => {
                if self.in_flight == Some(token) {
                    self.in_flight = None;
                }
                return;
            }
            Status::Pending => {
                self.pending.remove(&key);
                return;
            }
            Status::Restarting | Status::Undefined => return,
        };
        let actor = cell.get_id();
        child.old = Some(actor);
        let shutdown = child.spec.shutdown;
        let id = child.spec.id.clone();
        self.by_actor.remove(&actor);
        let killed = shutdown_child(&cell, shutdown).await;
        tracing::debug!(child = %id, %actor, killed, "child shut down");
        self.emit(SupervisorEvent::ChildShutdown { id, actor, killed });
    }

    /// Remove child `key` without a trace (no event, no reply).
    pub(super) fn forget_child(&mut self, key: u64) -> Option<Child> {
        let child = self.children.remove(&key)?;
        self.by_id.remove(&child.spec.id);
        self.pending.remove(&key);
        match &child.status {
            Status::Running(cell) => {
                self.by_actor.remove(&cell.get_id());
            }
            Status::Starting(token) if self.in_flight == Some(*token) => self.in_flight = None,
            _ => {}
        }
        Some(child)
    }

    /// Remove child `key`, telling a waiting caller and the subscribers.
    pub(super) fn remove_child(&mut self, key: u64) {
        if let Some(child) = self.forget_child(key) {
            let id = child.spec.id;
            if let Some(waiter) = child.waiter {
                let _ = waiter.send(Err(SupervisorError::Terminated(id.clone())));
            }
            self.emit(SupervisorEvent::ChildDeleted { id });
        }
    }

    pub(super) fn start_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        spec: ChildSpec,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        if self.is_simple() {
            let _ = reply.send(Err(SupervisorError::SimpleOneForOne));
            return;
        }
        if let Err(e) = spec.validate() {
            let _ = reply.send(Err(e.into()));
            return;
        }
        if let Some(key) = self.by_id.get(&spec.id) {
            let err = match self.children[key].status {
                Status::Running(_) => SupervisorError::AlreadyStarted(spec.id),
                _ => SupervisorError::AlreadyPresent(spec.id),
            };
            let _ = reply.send(Err(err));
            return;
        }
        self.add_pending(myself, spec, reply);
    }

    /// Add `spec` at the end of the start order and queue its first start.
    pub(super) fn add_pending(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        spec: ChildSpec,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let key = self.next_key;
        self.next_key += 1;
        self.by_id.insert(spec.id.clone(), key);
        let mut child = Self::new_child(spec, Status::Pending);
        child.waiter = Some(reply);
        self.children.insert(key, child);
        self.pending.insert(key);
        self.pump(myself);
    }

    /// Start one more instance of the template with `arg` (simple-one-for-one only).
    pub(super) fn start_dynamic(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        arg: DynamicArg,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let Some(template) = self.template.as_ref().filter(|_| self.is_simple()) else {
            let _ = reply.send(Err(SupervisorError::NotSimpleOneForOne));
            return;
        };
        if !template.accepts(&arg) {
            let _ = reply.send(Err(SupervisorError::WrongArgument {
                expected: template.arg_type_name(),
                got: arg.type_name(),
            }));
            return;
        }
        self.next_instance += 1;
        let id = format!("{}#{}", template.id, self.next_instance);
        let spec = template.instance(id, arg);
        self.add_pending(myself, spec, reply);
    }

    /// Stop instance `actor` of a simple-one-for-one supervisor and forget it.
    pub(super) async fn terminate_actor(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        actor: ActorId,
    ) -> Result<(), SupervisorError> {
        if !self.is_simple() {
            return Err(SupervisorError::NotFound(actor.to_string()));
        }
        let key = match self.by_actor.get(&actor) {
            Some(&key) => Some(key),
            // an instance restarting after this incarnation's exit
            None => self
                .children
                .iter()
                .find(|(_, c)| !matches!(c.status, Status::Running(_)) && c.old == Some(actor))
                .map(|(&k, _)| k),
        };
        let Some(key) = key else {
            // OTP: terminating an instance that has already gone is fine; a live actor that
            // is not an instance is not
            return match ractor::registry::where_is_pid(actor) {
                Some(_) => Err(SupervisorError::NotFound(actor.to_string())),
                None => Ok(()),
            };
        };
        self.stop_child(key).await;
        if let Some(waiter) = self.children.get_mut(&key).and_then(|c| c.waiter.take()) {
            let _ = waiter.send(Err(SupervisorError::Terminated(actor.to_string())));
        }
        self.remove_child(key);
        self.pump(myself);
        Ok(())
    }

    pub(super) async fn terminate_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        id: &str,
    ) -> Result<(), SupervisorError> {
        let Some(&key) = self.by_id.get(id) else {
            return Err(SupervisorError::NotFound(id.to_string()));
        };
        let was_restarting = matches!(self.children[&key].status, Status::Restarting);
        self.stop_child(key).await;
        if was_restarting {
            // siblings whose restart waited for this child's retry or backoff would wait
            // forever: start them now, without it
            self.release(myself, key);
        }
        if let Some(child) = self.children.get_mut(&key) {
            child.cause = None;
            if let Some(waiter) = child.waiter.take() {
                let _ = waiter.send(Err(SupervisorError::Terminated(id.to_string())));
            }
            if child.spec.restart == Restart::Temporary {
                self.remove_child(key);
            }
        }
        self.pump(myself);
        Ok(())
    }

    pub(super) fn restart_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        id: &str,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let Some(&key) = self.by_id.get(id) else {
            let _ = reply.send(Err(SupervisorError::NotFound(id.to_string())));
            return;
        };
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        match child.status {
            Status::Running(_) => {
                let _ = reply.send(Err(SupervisorError::Running(id.to_string())));
            }
            Status::Pending | Status::Starting(_) | Status::Restarting => {
                let _ = reply.send(Err(SupervisorError::Restarting(id.to_string())));
            }
            Status::Undefined => {
                child.cause = Some(RestartCause::Manual);
                child.waiter = Some(reply);
                child.status = Status::Pending;
                self.pending.insert(key);
                self.pump(myself);
            }
        }
    }

    pub(super) fn delete_child(&mut self, id: &str) -> Result<(), SupervisorError> {
        let Some(&key) = self.by_id.get(id) else {
            return Err(SupervisorError::NotFound(id.to_string()));
        };
        match self.children[&key].status {
            Status::Running(_) => Err(SupervisorError::Running(id.to_string())),
            Status::Pending | Status::Starting(_) | Status::Restarting => {
                Err(SupervisorError::Restarting(id.to_string()))
            }
            Status::Undefined => {
                self.remove_child(key);
                Ok(())
            }
        }
    }

    pub(super) fn which_children(&self) -> Vec<ChildInfo> {
        self.children
            .values()
            .map(|c| ChildInfo {
                id: c.spec.id.clone(),
                state: match &c.status {
                    Status::Running(cell) => ChildState::Running(cell.clone()),
                    Status::Pending | Status::Starting(_) if c.cause.is_none() => {
                        ChildState::Starting
                    }
                    Status::Pending | Status::Starting(_) | Status::Restarting => {
                        ChildState::Restarting
                    }
                    Status::Undefined => ChildState::Undefined,
                },
                restart: c.spec.restart,
                shutdown: c.spec.shutdown,
                kind: c.spec.kind,
                restarts: c.restarts,
                start_timeout: c.spec.start_timeout,
            })
            .collect()
    }

    pub(super) fn count_children(&self) -> ChildCounts {
        let mut counts = ChildCounts {
            // a simple-one-for-one supervisor has one spec, its template (as OTP counts)
            specs: if self.is_simple() {
                1
            } else {
                self.children.len()
            },
            ..ChildCounts::default()
        };
        for c in self.children.values() {
            if let Status::Running(_) = c.status {
                counts.active += 1;
            }
            match c.spec.kind {
                ChildKind::Worker => counts.workers += 1,
                ChildKind::Supervisor => counts.supervisors += 1,
            }
        }
        counts
    }

    /// Stop every child in reverse start order and abandon all pending starts.
    pub(super) async fn shutdown_all(&mut self) {
        for (_, task) in self.tasks.drain() {
            task.abort();
        }
        for timer in self.timers.drain(..) {
            timer.abort();
        }
        self.in_flight = None;
        self.early_exits.clear();
        if self.is_simple() {
            self.shutdown_instances().await;
        }
        let keys: Vec<u64> = self.children.keys().rev().copied().collect();
        for key in keys {
            self.stop_child(key).await;
            if let Some(waiter) = self.children.get_mut(&key).and_then(|c| c.waiter.take()) {
                let _ = waiter.send(Err(SupervisorError::ShuttingDown));
            }
        }
        self.pending.clear();
    }

    /// Stop every running instance of a simple-one-for-one supervisor at once and wait for
    /// them together (OTP stops them asynchronously too; there is no order among instances).
    pub(super) async fn shutdown_instances(&mut self) {
        let mut stopping = Vec::new();
        for child in self.children.values_mut() {
            if let Status::Running(cell) = &child.status {
                let cell = cell.clone();
                child.status = Status::Undefined;
                child.old = Some(cell.get_id());
                self.by_actor.remove(&cell.get_id());
                stopping.push((child.spec.id.clone(), cell, child.spec.shutdown));
            }
        }
        let cells: Vec<_> = stopping.iter().map(|(_, c, s)| (c.clone(), *s)).collect();
        let killed = shutdown_together(&cells).await;
        for ((id, cell, _), killed) in stopping.into_iter().zip(killed) {
            self.emit(SupervisorEvent::ChildShutdown {
                id,
                actor: cell.get_id(),
                killed,
            });
        }
    }
}

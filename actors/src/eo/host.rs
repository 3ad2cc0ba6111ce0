//! The generic EO host actor: runs any [`Operation`].
//!
//! The host owns the bookkeeping every operation needs — current and previous parameter
//! values, epochs, activation state, up-time — and answers the eo-interface and the property
//! interface from it, so the operation itself holds only its algorithm.
//!
//! # Invariants
//! - At most one activation runs; its reply port is answered exactly once (`Finished`,
//!   `Suspended`, `Failed`), or dropped if the host crashes or is stopped — which the waiting
//!   side sees as a closed port (the instance is gone), never as a suspension.
//! - A command whose epoch is older than the highest accepted one changes nothing.
//! - Parameters change all at once or not at all.
//! - A finished task suspends the operation; the host never stops because work is done.

use super::messages::{EoMsg, EoReport, ParamOutcome};
use super::operation::{Identity, OpContext, Operation, Params, Step};
use marie_vocabulary::clock::{RealClock, SharedClock, Timer};
use marie_vocabulary::property::{
    Address, Collection, General, Group, Identification, Limit, Location, ParamMap, ParamSchema,
    PropertyReply, PropertyRequest, Signature, Specific, Value,
};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use std::marker::PhantomData;
use std::time::Duration;
use tokio::task::JoinHandle;

/// How to host an operation.
#[derive(Clone)]
pub struct HostOptions {
    /// The clock the operation reads and sleeps on (default: the process's, [`RealClock::process`]).
    pub clock: SharedClock,
    /// Start-up parameter values (may set read-only parameters); the rest take defaults.
    pub params: ParamMap,
    /// Publish in the registry (on by default).
    pub publish: bool,
    /// Told of every store and delete its datamanager clients get acknowledged
    /// ([`marie_dm::AckSink`]; a node publishes them on its bus). `None` by default.
    pub acks: Option<marie_dm::AckSink>,
    /// Where a `Parameterize` that changes its values is told (`reparameterized`: a run's
    /// provenance names every value an operation ran with). `None` by default.
    pub events: Option<marie_vocabulary::events::EventBus>,
    /// A test knob: the instance's first `n` activations fail at once (an
    /// [`EoReport::Failed`] right after their parameters are applied, before the
    /// operation's own `activate`); 0 by default. A node config sets it per `[[operation]]`
    /// (`fail_first_activations = 1`) to prove that a binding moved to a new version whose
    /// first activation fails goes back to the old instance (issue 44's rollback). Counted
    /// per instance: a restarted instance fails its first `n` again.
    pub fail_first_activations: u64,
    /// A binding to this instance runs on its version for the rest of the mission: it
    /// never moves to a newer version, and a stand-in must be of this version (the node
    /// config's `pin = true` on an `[[operation]]`). Answered as the property
    /// [`PINNED`]. False by default.
    pub pinned: bool,
}

/// The property an operation's host answers whether its node pins it under
/// ([`HostOptions::pinned`]); a build before pins answers `NotFound`: not pinned.
pub const PINNED: &str = "pinned";

impl std::fmt::Debug for HostOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HostOptions")
            .field("params", &self.params)
            .field("publish", &self.publish)
            .field("acks", &self.acks.is_some())
            .field("events", &self.events.is_some())
            .field("fail_first_activations", &self.fail_first_activations)
            .field("pinned", &self.pinned)
            .finish_non_exhaustive()
    }
}

impl Default for HostOptions {
    fn default() -> Self {
        HostOptions {
            clock: RealClock::process(),
            params: ParamMap::new(),
            publish: true,
            acks: None,
            events: None,
            fail_first_activations: 0,
            pinned: false,
        }
    }
}

impl HostOptions {
    /// Options with the given clock.
    pub fn with_clock(clock: SharedClock) -> Self {
        HostOptions {
            clock,
            ..Default::default()
        }
    }
}

/// The EO host actor for operation type `O`.
pub struct EoHost<O>(PhantomData<fn() -> O>);

impl<O> std::fmt::Debug for EoHost<O> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EoHost<{}>", std::any::type_name::<O>())
    }
}

impl<O> Default for EoHost<O> {
    fn default() -> Self {
        EoHost(PhantomData)
    }
}

/// Start-up arguments of [`EoHost`].
pub struct HostArgs<O> {
    /// The operation to run.
    pub operation: O,
    /// Hosting options.
    pub options: HostOptions,
}

impl<O> std::fmt::Debug for HostArgs<O> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HostArgs")
            .field("operation", &std::any::type_name::<O>())
            .field("options", &self.options)
            .finish()
    }
}

struct Active {
    number: u64,
    epoch: u64,
    reply: RpcReplyPort<EoReport>,
    /// Whether the operation's `activate` hook has run through. Until it has, the next
    /// tick runs it again instead of a step: an `activate` held because a module it needs
    /// was gone (its datamanager failing over) is retried once the module is back — a
    /// step would run on what `activate` never set up.
    set_up: bool,
}

/// State of an [`EoHost`].
pub struct HostState<O> {
    op: O,
    identity: Identity,
    /// The identification group, built once: it never changes, and a property request is
    /// answered by cloning it (no version formatting per request).
    identification: Identification,
    schema: ParamSchema,
    flags: Vec<FlagDecl>,
    period: Duration,
    /// The next step's timer.
    tick: Option<Timer>,
    deadline: Duration,
    ctx: OpContext,
    previous: ParamMap,
    /// Where changed parameters are told ([`HostOptions::events`]).
    events: Option<marie_vocabulary::events::EventBus>,
    epoch: u64,
    active: Option<Active>,
    activations: u64,
    /// [`HostOptions::fail_first_activations`].
    fail_first: u64,
    /// What the operation declares of its older versions' parameters, as the property
    /// interface answers it (`Get("migrations")`).
    migrations: Value,
    /// [`HostOptions::pinned`].
    pinned: bool,
    started: Duration,
}

impl<O> std::fmt::Debug for HostState<O> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HostState")
            .field("identity", &self.identity)
            .field("epoch", &self.epoch)
            .field("active", &self.active.is_some())
            .field("activations", &self.activations)
            .finish_non_exhaustive()
    }
}

impl<O: Operation> HostState<O> {
    fn uptime_ms(&self) -> u64 {
        (self.ctx.clock.now().saturating_sub(self.started)).as_millis() as u64
    }

    fn current(&self) -> &ParamMap {
        self.ctx.params.all()
    }

    fn set_params(&mut self, next: ParamMap) {
        if &next != self.current() {
            self.previous = self.current().clone();
            self.ctx.params = Params::new(next);
        }
    }

    /// Tell the values `next` changes ([`EventKind::Reparameterized`](marie_vocabulary::events::EventKind::Reparameterized)).
    fn tell_changes(&self, myself: &ActorRef<EoMsg>, next: &ParamMap) {
        let Some(bus) = &self.events else { return };
        let current = self.current();
        let values: Vec<marie_vocabulary::run::ParamValue> = next
            .iter()
            .filter(|(k, v)| current.get(*k) != Some(*v))
            .map(|(k, v)| marie_vocabulary::run::ParamValue {
                name: k.clone(),
                value: v.clone(),
                source: marie_vocabulary::run::ParamSource::Reparameterized,
            })
            .collect();
        if !values.is_empty() {
            bus.publish(marie_vocabulary::events::EventKind::Reparameterized {
                operation: self.identity.name.clone(),
                address: myself.get_id().to_string(),
                values,
            });
        }
    }

    fn answer(&self, myself: &ActorCell, request: PropertyRequest) -> PropertyReply {
        let id = &self.identity;
        match request {
            PropertyRequest::Group(Group::Identification) => {
                PropertyReply::Identification(self.identification.clone())
            }
            PropertyRequest::Group(Group::Location) => PropertyReply::Location(Location {
                node: registry::local_node_name(),
                address: myself.get_id().to_string(),
                alive: true,
            }),
            PropertyRequest::Group(Group::General) => PropertyReply::General(General {
                param_count: self.schema.len(),
                uptime_ms: self.uptime_ms(),
                in_use: self.active.is_some(),
                activations: self.activations,
                epoch: self.epoch,
                deadline_ms: self.deadline.as_millis() as u64,
            }),
            PropertyRequest::Group(Group::Specific) => PropertyReply::Specific(Specific {
                params: self.schema.params.clone(),
                previous: self.previous.clone(),
                current: self.current().clone(),
                flags: self.flags.clone(),
            }),
            PropertyRequest::Collection(Collection::Address) => PropertyReply::Address(Address {
                name: id.name.clone(),
                id: id.id,
                node: registry::local_node_name(),
                address: myself.get_id().to_string(),
            }),
            PropertyRequest::Collection(Collection::Signature) => {
                PropertyReply::Signature(Signature {
                    count: self.schema.len(),
                    params: self
                        .schema
                        .params
                        .iter()
                        .map(|d| (d.name.clone(), d.ty.clone()))
                        .collect(),
                })
            }
            PropertyRequest::Collection(Collection::Limits) => PropertyReply::Limits(
                self.schema
                    .params
                    .iter()
                    .map(|d| Limit {
                        name: d.name.clone(),
                        default: d.default.clone(),
                        min: d.min,
                        max: d.max,
                    })
                    .collect(),
            ),
            PropertyRequest::Collection(Collection::Previous) => {
                PropertyReply::Previous(self.previous.clone())
            }
            PropertyRequest::Collection(Collection::Current) => {
                PropertyReply::Current(self.current().clone())
            }
            PropertyRequest::Get(name) => match self.single(myself, &name) {
                Some(v) => PropertyReply::Value(v),
                None => PropertyReply::NotFound(name),
            },
        }
    }

    fn single(&self, myself: &ActorCell, name: &str) -> Option<Value> {
        let id = &self.identity;
        Some(match name {
            "name" => Value::Text(id.name.clone()),
            "id" => Value::Int(id.id.into()),
            "version" => Value::Text(self.identification.version.to_string()),
            "description" => Value::Text(id.description.clone()),
            "node" => Value::Text(registry::local_node_name()),
            "address" => Value::Text(myself.get_id().to_string()),
            "alive" => Value::Bool(true),
            "param_count" => Value::Int(self.schema.len() as i64),
            "uptime_ms" => Value::Int(self.uptime_ms() as i64),
            "in_use" => Value::Bool(self.active.is_some()),
            "activations" => Value::Int(self.activations as i64),
            "epoch" => Value::Int(self.epoch as i64),
            crate::declare::Migrations::PROPERTY => self.migrations.clone(),
            PINNED => Value::Bool(self.pinned),
            _ => {
                if let Some(param) = name.strip_prefix("param.") {
                    return self.current().get(param).cloned();
                }
                return self.op.property(name);
            }
        })
    }

    /// End the running activation (if any) with the report `make` builds from the flags.
    async fn end_activation(&mut self, make: impl FnOnce(StatusFlags, u64) -> EoReport) {
        let Some(active) = self.active.take() else {
            return;
        };
        if let Err(e) = self.op.suspend(&mut self.ctx).await {
            tracing::warn!(op = %self.identity.name, error = %e, "suspend hook failed");
        }
        let report = make(self.ctx.raised, active.epoch);
        tracing::debug!(op = %self.identity.name, activation = active.number, ?report, "activation ended");
        let _ = active.reply.send(report);
    }

    /// The host stops with an activation running (its node reincarnates its operations, its
    /// supervisor ends it): the operation's suspend hook runs, and the activation's port is
    /// dropped unanswered — nobody commanded its end, and its dispatcher hears what it hears
    /// of a crash (a closed port: the instance is gone, a stand-in is bound). Answered
    /// `Suspended`, as it was, the dispatcher took it for a suspension by another party and
    /// failed the run: the soak's run 7, its holder's own node reincarnating its operations.
    async fn abandon_activation(&mut self) {
        let Some(active) = self.active.take() else {
            return;
        };
        if let Err(e) = self.op.suspend(&mut self.ctx).await {
            tracing::warn!(op = %self.identity.name, error = %e, "suspend hook failed");
        }
        tracing::debug!(op = %self.identity.name, activation = active.number, "host stopped: activation abandoned");
        drop(active.reply);
    }

    /// Hand the running activation's report to a dispatcher taking over a lost one's run
    /// (see [`EoMsg::Attach`]).
    fn attach(&mut self, epoch: u64, since: u64, reply: RpcReplyPort<EoReport>) {
        if epoch < self.epoch {
            let _ = reply.send(EoReport::Stale {
                epoch,
                current: self.epoch,
            });
            return;
        }
        self.epoch = epoch;
        match &mut self.active {
            Some(active) if active.epoch >= since => {
                tracing::info!(op = %self.identity.name, activation = active.number, epoch, "activation attached to a new dispatcher");
                active.epoch = epoch;
                self.ctx.epoch = epoch;
                // the lost dispatcher's port is dropped: it hears nothing more
                active.reply = reply;
            }
            _ => {
                let _ = reply.send(EoReport::Idle { epoch });
            }
        }
    }

    /// Start an activation (`resumed`: taking over a lost instance's).
    async fn activate(
        &mut self,
        myself: &ActorRef<EoMsg>,
        params: ParamMap,
        epoch: u64,
        reply: RpcReplyPort<EoReport>,
        resumed: bool,
    ) {
        if epoch < self.epoch {
            let _ = reply.send(EoReport::Stale {
                epoch,
                current: self.epoch,
            });
            return;
        }
        self.epoch = epoch;
        let next = match self.schema.apply(self.current(), &params, false) {
            Ok(next) => next,
            Err(rejections) => {
                let _ = reply.send(EoReport::Rejected { rejections, epoch });
                return;
            }
        };
        self.end_activation(|flags, epoch| EoReport::Suspended { flags, epoch })
            .await;
        self.set_params(next);
        self.activations += 1;
        self.ctx.activation = self.activations;
        self.ctx.epoch = epoch;
        self.ctx.resumed = resumed;
        self.ctx.raised = StatusFlags::EMPTY;
        self.active = Some(Active {
            number: self.activations,
            epoch,
            reply,
            set_up: false,
        });
        if self.activations <= self.fail_first {
            let reason = format!(
                "activation {} of the first {} fails on purpose (fail_first_activations)",
                self.activations, self.fail_first
            );
            tracing::warn!(op = %self.identity.name, %reason, "activation failed by the test knob");
            self.end_activation(|flags, epoch| EoReport::Failed {
                reason,
                flags,
                epoch,
            })
            .await;
            return;
        }
        let outcome = self.op.activate(&mut self.ctx).await;
        self.after_step(myself, outcome).await;
    }

    /// The module whose absence `e` is, if it is gone and an activation runs: the
    /// activation's number and the module's kind and name — what the host then waits for
    /// instead of failing the activation.
    fn held_for(&self, e: &super::OpError) -> Option<(u64, ModuleKind, String)> {
        let activation = self.active.as_ref()?.number;
        let (kind, module) = e.needed_module()?;
        // a module absent at the call is waited for even if it is published again by now
        // (the wait then ends at once): the look comes after the call
        (e.is_absent() || self.ctx.module_gone(kind, module))
            .then(|| (activation, kind, module.to_string()))
    }

    /// React to the outcome of `activate` or `step`.
    async fn after_step(
        &mut self,
        myself: &ActorRef<EoMsg>,
        outcome: Result<Step, super::OpError>,
    ) {
        self.ctx.flush_puts();
        if outcome.is_ok() {
            if let Some(active) = &mut self.active {
                active.set_up = true;
            }
        }
        match outcome {
            Ok(Step::Continue) => {
                if let Some(active) = &self.active {
                    // kept in the state: a crashed host's pending tick dies with it
                    self.tick = Some(Timer::cast_after(
                        &self.ctx.clock,
                        self.period,
                        myself,
                        EoMsg::Tick {
                            activation: active.number,
                        },
                    ));
                }
            }
            Ok(Step::Finish(flags)) => {
                self.ctx.raised |= flags;
                self.end_activation(|flags, epoch| EoReport::Finished { flags, epoch })
                    .await;
            }
            Err(e) => match self.held_for(&e) {
                Some((activation, kind, module)) => {
                    // the module is gone (a DM crashed, the cart's node lost or cut off from
                    // this one): wait for its next incarnation, then step again
                    tracing::warn!(op = %self.identity.name, %module, error = %e, "module gone: waiting for it");
                    let reason = e.to_string();
                    let myself = myself.clone();
                    // held where the next tick is: it dies with the host, and a later tick or
                    // wait replaces (cancels) it; its message names its activation, which a
                    // host that has moved on ignores
                    self.tick = Some(Timer::task(tokio::spawn(async move {
                        let message =
                            match super::absence::wait_for_module(kind, &module, reason).await {
                                Ok(()) => {
                                    tracing::info!(%module, "module back: stepping on");
                                    EoMsg::Tick { activation }
                                }
                                Err(reason) => EoMsg::ModuleAbsent {
                                    activation,
                                    module,
                                    reason,
                                },
                            };
                        let _ = myself.cast(message);
                    })));
                }
                None => {
                    tracing::warn!(op = %self.identity.name, error = %e, "operation failed");
                    let reason = e.to_string();
                    self.end_activation(|flags, epoch| EoReport::Failed {
                        reason,
                        flags,
                        epoch,
                    })
                    .await;
                }
            },
        }
    }
}

impl<O: Operation> Actor for EoHost<O> {
    type Msg = EoMsg;
    type State = HostState<O>;
    type Arguments = HostArgs<O>;

    async fn pre_start(
        &self,
        myself: ActorRef<EoMsg>,
        args: HostArgs<O>,
    ) -> Result<HostState<O>, ActorProcessingErr> {
        let HostArgs { operation, options } = args;
        let identity = operation.identity();
        super::check_declaration(&operation)?;
        let schema = operation.parameters();
        let flags = operation.flags();
        let migrations = operation.migrations().to_value();
        let initial = schema
            .apply(&schema.defaults(), &options.params, true)
            .map_err(|rej| {
                let list: Vec<String> = rej.iter().map(|r| r.to_string()).collect();
                format!(
                    "operation {}: bad start-up parameters: {}",
                    identity.name,
                    list.join("; ")
                )
            })?;
        let started = options.clock.now();
        // Published before `spawn` returns, so a spawner can look the operation up at once.
        if options.publish {
            registry::publish(
                ModuleKind::Operation,
                identity.id,
                &identity.name,
                myself.get_cell(),
            )?;
        }
        tracing::debug!(op = %identity.name, version = %identity.version, actor = %myself.get_id(), "operation started");
        Ok(HostState {
            period: operation.period(),
            tick: None,
            deadline: operation.deadline(),
            ctx: OpContext {
                params: Params::new(initial.clone()),
                clock: options.clock,
                raised: StatusFlags::EMPTY,
                source: identity.name.clone(),
                activation: 0,
                epoch: 0,
                resumed: false,
                dms: Default::default(),
                acks: options.acks,
            },
            previous: initial,
            events: options.events,
            op: operation,
            identification: Identification {
                name: identity.name.as_str().into(),
                id: identity.id,
                version: identity.version.to_string().into(),
                description: identity.description.as_str().into(),
            },
            identity,
            schema,
            flags,
            epoch: 0,
            active: None,
            activations: 0,
            fail_first: options.fail_first_activations,
            migrations,
            pinned: options.pinned,
            started,
        })
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<EoMsg>,
        state: &mut HostState<O>,
    ) -> Result<(), ActorProcessingErr> {
        state.abandon_activation().await;
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<EoMsg>,
        msg: EoMsg,
        state: &mut HostState<O>,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            EoMsg::Activate {
                params,
                epoch,
                reply,
            } => Box::pin(state.activate(&myself, params, epoch, reply, false)).await,
            EoMsg::Resume {
                params,
                epoch,
                reply,
            } => Box::pin(state.activate(&myself, params, epoch, reply, true)).await,
            EoMsg::Attach {
                epoch,
                since,
                reply,
            } => state.attach(epoch, since, reply),
            EoMsg::Tick { activation } => {
                if state.active.as_ref().map(|a| a.number) != Some(activation) {
                    return Ok(()); // a tick of an activation that already ended
                }
                // boxed, like every arm that awaits: the operation's step future would
                // otherwise be part of every message's future (a property request pays for
                // the size of the largest arm)
                let set_up = state.active.as_ref().is_some_and(|a| a.set_up);
                let outcome = if set_up {
                    Box::pin(state.op.step(&mut state.ctx)).await
                } else {
                    Box::pin(state.op.activate(&mut state.ctx)).await
                };
                Box::pin(state.after_step(&myself, outcome)).await;
            }
            EoMsg::ModuleAbsent {
                activation,
                module,
                reason,
            } => {
                if state.active.as_ref().map(|a| a.number) != Some(activation) {
                    return Ok(()); // the activation ended while it waited
                }
                tracing::warn!(op = %state.identity.name, %module, %reason, "operation failed: a module it needs did not come back");
                Box::pin(state.end_activation(|flags, epoch| EoReport::Failed {
                    reason,
                    flags,
                    epoch,
                }))
                .await;
            }
            EoMsg::Suspend { epoch } => {
                if epoch < state.epoch {
                    tracing::debug!(op = %state.identity.name, epoch, current = state.epoch, "stale suspend ignored");
                    return Ok(());
                }
                state.epoch = epoch;
                Box::pin(state.end_activation(|flags, epoch| EoReport::Suspended { flags, epoch }))
                    .await;
            }
            EoMsg::Parameterize {
                values,
                epoch,
                reply,
            } => {
                if epoch < state.epoch {
                    let _ = reply.send(ParamOutcome::Stale {
                        current: state.epoch,
                    });
                    return Ok(());
                }
                state.epoch = epoch;
                let outcome = match state.schema.apply(state.current(), &values, false) {
                    Ok(next) => {
                        state.tell_changes(&myself, &next);
                        state.set_params(next);
                        ParamOutcome::Applied
                    }
                    Err(rej) => ParamOutcome::Rejected(rej),
                };
                let _ = reply.send(outcome);
            }
            EoMsg::Property { request, reply } => {
                let _ = reply.send(state.answer(&myself, request));
            }
            EoMsg::Inject { fault } => {
                tracing::warn!(op = %state.identity.name, actor = %myself.get_id(), ?fault, "injected fault");
                match fault {
                    FaultKind::Panic => {
                        panic!("injected fault: operation {} panics", state.identity.name)
                    }
                    // Only a kill ends this (ractor's kill signal interrupts a running handler).
                    FaultKind::Hang => std::future::pending::<()>().await,
                    FaultKind::Kill => myself.kill(),
                    // from the next step on (a step already due comes as it was planned)
                    FaultKind::Slow => state.period *= FaultKind::SLOW_FACTOR,
                    FaultKind::StopNode | FaultKind::FreezeNode | FaultKind::Partition => {
                        tracing::warn!(%fault, "a node's fault reached an operation: ignored")
                    }
                }
            }
        }
        Ok(())
    }
}

/// Spawn an operation in its host, unsupervised. The handle completes when the host stops.
pub async fn spawn_operation<O: Operation>(
    operation: O,
    options: HostOptions,
) -> Result<(ActorRef<EoMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn(
        None,
        EoHost::<O>::default(),
        HostArgs { operation, options },
    )
    .await
}

/// Spawn an operation in its host, linked to `supervisor`.
pub async fn spawn_operation_linked<O: Operation>(
    operation: O,
    options: HostOptions,
    supervisor: ActorCell,
) -> Result<(ActorRef<EoMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn_linked(
        None,
        EoHost::<O>::default(),
        HostArgs { operation, options },
        supervisor,
    )
    .await
}

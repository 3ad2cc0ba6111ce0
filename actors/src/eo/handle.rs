//! An operation handle: an embedder's typed, epoch-free hold on an operation by name, across
//! restarts of its instances.
//!
//! Why a second client: [`EoClient`] is the interface as the dispatcher speaks it — one
//! actor, commands under an explicit epoch (a wrong guess is answered `Stale` and changes
//! nothing), property answers as an 11-variant [`PropertyReply`], errors that name an actor
//! id, and a client that is useless once its actor died. An application that only wants to
//! read and set an operation's parameters needs none of that; [`OperationHandle`] says what
//! it does instead.

use super::client::{EoClient, EoError};
use super::handle_error::{HandleError, SetError};
use super::messages::{EoMsg, ParamOutcome};
use super::operation::Identity;
use crate::flags::FlagDecl;
use crate::property::{
    Collection, FromValue, General, Group, ParamMap, ParamSchema, PropertyReply, PropertyRequest,
    Specific, Value,
};
use crate::registry::{self, Instance, ModuleKind, RegistryEvent};
use ractor::{ActorId, ActorRef, ActorStatus};
use semver::VersionReq;
use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::time::Instant;

/// A typed hold on an operation by name that follows its restarts. Cheap to clone; clones
/// share the instance they follow. The handle:
///
/// - **finds the operation by name** (or numeric id, optionally a version requirement) in
///   the registry, taking the first live instance, as the registry orders them (local first);
/// - **follows restarts**: when its instance is gone — a call fails because the actor
///   stopped, or it is already dead when a call starts — it waits (bounded,
///   [`OperationHandle::DEFAULT_FOLLOW`]) for an instance of the same operation to be in the
///   registry (a supervisor's restart, a spare; [`crate::registry::watch`] so nothing is
///   polled) and retries the call there once. This is the dispatcher's rebind in miniature,
///   without its selection and restoring: a replacement starts with its own start-up
///   parameters, and the handle does not replay earlier [`set`](OperationHandle::set)s.
///   Across nodes ractor_cluster usually answers a request that timed out as if its actor
///   had died, so a hung remote instance is left like a gone one: the call waits for
///   another instance instead of reporting a [`HandleError::Timeout`];
/// - **answers in types**: [`Identity`], [`ParamSchema`], [`FlagDecl`]s, [`General`], a
///   parameter as any [`FromValue`] type;
/// - **keeps epochs inside**: [`set`](OperationHandle::set) reads the instance's current
///   epoch and commands at exactly that epoch — the host refuses only an epoch *below* its
///   current one ([`crate::fence`]) — and if a dispatcher raised it in between (the answer
///   is `Stale`), once more at the epoch the answer names. The handle never raises an
///   epoch, so it never fences off a dispatcher that drives the same operation;
/// - **names the operation and its node in every error** ([`HandleError`], [`SetError`]).
///
/// ```
/// use marie_actors::eo::{self, Identity, OperationHandle, Operation, OpContext, OpError, SetError, Step};
/// use marie_actors::property::{params, ParamDecl, ParamSchema, Value};
///
/// struct Pump;
/// impl Operation for Pump {
///     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
///     fn parameters(&self) -> ParamSchema {
///         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0)])
///     }
///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
/// }
///
/// # #[tokio::main(flavor = "current_thread")] async fn main() {
/// eo::spawn_operation(Pump, Default::default()).await.unwrap();
///
/// let pump = OperationHandle::lookup("pump").await.unwrap();
/// pump.set(params([("rate", Value::Float(2.5))])).await.unwrap();
/// assert_eq!(pump.value::<f64>("rate").await.unwrap(), 2.5);
///
/// // out of range: refused as a whole, each refused value listed, nothing changed
/// let refused = pump.set(params([("rate", Value::Float(99.0))])).await.unwrap_err();
/// assert!(matches!(&refused, SetError::Rejected { rejections, .. } if rejections[0].name == "rate"));
/// assert_eq!(pump.value::<f64>("rate").await.unwrap(), 2.5);
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct OperationHandle {
    /// The name or id it was looked up by.
    key: Arc<str>,
    /// The versions a replacement may have.
    versions: Option<VersionReq>,
    /// Deadline of each request.
    timeout: Duration,
    /// How long a call waits for a replacement of a gone instance.
    follow: Duration,
    /// The instance followed now, shared by clones (its client's timeout is not this
    /// handle's: `bound()` applies that).
    current: Arc<Mutex<Bound>>,
}

/// The instance a handle talks to.
#[derive(Clone, Debug)]
struct Bound {
    client: EoClient,
    /// The operation's name (also when looked up by id).
    name: String,
    node: String,
}

impl Bound {
    fn of(inst: Instance) -> Bound {
        Bound {
            client: EoClient::from_cell(inst.actor),
            name: inst.name,
            node: inst.node,
        }
    }

    fn id(&self) -> ActorId {
        self.client.actor().get_id()
    }

    /// The actor is known to have stopped (only a local actor's status tells).
    fn is_dead(&self) -> bool {
        matches!(
            self.client.actor().get_status(),
            ActorStatus::Stopping | ActorStatus::Stopped
        )
    }

    fn unexpected(&self, asked: &str, answer: impl std::fmt::Debug) -> HandleError {
        HandleError::Unexpected {
            operation: self.name.clone(),
            node: self.node.clone(),
            asked: asked.to_string(),
            answer: format!("{answer:?}"),
        }
    }
}

/// How one try of a call ended, short of an answer.
enum Attempt {
    /// The transport failed: a gone instance is followed, a timeout is reported.
    Eo(EoError),
    /// The instance answered, and the answer is an error.
    Answered(HandleError),
}

impl From<EoError> for Attempt {
    fn from(e: EoError) -> Self {
        Attempt::Eo(e)
    }
}

impl From<HandleError> for Attempt {
    fn from(e: HandleError) -> Self {
        Attempt::Answered(e)
    }
}

impl OperationHandle {
    /// Default deadline of each request, as [`EoClient`]'s; change it with
    /// [`OperationHandle::with_timeout`].
    ///
    /// ```
    /// use marie_actors::eo::OperationHandle;
    /// assert_eq!(OperationHandle::DEFAULT_TIMEOUT.as_secs(), 5);
    /// ```
    pub const DEFAULT_TIMEOUT: Duration = EoClient::DEFAULT_TIMEOUT;

    /// Default time a call waits for a new instance when its own is gone: long enough for a
    /// supervisor's restart with backoff, or for a node to start one on request. Change it
    /// with [`OperationHandle::following_for`].
    ///
    /// ```
    /// use marie_actors::eo::OperationHandle;
    /// assert_eq!(OperationHandle::DEFAULT_FOLLOW.as_secs(), 5);
    /// ```
    pub const DEFAULT_FOLLOW: Duration = Duration::from_secs(5);

    /// A handle to the first live instance of the operation named (or numbered)
    /// `name_or_id`, as [`registry::lookup`] orders them (local instances first). Returns at
    /// once: [`HandleError::NotFound`] when none runs.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// use marie_actors::eo::{HandleError, OperationHandle};
    /// eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let by_name = OperationHandle::lookup("pump").await.unwrap();
    /// let by_id = OperationHandle::lookup("7101").await.unwrap();
    /// assert_eq!(by_name.actor().get_id(), by_id.actor().get_id());
    /// assert!(matches!(
    ///     OperationHandle::lookup("kettle").await,
    ///     Err(HandleError::NotFound { .. })
    /// ));
    /// # }
    /// ```
    pub async fn lookup(name_or_id: &str) -> Result<OperationHandle, HandleError> {
        Self::find(name_or_id, None).await
    }

    /// Like [`OperationHandle::lookup`], the first live instance whose version meets
    /// `versions` (each instance is asked its identity, in registry order). A replacement
    /// must meet it too.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump(&'static str);
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, self.0, "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// use marie_actors::eo::OperationHandle;
    /// use semver::VersionReq;
    /// eo::spawn_operation(Pump("1.2.0"), Default::default()).await.unwrap();
    /// eo::spawn_operation(Pump("2.0.1"), Default::default()).await.unwrap();
    /// let v2 = OperationHandle::lookup_version("pump", VersionReq::parse("^2").unwrap())
    ///     .await
    ///     .unwrap();
    /// assert_eq!(v2.identity().await.unwrap().version.to_string(), "2.0.1");
    /// assert!(OperationHandle::lookup_version("pump", VersionReq::parse("^3").unwrap())
    ///     .await
    ///     .is_err());
    /// # }
    /// ```
    pub async fn lookup_version(
        name: &str,
        versions: VersionReq,
    ) -> Result<OperationHandle, HandleError> {
        Self::find(name, Some(versions)).await
    }

    async fn find(key: &str, versions: Option<VersionReq>) -> Result<OperationHandle, HandleError> {
        let key = key.trim();
        let timeout = Self::DEFAULT_TIMEOUT;
        for inst in registry::lookup(ModuleKind::Operation, key) {
            if fits(&inst, versions.as_ref(), timeout).await {
                return Ok(OperationHandle {
                    key: key.into(),
                    versions,
                    timeout,
                    follow: Self::DEFAULT_FOLLOW,
                    current: Arc::new(Mutex::new(Bound::of(inst))),
                });
            }
        }
        Err(HandleError::NotFound {
            operation: key.to_string(),
            requirement: versions.map(|v| v.to_string()),
        })
    }

    /// Use `timeout` as the deadline of each request (default
    /// [`OperationHandle::DEFAULT_TIMEOUT`]).
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// use marie_actors::eo::OperationHandle;
    /// use std::time::Duration;
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = OperationHandle::lookup("pump").await.unwrap().with_timeout(Duration::from_millis(500));
    /// assert!(pump.general().await.is_ok());
    /// # }
    /// ```
    pub fn with_timeout(mut self, timeout: Duration) -> OperationHandle {
        self.timeout = timeout;
        self
    }

    /// Wait at most `wait` for a new instance when the followed one is gone (default
    /// [`OperationHandle::DEFAULT_FOLLOW`]); past it, a call fails with
    /// [`HandleError::Gone`].
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// use marie_actors::eo::{HandleError, OperationHandle};
    /// use std::time::Duration;
    /// let (actor, done) = eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = OperationHandle::lookup("pump").await.unwrap()
    ///     .following_for(Duration::from_millis(100));
    /// actor.stop(None);
    /// done.await.unwrap();
    /// // nobody restarts it
    /// let gone = pump.general().await.unwrap_err();
    /// assert!(matches!(gone, HandleError::Gone { .. }));
    /// assert_eq!(
    ///     gone.to_string(),
    ///     "operation `pump` on node `local` is gone, and no instance took its place within 100 ms"
    /// );
    /// # }
    /// ```
    pub fn following_for(mut self, wait: Duration) -> OperationHandle {
        self.follow = wait;
        self
    }

    /// The operation's name (also when it was looked up by id).
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("7101").await.unwrap();
    /// assert_eq!(pump.name(), "pump");
    /// # }
    /// ```
    pub fn name(&self) -> String {
        self.bound().name
    }

    /// The node of the instance followed now ([`registry::local_node_name`] for one in
    /// this process).
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.node(), marie_actors::registry::local_node_name());
    /// # }
    /// ```
    pub fn node(&self) -> String {
        self.bound().node
    }

    /// The actor of the instance followed now; it changes when the handle follows a restart.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// let (actor, _) = eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.actor().get_id(), actor.get_id());
    /// # }
    /// ```
    pub fn actor(&self) -> ActorRef<EoMsg> {
        self.bound().client.actor().clone()
    }

    /// An [`EoClient`] for the instance followed now, for what the handle does not offer
    /// (activation, fault injection). It does not follow restarts.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::flags::StatusFlags;
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Finish(StatusFlags(0))) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// let done = pump.client().activate(Default::default(), 0).unwrap();
    /// assert!(matches!(done.await.unwrap(), eo::EoReport::Finished { .. }));
    /// # }
    /// ```
    pub fn client(&self) -> EoClient {
        self.bound().client
    }

    /// Who the operation is: name, id, version, description.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.identity().await.unwrap(), Identity::new("pump", 7101, "1.2.0", "pumps"));
    /// # }
    /// ```
    pub async fn identity(&self) -> Result<Identity, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::Identification))
                .await?
            {
                PropertyReply::Identification(i) => Ok(Identity {
                    name: i.name.to_string(),
                    id: i.id,
                    version: semver::Version::parse(&i.version)
                        .map_err(|_| bound.unexpected("its identity", &i))?,
                    description: i.description.to_string(),
                }),
                other => Err(bound.unexpected("its identity", other).into()),
            }
        })
        .await
    }

    /// The parameters it declares: names, types, defaults, ranges.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// let schema = pump.schema().await.unwrap();
    /// assert_eq!(schema.params[0].name, "rate");
    /// assert_eq!(schema.params[0].max, Some(10.0));
    /// # }
    /// ```
    pub async fn schema(&self) -> Result<ParamSchema, HandleError> {
        Ok(ParamSchema::new(self.specific().await?.params))
    }

    /// The status flags it can raise, in bit order.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::flags::FlagDecl;
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn flags(&self) -> Vec<FlagDecl> { vec![FlagDecl::new("primed", "pressure reached")] }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.flags().await.unwrap()[0].name, "primed");
    /// # }
    /// ```
    pub async fn flags(&self) -> Result<Vec<FlagDecl>, HandleError> {
        Ok(self.specific().await?.flags)
    }

    async fn specific(&self) -> Result<Specific, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::Specific))
                .await?
            {
                PropertyReply::Specific(s) => Ok(s),
                other => Err(bound.unexpected("its parameter declarations", other).into()),
            }
        })
        .await
    }

    /// Its general properties: up-time, whether an activation runs, how many ran, its
    /// epoch, its declared deadline.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// let general = pump.general().await.unwrap();
    /// assert!(!general.in_use);
    /// assert_eq!(general.activations, 0);
    /// # }
    /// ```
    pub async fn general(&self) -> Result<General, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::General))
                .await?
            {
                PropertyReply::General(g) => Ok(g),
                other => Err(bound.unexpected("its general properties", other).into()),
            }
        })
        .await
    }

    /// Every parameter's current value.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::property::{ParamDecl, ParamSchema, Value};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.current().await.unwrap()["rate"], Value::Float(1.0));
    /// # }
    /// ```
    pub async fn current(&self) -> Result<ParamMap, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Collection(Collection::Current))
                .await?
            {
                PropertyReply::Current(values) => Ok(values),
                other => Err(bound.unexpected("its current values", other).into()),
            }
        })
        .await
    }

    /// The current value of the parameter `key` names, of the key's type — the typed form
    /// of [`OperationHandle::value`].
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// use marie_actors::prelude::*;
    /// params! {
    ///     struct PumpParams {
    ///         /// litres per minute
    ///         rate: f64 = 1.0, range(0.0, 10.0);
    ///     }
    /// }
    /// struct Pump;
    /// impl Operation for Pump {
    ///     fn identity(&self) -> Identity { Identity::new("typed-pump", 7102, "1.0.0", "pumps") }
    ///     fn parameters(&self) -> ParamSchema { PumpParams::schema() }
    ///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = eo::OperationHandle::lookup("typed-pump").await.unwrap();
    /// pump.set(ParamMap::new().with(PumpParams::rate(), 2.5)).await.unwrap();
    /// let rate: f64 = pump.param(PumpParams::rate()).await.unwrap();
    /// assert_eq!(rate, 2.5);
    /// # }
    /// ```
    pub async fn param<T: crate::declare::ParamValue>(
        &self,
        key: crate::declare::Param<T>,
    ) -> Result<T, HandleError> {
        self.value::<T>(key.name()).await
    }

    /// The current value of parameter `name`, as a `T`: [`HandleError::NoParameter`] if it
    /// declares none of that name, [`HandleError::WrongType`] if it is no `T`.
    ///
    /// With a parameter declared by [`params!`](crate::params), [`OperationHandle::param`]
    /// takes its typed key instead: a typo is then a compile error.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0), ParamDecl::text("fluid", "water")])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// use marie_actors::eo::{HandleError, OperationHandle};
    /// let pump = OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.value::<f64>("rate").await.unwrap(), 1.0);
    /// assert_eq!(pump.value::<String>("fluid").await.unwrap(), "water");
    /// assert!(matches!(pump.value::<bool>("rate").await, Err(HandleError::WrongType { .. })));
    /// assert!(matches!(pump.value::<f64>("speed").await, Err(HandleError::NoParameter { .. })));
    /// # }
    /// ```
    pub async fn value<T: FromValue>(&self, name: &str) -> Result<T, HandleError> {
        let asked = format!("param.{name}");
        self.call(|bound| {
            let asked = asked.clone();
            async move {
                match bound.client.property(PropertyRequest::Get(asked)).await? {
                    PropertyReply::Value(v) => Ok(typed(&bound, name, v)?),
                    PropertyReply::NotFound(_) => Err(HandleError::NoParameter {
                        operation: bound.name.clone(),
                        node: bound.node.clone(),
                        name: name.to_string(),
                    }
                    .into()),
                    other => Err(bound
                        .unexpected(&format!("parameter `{name}`"), other)
                        .into()),
                }
            }
        })
        .await
    }

    /// Property `name` as a `T`: a standard one ([`crate::property::STANDARD_PROPERTIES`]:
    /// `uptime_ms`, `in_use`, ...), `param.NAME`, or one the operation adds
    /// ([`super::Operation::property`]). [`HandleError::NoProperty`] if it has none of that
    /// name.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::property::Value;
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn property(&self, name: &str) -> Option<Value> { (name == "litres").then_some(Value::Float(0.0)) }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.property::<f64>("litres").await.unwrap(), 0.0);
    /// assert_eq!(pump.property::<String>("version").await.unwrap(), "1.2.0");
    /// assert!(!pump.property::<bool>("in_use").await.unwrap());
    /// # }
    /// ```
    pub async fn property<T: FromValue>(&self, name: &str) -> Result<T, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Get(name.to_string()))
                .await?
            {
                PropertyReply::Value(v) => Ok(typed(&bound, name, v)?),
                PropertyReply::NotFound(_) => Err(HandleError::NoProperty {
                    operation: bound.name.clone(),
                    node: bound.node.clone(),
                    name: name.to_string(),
                }
                .into()),
                other => Err(bound
                    .unexpected(&format!("property `{name}`"), other)
                    .into()),
            }
        })
        .await
    }

    /// Change parameters: all of `values` or none. Refused values come back as
    /// [`SetError::Rejected`], one [`crate::property::Rejection`] each, and nothing changed.
    ///
    /// The command goes at the instance's current epoch, read just before (see
    /// [`OperationHandle`]); answered `Stale` — a dispatcher raised the epoch in between — it is sent
    /// once more at the epoch the answer names, then [`SetError::Superseded`].
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_actors::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0), ParamDecl::int("stages", 1)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// use marie_actors::eo::{OperationHandle, SetError};
    /// use marie_actors::property::{params, RejectReason, Value};
    /// let pump = OperationHandle::lookup("pump").await.unwrap();
    /// pump.set(params([("rate", Value::Float(4.0)), ("stages", Value::Int(2))])).await.unwrap();
    ///
    /// let Err(SetError::Rejected { rejections, .. }) =
    ///     pump.set(params([("rate", Value::Float(12.0)), ("stages", Value::Int(3))])).await
    /// else { panic!("a rate of 12 is out of range") };
    /// assert_eq!(rejections.len(), 1);
    /// assert_eq!(rejections[0].name, "rate");
    /// assert!(matches!(rejections[0].reason, RejectReason::OutOfRange { .. }));
    /// assert_eq!(pump.value::<i64>("stages").await.unwrap(), 2, "nothing changed");
    /// # }
    /// ```
    pub async fn set(&self, values: ParamMap) -> Result<(), SetError> {
        self.call(|bound| {
            let values = values.clone();
            async move { set_at_current_epoch(&bound, values).await }
        })
        .await?
    }

    /// The instance followed now, its client with this handle's timeout.
    fn bound(&self) -> Bound {
        let current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        self.with_own_timeout(&current)
    }

    fn with_own_timeout(&self, bound: &Bound) -> Bound {
        Bound {
            client: bound.client.clone().with_timeout(self.timeout),
            ..bound.clone()
        }
    }

    /// Run `request` on the instance followed now; if that instance is gone (dead before
    /// the call, or the call finds it gone), follow the operation to a new instance and run
    /// `request` there. The operation is followed once per call: a replacement that is gone
    /// too ends the call ([`HandleError::GoneAgain`]).
    async fn call<T, F, Fut>(&self, request: F) -> Result<T, HandleError>
    where
        F: Fn(Bound) -> Fut,
        Fut: Future<Output = Result<T, Attempt>>,
    {
        let mut bound = self.bound();
        let mut followed = false;
        if bound.is_dead() {
            bound = self.follow(&bound).await?;
            followed = true;
        }
        match request(bound.clone()).await {
            Ok(v) => Ok(v),
            Err(Attempt::Eo(EoError::Gone(_))) if !followed => {
                let next = self.follow(&bound).await?;
                request(next.clone())
                    .await
                    .map_err(|e| self.failure(&next, e))
            }
            Err(e) => Err(self.failure(&bound, e)),
        }
    }

    /// The error of a try on `bound` that will not be retried: `bound` is an instance the
    /// call has already followed the operation to, if the try found it gone.
    fn failure(&self, bound: &Bound, attempt: Attempt) -> HandleError {
        match attempt {
            Attempt::Answered(e) => e,
            Attempt::Eo(EoError::Timeout(_, after)) => HandleError::Timeout {
                operation: bound.name.clone(),
                node: bound.node.clone(),
                after,
            },
            Attempt::Eo(EoError::Gone(_)) => HandleError::GoneAgain {
                operation: bound.name.clone(),
                node: bound.node.clone(),
            },
        }
    }

    /// `lost` is gone: take the instance another clone already moved to, or the first
    /// instance of the operation (other than `lost`, meeting the version requirement) in
    /// the registry now or within the follow time.
    async fn follow(&self, lost: &Bound) -> Result<Bound, HandleError> {
        let dead = lost.id();
        {
            let now = self.bound();
            if now.id() != dead && !now.is_dead() {
                return Ok(now);
            }
        }
        let gone = || HandleError::Gone {
            operation: lost.name.clone(),
            node: lost.node.clone(),
            waited: self.follow,
        };
        let deadline = Instant::now() + self.follow;
        // watch first, then look: an instance that joins in between is in one or the other
        let mut watch = registry::watch(Some(ModuleKind::Operation))
            .await
            .map_err(|e| HandleError::Registry {
                operation: lost.name.clone(),
                reason: e.to_string(),
            })?;
        for inst in registry::lookup(ModuleKind::Operation, &self.key) {
            if self.may_take(&inst, &dead, deadline).await {
                return Ok(self.adopt(inst, lost));
            }
        }
        loop {
            let event = tokio::time::timeout_at(deadline, watch.next())
                .await
                .map_err(|_| gone())?;
            match event {
                Some(RegistryEvent::Joined(inst))
                    if (inst.name == *self.key || inst.id.to_string() == *self.key)
                        && self.may_take(&inst, &dead, deadline).await =>
                {
                    return Ok(self.adopt(inst, lost));
                }
                Some(_) => {}
                None => return Err(gone()),
            }
        }
    }

    /// `inst` may replace the instance `dead`: it is another, alive, of a fitting version.
    async fn may_take(&self, inst: &Instance, dead: &ActorId, deadline: Instant) -> bool {
        if inst.actor.get_id() == *dead
            || matches!(
                inst.actor.get_status(),
                ActorStatus::Stopping | ActorStatus::Stopped
            )
        {
            return false;
        }
        let left = deadline.saturating_duration_since(Instant::now());
        fits(inst, self.versions.as_ref(), self.timeout.min(left)).await
    }

    /// Follow `inst` from now on (unless another clone already moved on from `lost`).
    fn adopt(&self, inst: Instance, lost: &Bound) -> Bound {
        let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        if current.id() == lost.id() {
            *current = Bound::of(inst);
            tracing::debug!(
                op = %current.name, from = %lost.id(), to = %current.id(), node = %current.node,
                "operation handle follows a new instance"
            );
        }
        self.with_own_timeout(&current)
    }
}

/// `inst` meets `versions` (asked within `timeout`); any instance when there is none.
async fn fits(inst: &Instance, versions: Option<&VersionReq>, timeout: Duration) -> bool {
    let Some(versions) = versions else {
        return true;
    };
    let client =
        EoClient::from_cell(inst.actor.clone()).with_timeout(timeout.max(Duration::from_millis(1)));
    match client
        .property(PropertyRequest::Group(Group::Identification))
        .await
    {
        Ok(PropertyReply::Identification(i)) => {
            semver::Version::parse(&i.version).is_ok_and(|v| versions.matches(&v))
        }
        _ => false,
    }
}

/// `value` (of `name`) as a `T`, or the error naming what it is instead.
fn typed<T: FromValue>(bound: &Bound, name: &str, value: Value) -> Result<T, HandleError> {
    T::from_value(&value).ok_or_else(|| HandleError::WrongType {
        operation: bound.name.clone(),
        node: bound.node.clone(),
        name: name.to_string(),
        expected: T::EXPECTED,
        got: value,
    })
}

/// Read the instance's epoch, parameterize at it; if it moved on in between, once more at
/// the epoch the answer names.
async fn set_at_current_epoch(
    bound: &Bound,
    values: ParamMap,
) -> Result<Result<(), SetError>, Attempt> {
    let mut epoch = match bound
        .client
        .property(PropertyRequest::Get("epoch".into()))
        .await?
    {
        PropertyReply::Value(Value::Int(e)) => u64::try_from(e).unwrap_or(0),
        other => return Err(bound.unexpected("its epoch", other).into()),
    };
    for _ in 0..2 {
        match bound.client.parameterize(values.clone(), epoch).await? {
            ParamOutcome::Applied => return Ok(Ok(())),
            ParamOutcome::Rejected(rejections) => {
                return Ok(Err(SetError::Rejected {
                    operation: bound.name.clone(),
                    node: bound.node.clone(),
                    rejections,
                }))
            }
            ParamOutcome::Stale { current } => epoch = current,
        }
    }
    Ok(Err(SetError::Superseded {
        operation: bound.name.clone(),
        node: bound.node.clone(),
        epoch,
    }))
}

//! An operation handle: an embedder's typed, epoch-free hold on an operation by name, across
//! restarts of its instances.
//!
//! Why a second client: [`EoClient`] is the interface as the dispatcher speaks it — one
//! actor, commands under an explicit epoch (a wrong guess is answered `Stale` and changes
//! nothing), property answers as an 11-variant [`PropertyReply`](marie_vocabulary::property::PropertyReply), errors that name an actor
//! id, and a client that is useless once its actor died. An application that only wants to
//! read and set an operation's parameters needs none of that; [`OperationHandle`] says what
//! it does instead.

mod follow;
mod read;
mod set;

use follow::{fits, Bound};

use super::client::EoClient;
use super::handle_error::HandleError;
use super::messages::EoMsg;
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::ActorRef;
use semver::VersionReq;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A typed hold on an operation by name that follows its restarts. Cheap to clone; clones
/// share the instance they follow. The handle:
///
/// - **finds the operation by name** (or numeric id, optionally a version requirement) in
///   the registry, taking the first live instance, as the registry orders them (local first);
/// - **follows restarts**: when its instance is gone — a call fails because the actor
///   stopped, or it is already dead when a call starts — it waits (bounded,
///   [`OperationHandle::DEFAULT_FOLLOW`]) for an instance of the same operation to be in the
///   registry (a supervisor's restart, a spare; [`marie_vocabulary::registry::watch`] so nothing is
///   polled) and retries the call there once. This is the dispatcher's rebind in miniature,
///   without its selection and restoring: a replacement starts with its own start-up
///   parameters, and the handle does not replay earlier [`set`](OperationHandle::set)s.
///   Across nodes ractor_cluster usually answers a request that timed out as if its actor
///   had died, so a hung remote instance is left like a gone one: the call waits for
///   another instance instead of reporting a [`HandleError::Timeout`];
/// - **answers in types**: [`Identity`](super::Identity), [`ParamSchema`](marie_vocabulary::property::ParamSchema),
///   [`FlagDecl`](marie_vocabulary::status::FlagDecl)s, [`General`](marie_vocabulary::property::General), a
///   parameter as any [`FromValue`](marie_vocabulary::property::FromValue) type;
/// - **keeps epochs inside**: [`set`](OperationHandle::set) reads the instance's current
///   epoch and commands at exactly that epoch — the host refuses only an epoch *below* its
///   current one ([`marie_vocabulary::fence`]) — and if a dispatcher raised it in between (the answer
///   is `Stale`), once more at the epoch the answer names. The handle never raises an
///   epoch, so it never fences off a dispatcher that drives the same operation;
/// - **names the operation and its node in every error** ([`HandleError`], [`SetError`](super::SetError)).
///
/// ```
/// use marie_actors::eo::{self, Identity, OperationHandle, Operation, OpContext, OpError, SetError, Step};
/// use marie_vocabulary::property::{param_map, ParamDecl, ParamSchema, Value};
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
/// pump.set(param_map([("rate", Value::Float(2.5))])).await.unwrap();
/// assert_eq!(pump.value::<f64>("rate").await.unwrap(), 2.5);
///
/// // out of range: refused as a whole, each refused value listed, nothing changed
/// let refused = pump.set(param_map([("rate", Value::Float(99.0))])).await.unwrap_err();
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
    /// assert_eq!(pump.node(), marie_vocabulary::registry::local_node_name());
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
    /// # use marie_vocabulary::status::StatusFlags;
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
}

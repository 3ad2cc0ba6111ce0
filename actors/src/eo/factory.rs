//! Operations as factories: each call starts a fresh instance (new state, new actor), which
//! is what a supervisor needs to restart a crashed operation and what a node needs to host
//! the operations its config names — by name and version — without knowing them.
//!
//! Three ways to say how an instance is built, so an application can hand its operations
//! what they need (a driver handle, a channel, its configuration) instead of leaving them
//! to find it by a global name:
//!
//! - [`OperationFactory::new`] / [`OperationFactory::of`]: `O::default()`, the easy path;
//! - [`OperationFactory::from_fn`]: a closure the application writes, called once per
//!   instance (`|| Pump::new(driver.clone())`);
//! - [`OperationFactory::from_value`]: a value cloned per instance.
//!
//! A factory is a closure in *this* process: code is never shipped over the network. Each
//! node process builds its instances from the factories its own program registered, so a
//! node can host — and start on another node's request — only the operations its own
//! catalogue has; a node config that names any other is refused at start.
//!
//! ```
//! use marie_actors::eo::{Identity, OpContext, OpError, Operation, OperationFactory, Step};
//! use std::sync::Arc;
//!
//! /// What the application hands its operation: here, where the pump's litres go.
//! struct Tank(std::sync::atomic::AtomicU64);
//!
//! struct Pump { tank: Arc<Tank> }
//! impl Operation for Pump {
//!     fn identity(&self) -> Identity { Identity::new("f-pump", 4501, "1.0.0", "pumps") }
//!     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
//!         self.tank.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
//!         Ok(Step::Continue)
//!     }
//! }
//!
//! let tank = Arc::new(Tank(0.into()));
//! let factory = OperationFactory::from_fn(move || Pump { tank: tank.clone() });
//! assert_eq!((factory.name, factory.version.as_str()), ("f-pump", "1.0.0"));
//! assert!(factory.check_declaration().is_ok());
//! ```

use super::{
    check_declaration, spawn_operation, spawn_operation_linked, DeclarationError, Declared,
    HostOptions, Operation,
};
use ractor::{ActorCell, SpawnErr};
use std::future::Future;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::pin::Pin;
use std::sync::Arc;

/// A function that starts one operation instance in a host linked to the given supervisor.
pub type StartOperation = Arc<
    dyn Fn(
            HostOptions,
            Option<ActorCell>,
        ) -> Pin<Box<dyn Future<Output = Result<ActorCell, SpawnErr>> + Send>>
        + Send
        + Sync,
>;

/// Builds one instance of an operation (the application's closure, shared by every start).
type Make<O> = Arc<dyn Fn() -> O + Send + Sync>;

/// How to start instances of one operation: each call starts a fresh one (new state, new
/// actor), which is what a supervisor needs to restart a crashed operation.
#[derive(Clone)]
pub struct OperationFactory {
    /// The operation's registry name.
    pub name: &'static str,
    /// Its version (two versions of one operation have two factories).
    pub version: String,
    /// Start an instance: hosted with these options, linked to the supervisor if given.
    pub start: StartOperation,
    /// Build one instance the way [`OperationFactory::start`] does and check what it
    /// declares.
    check: Arc<dyn Fn() -> Result<(), DeclarationError> + Send + Sync>,
    /// Build one instance and read what it declares.
    declared: Arc<dyn Fn() -> Option<Declared> + Send + Sync>,
}

impl OperationFactory {
    /// The factory of operations built by `O::default()`, registered under `name`.
    pub fn of<O: Operation + Default>(name: &'static str) -> OperationFactory {
        let version = O::default().identity().version.to_string();
        OperationFactory::built(name, version, Arc::new(O::default))
    }

    /// The factory of operations built by `O::default()`, named as `O` names itself
    /// ([`Operation::identity`]).
    pub fn new<O: Operation + Default>() -> OperationFactory {
        OperationFactory::of::<O>(intern(&O::default().identity().name))
    }

    /// The factory of operations built by `make`, called once for every instance started
    /// — at the node's start, and again for each restart after a crash — so whatever it
    /// captures (a driver handle, a channel, a configuration) reaches every instance. Named
    /// and versioned as the operation says ([`Operation::identity`]): `make` is called once
    /// now to ask.
    ///
    /// A `make` that panics fails that start (`SpawnErr::StartupFailed`, which a
    /// supervisor counts as a failed restart); it does not take the supervisor down.
    pub fn from_fn<O, F>(make: F) -> OperationFactory
    where
        O: Operation,
        F: Fn() -> O + Send + Sync + 'static,
    {
        let identity = make().identity();
        OperationFactory::built(
            intern(&identity.name),
            identity.version.to_string(),
            Arc::new(make),
        )
    }

    /// The factory of operations cloned from `op`: every instance starts as a copy of it
    /// (what it holds — e.g. an `Arc` to a shared resource — is cloned per instance, never
    /// moved away). Named and versioned as `op` says.
    pub fn from_value<O: Operation + Clone>(op: O) -> OperationFactory {
        // a Mutex makes the prototype shareable by the factory's threads without asking
        // `O: Sync` of the application; it is locked only while cloning
        let prototype = std::sync::Mutex::new(op);
        OperationFactory::from_fn(move || {
            prototype.lock().unwrap_or_else(|e| e.into_inner()).clone()
        })
    }

    /// A factory whose instances `make` builds.
    fn built<O: Operation>(name: &'static str, version: String, make: Make<O>) -> Self {
        let for_check = make.clone();
        let for_declared = make.clone();
        let checked_version = version.clone();
        OperationFactory {
            name,
            version,
            start: Arc::new(move |options, supervisor| {
                let make = make.clone();
                Box::pin(async move {
                    let op = build(name, &*make).map_err(SpawnErr::StartupFailed)?;
                    let actor = match supervisor {
                        Some(sup) => spawn_operation_linked(op, options, sup).await?.0,
                        None => spawn_operation(op, options).await?.0,
                    };
                    Ok(actor.get_cell())
                })
            }),
            check: Arc::new(move || match build(name, &*for_check) {
                Ok(op) => check_declaration(&op),
                Err(e) => Err(DeclarationError {
                    operation: name.to_string(),
                    version: checked_version.clone(),
                    problems: vec![e.to_string()],
                }),
            }),
            declared: Arc::new(move || {
                build(name, &*for_declared).ok().map(|op| Declared::of(&op))
            }),
        }
    }

    /// What the operation declares (identity, parameters, flags, migrations), read from one
    /// instance built the way every start builds it (`None` if that build panics).
    pub fn declared(&self) -> Option<Declared> {
        (self.declared)()
    }

    /// Build one instance the way every start does and check its declarations
    /// ([`check_declaration`]): what a node's builder does for each factory before anything
    /// starts, so a bad declaration is refused naming the operation instead of failing
    /// each instance's start.
    pub fn check_declaration(&self) -> Result<(), DeclarationError> {
        (self.check)()
    }

    /// The operation's version, parsed (a factory built by [`OperationFactory::of`] always has
    /// a valid one).
    pub fn semver(&self) -> Option<semver::Version> {
        semver::Version::parse(&self.version).ok()
    }

    /// A child id unique among the factories: `name@version`.
    pub fn key(&self) -> String {
        format!("{}@{}", self.name, self.version)
    }
}

/// Why an application's `make` gave no instance.
#[derive(Debug, thiserror::Error)]
#[error("the factory of operation `{operation}` panicked: {message}")]
struct FactoryPanicked {
    operation: &'static str,
    message: String,
}

/// Call `make`, a panic turned into an error (it must not unwind into whoever starts the
/// instance: a supervisor's restart loop).
fn build<O>(
    name: &'static str,
    make: &(dyn Fn() -> O + Send + Sync),
) -> Result<O, ractor::ActorProcessingErr> {
    catch_unwind(AssertUnwindSafe(make)).map_err(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "(no message)".to_string());
        Box::new(FactoryPanicked {
            operation: name,
            message,
        }) as ractor::ActorProcessingErr
    })
}

/// `name` as a `&'static str`: a factory's name is static, and an operation type named at
/// run time is kept once per distinct name (a handful per application).
fn intern(name: &str) -> &'static str {
    static NAMES: std::sync::Mutex<std::collections::BTreeSet<&'static str>> =
        std::sync::Mutex::new(std::collections::BTreeSet::new());
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    match names.get(name) {
        Some(known) => known,
        None => {
            let leaked: &'static str = Box::leak(name.to_string().into_boxed_str());
            names.insert(leaked);
            leaked
        }
    }
}

impl std::fmt::Debug for OperationFactory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OperationFactory")
            .field("name", &self.name)
            .field("version", &self.version)
            .finish_non_exhaustive()
    }
}

//! Operations as factories: each call starts a fresh instance (new state, new actor), which
//! is what a supervisor needs to restart a crashed operation and what a node needs to host
//! the operations its config names — by name and version — without knowing them.

use super::{spawn_operation, spawn_operation_linked, HostOptions, Operation};
use ractor::{ActorCell, SpawnErr};
use std::future::Future;
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
}

impl OperationFactory {
    /// The factory of operations built by `O::default()`.
    pub fn of<O: Operation + Default>(name: &'static str) -> OperationFactory {
        OperationFactory {
            name,
            version: O::default().identity().version.to_string(),
            start: Arc::new(|options, supervisor| {
                Box::pin(async move {
                    let op = O::default();
                    let actor = match supervisor {
                        Some(sup) => spawn_operation_linked(op, options, sup).await?.0,
                        None => spawn_operation(op, options).await?.0,
                    };
                    Ok(actor.get_cell())
                })
            }),
        }
    }

    /// The factory of operations built by `O::default()`, named as `O` names itself
    /// ([`Operation::identity`]).
    pub fn new<O: Operation + Default>() -> OperationFactory {
        OperationFactory::of::<O>(intern(&O::default().identity().name))
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

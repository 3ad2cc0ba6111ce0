//! What an operation author implements.

use crate::declare::{DeclaredParams, DmName, Param, ParamError, ParamValue};
use marie_dm::DmError;
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::property::{ParamMap, ParamSchema, Value};
use marie_vocabulary::registry::ModuleKind;
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use serde::{Deserialize, Serialize};
use std::future::Future;
use std::time::Duration;

/// Who an operation is: the thesis' identification group.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// Module name, a word such as `wall-follower` (letters, digits, `-`, `_`, `.`).
    pub name: String,
    /// Numeric id, e.g. 1512. Several versions of one operation share name and id.
    pub id: u32,
    /// Semantic version.
    pub version: semver::Version,
    /// One line about what it does.
    pub description: String,
}

impl Identity {
    /// An identity; `version` must be a semantic version such as `1.2.0`.
    ///
    /// # Panics
    /// On a malformed version: identities are written in code, so this is a programming error
    /// caught by the first test that spawns the operation.
    pub fn new(name: &str, id: u32, version: &str, description: &str) -> Self {
        Identity {
            name: name.to_string(),
            id,
            version: semver::Version::parse(version)
                .unwrap_or_else(|e| panic!("operation {name}: bad version {version:?}: {e}")),
            description: description.to_string(),
        }
    }
}

/// What a step (or an activation) decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Keep running: the host calls `step` again after [`Operation::period`].
    Continue,
    /// The task is done: report these flags (in the operation's own bit order, added to those
    /// raised with [`OpContext::raise`]) and suspend.
    Finish(StatusFlags),
}

impl Step {
    /// [`Step::Finish`] with `flags`: a [`StatusFlags`] word or a flag declared with
    /// [`flags!`](crate::flags!) (`Step::finish(CollatzFlag::ReachedOne)`).
    pub fn finish(flags: impl Into<StatusFlags>) -> Step {
        Step::Finish(flags.into())
    }
}

/// Why an operation could not go on. The host reports it to the dispatcher as a failure (a
/// panic, by contrast, crashes the host and is a matter for its supervisor).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OpError {
    /// The operation's own judgement.
    #[error("{0}")]
    Failed(String),
    /// A parameter was missing or of an unexpected type (a declaration bug).
    #[error("parameter {name}: {problem}")]
    Param {
        /// Parameter name.
        name: String,
        /// What is wrong.
        problem: String,
    },
    /// A datamanager could not be reached or refused a request.
    #[error("datamanager {dm}: {problem}")]
    Datamanager {
        /// Datamanager name.
        dm: String,
        /// What went wrong.
        problem: String,
    },
    /// Another module the operation needs (a hardware module such as the cart) could not
    /// be reached. When the module is gone from the registry (its node lost, or cut off
    /// from this one), or was absent at the call (`absent`), the host holds the
    /// operation's steps until it is back, as for a datamanager
    /// ([`DATAMANAGER_RETURN`](super::DATAMANAGER_RETURN)), instead of failing the
    /// activation at once.
    #[error("{problem}")]
    Unreachable {
        /// What kind of module.
        kind: ModuleKind,
        /// Its registry name.
        module: String,
        /// What went wrong.
        problem: String,
        /// Whether the module was absent at the call: none was published, or the instance
        /// called stopped before it answered (its node lost or cut off mid-call). The host
        /// then waits for the next instance even if one is published by the time it looks
        /// — the look comes after the call, and a node cut off for a few seconds is back
        /// by the end of a call's deadline —; the wait ends at once if it is.
        absent: bool,
    },
}

impl OpError {
    /// An operation-specific failure.
    pub fn failed(msg: impl Into<String>) -> Self {
        OpError::Failed(msg.into())
    }

    /// A module `kind` named `module` could not be reached: `problem` says how. Use
    /// [`OpError::absent`] when the module is known to have been absent at the call.
    pub fn unreachable(
        kind: ModuleKind,
        module: impl Into<String>,
        problem: impl Into<String>,
    ) -> Self {
        OpError::Unreachable {
            kind,
            module: module.into(),
            problem: problem.into(),
            absent: false,
        }
    }

    /// A module `kind` named `module` was absent at the call (none published, or the
    /// instance called stopped before it answered): the host waits for its next instance
    /// and steps again — at once if one is published by the time it looks.
    ///
    /// ```
    /// use marie_actors::eo::OpError;
    /// use marie_vocabulary::registry::ModuleKind;
    ///
    /// let e = OpError::absent(ModuleKind::Hardware, "cart", "the virtual cart was lost");
    /// assert!(e.is_absent());
    /// assert!(!OpError::unreachable(ModuleKind::Hardware, "cart", "no answer").is_absent());
    /// ```
    pub fn absent(kind: ModuleKind, module: impl Into<String>, problem: impl Into<String>) -> Self {
        OpError::Unreachable {
            kind,
            module: module.into(),
            problem: problem.into(),
            absent: true,
        }
    }

    /// Datamanager `dm`'s error `e`: [`OpError::Unreachable`] when it says the datamanager
    /// was absent (none registered, its actor gone) — the host then waits for it even if a
    /// new leader is published by the time it looks (an election between the failed call
    /// and the look), and steps again —, [`OpError::Datamanager`] otherwise. The words are
    /// the same either way: `datamanager DM: PROBLEM`.
    pub fn of_dm(dm: impl Into<String>, e: &DmError) -> Self {
        let dm = dm.into();
        match e {
            DmError::NotRegistered(_) | DmError::Unreachable(_) => OpError::Unreachable {
                kind: ModuleKind::Datamanager,
                problem: format!("datamanager {dm}: {e}"),
                module: dm,
                absent: true,
            },
            _ => OpError::Datamanager {
                dm,
                problem: e.to_string(),
            },
        }
    }

    /// Whether it says a module was absent when the operation called it
    /// ([`OpError::absent`], a datamanager's [`OpError::of_dm`]).
    pub fn is_absent(&self) -> bool {
        matches!(self, OpError::Unreachable { absent: true, .. })
    }

    /// The datamanager it names, for a datamanager's error.
    pub fn datamanager(&self) -> Option<&str> {
        match self {
            OpError::Datamanager { dm, .. } => Some(dm),
            OpError::Unreachable {
                kind: ModuleKind::Datamanager,
                module,
                ..
            } => Some(module),
            _ => None,
        }
    }

    /// The module whose absence it may be (a datamanager's error, an unreachable module):
    /// its kind and name.
    pub fn needed_module(&self) -> Option<(ModuleKind, &str)> {
        match self {
            OpError::Datamanager { dm, .. } => Some((ModuleKind::Datamanager, dm)),
            OpError::Unreachable { kind, module, .. } => Some((*kind, module)),
            _ => None,
        }
    }
}

/// A datamanager error inside an operation, so that `ctx.dm(FEATURE)?.store(..).await?`
/// works in [`Operation::step`]. The datamanager is named where the error names it
/// ([`DmError::datamanager`]), `?` otherwise (a payload that does not decode, a bad name):
/// `map_err` to name it there.
impl From<DmError> for OpError {
    fn from(e: DmError) -> OpError {
        OpError::of_dm(e.datamanager().unwrap_or("?"), &e)
    }
}

/// Current parameter values with typed getters. The host validated them against the
/// declaration, so a failing getter means the declaration and the code disagree.
#[derive(Clone, Debug, Default)]
pub struct Params {
    values: ParamMap,
}

impl Params {
    pub(crate) fn new(values: ParamMap) -> Self {
        Params { values }
    }

    /// All values.
    pub fn all(&self) -> &ParamMap {
        &self.values
    }

    /// A value by name.
    pub fn get(&self, name: &str) -> Result<&Value, OpError> {
        self.values.get(name).ok_or_else(|| OpError::Param {
            name: name.to_string(),
            problem: "not declared".to_string(),
        })
    }

    fn typed<T>(
        &self,
        name: &str,
        kind: &str,
        f: impl Fn(&Value) -> Option<T>,
    ) -> Result<T, OpError> {
        let v = self.get(name)?;
        f(v).ok_or_else(|| OpError::Param {
            name: name.to_string(),
            problem: format!("expected {kind}, found {}", v.kind()),
        })
    }

    /// A float (integers convert).
    pub fn f64(&self, name: &str) -> Result<f64, OpError> {
        self.typed(name, "float", Value::as_f64)
    }

    /// An integer.
    pub fn i64(&self, name: &str) -> Result<i64, OpError> {
        self.typed(name, "int", Value::as_i64)
    }

    /// A bool.
    pub fn bool(&self, name: &str) -> Result<bool, OpError> {
        self.typed(name, "bool", Value::as_bool)
    }

    /// Text or a choice.
    pub fn text(&self, name: &str) -> Result<&str, OpError> {
        let v = self.get(name)?;
        v.as_str().ok_or_else(|| OpError::Param {
            name: name.to_string(),
            problem: format!("expected text, found {}", v.kind()),
        })
    }

    /// One parameter by its typed key ([`Param`], e.g. `CollatzParams::start()` from
    /// [`params!`](crate::params)).
    pub fn value<T: ParamValue>(&self, key: Param<T>) -> Result<T, OpError> {
        Ok(key.read(&self.values)?)
    }

    /// Every parameter of a declared set: `let p: CollatzParams = ctx.params().read()?`.
    pub fn read<P: DeclaredParams>(&self) -> Result<P, OpError> {
        Ok(P::from_map(self.all())?)
    }
}

impl From<ParamError> for OpError {
    fn from(e: ParamError) -> OpError {
        OpError::Param {
            name: e.name,
            problem: e.problem,
        }
    }
}

/// What the host lends an operation while it runs.
pub struct OpContext {
    pub(crate) params: Params,
    pub(crate) clock: SharedClock,
    pub(crate) raised: StatusFlags,
    pub(crate) source: String,
    pub(crate) activation: u64,
    pub(crate) epoch: u64,
    pub(crate) resumed: bool,
    pub(crate) dms: std::collections::HashMap<String, marie_dm::DmClient>,
    /// Handed to every datamanager client it makes ([`super::HostOptions::acks`]).
    pub(crate) acks: Option<marie_dm::AckSink>,
}

impl std::fmt::Debug for OpContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OpContext")
            .field("params", &self.params)
            .field("raised", &self.raised)
            .finish_non_exhaustive()
    }
}

impl OpContext {
    /// Current parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The node's clock: read time from it, never from the OS, so simulations can run fast.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// True when this activation takes over one whose instance was lost (a `Resume` from a
    /// dispatcher that rebound the operation): state kept in the datamanagers by the lost
    /// instance is this activation's to continue, not a previous task's.
    pub fn resumed(&self) -> bool {
        self.resumed
    }

    /// Clock time now.
    pub fn now(&self) -> Duration {
        self.clock.now()
    }

    /// Raise flags (operation bit order) now; they are reported when the activation ends,
    /// whether it finishes or is suspended.
    ///
    /// Takes a [`StatusFlags`] word or a flag declared with [`flags!`](crate::flags!).
    pub fn raise(&mut self, flags: impl Into<StatusFlags>) {
        self.raised |= flags.into();
    }

    /// Flags raised so far in this activation.
    pub fn raised(&self) -> StatusFlags {
        self.raised
    }

    /// The name this operation writes as the source of datamanager records.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Number of the current activation (1 for the first).
    pub fn activation(&self) -> u64 {
        self.activation
    }

    /// The epoch of the binding this activation runs under (0 outside any).
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// This operation's fencing token: give it with every command to hardware, which then
    /// obeys only the newest incarnation of the operation ([`marie_vocabulary::fence`]).
    pub fn fence(&self) -> marie_vocabulary::fence::Fence {
        marie_vocabulary::fence::Fence::new(self.source.clone(), self.epoch)
    }

    /// A client of the datamanager `name` (or numeric id) that records this operation as the
    /// source, under this activation's epoch (the DM refuses records of a replaced
    /// incarnation). Found through the registry and kept until its actor stops, then found
    /// again (a restarted datamanager is a new actor).
    ///
    /// `name` is a constant such as [`marie_dm::FEATURE`] or text (`"feature"`, `"1201"`):
    /// see [`DmName`].
    pub fn dm(&mut self, name: impl DmName) -> Result<marie_dm::DmClient, OpError> {
        let name = name.dm_name();
        let epoch = self.epoch;
        if let Some(c) = self.dms.get(name) {
            if c.actor().get_status() <= ractor::ActorStatus::Running {
                return Ok(c.clone().with_epoch(epoch));
            }
        }
        let mut client =
            marie_dm::DmClient::lookup(name, &self.source).map_err(|e| OpError::Datamanager {
                dm: name.to_string(),
                problem: e.to_string(),
            })?;
        if let Some(acks) = &self.acks {
            client = client.with_acks(acks.clone());
        }
        self.dms.insert(name.to_string(), client.clone());
        Ok(client.with_epoch(epoch))
    }

    /// Whether the module `kind` named `module` is gone: a datamanager as
    /// [`dm_gone`](Self::dm_gone) says, any other when the registry has no live instance
    /// of it.
    pub(crate) fn module_gone(&self, kind: ModuleKind, module: &str) -> bool {
        match kind {
            ModuleKind::Datamanager => self.dm_gone(module),
            _ => marie_vocabulary::registry::follow::published(kind, module, None).is_none(),
        }
    }

    /// Whether the datamanager `dm` is gone now: no longer registered, or the actor this
    /// context reached it through has stopped (a new incarnation may be on its way).
    pub(crate) fn dm_gone(&self, dm: &str) -> bool {
        let stopped = self
            .dms
            .get(dm)
            .is_some_and(|c| c.actor().get_status() > ractor::ActorStatus::Running);
        stopped
            || marie_vocabulary::registry::lookup(
                marie_vocabulary::registry::ModuleKind::Datamanager,
                dm,
            )
            .is_empty()
    }

    /// Send what the operation put to datamanagers on other nodes and is still queued
    /// ([`marie_dm::DmClient::flush`]): the host does it after every step, so that a step's
    /// puts leave before anything the host then reports.
    pub(crate) fn flush_puts(&self) {
        for (dm, client) in &self.dms {
            if let Err(e) = client.flush() {
                tracing::debug!(%dm, error = %e, "queued puts not sent");
            }
        }
    }
}

/// An elementary operation: a small concurrent unit that senses, reasons or acts (thesis
/// 3.2.4.2). The EO host actor runs it: repeated activation and suspension, atomic
/// reparameterization, the property interface, the registry — none of that is the author's
/// concern.
///
/// Between [`Operation::activate`] and the end of the activation the host calls
/// [`Operation::step`] every [`Operation::period`] of clock time. Returning
/// [`Step::Finish`] reports `Finished` to the dispatcher and *suspends* the operation; it stays
/// alive for the next activation.
pub trait Operation: Send + 'static {
    /// Name, id, version, description.
    fn identity(&self) -> Identity;

    /// Declared parameters. Missions that omit a parameter get its default.
    fn parameters(&self) -> ParamSchema {
        ParamSchema::default()
    }

    /// Flags the operation can raise; bit `i` of its reports means `flags()[i]`.
    fn flags(&self) -> Vec<FlagDecl> {
        Vec::new()
    }

    /// How parameters of this operation's older versions map onto this version's (see
    /// [`Migrations`](crate::declare::Migrations)): none unless the operation says so. A
    /// binding that moves to this version mid-mission sends the mission's parameters
    /// through them.
    fn migrations(&self) -> crate::declare::Migrations {
        crate::declare::Migrations::default()
    }

    /// Clock time between steps: [`DEFAULT_PERIOD`](super::DEFAULT_PERIOD) (100 ms)
    /// unless the operation says otherwise.
    fn period(&self) -> Duration {
        super::DEFAULT_PERIOD
    }

    /// The longest the operation may take to answer a command (a step included). It is
    /// published in the general property group; a dispatcher that gets no answer within it
    /// kills the operation and handles it as crashed (self-healing of hung operations).
    fn deadline(&self) -> Duration {
        super::DEFAULT_DEADLINE
    }

    /// Called when activated, with the new parameters in place.
    fn activate(
        &mut self,
        ctx: &mut OpContext,
    ) -> impl Future<Output = Result<Step, OpError>> + Send {
        let _ = ctx;
        async { Ok(Step::Continue) }
    }

    /// One unit of work.
    fn step(&mut self, ctx: &mut OpContext) -> impl Future<Output = Result<Step, OpError>> + Send;

    /// Called when the activation ends (finished, suspended, or failed): stop motors, release
    /// resources. Errors are logged.
    fn suspend(&mut self, ctx: &mut OpContext) -> impl Future<Output = Result<(), OpError>> + Send {
        let _ = ctx;
        async { Ok(()) }
    }

    /// Operation-specific properties, asked by name through the property interface.
    fn property(&self, name: &str) -> Option<Value> {
        let _ = name;
        None
    }
}

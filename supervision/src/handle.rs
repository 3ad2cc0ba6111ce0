//! A typed handle on a running supervisor.

use std::time::Duration;

use ractor::rpc::CallResult;
use ractor::{ActorCell, ActorId, ActorRef, RpcReplyPort};
use tokio::sync::broadcast;

use crate::child::ChildSpec;
use crate::error::SupervisorError;
use crate::events::SupervisorEvent;
use crate::exit::SHUTDOWN;
use crate::info::{ChildCounts, ChildInfo};
use crate::messages::SupervisorMsg;
use crate::simple::DynamicArg;

/// A handle on a [`crate::Supervisor`]: OTP's supervisor API as async methods. Cheap to
/// clone; it does not keep the supervisor alive.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SupervisorRef {
    actor: ActorRef<SupervisorMsg>,
}

impl SupervisorRef {
    /// The handle of the supervisor behind `cell`, if it is one (e.g. the cell of a child
    /// supervisor from [`SupervisorRef::which_children`]).
    pub fn from_cell(cell: ActorCell) -> Option<Self> {
        (cell.is_message_type_of::<SupervisorMsg>() == Some(true))
            .then(|| SupervisorRef { actor: cell.into() })
    }

    /// The supervisor's actor.
    pub fn actor(&self) -> &ActorRef<SupervisorMsg> {
        &self.actor
    }

    /// The supervisor's cell: to link, monitor or pass as a parent.
    pub fn get_cell(&self) -> ActorCell {
        self.actor.get_cell()
    }

    /// The supervisor's actor id.
    pub fn get_id(&self) -> ActorId {
        self.actor.get_id()
    }

    async fn call<T: Send + 'static>(
        &self,
        build: impl FnOnce(RpcReplyPort<T>) -> SupervisorMsg,
    ) -> Result<T, SupervisorError> {
        match self.actor.call(build, None).await {
            Ok(CallResult::Success(v)) => Ok(v),
            _ => Err(SupervisorError::NotRunning),
        }
    }

    /// Add `spec` at the end of the start order and start it; the new child's cell once it
    /// started. Fails with `InvalidSpec` if the spec does not validate
    /// ([`ChildSpec::validate`]), with `AlreadyStarted` / `AlreadyPresent` if the id is taken,
    /// with `StartFailed` (leaving no spec behind) if the start fails, with `Ignored` if the
    /// start answered [`crate::ChildStart::Ignore`] (the spec is kept, not running, unless the
    /// child is temporary), and with `SimpleOneForOne` on a simple-one-for-one supervisor (use
    /// [`SupervisorRef::start_dynamic`]).
    pub async fn start_child(&self, spec: ChildSpec) -> Result<ActorCell, SupervisorError> {
        self.call(|reply| SupervisorMsg::StartChild(spec, reply))
            .await?
    }

    /// Stop child `id` by its shutdown spec. Its spec stays (undefined, see
    /// [`SupervisorRef::restart_child`]), except for temporary children, which are removed.
    pub async fn terminate_child(&self, id: &str) -> Result<(), SupervisorError> {
        self.call(|reply| SupervisorMsg::TerminateChild(id.to_string(), reply))
            .await?
    }

    /// Start one more instance of a simple-one-for-one supervisor's template with `arg` — "start
    /// another instance of operation X that my config allows". The new instance's actor once
    /// it started; it restarts by the template's restart type with (a clone of) the same
    /// `arg`. Fails with `WrongArgument` if the template's start function takes another type
    /// (nothing starts), `NotSimpleOneForOne` on a supervisor of another strategy,
    /// `StartFailed` if the start fails and `Ignored` if it answered
    /// [`crate::ChildStart::Ignore`] (both leave nothing behind, as in OTP).
    pub async fn start_dynamic<A: Clone + Send + Sync + 'static>(
        &self,
        arg: A,
    ) -> Result<ActorCell, SupervisorError> {
        let arg = DynamicArg::new(arg);
        self.call(|reply| SupervisorMsg::StartDynamic(arg, reply))
            .await?
    }

    /// Stop a simple-one-for-one instance by its actor (by its shutdown spec, as
    /// `terminate_child`) and forget it (OTP's `terminate_child` with a pid). An actor that
    /// was an instance but has stopped meanwhile is fine (`Ok`, as in OTP); a live actor that
    /// is not an instance of this supervisor is `NotFound`, and so is any actor on a
    /// supervisor of another strategy (address its children by id).
    pub async fn terminate_actor(&self, actor: ActorId) -> Result<(), SupervisorError> {
        self.call(|reply| SupervisorMsg::TerminateActor(actor, reply))
            .await?
    }

    /// Start terminated child `id` again. `Ignored` if its start answered
    /// [`crate::ChildStart::Ignore`] again (it stays, not running).
    pub async fn restart_child(&self, id: &str) -> Result<ActorCell, SupervisorError> {
        self.call(|reply| SupervisorMsg::RestartChild(id.to_string(), reply))
            .await?
    }

    /// Remove the spec of terminated child `id`.
    pub async fn delete_child(&self, id: &str) -> Result<(), SupervisorError> {
        self.call(|reply| SupervisorMsg::DeleteChild(id.to_string(), reply))
            .await?
    }

    /// The spec of child `id` (OTP's `get_childspec`): to inspect its restart type, shutdown
    /// and kind, or to hand it to another supervisor. For a simple-one-for-one instance, the
    /// template's settings with the instance's argument bound; for a temporary child, a spec
    /// whose start function fails (its start parameters are not kept).
    pub async fn get_child_spec(&self, id: &str) -> Result<ChildSpec, SupervisorError> {
        self.call(|reply| SupervisorMsg::GetChildSpec(id.to_string(), reply))
            .await?
    }

    /// All children in start order, with their state and restart counts.
    pub async fn which_children(&self) -> Result<Vec<ChildInfo>, SupervisorError> {
        self.call(SupervisorMsg::WhichChildren).await
    }

    /// Counts of the children.
    pub async fn count_children(&self) -> Result<ChildCounts, SupervisorError> {
        self.call(SupervisorMsg::CountChildren).await
    }

    /// A receiver of the supervisor's events from now on. The channel closes after the
    /// final [`SupervisorEvent::Stopped`]. The initial children started before anyone could
    /// subscribe; [`SupervisorRef::which_children`] lists them.
    pub async fn subscribe(&self) -> Result<broadcast::Receiver<SupervisorEvent>, SupervisorError> {
        self.call(SupervisorMsg::Subscribe).await
    }

    /// Stop the supervisor in order — its children in reverse start order, each by its
    /// shutdown spec — with reason [`SHUTDOWN`], and wait until it has stopped.
    pub async fn stop(&self) {
        self.actor.stop(Some(SHUTDOWN.to_string()));
        let _ = self.actor.wait(None).await;
    }

    /// Like [`SupervisorRef::stop`], but give up waiting after `timeout`; `false` if it has
    /// not stopped by then.
    pub async fn stop_timeout(&self, timeout: Duration) -> bool {
        self.actor.stop(Some(SHUTDOWN.to_string()));
        self.actor.wait(Some(timeout)).await.is_ok()
    }

    /// Kill the supervisor: its children are killed too, without their shutdown specs.
    pub fn kill(&self) {
        self.actor.kill();
    }

    /// Wait until the supervisor has stopped, however it stops.
    pub async fn wait(&self) {
        let _ = self.actor.wait(None).await;
    }
}

impl From<ActorRef<SupervisorMsg>> for SupervisorRef {
    fn from(actor: ActorRef<SupervisorMsg>) -> Self {
        SupervisorRef { actor }
    }
}

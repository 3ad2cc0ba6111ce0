//! A typed handle for sending the eo-interface and property interface to an operation.

use super::messages::{EoMsg, EoReport, ParamOutcome};
use marie_vocabulary::property::{ParamMap, PropertyReply, PropertyRequest};
use marie_vocabulary::run::FaultKind;
use ractor::concurrency::OneshotReceiver;
use ractor::rpc::CallResult;
use ractor::{ActorCell, ActorRef};
use std::time::Duration;

/// Why a request to an operation got no answer.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EoError {
    /// The operation's actor is gone (stopped, crashed, or its node is unreachable).
    #[error("operation {0} is not reachable")]
    Gone(String),
    /// No answer within the deadline.
    #[error("operation {0} did not answer within {1:?}")]
    Timeout(String, Duration),
}

/// A typed handle to an EO host. Cheap to clone.
#[derive(Clone, Debug)]
pub struct EoClient {
    actor: ActorRef<EoMsg>,
    timeout: Duration,
}

impl EoClient {
    /// Default deadline of a request.
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

    /// A handle to `actor`.
    pub fn new(actor: ActorRef<EoMsg>) -> Self {
        EoClient {
            actor,
            timeout: Self::DEFAULT_TIMEOUT,
        }
    }

    /// A handle to an actor found in the registry under [`marie_vocabulary::registry::ModuleKind::Operation`].
    pub fn from_cell(cell: ActorCell) -> Self {
        Self::new(cell.into())
    }

    /// Use `timeout` as the deadline of requests.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The actor behind the handle.
    pub fn actor(&self) -> &ActorRef<EoMsg> {
        &self.actor
    }

    fn who(&self) -> String {
        self.actor.get_id().to_string()
    }

    /// Activate with `params` (applied atomically first). Returns the port on which the
    /// activation's end is reported; it closes without a report if the operation dies.
    pub fn activate(
        &self,
        params: ParamMap,
        epoch: u64,
    ) -> Result<OneshotReceiver<EoReport>, EoError> {
        self.start(|reply| EoMsg::Activate {
            params,
            epoch,
            reply,
        })
    }

    /// Like [`EoClient::activate`], taking over the activation of a lost instance (see
    /// [`crate::eo::OpContext::resumed`]).
    pub fn resume(
        &self,
        params: ParamMap,
        epoch: u64,
    ) -> Result<OneshotReceiver<EoReport>, EoError> {
        self.start(|reply| EoMsg::Resume {
            params,
            epoch,
            reply,
        })
    }

    /// Take over the running activation (if one of epoch `since` or newer runs) under
    /// `epoch`: the port its end is reported on ([`EoMsg::Attach`]).
    pub fn attach(&self, epoch: u64, since: u64) -> Result<OneshotReceiver<EoReport>, EoError> {
        self.start(|reply| EoMsg::Attach {
            epoch,
            since,
            reply,
        })
    }

    /// Send an activation built by `make`; the port its end is reported on.
    fn start(
        &self,
        make: impl FnOnce(ractor::RpcReplyPort<EoReport>) -> EoMsg,
    ) -> Result<OneshotReceiver<EoReport>, EoError> {
        let (tx, rx) = ractor::concurrency::oneshot();
        self.actor
            .cast(make(tx.into()))
            .map_err(|_| EoError::Gone(self.who()))?;
        Ok(rx)
    }

    /// Suspend the running activation (if its epoch is not older than the one in force).
    pub fn suspend(&self, epoch: u64) -> Result<(), EoError> {
        self.actor
            .cast(EoMsg::Suspend { epoch })
            .map_err(|_| EoError::Gone(self.who()))
    }

    /// Tell the operation to commit `fault` (fault injection).
    pub fn inject(&self, fault: FaultKind) -> Result<(), EoError> {
        self.actor
            .cast(EoMsg::Inject { fault })
            .map_err(|_| EoError::Gone(self.who()))
    }

    async fn call<T>(
        &self,
        make: impl FnOnce(ractor::RpcReplyPort<T>) -> EoMsg,
    ) -> Result<T, EoError>
    where
        T: Send + 'static,
    {
        match self.actor.call(make, Some(self.timeout)).await {
            Ok(CallResult::Success(v)) => Ok(v),
            Ok(CallResult::Timeout) => Err(EoError::Timeout(self.who(), self.timeout)),
            Ok(CallResult::SenderError) | Err(_) => Err(EoError::Gone(self.who())),
        }
    }

    /// Change parameters: all or nothing.
    pub async fn parameterize(
        &self,
        values: ParamMap,
        epoch: u64,
    ) -> Result<ParamOutcome, EoError> {
        self.call(|reply| EoMsg::Parameterize {
            values,
            epoch,
            reply,
        })
        .await
    }

    /// Ask a property.
    pub async fn property(&self, request: PropertyRequest) -> Result<PropertyReply, EoError> {
        self.call(|reply| EoMsg::Property { request, reply }).await
    }
}

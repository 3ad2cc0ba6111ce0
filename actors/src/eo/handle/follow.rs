//! How a handle follows its operation: the instance it talks to now ([`Bound`]), one try of
//! a call ([`Attempt`]), and when the instance is gone, the next one — another clone's
//! choice, or an instance of the operation (of a fitting version) in the registry now or
//! within the follow time.

use super::OperationHandle;
use crate::eo::client::{EoClient, EoError};
use crate::eo::handle_error::HandleError;
use marie_vocabulary::property::{Group, PropertyReply, PropertyRequest};
use marie_vocabulary::registry::{self, Instance, ModuleKind, RegistryEvent};
use ractor::{ActorId, ActorStatus};
use semver::VersionReq;
use std::future::Future;
use std::time::Duration;
use tokio::time::Instant;

/// The instance a handle talks to.
#[derive(Clone, Debug)]
pub(super) struct Bound {
    pub(super) client: EoClient,
    /// The operation's name (also when looked up by id).
    pub(super) name: String,
    pub(super) node: String,
}

impl Bound {
    pub(super) fn of(inst: Instance) -> Bound {
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

    pub(super) fn unexpected(&self, asked: &str, answer: impl std::fmt::Debug) -> HandleError {
        HandleError::Unexpected {
            operation: self.name.clone(),
            node: self.node.clone(),
            asked: asked.to_string(),
            answer: format!("{answer:?}"),
        }
    }
}

/// How one try of a call ended, short of an answer.
pub(super) enum Attempt {
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
    /// The instance followed now, its client with this handle's timeout.
    pub(super) fn bound(&self) -> Bound {
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
    pub(super) async fn call<T, F, Fut>(&self, request: F) -> Result<T, HandleError>
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
                    if inst.answers_to(&self.key)
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
pub(super) async fn fits(
    inst: &Instance,
    versions: Option<&VersionReq>,
    timeout: Duration,
) -> bool {
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

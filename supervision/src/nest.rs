//! Supervisors as children, so that supervisors nest: the child spec and the child template
//! whose start starts a [`Supervisor`] linked to its parent. They stand here, above the
//! supervisor, and not beside the plain specs they build ([`ChildSpec`], [`ChildTemplate`]),
//! which know no actor.

use std::sync::Arc;

use ractor::SpawnErr;

use crate::child::{ChildKind, ChildSpec, ChildStart, Shutdown, StartFn};
use crate::simple::ChildTemplate;
use crate::spec::SupervisorSpec;
use crate::supervisor::Supervisor;

impl ChildSpec {
    /// A permanent child supervisor with infinite shutdown, so supervisors nest: it starts a
    /// [`Supervisor`] with `spec` and `children` linked to the parent. When it gives up
    /// (restart intensity exceeded) the parent sees an abnormal exit and applies its own
    /// strategy.
    pub fn supervisor(
        id: impl Into<String>,
        spec: SupervisorSpec,
        children: Vec<ChildSpec>,
    ) -> Self {
        let start: StartFn = Arc::new(move |sup| {
            let spec = spec.clone();
            let children = children.clone();
            Box::pin(async move {
                let (handle, _) = Supervisor::start_linked(None, spec, children, sup)
                    .await
                    .map_err(|e| SpawnErr::StartupFailed(Box::new(e)))?;
                Ok(ChildStart::Started(handle.get_cell()))
            })
        });
        Self::new(id, ChildKind::Supervisor, start)
    }
}

impl ChildTemplate {
    /// A template of child supervisors (infinite shutdown): each instance is a
    /// [`Supervisor`] with the spec and children `make` builds from the instance's argument.
    pub fn supervisor<A, F>(id: impl Into<String>, make: F) -> Self
    where
        A: Clone + Send + Sync + 'static,
        F: Fn(A) -> (SupervisorSpec, Vec<ChildSpec>) + Send + Sync + 'static,
    {
        let mut template = Self::worker(id, move |sup, arg: A| {
            let (spec, children) = make(arg);
            async move {
                let (handle, _) = Supervisor::start_linked(None, spec, children, sup)
                    .await
                    .map_err(|e| SpawnErr::StartupFailed(Box::new(e)))?;
                Ok(ChildStart::Started(handle.get_cell()))
            }
        });
        template.kind = ChildKind::Supervisor;
        template.shutdown = Shutdown::Infinity;
        template
    }
}

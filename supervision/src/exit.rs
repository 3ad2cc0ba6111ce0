//! Why a child stopped, in OTP's three classes: normal, shutdown, abnormal (see
//! [`ExitReason`] for the convention).

use std::fmt;

use ractor::{ActorCell, SupervisionEvent};

/// Stop reason of a normal exit (OTP's `normal`). Stopping with no reason is normal too.
pub const NORMAL: &str = "normal";

/// Stop reason of an orderly shutdown (OTP's `shutdown`). Supervisors stop their children with
/// it, and stop themselves with it when asked to ([`crate::SupervisorRef::stop`]).
/// `"shutdown: <detail>"` is a shutdown as well (OTP's `{shutdown, Term}`).
pub const SHUTDOWN: &str = "shutdown";

/// Failure reason of a supervisor that exceeded its restart intensity. It fails (rather than
/// stopping) with this reason, so its parent sees an abnormal exit and applies its own
/// strategy — OTP's escalation.
pub const REACHED_MAX_RESTART_INTENSITY: &str = "reached_max_restart_intensity";

/// ractor's stop reason for a kill signal.
const KILLED: &str = "killed";
/// ractor's stop reason when the actor's task was dropped (e.g. runtime shutdown).
const TASK_CANCELLED: &str = "actor_task_cancelled";
/// ractor's stop reason after `drain`: every queued message was handled, then the actor stopped.
const DRAINED: &str = "Drained";

/// Why a child stopped, classified the way OTP's restart types need it.
///
/// ractor reports a stopped child as `ActorTerminated(cell, state, reason)` (it stopped; the
/// reason is the string given to `stop`, or `"killed"` after a kill) or `ActorFailed(cell,
/// error)` (a handler panicked or returned `Err`). OTP's restart types need to know whether
/// an exit was *normal*, a *shutdown* or *abnormal*; marie's convention maps one onto the
/// other:
///
/// | ractor event | `ExitReason` | class |
/// |---|---|---|
/// | `ActorTerminated` with no reason, [`NORMAL`] or `"Drained"` | [`Normal`](ExitReason::Normal) | normal |
/// | `ActorTerminated` with [`SHUTDOWN`] or `"shutdown: <detail>"` | [`Shutdown`](ExitReason::Shutdown) | shutdown |
/// | `ActorTerminated` with `"killed"` (kill signal) or `"actor_task_cancelled"` | [`Killed`](ExitReason::Killed) | abnormal |
/// | `ActorFailed` (panic or `Err` in a handler) | [`Failed`](ExitReason::Failed) | abnormal |
/// | `ActorTerminated` with any other reason | [`Other`](ExitReason::Other) | abnormal |
///
/// So an actor that wants to end for good under a `Transient` spec stops itself with
/// `myself.stop(None)` (normal) or `myself.stop(Some(SHUTDOWN.into()))`; any other reason
/// counts as a fault. A supervisor that gives up *fails* (returns an error from its handler)
/// with [`REACHED_MAX_RESTART_INTENSITY`], which its own parent classifies as
/// [`Failed`](ExitReason::Failed) — an abnormal exit, so the fault escalates.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum ExitReason {
    /// Stopped cleanly: no reason, [`NORMAL`], or drained.
    Normal,
    /// Stopped with [`SHUTDOWN`]; the detail after `"shutdown:"` when one was given.
    Shutdown(Option<String>),
    /// Killed (ractor's kill signal, or its task was cancelled).
    Killed,
    /// A handler panicked or returned an error; the error text.
    Failed(String),
    /// Stopped with a reason that is neither normal nor shutdown.
    Other(String),
}

impl ExitReason {
    /// Classify the reason string of an `ActorTerminated` event (or of `stop`).
    pub fn from_stop_reason(reason: Option<&str>) -> Self {
        match reason {
            None | Some(NORMAL) | Some(DRAINED) => ExitReason::Normal,
            Some(SHUTDOWN) => ExitReason::Shutdown(None),
            Some(KILLED) | Some(TASK_CANCELLED) => ExitReason::Killed,
            Some(r) => match r.strip_prefix("shutdown:") {
                Some(detail) => ExitReason::Shutdown(Some(detail.trim().to_string())),
                None => ExitReason::Other(r.to_string()),
            },
        }
    }

    /// The stopped actor and why, for the two events that report a stop; `None` for the
    /// others (started, process groups, pid lifecycle).
    pub fn from_supervision_event(event: &SupervisionEvent) -> Option<(ActorCell, ExitReason)> {
        match event {
            SupervisionEvent::ActorTerminated(cell, _, reason) => Some((
                cell.clone(),
                ExitReason::from_stop_reason(reason.as_deref()),
            )),
            SupervisionEvent::ActorFailed(cell, err) => {
                Some((cell.clone(), ExitReason::Failed(err.to_string())))
            }
            _ => None,
        }
    }

    /// A normal exit: a `Transient` child stays stopped.
    pub fn is_normal(&self) -> bool {
        matches!(self, ExitReason::Normal)
    }

    /// A shutdown: a `Transient` child stays stopped.
    pub fn is_shutdown(&self) -> bool {
        matches!(self, ExitReason::Shutdown(_))
    }

    /// Neither normal nor shutdown: a fault, after which `Transient` children are restarted.
    pub fn is_abnormal(&self) -> bool {
        !self.is_normal() && !self.is_shutdown()
    }

    /// The exit of a supervisor that gave up after exceeding its restart intensity.
    pub fn is_intensity_escalation(&self) -> bool {
        matches!(self, ExitReason::Failed(r) if r == REACHED_MAX_RESTART_INTENSITY)
    }
}

impl fmt::Display for ExitReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExitReason::Normal => f.write_str(NORMAL),
            ExitReason::Shutdown(None) => f.write_str(SHUTDOWN),
            ExitReason::Shutdown(Some(d)) => write!(f, "{SHUTDOWN}: {d}"),
            ExitReason::Killed => f.write_str(KILLED),
            ExitReason::Failed(e) => write!(f, "failed: {e}"),
            ExitReason::Other(r) => f.write_str(r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stop_reasons_map_to_otp_classes() {
        assert!(ExitReason::from_stop_reason(None).is_normal());
        assert!(ExitReason::from_stop_reason(Some("normal")).is_normal());
        assert!(ExitReason::from_stop_reason(Some("Drained")).is_normal());
        assert_eq!(
            ExitReason::from_stop_reason(Some("shutdown")),
            ExitReason::Shutdown(None)
        );
        assert_eq!(
            ExitReason::from_stop_reason(Some("shutdown: maintenance")),
            ExitReason::Shutdown(Some("maintenance".into()))
        );
        assert_eq!(
            ExitReason::from_stop_reason(Some("killed")),
            ExitReason::Killed
        );
        let other = ExitReason::from_stop_reason(Some("bored"));
        assert_eq!(other, ExitReason::Other("bored".into()));
        assert!(other.is_abnormal());
        assert!(!ExitReason::from_stop_reason(Some("shutdownx")).is_shutdown());
    }

    #[test]
    fn escalation_is_abnormal() {
        let r = ExitReason::Failed(REACHED_MAX_RESTART_INTENSITY.into());
        assert!(r.is_abnormal());
        assert!(r.is_intensity_escalation());
    }
}

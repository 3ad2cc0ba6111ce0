//! What an [`OperationHandle`](super::OperationHandle) call can end in, said about the
//! operation and its node.
//!
//! An embedder knows an operation by its name; an actor id (`0.17`) changes with every
//! restart and tells them nothing. So every error here names the operation and the node it
//! ran on — `operation `collatz` on node `embedded` did not answer within 5 s` — and keeps
//! them as fields for code that reacts to them.

use marie_vocabulary::property::{Rejection, Value};
use std::fmt;
use std::time::Duration;

/// Why a call through an [`OperationHandle`](super::OperationHandle) got no usable answer.
///
/// ```
/// use marie_actors::eo::HandleError;
/// use std::time::Duration;
/// let e = HandleError::Timeout {
///     operation: "collatz".into(),
///     node: "embedded".into(),
///     after: Duration::from_secs(5),
/// };
/// assert_eq!(e.to_string(), "operation `collatz` on node `embedded` did not answer within 5 s");
/// ```
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HandleError {
    /// No live instance of the operation (that meets the version requirement) is in the
    /// registry.
    #[error("no running instance of operation `{operation}`{}", requirement.as_ref().map(|r| format!(" with a version matching `{r}`")).unwrap_or_default())]
    NotFound {
        /// The name or id looked up.
        operation: String,
        /// The version requirement, if the lookup had one.
        requirement: Option<String>,
    },
    /// The instance did not answer within the handle's deadline. It may hang; the handle
    /// does not follow it elsewhere (it is alive, as far as anyone knows).
    #[error("operation `{operation}` on node `{node}` did not answer within {}", Secs(*after))]
    Timeout {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// The deadline.
        after: Duration,
    },
    /// The instance is gone (stopped, crashed, its node lost) and no instance took its place
    /// in time.
    #[error("operation `{operation}` on node `{node}` is gone, and no instance took its place within {}", Secs(*waited))]
    Gone {
        /// The operation.
        operation: String,
        /// The node of the instance that is gone.
        node: String,
        /// How long the handle waited for a replacement.
        waited: Duration,
    },
    /// The instance that took the place of a gone one was gone too before it answered (the
    /// operation keeps failing, or its node is being lost): a call follows the operation
    /// once.
    #[error("operation `{operation}` on node `{node}` is gone too: the instance that took the place of a gone one stopped before it answered")]
    GoneAgain {
        /// The operation.
        operation: String,
        /// The node of the replacement that is gone.
        node: String,
    },
    /// The operation declares no parameter of that name.
    #[error("operation `{operation}` on node `{node}` has no parameter `{name}`")]
    NoParameter {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// The parameter asked for.
        name: String,
    },
    /// The operation has no property of that name.
    #[error("operation `{operation}` on node `{node}` has no property `{name}`")]
    NoProperty {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// The property asked for.
        name: String,
    },
    /// The value is of another kind than the type asked for.
    #[error("`{name}` of operation `{operation}` on node `{node}` is {} {got}, not {expected}", got.kind())]
    WrongType {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// The parameter or property.
        name: String,
        /// The type asked for ([`marie_vocabulary::property::FromValue::EXPECTED`]).
        expected: &'static str,
        /// The value it has.
        got: Value,
    },
    /// The instance answered something the property interface does not answer to that
    /// request (another program behind the name?).
    #[error("operation `{operation}` on node `{node}` answered {asked} with {answer}")]
    Unexpected {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// What was asked.
        asked: String,
        /// What came back.
        answer: String,
    },
    /// The handle could not watch the registry for a replacement.
    #[error("cannot wait for a new instance of operation `{operation}`: {reason}")]
    Registry {
        /// The operation.
        operation: String,
        /// Why.
        reason: String,
    },
}

/// Why [`OperationHandle::set`](super::OperationHandle::set) changed nothing.
///
/// ```
/// use marie_actors::eo::SetError;
/// use marie_vocabulary::property::{RejectReason, Rejection};
/// let e = SetError::Rejected {
///     operation: "pump".into(),
///     node: "embedded".into(),
///     rejections: vec![Rejection::new("rate", RejectReason::ReadOnly)],
/// };
/// assert_eq!(
///     e.to_string(),
///     "operation `pump` on node `embedded` refused the parameters, nothing changed: rate: read-only"
/// );
/// ```
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SetError {
    /// The operation refused the values (unknown names, wrong types, out of range,
    /// read-only): all of them, since parameters change all at once or not at all. One
    /// [`Rejection`] per refused value.
    #[error(
        "operation `{operation}` on node `{node}` refused the parameters, nothing changed: {}",
        list(rejections)
    )]
    Rejected {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// Each refused value and why.
        rejections: Vec<Rejection>,
    },
    /// Twice in a row the operation had moved to a newer epoch between the handle reading
    /// it and the handle's command arriving: something else (a dispatcher) is driving it and
    /// keeps reparameterizing it. Nothing changed.
    #[error("operation `{operation}` on node `{node}` moved on to epoch {epoch} while being set: something else drives it; nothing changed")]
    Superseded {
        /// The operation.
        operation: String,
        /// Its node.
        node: String,
        /// The epoch it was at last.
        epoch: u64,
    },
    /// The operation did not answer (see [`HandleError`]).
    #[error(transparent)]
    Handle(#[from] HandleError),
}

fn list(rejections: &[Rejection]) -> String {
    rejections
        .iter()
        .map(Rejection::to_string)
        .collect::<Vec<_>>()
        .join("; ")
}

/// A duration as people read it in a message: `5 s`, `2.5 s`, `300 ms`.
struct Secs(Duration);

impl fmt::Display for Secs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = self.0;
        if d < Duration::from_secs(1) {
            write!(f, "{} ms", d.as_millis())
        } else if d.subsec_millis() == 0 {
            write!(f, "{} s", d.as_secs())
        } else {
            write!(f, "{:.1} s", d.as_secs_f64())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_people_write_them() {
        assert_eq!(Secs(Duration::from_secs(5)).to_string(), "5 s");
        assert_eq!(Secs(Duration::from_millis(2500)).to_string(), "2.5 s");
        assert_eq!(Secs(Duration::from_millis(300)).to_string(), "300 ms");
    }

    #[test]
    fn every_error_names_the_operation() {
        let gone = HandleError::Gone {
            operation: "collatz".into(),
            node: "alpha".into(),
            waited: Duration::from_secs(5),
        };
        assert_eq!(
            gone.to_string(),
            "operation `collatz` on node `alpha` is gone, and no instance took its place within 5 s"
        );
        let wrong = HandleError::WrongType {
            operation: "collatz".into(),
            node: "alpha".into(),
            name: "start".into(),
            expected: "bool",
            got: Value::Int(27),
        };
        assert_eq!(
            wrong.to_string(),
            "`start` of operation `collatz` on node `alpha` is int 27, not bool"
        );
        let none = HandleError::NotFound {
            operation: "collatz".into(),
            requirement: Some("^2".into()),
        };
        assert_eq!(
            none.to_string(),
            "no running instance of operation `collatz` with a version matching `^2`"
        );
    }
}

//! Why a binding let its instance go: the cause recorded with a rebind and carried by loss
//! events, as a value rather than text, so readers match on it instead of parsing it.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Why a bound operation instance was lost.
///
/// Serialized internally tagged: `{"type": "hung", "deadline_ms": 300}`; the tags are stable
/// names (add variants, never rename them). [`Display`](fmt::Display) gives the human text
/// the live lines and failure reasons show.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum LossCause {
    /// The activation's reply port closed during action `action`: the instance died while
    /// running it.
    DiedInAction {
        /// The action it was running.
        action: String,
    },
    /// The instance left the registry (it died, or withdrew).
    LeftRegistry,
    /// A liveness probe found its actor gone.
    Gone,
    /// It did not answer a liveness probe within its declared deadline; the dispatcher killed
    /// it.
    Hung {
        /// Its declared answer deadline, in ms.
        deadline_ms: u64,
    },
    /// Its supervisor saw it fail with `reason` (for a node that knows why; the dispatcher
    /// itself only sees that an instance is gone).
    Crashed {
        /// The exit reason.
        reason: String,
    },
    /// It was killed (for a node that knows; see [`LossCause::Crashed`]).
    Killed,
    /// Its node was declared down by the failure detector.
    NodeDown {
        /// Name of the node.
        node: String,
    },
}

impl fmt::Display for LossCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LossCause::DiedInAction { action } => write!(f, "died during action `{action}`"),
            LossCause::LeftRegistry => f.write_str("died: it left the registry"),
            LossCause::Gone => f.write_str("died: its actor is gone"),
            LossCause::Hung { deadline_ms } => write!(
                f,
                "hung: no answer within its deadline of {deadline_ms} ms; killed"
            ),
            LossCause::Crashed { reason } => write!(f, "died: crashed ({reason})"),
            LossCause::Killed => f.write_str("died: killed"),
            LossCause::NodeDown { node } => write!(f, "its node `{node}` went down"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn causes_serialize_as_tagged_values_and_read_back() {
        let causes = [
            LossCause::DiedInAction { action: "a".into() },
            LossCause::LeftRegistry,
            LossCause::Gone,
            LossCause::Hung { deadline_ms: 300 },
            LossCause::Crashed {
                reason: "boom".into(),
            },
            LossCause::Killed,
            LossCause::NodeDown { node: "n@h".into() },
        ];
        for cause in causes {
            let json = serde_json::to_string(&cause).unwrap();
            assert_eq!(serde_json::from_str::<LossCause>(&json).unwrap(), cause);
            let bytes = rmp_serde::to_vec_named(&cause).unwrap();
            assert_eq!(rmp_serde::from_slice::<LossCause>(&bytes).unwrap(), cause);
        }
        assert_eq!(
            serde_json::to_string(&LossCause::Hung { deadline_ms: 300 }).unwrap(),
            r#"{"type":"hung","deadline_ms":300}"#
        );
        assert_eq!(
            LossCause::Hung { deadline_ms: 300 }.to_string(),
            "hung: no answer within its deadline of 300 ms; killed"
        );
    }
}

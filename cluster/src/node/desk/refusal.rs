//! Why a desk did not start a run, and why it could not record one.

use marie_dm::RUN;
use serde::{Deserialize, Serialize};

/// The cluster has no run datamanager ([`RUN`]) to record a dispatched run in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "no run datamanager `{}` in the cluster: a dispatched run records its progress there so \
     that a standby can take it over (a node config hosts it: `[[datamanager]] name = \
     \"run\"`, best with copies on other nodes)",
    RUN.name
)]
pub struct NoRunDm;

/// Why a desk did not start a run ([`super::DeskMsg::Start`]).
///
/// It answers across nodes, where it travels as its words — a MessagePack string, as the
/// answers of an earlier build (`Result<(), String>`) did: a node of either build reads the
/// other's, with no new protocol version. What the member does with a refusal is tell it,
/// so the words are all it needs; a refusal read from the wire is [`DeskRefusal::Text`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error, Serialize, Deserialize)]
#[serde(into = "String", from = "String")]
pub enum DeskRefusal {
    /// The desk's dispatcher runs another run.
    #[error("node `{node}` already dispatches a run: one at a time")]
    Busy {
        /// The desk's node.
        node: String,
    },
    /// The mission's bytes do not decode.
    #[error("the mission did not arrive whole: {reason}")]
    Garbled {
        /// Why they do not decode.
        reason: String,
    },
    /// The run could not be recorded.
    #[error(transparent)]
    NoRunDm(#[from] NoRunDm),
    /// The dispatcher did not start.
    #[error("{reason}")]
    NotStarted {
        /// Why.
        reason: String,
    },
    /// A refusal in words only: what came over the wire (from a node of either build).
    #[error("{0}")]
    Text(String),
}

impl From<DeskRefusal> for String {
    fn from(refusal: DeskRefusal) -> String {
        refusal.to_string()
    }
}

impl From<String> for DeskRefusal {
    fn from(text: String) -> DeskRefusal {
        DeskRefusal::Text(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::wire::{decode, encode};

    #[test]
    fn a_refusal_crosses_nodes_as_its_words_both_ways_between_builds() {
        let refusals = [
            DeskRefusal::Busy { node: "n1".into() },
            DeskRefusal::Garbled {
                reason: "invalid marker".into(),
            },
            DeskRefusal::NoRunDm(NoRunDm),
            DeskRefusal::NotStarted {
                reason: "node supervisor: it gave up".into(),
            },
        ];
        for refusal in refusals {
            let words = refusal.to_string();
            let answer: Result<(), DeskRefusal> = Err(refusal);
            let bytes = encode(&answer).unwrap();
            // a node of an earlier build reads `Result<(), String>`
            let old: Result<(), String> = decode(&bytes).unwrap();
            assert_eq!(old, Err(words.clone()));
            let back: Result<(), DeskRefusal> = decode(&bytes).unwrap();
            assert_eq!(back, Err(DeskRefusal::Text(words)));
        }
        // a node of an earlier build answered `Result<(), String>`
        let old: Result<(), String> =
            Err("node `n2` already dispatches a run: one at a time".into());
        let back: Result<(), DeskRefusal> = decode(&encode(&old).unwrap()).unwrap();
        assert_eq!(
            back.unwrap_err().to_string(),
            "node `n2` already dispatches a run: one at a time"
        );
        let ok: Result<(), DeskRefusal> = decode(&encode(&Ok::<(), String>(())).unwrap()).unwrap();
        assert_eq!(ok, Ok(()));
        let ok: Result<(), String> = decode(&encode(&Ok::<(), DeskRefusal>(())).unwrap()).unwrap();
        assert_eq!(ok, Ok(()));
    }

    #[test]
    fn no_run_datamanager_is_told_in_the_words_of_before() {
        assert_eq!(
            NoRunDm.to_string(),
            "no run datamanager `run` in the cluster: a dispatched run records its progress \
             there so that a standby can take it over (a node config hosts it: \
             `[[datamanager]] name = \"run\"`, best with copies on other nodes)"
        );
    }
}

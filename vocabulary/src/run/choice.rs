//! A choice among live instances of an operation, as a run records it: every candidate with
//! its verdict (chosen, lost, rejected) and why — what `--explain`, the `selected` event and
//! the report's `selection` show. The choosing itself is the dispatcher's
//! (`dispatcher::selection`).

use serde::{Deserialize, Serialize};

/// What became of a candidate.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Verdict {
    /// It was chosen.
    Chosen,
    /// It could serve, but another ranked higher.
    Lost {
        /// Why the chosen one was preferred.
        reason: String,
    },
    /// The mission cannot use it.
    Rejected {
        /// Why.
        reason: String,
    },
}

/// One candidate as the explanation shows it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Candidate {
    /// Its actor's address.
    pub address: String,
    /// Its node.
    pub node: String,
    /// Its version.
    pub version: String,
    /// The names of the parameters its schema declares.
    pub schema: Vec<String>,
    /// The names of the condition flags it declares it can raise.
    #[serde(default)]
    pub flags: Vec<String>,
    /// What became of it.
    pub verdict: Verdict,
}

/// The choice for one operation: every candidate with its verdict.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Choice {
    /// The operation, as the mission names it.
    pub operation: String,
    /// The candidates, in the order they were offered.
    pub candidates: Vec<Candidate>,
    /// When the choice is of a stand-in after a failure: the address of the instance it
    /// replaces (`None` for the binding at the mission's start).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replacing: Option<String>,
}

impl Choice {
    /// The chosen candidate, if one was.
    pub fn chosen(&self) -> Option<&Candidate> {
        self.candidates
            .iter()
            .find(|c| c.verdict == Verdict::Chosen)
    }

    /// Index of the chosen candidate among the offers.
    pub fn chosen_index(&self) -> Option<usize> {
        self.candidates
            .iter()
            .position(|c| c.verdict == Verdict::Chosen)
    }

    /// Why nothing was chosen: every candidate's reason, or that there was none.
    pub fn why_none(&self) -> String {
        if self.candidates.is_empty() {
            return format!("operation `{}` has no live instance", self.operation);
        }
        let reasons: Vec<String> = self
            .candidates
            .iter()
            .map(|c| match &c.verdict {
                Verdict::Rejected { reason } | Verdict::Lost { reason } => {
                    format!(
                        "{} on {} (version {}): {reason}",
                        c.address, c.node, c.version
                    )
                }
                Verdict::Chosen => format!("{} on {}: chosen", c.address, c.node),
            })
            .collect();
        format!(
            "no instance of operation `{}` fits the mission: {}",
            self.operation,
            reasons.join("; ")
        )
    }
}

//! What a node's desk does: run the cluster's missions (active) or stand by.

use serde::{Deserialize, Serialize};
use std::time::Duration;

/// How long an active node's desk lets a standby take a lost run over first.
pub const ACTIVE_STAGGER: Duration = Duration::from_secs(1);

/// What a node's desk does ([`crate::node::NodeConfig::desk`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeskRole {
    /// Runs the cluster's missions (`marie up --run` dispatches here), and takes a lost
    /// dispatcher's run over after [`ACTIVE_STAGGER`].
    Active,
    /// Takes a lost dispatcher's run over at once.
    Standby,
}

impl DeskRole {
    /// As a config writes it.
    pub fn label(self) -> &'static str {
        match self {
            DeskRole::Active => "active",
            DeskRole::Standby => "standby",
        }
    }

    /// How long it waits before taking a lost run over, and by how much it raises the
    /// term: an active desk that takes over after a standby did fences the standby off.
    pub(super) fn rank(self) -> (Duration, u64) {
        match self {
            DeskRole::Standby => (Duration::ZERO, 1),
            DeskRole::Active => (ACTIVE_STAGGER, 2),
        }
    }
}

/// A word that names no [`DeskRole`] (a node config's `dispatcher = "..."`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is not a dispatcher role: active or standby (or true, false)")]
pub struct UnknownDeskRole(pub String);

impl std::str::FromStr for DeskRole {
    type Err = UnknownDeskRole;
    fn from_str(s: &str) -> Result<DeskRole, UnknownDeskRole> {
        match s {
            "active" => Ok(DeskRole::Active),
            "standby" => Ok(DeskRole::Standby),
            other => Err(UnknownDeskRole(other.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_role_reads_as_a_config_writes_it_and_another_word_is_refused_in_those_words() {
        for role in [DeskRole::Active, DeskRole::Standby] {
            assert_eq!(role.label().parse(), Ok(role));
        }
        assert_eq!(
            "yes".parse::<DeskRole>().unwrap_err().to_string(),
            "`yes` is not a dispatcher role: active or standby (or true, false)"
        );
    }
}

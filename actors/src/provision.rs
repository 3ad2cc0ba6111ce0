//! Asking the cluster for a new instance of an operation, when no compatible one runs
//! anywhere.
//!
//! A node that can start instances on request (its config allows the operation: OTP's
//! `simple_one_for_one`) runs a provisioner actor in `pg` (scope [`SCOPE`], group
//! [`GROUP`]); the dispatcher, when a binding is lost and no stand-in can be adopted, asks
//! them in turn — its own node's first — with [`request`], and adopts the new instance when
//! it publishes itself in the registry, like any stand-in.
//!
//! ```no_run
//! # async fn demo() {
//! use marie_actors::provision;
//! let req = semver::VersionReq::parse("^1").unwrap();
//! match provision::request("wall-follower", &req).await {
//!     Ok(node) => println!("a new wall follower starts on {node}"),
//!     Err(e) => println!("nobody can start one: {e}"),
//! }
//! # }
//! ```

use ractor::rpc::CallResult;
use ractor::{pg, ActorCell, ActorRef};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// The `pg` scope of provisioners.
pub const SCOPE: &str = "marie-provision";
/// The `pg` group of provisioners.
pub const GROUP: &str = "provision";
/// How long a dispatcher's lost binding waits for a stand-in — a supervisor's restart, a
/// spare instance anywhere in the cluster — before it asks the provisioners to start one:
/// 1 s, or half the mission's rebind deadline if that is shorter. A restart or a spare
/// usually shows up sooner; a lost node's instances never do, and a standby (an operation
/// a node hosts with `instances = 0`) is started only then.
pub const GRACE: Duration = Duration::from_secs(1);

/// How long one provisioner may take to start an instance.
pub const TIMEOUT: Duration = Duration::from_secs(5);

marie_vocabulary::remote_message! {
    /// Messages of a provisioner.
    pub enum ProvisionMsg {
        /// Start an instance of `operation` of a version matching `version` (a semver
        /// requirement); the answer names the node, or why not.
        Start {
            /// The operation's name.
            operation: String,
            /// The version requirement, e.g. `^1.0.0`.
            version: String,
        } -> Result<String, Refusal>,
    }
}

/// Why a provisioner did not start an instance. It answers [`ProvisionMsg::Start`] across
/// nodes, so its serialized shape is wire format: variant names are tags (never rename
/// them), fields may be added with `#[serde(default)]`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum Refusal {
    /// The version requirement asked for does not parse.
    #[error("`{requirement}` is not a version requirement: {reason}")]
    Requirement {
        /// The requirement as sent.
        requirement: String,
        /// Why it does not parse.
        reason: String,
    },
    /// The node's config does not allow the operation (in a matching version).
    #[error("node `{node}` does not host operation `{operation}` (its config allows: {allowed})")]
    NotAllowed {
        /// The node.
        node: String,
        /// The operation asked for, `name@requirement`.
        operation: String,
        /// What its config allows, `name@requirement` listed.
        allowed: String,
    },
    /// The node allows the operation, but starting it failed.
    #[error("{reason}")]
    Failed {
        /// The node.
        node: String,
        /// The operation asked for, `name@requirement`.
        operation: String,
        /// What went wrong.
        reason: String,
    },
    /// The provisioner did not answer within [`TIMEOUT`] (recorded by the asker; never sent).
    #[error("provisioner {provisioner} did not answer")]
    Silent {
        /// The provisioner's actor.
        provisioner: String,
    },
    /// A refusal in words only: what a node of an earlier build answers (its refusals were
    /// plain text).
    #[error("{0}")]
    #[serde(untagged)]
    Text(String),
}

/// Why no instance could be provisioned.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProvisionError {
    /// No node runs a provisioner.
    #[error("no node offers to start instances")]
    NoProvisioner,
    /// Every provisioner refused, each for its reason (in the order asked).
    #[error("{}", .refusals.iter().map(Refusal::to_string).collect::<Vec<_>>().join("; "))]
    Refused {
        /// Each provisioner's refusal.
        refusals: Vec<Refusal>,
    },
}

/// Publish `cell` as a provisioner.
pub fn publish(cell: ActorCell) {
    pg::join_scoped(SCOPE.into(), GROUP.into(), vec![cell]);
}

/// Ask the provisioners, local first, to start an instance of `operation` matching
/// `version`, until one does: its node's name — or every refusal.
pub async fn request(
    operation: &str,
    version: &semver::VersionReq,
) -> Result<String, ProvisionError> {
    let mut members = pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string());
    members.sort_by_key(|c| !c.get_id().is_local());
    if members.is_empty() {
        return Err(ProvisionError::NoProvisioner);
    }
    let mut refusals = Vec::new();
    for cell in members {
        let actor: ActorRef<ProvisionMsg> = cell.into();
        let answer = actor
            .call(
                |reply| ProvisionMsg::Start {
                    operation: operation.to_string(),
                    version: version.to_string(),
                    reply,
                },
                Some(TIMEOUT),
            )
            .await;
        match answer {
            Ok(CallResult::Success(Ok(node))) => return Ok(node),
            Ok(CallResult::Success(Err(why))) => refusals.push(why),
            _ => refusals.push(Refusal::Silent {
                provisioner: actor.get_id().to_string(),
            }),
        }
    }
    Err(ProvisionError::Refused { refusals })
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::wire::{decode, encode};

    #[test]
    fn a_refusal_crosses_nodes_as_data_and_an_earlier_builds_text_still_reads() {
        let refusals = [
            Refusal::Requirement {
                requirement: "^x".into(),
                reason: "unexpected character".into(),
            },
            Refusal::NotAllowed {
                node: "n1".into(),
                operation: "pump@^1".into(),
                allowed: "valve@*".into(),
            },
            Refusal::Failed {
                node: "n1".into(),
                operation: "pump@^1".into(),
                reason: "node supervisor: it gave up".into(),
            },
            Refusal::Text("anything".into()),
        ];
        for refusal in refusals {
            let answer: Result<String, Refusal> = Err(refusal);
            let back: Result<String, Refusal> = decode(&encode(&answer).unwrap()).unwrap();
            assert_eq!(back, answer);
        }
        // a node of an earlier build answered `Result<String, String>`
        let old: Result<String, String> = Err("node `n2` does not host operation `x`".into());
        let back: Result<String, Refusal> = decode(&encode(&old).unwrap()).unwrap();
        assert_eq!(
            back,
            Err(Refusal::Text(
                "node `n2` does not host operation `x`".into()
            ))
        );
        let ok: Result<String, Refusal> = decode(&encode(&Ok::<_, String>("n3")).unwrap()).unwrap();
        assert_eq!(ok, Ok("n3".to_string()));
    }

    #[test]
    fn every_refusal_is_told_in_the_words_of_before() {
        let e = ProvisionError::Refused {
            refusals: vec![
                Refusal::NotAllowed {
                    node: "n1".into(),
                    operation: "pump@^1".into(),
                    allowed: "valve@*".into(),
                },
                Refusal::Silent {
                    provisioner: "0.42".into(),
                },
            ],
        };
        assert_eq!(
            e.to_string(),
            "node `n1` does not host operation `pump@^1` (its config allows: valve@*); \
             provisioner 0.42 did not answer"
        );
        assert_eq!(
            ProvisionError::NoProvisioner.to_string(),
            "no node offers to start instances"
        );
    }
}

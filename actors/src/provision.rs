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
//!     Err(refusals) => println!("nobody can start one: {}", refusals.join("; ")),
//! }
//! # }
//! ```

use ractor::rpc::CallResult;
use ractor::{pg, ActorCell, ActorRef};
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

crate::remote_message! {
    /// Messages of a provisioner.
    pub enum ProvisionMsg {
        /// Start an instance of `operation` of a version matching `version` (a semver
        /// requirement); the answer names the node, or says why not.
        Start {
            /// The operation's name.
            operation: String,
            /// The version requirement, e.g. `^1.0.0`.
            version: String,
        } -> Result<String, String>,
    }
}

/// Publish `cell` as a provisioner.
pub fn publish(cell: ActorCell) {
    pg::join_scoped(SCOPE.into(), GROUP.into(), vec![cell]);
}

/// Ask the provisioners, local first, to start an instance of `operation` matching
/// `version`, until one does: its node's name — or every refusal.
pub async fn request(operation: &str, version: &semver::VersionReq) -> Result<String, Vec<String>> {
    let mut members = pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string());
    members.sort_by_key(|c| !c.get_id().is_local());
    if members.is_empty() {
        return Err(vec!["no node offers to start instances".into()]);
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
            _ => refusals.push(format!("provisioner {} did not answer", actor.get_id())),
        }
    }
    Err(refusals)
}

//! A hung datamanager is restarted, as a hung operation is: nothing else would notice.
//!
//! A dispatcher kills an operation that misses its answer deadline, and its supervisor
//! restarts it. A datamanager answers whoever asks, so no one owns its deadline: a DM stuck
//! in a handler (a `hang` fault, a bug) would leave every client timing out forever while
//! its supervisor sees nothing wrong. The watchdog asks each datamanager the node hosts for
//! its own stats every [`PERIOD`]; one that does not answer within [`DEADLINE`] is killed,
//! and its supervisor restarts it (an abnormal exit, within the supervisor's restart
//! intensity).
//!
//! "Each datamanager the node hosts" is what the node's datamanager supervisor runs at each
//! look, not a list fixed at the node's start: a replica added while the node runs (`marie
//! dm add-replica`, `replace_after`) is watched from the next period, one dropped is not, a
//! replica that follows a leader elsewhere is watched as the leader is. Each is asked
//! [`DmMsg::ReplicaStats`], which every datamanager answers itself, whatever its role (a
//! follower sends `Stats` on to its leader: a hung leader on another node would have its
//! followers here killed).
//!
//! Both are measured on the runtime's timer: real time on a node, and in a simulation's
//! paused runtime virtual time, which stands still while a DM works — so a DM busy with a
//! long backlog is never taken for hung there; on a real node the deadline is generous
//! (twice a client's request deadline) for the same reason.

use super::tree;
use marie_dm::{DmClient, DmMsg};
use marie_supervision::SupervisorRef;
use ractor::rpc::CallResult;
use ractor::{ActorCell, ActorRef};
use std::time::Duration;
use tokio::task::JoinHandle;

/// How often each of the node's datamanagers is asked.
pub const PERIOD: Duration = Duration::from_secs(2);

/// How long a datamanager may take to answer before it is taken for hung and killed.
pub const DEADLINE: Duration = Duration::from_secs(2 * DmClient::DEFAULT_TIMEOUT.as_secs());

/// Watch every datamanager the node rooted at `root` hosts, until aborted.
pub(super) fn spawn(root: SupervisorRef) -> JoinHandle<()> {
    tokio::spawn(async move {
        let mut ticks = tokio::time::interval(PERIOD);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            ticks.tick().await;
            for (name, dm) in hosted(&root).await {
                let actor = ActorRef::<DmMsg>::from(dm.clone());
                let answer = actor
                    .call(|reply| DmMsg::ReplicaStats { reply }, Some(DEADLINE))
                    .await;
                if matches!(answer, Ok(CallResult::Timeout)) {
                    tracing::warn!(dm = %name, actor = %dm.get_id(), deadline = ?DEADLINE,
                        "datamanager hung: killed, for its supervisor to restart");
                    dm.kill();
                }
            }
        }
    })
}

/// The datamanagers the node's datamanager supervisor runs now, by name (none while it has
/// no such supervisor: a node that hosts a replica only once one is added).
async fn hosted(root: &SupervisorRef) -> Vec<(String, ActorCell)> {
    let Ok(sup) = tree::child_supervisor(root, tree::DATAMANAGERS).await else {
        return Vec::new();
    };
    sup.which_children()
        .await
        .unwrap_or_default()
        .into_iter()
        .filter_map(|c| c.state.actor().cloned().map(|a| (c.id, a)))
        .collect()
}

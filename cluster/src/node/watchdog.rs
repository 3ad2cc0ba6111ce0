//! A hung datamanager is restarted, as a hung operation is: nothing else would notice.
//!
//! A dispatcher kills an operation that misses its answer deadline, and its supervisor
//! restarts it. A datamanager answers whoever asks, so no one owns its deadline: a DM stuck
//! in a handler (a `hang` fault, a bug) would leave every client timing out forever while
//! its supervisor sees nothing wrong. The watchdog asks each of the node's own DMs for its
//! stats every [`PERIOD`]; one that does not answer within [`DEADLINE`] is killed, and its
//! supervisor restarts it (an abnormal exit, within the supervisor's restart intensity).
//!
//! Both are measured on the runtime's timer: real time on a node, and in a simulation's
//! paused runtime virtual time, which stands still while a DM works — so a DM busy with a
//! long backlog is never taken for hung there; on a real node the deadline is generous
//! (twice a client's request deadline) for the same reason.

use marie_dm::{DmClient, DmMsg};
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::time::Duration;
use tokio::task::JoinHandle;

/// How often each of the node's datamanagers is asked.
pub const PERIOD: Duration = Duration::from_secs(2);

/// How long a datamanager may take to answer before it is taken for hung and killed.
pub const DEADLINE: Duration = Duration::from_secs(2 * DmClient::DEFAULT_TIMEOUT.as_secs());

/// Watch the datamanagers named `names` that run in this process, until aborted.
pub(super) fn spawn(names: Vec<String>) -> JoinHandle<()> {
    tokio::spawn(async move {
        let mut ticks = tokio::time::interval(PERIOD);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            ticks.tick().await;
            for name in &names {
                for dm in registry::lookup(ModuleKind::Datamanager, name) {
                    if !dm.is_local() {
                        continue;
                    }
                    let actor = ActorRef::<DmMsg>::from(dm.actor.clone());
                    let answer = actor
                        .call(|reply| DmMsg::Stats { reply }, Some(DEADLINE))
                        .await;
                    if matches!(answer, Ok(CallResult::Timeout)) {
                        tracing::warn!(dm = %name, actor = %dm.actor.get_id(), deadline = ?DEADLINE,
                            "datamanager hung: killed, for its supervisor to restart");
                        dm.actor.kill();
                    }
                }
            }
        }
    })
}

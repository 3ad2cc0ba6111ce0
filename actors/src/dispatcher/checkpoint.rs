//! Checkpoints: a run's progress as its dispatcher records it at every transition, in the
//! run datamanager ([`RUN`](marie_dm::RUN), kept in replicas on other nodes), so that a
//! standby dispatcher can take the run over when the dispatcher's node is lost.
//!
//! A [`Checkpoint`] is everything a standby needs to carry the run on: the run's id, the
//! mission and its hash, the status word, which actions are done, the running action (its
//! operations still running, its enders done, whether it is ending), every binding with
//! its instance, epoch and the parameters sent last, and the dispatcher's *term*. It is
//! stored as one record (class [`CHECKPOINT_CLASS`], sub-class the run's id) stamped with
//! the term as its epoch, from the source [`CHECKPOINT_SOURCE`]`/RUN-ID`: the datamanager's
//! fence ([`marie_vocabulary::fence`]) then refuses every checkpoint of the run of an older
//! term once a newer one was stored — of that run only: each run's terms count from 1, and
//! a run after one that was taken over (term 2) is not fenced off by it. That refusal is how a dispatcher learns that a standby carries its run on (it
//! was frozen, or cut off, and declared lost): it stops without ending the run.
//!
//! # Invariants
//! - Checkpoints are written in the order of the transitions, one at a time.
//! - What raises an epoch — the run's first bindings, an adoption, a takeover —, an
//!   action's start and the run's end wait for their checkpoint before any command or
//!   `run_ended` goes out: a dispatcher that has been replaced can never outbid its
//!   successor's epochs, nor end the run, and a standby never carries on from an action
//!   older than the one whose commands went out. The other transitions (an operation's
//!   report, an action's end) are recorded as they happen, without waiting: their commands
//!   carry epochs already in force, which the operations fence, and an operation whose
//!   report a standby never saw is attached again (or resumed, if it ended).
//! - A dispatcher one of whose checkpoints a newer term refused commands nothing more: it
//!   is fenced off before it handles another message (the writer's refusal is read before
//!   every message, not only when its `Fenced` comes through the mailbox) or, when it was
//!   waiting for that checkpoint, at once. So an epoch it raised and could not store —
//!   an adoption raises the epoch above the instance's, which may be its successor's —
//!   never reaches an operation its successor holds.
//! - A checkpoint that cannot be stored for want of the datamanager (its leader failing
//!   over, a partition, a node of its replicas restarting) is retried until it is stored or
//!   refused — for at most [`MAJORITY_WAIT`]: a run datamanager without a majority for that
//!   long is an outcome, not a wait without end. The dispatcher is told
//!   ([`DispatcherMsg::NoMajority`]) with a reason naming the datamanager and the nodes it
//!   misses, and ends the run as failed without storing its end (it cannot); a task goes on
//!   trying to store that end for [`END_AFTERLIFE`], so that no standby takes over a run
//!   that ended once the majority is back.

use super::messages::DispatcherMsg;
use super::mission::Mission;
use marie_dm::{DmClient, DmError, Query, MAJORITY_WAIT, VIEW_TIMEOUT};
use marie_vocabulary::property::ParamMap;
use marie_vocabulary::run::Outcome;
use ractor::ActorRef;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

/// The class of checkpoint records in the run datamanager.
pub const CHECKPOINT_CLASS: &str = "checkpoint";
/// The source checkpoints are stored under, followed by `/` and the run's id (the term is
/// their epoch, fenced per run).
pub const CHECKPOINT_SOURCE: &str = "dispatcher";
/// How many checkpoints the run datamanager keeps (of all runs together, the newest), unless
/// its declaration bounds the class otherwise: a standby reads only the newest, and a run's
/// check counts an older one gone as dropped by retention, not lost. Unbounded but for the
/// datamanagers' default (10 000 records a class, some 4 KiB each), every replica of a kept-up
/// cluster's run datamanager held every run's checkpoints — tens of MB after a soak of a few
/// hundred runs. A docking run writes some 35.
pub const CHECKPOINTS_KEPT: usize = 512;
/// How long a checkpoint write waits before it is tried again.
const RETRY: Duration = Duration::from_millis(200);
/// How long the end of a run that ended for want of a majority is still tried, once its
/// dispatcher has stopped (see the module invariants).
pub const END_AFTERLIFE: Duration = Duration::from_secs(300);

/// A run's progress at one transition (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The run's id.
    pub run: String,
    /// The term of the dispatcher that wrote it: 1 for the run's first, one more for each
    /// takeover.
    pub term: u64,
    /// Its number among its term's checkpoints.
    pub seq: u64,
    /// The node of the dispatcher that wrote it.
    pub node: String,
    /// The mission.
    pub mission: Mission,
    /// A hash of the mission ([`Checkpoint::hash_of`]), to tell two missions apart.
    pub mission_hash: u64,
    /// Mission time since the run began, ms.
    pub run_ms: u64,
    /// The node's clock when the run began, ms: a cluster's nodes read one clock
    /// (`ScaledClock::cluster`), so a standby's run time carries on from the same start.
    pub started_ms: u64,
    /// Wall-clock time it was written, ms since the Unix epoch.
    pub unix_ms: u64,
    /// The status word.
    pub status: u32,
    /// Which actions are done, in file order.
    pub done: Vec<bool>,
    /// The generation of the latest action started.
    pub generation: u64,
    /// The actions that run or end (more than one under a parallel).
    pub live: Vec<CurrentCheckpoint>,
    /// The state of the mission's tree, by node id
    /// ([`Tree::state`](super::tree::Tree::state)): a standby carries on mid-retry,
    /// mid-fallback, with the same timeouts.
    pub tree: Vec<super::tree::NodeState>,
    /// Actions the tree started that waited for halted ones to end.
    pub pending: Vec<usize>,
    /// Why the latest action failed.
    pub failure: Option<String>,
    /// Every binding.
    pub bindings: Vec<BindingCheckpoint>,
    /// The run's outcome, once it ended.
    pub ended: Option<Outcome>,
    /// The writing dispatcher's actor number on its node (`None` from a build before it):
    /// a desk that sees one dispatcher of a node leave takes the run over only if that one
    /// wrote the newest checkpoint — not when a superseded dispatcher of the same node is
    /// stopped while the node's new one carries the run.
    #[serde(default)]
    pub writer: Option<u64>,
    /// Who follows the run (the requester's event watcher), if it was asked for by
    /// another node (`None` from a build before it, and for a run of the dispatcher's own
    /// node): a desk restarted after its dispatcher's process died resumes the run only
    /// while that watcher is still in reach — a cluster started again on old data
    /// directories leaves a run nobody waits for alone.
    #[serde(default)]
    pub watcher: Option<RunWatcher>,
}

/// The event watcher of whoever asked for a run ([`Checkpoint::watcher`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunWatcher {
    /// Its node.
    pub node: String,
    /// Its actor number there.
    pub pid: u64,
}

/// The running action in a [`Checkpoint`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CurrentCheckpoint {
    /// Its index among the mission's actions.
    pub index: usize,
    /// Its operations (keys) still running.
    pub running: Vec<String>,
    /// Its enders that finished.
    pub enders_done: Vec<String>,
    /// True once it ended and waits for its suspended operations.
    pub ending: bool,
    /// When it started, ms since the run began.
    pub started_ms: u64,
    /// Whether its operations were activated: an action is recorded before its commands
    /// go out, and a standby launches one that was not.
    #[serde(default)]
    pub launched: bool,
    /// When ending: whether the tree halted it (its end is not the tree's news).
    #[serde(default)]
    pub halted: bool,
    /// When ending: why it failed, if it did.
    #[serde(default)]
    pub failure: Option<String>,
}

/// A binding in a [`Checkpoint`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BindingCheckpoint {
    /// Operation name.
    pub name: String,
    /// The node of the instance held.
    pub node: String,
    /// The instance's actor number on its node.
    pub pid: u64,
    /// The binding's epoch.
    pub epoch: u64,
    /// The parameters sent last.
    pub params: ParamMap,
    /// True while its instance is lost and no stand-in adopted.
    pub lost: bool,
}

impl Checkpoint {
    /// True if the dispatcher of node `node` with actor number `pid` (`None`: any of that
    /// node) wrote it: a desk takes the run over from a lost dispatcher only then. A
    /// superseded dispatcher stopped on the node whose new one carries the run on (a desk
    /// that takes the run back kills its hung one) is not the run's. A checkpoint of a build
    /// that named no writer is weighed by its node alone.
    pub fn written_by(&self, node: &str, pid: Option<u64>) -> bool {
        self.node == node
            && match (pid, self.writer) {
                (Some(lost), Some(writer)) => lost == writer,
                _ => true,
            }
    }

    /// The newest checkpoint in the run datamanager `dm` (of any run: a dispatcher of an
    /// older term can no longer store one once a newer term has).
    pub async fn newest(dm: &DmClient) -> Result<Option<Checkpoint>, DmError> {
        let found = dm
            .select_typed::<Checkpoint>(Query::class(CHECKPOINT_CLASS).newest(1))
            .await?;
        Ok(found.into_iter().next().map(|(_, c)| c))
    }

    /// The hash a checkpoint carries of `mission`: the datamanagers' payload digest
    /// ([`marie_dm::digest`]) of its MessagePack.
    pub fn hash_of(mission: &Mission) -> u64 {
        marie_dm::digest(&rmp_serde::to_vec(mission).unwrap_or_default())
    }
}

/// Where and under which term a dispatcher records its run ([`super::DispatcherArgs`]).
#[derive(Clone, Debug)]
pub struct CheckpointArgs {
    /// The run's id.
    pub run: String,
    /// The dispatcher's term.
    pub term: u64,
    /// The run datamanager (its epoch is set to the term).
    pub dm: DmClient,
    /// Who follows the run, stamped on each checkpoint ([`Checkpoint::watcher`]).
    pub watcher: Option<RunWatcher>,
}

/// Why a checkpoint was not stored: a dispatcher of a newer term carries the run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Superseded {
    /// The newer term.
    pub(super) newer: u64,
}

/// Why [`write`] gave up on a checkpoint.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Unstored {
    /// A newer term refused it.
    Superseded(Superseded),
    /// The run datamanager stored nothing for [`MAJORITY_WAIT`]: why, naming it and the
    /// nodes it misses.
    NoMajority(String),
}

/// A checkpoint to write, and who waits for it.
struct Job {
    checkpoint: Box<Checkpoint>,
    done: Option<oneshot::Sender<Result<(), Superseded>>>,
}

/// The dispatcher's writer of checkpoints: a task that stores them in order (see the
/// module invariants), and tells the dispatcher [`DispatcherMsg::Fenced`] once one is
/// refused for a newer term.
pub(super) struct Checkpointer {
    pub(super) run: String,
    pub(super) term: u64,
    seq: u64,
    /// The dispatcher's actor number, stamped on each checkpoint ([`Checkpoint::writer`]).
    pid: u64,
    /// Who follows the run, stamped on each checkpoint ([`Checkpoint::watcher`]).
    watcher: Option<RunWatcher>,
    /// The run datamanager, at the term's epoch.
    dm: DmClient,
    jobs: mpsc::UnboundedSender<Job>,
    /// The newer term that refused a checkpoint (0: none yet), set by the writing task
    /// the moment it is refused. Read by the dispatcher before every message it handles:
    /// [`DispatcherMsg::Fenced`] queues behind what already waits in its mailbox, and a
    /// dispatcher that handled those first would command a run its successor holds — with
    /// epochs it raised above the successor's (an adoption reads the instance's epoch) and
    /// could not store (the soak's `suspended by another party`).
    superseded: Arc<AtomicU64>,
    /// The writing task, aborted with the dispatcher: a write it retries for a dispatcher
    /// that stopped must not land later.
    task: tokio::task::JoinHandle<()>,
}

impl Drop for Checkpointer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl Checkpointer {
    /// Start writing `args`' checkpoints for `dispatcher`.
    pub(super) fn start(args: CheckpointArgs, dispatcher: ActorRef<DispatcherMsg>) -> Checkpointer {
        let (jobs, mut rx) = mpsc::unbounded_channel::<Job>();
        let pid = dispatcher.get_id().pid();
        let superseded = Arc::new(AtomicU64::new(0));
        let refused = superseded.clone();
        // fenced per run: a term counts within its run only
        let dm = args
            .dm
            .with_source(&format!("{CHECKPOINT_SOURCE}/{}", args.run))
            .with_epoch(args.term);
        let run = args.run.clone();
        let writer_dm = dm.clone();
        let task = tokio::spawn(async move {
            let dm = writer_dm;
            // once given up for want of a majority, every later job is dropped as the one
            // given up on was: its waiter never hears it stored (the run's end concludes all
            // the same: see `checkpoint_end`)
            let mut given_up = false;
            while let Some(job) = rx.recv().await {
                if given_up {
                    continue;
                }
                match write(&dm, &run, &job.checkpoint, MAJORITY_WAIT).await {
                    Ok(()) => {
                        if let Some(done) = job.done {
                            let _ = done.send(Ok(()));
                        }
                    }
                    Err(Unstored::Superseded(superseded)) => {
                        refused.store(superseded.newer.max(1), Ordering::SeqCst);
                        let _ = dispatcher.cast(DispatcherMsg::Fenced {
                            newer: superseded.newer,
                        });
                        if let Some(done) = job.done {
                            let _ = done.send(Err(superseded));
                        }
                        break; // nothing more of this term is stored
                    }
                    Err(Unstored::NoMajority(reason)) => {
                        given_up = true;
                        let _ = dispatcher.cast(DispatcherMsg::NoMajority { reason });
                    }
                }
            }
        });
        Checkpointer {
            run: args.run,
            term: args.term,
            seq: 0,
            pid,
            watcher: args.watcher,
            dm,
            jobs,
            superseded,
            task,
        }
    }

    /// The newer term that refused one of this writer's checkpoints, if one did: the
    /// dispatcher is fenced off from then on, whatever its mailbox still holds.
    pub(super) fn superseded(&self) -> Option<Superseded> {
        match self.superseded.load(Ordering::SeqCst) {
            0 => None,
            newer => Some(Superseded { newer }),
        }
    }

    /// Number `checkpoint` (the next of this writer's) and name its writer and watcher.
    fn stamp(&mut self, checkpoint: &mut Checkpoint) {
        self.seq += 1;
        checkpoint.seq = self.seq;
        checkpoint.writer = Some(self.pid);
        checkpoint.watcher = self.watcher.clone();
    }

    /// Number `checkpoint` and queue it; the receiver says when it is stored (or refused).
    pub(super) fn write(
        &mut self,
        mut checkpoint: Checkpoint,
    ) -> oneshot::Receiver<Result<(), Superseded>> {
        self.stamp(&mut checkpoint);
        let (tx, rx) = oneshot::channel();
        let job = Job {
            checkpoint: Box::new(checkpoint),
            done: Some(tx),
        };
        if let Err(mpsc::error::SendError(job)) = self.jobs.send(job) {
            // the writer stopped after a refusal: so is this one
            if let Some(done) = job.done {
                let refused = self.superseded().unwrap_or(Superseded {
                    newer: self.term + 1,
                });
                let _ = done.send(Err(refused));
            }
        }
        rx
    }
}

impl Checkpointer {
    /// Number the end of a run that ended for want of the run datamanager's majority and
    /// store it once it has one again, for at most [`END_AFTERLIFE`], in a task of its own
    /// (the dispatcher stops): refused by a newer term or given up, nothing more is done.
    pub(super) fn store_end_later(mut self, mut checkpoint: Checkpoint) {
        self.stamp(&mut checkpoint);
        store_end_later(self.dm.clone(), checkpoint);
    }
}

/// See [`Checkpointer::store_end_later`].
fn store_end_later(dm: DmClient, checkpoint: Checkpoint) {
    tokio::spawn(async move {
        let run = checkpoint.run.clone();
        match write(&dm, &run, &checkpoint, END_AFTERLIFE).await {
            Ok(()) => tracing::info!(%run, "the end of the run is stored: its majority is back"),
            Err(why) => tracing::warn!(%run, ?why, "the end of the run was never stored"),
        }
    });
}

/// Store `checkpoint` until it is stored, refused for a newer term, or nothing was stored
/// for `patience`.
async fn write(
    dm: &DmClient,
    run: &str,
    checkpoint: &Checkpoint,
    patience: Duration,
) -> Result<(), Unstored> {
    let since = tokio::time::Instant::now();
    let mut tries = 0u32;
    loop {
        match dm
            .store(CHECKPOINT_CLASS, Some(run), None, checkpoint)
            .await
        {
            Ok(seq) => {
                tracing::debug!(
                    run,
                    term = checkpoint.term,
                    n = checkpoint.seq,
                    seq,
                    generation = checkpoint.generation,
                    "checkpoint stored"
                );
                return Ok(());
            }
            Err(DmError::Fenced(stale)) => {
                tracing::warn!(
                    run,
                    term = checkpoint.term,
                    newer = stale.current,
                    "checkpoint refused: a newer dispatcher carries the run on"
                );
                return Err(Unstored::Superseded(Superseded {
                    newer: stale.current,
                }));
            }
            Err(e) if since.elapsed() >= patience => {
                let why = match marie_dm::without_leader(dm.dm_name(), VIEW_TIMEOUT).await {
                    Some(lost) => lost.to_string(),
                    None => format!(
                        "datamanager `{}` stored no checkpoint for {} s: {e}",
                        dm.dm_name(),
                        patience.as_secs()
                    ),
                };
                tracing::warn!(run, %why, tries, "checkpoint given up");
                return Err(Unstored::NoMajority(format!(
                    "the run's progress could not be recorded for {} s: {why}",
                    patience.as_secs()
                )));
            }
            Err(e) => {
                tries += 1;
                if tries == 1 || tries % 25 == 0 {
                    tracing::warn!(run, error = %e, tries, "checkpoint not stored yet; trying again");
                }
                tokio::time::sleep(RETRY).await;
            }
        }
    }
}

/// Wall-clock ms since the Unix epoch.
pub fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dispatcher::mission::ParsedMission;

    fn mission(name: &str) -> Mission {
        let text = format!(
            "[mission]\nname = \"{name}\"\nsuccess = [\"done\"]\n[flags]\ndone = 0\n\
             [[action]]\nname = \"a\"\n[action.ops.op]\n"
        );
        let mut ops = std::collections::BTreeMap::new();
        let mut op = crate::dispatcher::mission::OpInfo::new("op", 1, "1.0.0");
        op.flags = vec![marie_vocabulary::status::FlagDecl::new("done", "done")];
        ops.insert("op".to_string(), op);
        ParsedMission::parse(&text, None)
            .unwrap()
            .validate(&ops)
            .unwrap()
    }

    #[test]
    fn a_checkpoint_crosses_nodes_whole_its_hash_tells_missions_apart_and_it_names_its_writer() {
        let m = mission("m");
        assert_eq!(Checkpoint::hash_of(&m), Checkpoint::hash_of(&m.clone()));
        assert_ne!(Checkpoint::hash_of(&m), Checkpoint::hash_of(&mission("n")));
        let checkpoint = Checkpoint {
            run: "r".into(),
            term: 2,
            seq: 5,
            node: "spare".into(),
            mission_hash: Checkpoint::hash_of(&m),
            mission: m,
            run_ms: 1200,
            started_ms: 7,
            unix_ms: 9,
            status: 1,
            done: vec![false],
            generation: 1,
            live: vec![CurrentCheckpoint {
                index: 0,
                running: vec!["op".into()],
                enders_done: vec![],
                ending: false,
                started_ms: 3,
                launched: true,
                halted: false,
                failure: None,
            }],
            tree: vec![Default::default(); 2],
            pending: vec![],
            failure: None,
            bindings: vec![BindingCheckpoint {
                name: "op".into(),
                node: "n".into(),
                pid: 42,
                epoch: 1000,
                params: Default::default(),
                lost: false,
            }],
            ended: None,
            writer: Some(17),
            watcher: Some(RunWatcher {
                node: "run-1".into(),
                pid: 9,
            }),
        };
        let bytes = rmp_serde::to_vec(&checkpoint).unwrap();
        let back: Checkpoint = rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(back, checkpoint);
        // the run is lost with the dispatcher that wrote it, or with its whole node; not
        // with another dispatcher of that node (a superseded one stopped)
        assert!(checkpoint.written_by("spare", Some(17)));
        assert!(checkpoint.written_by("spare", None));
        assert!(!checkpoint.written_by("spare", Some(16)));
        assert!(!checkpoint.written_by("features", Some(17)));
        let older = Checkpoint {
            writer: None,
            ..checkpoint
        };
        assert!(older.written_by("spare", Some(16)));
    }
}

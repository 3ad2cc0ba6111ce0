//! What became of each node fault of a soak (`marie up --runs N --chaos-nodes SEED`): when
//! its node was back — restarted (the supervisor says when it listened again), let go on
//! after a freeze, its cut healed — and when every replica on it had caught up.
//!
//! No event tells that a follower caught up, so it is measured here, as `marie ls` would
//! see it: every 100 ms, while a member of this process is in the cluster (a run's), every
//! datamanager replica found in the replicas' `pg` scope is asked for its view; the node
//! has caught up once, for every replicated datamanager that has a replica on it, the
//! leader's view reaches that replica and counts it at lag 0 (or the replica leads):
//! [`marie::dm::caught_up`], which `benches/catch_up.rs` measures by too. The time said
//! is from the moment it was back to the end of the first probe that found it so: at most
//! 100 ms and one probe late. Between two runs no member is in the cluster and nothing is
//! probed; after the last run, [`CatchUp::finish`] joins as a member of its own to see the
//! last faults through.

use super::plan::UpPlan;
use super::supervisor::Restarted;
use crate::cli::join::{join, member_name};
use marie::cluster::fault::Struck;
use marie::run::FaultKind;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};
use tokio::task::JoinHandle;

/// How often the replicas are asked, while a fault's node is back and not caught up.
const PROBE_EVERY: Duration = Duration::from_millis(100);
/// How long a replica has to answer a probe (a frozen one does not).
const PROBE_TIMEOUT: Duration = Duration::from_millis(500);
/// How long the soak's end waits for the last faults' nodes to come back and catch up.
const END_WAIT: Duration = Duration::from_secs(60);

/// What became of one node fault.
#[derive(Clone, Debug)]
pub(super) struct Fate {
    /// The strike.
    pub(super) struck: Struck,
    /// The run it struck in, from 1.
    pub(super) run: u32,
    /// How long after the strike its node was back (for a kill: after its process ended,
    /// as the supervisor measured); `None`: not back.
    pub(super) back_after: Option<Duration>,
    /// How long after it was back every replica on it had caught up; `None`: not seen.
    pub(super) caught_up_after: Option<Duration>,
    /// The fault that hit the same node before it had caught up, if one did.
    pub(super) hit_again_by: Option<u64>,
}

impl Fate {
    /// The fault, as the lines name it: `stop-node features, run 3 at 12.4 s`.
    pub(super) fn label(&self) -> String {
        let s = &self.struck;
        let lasting = s
            .strike
            .lasting
            .map(|d| format!(" for {:.1} s", d.as_secs_f64()))
            .unwrap_or_default();
        format!(
            "{} {}{lasting}, run {} at {:.1} s",
            s.strike.kind,
            s.strike.node(),
            self.run,
            s.in_run.as_secs_f64()
        )
    }

    /// Its line: `fault 7 (stop-node features, run 3 at 12.4 s): back 0.21 s after it
    /// struck, caught up 0.84 s after it was back`.
    pub(super) fn line(&self) -> String {
        let head = format!("fault {} ({})", self.struck.number, self.label());
        if let Err(why) = &self.struck.outcome {
            return format!("{head}: not injected: {why}");
        }
        let Some(back) = self.back_after else {
            return match self.hit_again_by {
                Some(n) => format!("{head}: fault {n} hit its node again before it was back"),
                None => format!("{head}: its node was not back by the soak's end"),
            };
        };
        let caught = match (self.caught_up_after, self.hit_again_by) {
            (Some(c), _) => format!("caught up {:.2} s after it was back", c.as_secs_f64()),
            (None, Some(n)) => format!("not caught up before fault {n} hit it again"),
            (None, None) => "not seen caught up by the soak's end".to_string(),
        };
        format!(
            "{head}: back {:.2} s after it struck, {caught}",
            back.as_secs_f64()
        )
    }
}

/// A fault whose fate is not known yet.
struct Pending {
    fate: Fate,
    struck_at: Instant,
    /// When its node was back.
    back_at: Option<Instant>,
}

/// The watch of a soak's faults, running until [`finish`](CatchUp::finish).
pub(super) struct CatchUp {
    end: oneshot::Sender<Instant>,
    task: JoinHandle<Vec<Fate>>,
}

impl CatchUp {
    /// Watch the strikes told on `strikes` and the restarts on `restarted`; `run` says the
    /// run now under way, `speed` turns a freeze's or a cut's mission time into real time.
    pub(super) fn start(
        strikes: mpsc::UnboundedReceiver<Struck>,
        restarted: mpsc::UnboundedReceiver<Restarted>,
        run: Arc<AtomicU32>,
        speed: f64,
    ) -> CatchUp {
        let (end, ending) = oneshot::channel();
        let watch = Watch {
            pending: Vec::new(),
            fates: Vec::new(),
            run,
            speed,
        };
        let task = tokio::spawn(watch.run(strikes, restarted, ending));
        CatchUp { end, task }
    }

    /// The soak's runs are over: see the last faults through as a member of this process's
    /// own (for at most [`END_WAIT`]); every fault's fate, in order.
    pub(super) async fn finish(self, plan: &UpPlan) -> Vec<Fate> {
        let member = match join(&member_name("up"), &plan.first_node()).await {
            Ok(t) => Some(t),
            Err(e) => {
                println!("cannot join the cluster to see the last faults through: {e:#}");
                None
            }
        };
        let _ = self.end.send(Instant::now() + END_WAIT);
        let mut fates = self.task.await.unwrap_or_default();
        if let Some(t) = member {
            t.stop().await;
        }
        fates.sort_by_key(|f| f.struck.number);
        fates
    }
}

/// The watching task's state.
struct Watch {
    pending: Vec<Pending>,
    fates: Vec<Fate>,
    run: Arc<AtomicU32>,
    speed: f64,
}

impl Watch {
    async fn run(
        mut self,
        mut strikes: mpsc::UnboundedReceiver<Struck>,
        mut restarted: mpsc::UnboundedReceiver<Restarted>,
        mut ending: oneshot::Receiver<Instant>,
    ) -> Vec<Fate> {
        let mut tick = tokio::time::interval(PROBE_EVERY);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut deadline: Option<Instant> = None;
        let (mut strikes_open, mut restarts_open) = (true, true);
        loop {
            tokio::select! {
                s = strikes.recv(), if strikes_open => match s {
                    Some(s) => self.struck(s),
                    None => strikes_open = false,
                },
                r = restarted.recv(), if restarts_open => match r {
                    Some(r) => self.restarted(r),
                    None => restarts_open = false,
                },
                at = &mut ending, if deadline.is_none() => {
                    deadline = Some(at.unwrap_or_else(|_| Instant::now()));
                }
                _ = tick.tick() => self.probe().await,
            }
            if let Some(d) = deadline {
                if self.pending.is_empty() || Instant::now() >= d {
                    break;
                }
            }
        }
        for p in std::mem::take(&mut self.pending) {
            self.settle(p.fate);
        }
        self.fates
    }

    /// A strike: its node is out until back; a fault still pending on the same node is
    /// settled as hit again.
    fn struck(&mut self, struck: Struck) {
        let now = Instant::now();
        let run = self.run.load(Ordering::SeqCst);
        let fate = Fate {
            struck,
            run,
            back_after: None,
            caught_up_after: None,
            hit_again_by: None,
        };
        if fate.struck.outcome.is_err() {
            self.settle(fate);
            return;
        }
        let node = fate.struck.strike.node().to_string();
        if let Some(i) = self
            .pending
            .iter()
            .position(|p| p.fate.struck.strike.node() == node)
        {
            let mut before = self.pending.remove(i).fate;
            before.hit_again_by = Some(fate.struck.number);
            self.settle(before);
        }
        // a freeze or a cut ends by itself, its time in mission time
        let back_at = match fate.struck.strike.kind {
            FaultKind::StopNode => None,
            _ => {
                let lasting = fate.struck.strike.lasting.unwrap_or_default();
                Some(now + lasting.div_f64(self.speed.max(f64::MIN_POSITIVE)))
            }
        };
        self.pending.push(Pending {
            fate,
            struck_at: now,
            back_at,
        });
    }

    /// A node restarted: the kill that stopped it is back.
    fn restarted(&mut self, r: Restarted) {
        let kill = self.pending.iter_mut().find(|p| {
            p.back_at.is_none()
                && p.fate.struck.strike.kind == FaultKind::StopNode
                && p.fate.struck.strike.node() == r.node
        });
        match kill {
            Some(p) => {
                p.back_at = Some(r.at);
                p.fate.back_after = Some(r.after);
            }
            None => println!(
                "node {} was restarted without a fault of the soak's stopping it",
                r.node
            ),
        }
    }

    /// Ask the replicas, if a fault's node is back and waits to catch up.
    async fn probe(&mut self) {
        let now = Instant::now();
        if !self
            .pending
            .iter()
            .any(|p| p.back_at.is_some_and(|b| b <= now))
        {
            return;
        }
        let views = marie::dm::replica_views(PROBE_TIMEOUT).await;
        if views.is_empty() {
            // no member of this process in the cluster now (between two runs)
            return;
        }
        let seen = Instant::now();
        let mut i = 0;
        while i < self.pending.len() {
            let p = &self.pending[i];
            let node = p.fate.struck.strike.node();
            match p.back_at {
                Some(back) if back <= now && marie::dm::caught_up(node, &views) => {
                    let mut p = self.pending.remove(i);
                    p.fate.back_after.get_or_insert(back - p.struck_at);
                    p.fate.caught_up_after = Some(seen.saturating_duration_since(back));
                    self.settle(p.fate);
                }
                _ => i += 1,
            }
        }
    }

    /// A fault's fate is known: said, kept.
    fn settle(&mut self, fate: Fate) {
        println!("{}", fate.line());
        self.fates.push(fate);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fate_says_what_became_of_its_fault() {
        use marie::cluster::fault::{NodeStrike, Target};
        let struck = |n: u64, outcome: Result<(), String>| Struck {
            number: n,
            at: Duration::from_secs(40),
            in_run: Duration::from_millis(12_400),
            strike: NodeStrike {
                kind: FaultKind::StopNode,
                target: Target::Node("features".into()),
                lasting: None,
            },
            outcome,
        };
        let mut fate = Fate {
            struck: struck(7, Ok(())),
            run: 3,
            back_after: Some(Duration::from_millis(210)),
            caught_up_after: Some(Duration::from_millis(840)),
            hit_again_by: None,
        };
        assert_eq!(
            fate.line(),
            "fault 7 (stop-node features, run 3 at 12.4 s): back 0.21 s after it struck, \
             caught up 0.84 s after it was back"
        );
        fate.caught_up_after = None;
        fate.hit_again_by = Some(8);
        assert!(fate
            .line()
            .ends_with("not caught up before fault 8 hit it again"));
        fate.back_after = None;
        assert!(fate
            .line()
            .ends_with("fault 8 hit its node again before it was back"));
        fate.hit_again_by = None;
        assert!(fate
            .line()
            .ends_with("its node was not back by the soak's end"));
        fate.struck = struck(9, Err("it is frozen already".into()));
        assert!(fate.line().ends_with("not injected: it is frozen already"));
    }
}

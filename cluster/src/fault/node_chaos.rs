//! Seeded random node faults for `marie up --run … --chaos-nodes SEED`: every 10 to 20 s
//! of mission time, one node other than the spared ones (the cart's: its loss is the
//! robot's) is stopped, frozen for a while, or cut off from all the others for a while.
//!
//! One schedule for however many runs (`marie up --runs N`): its clock is the mission time
//! of the runs it strikes in — from each run's binding to its end —, so the faults keep
//! coming at the same pace from one run to the next instead of starting over with each
//! (a run of 12 s would otherwise never see its first fault). Clones share the schedule;
//! whoever wants to know what it did [watches](NodeChaos::watch) its strikes.

use super::{Chaos, NodeProcesses, Target};
use marie_vocabulary::run::FaultKind;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::sync::mpsc;

/// Shortest gap between two strikes, by default (mission time).
pub const DEFAULT_MIN_GAP: Duration = Duration::from_secs(10);
/// Longest gap between two strikes, by default (mission time).
pub const DEFAULT_MAX_GAP: Duration = Duration::from_secs(20);

/// Random node faults, seeded: the same seed and the same nodes give the same faults at the
/// same times. Cheap to clone; clones share the schedule (see the module's docs).
#[derive(Clone, Debug)]
pub struct NodeChaos {
    schedule: Arc<Mutex<Schedule>>,
    /// Nodes never hit (the cart's).
    spared: Vec<String>,
    /// Shortest a freeze or a cut lasts.
    pub min_lasting: Duration,
    /// Longest a freeze or a cut lasts.
    pub max_lasting: Duration,
}

/// One node fault a [`NodeChaos`] drew.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeStrike {
    /// What.
    pub kind: FaultKind,
    /// To what: a node, or a node cut off from the others.
    pub target: Target,
    /// How long, for a freeze or a cut.
    pub lasting: Option<Duration>,
}

impl NodeStrike {
    /// The node hit (for a cut: the one cut off from the others); empty for a target
    /// that names no node (a strike never has one).
    pub fn node(&self) -> &str {
        match &self.target {
            Target::Cut { a, .. } => a.first().map_or("", String::as_str),
            Target::Node(n) => n,
            _ => "",
        }
    }
}

/// A strike as it went, told to the schedule's [watchers](NodeChaos::watch).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Struck {
    /// Its number in the schedule, from 1.
    pub number: u64,
    /// When, on the schedule's clock: mission time of the runs it struck in.
    pub at: Duration,
    /// When, in mission time since its run began.
    pub in_run: Duration,
    /// What was drawn.
    pub strike: NodeStrike,
    /// Whether it was injected, or why not.
    pub outcome: Result<(), String>,
}

/// Where the schedule stands; a core with time passed in (the runs' clock readings).
#[derive(Debug)]
struct Schedule {
    chaos: Chaos,
    /// Schedule time the runs before the current one added.
    elapsed: Duration,
    /// While a run strikes: its clock's reading when it began to (its binding).
    lap_from: Option<Duration>,
    /// Schedule time of the next strike, once drawn.
    next_at: Option<Duration>,
    /// Strikes so far.
    struck: u64,
    watchers: Vec<mpsc::UnboundedSender<Struck>>,
}

impl Schedule {
    /// The schedule's time when the run's clock reads `now`.
    fn now(&self, now: Duration) -> Duration {
        self.elapsed
            + self
                .lap_from
                .map_or(Duration::ZERO, |f| now.saturating_sub(f))
    }

    /// How long until the next strike, on the run's clock reading `now`.
    fn until_next(&mut self, now: Duration) -> Duration {
        let next = match self.next_at {
            Some(at) => at,
            None => *self.next_at.insert(self.chaos.next_gap()),
        };
        next.saturating_sub(self.now(now))
    }

    /// The strike due was done (or skipped): the next one a gap later.
    fn advance(&mut self) {
        let gap = self.chaos.next_gap();
        let due = self.next_at.unwrap_or_default();
        self.next_at = Some(due + gap);
    }

    fn lap_ends(&mut self, now: Duration) {
        self.elapsed = self.now(now);
        self.lap_from = None;
    }
}

impl NodeChaos {
    /// Node chaos seeded by `seed`, a fault every 10 to 20 seconds of mission time
    /// ([`with_gaps`](Self::with_gaps) changes it), each freeze or cut lasting 2 to 6
    /// seconds of mission time, never touching the `spared` nodes. At wall-clock speed that
    /// is past the failure detector's default deadline (1.2 s of real time), so the peers
    /// declare the node down; a cluster run faster (`--speed 4`: 0.5 to 1.5 s of real time)
    /// may see a short one ride through.
    pub fn new(seed: u64, spared: impl IntoIterator<Item = String>) -> NodeChaos {
        let chaos = Chaos::new(seed).with_gaps(DEFAULT_MIN_GAP, DEFAULT_MAX_GAP);
        NodeChaos {
            schedule: Arc::new(Mutex::new(Schedule {
                chaos,
                elapsed: Duration::ZERO,
                lap_from: None,
                next_at: None,
                struck: 0,
                watchers: Vec::new(),
            })),
            spared: spared.into_iter().collect(),
            min_lasting: Duration::from_secs(2),
            max_lasting: Duration::from_secs(6),
        }
    }

    /// Strike every `min` to `max` of mission time instead.
    pub fn with_gaps(self, min: Duration, max: Duration) -> NodeChaos {
        {
            let mut s = self.lock();
            s.chaos = s.chaos.clone().with_gaps(min, max);
        }
        self
    }

    /// The shortest and the longest gap between two strikes.
    pub fn gaps(&self) -> (Duration, Duration) {
        let s = self.lock();
        (s.chaos.min_gap, s.chaos.max_gap)
    }

    /// Tell every strike from now on to the receiver given (dropped: no longer told).
    pub fn watch(&self) -> mpsc::UnboundedReceiver<Struck> {
        let (tx, rx) = mpsc::unbounded_channel();
        self.lock().watchers.push(tx);
        rx
    }

    /// How many strikes the schedule has made (injected or not).
    pub fn struck(&self) -> u64 {
        self.lock().struck
    }

    /// The time until the next fault, drawn afresh (the schedule's own gaps are drawn as
    /// it strikes).
    pub fn next_gap(&self) -> Duration {
        self.lock().chaos.next_gap()
    }

    /// Draw the next fault among the nodes `processes` may hit now (a stopped node is no
    /// longer among them until it is restarted): a node other than the spared ones, and a
    /// kind among `stop-node`, `freeze-node` and — when the nodes run in a network that can
    /// be cut — `partition` (that node against every other). `None` when no node may be
    /// hit.
    pub fn draw(&self, processes: &NodeProcesses) -> Option<NodeStrike> {
        let all = processes.names();
        let victims: Vec<&String> = all.iter().filter(|n| !self.spared.contains(n)).collect();
        let mut s = self.lock();
        let node = (*s.chaos.pick(&victims)?).clone();
        let mut kinds = vec![FaultKind::StopNode, FaultKind::FreezeNode];
        if processes.can_cut() && all.len() > 1 {
            kinds.push(FaultKind::Partition);
        }
        let kind = *s.chaos.pick(&kinds)?;
        let lasting = kind
            .lasts()
            .then(|| s.chaos.between(self.min_lasting, self.max_lasting));
        let target = match kind {
            FaultKind::Partition => Target::cut_off(&node, &all),
            _ => Target::Node(node),
        };
        Some(NodeStrike {
            kind,
            target,
            lasting,
        })
    }

    /// A run begins to strike, its clock reading `now` (one run at a time).
    pub(crate) fn lap_begins(&self, now: Duration) {
        self.lock().lap_from = Some(now);
    }

    /// The run that struck ends, its clock reading `now`: the schedule's clock stops until
    /// the next run begins (nothing when no run had begun).
    pub(crate) fn lap_ends(&self, now: Duration) {
        let mut s = self.lock();
        if s.lap_from.is_some() {
            s.lap_ends(now);
        }
    }

    /// How long until the next strike is due, on the run's clock reading `now`.
    pub(crate) fn until_next(&self, now: Duration) -> Duration {
        self.lock().until_next(now)
    }

    /// The strike due was `done` (`None`: no node could be hit, skipped), `in_run` into its
    /// run: numbered, told to the watchers; the next one is due a gap later.
    pub(crate) fn done(&self, done: Option<(NodeStrike, Result<(), String>)>, in_run: Duration) {
        let mut s = self.lock();
        let at = s.next_at.unwrap_or_default();
        s.advance();
        let Some((strike, outcome)) = done else {
            return;
        };
        s.struck += 1;
        let struck = Struck {
            number: s.struck,
            at,
            in_run,
            strike,
            outcome,
        };
        s.watchers.retain(|w| w.send(struck.clone()).is_ok());
    }

    fn lock(&self) -> MutexGuard<'_, Schedule> {
        self.schedule.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn thesis() -> NodeProcesses {
        NodeProcesses::new(
            ["cart", "features", "operations", "spare"]
                .into_iter()
                .enumerate()
                .map(|(i, n)| (n.to_string(), 1000 + i as u32)),
        )
    }

    #[test]
    fn node_chaos_is_deterministic_spares_the_cart_and_stays_within_its_bounds() {
        let processes = thesis();
        let a = NodeChaos::new(3, ["cart".to_string()]);
        let b = NodeChaos::new(3, ["cart".to_string()]);
        let mut kinds = std::collections::BTreeSet::new();
        for _ in 0..200 {
            let gap = a.next_gap();
            assert_eq!(gap, b.next_gap());
            assert!((DEFAULT_MIN_GAP..=DEFAULT_MAX_GAP).contains(&gap));
            let strike = a.draw(&processes).unwrap();
            assert_eq!(Some(&strike), b.draw(&processes).as_ref());
            match &strike.target {
                Target::Node(n) => assert_ne!(n, "cart"),
                other => panic!("no network to cut: {other:?}"),
            }
            assert_eq!(strike.lasting.is_some(), strike.kind.lasts());
            if let Some(d) = strike.lasting {
                assert!((a.min_lasting..=a.max_lasting).contains(&d), "{d:?}");
            }
            kinds.insert(strike.kind);
        }
        assert_eq!(
            kinds.into_iter().collect::<Vec<_>>(),
            [FaultKind::StopNode, FaultKind::FreezeNode]
        );
        // only the cart left: nothing to hit
        let cart_only = NodeProcesses::new([("cart".to_string(), 1)]);
        assert_eq!(a.draw(&cart_only), None);
    }

    /// Strike as a run's task does, on a run clock that reads `from`.. `to`: the strikes'
    /// schedule times, their times in the run, and the run clock when each fell.
    fn run(chaos: &NodeChaos, from: Duration, to: Duration) -> Vec<(Duration, Duration)> {
        let processes = thesis();
        let mut now = from;
        chaos.lap_begins(now);
        let mut watch = chaos.watch();
        let mut seen = Vec::new();
        loop {
            let wait = chaos.until_next(now);
            if now + wait >= to {
                break;
            }
            now += wait;
            let strike = chaos.draw(&processes).unwrap();
            chaos.done(Some((strike, Ok(()))), now - from);
            let struck = watch.try_recv().unwrap();
            seen.push((struck.at, struck.in_run));
        }
        chaos.lap_ends(to);
        seen
    }

    #[test]
    fn one_schedule_runs_on_across_runs_as_in_one_long_run() {
        let secs = Duration::from_secs;
        // one run of 200 s
        let long = NodeChaos::new(9, ["cart".to_string()]);
        let whole: Vec<Duration> = run(&long, secs(0), secs(200))
            .into_iter()
            .map(|(at, _)| at)
            .collect();
        // the same 200 s of mission time as five runs of 40 s, each on a clock of its own
        // (a run's clock need not start at 0), with time between them that does not count
        let laps = NodeChaos::new(9, ["cart".to_string()]);
        let mut pieces = Vec::new();
        for lap in 0..5u64 {
            let from = secs(1000 * lap + 7);
            for (at, in_run) in run(&laps, from, from + secs(40)) {
                // each strike falls inside its run, at its schedule time less the runs before
                assert_eq!(in_run, at - secs(40 * lap), "{at:?} in lap {lap}");
                pieces.push(at);
            }
        }
        assert_eq!(pieces, whole);
        assert!(whole.len() >= 200 / 20, "{whole:?}");
        for pair in whole.windows(2) {
            assert!((DEFAULT_MIN_GAP..=DEFAULT_MAX_GAP).contains(&(pair[1] - pair[0])));
        }
        assert_eq!(laps.struck(), whole.len() as u64);
    }

    #[test]
    fn a_skipped_strike_keeps_the_pace_and_gaps_can_be_set() {
        let secs = Duration::from_secs;
        let chaos = NodeChaos::new(1, ["cart".to_string()]).with_gaps(secs(3), secs(4));
        assert_eq!(chaos.gaps(), (secs(3), secs(4)));
        let mut watch = chaos.watch();
        chaos.lap_begins(secs(0));
        let first = chaos.until_next(secs(0));
        assert!((secs(3)..=secs(4)).contains(&first));
        // nobody to hit: no strike told, the next one due a gap later
        chaos.done(None, first);
        assert!(watch.try_recv().is_err());
        let second = chaos.until_next(first);
        assert!((secs(3)..=secs(4)).contains(&second));
        assert_eq!(chaos.struck(), 0);
        // between runs the schedule's clock stands still
        chaos.lap_ends(first);
        chaos.lap_begins(secs(500));
        assert_eq!(chaos.until_next(secs(500)), second);
    }
}

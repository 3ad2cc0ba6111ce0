//! The dispatcher running a mission's behaviour tree with real operations: retries,
//! fallbacks, timeouts, recoveries, parallels and reactive conditions, and the two
//! promises a halt makes — the halted action's operations are suspended within the
//! suspension grace, and nothing else starts before they are.
//!
//! The trees are set on validated missions directly ([`Control::new`]); the mission file's
//! syntax for them is tested with the parser.

use marie_actors::dispatcher::mission::{Control, Mission, ParsedMission};
use marie_actors::dispatcher::tree::{Node, Scheduled};
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::{
    spawn_operation, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{Event, EventBus, EventKind};
use marie_vocabulary::property::{ParamDecl, ParamSchema};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::{OpEnd, Outcome};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::time::timeout;

const T: Duration = Duration::from_secs(60);

/// What happened to an operation, when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Activated,
    /// Finished, failed or suspended: it no longer drives anything.
    Stopped,
}

type Log = Arc<Mutex<Vec<(String, Phase, Instant)>>>;

/// A test operation: fails its first `fail_first` activations at its first step, then
/// finishes after `steps` steps (parameter; 0: runs until suspended), raising its flag.
struct Scripted {
    name: String,
    id: u32,
    fail_first: u32,
    activations: u32,
    taken: i64,
    log: Log,
}

impl Scripted {
    fn note(&self, phase: Phase) {
        self.log
            .lock()
            .unwrap()
            .push((self.name.clone(), phase, Instant::now()));
    }
}

impl Operation for Scripted {
    fn identity(&self) -> Identity {
        Identity::new(&self.name, self.id, "1.0.0", "scripted test operation")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("steps", 3).range(0.0, 100_000.0)])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(format!("{}-done", self.name), "finished")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(5)
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.activations += 1;
        self.taken = 0;
        self.note(Phase::Activated);
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken += 1;
        if self.activations <= self.fail_first {
            self.note(Phase::Stopped);
            return Err(OpError::failed(format!(
                "scripted failure {} of {}",
                self.activations, self.fail_first
            )));
        }
        let steps = ctx.params().i64("steps")?;
        if steps > 0 && self.taken >= steps {
            self.note(Phase::Stopped);
            return Ok(Step::Finish(StatusFlags(1)));
        }
        Ok(Step::Continue)
    }
    async fn suspend(&mut self, _: &mut OpContext) -> Result<(), OpError> {
        self.note(Phase::Stopped);
        Ok(())
    }
}

/// Spawn operation `name` (id `id`) failing its first `fail_first` activations.
async fn spawn(name: &str, id: u32, fail_first: u32, log: &Log) {
    let op = Scripted {
        name: name.to_string(),
        id,
        fail_first,
        activations: 0,
        taken: 0,
        log: log.clone(),
    };
    spawn_operation(op, HostOptions::default()).await.unwrap();
}

/// Validate `src` against the running operations and give it the tree `root` (labels from
/// its actions).
async fn mission(src: &str, root: Node) -> Mission {
    let parsed = ParsedMission::parse(src, None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mut mission = parsed.validate(&catalog).expect("mission validates");
    mission.control = Control::new(root, &mission.name, &mission.actions, &[]);
    mission
}

async fn run(mission: Mission) -> (RunReport, Vec<Event>) {
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let mut events = bus.subscribe();
    let report = timeout(T, run_mission(mission, clock, Some(bus)))
        .await
        .expect("mission ends")
        .expect("dispatcher runs");
    let events = events.drain();
    assert_eq!(
        RunReport::from_events(&events),
        report,
        "the report replays"
    );
    (report, events)
}

fn decisions(report: &RunReport) -> Vec<String> {
    report
        .control
        .iter()
        .map(|c| format!("{}: {}", c.item, c.decision))
        .collect()
}

fn started(events: &[Event]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::ActionStarted { action, .. } => Some(action.clone()),
            _ => None,
        })
        .collect()
}

/// When operation `name` was activated the `n`th time (from 0), and when it stopped after.
fn interval(log: &Log, name: &str, n: usize) -> (Instant, Instant) {
    let log = log.lock().unwrap();
    let mine: Vec<_> = log.iter().filter(|(op, ..)| op == name).collect();
    let starts: Vec<usize> = (0..mine.len())
        .filter(|i| mine[*i].1 == Phase::Activated)
        .collect();
    let at = starts[n];
    let stop = mine[at..]
        .iter()
        .find(|(_, p, _)| *p == Phase::Stopped)
        .unwrap_or_else(|| panic!("{name} activation {n} never stopped: {mine:?}"));
    (mine[at].2, stop.2)
}

fn action(i: usize) -> Node {
    Node::Action(i)
}

/// A mission header with flags for operations `ops` (`<op>-done`) and `success`.
fn header(name: &str, ops: &[&str], success: &str) -> String {
    let flags: String = ops
        .iter()
        .enumerate()
        .map(|(i, op)| format!("{op}-done = {i}\n"))
        .collect();
    format!("[mission]\nname = \"{name}\"\nsuccess = [\"{success}-done\"]\n[flags]\n{flags}")
}

#[tokio::test]
async fn a_retried_action_that_fails_once_succeeds_at_its_second_attempt() {
    let log = Log::default();
    spawn("rt-flaky", 4101, 1, &log).await;
    let src = header("retry", &["rt-flaky"], "rt-flaky")
        + "[[action]]\nname = \"pass\"\n[action.ops.rt-flaky]\n";
    let root = Node::Schedule(vec![Scheduled {
        when: 0,
        node: Node::Retry {
            child: Box::new(action(0)),
            attempts: 3,
            backoff: Duration::from_millis(50),
        },
    }]);
    let (report, events) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(decisions(&report), ["retry(pass): retry 2 of 3"]);
    assert_eq!(started(&events), ["pass", "pass"]);
    assert_eq!(report.actions[0].operations[0].ended, OpEnd::Failed);
    assert_eq!(report.actions[1].operations[0].ended, OpEnd::Finished);
}

#[tokio::test]
async fn a_retry_gives_up_after_its_attempts_with_the_last_failure_as_the_reason() {
    let log = Log::default();
    spawn("rt-broken", 4111, 100, &log).await;
    let src = header("give-up", &["rt-broken"], "rt-broken")
        + "[[action]]\nname = \"pass\"\n[action.ops.rt-broken]\n";
    let root = Node::Retry {
        child: Box::new(action(0)),
        attempts: 2,
        backoff: Duration::ZERO,
    };
    let (report, _) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Failed);
    assert!(
        report.reason.contains("scripted failure 2 of 100"),
        "{}",
        report.reason
    );
    assert_eq!(
        decisions(&report),
        [
            "retry(pass): retry 2 of 2",
            "retry(pass): gave up after 2 attempts"
        ]
    );
}

#[tokio::test]
async fn a_fallback_runs_its_next_child_when_the_first_fails() {
    let log = Log::default();
    spawn("fb-corridor", 4121, 100, &log).await;
    spawn("fb-wall", 4122, 0, &log).await;
    let src = header("fallback", &["fb-corridor", "fb-wall"], "fb-wall")
        + "[[action]]\nname = \"corridor\"\n[action.ops.fb-corridor]\n\
           [[action]]\nname = \"wall\"\n[action.ops.fb-wall]\n";
    let root = Node::Fallback(vec![action(0), action(1)]);
    let (report, events) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(
        decisions(&report),
        ["fallback(corridor, wall): fallback to `wall`"]
    );
    assert_eq!(started(&events), ["corridor", "wall"]);
}

#[tokio::test]
async fn a_timeout_halts_its_action_within_the_grace_and_its_recovery_starts_only_after() {
    let log = Log::default();
    // `cruise` never finishes by itself; `recover` runs when its timeout passes
    spawn("to-cruise", 4131, 0, &log).await;
    spawn("to-watch", 4132, 0, &log).await;
    spawn("to-turn", 4133, 0, &log).await;
    let src = header("timeout", &["to-cruise", "to-watch", "to-turn"], "to-turn")
        + "[[action]]\nname = \"cruise\"\n[action.ops.to-cruise]\nsteps = 0\n\
           [action.ops.to-watch]\nsteps = 0\n\
           [[action]]\nname = \"turn\"\n[action.ops.to-turn]\n";
    // the recovery succeeds, but the recovered node fails: a fallback above carries on
    let root = Node::Fallback(vec![
        Node::Recover {
            child: Box::new(Node::Timeout {
                child: Box::new(action(0)),
                limit: Duration::from_millis(300),
            }),
            recovery: Box::new(action(1)),
        },
        Node::Condition(1 << 2),
    ]);
    let (report, events) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let told = decisions(&report);
    assert!(told[0].ends_with("timeout after 0.3 s"), "{told:?}");
    assert!(told[1].ends_with("recovery `turn`"), "{told:?}");
    // both of the halted action's operations were suspended, within the grace
    let halted = &report.actions[0];
    assert_eq!(halted.name, "cruise");
    assert!(
        halted
            .operations
            .iter()
            .all(|o| o.ended == OpEnd::Suspended),
        "{halted:?}"
    );
    let (_, cruise_stopped) = interval(&log, "to-cruise", 0);
    let (_, watch_stopped) = interval(&log, "to-watch", 0);
    let (turn_started, _) = interval(&log, "to-turn", 0);
    assert!(
        cruise_stopped <= turn_started && watch_stopped <= turn_started,
        "the recovery started before the halted action's operations stopped"
    );
    let timeout_at = events
        .iter()
        .find(|e| matches!(e.kind, EventKind::Control { .. }))
        .map(|e| e.at_ms)
        .unwrap();
    let ended_at = events
        .iter()
        .find(|e| matches!(&e.kind, EventKind::ActionEnded { action, .. } if action == "cruise"))
        .map(|e| e.at_ms)
        .unwrap();
    assert!(
        ended_at - timeout_at <= 5_000,
        "halted within the suspension grace: {} ms",
        ended_at - timeout_at
    );
}

#[tokio::test]
async fn no_two_actions_of_a_reactive_sequence_ever_run_at_once() {
    let log = Log::default();
    // each action: an ender that finishes and a companion that runs until suspended
    for (i, name) in ["rs-a", "rs-a2", "rs-b", "rs-b2", "rs-c", "rs-c2"]
        .iter()
        .enumerate()
    {
        spawn(name, 4141 + i as u32, 0, &log).await;
    }
    let src = header(
        "reactive",
        &["rs-a", "rs-a2", "rs-b", "rs-b2", "rs-c", "rs-c2"],
        "rs-c",
    ) + "[[action]]\nname = \"a\"\nends_on = [\"rs-a\"]\n[action.ops.rs-a]\nsteps = 20\n[action.ops.rs-a2]\nsteps = 0\n\
         [[action]]\nname = \"b\"\nends_on = [\"rs-b\"]\n[action.ops.rs-b]\nsteps = 20\n[action.ops.rs-b2]\nsteps = 0\n\
         [[action]]\nname = \"c\"\nends_on = [\"rs-c\"]\n[action.ops.rs-c]\nsteps = 20\n[action.ops.rs-c2]\nsteps = 0\n";
    let root = Node::Reactive {
        while_: 0,
        unless: 1 << 31,
        children: vec![action(0), action(1), action(2)],
    };
    let (report, _) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    // every operation of one action stopped before any of the next started
    let spans: Vec<(Instant, Instant)> = [["rs-a", "rs-a2"], ["rs-b", "rs-b2"], ["rs-c", "rs-c2"]]
        .iter()
        .map(|ops| {
            let (s1, e1) = interval(&log, ops[0], 0);
            let (s2, e2) = interval(&log, ops[1], 0);
            (s1.min(s2), e1.max(e2))
        })
        .collect();
    for w in spans.windows(2) {
        assert!(w[0].1 <= w[1].0, "two actions of the sequence overlapped");
    }
}

#[tokio::test]
async fn a_reactive_condition_set_by_a_parallel_watcher_halts_the_running_action() {
    let log = Log::default();
    spawn("rc-follow", 4151, 0, &log).await;
    spawn("rc-dead-end", 4152, 0, &log).await;
    let src = header(
        "reactive-halt",
        &["rc-follow", "rc-dead-end"],
        "rc-dead-end",
    ) + "[[action]]\nname = \"follow\"\n[action.ops.rc-follow]\nsteps = 0\n\
           [[action]]\nname = \"watch\"\n[action.ops.rc-dead-end]\nsteps = 40\n";
    // follow unless the watcher saw the dead end; the parallel needs the watcher only
    let root = Node::Parallel {
        children: vec![
            Node::Reactive {
                while_: 0,
                unless: 1 << 1,
                children: vec![action(0)],
            },
            action(1),
        ],
        success: 1,
        failure: 2,
    };
    let (report, _) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    let told = decisions(&report);
    assert!(
        told.iter()
            .any(|d| d.ends_with("condition no longer holds")),
        "{told:?}"
    );
    let follow = report.actions.iter().find(|a| a.name == "follow").unwrap();
    assert_eq!(follow.operations[0].ended, OpEnd::Suspended);
}

#[tokio::test]
async fn a_parallel_runs_its_children_at_once_and_halts_the_rest_at_its_threshold() {
    let log = Log::default();
    spawn("pl-fast", 4161, 0, &log).await;
    spawn("pl-slow", 4162, 0, &log).await;
    let src = header("parallel", &["pl-fast", "pl-slow"], "pl-fast")
        + "[[action]]\nname = \"fast\"\n[action.ops.pl-fast]\nsteps = 10\n\
           [[action]]\nname = \"slow\"\n[action.ops.pl-slow]\nsteps = 0\n";
    let root = Node::Parallel {
        children: vec![action(0), action(1)],
        success: 1,
        failure: 1,
    };
    let (report, events) = run(mission(&src, root).await).await;
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(started(&events), ["fast", "slow"]);
    let (fast_start, _) = interval(&log, "pl-fast", 0);
    let (slow_start, slow_stop) = interval(&log, "pl-slow", 0);
    assert!(
        slow_start < slow_stop && fast_start < slow_stop,
        "they overlapped"
    );
    assert_eq!(
        decisions(&report),
        ["parallel(fast, slow): parallel succeeded"]
    );
    let slow = report.actions.iter().find(|a| a.name == "slow").unwrap();
    assert_eq!(slow.operations[0].ended, OpEnd::Suspended);
}

//! The supervisor against Erlang/OTP's `supervisor_SUITE` (lib/stdlib/test): the test names
//! follow OTP's cases, so the list reads as the specification. Tests wait for supervisor
//! events or replies, never for fixed sleeps; time-dependent cases run on tokio's paused
//! clock.

mod common;

use std::sync::atomic::Ordering;
use std::time::Duration;

use common::*;
use marie_supervision::{
    Backoff, ChildKind, ChildSpec, ChildState, ExitReason, RestartCause, Shutdown, SpecError,
    Strategy, Supervisor, SupervisorError, SupervisorEvent, SupervisorSpec,
    REACHED_MAX_RESTART_INTENSITY, SHUTDOWN,
};
use ractor::ActorStatus;

const HOUR: Duration = Duration::from_secs(3600);

fn is_restart_of(e: &SupervisorEvent, id: &str) -> bool {
    matches!(e, SupervisorEvent::ChildRestarted { id: i, .. } if i == id)
}

fn ids(children: &[marie_supervision::ChildInfo]) -> Vec<String> {
    children.iter().map(|c| c.id.clone()).collect()
}

/// The supervisor gave up and its probe parent saw it fail with the escalation reason.
async fn assert_escalated(exits: &mut Exits, sup: &marie_supervision::SupervisorRef) {
    let reason = exit_of(exits, sup.get_id()).await;
    assert!(
        reason.is_intensity_escalation() && reason.is_abnormal(),
        "the parent must see an abnormal exit, got {reason:?}"
    );
    // ractor tells the parent just before it marks the actor stopped
    tokio::time::timeout(PATIENCE, sup.wait())
        .await
        .expect("the supervisor stops");
}

// ---------------------------------------------------------------------------------------------
// start and stop

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_normal() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![worker("c1", &log), worker("c2", &log)],
    )
    .await
    .unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["c1", "c2"]);
    assert!(children
        .iter()
        .all(|c| matches!(c.state, ChildState::Running(_))));
    assert_eq!(log.with_prefix("start "), ["start c1", "start c2"]);
    assert_eq!(
        sup.get_cell().get_children().len(),
        2,
        "children are linked"
    );

    let mut events = sup.subscribe().await.unwrap();
    sup.stop().await;
    assert_eq!(sup.get_cell().get_status(), ActorStatus::Stopped);
    assert_eq!(log.with_prefix("stop "), ["stop c2", "stop c1"]);
    wait_for(
        &mut events,
        "stopped",
        |e| matches!(e, SupervisorEvent::Stopped { reason } if reason == SHUTDOWN),
    )
    .await;
    assert!(matches!(
        sup.which_children().await,
        Err(SupervisorError::NotRunning)
    ));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_fail() {
    let log = Log::default();
    let fail = flag(true);
    let children = vec![
        worker("c1", &log),
        worker_with("c2", &log, WorkerOpts::failing(&fail)),
        worker("c3", &log),
    ];
    let err = Supervisor::start(None, SupervisorSpec::one_for_one(), children)
        .await
        .unwrap_err();
    assert!(
        matches!(&err, SupervisorError::StartFailed { id, .. } if id == "c2"),
        "{err:?}"
    );
    assert_eq!(
        log.entries(),
        ["start c1", "failed start c2", "stop c1", "stopped c1"],
        "c1 is stopped again, c3 never started"
    );
}

#[tokio::test]
async fn sup_start_duplicate_child_id() {
    let log = Log::default();
    let err = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![worker("c1", &log), worker("c1", &log)],
    )
    .await
    .unwrap_err();
    assert_eq!(
        err,
        SupervisorError::InvalidSpec(SpecError::DuplicateChildId("c1".into()))
    );
    assert!(log.entries().is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_stop_infinity() {
    let log = Log::default();
    let slow = worker_with(
        "c1",
        &log,
        WorkerOpts {
            stop_delay: Some(Duration::from_millis(200)),
            ..Default::default()
        },
    )
    .with_shutdown(Shutdown::Infinity);
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![slow])
        .await
        .unwrap();
    let child = running(&sup, "c1").await;
    sup.stop().await;
    assert_eq!(log.with_prefix("stop"), ["stop c1", "stopped c1"]);
    assert_eq!(child.get_status(), ActorStatus::Stopped);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_stop_timeout() {
    let log = Log::default();
    let polite = worker("c1", &log);
    let stubborn = worker_with(
        "c2",
        &log,
        WorkerOpts {
            stop_delay: Some(HOUR),
            ..Default::default()
        },
    )
    .with_shutdown(Shutdown::Timeout(Duration::from_millis(100)));
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![polite, stubborn])
        .await
        .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    assert!(
        sup.stop_timeout(PATIENCE).await,
        "the stubborn child is killed"
    );
    let shutdowns: Vec<(String, bool)> = events_until(&mut events, "stopped", |e| {
        matches!(e, SupervisorEvent::Stopped { .. })
    })
    .await
    .into_iter()
    .filter_map(|e| match e {
        SupervisorEvent::ChildShutdown { id, killed, .. } => Some((id, killed)),
        _ => None,
    })
    .collect();
    assert_eq!(
        shutdowns,
        [("c2".to_string(), true), ("c1".to_string(), false)]
    );
    assert_eq!(
        log.with_prefix("stop"),
        ["stop c2", "stop c1", "stopped c1"],
        "c2 was killed in its post_stop"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_stop_brutal_kill() {
    let log = Log::default();
    let child = worker("c1", &log).with_shutdown(Shutdown::BrutalKill);
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![child])
        .await
        .unwrap();
    let cell = running(&sup, "c1").await;
    let mut events = sup.subscribe().await.unwrap();
    sup.stop().await;
    wait_for(&mut events, "brutal kill", |e| {
        matches!(e, SupervisorEvent::ChildShutdown { killed: true, .. })
    })
    .await;
    assert_eq!(cell.get_status(), ActorStatus::Stopped);
    assert!(
        log.with_prefix("stop").is_empty(),
        "a killed child's post_stop does not run"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn child_unlink() {
    // a child that unlinks itself from its supervisor is still stopped promptly: the
    // supervisor waits for the actor, not for a supervision event
    let log = Log::default();
    let child = worker_with(
        "c1",
        &log,
        WorkerOpts {
            unlink: true,
            ..Default::default()
        },
    );
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![child])
        .await
        .unwrap();
    let cell = running(&sup, "c1").await;
    tokio::time::timeout(PATIENCE, sup.terminate_child("c1"))
        .await
        .expect("terminate_child does not hang")
        .unwrap();
    assert_eq!(cell.get_status(), ActorStatus::Stopped);
    assert!(sup.stop_timeout(PATIENCE).await);
}

// ---------------------------------------------------------------------------------------------
// strategies

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_for_one() {
    let log = Log::default();
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_one().with_intensity(2, HOUR),
        vec![worker("c1", &log), worker("c2", &log)],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    let c1 = running(&sup, "c1").await;
    let c2 = running(&sup, "c2").await;

    crash(&c1);
    let new_c1 = restarted(&mut events, "c1").await;
    assert_ne!(new_c1.get_id(), c1.get_id());
    assert_eq!(running(&sup, "c1").await, new_c1);
    assert_eq!(running(&sup, "c2").await, c2, "the sibling is left alone");

    crash(&c2);
    let new_c2 = restarted(&mut events, "c2").await;
    assert_eq!(running(&sup, "c1").await, new_c1);

    // a third restart within the hour exceeds the intensity of 2
    crash(&new_c2);
    assert_escalated(&mut exits, &sup).await;
    assert_eq!(new_c1.get_status(), ActorStatus::Stopped);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_for_one_escalation() {
    let log = Log::default();
    let fail = flag(false);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_one().with_intensity(4, HOUR),
        vec![
            worker_with("c1", &log, WorkerOpts::failing(&fail)),
            worker("c2", &log),
        ],
    )
    .await;
    let c1 = running(&sup, "c1").await;
    let c2 = running(&sup, "c2").await;
    fail.store(true, Ordering::SeqCst);
    crash(&c1);
    assert_escalated(&mut exits, &sup).await;
    assert_eq!(c2.get_status(), ActorStatus::Stopped);
    assert_eq!(log.with_prefix("failed start c1").len(), 4);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_for_all() {
    let log = Log::default();
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_all().with_intensity(1, HOUR),
        vec![worker("c1", &log), worker("c2", &log), worker("c3", &log)],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    let before = [
        running(&sup, "c1").await,
        running(&sup, "c2").await,
        running(&sup, "c3").await,
    ];
    log.clear();

    crash(&before[1]);
    let seen = events_until(&mut events, "all restarted", |e| is_restart_of(e, "c3")).await;
    let order: Vec<String> = seen
        .iter()
        .filter_map(|e| match e {
            SupervisorEvent::ChildShutdown { id, .. } => Some(format!("shutdown {id}")),
            SupervisorEvent::ChildRestarted { id, .. } => Some(format!("restart {id}")),
            _ => None,
        })
        .collect();
    assert_eq!(
        order,
        [
            "shutdown c3",
            "shutdown c1",
            "restart c1",
            "restart c2",
            "restart c3"
        ]
    );
    assert_eq!(
        log.entries(),
        [
            "stop c3",
            "stopped c3",
            "stop c1",
            "stopped c1",
            "start c1",
            "start c2",
            "start c3"
        ]
    );
    for (cell, id) in before.iter().zip(["c1", "c2", "c3"]) {
        assert_ne!(&running(&sup, id).await, cell);
        stopped(cell).await;
    }

    crash(&running(&sup, "c3").await);
    assert_escalated(&mut exits, &sup).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_for_all_escalation() {
    let log = Log::default();
    let fail = flag(false);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_all().with_intensity(4, HOUR),
        vec![
            worker("c1", &log),
            worker_with("c2", &log, WorkerOpts::failing(&fail)),
        ],
    )
    .await;
    let c1 = running(&sup, "c1").await;
    fail.store(true, Ordering::SeqCst);
    crash(&c1);
    assert_escalated(&mut exits, &sup).await;
    // every round restarts c1, then fails on c2
    assert_eq!(log.with_prefix("failed start c2").len(), 4);
    assert_eq!(
        log.with_prefix("start c1").len(),
        5,
        "the initial start and one per round"
    );
    assert!(sup.get_cell().get_children().is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rest_for_one() {
    let log = Log::default();
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::rest_for_one().with_intensity(2, HOUR),
        vec![worker("c1", &log), worker("c2", &log), worker("c3", &log)],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    let c1 = running(&sup, "c1").await;
    let c2 = running(&sup, "c2").await;
    let c3 = running(&sup, "c3").await;
    log.clear();

    crash(&c2);
    restarted(&mut events, "c3").await;
    assert_eq!(
        running(&sup, "c1").await,
        c1,
        "c1 started before c2: untouched"
    );
    assert_ne!(running(&sup, "c2").await, c2);
    assert_ne!(running(&sup, "c3").await, c3);
    assert_eq!(
        log.entries(),
        ["stop c3", "stopped c3", "start c2", "start c3"]
    );

    log.clear();
    crash(&c1);
    restarted(&mut events, "c3").await;
    assert_eq!(
        log.with_prefix("st"),
        [
            "stop c3",
            "stopped c3",
            "stop c2",
            "stopped c2",
            "start c1",
            "start c2",
            "start c3"
        ]
    );
    crash(&running(&sup, "c3").await);
    assert_escalated(&mut exits, &sup).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rest_for_one_escalation() {
    let log = Log::default();
    let fail = flag(false);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::rest_for_one().with_intensity(4, HOUR),
        vec![
            worker("c1", &log),
            worker_with("c2", &log, WorkerOpts::failing(&fail)),
        ],
    )
    .await;
    let c1 = running(&sup, "c1").await;
    fail.store(true, Ordering::SeqCst);
    crash(&c1);
    assert_escalated(&mut exits, &sup).await;
    assert_eq!(log.with_prefix("failed start c2").len(), 4);
}

// ---------------------------------------------------------------------------------------------
// restart types

/// Start a one-for-one supervisor with one child of `restart` type, stop the child with
/// `how`, and return the supervisor, the events and the child's exit event.
async fn exit_child(
    restart: marie_supervision::Restart,
    how: impl FnOnce(&ractor::ActorCell),
) -> (
    marie_supervision::SupervisorRef,
    tokio::sync::broadcast::Receiver<SupervisorEvent>,
    ExitReason,
) {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(10, HOUR),
        vec![worker("c1", &log).with_restart(restart)],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    how(&running(&sup, "c1").await);
    let reason = match wait_for(&mut events, "exit of c1", |e| {
        matches!(e, SupervisorEvent::ChildExited { .. })
    })
    .await
    {
        SupervisorEvent::ChildExited { reason, .. } => reason,
        _ => unreachable!(),
    };
    (sup, events, reason)
}

fn stop_normal(c: &ractor::ActorCell) {
    send(c, WorkerMsg::Stop(None));
}
fn stop_shutdown(c: &ractor::ActorCell) {
    send(c, WorkerMsg::Stop(Some(SHUTDOWN.into())));
}
fn stop_shutdown_detail(c: &ractor::ActorCell) {
    send(c, WorkerMsg::Stop(Some("shutdown: maintenance".into())));
}
fn stop_abnormal(c: &ractor::ActorCell) {
    send(c, WorkerMsg::Panic);
}

async fn assert_restarted(
    sup: &marie_supervision::SupervisorRef,
    events: &mut tokio::sync::broadcast::Receiver<SupervisorEvent>,
) {
    restarted(events, "c1").await;
    let info = &sup.which_children().await.unwrap()[0];
    assert!(matches!(info.state, ChildState::Running(_)));
    assert_eq!(info.restarts, 1);
    sup.stop().await;
}

/// Not restarted: the exit handler has run when `which_children` answers (the supervisor
/// serves one message at a time), so a restart would show as Restarting or Running.
async fn assert_not_restarted(sup: &marie_supervision::SupervisorRef, removed: bool) {
    let children = sup.which_children().await.unwrap();
    if removed {
        assert!(children.is_empty(), "{children:?}");
    } else {
        assert_eq!(children.len(), 1);
        assert_eq!(children[0].state, ChildState::Undefined);
        assert_eq!(children[0].restarts, 0);
    }
    assert_eq!(sup.count_children().await.unwrap().active, 0);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn permanent_normal() {
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Permanent, stop_normal).await;
    assert_eq!(reason, ExitReason::Normal);
    assert_restarted(&sup, &mut events).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn permanent_shutdown() {
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Permanent, stop_shutdown).await;
    assert_eq!(reason, ExitReason::Shutdown(None));
    assert_restarted(&sup, &mut events).await;
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Permanent, stop_shutdown_detail).await;
    assert_eq!(reason, ExitReason::Shutdown(Some("maintenance".into())));
    assert_restarted(&sup, &mut events).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn permanent_abnormal() {
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Permanent, stop_abnormal).await;
    assert!(matches!(reason, ExitReason::Failed(ref m) if m.contains("induced panic")));
    assert_restarted(&sup, &mut events).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn transient_normal() {
    let (sup, _, reason) = exit_child(marie_supervision::Restart::Transient, stop_normal).await;
    assert!(reason.is_normal());
    assert_not_restarted(&sup, false).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn transient_shutdown() {
    let (sup, _, reason) = exit_child(marie_supervision::Restart::Transient, stop_shutdown).await;
    assert!(reason.is_shutdown());
    assert_not_restarted(&sup, false).await;
    let (sup, _, reason) =
        exit_child(marie_supervision::Restart::Transient, stop_shutdown_detail).await;
    assert!(reason.is_shutdown());
    assert_not_restarted(&sup, false).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn transient_abnormal() {
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Transient, stop_abnormal).await;
    assert!(reason.is_abnormal());
    assert_restarted(&sup, &mut events).await;
    // a kill is abnormal too
    let (sup, mut events, reason) =
        exit_child(marie_supervision::Restart::Transient, |c| c.kill()).await;
    assert_eq!(reason, ExitReason::Killed);
    assert_restarted(&sup, &mut events).await;
    // and so is any reason other than normal or shutdown
    let (sup, mut events, reason) = exit_child(marie_supervision::Restart::Transient, |c| {
        send(c, WorkerMsg::Stop(Some("out of coffee".into())))
    })
    .await;
    assert_eq!(reason, ExitReason::Other("out of coffee".into()));
    assert_restarted(&sup, &mut events).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn temporary_normal() {
    let (sup, mut events, _) = exit_child(marie_supervision::Restart::Temporary, stop_normal).await;
    wait_for(&mut events, "removal", |e| {
        matches!(e, SupervisorEvent::ChildDeleted { .. })
    })
    .await;
    assert_not_restarted(&sup, true).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn temporary_shutdown() {
    let (sup, _, _) = exit_child(marie_supervision::Restart::Temporary, stop_shutdown).await;
    assert_not_restarted(&sup, true).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn temporary_abnormal() {
    let (sup, _, _) = exit_child(marie_supervision::Restart::Temporary, stop_abnormal).await;
    assert_not_restarted(&sup, true).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn temporary_bystander() {
    // a temporary child caught in a one-for-all restart is stopped and removed, not restarted
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_all().with_intensity(2, HOUR),
        vec![
            worker("c1", &log),
            worker("c2", &log).with_restart(marie_supervision::Restart::Temporary),
        ],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    let c2 = running(&sup, "c2").await;
    stop_normal(&running(&sup, "c1").await);
    restarted(&mut events, "c1").await;
    assert_eq!(ids(&sup.which_children().await.unwrap()), ["c1"]);
    assert_eq!(c2.get_status(), ActorStatus::Stopped);
    assert_eq!(log.with_prefix("start c2").len(), 1);
    sup.stop().await;
}

// ---------------------------------------------------------------------------------------------
// restart intensity

#[tokio::test(start_paused = true)]
async fn multiple_restarts() {
    // failures spaced wider than the period never trip the limit (the window slides)
    let log = Log::default();
    let period = Duration::from_secs(5);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_one().with_intensity(1, period),
        vec![worker("c1", &log)],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    let mut child = running(&sup, "c1").await;
    for _ in 0..10 {
        crash(&child);
        child = restarted(&mut events, "c1").await;
        tokio::time::sleep(period + Duration::from_secs(1)).await;
    }
    assert_eq!(sup.get_cell().get_status(), ActorStatus::Running);
    assert_eq!(sup.which_children().await.unwrap()[0].restarts, 10);

    // two restarts within the period exceed max_restarts = 1
    crash(&child);
    let child = restarted(&mut events, "c1").await;
    tokio::time::sleep(Duration::from_secs(1)).await;
    crash(&child);
    assert_escalated(&mut exits, &sup).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn max_restart_intensity_stops_children_in_reverse_order() {
    let log = Log::default();
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_one().with_intensity(0, HOUR),
        vec![
            worker("c1", &log),
            worker("c2", &log),
            worker("c3", &log),
            worker("c4", &log),
        ],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    crash(&running(&sup, "c2").await);
    let seen = events_until(&mut events, "stopped", |e| {
        matches!(e, SupervisorEvent::Stopped { .. })
    })
    .await;
    assert!(seen.iter().any(|e| matches!(
        e,
        SupervisorEvent::IntensityExceeded {
            max_restarts: 0,
            ..
        }
    )));
    assert!(
        matches!(seen.last(), Some(SupervisorEvent::Stopped { reason }) if reason == REACHED_MAX_RESTART_INTENSITY)
    );
    assert_eq!(log.with_prefix("stop "), ["stop c4", "stop c3", "stop c1"]);
    assert_escalated(&mut exits, &sup).await;
    // the event channel closes with the supervisor
    assert!(matches!(
        events.recv().await,
        Err(tokio::sync::broadcast::error::RecvError::Closed)
    ));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn escalation_to_parent_supervisor() {
    // a child supervisor that gives up is restarted by its parent, like any crashed child
    let log = Log::default();
    let sub = ChildSpec::supervisor(
        "sub",
        SupervisorSpec::one_for_one().with_intensity(0, HOUR),
        vec![worker("w", &log)],
    );
    let (top, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(3, HOUR),
        vec![worker("sibling", &log), sub],
    )
    .await
    .unwrap();
    let mut events = top.subscribe().await.unwrap();
    let sibling = running(&top, "sibling").await;
    let sub = marie_supervision::SupervisorRef::from_cell(running(&top, "sub").await)
        .expect("a supervisor");
    assert_eq!(
        top.which_children().await.unwrap()[1].kind,
        ChildKind::Supervisor
    );
    crash(&running(&sub, "w").await);
    match wait_for(&mut events, "restart of sub", |e| is_restart_of(e, "sub")).await {
        SupervisorEvent::ChildRestarted { cause, old, .. } => {
            assert_eq!(old, Some(sub.get_id()));
            assert!(
                matches!(&cause, RestartCause::Exited(r) if r.is_intensity_escalation()),
                "{cause:?}"
            );
        }
        _ => unreachable!(),
    }
    let new_sub = marie_supervision::SupervisorRef::from_cell(running(&top, "sub").await).unwrap();
    running(&new_sub, "w").await;
    assert_eq!(running(&top, "sibling").await, sibling);
    assert_eq!(log.with_prefix("start w").len(), 2);

    // stopping the top stops the child supervisor, which stops its worker first
    log.clear();
    top.stop().await;
    assert_eq!(
        log.with_prefix("stop "),
        ["stop w", "stop sibling"],
        "reverse order, depth first"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn restart_fails_counts_toward_intensity() {
    // OTP child_restart_fail: a restart whose start fails counts as a restart and is retried
    // until the intensity is exceeded
    let log = Log::default();
    let fail = flag(false);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::one_for_one().with_intensity(3, HOUR),
        vec![worker_with("c1", &log, WorkerOpts::failing(&fail))],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    let seen = events_until(&mut events, "giving up", |e| {
        matches!(e, SupervisorEvent::IntensityExceeded { .. })
    })
    .await;
    let failures = seen
        .iter()
        .filter(|e| matches!(e, SupervisorEvent::RestartFailed { .. }))
        .count();
    assert_eq!(
        failures, 3,
        "restarts 1..=3 fail, the 4th exceeds the intensity"
    );
    assert_escalated(&mut exits, &sup).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn restart_fails_then_recovers() {
    // the next three starts fail; the fourth attempt succeeds within the intensity of 4
    let log = Log::default();
    let failures = counter(0);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(4, HOUR),
        vec![worker_with(
            "c1",
            &log,
            WorkerOpts {
                fail_count: Some(failures.clone()),
                ..Default::default()
            },
        )],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    failures.store(3, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    let seen = events_until(&mut events, "recovery", |e| is_restart_of(e, "c1")).await;
    let failed = seen
        .iter()
        .filter(|e| matches!(e, SupervisorEvent::RestartFailed { .. }))
        .count();
    assert_eq!(failed, 3);
    assert_eq!(sup.which_children().await.unwrap()[0].restarts, 1);
    assert!(matches!(
        sup.which_children().await.unwrap()[0].state,
        ChildState::Running(_)
    ));
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stale_exit_events_do_not_restart_twice() {
    // the old incarnations a one-for-all restart stops report their exits too; they must not
    // trigger more restarts
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_all().with_intensity(1, HOUR),
        vec![worker("c1", &log), worker("c2", &log), worker("c3", &log)],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    crash(&running(&sup, "c1").await);
    restarted(&mut events, "c3").await;
    // a round trip after every old exit has been delivered
    let children = sup.which_children().await.unwrap();
    assert!(children
        .iter()
        .all(|c| c.restarts == 1 && matches!(c.state, ChildState::Running(_))));
    assert_eq!(sup.get_cell().get_status(), ActorStatus::Running);
    assert_eq!(log.with_prefix("start ").len(), 6);
    sup.stop().await;
}

// ---------------------------------------------------------------------------------------------
// hanging restarts

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hanging_restart_loop() {
    // while a restart keeps failing, the supervisor keeps serving its mailbox
    let log = Log::default();
    let fail = flag(false);
    let spec = worker_with("c1", &log, WorkerOpts::failing(&fail));
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(usize::MAX, Duration::from_secs(10)),
        vec![spec.clone(), worker("c2", &log)],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    wait_for(&mut events, "a failed restart", |e| {
        matches!(e, SupervisorEvent::RestartFailed { .. })
    })
    .await;

    assert_eq!(
        sup.start_child(spec.clone()).await.unwrap_err(),
        SupervisorError::AlreadyPresent("c1".into())
    );
    assert_eq!(
        sup.restart_child("c1").await.unwrap_err(),
        SupervisorError::Restarting("c1".into())
    );
    assert_eq!(
        sup.delete_child("c1").await.unwrap_err(),
        SupervisorError::Restarting("c1".into())
    );
    assert!(matches!(
        sup.which_children().await.unwrap()[0].state,
        ChildState::Restarting
    ));
    sup.terminate_child("c1").await.unwrap();
    assert_eq!(
        sup.which_children().await.unwrap()[0].state,
        ChildState::Undefined
    );

    fail.store(false, Ordering::SeqCst);
    let c1 = sup.restart_child("c1").await.unwrap();
    assert_eq!(running(&sup, "c1").await, c1);
    assert!(sup.stop_timeout(PATIENCE).await);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hanging_restart_does_not_block_shutdown() {
    // a restart that never finishes: the supervisor still answers and stops promptly
    let log = Log::default();
    let hang = flag(false);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(5, HOUR),
        vec![
            worker("c0", &log),
            worker_with("c1", &log, WorkerOpts::hanging(&hang)),
        ],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    hang.store(true, Ordering::SeqCst);
    let c1 = running(&sup, "c1").await;
    crash(&c1);
    wait_for(&mut events, "exit of c1", |e| {
        matches!(e, SupervisorEvent::ChildExited { .. })
    })
    .await;
    assert_eq!(
        sup.which_children().await.unwrap()[1].state,
        ChildState::Restarting
    );
    assert_eq!(sup.count_children().await.unwrap().active, 1);
    assert!(
        sup.stop_timeout(PATIENCE).await,
        "stop completes although a start hangs"
    );
    assert_eq!(log.with_prefix("stop "), ["stop c0"]);
}

#[tokio::test(start_paused = true)]
async fn start_timeout_counts_as_failed_restart() {
    let log = Log::default();
    let hang = flag(false);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(5, HOUR),
        vec![worker_with("c1", &log, WorkerOpts::hanging(&hang))
            .with_start_timeout(Duration::from_secs(1))],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    hang.store(true, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    match wait_for(&mut events, "timed-out restart", |e| {
        matches!(e, SupervisorEvent::RestartFailed { .. })
    })
    .await
    {
        SupervisorEvent::RestartFailed { error, .. } => assert!(error.contains("timed out")),
        _ => unreachable!(),
    }
    hang.store(false, Ordering::SeqCst);
    restarted(&mut events, "c1").await;
    sup.stop().await;
}

// ---------------------------------------------------------------------------------------------
// order, dynamic children, introspection

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn order_of_children() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::rest_for_one().with_intensity(10, HOUR),
        vec![worker("c1", &log), worker("c2", &log), worker("c3", &log)],
    )
    .await
    .unwrap();
    assert_eq!(log.entries(), ["start c1", "start c2", "start c3"]);
    // a dynamic child goes last
    sup.start_child(worker("c4", &log)).await.unwrap();
    let mut events = sup.subscribe().await.unwrap();
    log.clear();

    crash(&running(&sup, "c2").await);
    restarted(&mut events, "c4").await;
    assert_eq!(
        log.with_prefix("st"),
        ["stop c4", "stop c3", "start c2", "start c3", "start c4"]
            .iter()
            .flat_map(|e| {
                // each stop is followed by its "stopped"
                if let Some(n) = e.strip_prefix("stop ") {
                    vec![e.to_string(), format!("stopped {n}")]
                } else {
                    vec![e.to_string()]
                }
            })
            .collect::<Vec<_>>()
    );
    // restarted children keep their position
    assert_eq!(
        ids(&sup.which_children().await.unwrap()),
        ["c1", "c2", "c3", "c4"]
    );
    log.clear();
    sup.stop().await;
    assert_eq!(
        log.with_prefix("stop "),
        ["stop c4", "stop c3", "stop c2", "stop c1"]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn child_adm() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![])
        .await
        .unwrap();
    let c1 = sup.start_child(worker("c1", &log)).await.unwrap();
    assert_eq!(running(&sup, "c1").await, c1);
    assert_eq!(
        sup.start_child(worker("c1", &log)).await.unwrap_err(),
        SupervisorError::AlreadyStarted("c1".into())
    );
    assert_eq!(
        sup.delete_child("c1").await.unwrap_err(),
        SupervisorError::Running("c1".into())
    );
    assert_eq!(
        sup.restart_child("c1").await.unwrap_err(),
        SupervisorError::Running("c1".into())
    );

    sup.terminate_child("c1").await.unwrap();
    assert_eq!(c1.get_status(), ActorStatus::Stopped);
    assert_eq!(log.with_prefix("stop"), ["stop c1", "stopped c1"]);
    assert_eq!(
        sup.which_children().await.unwrap()[0].state,
        ChildState::Undefined
    );
    sup.terminate_child("c1").await.unwrap(); // terminating twice is fine
    assert_eq!(
        sup.start_child(worker("c1", &log)).await.unwrap_err(),
        SupervisorError::AlreadyPresent("c1".into())
    );

    let again = sup.restart_child("c1").await.unwrap();
    assert_ne!(again, c1);
    assert_eq!(running(&sup, "c1").await, again);

    sup.terminate_child("c1").await.unwrap();
    sup.delete_child("c1").await.unwrap();
    assert!(sup.which_children().await.unwrap().is_empty());

    let missing = SupervisorError::NotFound("nope".into());
    assert_eq!(sup.terminate_child("nope").await.unwrap_err(), missing);
    assert_eq!(sup.restart_child("nope").await.unwrap_err(), missing);
    assert_eq!(sup.delete_child("nope").await.unwrap_err(), missing);

    // a temporary child is removed when terminated
    sup.start_child(worker("t", &log).with_restart(marie_supervision::Restart::Temporary))
        .await
        .unwrap();
    sup.terminate_child("t").await.unwrap();
    assert!(sup.which_children().await.unwrap().is_empty());

    // a dynamic child whose start fails leaves no spec behind
    let bad = worker_with("bad", &log, WorkerOpts::failing(&flag(true)));
    assert!(matches!(
        sup.start_child(bad).await.unwrap_err(),
        SupervisorError::StartFailed { id, .. } if id == "bad"
    ));
    assert!(sup.which_children().await.unwrap().is_empty());
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn count_children() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![
            worker("w1", &log),
            worker("w2", &log),
            ChildSpec::supervisor("s1", SupervisorSpec::one_for_one(), vec![]),
        ],
    )
    .await
    .unwrap();
    let counts = sup.count_children().await.unwrap();
    assert_eq!(
        (
            counts.specs,
            counts.active,
            counts.workers,
            counts.supervisors
        ),
        (3, 3, 2, 1)
    );
    sup.terminate_child("w2").await.unwrap();
    let counts = sup.count_children().await.unwrap();
    assert_eq!(
        (
            counts.specs,
            counts.active,
            counts.workers,
            counts.supervisors
        ),
        (3, 2, 2, 1)
    );
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn which_children() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![
            worker("w1", &log)
                .with_restart(marie_supervision::Restart::Transient)
                .with_shutdown(Shutdown::BrutalKill),
            ChildSpec::supervisor("s1", SupervisorSpec::one_for_one(), vec![]),
        ],
    )
    .await
    .unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["w1", "s1"]);
    assert_eq!(children[0].kind, ChildKind::Worker);
    assert_eq!(children[0].restart, marie_supervision::Restart::Transient);
    assert_eq!(children[0].shutdown, Shutdown::BrutalKill);
    assert_eq!(children[1].kind, ChildKind::Supervisor);
    assert_eq!(children[1].shutdown, Shutdown::Infinity);
    assert_eq!(children[1].restart, marie_supervision::Restart::Permanent);
    assert!(children
        .iter()
        .all(|c| matches!(c.state, ChildState::Running(_)) && c.restarts == 0));
    sup.terminate_child("w1").await.unwrap();
    assert_eq!(
        sup.which_children().await.unwrap()[0].state,
        ChildState::Undefined
    );
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn actor_child_spec() {
    // the ChildSpec::actor convenience builds handler and arguments afresh per start
    let log = Log::default();
    let l = log.clone();
    let spec = ChildSpec::actor("a", move || {
        (
            Worker,
            WorkerArgs {
                name: "a".into(),
                log: l.clone(),
                stop_delay: None,
                unlink: false,
            },
        )
    });
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(1, HOUR),
        vec![spec],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    crash(&running(&sup, "a").await);
    restarted(&mut events, "a").await;
    assert_eq!(log.with_prefix("start a").len(), 2);
    sup.stop().await;
}

// ---------------------------------------------------------------------------------------------
// backoff

#[test]
fn backoff_delays_grow_and_are_jittered() {
    let b = Backoff::exponential(Duration::from_millis(100), Duration::from_secs(10))
        .with_jitter(0.5)
        .with_seed(42);
    let delays: Vec<Duration> = b.schedule().take(10).collect();
    for (n, d) in delays.iter().enumerate() {
        let nominal = b.nominal(n as u32);
        assert!(
            *d <= nominal && *d >= nominal.mul_f64(0.5),
            "attempt {n}: {d:?} vs {nominal:?}"
        );
    }
    assert_eq!(
        (0..10).map(|n| b.nominal(n)).collect::<Vec<_>>(),
        [100, 200, 400, 800, 1600, 3200, 6400, 10_000, 10_000, 10_000].map(Duration::from_millis)
    );
    assert!(
        delays.iter().zip(b.schedule()).all(|(a, b)| *a == b),
        "the same seed gives the same delays"
    );
    let other: Vec<Duration> = b.clone().with_seed(43).schedule().take(10).collect();
    assert_ne!(delays, other, "another seed, other delays");
    assert!(
        delays.iter().zip(0..).any(|(d, n)| *d != b.nominal(n)),
        "jitter changes the delays"
    );
    let plain = b.clone().with_jitter(0.0);
    assert!(plain
        .schedule()
        .take(10)
        .zip(0..)
        .all(|(d, n)| d == plain.nominal(n)));
}

#[tokio::test(start_paused = true)]
async fn backoff_end_to_end() {
    // a child whose restarts fail waits 1, 2, 4, 8, 8 s between attempts (no jitter), then
    // recovers; the paused clock makes this take no real time
    let log = Log::default();
    let fail = flag(false);
    let backoff = Backoff::exponential(Duration::from_secs(1), Duration::from_secs(8))
        .with_jitter(0.0)
        .with_reset_after(Duration::from_secs(60));
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one()
            .with_intensity(10, Duration::from_secs(60))
            .with_backoff(backoff),
        vec![worker_with("c1", &log, WorkerOpts::failing(&fail))],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    let mut waited = Vec::new();
    for attempt in 0..5u32 {
        let (delay, at) = match wait_for(&mut events, "scheduled restart", |e| {
            matches!(e, SupervisorEvent::RestartScheduled { .. })
        })
        .await
        {
            SupervisorEvent::RestartScheduled {
                delay, attempt: a, ..
            } => {
                assert_eq!(a, attempt);
                (delay, tokio::time::Instant::now())
            }
            _ => unreachable!(),
        };
        assert!(matches!(
            sup.which_children().await.unwrap()[0].state,
            ChildState::Restarting
        ));
        wait_for(&mut events, "failed restart", |e| {
            matches!(e, SupervisorEvent::RestartFailed { .. })
        })
        .await;
        let elapsed = at.elapsed();
        assert!(
            elapsed >= delay && elapsed < delay + Duration::from_millis(100),
            "attempt {attempt}: waited {elapsed:?} for a delay of {delay:?}"
        );
        waited.push(delay.as_secs());
    }
    assert_eq!(waited, [1, 2, 4, 8, 8]);
    fail.store(false, Ordering::SeqCst);
    match wait_for(&mut events, "recovery", |e| is_restart_of(e, "c1")).await {
        SupervisorEvent::ChildRestarted { restarts, .. } => assert_eq!(restarts, 1),
        _ => unreachable!(),
    }
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terminate_child_during_backoff_releases_its_siblings() {
    // rest-for-one: c2 crashes and waits an hour of backoff, c3 waits with it; terminating c2
    // must not leave c3 waiting for a restart that will never come
    let log = Log::default();
    let backoff = Backoff::exponential(HOUR, HOUR).with_jitter(0.0);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::rest_for_one()
            .with_intensity(10, HOUR)
            .with_backoff(backoff),
        vec![worker("c1", &log), worker("c2", &log), worker("c3", &log)],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    let c1 = running(&sup, "c1").await;
    crash(&running(&sup, "c2").await);
    wait_for(
        &mut events,
        "scheduled restart",
        |e| matches!(e, SupervisorEvent::RestartScheduled { id, .. } if id == "c2"),
    )
    .await;
    let states: Vec<ChildState> = sup
        .which_children()
        .await
        .unwrap()
        .into_iter()
        .map(|c| c.state)
        .collect();
    assert_eq!(
        states,
        [
            ChildState::Running(c1.clone()),
            ChildState::Restarting,
            ChildState::Restarting
        ]
    );

    sup.terminate_child("c2").await.unwrap();
    match wait_for(&mut events, "restart of c3", |e| is_restart_of(e, "c3")).await {
        SupervisorEvent::ChildRestarted { cause, .. } => {
            assert_eq!(cause, RestartCause::Sibling("c2".into()))
        }
        _ => unreachable!(),
    }
    let children = sup.which_children().await.unwrap();
    assert_eq!(children[0].state, ChildState::Running(c1));
    assert_eq!(children[1].state, ChildState::Undefined);
    assert!(matches!(children[2].state, ChildState::Running(_)));
    sup.stop().await;
}

#[test]
fn strategy_default_is_one_for_one() {
    assert_eq!(SupervisorSpec::default().strategy, Strategy::OneForOne);
    assert_eq!(SupervisorSpec::default().max_restarts, 1);
    assert_eq!(SupervisorSpec::default().period, Duration::from_secs(5));
    assert!(SupervisorSpec::default().backoff.is_none());
}

// ---------------------------------------------------------------------------------------------
// ignore: a start may decline to run (OTP's `ignore`)

fn counts(c: marie_supervision::ChildCounts) -> [usize; 4] {
    // OTP's get_child_counts order: specs, active, supervisors, workers
    [c.specs, c.active, c.supervisors, c.workers]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_child() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![])
        .await
        .unwrap();
    let ignoring = worker_with("child1", &log, WorkerOpts::ignoring(&flag(true)));
    assert_eq!(
        sup.start_child(ignoring).await.unwrap_err(),
        SupervisorError::Ignored("child1".into())
    );
    let c2 = sup.start_child(worker("child2", &log)).await.unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child1", "child2"]);
    assert_eq!(children[0].state, ChildState::Undefined);
    assert_eq!(children[1].state, ChildState::Running(c2));
    assert_eq!(counts(sup.count_children().await.unwrap()), [2, 1, 0, 2]);
    sup.stop().await;

    // the same for a static child: kept, not running
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![
            worker_with("child1", &log, WorkerOpts::ignoring(&flag(true))),
            worker("child2", &log),
        ],
    )
    .await
    .unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child1", "child2"]);
    assert_eq!(children[0].state, ChildState::Undefined);
    assert_eq!(counts(sup.count_children().await.unwrap()), [2, 1, 0, 2]);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_temporary_child() {
    // a temporary static child that ignores its start leaves no spec behind
    let log = Log::default();
    let temporary = marie_supervision::Restart::Temporary;
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![
            worker_with("child1", &log, WorkerOpts::ignoring(&flag(true))).with_restart(temporary),
            worker("child2", &log).with_restart(temporary),
        ],
    )
    .await
    .unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child2"]);
    assert!(children[0].state.actor().is_some());
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_temporary_child_start_child() {
    let log = Log::default();
    let temporary = marie_supervision::Restart::Temporary;
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), vec![])
        .await
        .unwrap();
    let ignoring =
        worker_with("child1", &log, WorkerOpts::ignoring(&flag(true))).with_restart(temporary);
    assert_eq!(
        sup.start_child(ignoring).await.unwrap_err(),
        SupervisorError::Ignored("child1".into())
    );
    let c2 = sup
        .start_child(worker("child2", &log).with_restart(temporary))
        .await
        .unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child2"]);
    assert_eq!(children[0].state, ChildState::Running(c2));
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    assert_eq!(
        sup.restart_child("child1").await.unwrap_err(),
        SupervisorError::NotFound("child1".into())
    );
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_permanent_child_start_child() {
    // a permanent child that ignores its start stays, not running; restart_child tries again
    let log = Log::default();
    let ignore = flag(true);
    let spec = worker_with("child", &log, WorkerOpts::ignoring(&ignore));
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(10, HOUR),
        vec![],
    )
    .await
    .unwrap();
    assert_eq!(
        sup.start_child(spec.clone()).await.unwrap_err(),
        SupervisorError::Ignored("child".into())
    );
    assert_eq!(
        sup.start_child(spec.clone()).await.unwrap_err(),
        SupervisorError::AlreadyPresent("child".into())
    );
    assert_eq!(
        sup.restart_child("child").await.unwrap_err(),
        SupervisorError::Ignored("child".into())
    );
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child"]);
    assert_eq!(children[0].state, ChildState::Undefined);
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 0, 0, 1]);

    ignore.store(false, Ordering::SeqCst);
    let cell = sup.restart_child("child").await.unwrap();
    assert_eq!(running(&sup, "child").await, cell);
    assert_eq!(log.with_prefix("ignored start").len(), 2);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_temporary_child_start_child_simple() {
    let log = Log::default();
    let template = template(&log).with_restart(marie_supervision::Restart::Temporary);
    let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
        .await
        .unwrap();
    let ignoring = Inst {
        ignore: true,
        ..Inst::named("i1")
    };
    assert!(matches!(
        sup.start_dynamic(ignoring).await.unwrap_err(),
        SupervisorError::Ignored(_)
    ));
    let c2 = sup.start_dynamic(Inst::named("i2")).await.unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 1);
    assert_eq!(children[0].state, ChildState::Running(c2));
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sup_start_ignore_permanent_child_start_child_simple() {
    // an instance that ignores its start leaves nothing behind, whatever its restart type
    let log = Log::default();
    let (sup, _probe, mut exits) =
        start_probed(SupervisorSpec::simple_one_for_one(template(&log)), vec![]).await;
    let mut events = sup.subscribe().await.unwrap();
    let ignoring = Inst {
        ignore: true,
        ..Inst::named("i1")
    };
    assert!(matches!(
        sup.start_dynamic(ignoring).await.unwrap_err(),
        SupervisorError::Ignored(_)
    ));
    wait_for(&mut events, "ignored", |e| {
        matches!(e, SupervisorEvent::ChildIgnored { .. })
    })
    .await;
    let c2 = sup.start_dynamic(Inst::named("i2")).await.unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 1);
    assert_eq!(children[0].state, ChildState::Running(c2));
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    // the supervisor terminates without error
    sup.stop().await;
    assert!(matches!(
        exit_of(&mut exits, sup.get_id()).await,
        ExitReason::Shutdown(None)
    ));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn restart_answering_ignore_leaves_the_child_undefined() {
    // a permanent child whose restart answers ignore is not running and not retried; the
    // ignore counts no restart
    let log = Log::default();
    let ignore = flag(false);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(1, HOUR),
        vec![
            worker_with("c1", &log, WorkerOpts::ignoring(&ignore)),
            worker("c2", &log),
        ],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    ignore.store(true, Ordering::SeqCst);
    crash(&running(&sup, "c1").await);
    wait_for(
        &mut events,
        "ignored restart",
        |e| matches!(e, SupervisorEvent::ChildIgnored { id } if id == "c1"),
    )
    .await;
    let children = sup.which_children().await.unwrap();
    assert_eq!(children[0].state, ChildState::Undefined);
    assert!(children[1].state.actor().is_some());
    // one more restart is still allowed: the ignored one did not count twice
    ignore.store(false, Ordering::SeqCst);
    sup.restart_child("c1").await.unwrap();
    assert_eq!(sup.get_cell().get_status(), ActorStatus::Running);
    sup.stop().await;
}

// ---------------------------------------------------------------------------------------------
// simple_one_for_one

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn child_adm_simple() {
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::simple_one_for_one(template(&log)),
        vec![],
    )
    .await
    .unwrap();
    // all children are added at run time
    assert!(sup.which_children().await.unwrap().is_empty());
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 0, 0, 0]);

    let c1 = sup.start_dynamic(Inst::named("i1")).await.unwrap();
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 1);
    assert_eq!(children[0].state, ChildState::Running(c1.clone()));
    assert_eq!(children[0].id, "child#1", "instance ids are generated");
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    let c2 = sup.start_dynamic(Inst::named("i2")).await.unwrap();
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 2, 0, 2]);

    // termination is by actor
    assert_eq!(
        sup.terminate_child("child#1").await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 2, 0, 2]);
    sup.terminate_actor(c1.get_id()).await.unwrap();
    assert_eq!(c1.get_status(), ActorStatus::Stopped);
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 1);
    assert_eq!(children[0].state, ChildState::Running(c2.clone()));
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    // terminating an instance that is gone is fine
    sup.terminate_actor(c1.get_id()).await.unwrap();
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    // a live actor that is not a child is not found, and left alone
    let (stranger, _) = ractor::Actor::spawn(None, Probe, tokio::sync::mpsc::unbounded_channel().0)
        .await
        .unwrap();
    assert!(matches!(
        sup.terminate_actor(stranger.get_id()).await.unwrap_err(),
        SupervisorError::NotFound(_)
    ));
    assert_eq!(stranger.get_status(), ActorStatus::Running);
    stranger.stop(None);

    // no specs to restart, delete or add
    assert_eq!(
        sup.restart_child("child#2").await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    assert_eq!(
        sup.delete_child("child#2").await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    assert_eq!(
        sup.start_child(worker("c", &log)).await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    // the argument's type is checked before anything starts
    match sup.start_dynamic(42u32).await.unwrap_err() {
        SupervisorError::WrongArgument { expected, got } => {
            assert!(expected.ends_with("Inst"), "{expected}");
            assert_eq!(got, "u32");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 1, 0, 1]);
    sup.stop().await;
    assert_eq!(c2.get_status(), ActorStatus::Stopped);

    // on other strategies: no template, and children are addressed by id (OTP child_adm)
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one(),
        vec![worker("child1", &log)],
    )
    .await
    .unwrap();
    assert_eq!(
        sup.start_dynamic(Inst::named("x")).await.unwrap_err(),
        SupervisorError::NotSimpleOneForOne
    );
    let child1 = running(&sup, "child1").await;
    assert!(matches!(
        sup.terminate_actor(child1.get_id()).await.unwrap_err(),
        SupervisorError::NotFound(_)
    ));
    assert_eq!(running(&sup, "child1").await, child1);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simple_one_for_one() {
    let log = Log::default();
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::simple_one_for_one(template(&log)).with_intensity(2, HOUR),
        vec![],
    )
    .await;
    let mut events = sup.subscribe().await.unwrap();
    let c1 = sup.start_dynamic(Inst::named("i1")).await.unwrap();
    let c2 = sup.start_dynamic(Inst::named("i2")).await.unwrap();

    crash(&c1);
    let new_c1 = restarted(&mut events, "child#1").await;
    assert_ne!(new_c1, c1);
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 2);
    assert!(children
        .iter()
        .any(|c| c.state == ChildState::Running(c2.clone())));
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 2, 0, 2]);

    // restart intensity over all instances together
    crash(&c2);
    let new_c2 = restarted(&mut events, "child#2").await;
    crash(&new_c2);
    assert_escalated(&mut exits, &sup).await;
    stopped(&new_c1).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simple_one_for_one_extra() {
    // each instance is restarted with the argument it was started with
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::simple_one_for_one(template(&log)).with_intensity(2, HOUR),
        vec![],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    let alpha = sup.start_dynamic(Inst::named("alpha")).await.unwrap();
    let beta = sup.start_dynamic(Inst::named("beta")).await.unwrap();
    log.clear();
    crash(&alpha);
    match wait_for(&mut events, "restart", |e| is_restart_of(e, "child#1")).await {
        SupervisorEvent::ChildRestarted {
            old,
            cause,
            restarts,
            ..
        } => {
            assert_eq!(old, Some(alpha.get_id()));
            assert!(matches!(cause, RestartCause::Exited(ExitReason::Failed(_))));
            assert_eq!(restarts, 1);
        }
        _ => unreachable!(),
    }
    assert_eq!(log.with_prefix("start "), ["start alpha"]);
    let children = sup.which_children().await.unwrap();
    assert_eq!(ids(&children), ["child#1", "child#2"]);
    assert_eq!(children[1].state, ChildState::Running(beta));
    assert_eq!((children[0].restarts, children[1].restarts), (1, 0));
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simple_one_for_one_escalation() {
    let log = Log::default();
    let fail = flag(false);
    let (sup, _probe, mut exits) = start_probed(
        SupervisorSpec::simple_one_for_one(template(&log)).with_intensity(4, HOUR),
        vec![],
    )
    .await;
    let c1 = sup
        .start_dynamic(Inst {
            fail_start: Some(fail.clone()),
            ..Inst::named("i1")
        })
        .await
        .unwrap();
    let c2 = sup.start_dynamic(Inst::named("i2")).await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&c1);
    assert_escalated(&mut exits, &sup).await;
    assert_eq!(c2.get_status(), ActorStatus::Stopped);
    assert_eq!(log.with_prefix("failed start i1").len(), 4);
}

#[tokio::test(start_paused = true)]
async fn simple_one_for_one_shutdown() {
    // instances are stopped together: two stop within their shutdown time, the third is
    // killed at the deadline; the whole shutdown takes one deadline, not the sum
    let log = Log::default();
    let t = Duration::from_secs(1);
    let template = template(&log).with_shutdown(Shutdown::Timeout(2 * t));
    let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
        .await
        .unwrap();
    for (name, delay) in [("i1", t), ("i2", t), ("i3", 5 * t)] {
        sup.start_dynamic(Inst {
            stop_delay: Some(delay),
            ..Inst::named(name)
        })
        .await
        .unwrap();
    }
    let mut events = sup.subscribe().await.unwrap();
    let begin = tokio::time::Instant::now();
    sup.stop().await;
    let took = begin.elapsed();
    assert!(
        took >= t && took < 5 * t,
        "shutdown took {took:?}: the children wait before exiting"
    );
    assert!(
        took < 2 * t + Duration::from_millis(500),
        "shutdown took {took:?}: the instances must stop together"
    );
    let mut killed: Vec<(String, bool)> = events_until(&mut events, "stopped", |e| {
        matches!(e, SupervisorEvent::Stopped { .. })
    })
    .await
    .into_iter()
    .filter_map(|e| match e {
        SupervisorEvent::ChildShutdown { id, killed, .. } => Some((id, killed)),
        _ => None,
    })
    .collect();
    killed.sort();
    assert_eq!(
        killed,
        [
            ("child#1".to_string(), false),
            ("child#2".to_string(), false),
            ("child#3".to_string(), true)
        ]
    );
    let mut stops = log.with_prefix("stop");
    stops.sort();
    assert_eq!(
        stops,
        ["stop i1", "stop i2", "stop i3", "stopped i1", "stopped i2"]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hanging_restart_loop_simple() {
    let log = Log::default();
    let fail = flag(false);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::simple_one_for_one(template(&log).with_shutdown(Shutdown::BrutalKill))
            .with_intensity(usize::MAX, Duration::from_secs(10)),
        vec![],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    let inst = Inst {
        fail_start: Some(fail.clone()),
        ..Inst::named("i1")
    };
    let c1 = sup.start_dynamic(inst.clone()).await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&c1);
    wait_for(&mut events, "a failed restart", |e| {
        matches!(e, SupervisorEvent::RestartFailed { .. })
    })
    .await;
    assert_eq!(
        sup.restart_child("child#1").await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    assert_eq!(
        sup.delete_child("child#1").await.unwrap_err(),
        SupervisorError::SimpleOneForOne
    );
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 1);
    assert_eq!(children[0].state, ChildState::Restarting);
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 0, 0, 1]);
    // the restarting instance is still addressed by its last actor
    sup.terminate_actor(c1.get_id()).await.unwrap();
    assert!(sup.which_children().await.unwrap().is_empty());

    fail.store(false, Ordering::SeqCst);
    let c2 = sup.start_dynamic(inst).await.unwrap();
    fail.store(true, Ordering::SeqCst);
    crash(&c2);
    wait_for(&mut events, "a failed restart", |e| {
        matches!(e, SupervisorEvent::RestartFailed { .. })
    })
    .await;
    // the supervisor does not hang in its restart loop
    assert!(sup.stop_timeout(PATIENCE).await);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn count_children_simple() {
    // OTP's count_children: 1000 temporary instances, then 1000 more, then all killed
    let log = Log::default();
    let template = template(&log).with_restart(marie_supervision::Restart::Temporary);
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::simple_one_for_one(template).with_event_capacity(8192),
        vec![],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    for _ in 0..1000 {
        sup.start_dynamic(Inst::named("i")).await.unwrap();
    }
    assert_eq!(sup.which_children().await.unwrap().len(), 1000);
    assert_eq!(
        counts(sup.count_children().await.unwrap()),
        [1, 1000, 0, 1000]
    );
    for _ in 0..1000 {
        sup.start_dynamic(Inst::named("i")).await.unwrap();
    }
    let children = sup.which_children().await.unwrap();
    assert_eq!(children.len(), 2000);
    assert_eq!(
        counts(sup.count_children().await.unwrap()),
        [1, 2000, 0, 2000]
    );
    for child in &children {
        child.state.actor().unwrap().kill();
    }
    let mut removed = 0;
    while removed < 2000 {
        wait_for(&mut events, "removals", |e| {
            matches!(e, SupervisorEvent::ChildDeleted { .. })
        })
        .await;
        removed += 1;
    }
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 0, 0, 0]);
    sup.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simple_one_for_one_scale_many_temporary_children() {
    // OTP-9242: terminating n temporary instances one by one costs O(n), not O(n²): 10 000
    // take at most 50 times as long as 1 000 (linear would be 10; the margin absorbs a
    // loaded machine)
    let log = Log::default();
    let template = template(&log).with_restart(marie_supervision::Restart::Temporary);
    let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
        .await
        .unwrap();
    async fn start_n(sup: &marie_supervision::SupervisorRef, n: usize) -> Vec<ractor::ActorId> {
        let mut actors = Vec::with_capacity(n);
        for _ in 0..n {
            actors.push(sup.start_dynamic(Inst::named("i")).await.unwrap().get_id());
        }
        actors
    }
    async fn terminate_all(
        sup: &marie_supervision::SupervisorRef,
        actors: Vec<ractor::ActorId>,
    ) -> Duration {
        let begin = std::time::Instant::now();
        for actor in actors {
            sup.terminate_actor(actor).await.unwrap();
        }
        begin.elapsed()
    }
    // the best of three small runs, against one large run
    let mut t1 = Duration::MAX;
    for _ in 0..3 {
        let c1 = start_n(&sup, 1_000).await;
        t1 = t1.min(terminate_all(&sup, c1).await);
    }
    let c2 = start_n(&sup, 10_000).await;
    assert_eq!(sup.count_children().await.unwrap().active, 10_000);
    let t2 = terminate_all(&sup, c2).await;
    let scaling = t2.as_secs_f64() / t1.as_secs_f64();
    assert!(
        scaling <= 50.0,
        "terminating 10 000 took {t2:?}, 1 000 took {t1:?}: scaling {scaling:.1}"
    );
    assert_eq!(counts(sup.count_children().await.unwrap()), [1, 0, 0, 0]);
    assert_eq!(log.with_prefix("stopped ").len(), 13_000);
    sup.stop().await;
}

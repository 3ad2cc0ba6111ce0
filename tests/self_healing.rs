//! Self-healing end to end: faults injected into the operations of the running action while
//! the thesis' missions run in the simulated world, through the `marie` binary (one process
//! per run, in virtual time), and the node's supervision tree through the library.

use crate::common;

use common::{marie, report_of, text};
use marie::cluster::fault;
use marie::cluster::node::{Node, NodeConfig, NodeOptions};
use marie::registry::{self, ModuleKind};
use marie::run::FaultKind;
use marie::supervision::SupervisorEvent;
use std::time::Duration;

/// Run `mission` with `fault` and check that it succeeded, that the fault hit `op` and that
/// the dispatcher rebound `op`, with a cause containing `cause`.
fn heals(mission: &str, fault: &str, op: &str, cause: &str) {
    let (out, json) = report_of(&["run", mission, "--fault", fault]);
    let log = format!("{}\n{}", text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{fault}: {log}");
    assert_eq!(json["outcome"], "succeeded", "{fault}: {json}");
    assert_eq!(json["inside_goal"], true, "{fault}");
    let faults = json["faults"].as_array().expect("faults in the report");
    assert_eq!(faults.len(), 1, "{json}");
    assert_eq!(faults[0]["operation"], op);
    assert!(faults[0]["error"].is_null(), "{}", faults[0]);
    let rebinds = json["rebinds"].as_array().expect("rebinds in the report");
    let rebind = rebinds
        .iter()
        .find(|r| r["operation"] == op)
        .unwrap_or_else(|| panic!("{fault}: no rebind of {op}: {json}"));
    assert_eq!(
        rebind["from"], faults[0]["actor"],
        "the faulty instance was left"
    );
    assert_ne!(rebind["to"], rebind["from"]);
    let why: marie::run::LossCause =
        serde_json::from_value(rebind["cause"].clone()).expect("a typed loss cause");
    assert!(why.to_string().contains(cause), "{fault}: cause `{why}`");
    if let marie::run::LossCause::Hung { deadline_ms } = why {
        // a hung instance is down from its last sign of life, not from when it was found out
        let down = rebind["downtime_ms"].as_u64().unwrap();
        assert!(
            down >= deadline_ms,
            "{fault}: down {down} ms < deadline {deadline_ms} ms"
        );
    }
    assert!(
        text(&out.stdout).contains(&format!("~ {op} rebound")),
        "live output shows the rebind: {log}"
    );
}

#[test]
fn docking_completes_when_the_wall_follower_is_killed_while_following_the_wall() {
    heals(
        "missions/docking.toml",
        "kill:wall-follower@20",
        "wall-follower",
        "died",
    );
}

#[test]
fn docking_completes_when_the_docking_detector_panics_while_following_the_wall() {
    heals(
        "missions/docking.toml",
        "panic:docking-detector@25",
        "docking-detector",
        "died",
    );
}

#[test]
fn docking_completes_when_the_trajectory_controller_hangs_while_parking() {
    heals(
        "missions/docking.toml",
        "hang:trajectory-controller@50",
        "trajectory-controller",
        "hung",
    );
}

#[test]
fn corner_completes_when_the_trajectory_controller_is_killed_while_driving_to_the_wall() {
    heals(
        "missions/corner.toml",
        "kill:trajectory-controller@5",
        "trajectory-controller",
        "died",
    );
}

#[test]
fn corner_completes_when_the_sensor_based_controller_panics_while_aligning() {
    heals(
        "missions/corner.toml",
        "panic:sensor-based-controller@20",
        "sensor-based-controller",
        "died",
    );
}

#[test]
fn corner_completes_when_the_sensor_based_controller_hangs_while_backing_into_the_corner() {
    heals(
        "missions/corner.toml",
        "hang:sensor-based-controller@60",
        "sensor-based-controller",
        "hung",
    );
}

/// Run `mission` under `--chaos seed` and check that it succeeded despite at least `min`
/// kills, each one rebound.
fn survives_chaos(mission: &str, seed: &str, min: usize) {
    // seeded chaos in virtual time is repeatable
    let (out, json) = report_of(&["run", mission, "--chaos", seed]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert_eq!(json["outcome"], "succeeded");
    let kills = json["faults"].as_array().unwrap().len();
    assert!(kills >= min, "{json}");
    assert_eq!(json["rebinds"].as_array().unwrap().len(), kills);
}

#[test]
fn docking_completes_under_chaos() {
    // seed 2 kills seven operations, the docking detector twice: the stand-ins resume the
    // search with the echoes gathered before the crashes
    survives_chaos("missions/docking.toml", "2", 7);
}

#[test]
fn corner_completes_under_chaos() {
    survives_chaos("missions/corner.toml", "2", 8);
}

#[test]
fn a_crash_loop_beyond_the_restart_intensity_ends_the_mission_in_a_full_stop_naming_the_operation()
{
    // seven panics within 0.6 s of mission time: more than 5 restarts in 10 s
    let specs: Vec<String> = (0..7)
        .map(|i| format!("panic:wall-follower@{}", 20.0 + 0.1 * f64::from(i)))
        .collect();
    let mut args = vec!["run", "missions/docking.toml"];
    for s in &specs {
        args.extend(["--fault", s.as_str()]);
    }
    let (out, json) = report_of(&args);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stdout));
    assert_eq!(json["outcome"], "failed");
    let reason = json["reason"].as_str().unwrap();
    assert!(
        reason.contains("the operation supervisor gave up")
            && reason.contains("more than 5 restarts within 10.0s")
            && reason.contains("wall-follower"),
        "{reason}"
    );
    assert!(text(&out.stdout).contains("mission FAILED (full stop)"));
}

#[test]
fn a_fault_for_an_operation_that_does_not_run_is_bad_input() {
    let out = marie(&["run", "missions/docking.toml", "--fault", "kill:nosuch@3"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("no operation `nosuch` is running"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn a_malformed_fault_is_bad_input() {
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "melt:wall-sensor@3",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("unknown fault `melt`"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn marie_kill_shows_the_operation_supervisor_restarting_the_operation() {
    let out = marie(&["kill", "averager"]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}{}", text(&out.stderr));
    assert!(stdout.contains("killed averager (1602)"), "{stdout}");
    assert!(
        stdout.contains("restarted by the operation supervisor as"),
        "{stdout}"
    );
    let out = marie(&["kill", "1999"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn marie_kill_shows_the_datamanager_supervisor_restarting_a_datamanager() {
    for target in ["feature", "1201"] {
        let out = marie(&["kill", target]);
        let stdout = text(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{stdout}{}", text(&out.stderr));
        assert!(stdout.contains("killed feature (1201)"), "{stdout}");
        assert!(
            stdout.contains("restarted by the datamanager supervisor as"),
            "{stdout}"
        );
    }
}

/// The README's first command with a datamanager killed (or panicking): a memory
/// datamanager survives its own crash — its next incarnation takes the records it left
/// (`dm_inherited`) — so the mission docks, and the check at the end finds every
/// acknowledged record and every put record still held. (Before, the restarted feature
/// datamanager was empty, the docking mission failed, and the verdict said "0 lost": the
/// operations' records are puts, which the check did not count.)
#[test]
fn docking_completes_when_a_datamanager_in_memory_is_killed_and_it_keeps_its_records() {
    for (fault, dm) in [
        ("kill:feature@20", "feature"),
        ("kill:feature@45", "feature"),
        ("panic:feature@20", "feature"),
        ("kill:world@20", "world"),
        // parking: the path planned and the progress driven so far
        ("kill:parameter@50", "parameter"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let events = dir.path().join("events.jsonl");
        let events_arg = events.display().to_string();
        let (out, json) = report_of(&[
            "run",
            "missions/docking.toml",
            "--speed",
            "max",
            "--fault",
            fault,
            "--events",
            &events_arg,
        ]);
        let stdout = text(&out.stdout);
        let log = format!("{stdout}\n{}", text(&out.stderr));
        assert_eq!(out.status.code(), Some(0), "{fault}: {log}");
        assert!(stdout.contains("outcome: succeeded"), "{fault}: {log}");
        assert_eq!(json["inside_goal"], true, "{fault}");
        assert_eq!(json["faults"][0]["operation"], dm, "{fault}");
        // the restarted datamanager took what its previous incarnation held
        let inherited: Vec<serde_json::Value> = std::fs::read_to_string(&events)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|e| e["kind"]["type"] == "dm_inherited")
            .collect();
        assert_eq!(inherited.len(), 1, "{fault}: {inherited:?}");
        assert_eq!(inherited[0]["kind"]["dm"], dm, "{fault}");
        assert!(
            inherited[0]["kind"]["records"].as_u64() > Some(0),
            "{fault}"
        );
        assert_eq!(inherited[0]["kind"]["refused"], 0, "{fault}");
        let recoveries = json["dm_recoveries"].as_array().expect("dm_recoveries");
        assert!(
            recoveries
                .iter()
                .any(|r| r["dm"] == dm && r["from"] == "heir"),
            "{fault}: {recoveries:?}"
        );
        // nothing lost, puts counted: the operations' sonar readings and segments
        let checks = json["dm_checks"].as_array().expect("dm_checks");
        for check in checks {
            assert_eq!(check["lost"], 0, "{fault}: {check}");
            assert!(check["applied_lost"].is_null(), "{fault}: {check}");
        }
        let feature = checks.iter().find(|c| c["dm"] == "feature").unwrap();
        let applied = feature["applied"].as_u64().unwrap_or_default();
        assert!(applied > 100, "{fault}: {feature}");
        assert_eq!(json["acknowledged_lost"], 0, "{fault}");
        assert_eq!(json["applied_lost"], 0, "{fault}");
        let puts: u64 = checks.iter().filter_map(|c| c["applied"].as_u64()).sum();
        assert!(
            stdout.contains(&format!(", 0 of {puts} put records lost, ")),
            "{fault}: the verdict: {stdout}"
        );
    }
}

#[test]
fn a_datamanager_fault_is_injected_and_in_the_report() {
    let (out, json) = report_of(&[
        "run",
        "missions/demo.toml",
        "--fault",
        "panic:parameter@0.5",
    ]);
    let faults = json["faults"].as_array().unwrap();
    assert_eq!(faults.len(), 1, "{json}");
    assert_eq!(faults[0]["fault"], "panic");
    assert_eq!(faults[0]["operation"], "parameter");
    assert!(faults[0]["error"].is_null(), "{json}");
    assert!(
        text(&out.stdout).contains("* injected panic into parameter"),
        "{}",
        text(&out.stdout)
    );
}

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn the_node_tree_is_datamanagers_operations_dynamic_provisioner_and_heals_a_killed_operation()
{
    let catalog = marie_missions::builtin_operations();
    let config = NodeConfig::everything("tree", &catalog);
    let node = Node::start(config, NodeOptions::with_catalog(catalog))
        .await
        .unwrap();
    let ids: Vec<String> = node
        .supervisor()
        .which_children()
        .await
        .unwrap()
        .into_iter()
        .map(|c| c.id)
        .collect();
    assert_eq!(
        ids,
        ["datamanagers", "operations", "dynamic", "provisioner"]
    );
    let dms: Vec<String> = node
        .datamanager_supervisor()
        .await
        .unwrap()
        .which_children()
        .await
        .unwrap()
        .into_iter()
        .map(|c| c.id)
        .collect();
    assert_eq!(dms, ["feature", "parameter", "world"]);
    let ops = node.operation_supervisor().await.unwrap();
    let mut events = ops.subscribe().await.unwrap();
    let sampler = registry::lookup(ModuleKind::Operation, "sampler")[0].clone();
    fault::inject_into(FaultKind::Kill, &sampler).unwrap();
    let killed = sampler.actor_id();
    let new = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            if let SupervisorEvent::ChildRestarted { old, new, .. } = events.recv().await.unwrap() {
                if old == Some(killed) {
                    return new;
                }
            }
        }
    })
    .await
    .expect("restarted");
    let now = registry::lookup(ModuleKind::Operation, "sampler");
    assert_eq!(now.len(), 1);
    assert_eq!(
        now[0].actor.get_id(),
        new.get_id(),
        "the registry has the new one"
    );
    node.shutdown().await;
}

/// Runs until suspended.
#[derive(Default)]
struct Endless;

impl marie::eo::Operation for Endless {
    fn identity(&self) -> marie::eo::Identity {
        marie::eo::Identity::new("endless", 7101, "1.0.0", "never finishes")
    }
    fn parameters(&self) -> marie::property::ParamSchema {
        marie::property::ParamSchema::new(vec![
            marie::property::ParamDecl::int("level", 1).range(0.0, 10.0)
        ])
    }
    fn flags(&self) -> Vec<marie::status::FlagDecl> {
        vec![marie::status::FlagDecl::new("never", "never raised")]
    }
    async fn step(
        &mut self,
        _: &mut marie::eo::OpContext,
    ) -> Result<marie::eo::Step, marie::eo::OpError> {
        Ok(marie::eo::Step::Continue)
    }
}

/// The next `ActionStarted` (`None`) or `Rebound` (the new instance's address) event.
async fn next(
    events: &mut marie::events::EventSubscription,
) -> Result<Option<String>, tokio::time::error::Elapsed> {
    use marie::events::EventKind;
    tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            match events.recv().await.map(|e| e.kind) {
                Ok(EventKind::ActionStarted { .. }) => return None,
                Ok(EventKind::Rebound(r)) => return Some(r.to),
                Ok(EventKind::RunEnded { reason, .. }) => panic!("the mission ended: {reason}"),
                Ok(_) => {}
                Err(e) => panic!("no more dispatcher events: {e}"),
            }
        }
    })
    .await
}

/// Keep the test log readable: the injected panics are expected.
fn quiet_injected_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !info.to_string().contains("injected fault") {
            default(info);
        }
    }));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_thousand_crash_restart_cycles_during_a_mission_leave_the_actor_count_at_its_baseline() {
    use marie::dispatcher::{self, DispatcherArgs, DispatcherMsg};
    use marie::dispatcher::{mission::ParsedMission, RegistryCatalog};
    use marie::supervision::{ChildSpec, Supervisor, SupervisorSpec};
    quiet_injected_panics();
    const CYCLES: usize = 1000;
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(10 * CYCLES, Duration::from_secs(1)),
        vec![ChildSpec::worker("endless", |sup| async move {
            let opts = marie::eo::HostOptions::default();
            let (a, _) = marie::eo::spawn_operation_linked(Endless, opts, sup).await?;
            Ok(a.get_cell())
        })],
    )
    .await
    .unwrap();
    let baseline = ractor::registry::get_all_pids().len();
    let tasks = || {
        tokio::runtime::Handle::current()
            .metrics()
            .num_alive_tasks()
    };
    let baseline_tasks = tasks();

    let parsed = ParsedMission::parse(
        "[mission]\nname = \"endless\"\n[flags]\nnever = 0\n[[action]]\nname = \"run\"\ndeadline_s = 3600.0\n[action.ops.endless]\nlevel = 7\n",
        None,
    )
    .unwrap();
    let catalog = RegistryCatalog::gather(parsed.ops()).await.unwrap();
    let mission = parsed.validate(&catalog).unwrap();
    let clock = marie::clock::RealClock::shared();
    let bus = marie::events::EventBus::new("test", clock.clone());
    let mut events = bus.subscribe();
    // the run's report: its events, folded
    let folded = marie::report::ReportBuilder::attach(&bus);
    let args = DispatcherArgs::new(mission, clock, bus);
    let dispatcher = dispatcher::spawn_dispatcher(args, None).await.unwrap();
    let run = {
        let d = dispatcher.clone();
        tokio::spawn(async move { dispatcher::request_run(&d).await })
    };
    assert_eq!(next(&mut events).await.expect("started"), None);
    let mut current = registry::lookup(ModuleKind::Operation, "endless")[0].clone();
    for cycle in 0..CYCLES {
        fault::inject_into(FaultKind::Panic, &current).unwrap();
        let to = next(&mut events)
            .await
            .unwrap_or_else(|_| panic!("no rebind after crash {cycle}"))
            .expect("a rebind");
        current = registry::lookup(ModuleKind::Operation, "endless")
            .into_iter()
            .find(|i| i.actor.get_id().to_string() == to)
            .expect("the stand-in is in the registry");
    }
    let _ = dispatcher.cast(DispatcherMsg::Abort {
        reason: "enough".into(),
    });
    run.await.unwrap().unwrap();
    let report = folded.finish();
    assert_eq!(report.reason, "enough");
    assert_eq!(report.rebinds_total, CYCLES as u64);
    assert_eq!(report.rebinds.len(), marie::report::REPORT_KEEPS);
    // nor do the choices of the stand-ins pile up in it (every failover chooses one, ~350
    // bytes kept per cycle before they were bounded): the start's choice and the latest
    assert!(
        report.selection_total > CYCLES as u64,
        "{}",
        report.selection_total
    );
    assert_eq!(report.selection.len(), 1 + marie::report::REPORT_KEEPS);
    assert_eq!(report.selection[0].replacing, None);
    // the dispatcher (and its registry watcher) stop once they have reported; no timer or
    // waiter of the 1000 failovers outlives the run
    let settled = tokio::time::timeout(Duration::from_secs(30), async {
        while ractor::registry::get_all_pids().len() != baseline || tasks() > baseline_tasks {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await;
    assert!(
        settled.is_ok(),
        "{} actors (baseline {baseline}), {} tasks (baseline {baseline_tasks})",
        ractor::registry::get_all_pids().len(),
        tasks()
    );
    assert_eq!(
        sup.which_children().await.unwrap()[0].restarts,
        CYCLES as u32
    );
    sup.stop().await;
}

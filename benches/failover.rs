//! Failover latency: an operation panics mid-action → its supervisor restarts it → the
//! dispatcher rebinds and re-activates the new instance. Measured from the injection to the
//! new instance's `activate` hook running; p50 and p99 over many cycles (goal: p50 ≤ 1 ms,
//! p99 ≤ 10 ms). Also the process's resident memory before and after 1000 crash cycles.
//!
//! `cargo bench --bench failover`
//!
//! A plain bench binary (not criterion): each sample is one crash, which cannot be repeated
//! in a tight loop the way criterion wants.

use marie::actors::clock::RealClock;
use marie::actors::dispatcher::mission::ParsedMission;
use marie::actors::dispatcher::{
    request_run, spawn_dispatcher, DispatcherArgs, DispatcherMsg, RegistryCatalog,
};
use marie::actors::eo::{
    spawn_operation_linked, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie::actors::property::{ParamDecl, ParamSchema};
use marie::actors::registry::{self, ModuleKind};
use marie::actors::run::FaultKind;
use marie::actors::status::FlagDecl;
use marie::cluster::fault;
use marie::supervision::{ChildSpec, Supervisor, SupervisorSpec};
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

mod common;

#[global_allocator]
static ALLOC: common::Counting = common::Counting;

fn live_kib() -> isize {
    common::live() / 1024
}

/// Where activations report when they ran.
static ACTIVATED: OnceLock<mpsc::UnboundedSender<Instant>> = OnceLock::new();

/// Runs until suspended; tells the bench when it was activated.
#[derive(Default)]
struct Worker;

impl Operation for Worker {
    fn identity(&self) -> Identity {
        Identity::new("failover-worker", 9950, "1.0.0", "runs until suspended")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("level", 1).range(0.0, 10.0)])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("never", "never raised")]
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        if let Some(tx) = ACTIVATED.get() {
            let _ = tx.send(Instant::now());
        }
        Ok(Step::Continue)
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
}

fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// Crash the running instance `n` times; the latency of each failover.
async fn crashes(n: usize, activated: &mut mpsc::UnboundedReceiver<Instant>) -> Vec<Duration> {
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let inst = loop {
            // the registry may still list the dead instance for a moment: take a live one
            if let Some(i) = registry::lookup(ModuleKind::Operation, "failover-worker")
                .into_iter()
                .find(|i| i.actor.get_status() == ractor::ActorStatus::Running)
            {
                break i;
            }
            tokio::task::yield_now().await;
        };
        let t0 = Instant::now();
        fault::inject_into(FaultKind::Panic, &inst).expect("inject");
        let t1 = tokio::time::timeout(Duration::from_secs(10), activated.recv())
            .await
            .expect("re-activated in time")
            .expect("activation channel");
        out.push(t1.saturating_duration_since(t0));
    }
    out
}

fn main() {
    // cargo passes --bench (and filters); nothing to parse
    std::panic::set_hook(Box::new(|_| {})); // the injected panics are the point
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async {
        let (tx, mut activated) = mpsc::unbounded_channel();
        ACTIVATED.set(tx).expect("set once");
        let (sup, _) = Supervisor::start(
            None,
            SupervisorSpec::one_for_one().with_intensity(1_000_000, Duration::from_secs(1)),
            vec![ChildSpec::worker("worker", |sup| async move {
                let (a, _) = spawn_operation_linked(Worker, HostOptions::default(), sup).await?;
                Ok(a.get_cell())
            })],
        )
        .await
        .expect("supervisor");
        let parsed = ParsedMission::parse(
            "[mission]\nname = \"failover\"\n[flags]\nnever = 0\n[[action]]\nname = \"run\"\n\
             deadline_s = 36000.0\n[action.ops.failover-worker]\nlevel = 3\n",
            None,
        )
        .expect("mission");
        let catalog = RegistryCatalog::gather(parsed.ops()).await.expect("catalog");
        let mission = parsed.validate(&catalog).expect("valid");
        let clock = RealClock::shared();
        let bus = marie::actors::events::EventBus::new("bench", clock.clone());
        // the run's report: its events folded (bounded: the latest rebinds, and counts)
        let folded = marie::actors::report::ReportBuilder::attach(&bus);
        let dispatcher = spawn_dispatcher(
            DispatcherArgs {
                mission,
                clock,
                bus,
            },
            None,
        )
        .await
        .expect("dispatcher");
        let run = {
            let d = dispatcher.clone();
            tokio::spawn(async move { request_run(&d).await })
        };
        // nobody subscribes to the bus: its events are not kept, only folded
        activated.recv().await.expect("first activation");

        let _ = crashes(200, &mut activated).await; // warm-up
        let (rss_before, live_before) = (rss_kib(), live_kib());
        let mut lat = crashes(1000, &mut activated).await;
        let (rss_after, live_after) = (rss_kib(), live_kib());
        let mut rss_rounds = Vec::new();
        for _ in 0..10 {
            lat.extend(crashes(1000, &mut activated).await);
            rss_rounds.push((
                rss_kib(),
                live_kib(),
                ractor::registry::get_all_pids().len(),
                tokio::runtime::Handle::current().metrics().num_alive_tasks(),
            ));
        }
        lat.sort();

        let _ = dispatcher.cast(DispatcherMsg::Abort {
            reason: "bench done".into(),
        });
        run.await.expect("join").expect("the run's end");
        let report = folded.finish();
        let report_keep = report.clone();
        tokio::time::sleep(Duration::from_millis(200)).await;
        println!("tasks after the dispatcher ended: {}", tokio::runtime::Handle::current().metrics().num_alive_tasks());
        sup.stop().await;
        tokio::time::sleep(Duration::from_millis(200)).await;
        println!("tasks after the supervisor ended: {}", tokio::runtime::Handle::current().metrics().num_alive_tasks());
        drop(report_keep);
        println!("live heap after everything stopped: {} KiB (before the crashes: {live_before} KiB)", live_kib());

        let mean = lat.iter().sum::<Duration>() / lat.len() as u32;
        println!("failover (panic -> supervisor restart -> rebind -> re-activation), {} crashes:", lat.len());
        println!(
            "  p50 {:>9.3} ms   (goal <= 1 ms)\n  p99 {:>9.3} ms   (goal <= 10 ms)\n  max {:>9.3} ms\n  mean {:>8.3} ms",
            common::percentile(&lat, 0.50).as_secs_f64() * 1e3,
            common::percentile(&lat, 0.99).as_secs_f64() * 1e3,
            lat.last().copied().unwrap_or_default().as_secs_f64() * 1e3,
            mean.as_secs_f64() * 1e3
        );
        println!(
            "RSS before 1000 crash cycles {rss_before} KiB, after {rss_after} KiB ({:+} KiB); \
             live heap {live_before} KiB -> {live_after} KiB ({:+} KiB)",
            rss_after as i64 - rss_before as i64,
            live_after - live_before
        );
        println!("after each further 1000 cycles (RSS KiB, live heap KiB, actors, tasks): {rss_rounds:?}");
        let mut causes = std::collections::BTreeMap::new();
        for r in &report.rebinds {
            *causes.entry(r.cause.clone()).or_insert(0) += 1;
        }
        println!(
            "rebinds: {} in all, the latest {} kept: {causes:?}",
            report.rebinds_total,
            report.rebinds.len()
        );
    });
}

//! Cost of starting and stopping a supervisor with many children: 1 000 vs 10 000.
//!
//! A supervisor starts its children one after the other and stops them one after the other in
//! reverse order, so the total cost should grow linearly with the number of children — the
//! per-child cost at 10 000 should be close to that at 1 000. The same holds for a
//! simple-one-for-one supervisor's temporary instances, started one by one with
//! `start_dynamic` and either terminated one by one with `terminate_actor` (OTP's
//! `simple_one_for_one_scale_many_temporary_children`) or stopped all together by the
//! supervisor's shutdown. Criterion reports each size (with the children as throughput
//! elements); a short manual pass afterwards prints the per-child costs and their ratio,
//! measured in the same run.
//!
//! `cargo bench -p marie-supervision --bench children`

use std::time::{Duration, Instant};

use criterion::{criterion_group, BenchmarkId, Criterion, Throughput};
use marie_supervision::{
    ChildSpec, ChildTemplate, Restart, Shutdown, Supervisor, SupervisorRef, SupervisorSpec,
};
use ractor::{Actor, ActorProcessingErr, ActorRef};

/// The smallest possible child.
struct Idle;

impl Actor for Idle {
    type Msg = ();
    type State = ();
    type Arguments = ();
    async fn pre_start(&self, _: ActorRef<()>, _: ()) -> Result<(), ActorProcessingErr> {
        Ok(())
    }
}

fn children(n: usize) -> Vec<ChildSpec> {
    (0..n)
        .map(|i| {
            ChildSpec::actor(format!("c{i}"), || (Idle, ()))
                .with_shutdown(Shutdown::Timeout(Duration::from_secs(5)))
        })
        .collect()
}

/// Start a supervisor with `specs`, then stop it (which stops every child in reverse order).
async fn start_stop(specs: Vec<ChildSpec>) {
    let (sup, _) = Supervisor::start(None, SupervisorSpec::one_for_one(), specs)
        .await
        .expect("supervisor starts");
    sup.stop().await;
}

/// A simple-one-for-one supervisor of temporary idle instances (argument `()`).
async fn simple_supervisor() -> SupervisorRef {
    let template = ChildTemplate::actor("idle", |_: ()| (Idle, ()))
        .with_restart(Restart::Temporary)
        .with_shutdown(Shutdown::Timeout(Duration::from_secs(5)));
    let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
        .await
        .expect("supervisor starts");
    sup
}

/// Start `n` temporary instances one by one.
async fn start_instances(sup: &SupervisorRef, n: usize) -> Vec<ractor::ActorId> {
    let mut actors = Vec::with_capacity(n);
    for _ in 0..n {
        let cell = sup.start_dynamic(()).await.expect("instance starts");
        actors.push(cell.get_id());
    }
    actors
}

/// Start `n` temporary instances, then terminate them one by one by actor.
async fn simple_start_terminate(n: usize) {
    let sup = simple_supervisor().await;
    for actor in start_instances(&sup, n).await {
        sup.terminate_actor(actor)
            .await
            .expect("instance terminates");
    }
    sup.stop().await;
}

/// Start `n` temporary instances, then stop the supervisor (all instances stop together).
async fn simple_start_shutdown(n: usize) {
    let sup = simple_supervisor().await;
    start_instances(&sup, n).await;
    sup.stop().await;
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime")
}

fn bench_children(c: &mut Criterion) {
    let rt = runtime();
    let mut group = c.benchmark_group("supervisor_start_stop");
    group.sample_size(10);
    for n in [1_000usize, 10_000] {
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, &n| {
            b.to_async(&rt).iter_batched(
                || children(n),
                start_stop,
                criterion::BatchSize::PerIteration,
            )
        });
    }
    group.finish();

    let mut group = c.benchmark_group("simple_one_for_one_temporary");
    group.sample_size(10);
    for n in [1_000usize, 10_000] {
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::new("start_terminate", n), &n, |b, &n| {
            b.to_async(&rt).iter(|| simple_start_terminate(n))
        });
        group.bench_with_input(BenchmarkId::new("start_shutdown", n), &n, |b, &n| {
            b.to_async(&rt).iter(|| simple_start_shutdown(n))
        });
    }
    group.finish();
}

/// The same work without a supervisor: spawn `n` actors linked to a plain parent, then stop
/// and await them one by one in reverse order — ractor's own cost, the baseline.
async fn raw_spawn_stop(n: usize) {
    let (parent, _) = Actor::spawn(None, Idle, ()).await.expect("parent spawns");
    let mut cells = Vec::with_capacity(n);
    for _ in 0..n {
        let (a, _) = Actor::spawn_linked(None, Idle, (), parent.get_cell())
            .await
            .expect("child spawns");
        cells.push(a.get_cell());
    }
    for c in cells.iter().rev() {
        c.stop(None);
        let _ = c.wait(None).await;
    }
    parent.stop(None);
    let _ = parent.wait(None).await;
}

/// Median per-child cost of `run(n)` over `reps` runs.
fn per_child<F: std::future::Future<Output = ()>>(
    rt: &tokio::runtime::Runtime,
    n: usize,
    reps: usize,
    run: impl Fn(usize) -> F,
) -> Duration {
    let mut runs: Vec<Duration> = (0..reps)
        .map(|_| {
            let work = run(n);
            let t = Instant::now();
            rt.block_on(work);
            t.elapsed()
        })
        .collect();
    runs.sort();
    runs[reps / 2] / n as u32
}

fn ratio_report() {
    let rt = runtime();
    let sup = |n| start_stop(children(n));
    // warm up the allocator and the runtime
    per_child(&rt, 1_000, 3, sup);
    let small = per_child(&rt, 1_000, 9, sup);
    let large = per_child(&rt, 10_000, 5, sup);
    let raw_small = per_child(&rt, 1_000, 9, raw_spawn_stop);
    let raw_large = per_child(&rt, 10_000, 5, raw_spawn_stop);
    let term_small = per_child(&rt, 1_000, 9, simple_start_terminate);
    let term_large = per_child(&rt, 10_000, 5, simple_start_terminate);
    let shut_small = per_child(&rt, 1_000, 9, simple_start_shutdown);
    let shut_large = per_child(&rt, 10_000, 5, simple_start_shutdown);
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    let ratio = |large: Duration, small: Duration| large.as_secs_f64() / small.as_secs_f64();
    println!();
    println!("start + stop, per child (median)     supervisor   ractor alone");
    println!(
        "   1 000 children:                   {:>8.2} µs    {:>8.2} µs",
        us(small),
        us(raw_small)
    );
    println!(
        "  10 000 children:                   {:>8.2} µs    {:>8.2} µs",
        us(large),
        us(raw_large)
    );
    println!(
        "  ratio 10 000 / 1 000:              {:>8.2}       {:>8.2}    (1.00 = linear)",
        ratio(large, small),
        ratio(raw_large, raw_small)
    );
    println!();
    println!("simple_one_for_one, temporary, per child (median)");
    println!("                                   start+terminate  start+shutdown");
    println!(
        "   1 000 children:                   {:>8.2} µs    {:>8.2} µs",
        us(term_small),
        us(shut_small)
    );
    println!(
        "  10 000 children:                   {:>8.2} µs    {:>8.2} µs",
        us(term_large),
        us(shut_large)
    );
    println!(
        "  ratio 10 000 / 1 000:              {:>8.2}       {:>8.2}    (1.00 = linear)",
        ratio(term_large, term_small),
        ratio(shut_large, shut_small)
    );
}

criterion_group!(benches, bench_children);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    // `cargo test --benches` / `cargo bench -- --test` only check that the bench runs
    if !std::env::args().any(|a| a == "--test" || a == "--list") {
        ratio_report();
    }
}

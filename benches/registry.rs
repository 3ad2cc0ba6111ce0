//! Registry lookup by name with 1000 operation instances published (goal: local lookup p50
//! ≤ 10 µs), against a raw `pg` member read of the same group measured in the same run.
//!
//! `cargo bench --bench registry`

use criterion::{criterion_group, criterion_main, Criterion};
use marie::registry::{self, ModuleKind};
use ractor::{pg, Actor, ActorProcessingErr, ActorRef};

/// A module that does nothing: only its registry entry matters here.
struct Quiet;
impl Actor for Quiet {
    type Msg = ();
    type State = ();
    type Arguments = ();
    async fn pre_start(&self, _: ActorRef<()>, _: ()) -> Result<(), ActorProcessingErr> {
        Ok(())
    }
}

/// 1000 instances: 100 operation names × 10 instances each.
const NAMES: u32 = 100;
const EACH: u32 = 10;

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let actors: Vec<ActorRef<()>> = rt.block_on(async {
        let mut actors = Vec::new();
        for n in 0..NAMES {
            for _ in 0..EACH {
                let (a, _) = Actor::spawn(None, Quiet, ()).await.unwrap();
                registry::publish(
                    ModuleKind::Operation,
                    2000 + n,
                    &format!("op-{n}"),
                    a.get_cell(),
                )
                .unwrap();
                actors.push(a);
            }
        }
        actors
    });
    assert_eq!(
        registry::lookup(ModuleKind::Operation, "op-42").len(),
        EACH as usize
    );
    // the baseline reads the group the lookup reads: were its name to change, it would time
    // an empty group
    let members = pg::get_scoped_members(&registry::SCOPE.to_string(), &"eo/op-42".to_string());
    assert_eq!(members.len(), EACH as usize);
    let mut g = c.benchmark_group("registry_1000");
    g.bench_function("lookup_by_name", |b| {
        b.iter(|| registry::lookup(ModuleKind::Operation, "op-42"))
    });
    g.bench_function("raw_pg_members", |b| {
        // the strings built per call, as the lookup builds its group's
        b.iter(|| pg::get_scoped_members(&registry::SCOPE.to_string(), &"eo/op-42".to_string()))
    });
    g.finish();
    for a in actors {
        a.stop(None);
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);

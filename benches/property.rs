//! Property request round trip through an EO host vs a raw ractor `call` to a trivial actor,
//! measured in the same run (goal: ≤ 1.2×).
//!
//! `cargo bench --bench property`
//!
//! Both run on a current-thread runtime: a round trip is then two task switches, and the
//! comparison is not drowned by cross-thread wake-up noise on a shared 2-core machine.

use criterion::{criterion_group, criterion_main, Criterion};
use marie::eo::EoMsg;
use marie::eo::{spawn_operation, HostOptions};
use marie::property::{Group, Identification, PropertyRequest};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use std::time::Duration;

mod common;
use common::Idle;

/// The baseline: an actor that answers a call with a small struct.
struct Echo;
enum EchoMsg {
    Ask(RpcReplyPort<(u32, String)>),
    /// Answers what the identification group answers, to split payload cost from the host's.
    AskSame(RpcReplyPort<Identification>),
}
impl ractor::Message for EchoMsg {}
impl Actor for Echo {
    type Msg = EchoMsg;
    type State = Identification;
    type Arguments = ();
    async fn pre_start(
        &self,
        _: ActorRef<EchoMsg>,
        _: (),
    ) -> Result<Identification, ActorProcessingErr> {
        Ok(Identification {
            name: "bench-idle".into(),
            id: 9900,
            version: "1.0.0".into(),
            description: "does nothing".into(),
        })
    }
    async fn handle(
        &self,
        _: ActorRef<EchoMsg>,
        msg: EchoMsg,
        same: &mut Identification,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            EchoMsg::Ask(reply) => {
                let _ = reply.send((9900, "bench-idle".to_string()));
            }
            EchoMsg::AskSame(reply) => {
                let _ = reply.send(same.clone());
            }
        }
        Ok(())
    }
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let (op, echo) = rt.block_on(async {
        let (op, _) = spawn_operation(Idle, HostOptions::default()).await.unwrap();
        let (echo, _) = Actor::spawn(None, Echo, ()).await.unwrap();
        (op, echo)
    });
    let mut g = c.benchmark_group("property_round_trip");
    g.measurement_time(Duration::from_secs(5));
    g.bench_function("raw_ractor_call", |b| {
        b.to_async(&rt)
            .iter(|| async { ractor::call!(echo, EchoMsg::Ask).unwrap() })
    });
    g.bench_function("raw_call_same_answer", |b| {
        b.to_async(&rt)
            .iter(|| async { ractor::call!(echo, EchoMsg::AskSame).unwrap() })
    });
    g.bench_function("property_identification", |b| {
        b.to_async(&rt).iter(|| async {
            ractor::call!(op, |reply| EoMsg::Property {
                request: PropertyRequest::Group(Group::Identification),
                reply
            })
            .unwrap()
        })
    });
    g.bench_function("property_get_version", |b| {
        b.to_async(&rt).iter(|| async {
            ractor::call!(op, |reply| EoMsg::Property {
                request: PropertyRequest::Get("version".into()),
                reply
            })
            .unwrap()
        })
    });
    g.finish();
    op.stop(None);
    echo.stop(None);
}

criterion_group!(benches, bench);
criterion_main!(benches);

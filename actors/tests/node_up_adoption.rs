//! A stand-in that joined the registry while its node was still declared down is adopted
//! once the node is up again.
//!
//! In a cluster a node's modules reach a peer's registry before the session with it is
//! ready — ractor_cluster exchanges the process groups first —, and only a ready session
//! lifts the failure detector's verdict on the node. So the operations a node restarts as
//! it wakes from a freeze past the deadline show up, in the dispatcher's registry, while
//! their node is still declared down, and are ruled out as stand-ins then. Here that order
//! is played in one process, on the process's own node (which is why this test has a
//! binary of its own: the verdicts are the process's): its verdict set, the stand-in
//! started, the bound instance lost with the node; once the lost binding has looked for a
//! stand-in (the cluster's provisioners asked, after the grace), the verdict lifted and the
//! node up on the bus.

mod common;

use common::ops::{general, Worker};
use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::EoClient;
use marie_actors::provision::{self, ProvisionMsg, Refusal};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind};
use marie_vocabulary::registry;
use marie_vocabulary::run::{LossCause, Outcome};
use ractor::{Actor, ActorProcessingErr, ActorRef};
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::time::timeout;

/// Generous: a loaded 2-core machine may be slow.
const T: Duration = Duration::from_secs(30);

/// An instance of the test's [`Worker`].
async fn start() -> EoClient {
    Worker::new("nu-worker", 4100, "1.0.0")
        .steps_only()
        .start()
        .await
}

async fn in_use(c: &EoClient) -> bool {
    general(c).await.in_use
}

/// A provisioner that starts nothing: it tells the test each time it is asked, and refuses
/// (the cluster has no node that could start the operation now).
struct Refusing;

impl Actor for Refusing {
    type Msg = ProvisionMsg;
    type State = mpsc::UnboundedSender<String>;
    type Arguments = mpsc::UnboundedSender<String>;

    async fn pre_start(
        &self,
        myself: ActorRef<ProvisionMsg>,
        asked: Self::Arguments,
    ) -> Result<Self::State, ActorProcessingErr> {
        provision::publish(myself.get_cell());
        Ok(asked)
    }

    async fn handle(
        &self,
        _myself: ActorRef<ProvisionMsg>,
        msg: ProvisionMsg,
        asked: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        let ProvisionMsg::Start {
            operation, reply, ..
        } = msg;
        let _ = asked.send(operation);
        let _ = reply.send(Err(Refusal::Text("no node can start it now".into())));
        Ok(())
    }
}

const MISSION: &str = r#"
[mission]
name = "node-up"
success = ["done"]
rebind_deadline_s = 20.0
[flags]
done = 0
[[action]]
name = "work"
[action.ops.nu-worker]
steps = 1500
"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stand_in_that_joined_while_its_node_was_declared_down_is_adopted_once_it_is_up() {
    let node = registry::local_node_name();
    let first = start().await;
    let (asked_tx, mut asked) = mpsc::unbounded_channel();
    let (_provisioner, _) = Actor::spawn(None, Refusing, asked_tx).await.unwrap();

    let parsed = ParsedMission::parse(MISSION, None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mission = parsed.validate(&catalog).expect("mission validates");
    let clock = RealClock::shared();
    let bus = EventBus::new(node.clone(), clock.clone());
    let mut events = bus.subscribe();
    let run = tokio::spawn({
        let bus = bus.clone();
        async move {
            timeout(T * 2, run_mission(mission, clock, Some(bus)))
                .await
                .expect("mission ends")
                .expect("dispatcher runs")
        }
    });
    let deadline = tokio::time::Instant::now() + T;
    while !in_use(&first).await {
        assert!(tokio::time::Instant::now() < deadline, "never activated");
        tokio::time::sleep(Duration::from_millis(1)).await;
    }

    // the node is declared down; what it restarts joins the registry meanwhile
    registry::declare_down(&node);
    let second = start().await;
    bus.publish(EventKind::NodeDown {
        peer: node.clone(),
        silent_ms: 1500,
    });
    let lost = timeout(T, async {
        loop {
            if let EventKind::Lost { operation, cause } = events.recv().await.unwrap().kind {
                return (operation, cause);
            }
        }
    })
    .await
    .expect("the binding is lost");
    assert_eq!(
        lost,
        (
            "nu-worker".to_string(),
            LossCause::NodeDown { node: node.clone() }
        )
    );
    first.actor().kill();
    // no stand-in within the grace (the second is on a node declared down): the cluster
    // is asked for one, in vain; then the node is up again
    let operation = timeout(T, asked.recv())
        .await
        .expect("the cluster is asked");
    assert_eq!(operation.as_deref(), Some("nu-worker"));
    registry::declare_up(&node);
    bus.publish(EventKind::NodeUp {
        peer: node.clone(),
        address: "127.0.0.1:1".into(),
    });

    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{}", report.reason);
    assert_eq!(report.rebinds.len(), 1, "{:?}", report.rebinds);
    let rebind = &report.rebinds[0];
    assert_eq!(rebind.from, first.actor().get_id().to_string());
    assert_eq!(rebind.to, second.actor().get_id().to_string());
    assert_eq!(rebind.to_node, node);
    assert_eq!(rebind.cause, LossCause::NodeDown { node });
}

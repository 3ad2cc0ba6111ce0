//! A node joins the cluster its config names — built with `Node::builder(..).cluster(..)`
//! or started with `Node::start` on a config `with_cluster` — and leaves it at shutdown; a
//! cluster setting that cannot work is refused, never ignored.
//!
//! One node per process is what a cluster needs (ractor's registry and process groups are
//! process-wide); here one node at a time listens, and a plain TCP connection tells whether
//! it does. Two processes that fail over are `embedding/failover`'s test.

use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_cluster::net::{ClusterConfig, HeartbeatConfig, TransportError};
use marie_cluster::node::{Node, NodeConfig, NodeError, NodeOptions};
use marie_vocabulary::registry::{self, ModuleKind};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::Duration;

/// An operation that does nothing, registered under the name it is given (each test owns
/// its names: the registry is one per process).
#[derive(Clone)]
struct Idle(&'static str);
impl Operation for Idle {
    fn identity(&self) -> Identity {
        Identity::new(self.0, 9401, "1.0.0", "does nothing")
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
}

fn any_port() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 0))
}

/// Whether something accepts TCP connections at `addr`.
fn listens(addr: SocketAddr) -> bool {
    TcpStream::connect_timeout(&addr, Duration::from_secs(5)).is_ok()
}

fn refused(started: Result<Node, NodeError>) -> NodeError {
    match started {
        Ok(_) => panic!("the node started"),
        Err(e) => e,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_joins_the_cluster_its_config_names_and_leaves_it_at_shutdown() {
    // the builder's road
    let node = Node::builder("join-built")
        .operation_value(Idle("join-idle"))
        .cluster(
            ClusterConfig::new(any_port(), "c")
                .with_heartbeat(HeartbeatConfig::with_deadline(Duration::from_secs(2))),
        )
        .start()
        .await
        .expect("starts and joins");
    let transport = node.transport().expect("it joined");
    let addr = transport.listen();
    assert_ne!(addr.port(), 0, "the port the system picked");
    assert_eq!(transport.node(), "join-built");
    assert!(transport.peers().is_empty());
    assert!(listens(addr), "nothing listens on {addr}");
    assert!(node.reincarnations().is_some());
    node.shutdown().await;
    assert!(!listens(addr), "{addr} still listens after the node left");

    // `Node::start` on a config with a cluster: the same road
    let config = NodeConfig::new("join-config").with_cluster(ClusterConfig::new(any_port(), "c"));
    let node = Node::start(config, NodeOptions::with_catalog(Vec::new()))
        .await
        .expect("starts and joins");
    let addr = node.transport().expect("it joined").listen();
    assert!(listens(addr), "nothing listens on {addr}");
    node.shutdown().await;
    assert!(!listens(addr), "{addr} still listens after the node left");
}

#[tokio::test]
async fn a_node_without_a_cluster_has_no_transport() {
    let node = Node::builder("join-none").start().await.expect("starts");
    assert!(node.transport().is_none());
    assert!(node.reincarnations().is_none());
    node.shutdown().await;
}

#[tokio::test]
async fn cluster_settings_that_cannot_work_are_refused_before_anything_starts() {
    let start = |name: &str, cluster: ClusterConfig| {
        Node::builder(name)
            .operation_value(Idle("join-refused"))
            .cluster(cluster)
            .start()
    };
    let err = refused(start("join-cookie", ClusterConfig::new(any_port(), "")).await);
    assert!(
        matches!(err, NodeError::Cluster(TransportError::Config(_))),
        "{err}"
    );
    assert!(err.to_string().contains("cookie"), "{err}");
    let err = refused(start("join@host", ClusterConfig::new(any_port(), "c")).await);
    assert!(err.to_string().contains("join@host"), "{err}");
    let short = HeartbeatConfig::with_deadline(Duration::from_millis(10));
    let err = refused(
        start(
            "join-heartbeat",
            ClusterConfig::new(any_port(), "c").with_heartbeat(short),
        )
        .await,
    );
    assert!(err.to_string().contains("deadline"), "{err}");
    assert!(registry::lookup(ModuleKind::Operation, "join-refused").is_empty());
}

#[tokio::test]
async fn a_taken_listen_address_is_refused_and_the_half_started_node_stopped() {
    let taken = TcpListener::bind(any_port()).expect("bind");
    let addr = taken.local_addr().expect("address");
    let err = refused(
        Node::builder("join-taken")
            .operation_value(Idle("join-taken"))
            .cluster(ClusterConfig::new(addr, "c"))
            .start()
            .await,
    );
    assert!(
        matches!(err, NodeError::Cluster(TransportError::Listen { .. })),
        "{err}"
    );
    assert!(err.to_string().contains(&addr.to_string()), "{err}");
    // what had started is stopped again: its operation left the registry
    assert!(registry::lookup(ModuleKind::Operation, "join-taken").is_empty());
}

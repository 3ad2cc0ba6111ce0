//! A session the peer turns away is dialled again at once, not after the dial timeout.
//!
//! ractor_cluster's `client_connect` returns before the handshake; the dialer then waits
//! for its session to be ready. When the peer turns the session away (a duplicate around a
//! restart, a failed handshake) and nothing tells the dialer, it waits out the whole dial
//! timeout before the next dial. Here the peer's address is a listener that hands its first
//! connection to a ractor_cluster node server with another cookie (the handshake fails, the
//! session ends) and every later one to a node server with the cluster's cookie, under the
//! same node name. The dial timeout is 30 s: the peer ready well within the test's 20 s
//! means the dialer heard its first session end and dialled again, before the timeout
//! could end its wait.
//!
//! The peer's two node servers run in this process beside the transport (ractor's process
//! groups are one per process, so the peer sees the transport's own actors as remote ones
//! too — harmless here: the test looks at sessions only, and the heartbeat's deadline is
//! longer than the test).

use marie_cluster::net::{ClusterConfig, HeartbeatConfig, Transport};
use ractor::{Actor, ActorRef};
use ractor_cluster::node::NodeConnectionMode;
use ractor_cluster::{NetworkStream, NodeServer, NodeServerMessage};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;

/// Longer than the test: a wait the dialer ends only by this timeout fails it.
const DIAL_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the test waits for the peer: generous on a loaded machine, shorter than
/// [`DIAL_TIMEOUT`].
const WAIT: Duration = Duration::from_secs(20);
const COOKIE: &str = "redial";
const PEER: &str = "redial-peer";

/// A node server named [`PEER`] with `cookie`, naming itself as listening on `port`.
async fn peer_server(cookie: &str, port: u16) -> ActorRef<NodeServerMessage> {
    let server = NodeServer::new(
        0,
        cookie.to_string(),
        PEER.to_string(),
        "127.0.0.1".to_string(),
        None,
        Some(NodeConnectionMode::Isolated),
    )
    .with_listen_addr([127, 0, 0, 1].into());
    let (server, _) = Actor::spawn(None, server, ()).await.expect("a node server");
    server
        .cast(NodeServerMessage::PortChanged { port })
        .expect("the node server takes its port");
    server
}

/// Hand the connections to `listener`'s first to `first`, the later ones to `later`, as
/// incoming sessions; count them in `accepted`.
async fn hand_over(
    listener: TcpListener,
    first: ActorRef<NodeServerMessage>,
    later: ActorRef<NodeServerMessage>,
    accepted: Arc<AtomicUsize>,
) {
    while let Ok((stream, peer_addr)) = listener.accept().await {
        let Ok(local_addr) = stream.local_addr() else {
            continue;
        };
        let server = match accepted.fetch_add(1, Ordering::SeqCst) {
            0 => &first,
            _ => &later,
        };
        let _ = server.cast(NodeServerMessage::ConnectionOpened {
            stream: Box::new(NetworkStream::Raw {
                peer_addr,
                local_addr,
                stream,
            }),
            is_server: true,
        });
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dialled_session_turned_away_is_dialled_again_before_the_dial_timeout() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr: SocketAddr = listener.local_addr().unwrap();
    let refusing = peer_server("another cookie", addr.port()).await;
    let welcoming = peer_server(COOKIE, addr.port()).await;
    let accepted = Arc::new(AtomicUsize::new(0));
    let serving = tokio::spawn(hand_over(
        listener,
        refusing.clone(),
        welcoming.clone(),
        accepted.clone(),
    ));

    let config = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE)
        .with_peer(addr)
        .with_dial_timeout(DIAL_TIMEOUT)
        .with_heartbeat(HeartbeatConfig::with_deadline(Duration::from_secs(120)));
    let transport = Transport::start("redial-me", &config).await.unwrap();
    let seen = transport.wait_for_peers(1, WAIT).await;
    let connections = accepted.load(Ordering::SeqCst);
    let peers = seen.unwrap_or_else(|e| {
        panic!(
            "{e} ({connections} connection(s) dialled): the dialer waited for the session \
             the peer turned away instead of dialling again"
        )
    });
    assert_eq!(peers[0].name, PEER);
    assert_eq!(peers[0].address, addr.to_string());
    assert!(
        connections >= 2,
        "ready through the first session, which the peer turns away? {connections}"
    );

    transport.stop().await;
    serving.abort();
    refusing.stop(None);
    welcoming.stop(None);
}

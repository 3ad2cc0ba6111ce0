//! A node's listener: marie accepts its peers' connections itself and hands ractor_cluster
//! only streams ready for a session.
//!
//! ractor_cluster's own listener awaits each TLS handshake before it accepts the next
//! connection, with no time limit, so one silent client would stop a node from accepting
//! any peer; and it cannot tell marie the port it bound before the node names itself. Here
//! a plain connection is handed over at once, and a TLS one after its handshake and the
//! check of the name in its client certificate (`Tls::check_client`), which run on a task
//! of its own — at most [`MAX_HANDSHAKES`] at once, each for at most [`HANDSHAKE_TIMEOUT`].
//! (ractor_cluster's listener still runs, on a port nobody is told; with TLS it completes
//! no handshake, since it would not check that name.)

use super::events::NetEvent;
use super::sessions::Sessions;
use super::tls::Tls;
use ractor::ActorRef;
use ractor_cluster::{NetworkStream, NodeServerMessage};
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// Longest an incoming connection may take to complete its TLS handshake.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// Most incoming handshakes in progress at once; a connection beyond them is closed.
pub const MAX_HANDSHAKES: usize = 64;

/// Accept connections on `listener` and hand them to `server`: at once without `tls`, after
/// a handshake on a task of its own with it; a connection that fails its handshake, or
/// whose certificate names neither the address it comes from nor `server_name`, is closed
/// and told as [`NetEvent::ConnectionRefused`].
pub(crate) async fn serve(
    listener: TcpListener,
    tls: Option<Tls>,
    server: ActorRef<NodeServerMessage>,
    sessions: Sessions,
) {
    let slots = Arc::new(Semaphore::new(MAX_HANDSHAKES));
    loop {
        let (stream, peer_addr) = match listener.accept().await {
            Ok(s) => s,
            Err(e) => {
                // e.g. out of file descriptors: wait rather than spin
                tracing::warn!(error = %e, "accepting a connection failed");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        let local_addr = match stream.local_addr() {
            Ok(a) => a,
            Err(e) => {
                tracing::debug!(%peer_addr, error = %e, "a connection closed before it was served");
                continue;
            }
        };
        let Some(tls) = &tls else {
            open(
                &server,
                NetworkStream::Raw {
                    peer_addr,
                    local_addr,
                    stream,
                },
            );
            continue;
        };
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            tracing::warn!(%peer_addr, "{MAX_HANDSHAKES} TLS handshakes in progress: connection closed");
            continue;
        };
        let (tls, server, sessions) = (tls.clone(), server.clone(), sessions.clone());
        tokio::spawn(async move {
            let _slot = slot;
            let refused = |reason: String| {
                sessions.tell_refusal(NetEvent::ConnectionRefused {
                    from: peer_addr,
                    reason,
                })
            };
            match tokio::time::timeout(HANDSHAKE_TIMEOUT, tls.acceptor().accept(stream)).await {
                Err(_) => refused(format!(
                    "no TLS handshake within {} s",
                    HANDSHAKE_TIMEOUT.as_secs()
                )),
                Ok(Err(e)) => refused(format!("TLS: {e}")),
                // a certificate of the cluster's CA, but made out to another address (or to
                // none): dropped before ractor_cluster sees the stream
                Ok(Ok(stream)) => {
                    match tls.check_client(stream.get_ref().1.peer_certificates(), peer_addr.ip()) {
                        Err(e) => refused(format!("TLS: {e}")),
                        Ok(()) => open(
                            &server,
                            NetworkStream::TlsServer {
                                peer_addr,
                                local_addr,
                                stream,
                            },
                        ),
                    }
                }
            }
        });
    }
}

/// Hand an incoming stream to ractor_cluster, which opens a session on it.
fn open(server: &ActorRef<NodeServerMessage>, stream: NetworkStream) {
    let _ = server.cast(NodeServerMessage::ConnectionOpened {
        stream: Box::new(stream),
        is_server: true,
    });
}

//! `--join ADDR --cookie C`: how a verb acts on a running cluster — it joins as a short-lived
//! member named after itself (`run-4242`, `ls-4242`), sees the others' modules in its
//! registry, does its work and leaves.

use super::args::RobotArgs;
use super::error::BadInput;
use marie::cluster::net::{ClusterConfig, NetEvent, Peer, TlsFiles, Transport};
use marie::cluster::node::{NodeConfig, SimulationConfig};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

/// How long a joining command waits for the node it dials.
pub(crate) const JOIN_TIMEOUT: Duration = Duration::from_secs(10);
/// A joining command acts once no new peer has appeared for this long (the members behind
/// the one it dialed are dialed a moment after).
pub(crate) const QUIET: Duration = Duration::from_millis(300);

/// The flags of a verb that can act on a running cluster.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct JoinArgs {
    /// Act on a running cluster: the address of any one of its nodes (`marie node` or
    /// `marie up` print them).
    #[arg(long, value_name = "ADDR", requires = "cookie")]
    pub join: Option<SocketAddr>,
    /// The cluster's cookie (with `--join`).
    #[arg(long, value_name = "C", requires = "join")]
    pub cookie: Option<String>,
    /// With `--join` to a cluster that runs mutual TLS: this member's certificate (PEM),
    /// signed by the cluster's CA.
    #[arg(long, value_name = "FILE", requires_all = ["join", "tls_key", "tls_ca"])]
    pub tls_cert: Option<PathBuf>,
    /// This member's private key (PEM), with `--tls-cert`.
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// The cluster's CA certificate (PEM), with `--tls-cert`.
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub tls_ca: Option<PathBuf>,
    /// The name the nodes' certificates carry (default: the node's IP address).
    #[arg(long, value_name = "NAME", requires = "tls_cert")]
    pub tls_server_name: Option<String>,
}

/// Where and how a command joins a running cluster.
#[derive(Debug, Clone)]
pub(crate) struct ClusterEntry {
    /// Any node of the cluster.
    pub addr: SocketAddr,
    /// The cluster's cookie.
    pub cookie: String,
    /// This member's TLS files, for a cluster that runs TLS.
    pub tls: Option<TlsFiles>,
}

impl JoinArgs {
    /// Where to join, when `--join` was given.
    pub(crate) fn target(&self) -> Option<ClusterEntry> {
        let tls = match (&self.tls_cert, &self.tls_key, &self.tls_ca) {
            (Some(cert), Some(key), Some(ca)) => Some(TlsFiles {
                cert: cert.clone(),
                key: key.clone(),
                ca: ca.clone(),
                server_name: self.tls_server_name.clone(),
            }),
            _ => None,
        };
        Some(ClusterEntry {
            addr: self.join?,
            cookie: self.cookie.clone()?,
            tls,
        })
    }

    /// The member a mission verb (`run`, `check`) joins as, when `--join` was given: it
    /// hosts the dispatcher (and judges with `--world`), so only `--node` is refused. `speed`
    /// is the cluster's factor, checked.
    pub(crate) fn joining(
        &self,
        verb: &str,
        robot: &RobotArgs,
        speed: f64,
    ) -> Result<Option<Joining>, BadInput> {
        let Some(target) = self.target() else {
            return Ok(None);
        };
        if robot.node.is_some() {
            return Err(BadInput(format!(
                "--join {verb}s in a running cluster: --node starts a node of its own"
            )));
        }
        let speed = marie::cluster::layout::cluster_speed(speed)
            .map_err(|e| BadInput(format!("--speed with --join: {e}")))?;
        Ok(Some(Joining {
            me: member_name(verb),
            target,
            speed,
        }))
    }

    /// [`JoinArgs::target`] for a verb that otherwise starts a node of its own: `--node`
    /// and `--world` (in `robot`) make no sense with `--join` (bad input). `acts` says what
    /// the verb does in the cluster, for the message.
    pub(crate) fn target_alone(
        &self,
        robot: &RobotArgs,
        acts: &str,
    ) -> Result<Option<ClusterEntry>, BadInput> {
        match self.target() {
            Some(_) if robot.node.is_some() || robot.world.is_some() => Err(BadInput(format!(
                "--join {acts} a running cluster: --node and --world start a node of their own"
            ))),
            target => Ok(target),
        }
    }
}

/// The name a command's member takes: the verb and the process id.
pub(crate) fn member_name(verb: &str) -> String {
    format!("{verb}-{}", std::process::id())
}

/// Join the cluster at `target` as member `me` (listening on a free port of the address
/// it dials from): wait for the node dialed and the members behind it, say on stderr whom
/// it sees.
pub(crate) async fn join(me: &str, target: &ClusterEntry) -> anyhow::Result<Transport> {
    let addr = target.addr;
    let any_port = SocketAddr::new(local_ip_towards(addr), 0);
    let mut config = ClusterConfig::new(any_port, target.cookie.clone()).with_peer(addr);
    config.tls = target.tls.clone();
    config.validate(me).map_err(|e| BadInput(e.to_string()))?;
    let transport = match Transport::start(me, &config).await {
        Ok(t) => t,
        Err(e @ marie::cluster::net::TransportError::Tls(_)) => {
            return Err(BadInput(e.to_string()).into())
        }
        Err(e) => return Err(e.into()),
    };
    let joined = tokio::select! {
        seen = transport.wait_for_peers(1, JOIN_TIMEOUT) => seen.map(|_| ()).map_err(|e| {
            format!(
                "{e} (is a node listening there, with this cookie{}?)",
                match &target.tls {
                    Some(_) => format!(
                        " and a certificate from its CA naming {}, the address this member \
                         dials from",
                        any_port.ip()
                    ),
                    None => " and without TLS".into(),
                }
            )
        }),
        why = refused(&transport, addr) => Err(why),
    };
    if let Err(why) = joined {
        transport.stop().await;
        anyhow::bail!("{me} could not join the cluster at {addr}: {why}");
    }
    let peers = transport.settle(QUIET, JOIN_TIMEOUT).await;
    eprintln!("{me} sees {}", describe(&peers));
    Ok(transport)
}

/// Once the node at `addr` is refused — this member refused its certificate, or it refused
/// this member at authentication —, why: a refusal is no reason to wait longer.
async fn refused(transport: &Transport, addr: SocketAddr) -> String {
    // subscribed before the look at what was refused already: nothing told in between is
    // missed
    let (_, mut news) = transport.events();
    if let Some(why) = transport.refusal(addr).and_then(|e| why_refused(&e, addr)) {
        return why;
    }
    loop {
        match news.recv().await {
            Ok(event) => {
                if let Some(why) = why_refused(&event, addr) {
                    return why;
                }
            }
            Err(RecvError::Lagged(_)) => {}
            Err(RecvError::Closed) => return std::future::pending().await,
        }
    }
}

/// What `event` says of a refusal of the node at `addr`, if it is one.
fn why_refused(event: &NetEvent, addr: SocketAddr) -> Option<String> {
    match event {
        NetEvent::DialRefused { to, reason } if *to == addr => Some(format!(
            "this member refused the node's certificate: {reason}"
        )),
        NetEvent::RefusedBy {
            peer,
            address,
            reason,
        } if *address == addr.to_string() => Some(format!("{peer} refused this member: {reason}")),
        _ => None,
    }
}

/// The local address a connection to `peer` leaves from (peers dial a member back there):
/// loopback for a loopback peer.
fn local_ip_towards(peer: SocketAddr) -> std::net::IpAddr {
    if peer.ip().is_loopback() {
        return std::net::Ipv4Addr::LOCALHOST.into();
    }
    std::net::UdpSocket::bind("0.0.0.0:0")
        .and_then(|s| s.connect(peer).and_then(|()| s.local_addr()))
        .map(|a| a.ip())
        .unwrap_or(std::net::Ipv4Addr::LOCALHOST.into())
}

/// `alpha (127.0.0.1:7001), beta (127.0.0.1:7002)`.
pub(crate) fn describe(peers: &[Peer]) -> String {
    if peers.is_empty() {
        return "nobody".into();
    }
    peers
        .iter()
        .map(|p| format!("{} ({})", p.name, p.address))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A mission run (or checked) from a member of a running cluster (`--join ADDR --cookie C`).
#[derive(Clone, Debug)]
pub(crate) struct Joining {
    /// The member's name (`run-4242`).
    pub me: String,
    /// Where it joins.
    pub target: ClusterEntry,
    /// The cluster's speed factor.
    pub speed: f64,
}

impl Joining {
    /// The member's node: a dispatcher and nothing else — the operations, datamanagers and
    /// the cart are the cluster's — plus, when a world is known, the robot without drivers,
    /// to judge the run by the cart's final pose (asked of the cart wherever it runs).
    pub(crate) fn config(&self) -> NodeConfig {
        NodeConfig {
            simulation: Some(SimulationConfig {
                world: None,
                world_at: None,
                seed: None,
                drivers: false,
            }),
            ..NodeConfig::new(self.me.clone())
        }
    }
}

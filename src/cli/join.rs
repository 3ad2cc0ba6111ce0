//! `--join ADDR --cookie C`: how a verb acts on a running cluster — it joins as a short-lived
//! member named after itself (`run-4242`, `ls-4242`), sees the others' modules in its
//! registry, does its work and leaves.

use super::args::RobotArgs;
use super::error::BadInput;
use super::prepare::Joining;
use marie::net::{ClusterConfig, Peer, Transport};
use std::net::SocketAddr;
use std::time::Duration;

/// How long a joining command waits for the node it dials.
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(10);
/// A joining command acts once no new peer has appeared for this long (the members behind
/// the one it dialed are dialed a moment after).
pub const QUIET: Duration = Duration::from_millis(300);

/// The flags of a verb that can act on a running cluster.
#[derive(clap::Args, Debug, Clone)]
pub struct JoinArgs {
    /// Act on a running cluster: the address of any one of its nodes (`marie node` or
    /// `marie up` print them).
    #[arg(long, value_name = "ADDR", requires = "cookie")]
    pub join: Option<SocketAddr>,
    /// The cluster's cookie (with `--join`).
    #[arg(long, value_name = "C", requires = "join")]
    pub cookie: Option<String>,
}

impl JoinArgs {
    /// The address and cookie, when `--join` was given.
    pub fn target(&self) -> Option<(SocketAddr, &str)> {
        Some((self.join?, self.cookie.as_deref()?))
    }

    /// The member a mission verb (`run`, `check`) joins as, when `--join` was given: it
    /// hosts the dispatcher (and judges with `--world`), so only `--node` is refused. `speed`
    /// is the cluster's factor, checked.
    pub fn joining(
        &self,
        verb: &str,
        robot: &RobotArgs,
        speed: f64,
    ) -> Result<Option<Joining>, BadInput> {
        let Some((addr, cookie)) = self.target() else {
            return Ok(None);
        };
        if robot.node.is_some() {
            return Err(BadInput(format!(
                "--join {verb}s in a running cluster: --node starts a node of its own"
            )));
        }
        let speed = marie::layout::cluster_speed(speed)
            .map_err(|e| BadInput(format!("--speed with --join: {e}")))?;
        Ok(Some(Joining {
            me: member_name(verb),
            addr,
            cookie: cookie.to_string(),
            speed,
        }))
    }

    /// [`JoinArgs::target`] for a verb that otherwise starts a node of its own: `--node`
    /// and `--world` (in `robot`) make no sense with `--join` (bad input). `acts` says what
    /// the verb does in the cluster, for the message.
    pub fn target_alone(
        &self,
        robot: &RobotArgs,
        acts: &str,
    ) -> Result<Option<(SocketAddr, &str)>, BadInput> {
        match self.target() {
            Some(_) if robot.node.is_some() || robot.world.is_some() => Err(BadInput(format!(
                "--join {acts} a running cluster: --node and --world start a node of their own"
            ))),
            target => Ok(target),
        }
    }
}

/// The name a command's member takes: the verb and the process id.
pub fn member_name(verb: &str) -> String {
    format!("{verb}-{}", std::process::id())
}

/// Join the cluster at `addr` as member `me` (listening on a free loopback port): wait for
/// the node dialed and the members behind it, say on stderr whom it sees.
pub async fn join(me: &str, addr: SocketAddr, cookie: &str) -> anyhow::Result<Transport> {
    let any_port = SocketAddr::new(std::net::Ipv4Addr::LOCALHOST.into(), 0);
    let config = ClusterConfig::new(any_port, cookie).with_peer(addr);
    config.validate(me).map_err(|e| BadInput(e.to_string()))?;
    let transport = Transport::start(me, &config).await?;
    if let Err(e) = transport.wait_for_peers(1, JOIN_TIMEOUT).await {
        transport.stop().await;
        anyhow::bail!(
            "{me} could not join the cluster at {addr}: {e} (is a node listening there, with \
             this cookie?)"
        );
    }
    let peers = transport.settle(QUIET, JOIN_TIMEOUT).await;
    eprintln!("{me} sees {}", describe(&peers));
    Ok(transport)
}

/// `alpha (127.0.0.1:7001), beta (127.0.0.1:7002)`.
pub fn describe(peers: &[Peer]) -> String {
    if peers.is_empty() {
        return "nobody".into();
    }
    peers
        .iter()
        .map(|p| format!("{} ({})", p.name, p.address))
        .collect::<Vec<_>>()
        .join(", ")
}

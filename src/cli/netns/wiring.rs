//! The `ip` commands that make a private network of Linux network namespaces — a hub that
//! routes between node namespaces, each joined to it by a veth pair — cut two of its nodes
//! apart, and sweep up the namespaces that processes gone (a `kill -9`) left behind.
//!
//! ```text
//!   node 0 (10.77.1.2) ──veth── 10.77.1.1 ┐
//!   node 1 (10.77.2.2) ──veth── 10.77.2.1 ├─ hub (forwards)
//!   node 2 (10.77.3.2) ──veth── 10.77.3.1 ┘
//! ```
//!
//! Shared by `marie up`'s private network (`src/cli/netns/mod.rs`) and the partition tests'
//! (`tests/common/netns.rs`), which include this file with `#[path]`: the root package is a
//! binary only, so its tests cannot link to its code, and the network the tests cut must be
//! wired as the one `marie up` cuts. So it uses nothing but std and thiserror.

use std::net::Ipv4Addr;
use std::process::Command;

/// An `ip` command that failed.
#[derive(Debug, thiserror::Error)]
pub(crate) enum IpError {
    /// `ip` did not run (not installed).
    #[error("cannot run `ip`: {0}")]
    Spawn(#[source] std::io::Error),
    /// It ran and failed.
    #[error("ip {args}: {stderr}")]
    Failed {
        /// Its arguments.
        args: String,
        /// What it said.
        stderr: String,
    },
}

/// Run `ip ARGS`; its stderr on failure.
pub(crate) fn ip(args: &[&str]) -> Result<(), IpError> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(IpError::Spawn)?;
    if out.status.success() {
        Ok(())
    } else {
        Err(IpError::Failed {
            args: args.join(" "),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        })
    }
}

/// Node `i`'s link with the hub: the hub's end and the node's, `10.77.<i+1>.1` and
/// `10.77.<i+1>.2` (at most 249 nodes).
pub(crate) fn addresses(i: usize) -> (Ipv4Addr, Ipv4Addr) {
    let subnet = i as u8 + 1;
    (
        Ipv4Addr::new(10, 77, subnet, 1),
        Ipv4Addr::new(10, 77, subnet, 2),
    )
}

/// Make namespace `hub` (made already) route between the nodes: its loopback up, IPv4
/// forwarding on.
pub(crate) fn route_through(hub: &str) -> Result<(), IpError> {
    ip(&["-n", hub, "link", "set", "lo", "up"])?;
    ip(&[
        "netns",
        "exec",
        hub,
        "sysctl",
        "-qw",
        "net.ipv4.ip_forward=1",
    ])
}

/// Join namespace `ns` (made already) to `hub` as node `i`: a veth pair (`h<i>` in the
/// hub, `eth0` in the node), their [`addresses`], and the node's default route through
/// the hub.
pub(crate) fn join(hub: &str, ns: &str, i: usize) -> Result<(), IpError> {
    let hub_end = format!("h{i}"); // in the hub's namespace only: no clash
    let (hub_ip, node_ip) = addresses(i);
    ip(&["-n", ns, "link", "set", "lo", "up"])?;
    ip(&[
        "-n", hub, "link", "add", &hub_end, "type", "veth", "peer", "name", "eth0", "netns", ns,
    ])?;
    ip(&[
        "-n",
        hub,
        "addr",
        "add",
        &format!("{hub_ip}/24"),
        "dev",
        &hub_end,
    ])?;
    ip(&["-n", hub, "link", "set", &hub_end, "up"])?;
    ip(&[
        "-n",
        ns,
        "addr",
        "add",
        &format!("{node_ip}/24"),
        "dev",
        "eth0",
    ])?;
    ip(&["-n", ns, "link", "set", "eth0", "up"])?;
    ip(&[
        "-n",
        ns,
        "route",
        "add",
        "default",
        "via",
        &hub_ip.to_string(),
    ])
}

/// Add (`verb` `add`) or delete (`del`) the blackhole route to `to` in namespace `from`:
/// packets from there to there vanish silently, as behind a cut cable.
pub(crate) fn blackhole(verb: &str, from: &str, to: Ipv4Addr) -> Result<(), IpError> {
    ip(&["-n", from, "route", verb, "blackhole", &format!("{to}/32")])
}

/// Delete the namespaces named `<prefix><pid>-…` whose process `pid` is gone.
pub(crate) fn sweep_left_behind(prefix: &str) {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Some(name) = line.split_whitespace().next() else {
            continue;
        };
        let Some(pid) = name
            .strip_prefix(prefix)
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !std::path::Path::new(&format!("/proc/{pid}")).exists() {
            let _ = ip(&["netns", "del", name]);
        }
    }
}

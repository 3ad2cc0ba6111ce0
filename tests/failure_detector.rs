//! The failure detector across real processes on 127.0.0.1: a frozen node (`SIGSTOP`) is
//! declared down after its deadline, its modules leave the registry, and it rejoins when it
//! wakes; a node frozen just past its peer's deadline — also one whose own deadline is longer
//! than its peer's — finds out when it wakes and restarts its operations; a node of another
//! protocol version is refused, naming both versions, and the cluster keeps serving.

use crate::common;

use common::cluster::{silence_ms, NodeProc};

const COOKIE: &str = "detector";
const ALPHA: &str = "[[datamanager]]\nname = \"feature\"\n";
const BETA: &str = "[[operation]]\nname = \"sampler\"\n";

/// The nodes of every module `ls --join addr` lists.
fn nodes_listed(addr: &std::net::SocketAddr) -> Vec<String> {
    let (code, listed, stderr) = common::cluster::ls_join(&addr.to_string(), COOKIE, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    let mut nodes: Vec<String> = listed.into_iter().map(|(_, _, node)| node).collect();
    nodes.sort();
    nodes
}

#[test]
fn a_frozen_node_is_declared_down_after_its_deadline_and_rejoins_when_it_wakes() {
    let dir = tempfile::tempdir().unwrap();
    // a short deadline (the configurable minimum is 300 ms); beats every 100 ms
    let detector = "deadline_ms = 600\nheartbeat_ms = 100\n";
    let (mut alpha, mut beta) = alpha_and_beta(dir.path(), detector, detector);
    assert_eq!(nodes_listed(&alpha.addr), ["alpha", "beta"]);

    let mark = alpha.seen().len();
    beta.signal("STOP");
    let down = alpha.wait_line_since(mark, "node alpha declared beta down");
    assert!(silence_ms(&down) >= 600, "{down}");
    alpha.wait_line_since(mark, "node alpha lost beta");
    // beta's modules left with it; alpha still serves
    assert_eq!(nodes_listed(&alpha.addr), ["alpha"]);

    let mark = alpha.seen().len();
    let beta_mark = beta.seen().len();
    // at once: the sooner it wakes after alpha's verdict, the shorter its own timer gap
    beta.signal_now(libc::SIGCONT);
    alpha.wait_line_since(mark, "node alpha sees beta");
    beta.wait_line_since(beta_mark, "node beta sees alpha");
    // beta, which was asleep, declared nobody down: the silence was its own; knowing its
    // peers have replaced it, it restarts its operations as a new incarnation
    beta.wait_line_since(beta_mark, "node beta was frozen for");
    beta.wait_line_since(
        beta_mark,
        "node beta restarted its 1 operation instance(s) as a new incarnation",
    );
    assert_eq!(nodes_listed(&alpha.addr), ["alpha", "beta"]);
    for node in [&mut alpha, &mut beta] {
        node.signal("TERM");
        node.wait_line("stopped");
        assert_eq!(node.wait_exit(), Some(0));
    }
    // every line beta printed is in now, not only those waited for
    assert!(
        !beta
            .seen()
            .iter()
            .any(|l| l.contains("declared alpha down")),
        "{:?}",
        beta.seen()
    );
    // the handshakes that a freeze held up and its end cut short are no refusal, on
    // either side
    for node in [&alpha, &beta] {
        assert!(
            !node.seen().iter().any(|l| l.contains("refused")),
            "{:?}",
            node.seen()
        );
    }
}

/// Start alpha and beta with these `[cluster]` settings, freeze beta (`SIGSTOP`) until alpha
/// has declared it down, and wake it (`SIGCONT`) at once: beta must find out it was frozen
/// past its peer's deadline, say so once, restart its operation once, and declare nobody
/// down (the silence was its own). Gives beta's lines.
fn beta_frozen_just_past_alphas_deadline(alpha_detector: &str, beta_detector: &str) -> Vec<String> {
    let dir = tempfile::tempdir().unwrap();
    let (mut alpha, mut beta) = alpha_and_beta(dir.path(), alpha_detector, beta_detector);
    // (and both beat for a while: a freeze right after the greeting beats comes just
    // after a beat, when a node's own timer gap is longest against its peers' view)
    assert_eq!(nodes_listed(&alpha.addr), ["alpha", "beta"]);

    let mark = alpha.seen().len();
    beta.signal("STOP");
    alpha.wait_line_since(mark, "node alpha declared beta down");
    let beta_mark = beta.seen().len();
    // at once: the sooner it wakes after alpha's verdict, the shorter its own timer gap
    beta.signal_now(libc::SIGCONT);
    alpha.wait_line_since(mark, "node alpha lost beta");
    alpha.wait_line_since(mark, "node alpha sees beta");
    beta.wait_line_since(beta_mark, "node beta was frozen for");
    beta.wait_line_since(
        beta_mark,
        "node beta restarted its 1 operation instance(s) as a new incarnation",
    );
    assert_eq!(nodes_listed(&alpha.addr), ["alpha", "beta"]);
    for node in [&mut alpha, &mut beta] {
        node.signal("TERM");
        node.wait_line("stopped");
        assert_eq!(node.wait_exit(), Some(0));
    }
    // every line beta printed is in now: since it woke, one freeze, one restart, nobody
    // declared down
    let woke = &beta.seen()[beta_mark..];
    let count = |what: &str| woke.iter().filter(|l| l.contains(what)).count();
    assert_eq!(count("was frozen for"), 1, "{woke:?}");
    assert_eq!(count("as a new incarnation"), 1, "{woke:?}");
    assert_eq!(count("declared alpha down"), 0, "{woke:?}");
    woke.to_vec()
}

#[test]
fn a_node_frozen_past_a_shorter_peer_deadline_than_its_own_learns_it_from_the_peer() {
    // alpha declares a silent peer down after 600 ms; beta would take itself for frozen
    // only after 5 s without a tick of its own: its timer gap cannot tell it, alpha does
    let beta = beta_frozen_just_past_alphas_deadline(
        "deadline_ms = 600\nheartbeat_ms = 100\n",
        "deadline_ms = 5000\nheartbeat_ms = 100\n",
    );
    let frozen = beta.iter().find(|l| l.contains("was frozen for")).unwrap();
    // the silence alpha measured: past alpha's deadline, short of beta's own
    let ms = frozen_ms(frozen);
    assert!((600..5000).contains(&ms), "{frozen}");
}

#[test]
fn a_node_frozen_just_past_its_peers_deadline_finds_out_when_it_wakes() {
    // the default deadline on both: alpha counts beta's silence from beta's last beat, up
    // to a beat period before beta's last tick, so beta's own timer gap is often shorter
    // than the deadline alpha found it silent past
    beta_frozen_just_past_alphas_deadline("", "");
}

/// `node beta was frozen for 1234 ms: ...` → 1234.
fn frozen_ms(line: &str) -> u64 {
    line.split_once("frozen for ")
        .and_then(|(_, rest)| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no duration in {line:?}"))
}

#[test]
fn a_node_of_another_protocol_version_is_refused_naming_both_versions() {
    let ours = marie::wire::PROTOCOL_VERSION;
    let theirs = (ours + 1).to_string();
    let dir = tempfile::tempdir().unwrap();
    let mut alpha = NodeProc::start(dir.path(), "alpha", ALPHA, &[], COOKIE);
    let mut future = NodeProc::start_with(
        dir.path(),
        "future",
        BETA,
        &[alpha.addr],
        COOKIE,
        "",
        &["--protocol-version", &theirs],
    );
    let refused = alpha.wait_line("node alpha refused future");
    let mark = alpha.seen().len();
    assert!(
        refused.contains(&format!("protocol version {theirs}"))
            && refused.contains(&format!("protocol version {ours}")),
        "{refused}"
    );
    future.wait_line("node future refused alpha");
    // its session closes (after the grace that lets alpha's own beat tell it why) and the
    // refused node's modules leave; alpha keeps serving, and refuses it at every redial.
    // Whether alpha announced it at all depends on whether its first beat came before the
    // session was ready: if it did, it is lost again
    if alpha.seen()[..mark]
        .iter()
        .any(|l| l.contains("sees future"))
    {
        alpha.wait_line_since(mark, "node alpha lost future");
    }
    let deadline = std::time::Instant::now() + common::cluster::EVENT_TIMEOUT;
    while nodes_listed(&alpha.addr) != ["alpha"] {
        assert!(
            std::time::Instant::now() < deadline,
            "future's modules are still listed"
        );
    }
    alpha.signal("TERM");
    alpha.wait_line("stopped");
    assert_eq!(alpha.wait_exit(), Some(0));
    // future kept redialling (its dialer backs off to 2 s): alpha never saw it again
    let after: Vec<&String> = alpha.seen()[mark..]
        .iter()
        .filter(|l| l.contains("sees future"))
        .collect();
    assert!(after.is_empty(), "{after:?}");
    // the sessions closed at authentication are the version's refusal, not the cookie's
    future.signal("TERM");
    future.wait_line("stopped");
    for node in [&alpha, &future] {
        assert!(
            !node
                .seen()
                .iter()
                .any(|l| l.contains("failed authentication") || l.contains("was refused by")),
            "{:?}",
            node.seen()
        );
    }
}

/// Nodes alpha and beta (which joins alpha) with their `[cluster]` detector settings, once
/// each sees the other.
fn alpha_and_beta(
    dir: &std::path::Path,
    alpha_detector: &str,
    beta_detector: &str,
) -> (NodeProc, NodeProc) {
    let mut alpha = NodeProc::start_with(dir, "alpha", ALPHA, &[], COOKIE, alpha_detector, &[]);
    let mut beta =
        NodeProc::start_with(dir, "beta", BETA, &[alpha.addr], COOKIE, beta_detector, &[]);
    alpha.wait_line("node alpha sees beta");
    beta.wait_line("node beta sees alpha");
    (alpha, beta)
}

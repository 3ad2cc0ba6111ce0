//! Mutual TLS between real `marie node` processes on 127.0.0.1, with certificates the test
//! generates (the `openssl` command, which `.ci/run` installs when missing): nodes with
//! certificates from the cluster's CA form a full mesh — also the pair that never dialed
//! each other —; a peer without a certificate, with one from another CA, or one that opens
//! a connection and says nothing is refused, and the node keeps serving with nothing
//! changed; so is a peer with a certificate of the cluster's CA that names another address
//! or none, whether it dials or is dialed, a node or a `--join` command; `--join` commands
//! join with `--tls-cert/--tls-key/--tls-ca`.

use crate::common;

use common::cluster::NodeProc;
use common::{marie, text};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;

const COOKIE: &str = "tls";
const ALPHA_HOSTS: &str = "[[datamanager]]\nname = \"feature\"\n";
const BETA_HOSTS: &str = "[[operation]]\nname = \"sampler\"\n";
const GAMMA_HOSTS: &str = "[[operation]]\nname = \"averager\"\n";

/// Run `openssl ARGS` in `dir`; panics with its stderr when it fails.
fn openssl(dir: &Path, args: &[&str]) {
    let out = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the openssl command runs (.ci/run installs it)");
    assert!(
        out.status.success(),
        "openssl {args:?}: {}",
        text(&out.stderr)
    );
}

/// A certificate authority in `dir`: `NAME.pem`, `NAME.key`.
fn authority(dir: &Path, name: &str) {
    openssl(
        dir,
        &[
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-days",
            "2",
            "-subj",
            &format!("/CN={name}"),
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-addext",
            "keyUsage=critical,keyCertSign,cRLSign",
            "-keyout",
            &format!("{name}.key"),
            "-out",
            &format!("{name}.pem"),
        ],
    );
}

/// A node certificate for 127.0.0.1 signed by authority `ca`: `NAME.pem`, `NAME.key`.
fn certificate(dir: &Path, name: &str, ca: &str) {
    certificate_for(dir, name, ca, Some("IP:127.0.0.1"));
}

/// A node certificate naming `san` (a `subjectAltName` value; `None`: no such extension)
/// signed by authority `ca`: `NAME.pem`, `NAME.key`.
fn certificate_for(dir: &Path, name: &str, ca: &str, san: Option<&str>) {
    openssl(
        dir,
        &[
            "req",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-subj",
            &format!("/CN={name}"),
            "-keyout",
            &format!("{name}.key"),
            "-out",
            &format!("{name}.csr"),
        ],
    );
    let san = san.map_or(String::new(), |san| format!("subjectAltName={san}\n"));
    std::fs::write(
        dir.join(format!("{name}.ext")),
        format!(
            "basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature\n\
             extendedKeyUsage=serverAuth,clientAuth\n{san}"
        ),
    )
    .unwrap();
    openssl(
        dir,
        &[
            "x509",
            "-req",
            "-in",
            &format!("{name}.csr"),
            "-CA",
            &format!("{ca}.pem"),
            "-CAkey",
            &format!("{ca}.key"),
            "-CAcreateserial",
            "-days",
            "2",
            "-extfile",
            &format!("{name}.ext"),
            "-out",
            &format!("{name}.pem"),
        ],
    );
}

/// The cluster CA with certificates for alpha, beta, gamma and a joining command, and two
/// of the same CA that do not name 127.0.0.1 — `stray` names 10.9.9.9, `nameless` no
/// address at all —; a rogue CA with a certificate for a node that is not of this cluster.
fn pki(dir: &Path) {
    authority(dir, "ca");
    for name in ["alpha", "beta", "gamma", "cli"] {
        certificate(dir, name, "ca");
    }
    certificate_for(dir, "stray", "ca", Some("IP:10.9.9.9"));
    certificate_for(dir, "nameless", "ca", None);
    authority(dir, "rogue-ca");
    certificate(dir, "rogue", "rogue-ca");
}

/// The `[cluster.tls]` table of a node with certificate `name` trusting authority `ca`.
fn tls_table(dir: &Path, name: &str, ca: &str) -> String {
    let f = |n: &str| dir.join(n).display().to_string();
    format!(
        "[cluster.tls]\ncert = \"{}\"\nkey = \"{}\"\nca = \"{}\"\n",
        f(&format!("{name}.pem")),
        f(&format!("{name}.key")),
        f(&format!("{ca}.pem"))
    )
}

fn start(dir: &Path, name: &str, hosts: &str, peers: &[SocketAddr], tls: &str) -> NodeProc {
    NodeProc::start_with(dir, name, hosts, peers, COOKIE, tls, &[])
}

/// `marie ls --join ADDR --cookie C --json` with `tls` flags: exit code, (name, node) of
/// every entry sorted, stderr.
fn ls_join(addr: SocketAddr, tls: &[String]) -> (Option<i32>, Vec<(String, String)>, String) {
    let (code, listed, stderr) = common::cluster::ls_join(&addr.to_string(), COOKIE, tls);
    let mut pairs: Vec<(String, String)> = listed
        .into_iter()
        .map(|(_, name, node)| (name, node))
        .collect();
    pairs.sort();
    (code, pairs, stderr)
}

/// The `--tls-*` flags of a command with certificate `name` trusting authority `ca`.
fn tls_flags(dir: &Path, name: &str, ca: &str) -> Vec<String> {
    let f = |n: String| dir.join(n).display().to_string();
    vec![
        "--tls-cert".into(),
        f(format!("{name}.pem")),
        "--tls-key".into(),
        f(format!("{name}.key")),
        "--tls-ca".into(),
        f(format!("{ca}.pem")),
    ]
}

fn pair(name: &str, node: &str) -> (String, String) {
    (name.into(), node.into())
}

#[test]
fn nodes_with_certificates_of_the_cluster_ca_form_a_full_mesh_over_tls() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pki(d);
    let mut alpha = start(d, "alpha", ALPHA_HOSTS, &[], &tls_table(d, "alpha", "ca"));
    assert!(alpha.wait_line("listening on").contains("(mutual TLS)"));
    let mut beta = start(
        d,
        "beta",
        BETA_HOSTS,
        &[alpha.addr],
        &tls_table(d, "beta", "ca"),
    );
    beta.wait_line("node beta sees alpha");
    // gamma dials only beta; it learns alpha's address from beta's heartbeats and dials it
    // over TLS (ractor_cluster's own transitive dials would be plain TCP)
    let mut gamma = start(
        d,
        "gamma",
        GAMMA_HOSTS,
        &[beta.addr],
        &tls_table(d, "gamma", "ca"),
    );
    gamma.wait_line("node gamma sees beta");
    gamma.wait_line("node gamma sees alpha");
    alpha.wait_line("node alpha sees gamma");

    let (code, entries, stderr) = ls_join(alpha.addr, &tls_flags(d, "cli", "ca"));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        entries,
        vec![
            pair("averager", "gamma"),
            pair("feature", "alpha"),
            pair("sampler", "beta")
        ]
    );
    for node in [&mut alpha, &mut beta, &mut gamma] {
        // every line printed so far, not only those waited for
        let lines = node.drain();
        assert!(!lines.iter().any(|l| l.contains("refused")), "{lines:?}");
    }
}

#[test]
fn a_peer_without_a_valid_certificate_is_refused_and_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pki(d);
    let mut alpha = start(d, "alpha", ALPHA_HOSTS, &[], &tls_table(d, "alpha", "ca"));

    // a connection that never speaks holds a handshake slot, not the listener
    let silent = std::net::TcpStream::connect(alpha.addr).unwrap();

    // a node without TLS, and one with a certificate of another authority
    let mut plain = start(d, "plain", BETA_HOSTS, &[alpha.addr], "");
    let refused = alpha.wait_line("node alpha refused a connection from");
    assert!(refused.contains("TLS"), "{refused}");
    let mark = alpha.seen().len();
    let mut rogue = start(
        d,
        "rogue",
        GAMMA_HOSTS,
        &[alpha.addr],
        &tls_table(d, "rogue", "rogue-ca"),
    );
    alpha.wait_line_since(mark, "node alpha refused a connection from");

    // commands: without certificates, and with a rogue one
    for flags in [Vec::new(), tls_flags(d, "rogue", "rogue-ca")] {
        let (code, entries, stderr) = ls_join(alpha.addr, &flags);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(stderr.contains("could not join the cluster"), "{stderr}");
        assert!(entries.is_empty());
    }

    // a node with a good certificate still joins, past the silent connection, and sees
    // only alpha's modules: none of the refused peers' reached the registry
    let mut beta = start(
        d,
        "beta",
        GAMMA_HOSTS,
        &[alpha.addr],
        &tls_table(d, "beta", "ca"),
    );
    beta.wait_line("node beta sees alpha");
    let (code, entries, stderr) = ls_join(alpha.addr, &tls_flags(d, "cli", "ca"));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        entries,
        vec![pair("averager", "beta"), pair("feature", "alpha")]
    );
    // the silent connection is closed after the handshake timeout, and told
    alpha.wait_line("no TLS handshake within");
    drop(silent);
    // the refused nodes stopped, every line they printed is in: none saw alpha, nor alpha
    // them
    for node in [&mut rogue, &mut plain] {
        node.signal("TERM");
        node.wait_line("stopped");
        assert_eq!(node.wait_exit(), Some(0));
    }
    let lines = alpha.drain().to_vec();
    for (node, refused) in [(&lines, "plain"), (&lines, "rogue")] {
        assert!(
            !node
                .iter()
                .any(|l| l.contains(&format!("node alpha sees {refused}"))),
            "{node:?}"
        );
    }
    for node in [&rogue, &plain] {
        assert!(
            !node.seen().iter().any(|l| l.contains(" sees ")),
            "{:?}",
            node.seen()
        );
    }
}

#[test]
fn a_certificate_of_the_ca_naming_another_address_or_none_is_refused_both_ways() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pki(d);
    let mut alpha = start(d, "alpha", ALPHA_HOSTS, &[], &tls_table(d, "alpha", "ca"));
    let alpha_addr = alpha.addr.to_string();

    // a command with such a certificate is refused by the node it dials, which says so
    // (on stdout and stderr), and the command says what to check
    for (name, names) in [("stray", "10.9.9.9"), ("nameless", "any names")] {
        let mark = alpha.drain().len();
        let (code, entries, stderr) = ls_join(alpha.addr, &tls_flags(d, name, "ca"));
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("could not join the cluster at {alpha_addr}"))
                && stderr.contains("a certificate from its CA naming 127.0.0.1"),
            "{stderr}"
        );
        assert!(entries.is_empty());
        let refused = alpha.wait_line_since(mark, "node alpha refused a connection from");
        assert!(
            refused.contains(
                "TLS: invalid peer certificate: certificate not valid for name \"127.0.0.1\""
            ) && refused.contains(names),
            "{refused}"
        );
        let logged = alpha.wait_stderr(names);
        assert!(
            logged.contains("node alpha refused a connection from 127.0.0.1:"),
            "{logged}"
        );
    }

    // nodes with such certificates dial: alpha checks the name in their client
    // certificate against the address they come from, 127.0.0.1, and refuses them
    let mut strays = Vec::new();
    for (name, names) in [("stray", "10.9.9.9"), ("nameless", "any names")] {
        let mark = alpha.drain().len();
        let node = start(
            d,
            name,
            BETA_HOSTS,
            &[alpha.addr],
            &tls_table(d, name, "ca"),
        );
        // (the other stray keeps redialling: its refusals are told too)
        let refused = alpha.wait_line_since(mark, names);
        assert!(
            refused.contains("node alpha refused a connection from 127.0.0.1:")
                && refused.contains("not valid for name \"127.0.0.1\""),
            "{refused}"
        );
        strays.push(node);
    }

    // they are dialed: beta, of the cluster, refuses the certificates they answer with
    let mut beta = start(
        d,
        "beta",
        GAMMA_HOSTS,
        &[alpha.addr, strays[0].addr, strays[1].addr],
        &tls_table(d, "beta", "ca"),
    );
    for stray in &strays {
        let line = beta.wait_line(&format!(
            "node beta refused the node it dialed at {}",
            stray.addr
        ));
        assert!(
            line.contains(
                "TLS: invalid peer certificate: certificate not valid for name \"127.0.0.1\""
            ),
            "{line}"
        );
        beta.wait_stderr(&format!(
            "node beta refused the node it dialed at {}: TLS:",
            stray.addr
        ));
    }
    beta.wait_line("node beta sees alpha");

    // and a command with a good certificate refuses a node whose certificate does not
    // name its address, at once, saying why
    for stray in &strays {
        let (code, entries, stderr) = ls_join(stray.addr, &tls_flags(d, "cli", "ca"));
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!(
                "could not join the cluster at {}: this member refused the node's \
                 certificate: TLS: invalid peer certificate: certificate not valid for name \
                 \"127.0.0.1\"",
                stray.addr
            )),
            "{stderr}"
        );
        assert!(entries.is_empty());
    }

    // nothing changed: the cluster is alpha and beta, and neither saw a stray node
    let (code, entries, stderr) = ls_join(alpha.addr, &tls_flags(d, "cli", "ca"));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        entries,
        vec![pair("averager", "beta"), pair("feature", "alpha")]
    );
    for stray in &mut strays {
        stray.signal("TERM");
        stray.wait_line("stopped");
        assert_eq!(stray.wait_exit(), Some(0));
        assert!(
            !stray.seen().iter().any(|l| l.contains(" sees ")),
            "{:?}",
            stray.seen()
        );
    }
    for node in [&mut alpha, &mut beta] {
        let lines = node.drain();
        assert!(
            !lines
                .iter()
                .any(|l| l.contains("sees stray") || l.contains("sees nameless")),
            "{lines:?}"
        );
    }
    // a refusal repeated at every redial is told once
    let told = beta
        .seen()
        .iter()
        .filter(|l| l.contains(&format!("refused the node it dialed at {}", strays[0].addr)))
        .count();
    assert_eq!(told, 1, "{:?}", beta.seen());
}

/// The TCP ports process `pid` listens on (from `/proc`: its sockets' inodes, looked up
/// among the listening sockets of its network namespace).
fn listening_ports(pid: u32) -> Vec<u16> {
    let sockets: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter_map(|fd| std::fs::read_link(fd.ok()?.path()).ok())
        .filter_map(|target| {
            let target = target.to_str()?;
            Some(
                target
                    .strip_prefix("socket:[")?
                    .strip_suffix(']')?
                    .to_string(),
            )
        })
        .collect();
    let table = std::fs::read_to_string(format!("/proc/{pid}/net/tcp")).unwrap();
    let mut ports: Vec<u16> = table
        .lines()
        .skip(1)
        .filter_map(|row| {
            let cols: Vec<&str> = row.split_whitespace().collect();
            // local address, state (0A: listening), inode
            let (local, state, inode) = (cols.get(1)?, cols.get(3)?, cols.get(9)?);
            (*state == "0A" && sockets.iter().any(|s| s == inode))
                .then(|| u16::from_str_radix(local.rsplit_once(':')?.1, 16).ok())?
        })
        .collect();
    ports.sort();
    ports
}

#[test]
fn the_listener_ractor_cluster_keeps_admits_nobody() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pki(d);
    let alpha = start(d, "alpha", ALPHA_HOSTS, &[], &tls_table(d, "alpha", "ca"));
    // ractor_cluster's own listener still runs, on a port nobody is told, but anyone can
    // find: it must not let in a certificate marie's listener refuses (nor any other)
    let ports = listening_ports(alpha.pid());
    assert!(ports.contains(&alpha.addr.port()), "{ports:?}");
    let hidden: Vec<u16> = ports
        .into_iter()
        .filter(|p| *p != alpha.addr.port())
        .collect();
    assert_eq!(hidden.len(), 1, "{hidden:?}");
    let hidden = SocketAddr::from(([127, 0, 0, 1], hidden[0]));
    for name in ["stray", "cli"] {
        let (code, entries, stderr) = ls_join(hidden, &tls_flags(d, name, "ca"));
        assert_eq!(code, Some(1), "{name}: {entries:?} {stderr}");
        assert!(stderr.contains("could not join the cluster"), "{stderr}");
    }
}

#[test]
fn unreadable_or_wrong_tls_files_are_refused_at_start_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pki(d);
    let write = |name: &str, tls: &str| -> PathBuf {
        let path = d.join(format!("{name}.toml"));
        std::fs::write(
            &path,
            format!(
                "[node]\nname = \"{name}\"\n[cluster]\nlisten = \"127.0.0.1:0\"\ncookie = \"c\"\n{tls}"
            ),
        )
        .unwrap();
        path
    };
    // a file that does not exist: at its line, before anything starts
    let missing = write(
        "missing",
        &tls_table(d, "alpha", "ca").replace("alpha.pem", "nowhere.pem"),
    );
    let out = marie(&["node", "--config", missing.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("missing.toml:") && stderr.contains("nowhere.pem"),
        "{stderr}"
    );
    // a key given as the certificate: when the node starts, naming the file
    let swapped = write(
        "swapped",
        &tls_table(d, "alpha", "ca").replace("alpha.pem", "alpha.key"),
    );
    let out = marie(&["node", "--config", swapped.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("TLS") && stderr.contains("alpha.key"),
        "{stderr}"
    );
}

//! Mutual TLS between real `marie node` processes on 127.0.0.1, with certificates the test
//! generates (the `openssl` command, which `.ci/run` installs when missing): nodes with
//! certificates from the cluster's CA form a full mesh — also the pair that never dialed
//! each other —; a peer without a certificate, with one from another CA, or one that opens
//! a connection and says nothing is refused, and the node keeps serving with nothing
//! changed; `--join` commands join with `--tls-cert/--tls-key/--tls-ca`.

mod common;

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
    std::fs::write(
        dir.join(format!("{name}.ext")),
        "basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature\n\
         extendedKeyUsage=serverAuth,clientAuth\nsubjectAltName=IP:127.0.0.1\n",
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

/// The cluster CA with certificates for alpha, beta, gamma and a joining command, and a
/// rogue CA with a certificate for a node that is not of this cluster.
fn pki(dir: &Path) {
    authority(dir, "ca");
    for name in ["alpha", "beta", "gamma", "cli"] {
        certificate(dir, name, "ca");
    }
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

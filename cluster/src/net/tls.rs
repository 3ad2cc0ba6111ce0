//! Mutual TLS between nodes: each node proves itself with a certificate signed by the
//! cluster's certificate authority, and accepts only peers that do the same.
//!
//! A node with `[cluster.tls]` encrypts every session, in both directions, with rustls:
//! its server side demands a client certificate chaining to the CA, its client side checks
//! the peer's certificate against the CA and the peer's IP address (or the configured
//! `server_name`). The cookie is still checked inside the encrypted session.
//!
//! The handshake of an incoming connection runs in marie's listener
//! ([`super::listener`]), on a task of its own and with a time limit.
//!
//! ```no_run
//! use marie_cluster::net::{ClusterConfig, TlsFiles};
//! let config = ClusterConfig::new("127.0.0.1:7100".parse().unwrap(), "secret").with_tls(TlsFiles {
//!     cert: "certs/alpha.pem".into(),
//!     key: "certs/alpha.key".into(),
//!     ca: "certs/ca.pem".into(),
//!     server_name: None,
//! });
//! ```

use super::TransportError;
use ractor::ActorRef;
use ractor_cluster::NodeServerMessage;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName};
use tokio_rustls::rustls::{self, server::WebPkiClientVerifier, RootCertStore};
use tokio_rustls::{TlsAcceptor, TlsConnector};

/// Where a node's TLS material is: PEM files (`[cluster.tls]` in a node config).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TlsFiles {
    /// This node's certificate chain, leaf first.
    pub cert: PathBuf,
    /// This node's private key (PKCS#8, PKCS#1 or SEC1).
    pub key: PathBuf,
    /// The certificate(s) of the authority every node's certificate must chain to.
    pub ca: PathBuf,
    /// The name every peer's certificate must carry; `None`: the peer's IP address.
    pub server_name: Option<String>,
}

/// Loaded TLS settings: both sides of a node's sessions.
#[derive(Clone)]
pub(crate) struct Tls {
    acceptor: TlsAcceptor,
    connector: TlsConnector,
    server_name: Option<ServerName<'static>>,
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tls")
            .field("server_name", &self.server_name)
            .finish_non_exhaustive()
    }
}

fn tls_err(what: impl std::fmt::Display) -> TransportError {
    TransportError::Tls(what.to_string())
}

fn read_certs(path: &Path, what: &str) -> Result<Vec<CertificateDer<'static>>, TransportError> {
    let certs = CertificateDer::pem_file_iter(path)
        .and_then(|it| it.collect::<Result<Vec<_>, _>>())
        .map_err(|e| tls_err(format!("{what} {}: {e}", path.display())))?;
    if certs.is_empty() {
        return Err(tls_err(format!(
            "{what} {} holds no PEM certificate",
            path.display()
        )));
    }
    Ok(certs)
}

impl Tls {
    /// Read and check the files: every problem names the file.
    pub(crate) fn load(files: &TlsFiles) -> Result<Tls, TransportError> {
        let certs = read_certs(&files.cert, "certificate")?;
        let key = PrivateKeyDer::from_pem_file(&files.key)
            .map_err(|e| tls_err(format!("private key {}: {e}", files.key.display())))?;
        let mut roots = RootCertStore::empty();
        for ca in read_certs(&files.ca, "CA certificate")? {
            roots
                .add(ca)
                .map_err(|e| tls_err(format!("CA certificate {}: {e}", files.ca.display())))?;
        }
        let roots = Arc::new(roots);
        let provider = Arc::new(rustls::crypto::aws_lc_rs::default_provider());
        let verifier = WebPkiClientVerifier::builder_with_provider(roots.clone(), provider.clone())
            .build()
            .map_err(|e| tls_err(format!("CA {}: {e}", files.ca.display())))?;
        let server = rustls::ServerConfig::builder_with_provider(provider.clone())
            .with_safe_default_protocol_versions()
            .map_err(tls_err)?
            .with_client_cert_verifier(verifier)
            .with_single_cert(certs.clone(), key.clone_key())
            .map_err(|e| {
                tls_err(format!(
                    "certificate {} with key {}: {e}",
                    files.cert.display(),
                    files.key.display()
                ))
            })?;
        let client = rustls::ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(tls_err)?
            .with_root_certificates(roots)
            .with_client_auth_cert(certs, key)
            .map_err(|e| {
                tls_err(format!(
                    "certificate {} with key {}: {e}",
                    files.cert.display(),
                    files.key.display()
                ))
            })?;
        let server_name = match &files.server_name {
            None => None,
            Some(name) => Some(
                ServerName::try_from(name.clone())
                    .map_err(|e| tls_err(format!("server_name {name:?}: {e}")))?,
            ),
        };
        Ok(Tls {
            acceptor: TlsAcceptor::from(Arc::new(server)),
            connector: TlsConnector::from(Arc::new(client)),
            server_name,
        })
    }

    /// The server side of the handshake.
    pub(crate) fn acceptor(&self) -> TlsAcceptor {
        self.acceptor.clone()
    }

    /// Dial `addr` over TLS and hand the session to `server`.
    pub(crate) async fn dial(
        &self,
        server: &ActorRef<NodeServerMessage>,
        addr: SocketAddr,
    ) -> Result<(), String> {
        let name = self
            .server_name
            .clone()
            .unwrap_or_else(|| ServerName::IpAddress(addr.ip().into()));
        ractor_cluster::client_connect_enc(server, addr, self.connector.clone(), name)
            .await
            .map_err(|e| e.to_string())
    }
}

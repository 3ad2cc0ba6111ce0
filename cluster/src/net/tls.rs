//! Mutual TLS between nodes: each node proves itself with a certificate signed by the
//! cluster's certificate authority, and accepts only peers that do the same.
//!
//! A node with `[cluster.tls]` encrypts every session, in both directions, with rustls, and
//! holds every peer to one rule, whichever side dialed: its certificate chains to the CA
//! and names the peer's IP address (`subjectAltName = IP:…`: the address dialed, or the
//! one an incoming connection comes from) or the configured `server_name`. Its client side
//! has rustls check the node it dials against that name; its server side demands a client
//! certificate chaining to the CA and then checks the name itself (`Tls::check_client`) —
//! rustls' client verifier checks no name, and a certificate of the cluster's CA made out
//! to another address must not let its holder in from this one. The cookie is still
//! checked inside the encrypted session.
//!
//! The handshake of an incoming connection runs in marie's listener
//! ([`super::listener`]), on a task of its own and with a time limit; ractor_cluster's own
//! listener, which would skip that check, completes no handshake.
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

use ractor::ActorRef;
use ractor_cluster::{ClientConnectErr, NodeServerMessage};
use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio_rustls::rustls::pki_types::pem::{self, PemObject};
use tokio_rustls::rustls::pki_types::{
    CertificateDer, InvalidDnsNameError, PrivateKeyDer, ServerName,
};
use tokio_rustls::rustls::server::{ParsedCertificate, WebPkiClientVerifier};
use tokio_rustls::rustls::{self, RootCertStore};
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
    /// What ractor_cluster's own listener gets (see [`Tls::refusing_acceptor`]).
    refusing: TlsAcceptor,
    connector: TlsConnector,
    server_name: Option<ServerName<'static>>,
}

/// The certificates of a server that has none to offer: every handshake fails.
#[derive(Debug)]
struct NoCertificate;

impl rustls::server::ResolvesServerCert for NoCertificate {
    fn resolve(
        &self,
        _: rustls::server::ClientHello<'_>,
    ) -> Option<Arc<rustls::sign::CertifiedKey>> {
        None
    }
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tls")
            .field("server_name", &self.server_name)
            .finish_non_exhaustive()
    }
}

/// Which of a node's TLS files a [`TlsError`] is about; displayed as its messages name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TlsFile {
    /// The node's certificate chain ([`TlsFiles::cert`]).
    Certificate,
    /// The node's private key ([`TlsFiles::key`]).
    PrivateKey,
    /// The authority's certificate(s) ([`TlsFiles::ca`]).
    CaCertificate,
}

impl std::fmt::Display for TlsFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TlsFile::Certificate => "certificate",
            TlsFile::PrivateKey => "private key",
            TlsFile::CaCertificate => "CA certificate",
        })
    }
}

/// Why a node's TLS files cannot be used (`TransportError::Tls`): every variant names the
/// file (or setting) at fault and keeps the underlying error as its source, so a caller can
/// tell a missing file from a key that does not match its certificate.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A PEM file cannot be read or parsed.
    #[error("{file} {}: {source}", .path.display())]
    Read {
        /// Which file.
        file: TlsFile,
        /// Its path.
        path: PathBuf,
        /// What reading it said.
        source: pem::Error,
    },
    /// A certificate file holds no PEM certificate.
    #[error("{file} {} holds no PEM certificate", .path.display())]
    NoCertificate {
        /// Which file.
        file: TlsFile,
        /// Its path.
        path: PathBuf,
    },
    /// A CA certificate cannot be a trust anchor.
    #[error("CA certificate {}: {source}", .path.display())]
    Authority {
        /// The CA file.
        path: PathBuf,
        /// What rustls said.
        source: rustls::Error,
    },
    /// No client verifier can be built from the CA certificates.
    #[error("CA {}: {source}", .path.display())]
    Verifier {
        /// The CA file.
        path: PathBuf,
        /// What rustls said.
        source: rustls::server::VerifierBuilderError,
    },
    /// The crypto provider offers no safe protocol version.
    #[error("{0}")]
    Protocols(rustls::Error),
    /// The certificate and the key do not go together (or either is unusable).
    #[error("certificate {} with key {}: {source}", .cert.display(), .key.display())]
    CertifiedKey {
        /// The certificate file.
        cert: PathBuf,
        /// The key file.
        key: PathBuf,
        /// What rustls said.
        source: rustls::Error,
    },
    /// `server_name` is not a DNS name or IP address.
    #[error("server_name {name:?}: {source}")]
    ServerName {
        /// The name given.
        name: String,
        /// What parsing it said.
        source: InvalidDnsNameError,
    },
}

fn read_certs(path: &Path, file: TlsFile) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let certs = CertificateDer::pem_file_iter(path)
        .and_then(|it| it.collect::<Result<Vec<_>, _>>())
        .map_err(|source| TlsError::Read {
            file,
            path: path.to_path_buf(),
            source,
        })?;
    if certs.is_empty() {
        return Err(TlsError::NoCertificate {
            file,
            path: path.to_path_buf(),
        });
    }
    Ok(certs)
}

impl Tls {
    /// Read and check the files: every problem names the file.
    pub(crate) fn load(files: &TlsFiles) -> Result<Tls, TlsError> {
        let certs = read_certs(&files.cert, TlsFile::Certificate)?;
        let key = PrivateKeyDer::from_pem_file(&files.key).map_err(|source| TlsError::Read {
            file: TlsFile::PrivateKey,
            path: files.key.clone(),
            source,
        })?;
        let mut roots = RootCertStore::empty();
        for ca in read_certs(&files.ca, TlsFile::CaCertificate)? {
            roots.add(ca).map_err(|source| TlsError::Authority {
                path: files.ca.clone(),
                source,
            })?;
        }
        let roots = Arc::new(roots);
        let provider = Arc::new(rustls::crypto::aws_lc_rs::default_provider());
        let verifier = WebPkiClientVerifier::builder_with_provider(roots.clone(), provider.clone())
            .build()
            .map_err(|source| TlsError::Verifier {
                path: files.ca.clone(),
                source,
            })?;
        let certified_key = |source| TlsError::CertifiedKey {
            cert: files.cert.clone(),
            key: files.key.clone(),
            source,
        };
        let server = rustls::ServerConfig::builder_with_provider(provider.clone())
            .with_safe_default_protocol_versions()
            .map_err(TlsError::Protocols)?
            .with_client_cert_verifier(verifier)
            .with_single_cert(certs.clone(), key.clone_key())
            .map_err(certified_key)?;
        let refusing = rustls::ServerConfig::builder_with_provider(provider.clone())
            .with_safe_default_protocol_versions()
            .map_err(TlsError::Protocols)?
            .with_no_client_auth()
            .with_cert_resolver(Arc::new(NoCertificate));
        let client = rustls::ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(TlsError::Protocols)?
            .with_root_certificates(roots)
            .with_client_auth_cert(certs, key)
            .map_err(certified_key)?;
        let server_name =
            match &files.server_name {
                None => None,
                Some(name) => Some(ServerName::try_from(name.clone()).map_err(|source| {
                    TlsError::ServerName {
                        name: name.clone(),
                        source,
                    }
                })?),
            };
        Ok(Tls {
            acceptor: TlsAcceptor::from(Arc::new(server)),
            refusing: TlsAcceptor::from(Arc::new(refusing)),
            connector: TlsConnector::from(Arc::new(client)),
            server_name,
        })
    }

    /// The server side of the handshake.
    pub(crate) fn acceptor(&self) -> TlsAcceptor {
        self.acceptor.clone()
    }

    /// A server side that completes no handshake, for ractor_cluster's own listener: it
    /// runs on a port nobody is told, but anyone may find it, and a stream it accepts goes
    /// to a session without [`Tls::check_client`]. (Without TLS it would take plain
    /// connections, which must pass the cookie either way.)
    pub(crate) fn refusing_acceptor(&self) -> TlsAcceptor {
        self.refusing.clone()
    }

    /// The name a peer at `ip` must carry in its certificate: the configured `server_name`,
    /// else its address (an IPv4 peer seen through an IPv6 socket as the IPv4 address).
    fn name_for(&self, ip: IpAddr) -> ServerName<'static> {
        self.server_name
            .clone()
            .unwrap_or_else(|| ServerName::IpAddress(ip.to_canonical().into()))
    }

    /// Whether the certificate a client presented in an accepted handshake (`certs`, leaf
    /// first; it already chains to the CA) names the address it connected from, `peer`, or
    /// `server_name`: the check a dialing side gets from rustls, which the accepting side
    /// must make itself. The error reads as rustls' own (`invalid peer certificate: …`).
    pub(crate) fn check_client(
        &self,
        certs: Option<&[CertificateDer<'_>]>,
        peer: IpAddr,
    ) -> Result<(), rustls::Error> {
        let leaf = certs
            .and_then(|c| c.first())
            .ok_or(rustls::Error::NoCertificatesPresented)?;
        let parsed = ParsedCertificate::try_from(leaf)?;
        rustls::client::verify_server_name(&parsed, &self.name_for(peer))
    }

    /// Dial `addr` over TLS and hand the session to `server`.
    pub(crate) async fn dial(
        &self,
        server: &ActorRef<NodeServerMessage>,
        addr: SocketAddr,
    ) -> Result<(), ClientConnectErr> {
        let name = self.name_for(addr.ip());
        ractor_cluster::client_connect_enc(server, addr, self.connector.clone(), name).await
    }
}

/// Whether a failed dial is this node refusing the certificate of the node it dialed (it
/// does not chain to the CA, or names another address): the reason, `TLS: …`, if so. Any
/// other failure (no one listening, a peer that refused this node's certificate, a peer
/// without TLS) is not.
pub(crate) fn refused_certificate(err: &ClientConnectErr) -> Option<String> {
    let ClientConnectErr::Encryption(io) = err else {
        return None;
    };
    match io.get_ref()?.downcast_ref::<rustls::Error>()? {
        e @ (rustls::Error::InvalidCertificate(_) | rustls::Error::NoCertificatesPresented) => {
            Some(format!("TLS: {e}"))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unusable_tls_files_are_matched_by_kind_and_named() {
        let dir = tempfile::tempdir().unwrap();
        let files = |cert: &Path| TlsFiles {
            cert: cert.to_path_buf(),
            key: dir.path().join("node.key"),
            ca: dir.path().join("ca.pem"),
            server_name: None,
        };
        let missing = dir.path().join("nowhere.pem");
        let err = Tls::load(&files(&missing)).unwrap_err();
        assert!(
            matches!(&err, TlsError::Read { file: TlsFile::Certificate, path, .. } if *path == missing),
            "{err:?}"
        );
        assert!(
            err.to_string()
                .starts_with(&format!("certificate {}: ", missing.display())),
            "{err}"
        );

        let empty = dir.path().join("empty.pem");
        std::fs::write(&empty, "no PEM here\n").unwrap();
        let err = Tls::load(&files(&empty)).unwrap_err();
        assert!(
            matches!(&err, TlsError::NoCertificate { file: TlsFile::Certificate, path } if *path == empty),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            format!("certificate {} holds no PEM certificate", empty.display())
        );
        assert_eq!(TlsFile::CaCertificate.to_string(), "CA certificate");
        assert_eq!(TlsFile::PrivateKey.to_string(), "private key");
    }
}

//! What can keep a monitor from starting.

use std::net::SocketAddr;
use std::path::PathBuf;

/// Why a monitor did not start.
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    /// The listen address could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// The events file could not be read.
    #[error("cannot read the events file {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line of the events file is not an event.
    #[error("{}:{line}: not an event: {source}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// The line (from 1).
        line: usize,
        /// What is wrong with it.
        source: serde_json::Error,
    },
    /// The monitor's thread or runtime could not start.
    #[error("cannot start the monitor's runtime: {0}")]
    Runtime(std::io::Error),
}

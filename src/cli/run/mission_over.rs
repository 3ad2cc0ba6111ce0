//! When a run is over for whoever runs it: the flag `marie up --run` reads to tell a
//! Ctrl-C that closes the run's page from one that cuts the mission short.

use crate::cli::signal::Shutdown;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Set once a run's mission has ended, its outputs written — and, with a monitor, once the
/// run listens for the Ctrl-C that closes its page. Whoever runs it (`marie up --run`) and
/// hears a Ctrl-C then lets the run end by itself instead of cutting the mission short.
///
/// That runner hands the run its own Ctrl-C watch ([`MissionOver::heard_by`]), watching
/// since before the run: the page closes on the same watch, so one Ctrl-C ends both,
/// whenever it comes. With a watch each, a Ctrl-C between the run's last line and the
/// moment it watched for itself was the runner's alone, and the run waited for another.
#[derive(Clone, Debug, Default)]
pub(crate) struct MissionOver(Arc<Over>);

#[derive(Debug, Default)]
struct Over {
    set: AtomicBool,
    /// The runner's Ctrl-C watch; `None`: the run watches for itself from the moment its
    /// page's last line is due.
    heard_by: Option<Shutdown>,
}

impl MissionOver {
    /// For a run whose runner watches Ctrl-C with `shutdown`.
    pub(crate) fn heard_by(shutdown: Shutdown) -> MissionOver {
        MissionOver(Arc::new(Over {
            set: AtomicBool::new(false),
            heard_by: Some(shutdown),
        }))
    }

    pub(super) fn set(&self) {
        self.0.set.store(true, Ordering::SeqCst);
    }

    /// Whether the mission has ended (and the run hears a Ctrl-C itself).
    pub(crate) fn is_set(&self) -> bool {
        self.0.set.load(Ordering::SeqCst)
    }

    /// The Ctrl-C watch the page closes on: the runner's, else one from now on.
    pub(super) fn ctrl_c(&self) -> Shutdown {
        self.0
            .heard_by
            .clone()
            .unwrap_or_else(|| Shutdown::watch(false))
    }
}

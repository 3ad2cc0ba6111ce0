//! The failure detector's verdicts, where every reader in the process sees them at once:
//! the nodes declared down and not back since.
//!
//! The transport records a verdict *before* it closes the node's sessions, so whoever then
//! sees an instance of that node vanish — a closed reply port, a failed probe, a registry
//! leave — can tell that its node was declared down, with no race against the event that
//! announces it.
//!
//! ```
//! use marie_vocabulary::registry::{declare_down, declare_up, is_declared_down};
//! declare_down("wf-a");
//! assert!(is_declared_down("wf-a"));
//! declare_up("wf-a");
//! assert!(!is_declared_down("wf-a"));
//! ```

use std::collections::BTreeSet;
use std::sync::{OnceLock, RwLock};

fn down() -> &'static RwLock<BTreeSet<String>> {
    static DOWN: OnceLock<RwLock<BTreeSet<String>>> = OnceLock::new();
    DOWN.get_or_init(RwLock::default)
}

/// Record that the failure detector declared `node` down.
pub fn declare_down(node: &str) {
    down()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .insert(node.to_string());
}

/// Record that `node` is reachable again (a session with it is ready).
pub fn declare_up(node: &str) {
    down()
        .write()
        .unwrap_or_else(|e| e.into_inner())
        .remove(node);
}

/// Whether `node` was declared down and has not come back since.
pub fn is_declared_down(node: &str) -> bool {
    down()
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .contains(node)
}

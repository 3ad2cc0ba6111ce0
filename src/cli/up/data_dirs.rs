//! Where `marie up`'s nodes keep their datamanagers' journals: DIR/NODE under `--data-dir`
//! (kept), or under a fresh directory of the system's temporary one, removed when `up`
//! exits — and those a killed `up` left, removed by the next.

use crate::cli::error::BadInput;
use marie::cluster::node::NodeConfig;
use std::path::{Path, PathBuf};

/// Where `up`'s nodes keep their data: DIR/NODE for each node whose config names no
/// `data_dir`.
#[derive(Debug)]
pub(super) struct DataDirs {
    base: PathBuf,
    /// Made for this invocation (no `--data-dir`): removed on drop, once the nodes stopped.
    temporary: bool,
}

impl DataDirs {
    /// `--data-dir`, created if missing; else a new directory
    /// `marie-up-CLUSTER-PID[.N]` under [`std::env::temp_dir`] — new, never one left by an
    /// earlier process of the same pid, whose journals the nodes would read back.
    pub(super) fn new(kept: Option<&Path>, cluster: &Path) -> anyhow::Result<DataDirs> {
        if let Some(dir) = kept {
            std::fs::create_dir_all(dir)
                .map_err(|e| BadInput(format!("--data-dir {}: {e}", dir.display())))?;
            return Ok(DataDirs {
                base: dir.to_path_buf(),
                temporary: false,
            });
        }
        let stem: String = cluster
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let name = format!("marie-up-{stem}-{}", std::process::id());
        let tmp = std::env::temp_dir();
        sweep_left_behind(&tmp);
        for n in 0..1000 {
            let base = match n {
                0 => tmp.join(&name),
                n => tmp.join(format!("{name}.{n}")),
            };
            match std::fs::create_dir(&base) {
                Ok(()) => {
                    return Ok(DataDirs {
                        base,
                        temporary: true,
                    })
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => anyhow::bail!(
                    "cannot make the nodes' data directory {}: {e} (give one with --data-dir)",
                    base.display()
                ),
            }
        }
        anyhow::bail!(
            "cannot make the nodes' data directory: {}/{name}.N all exist (give one with \
             --data-dir)",
            tmp.display()
        )
    }

    /// The data directory of `node`, unless its config names one.
    pub(super) fn of(&self, node: &NodeConfig) -> Option<PathBuf> {
        match node.data_dir {
            Some(_) => None,
            None => Some(self.base.join(&node.name)),
        }
    }
}

/// Remove the temporary data directories of `marie up`s that were killed (`kill -9` leaves
/// them): `marie-up-…-PID[.N]` whose process is gone. Where a process's liveness cannot be
/// read (no `/proc`), nothing is removed.
fn sweep_left_behind(tmp: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(tmp) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(rest) = name.strip_prefix("marie-up-") else {
            continue;
        };
        // …-PID, or …-PID.N
        let last = rest.rsplit('-').next().unwrap_or_default();
        let Ok(pid) = last.split('.').next().unwrap_or_default().parse::<u32>() else {
            continue;
        };
        if Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        match std::fs::remove_dir_all(entry.path()) {
            Ok(()) => {
                tracing::debug!(dir = %entry.path().display(), "a killed marie up's data directory removed")
            }
            Err(e) => tracing::debug!(dir = %entry.path().display(), "left: {e}"),
        }
    }
}

impl Drop for DataDirs {
    fn drop(&mut self) {
        if self.temporary {
            if let Err(e) = std::fs::remove_dir_all(&self.base) {
                tracing::warn!(dir = %self.base.display(), "the nodes' data directory is left: {e}");
            }
        }
    }
}

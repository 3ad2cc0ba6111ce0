//! What makes a replica added while the cluster ran start again with its node: beside its
//! journal (`DATA_DIR/dm/NAME/`) the host writes `joined.json` — the datamanager's
//! [`Declaration`] and the voters it first joined — and a node that starts on that data
//! directory starts every replica so described as one that joins (its journal then says the
//! configuration it follows). A replica dropped after its removal has no directory left;
//! whatever started the node — `marie up`, systemd, by hand — the replica comes back.

use super::Declaration;
use crate::node::config::DatamanagerConfig;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file's name in the journal's directory.
pub const FILE: &str = "joined.json";

/// What `joined.json` holds.
#[derive(Debug, Serialize, Deserialize)]
struct Joined {
    declaration: Declaration,
    voters: Vec<String>,
}

/// Write `joined.json` in `journal_dir` (created if missing), synced: the replica is
/// started once it is there.
pub(crate) fn write(
    journal_dir: &Path,
    declaration: &Declaration,
    voters: &[String],
) -> std::io::Result<()> {
    std::fs::create_dir_all(journal_dir)?;
    let text = serde_json::to_vec_pretty(&Joined {
        declaration: declaration.clone(),
        voters: voters.to_vec(),
    })
    .map_err(std::io::Error::other)?;
    let path = journal_dir.join(FILE);
    let tmp = journal_dir.join(format!("{FILE}.tmp"));
    std::fs::write(&tmp, text)?;
    std::fs::File::open(&tmp)?.sync_all()?;
    std::fs::rename(tmp, path)
}

/// The replicas added to the node whose data directory is `data_dir`, each as a
/// datamanager that [joined](DatamanagerConfig::joined); a `joined.json` that does not
/// read is skipped with a warning (its journal is left as it is).
pub fn read_all(data_dir: &Path) -> Vec<DatamanagerConfig> {
    let Ok(entries) = std::fs::read_dir(data_dir.join("dm")) else {
        return Vec::new();
    };
    let mut joined = Vec::new();
    for entry in entries.flatten() {
        let path = entry.path().join(FILE);
        let Ok(text) = std::fs::read(&path) else {
            continue;
        };
        match serde_json::from_slice::<Joined>(&text) {
            Ok(j) => joined.push(j.declaration.joining(j.voters)),
            Err(e) => {
                tracing::warn!(file = %path.display(), error = %e, "a replica added while the cluster ran is not started again: its description does not read")
            }
        }
    }
    joined.sort_by(|a, b| a.name.cmp(&b.name));
    joined
}

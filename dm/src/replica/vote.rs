//! A replica's term and vote, kept on disk: a replica that restarts must not vote twice in a term
//! (Raft's safety rests on it), so both are synced before a vote or a new term is used.
//!
//! One small file, `VOTE` in the journal's directory (which the journal's lock guards):
//! `term` and `voted_for` on one line, written to a temporary file, synced, and renamed
//! over the old one, so a crash leaves the old or the new, never half of one.

use std::io::{self, Write};
use std::path::Path;

const FILE: &str = "VOTE";

/// The term and vote stored in `dir`: (0, none) if there is no file yet.
pub(crate) fn load(dir: &Path) -> io::Result<(u64, Option<String>)> {
    let text = match std::fs::read_to_string(dir.join(FILE)) {
        Ok(text) => text,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok((0, None)),
        Err(e) => return Err(e),
    };
    let mut words = text.split_whitespace();
    let term = words.next().and_then(|w| w.parse().ok()).ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{FILE}: no term in {text:?}"),
        )
    })?;
    Ok((term, words.next().map(str::to_string)))
}

/// Store `term` and `voted_for` in `dir`, durably, before returning.
pub(crate) fn save(dir: &Path, term: u64, voted_for: Option<&str>) -> io::Result<()> {
    let tmp = dir.join(format!("{FILE}.tmp"));
    let mut f = std::fs::File::create(&tmp)?;
    writeln!(f, "{term} {}", voted_for.unwrap_or(""))?;
    f.sync_all()?;
    std::fs::rename(&tmp, dir.join(FILE))?;
    std::fs::File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_saved_vote_is_loaded_back() {
        let dir = std::env::temp_dir().join(format!("marie-vote-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(super::load(&dir).unwrap(), (0, None));
        super::save(&dir, 7, Some("features")).unwrap();
        assert_eq!(super::load(&dir).unwrap(), (7, Some("features".into())));
        super::save(&dir, 8, None).unwrap();
        assert_eq!(super::load(&dir).unwrap(), (8, None));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

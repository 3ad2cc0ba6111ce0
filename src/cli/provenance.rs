//! What a `marie run` tells of itself as its first event: the command line, every file it
//! read with its SHA-256 and its text, the seed and the speed ([`Provenance`]; the node adds
//! the build, the start time and the nodes, the dispatcher the parameters).

use super::args::MAX_SPEED;
use marie::diagnostic::{read_source, Diagnostic};
use marie::run::{Digest, FileRead, FileRole, Provenance};
use std::path::Path;

/// A run's provenance as the command knows it: `files` in the order read (role and path;
/// each read again here for its digest and text — a file gone since is left out, with a
/// warning), the seed when a robot runs, the speed (`None`: the cluster's).
pub(crate) fn of_run(
    files: &[(FileRole, &Path)],
    seed: Option<u64>,
    speed: Option<f64>,
) -> Provenance {
    Provenance {
        command: std::env::args().collect(),
        files: files
            .iter()
            .filter_map(|(role, path)| match read(*role, path) {
                Ok(file) => Some(file),
                Err(e) => {
                    tracing::warn!(path = %path.display(), "a file the run read is not in its provenance: {e}");
                    None
                }
            })
            .collect(),
        seed,
        speed: speed.map(speed_text),
        ..Provenance::default()
    }
}

/// `max`, or the factor as given (`1`, `2.5`).
pub(crate) fn speed_text(speed: f64) -> String {
    match speed {
        MAX_SPEED => "max".into(),
        x => format!("{x}"),
    }
}

/// `path` as the file of `role`: its text (through the one reader of input files, with its
/// checks) and SHA-256.
fn read(role: FileRole, path: &Path) -> Result<FileRead, Diagnostic> {
    let text = read_source(path, role.name())?;
    Ok(FileRead {
        role,
        path: path.display().to_string(),
        sha256: sha256(text.as_bytes()),
        text,
    })
}

/// SHA-256 of `bytes`.
pub(crate) fn sha256(bytes: &[u8]) -> Digest {
    Digest::from_bytes(aws_lc_rs::digest::digest(&aws_lc_rs::digest::SHA256, bytes).as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_digest_of_a_file_is_its_sha256() {
        // FIPS 180-2's example
        assert_eq!(
            sha256(b"abc").0,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(speed_text(MAX_SPEED), "max");
        assert_eq!(speed_text(2.5), "2.5");
    }
}

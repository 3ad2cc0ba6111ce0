//! What an output path must be, checked before a command runs anything: a file that can be
//! created or overwritten — so a run never ends in an output it cannot write. (Input files —
//! missions, worlds, node configs — are checked by their one reader,
//! [`marie::diagnostic::read_source`], before it reads them.)

use super::error::BadInput;
use marie::diagnostic::file_kind;
use std::fs::{self, OpenOptions};
use std::path::Path;

/// Refuse an output path `flag` (e.g. `--report`) that cannot be written: a directory, a
/// fifo or socket, a missing or unwritable parent directory. A regular file is opened for
/// writing without truncating; a new file is created and removed again. Character devices
/// (`/dev/null`, `/dev/stdout`) are let through.
pub(crate) fn output(flag: &str, path: &Path) -> Result<(), BadInput> {
    let refuse = |why: String| BadInput(format!("{flag} {}: {why}", path.display()));
    match fs::metadata(path) {
        Ok(meta) if meta.is_file() => OpenOptions::new()
            .write(true)
            .open(path)
            .map(drop)
            .map_err(|e| refuse(format!("cannot be written: {e}"))),
        Ok(meta) if is_char_device(&meta) => Ok(()),
        Ok(meta) => Err(refuse(format!(
            "is not a regular file ({})",
            file_kind(&meta)
        ))),
        Err(_) => {
            let parent = match path.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            match fs::metadata(parent) {
                Ok(m) if m.is_dir() => {}
                Ok(_) => return Err(refuse(format!("{} is not a directory", parent.display()))),
                Err(e) => return Err(refuse(format!("no directory {}: {e}", parent.display()))),
            }
            OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(path)
                .map_err(|e| refuse(format!("cannot be created: {e}")))?;
            let _ = fs::remove_file(path);
            Ok(())
        }
    }
}

#[cfg(unix)]
fn is_char_device(meta: &fs::Metadata) -> bool {
    use std::os::unix::fs::FileTypeExt;
    meta.file_type().is_char_device()
}

#[cfg(not(unix))]
fn is_char_device(_: &fs::Metadata) -> bool {
    false
}

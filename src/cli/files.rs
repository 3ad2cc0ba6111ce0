//! What a file argument must be, checked before a command reads or runs anything: an input
//! a regular file of sane size (a directory, `/dev/zero` or a fifo would be read for ever or
//! block), an output a file that can be created or overwritten — so a run never ends in an
//! output it cannot write, and no input stalls or exhausts the command.

use super::error::BadInput;
use std::fs::{self, OpenOptions};
use std::path::Path;

/// The largest mission or world file read, in bytes (real ones are a few KiB).
pub const MAX_INPUT_BYTES: u64 = 4 * 1024 * 1024;

/// Refuse `path` (a `what`, e.g. "mission file") if it exists but is not a regular file or is
/// larger than [`MAX_INPUT_BYTES`]; its metadata is all that is looked at. A path that does
/// not exist passes: its reader reports that with its own diagnostics.
pub fn input(what: &str, path: &Path) -> Result<(), BadInput> {
    let Ok(meta) = fs::metadata(path) else {
        return Ok(());
    };
    if !meta.is_file() {
        return Err(BadInput(format!(
            "{}: the {what} is not a regular file ({})",
            path.display(),
            kind(&meta)
        )));
    }
    if meta.len() > MAX_INPUT_BYTES {
        return Err(BadInput(format!(
            "{}: the {what} is {} bytes, more than the {} MiB a {what} may have",
            path.display(),
            meta.len(),
            MAX_INPUT_BYTES / (1024 * 1024)
        )));
    }
    Ok(())
}

/// Refuse an output path `flag` (e.g. `--report`) that cannot be written: a directory, a
/// fifo or socket, a missing or unwritable parent directory. A regular file is opened for
/// writing without truncating; a new file is created and removed again. Character devices
/// (`/dev/null`, `/dev/stdout`) are let through.
pub fn output(flag: &str, path: &Path) -> Result<(), BadInput> {
    let refuse = |why: String| BadInput(format!("{flag} {}: {why}", path.display()));
    match fs::metadata(path) {
        Ok(meta) if meta.is_file() => OpenOptions::new()
            .write(true)
            .open(path)
            .map(drop)
            .map_err(|e| refuse(format!("cannot be written: {e}"))),
        Ok(meta) if is_char_device(&meta) => Ok(()),
        Ok(meta) => Err(refuse(format!("is not a regular file ({})", kind(&meta)))),
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

/// What a non-regular file is, for messages.
fn kind(meta: &fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return "a fifo";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if meta.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

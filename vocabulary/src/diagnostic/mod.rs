//! Problems found in a TOML file of marie's — a mission, a world, a node config — each
//! with its `file:line:column`, and the pieces every such loader shares.
//!
//! One module serves every file format so that every bad input reads the same way:
//! `path:line:column: what was expected`, one line per problem, sorted by position.
//!
//! - [`Pos`], [`LineIndex`] — byte offsets to 1-based line and column;
//! - [`Diagnostic`], [`Diagnostics`] — the problems, displayed the way editors link them;
//! - [`read_source`] — reading a file safely: a directory, a device, a fifo or a huge file is
//!   refused *before* it is read, and text that is not UTF-8 is reported at its first bad
//!   byte;
//! - [`toml`] — the span-keeping TOML reader that walks a document by hand so one pass
//!   reports every unknown key, wrong type and out-of-range value at its own position.
//!
//! ```
//! use marie_vocabulary::diagnostic::toml::{Reader, Rule};
//! let src = "[cart]\nspeed = -2\n";
//! let mut r = Reader::new(src, "cart.toml");
//! let doc = r.parse().unwrap();
//! let top = r.top(&doc, "the file");
//! let cart = r.table(top.get("cart").unwrap(), "[cart]").unwrap();
//! assert_eq!(r.num(&cart, "speed", Some(1.0), Rule::Positive), None);
//! let diags = r.finish(Some(()), "the file is not valid").unwrap_err();
//! assert_eq!(diags.to_string(), "cart.toml:2:9: `speed` must be greater than 0, found -2");
//! ```

pub mod toml;

use std::fmt;
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A position in a text file: 1-based line and 1-based column (counted in characters, not
/// bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Pos {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
}

impl Pos {
    /// The position of byte `offset` in `src`. Offsets past the end clamp to the end; offsets
    /// inside a multi-byte character move back to its start.
    pub fn of(src: &str, offset: usize) -> Pos {
        let mut offset = offset.min(src.len());
        while offset > 0 && !src.is_char_boundary(offset) {
            offset -= 1;
        }
        let before = src.get(..offset).unwrap_or_default();
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Pos {
            line: before.matches('\n').count() + 1,
            column: before.get(line_start..).unwrap_or_default().chars().count() + 1,
        }
    }
}

/// Byte offsets to positions in one text, in logarithmic time per lookup (a mission may hold
/// large arrays, and every value's position is recorded).
pub struct LineIndex<'s> {
    src: &'s str,
    /// Byte offset where each line starts.
    starts: Vec<usize>,
}

impl std::fmt::Debug for LineIndex<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LineIndex")
            .field("bytes", &self.src.len())
            .field("lines", &self.starts.len())
            .finish()
    }
}

impl<'s> LineIndex<'s> {
    /// Index the lines of `src`.
    pub fn new(src: &'s str) -> Self {
        let starts = std::iter::once(0)
            .chain(src.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        LineIndex { src, starts }
    }

    /// The position of byte `offset`, as [`Pos::of`] computes it.
    pub fn pos(&self, offset: usize) -> Pos {
        let mut offset = offset.min(self.src.len());
        while offset > 0 && !self.src.is_char_boundary(offset) {
            offset -= 1;
        }
        let line = self.starts.partition_point(|s| *s <= offset).max(1);
        let start = self.starts.get(line - 1).copied().unwrap_or(0);
        let column = self
            .src
            .get(start..offset)
            .unwrap_or_default()
            .chars()
            .count()
            + 1;
        Pos { line, column }
    }

    /// The position of the start of `span`.
    pub fn span(&self, span: &Range<usize>) -> Pos {
        self.pos(span.start)
    }
}

impl fmt::Display for Pos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.column)
    }
}

/// One problem in a file: where (`path:line:column`) and what was expected.
///
/// Displays as `path:line:column: message`, the form editors and terminals link to.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error, serde::Serialize)]
#[error("{path}:{line}:{column}: {message}")]
pub struct Diagnostic {
    /// The file's path, or a placeholder such as `<mission>` for text given without one.
    pub path: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column, counted in characters.
    pub column: usize,
    /// What is wrong and what was expected.
    pub message: String,
}

impl Diagnostic {
    /// A diagnostic for `path` at `line:column`.
    pub fn new(
        path: impl Into<String>,
        line: usize,
        column: usize,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            path: path.into(),
            line,
            column,
            message: message.into(),
        }
    }

    /// A diagnostic at `pos` of file `path`.
    pub fn at(path: &str, pos: Pos, message: impl Into<String>) -> Self {
        Diagnostic::new(path, pos.line, pos.column, message)
    }
}

/// Every problem found in one stage of checking a file, sorted by position.
///
/// Displays one diagnostic per line. Never empty when returned as an error.
#[derive(Clone, Debug, Default, PartialEq, Eq, thiserror::Error)]
#[error("{}", one_per_line(.0))]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl Diagnostics {
    /// Sort by position (stable: problems at one position keep the order they were found in)
    /// and drop exact duplicates.
    pub fn sort(&mut self) {
        self.0.sort_by_key(|d| (d.line, d.column));
        self.0.dedup();
    }

    /// The diagnostics, in order.
    pub fn iter(&self) -> std::slice::Iter<'_, Diagnostic> {
        self.0.iter()
    }

    /// Number of diagnostics.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True when there is no diagnostic.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// `Ok(value)` when there is no diagnostic, otherwise the sorted diagnostics.
    pub fn into_result<T>(mut self, value: T) -> Result<T, Diagnostics> {
        if self.0.is_empty() {
            Ok(value)
        } else {
            self.sort();
            Err(self)
        }
    }
}

/// The largest file marie reads as a mission, world or node config. Real ones are a few
/// KiB; anything this large is a mistake (a log, an image, `/dev/zero`), refused before
/// it is read.
pub const MAX_SOURCE_BYTES: u64 = 4 * 1024 * 1024;

/// A file named in the file at `file` (a mission's world, a node config's certificates, a
/// cluster file's node configs): relative to `file`'s directory, as a reader of that file
/// expects; an absolute name, or one with no file to be relative to, stays as written.
///
/// ```
/// use marie_vocabulary::diagnostic::beside;
/// use std::path::Path;
/// let mission = Path::new("missions/docking.toml");
/// assert_eq!(beside(Some(mission), "worlds/lab.toml"), Path::new("missions/worlds/lab.toml"));
/// assert_eq!(beside(Some(mission), "/srv/lab.toml"), Path::new("/srv/lab.toml"));
/// assert_eq!(beside(None, "lab.toml"), Path::new("lab.toml"));
/// ```
pub fn beside(file: Option<&Path>, named: impl AsRef<Path>) -> PathBuf {
    match file.and_then(Path::parent) {
        Some(dir) => dir.join(named),
        None => named.as_ref().to_path_buf(),
    }
}

/// Read the text of `path`, a `what` file (e.g. `"mission"`), as a loader needs it: a path that
/// is not a regular file (a directory, a device, a fifo) or is larger than
/// [`MAX_SOURCE_BYTES`] is refused without reading it, an unreadable file names the OS error,
/// and text that is not UTF-8 is reported at its first invalid byte. Every error is one
/// diagnostic at the file's `1:1` (or the bad byte's position).
pub fn read_source(path: &Path, what: &str) -> Result<String, Diagnostic> {
    let file = path.display().to_string();
    let at_start = |message: String| Diagnostic::new(&file, 1, 1, message);
    let meta = std::fs::metadata(path)
        .map_err(|e| at_start(format!("cannot read {what} file {file}: {e}")))?;
    if !meta.is_file() {
        return Err(at_start(format!(
            "cannot read {what} file {file}: it is not a regular file ({}), and a {what} file is TOML text",
            file_kind(&meta)
        )));
    }
    if meta.len() > MAX_SOURCE_BYTES {
        return Err(at_start(format!(
            "{what} file {file} is {} bytes, more than the {} MiB a {what} file may have",
            meta.len(),
            MAX_SOURCE_BYTES / (1024 * 1024)
        )));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_SOURCE_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| at_start(format!("cannot read {what} file {file}: {e}")))?;
    if bytes.len() as u64 > MAX_SOURCE_BYTES {
        return Err(at_start(format!(
            "{what} file {file} grew past {MAX_SOURCE_BYTES} bytes while it was read"
        )));
    }
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let prefix =
            std::str::from_utf8(e.as_bytes().get(..valid).unwrap_or_default()).unwrap_or_default();
        Diagnostic::at(
            &file,
            Pos::of(prefix, valid),
            format!("the {what} file is not valid UTF-8 text"),
        )
    })
}

/// What a path that is not a regular file is, for messages (`a directory`, `a fifo`, …).
pub fn file_kind(meta: &std::fs::Metadata) -> &'static str {
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
        "not a file"
    }
}

fn one_per_line(diagnostics: &[Diagnostic]) -> String {
    diagnostics
        .iter()
        .map(Diagnostic::to_string)
        .collect::<Vec<_>>()
        .join("\n")
}

impl<'a> IntoIterator for &'a Diagnostics {
    type Item = &'a Diagnostic;
    type IntoIter = std::slice::Iter<'a, Diagnostic>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl IntoIterator for Diagnostics {
    type Item = Diagnostic;
    type IntoIter = std::vec::IntoIter<Diagnostic>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl From<Diagnostic> for Diagnostics {
    fn from(d: Diagnostic) -> Self {
        Diagnostics(vec![d])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based_and_count_characters() {
        let src = "ab\nçd = 1\n";
        assert_eq!(Pos::of(src, 0), Pos { line: 1, column: 1 });
        assert_eq!(Pos::of(src, 3), Pos { line: 2, column: 1 });
        // `ç` is two bytes: `d` is byte 5 but column 2
        assert_eq!(Pos::of(src, 5), Pos { line: 2, column: 2 });
        // inside `ç`: back to its start
        assert_eq!(Pos::of(src, 4), Pos { line: 2, column: 1 });
        // past the end: clamps
        assert_eq!(Pos::of(src, 999), Pos { line: 3, column: 1 });
        let index = LineIndex::new(src);
        for offset in 0..=src.len() + 2 {
            assert_eq!(index.pos(offset), Pos::of(src, offset), "offset {offset}");
        }
        assert_eq!(LineIndex::new("").pos(5), Pos { line: 1, column: 1 });
    }

    #[test]
    fn diagnostics_sort_and_render_one_per_line() {
        let mut d = Diagnostics(vec![
            Diagnostic::new("m.toml", 3, 1, "c"),
            Diagnostic::new("m.toml", 1, 9, "b"),
            Diagnostic::new("m.toml", 1, 2, "a"),
        ]);
        d.sort();
        assert_eq!(d.to_string(), "m.toml:1:2: a\nm.toml:1:9: b\nm.toml:3:1: c");
    }

    #[test]
    fn a_directory_or_device_is_refused_without_reading_it() {
        let dir = std::env::temp_dir();
        let d = read_source(&dir, "mission").unwrap_err();
        assert!(
            d.message.contains("not a regular file (a directory)"),
            "{d}"
        );
        if Path::new("/dev/zero").exists() {
            let d = read_source(Path::new("/dev/zero"), "world").unwrap_err();
            assert!(d.message.contains("not a regular file"), "{d}");
        }
        let d = read_source(Path::new("/no/such/file.toml"), "node config").unwrap_err();
        assert!(d
            .to_string()
            .starts_with("/no/such/file.toml:1:1: cannot read node config file"));
    }

    #[test]
    fn text_that_is_not_utf8_is_reported_at_its_first_bad_byte() {
        let path = std::env::temp_dir().join(format!("marie-diag-{}.toml", std::process::id()));
        std::fs::write(&path, b"a = 1\nb = \"\xff\"\n").unwrap();
        let d = read_source(&path, "mission").unwrap_err();
        let _ = std::fs::remove_file(&path);
        assert_eq!((d.line, d.column), (2, 6), "{d}");
        assert!(d.message.contains("not valid UTF-8"), "{d}");
    }
}

//! What ran: the build, the command, the files with their texts, the nodes and their builds,
//! the seed and speed, and every parameter value with where it came from — the first event of
//! a run ([`EventKind::Provenance`](crate::events::EventKind::Provenance)) and the report's
//! `provenance` section.
//!
//! Why: the thesis' own complaint was that versions went unmanaged — old modules used by
//! mistake, old experiments that could not be compared with new ones. A report that names
//! the commit it was built from and carries the texts it ran can be told apart from another
//! (`marie diff`) and run again (`marie run --replay`).
//!
//! ```
//! use marie_vocabulary::run::{Build, Digest};
//! let build = Build::new("0.1.0", Some("1f2e3d4c5b6a79881f2e3d4c5b6a79881f2e3d4c"), Some(true));
//! assert_eq!(build.to_string(), "0.1.0 (commit 1f2e3d4c5b6a79881f2e3d4c5b6a79881f2e3d4c, uncommitted changes)");
//! assert_eq!(Build::new("0.1.0", None, None).to_string(), "0.1.0 (commit unknown)");
//! // a file's digest is told as lowercase hex
//! assert_eq!(Digest::from_bytes(&[0xab, 0x01]).to_string(), "ab01");
//! ```

use crate::property::Value;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::sync::OnceLock;

/// Which marie built a process: its version, the commit and whether the tree had
/// uncommitted changes, captured at build time (the `marie` command's `build.rs`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Build {
    /// The package version (`0.1.0`).
    pub version: String,
    /// The commit's 40 hex digits; `None` outside a git checkout (a source tarball) or for
    /// a library whose embedder did not say ([`set_this_build`]).
    #[serde(default)]
    pub commit: Option<String>,
    /// Whether the tree had uncommitted changes; `None` when not known.
    #[serde(default)]
    pub uncommitted_changes: Option<bool>,
}

impl Build {
    /// A build of `version` at `commit`, `dirty` if the tree had uncommitted changes.
    pub fn new(version: &str, commit: Option<&str>, dirty: Option<bool>) -> Build {
        Build {
            version: version.to_string(),
            commit: commit.filter(|c| !c.is_empty()).map(str::to_string),
            uncommitted_changes: dirty,
        }
    }

    /// Whether `other` is the same code: the same version at the same known commit, neither
    /// with uncommitted changes. Unknown commits are never the same.
    pub fn same_code(&self, other: &Build) -> bool {
        self.version == other.version
            && self.commit.is_some()
            && self.commit == other.commit
            && self.uncommitted_changes == Some(false)
            && other.uncommitted_changes == Some(false)
    }

    /// Whether `other` was built from another commit (or version) than this — what a
    /// replay or a cluster warns of. Unknown commits are not told apart.
    pub fn other_commit(&self, other: &Build) -> bool {
        self.version != other.version
            || matches!((&self.commit, &other.commit), (Some(a), Some(b)) if a != b)
    }
}

impl fmt::Display for Build {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.commit, self.uncommitted_changes) {
            (None, _) => write!(f, "{} (commit unknown)", self.version),
            (Some(c), Some(false)) => write!(f, "{} (commit {c})", self.version),
            (Some(c), Some(true)) => {
                write!(f, "{} (commit {c}, uncommitted changes)", self.version)
            }
            (Some(c), None) => write!(f, "{} (commit {c}, changes unknown)", self.version),
        }
    }
}

static THIS_BUILD: OnceLock<Build> = OnceLock::new();

/// Say which build this process is (once, before anything runs; later calls are ignored):
/// the `marie` command does so from what its `build.rs` captured. A node tells it to its
/// peers and names it in every run's provenance.
pub fn set_this_build(build: Build) {
    let _ = THIS_BUILD.set(build);
}

/// This process's build: what [`set_this_build`] said, else this crate's version at an
/// unknown commit.
pub fn this_build() -> Build {
    THIS_BUILD
        .get()
        .cloned()
        .unwrap_or_else(|| Build::new(env!("CARGO_PKG_VERSION"), None, None))
}

/// A SHA-256 digest, told as 64 lowercase hex digits.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Digest(pub String);

impl Digest {
    /// The hex text of `bytes` (a digest computed elsewhere: this crate links no hash).
    pub fn from_bytes(bytes: &[u8]) -> Digest {
        use fmt::Write;
        let mut s = String::with_capacity(bytes.len() * 2);
        for b in bytes {
            let _ = write!(s, "{b:02x}");
        }
        Digest(s)
    }
}

impl fmt::Display for Digest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// What a file a run read was to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FileRole {
    /// The mission (task tree).
    Mission,
    /// The world the simulated robot drove in.
    World,
    /// The node config the run's node hosted.
    Node,
    /// The cluster file `marie up` started the nodes of.
    Cluster,
}

impl FileRole {
    /// The role's name (`mission`, `world`, `node`, `cluster`).
    pub fn name(self) -> &'static str {
        match self {
            FileRole::Mission => "mission",
            FileRole::World => "world",
            FileRole::Node => "node",
            FileRole::Cluster => "cluster",
        }
    }
}

impl fmt::Display for FileRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A file a run read, with its text: enough to run it again from the report alone.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileRead {
    /// What it was to the run.
    pub role: FileRole,
    /// Its path, as given (or as the mission named it).
    pub path: String,
    /// SHA-256 of its bytes.
    pub sha256: Digest,
    /// Its text (the bytes read as UTF-8; a file that is not is refused by its reader).
    pub text: String,
}

/// A node of the run and the marie it runs.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeBuild {
    /// The node's name.
    pub node: String,
    /// Its build; `None` when it did not say (a node of an older build).
    pub marie: Option<Build>,
}

/// Where a parameter's value came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamSource {
    /// The mission file gave it.
    Mission,
    /// The mission left it out: the operation's declared default.
    Default,
    /// Set while the action ran, by someone other than the dispatcher (an application's
    /// `OperationHandle::set`, a tool).
    Reparameterized,
}

impl ParamSource {
    /// The source's name (`mission`, `default`, `reparameterized`).
    pub fn name(self) -> &'static str {
        match self {
            ParamSource::Mission => "mission",
            ParamSource::Default => "default",
            ParamSource::Reparameterized => "reparameterized",
        }
    }
}

impl fmt::Display for ParamSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One parameter's value as an operation ran with it, and where it came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamValue {
    /// The parameter's name.
    pub name: String,
    /// Its value.
    pub value: Value,
    /// Where it came from.
    pub source: ParamSource,
}

/// One parameter's value in an action of the run ([`Provenance::parameters`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamSetting {
    /// The action (empty for a re-parameterization between actions).
    pub action: String,
    /// The operation, by name.
    pub operation: String,
    /// The parameter's name.
    pub name: String,
    /// Its value.
    pub value: Value,
    /// Where it came from.
    pub source: ParamSource,
    /// For a re-parameterization: when, in ms since the run began.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_ms: Option<u64>,
}

/// What ran: see the [module docs](self).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The build of the process that ran the mission (its dispatcher's, at the start).
    #[serde(default)]
    pub marie: Option<Build>,
    /// The command line, one argument per item (empty for a run an application started).
    #[serde(default)]
    pub command: Vec<String>,
    /// When the run started, wall clock, ms since the Unix epoch.
    #[serde(default)]
    pub started_unix_ms: u64,
    /// The same, as RFC 3339 UTC text (`2026-11-27T17:50:00.123Z`).
    #[serde(default)]
    pub started: String,
    /// Every file the run read, in the order read: mission, world, node config, cluster file.
    #[serde(default)]
    pub files: Vec<FileRead>,
    /// The nodes of the run: the dispatcher's first, then its peers by name.
    #[serde(default)]
    pub nodes: Vec<NodeBuild>,
    /// The simulation's seed, when a robot runs.
    #[serde(default)]
    pub seed: Option<u64>,
    /// The clock's speed: `max`, or a factor of real time.
    #[serde(default)]
    pub speed: Option<String>,
    /// Every parameter value the operations ran with, per action, and where each came
    /// from; re-parameterizations last (the latest [`REPORT_KEEPS`](crate::report::REPORT_KEEPS)).
    /// Filled from the run's `action_started` and `reparameterized` events.
    #[serde(default)]
    pub parameters: Vec<ParamSetting>,
}

impl Provenance {
    /// The file read as `role` (the first, should there be several).
    pub fn file(&self, role: FileRole) -> Option<&FileRead> {
        self.files.iter().find(|f| f.role == role)
    }

    /// The nodes whose build is another commit than `build`'s ([`Build::other_commit`]).
    pub fn nodes_of_other_commits<'a>(
        &'a self,
        build: &'a Build,
    ) -> impl Iterator<Item = &'a NodeBuild> + 'a {
        self.nodes
            .iter()
            .filter(move |n| n.marie.as_ref().is_some_and(|b| b.other_commit(build)))
    }
}

/// `unix_ms` as RFC 3339 UTC text with milliseconds (`1970-01-01T00:00:00.000Z`).
pub fn rfc3339(unix_ms: u64) -> String {
    let secs = unix_ms / 1000;
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // civil from days (H. Hinnant's algorithm), for days since 1970-01-01
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60,
        unix_ms % 1000
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_time_is_told_as_rfc3339_utc() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        // 2026-11-27T17:50:00.123Z
        assert_eq!(rfc3339(1_795_801_800_123), "2026-11-27T17:50:00.123Z");
        // a leap day
        assert_eq!(rfc3339(951_782_400_000), "2000-02-29T00:00:00.000Z");
    }

    #[test]
    fn builds_of_other_commits_are_told_apart_and_unknown_ones_are_not() {
        let a = Build::new("0.1.0", Some("aaaa"), Some(false));
        let b = Build::new("0.1.0", Some("bbbb"), Some(false));
        let unknown = Build::new("0.1.0", None, None);
        assert!(a.other_commit(&b));
        assert!(!a.other_commit(&a.clone()));
        assert!(!a.other_commit(&unknown));
        assert!(a.same_code(&a.clone()));
        assert!(!unknown.same_code(&unknown.clone()));
        let dirty = Build::new("0.1.0", Some("aaaa"), Some(true));
        assert!(!a.same_code(&dirty));
    }

    #[test]
    fn a_provenance_without_fields_reads_from_an_empty_object() {
        let p: Provenance = serde_json::from_str("{}").unwrap();
        assert_eq!(p, Provenance::default());
    }
}

//! `marie compat`: the compatibility gate — a corpus of this build's encodings, and the
//! check that a build still reads an older build's corpus and still writes what it read.
//!
//! What the corpus holds, one file per sample (`samples`, `journal`, `report`):
//! - every remote variant of every `remote_message!` enum, encoded as ractor_cluster sends
//!   it (the variant's name in the manifest, its fields' MessagePack map in the file), the
//!   replicas' own messages (`DmMsg::Replica`: every `ReplicaMsg`, sampled by marie-dm)
//!   among them — a variant without a sample does not compile (see `samples`), an enum
//!   without samples fails `tests/compat.rs`;
//! - event frames in the versioned envelope, as the relay sends them to watchers: two built
//!   here and one of each kind a real run of the demo mission published;
//! - a stored record (`NewRecord`), and a datamanager's journal: a `process`-durability
//!   datamanager started in this process on a directory of the corpus, three stores and a
//!   delete, the records it kept beside it;
//! - the run report (`marie run --report`) of that demo run, made by this very binary.
//!
//! `marie compat write DIR` writes them with a `manifest.toml` (the build, the protocol
//! version, each sample's type, variant, form and file); the repository keeps the corpus of
//! each protocol version in `compat/vN/`, and `tests/compat.rs` checks the current one.
//!
//! `marie compat check DIR` refuses a corpus of a protocol version this build does not
//! speak (exit 2: its nodes and this build's refuse each other anyway), and otherwise — the
//! corpus of this build's version or of an older one it still speaks, as the next build
//! checks the previous build's `compat/v2` — decodes each sample with this build through the path a node
//! takes (ractor's `Message::deserialize` for messages, the envelope and its payload for
//! frames, `wire::decode` for records, a datamanager's replay for the journal, `marie
//! diff`'s reader for the report), encodes it again and requires every key of the old
//! encoding to be still there with the same kind — a renamed field breaks an older peer
//! that reads this build's frames even when this build reads the old ones thanks to a
//! default. A sample that does not decode is compared with this build's own sample of its
//! variant, which names the field that changed.
//!
//! ```text
//! $ marie compat write /tmp/corpus
//! wrote 69 samples of marie 0.1.0 (protocol 2) to /tmp/corpus
//! $ marie compat check compat/v2
//! ok      EoMsg::Activate
//! …
//! compat/v2: 69 samples of marie 0.1.0 (415555e…), protocol 2: 69 ok, 0 broken
//! $ marie compat check /tmp/renamed      # an older build that called `epoch` `epich`
//! BROKEN  EoMsg::Activate: does not decode with this build (…); field `epich` is gone; field `epoch` is new
//! $ marie compat diff compat/v2 /tmp/corpus
//! same    EoMsg::Activate
//! …
//! ```
//!
//! Exit codes: 0 every sample is read and written back compatibly (`diff`: the corpora
//! agree), 1 a break (`diff`: they differ), 2 bad input (no manifest, an unreadable sample).
//! When the check fails, either make the change compatible (add a field rather than rename
//! it — in a message, as an `Option`: a remote variant's fields carry no serde attributes
//! on the wire, so `#[serde(default)]` there does not apply —; add a variant rather than
//! rename one), or raise `PROTOCOL_VERSION` and write the new version's corpus with
//! `marie compat write compat/vN`.

mod corpus;
mod decode;
mod journal;
mod report;
mod samples;
mod shape;

use crate::cli::error::BadInput;
use corpus::{Corpus, Entry, Manifest};
use samples::Form;
use shape::Shape;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `marie compat`'s flags.
#[derive(clap::Args, Debug)]
pub(crate) struct CompatArgs {
    /// What to do.
    #[command(subcommand)]
    pub verb: CompatVerb,
}

/// `marie compat`'s verbs.
#[derive(clap::Subcommand, Debug)]
pub(crate) enum CompatVerb {
    /// Write this build's corpus to DIR: one file per sample and `manifest.toml`.
    Write {
        /// The directory (created if need be; its samples are replaced).
        dir: PathBuf,
    },
    /// Check that this build reads every sample of DIR and writes it back with every key
    /// and kind the sample has. Exit 0 when all are, 1 on a break, 2 on bad input.
    Check {
        /// A corpus written by `marie compat write` (for instance `compat/v2`).
        dir: PathBuf,
    },
    /// Compare two corpora sample by sample (say, of two builds): which types changed and
    /// how. Exit 0 when they agree, 1 when they differ, 2 on bad input.
    Diff {
        /// The older corpus.
        a: PathBuf,
        /// The newer corpus.
        b: PathBuf,
    },
}

/// Do what `marie compat` says.
pub(crate) async fn compat(args: CompatArgs) -> anyhow::Result<ExitCode> {
    match args.verb {
        CompatVerb::Write { dir } => write(&dir).await,
        CompatVerb::Check { dir } => check(&dir).await,
        CompatVerb::Diff { a, b } => diff(&a, &b),
    }
}

async fn write(dir: &Path) -> anyhow::Result<ExitCode> {
    let mut samples = samples::all().map_err(|e| anyhow::anyhow!("a sample: {e}"))?;
    std::fs::create_dir_all(dir)
        .map_err(|e| BadInput(format!("cannot create {}: {e}", dir.display())))?;
    samples.push(
        journal::write(dir)
            .await
            .map_err(|e| anyhow::anyhow!("the journal sample: {e}"))?,
    );
    samples.extend(
        report::write(dir)
            .await
            .map_err(|e| anyhow::anyhow!("the demo run's samples: {e}"))?,
    );
    let build = crate::cli::this_build();
    let manifest = Manifest {
        version: build.version,
        commit: build.commit,
        protocol: marie::wire::PROTOCOL_VERSION,
        samples: Vec::new(),
    };
    corpus::write(dir, manifest, &samples)?;
    println!(
        "wrote {} samples of marie {} (protocol {}) to {}",
        samples.len(),
        env!("CARGO_PKG_VERSION"),
        marie::wire::PROTOCOL_VERSION,
        dir.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The shape a sample's bytes have, its envelope's payload opened.
fn shape_of(entry: &Entry, bytes: &[u8]) -> Result<Shape, String> {
    match entry.form {
        Form::Envelope => Shape::of_envelope(bytes),
        Form::Report => Shape::of_json(bytes),
        _ => Shape::of(bytes),
    }
}

async fn check(dir: &Path) -> anyhow::Result<ExitCode> {
    let corpus = corpus::read(dir)?;
    in_range(dir, &corpus)?;
    let own = samples::all().map_err(|e| anyhow::anyhow!("a sample: {e}"))?;
    let mut broken = 0;
    for (entry, bytes) in &corpus.samples {
        let again = match entry.form {
            Form::Journal => journal::replay(dir, &entry.file, bytes).await,
            Form::Report => report::redo(bytes),
            _ => decode::redo(entry, bytes),
        };
        let problems = check_one(entry, bytes, again, &own);
        if problems.is_empty() {
            println!("ok      {}", entry.name());
        } else {
            broken += 1;
            println!("BROKEN  {}: {}", entry.name(), problems.join("; "));
        }
    }
    let missing: Vec<String> = own
        .iter()
        .filter(|s| !corpus.samples.iter().any(|(e, _)| e.file == s.file()))
        .map(|s| s.file())
        .collect();
    if !missing.is_empty() {
        println!(
            "note    this build has {} samples the corpus lacks (new since it was written): {}",
            missing.len(),
            missing.join(", ")
        );
    }
    println!(
        "{}: {} samples of {}: {} ok, {broken} broken",
        dir.display(),
        corpus.samples.len(),
        written_by(&corpus),
        corpus.samples.len() - broken
    );
    Ok(if broken == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// A corpus of a protocol version this build does not speak is refused before any sample
/// is read: the build would drop or misread that version's frames, so a sample read clean
/// would prove nothing — its nodes refuse each other at the handshake.
fn in_range(dir: &Path, corpus: &Corpus) -> Result<(), BadInput> {
    use marie::wire::{envelope::speaks, OLDEST_PROTOCOL, PROTOCOL_VERSION};
    let version = corpus.manifest.protocol;
    if (OLDEST_PROTOCOL..=PROTOCOL_VERSION).contains(&version) {
        return Ok(());
    }
    Err(BadInput(format!(
        "{} is a corpus of {} ({}); this build speaks {}: two such builds cannot run side \
         by side (their nodes refuse each other at the handshake), so it is not checked — \
         check it with a build that speaks its version",
        dir.display(),
        speaks(version, version),
        written_by(corpus),
        speaks(OLDEST_PROTOCOL, PROTOCOL_VERSION)
    )))
}

fn written_by(corpus: &Corpus) -> String {
    let m = &corpus.manifest;
    match &m.commit {
        Some(c) => format!("marie {} ({c}), protocol {}", m.version, m.protocol),
        None => format!("marie {}, protocol {}", m.version, m.protocol),
    }
}

/// What breaks in one sample (nothing: it is read and written back compatibly).
fn check_one(
    entry: &Entry,
    bytes: &[u8],
    again: Result<Vec<u8>, String>,
    own: &[samples::Sample],
) -> Vec<String> {
    let old = match shape_of(entry, bytes) {
        Ok(s) => s,
        Err(e) => return vec![e],
    };
    match again {
        Ok(again) => match shape_of(entry, &again) {
            Ok(new) => shape::breaks(&old, &new),
            Err(e) => vec![format!("this build's own encoding does not read back: {e}")],
        },
        Err(e) => {
            let mut out = vec![e];
            // name the field: against this build's own sample of the same variant
            if let Some(mine) = own.iter().find(|s| s.file() == entry.file) {
                let entry_now = Entry {
                    form: mine.form,
                    ..entry.clone()
                };
                if let Ok(new) = shape_of(&entry_now, &mine.bytes) {
                    out.extend(shape::breaks(&old, &new));
                    out.extend(shape::additions(&old, &new));
                }
            }
            out
        }
    }
}

fn diff(a: &Path, b: &Path) -> anyhow::Result<ExitCode> {
    let (ca, cb) = (corpus::read(a)?, corpus::read(b)?);
    let mut differ = 0;
    for (entry, bytes) in &ca.samples {
        let Some((theirs, other)) = cb.samples.iter().find(|(e, _)| e.file == entry.file) else {
            differ += 1;
            println!("gone    {}", entry.name());
            continue;
        };
        let (old, new) = match (shape_of(entry, bytes), shape_of(theirs, other)) {
            (Ok(old), Ok(new)) => (old, new),
            (Err(e), _) | (_, Err(e)) => {
                return Err(BadInput(format!("{}: {e}", entry.name())).into());
            }
        };
        let mut changes = shape::breaks(&old, &new);
        changes.extend(shape::additions(&old, &new));
        if entry.form != theirs.form {
            changes.push(format!(
                "travels as {:?}, was {:?}",
                theirs.form, entry.form
            ));
        }
        if changes.is_empty() {
            println!("same    {}", entry.name());
        } else {
            differ += 1;
            println!("changed {}: {}", entry.name(), changes.join("; "));
        }
    }
    for (entry, _) in &cb.samples {
        if !ca.samples.iter().any(|(e, _)| e.file == entry.file) {
            differ += 1;
            println!("new     {}", entry.name());
        }
    }
    println!(
        "{} ({}) → {} ({}): {differ} samples differ",
        a.display(),
        written_by(&ca),
        b.display(),
        written_by(&cb)
    );
    Ok(if differ == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

//! A corpus on disk: one file per sample and `manifest.toml`, which names the build that
//! wrote it, its protocol version and each sample's type, variant, form and file.

use super::samples::{Form, Sample};
use crate::cli::error::BadInput;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest's file name.
pub(crate) const MANIFEST: &str = "manifest.toml";

/// `manifest.toml`.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct Manifest {
    /// The marie version that wrote the corpus.
    pub version: String,
    /// Its commit, when known.
    #[serde(default)]
    pub commit: Option<String>,
    /// Its `PROTOCOL_VERSION`.
    pub protocol: u16,
    /// The samples.
    #[serde(rename = "sample", default)]
    pub samples: Vec<Entry>,
}

/// One sample in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Entry {
    /// The Rust type.
    #[serde(rename = "type")]
    pub ty: String,
    /// The variant on the wire (`-` for a plain value).
    pub variant: String,
    /// How it travels.
    pub form: Form,
    /// Its file, relative to the corpus.
    pub file: String,
}

impl Entry {
    /// `Type::Variant` (or `Type` for a plain value), and the file when it says more.
    pub(crate) fn name(&self) -> String {
        let stem = format!("{}.{}.", self.ty, self.variant);
        let base = match self.variant.as_str() {
            "-" => self.ty.clone(),
            v => format!("{}::{v}", self.ty),
        };
        if self
            .file
            .strip_prefix(&stem)
            .is_some_and(|ext| !ext.contains('.'))
        {
            base
        } else {
            format!("{base} ({})", self.file)
        }
    }
}

/// A corpus read back: its manifest and each entry's bytes.
#[derive(Debug)]
pub(crate) struct Corpus {
    /// What the manifest says.
    pub manifest: Manifest,
    /// Each entry with its bytes, in the manifest's order.
    pub samples: Vec<(Entry, Vec<u8>)>,
}

/// Write `samples` to `dir` (created if need be) with their manifest.
pub(crate) fn write(dir: &Path, manifest: Manifest, samples: &[Sample]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| BadInput(format!("cannot create {}: {e}", dir.display())))?;
    let mut manifest = manifest;
    for s in samples {
        let file = s.file();
        std::fs::write(dir.join(&file), &s.bytes)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", dir.join(&file).display()))?;
        manifest.samples.push(Entry {
            ty: s.ty.to_string(),
            variant: s.variant.clone(),
            form: s.form,
            file,
        });
    }
    let text = toml::to_string_pretty(&manifest)?;
    let header =
        "# Written by `marie compat write`: one sample of every encoding this build sends \
                  or stores.\n# Checked by `marie compat check` (tests/compat.rs); never edit \
                  by hand.\n";
    std::fs::write(dir.join(MANIFEST), format!("{header}{text}"))
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", dir.join(MANIFEST).display()))?;
    Ok(())
}

/// Read the corpus in `dir`: bad input (exit 2) when its manifest is missing or does not
/// parse, or a sample's file cannot be read.
pub(crate) fn read(dir: &Path) -> Result<Corpus, BadInput> {
    let path: PathBuf = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        BadInput(format!(
            "{} is not a corpus: cannot read {}: {e}",
            dir.display(),
            path.display()
        ))
    })?;
    let manifest: Manifest = toml::from_str(&text)
        .map_err(|e| BadInput(format!("{}: not a corpus manifest: {e}", path.display())))?;
    let mut samples = Vec::with_capacity(manifest.samples.len());
    for entry in &manifest.samples {
        if entry.file.contains("..") || Path::new(&entry.file).is_absolute() {
            return Err(BadInput(format!(
                "{}: sample file `{}` is outside the corpus",
                path.display(),
                entry.file
            )));
        }
        let bytes = std::fs::read(dir.join(&entry.file)).map_err(|e| {
            BadInput(format!(
                "{}: sample {} cannot be read: {e}",
                dir.display(),
                entry.name()
            ))
        })?;
        samples.push((entry.clone(), bytes));
    }
    Ok(Corpus { manifest, samples })
}

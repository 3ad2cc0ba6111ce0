//! `marie export EVENTS.jsonl --mcap FILE.mcap`: a run's events file (`marie run
//! --events`) as MCAP for Foxglove ([`super::mcap`] has the channels), read and written a
//! line at a time — an hours-long file is never held in memory.

use super::error::BadInput;
use super::mcap::McapWriter;
use marie::diagnostic::file_kind;
use marie::events::Event;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags of `marie export`.
#[derive(clap::Args, Debug)]
pub(crate) struct ExportArgs {
    /// The events file of a run (`marie run --events FILE.jsonl`): one event per line.
    #[arg(value_name = "EVENTS.jsonl")]
    pub events: PathBuf,
    /// Write the run as MCAP here: Foxglove opens it and draws the world, the cart, the sonar
    /// echoes and the paths, with every event in its log and the task tree's state.
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: PathBuf,
}

/// Convert the events file; print what the MCAP file holds. Exit 2 when the events file
/// cannot be read or a line of it is not an event (the output is then removed).
pub(crate) async fn export(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let ExportArgs { events, mcap } = args;
    super::mcap::output("--mcap", &mcap)?;
    let input = open(&events)?;
    let out = match convert(input, &events, McapWriter::create(&mcap)?) {
        Ok(out) => out,
        Err(e) => {
            remove_output(&mcap);
            return Err(e);
        }
    };
    let written = out.finish()?;
    println!(
        "{} from {}: {} events, {}",
        mcap.display(),
        events.display(),
        written.events,
        written.summary()
    );
    Ok(ExitCode::SUCCESS)
}

/// Write every event of `input` (the file `events`) to `out`; give it back to be finished
/// (on an error, it is dropped: the file is closed as it is).
fn convert(
    input: BufReader<File>,
    events: &Path,
    mut out: McapWriter,
) -> anyhow::Result<McapWriter> {
    for (i, line) in input.lines().enumerate() {
        let line = line.map_err(|e| {
            BadInput(format!(
                "cannot read the events file {}: line {}: {e}",
                events.display(),
                i + 1
            ))
        })?;
        if line.trim().is_empty() {
            continue;
        }
        let event = Event::from_json_line(&line)
            .map_err(|e| BadInput(format!("{}:{}: not an event: {e}", events.display(), i + 1)))?;
        out.write(&event)?;
    }
    Ok(out)
}

/// `path` opened for reading, or why not (exit 2).
fn open(path: &Path) -> Result<BufReader<File>, BadInput> {
    let refuse = |why: String| {
        BadInput(format!(
            "cannot read the events file {}: {why}",
            path.display()
        ))
    };
    let meta = std::fs::metadata(path).map_err(|e| refuse(e.to_string()))?;
    if meta.is_dir() {
        return Err(refuse(format!("it is {}", file_kind(&meta))));
    }
    File::open(path)
        .map(BufReader::new)
        .map_err(|e| refuse(e.to_string()))
}

/// Remove the half-written output of a conversion that failed — a regular file only (an
/// output such as `/dev/null` stays).
fn remove_output(path: &Path) {
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
        if let Err(e) = std::fs::remove_file(path) {
            tracing::warn!(path = %path.display(), error = %e, "cannot remove the unfinished MCAP file");
        }
    }
}

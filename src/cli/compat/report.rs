//! A run report as a sample: the JSON `marie run --report` writes, of a real run of the
//! demo mission by this very binary; the check reads it with the reader `marie diff` uses
//! and writes it back. The same run's events (`--events`), one of each kind it published,
//! are samples of event frames as the relay sends them.

use super::samples::{Form, Sample};
use marie::events::Event;
use marie::report::RunReport;
use std::path::Path;

/// The type named in the manifest.
pub(crate) const TYPE: &str = "RunReport";

/// The demo mission (missions/demo.toml): sampler and averager, no world, a tenth of a
/// second at `--speed max`, bounded by its own 60 s deadline.
const DEMO: &str = include_str!("../../../missions/demo.toml");

/// Run the demo mission with this binary and give its report and events as samples.
pub(crate) async fn write(corpus: &Path) -> Result<Vec<Sample>, String> {
    let sample = Sample {
        ty: TYPE,
        variant: "demo".into(),
        label: None,
        form: Form::Report,
        bytes: Vec::new(),
    };
    let mission = corpus.join(".demo-mission.toml");
    let report = corpus.join(sample.file());
    let events = corpus.join(".demo-events.jsonl");
    std::fs::write(&mission, DEMO).map_err(|e| format!("{}: {e}", mission.display()))?;
    let exe = std::env::current_exe().map_err(|e| format!("this binary: {e}"))?;
    let (m, r, e) = (mission.clone(), report.clone(), events.clone());
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(exe)
            .arg("run")
            .arg(&m)
            .arg("--seed")
            .arg("1")
            .arg("--report")
            .arg(&r)
            .arg("--events")
            .arg(&e)
            .stdout(std::process::Stdio::null())
            .output()
    })
    .await
    .map_err(|e| format!("the demo run: {e}"))?
    .map_err(|e| format!("the demo run does not start: {e}"))?;
    let _ = std::fs::remove_file(&mission);
    if !out.status.success() {
        return Err(format!(
            "the demo run failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let bytes = std::fs::read(&report).map_err(|e| format!("{}: {e}", report.display()))?;
    let lines = std::fs::read_to_string(&events);
    let _ = std::fs::remove_file(&events);
    let lines = lines.map_err(|e| format!("{}: {e}", events.display()))?;
    let mut out = vec![Sample { bytes, ..sample }];
    out.extend(one_of_each_kind(&lines)?);
    Ok(out)
}

/// The first event of each kind in an events file, as event frames.
fn one_of_each_kind(lines: &str) -> Result<Vec<Sample>, String> {
    let mut out: Vec<Sample> = Vec::new();
    for line in lines.lines().filter(|l| !l.trim().is_empty()) {
        let event = Event::from_json_line(line).map_err(|e| format!("the demo's event: {e}"))?;
        let kind = serde_json::to_value(&event.kind)
            .ok()
            .and_then(|v| v.get("type").and_then(|t| t.as_str()).map(str::to_string))
            .ok_or("an event kind without its `type`")?;
        if out.iter().any(|s| s.variant == kind) {
            continue;
        }
        out.push(Sample {
            ty: "Event",
            variant: kind,
            label: Some("demo".into()),
            form: Form::Envelope,
            bytes: super::samples::event_frame(&event)?,
        });
    }
    Ok(out)
}

/// Read a report as `marie diff` does and write it back.
pub(crate) fn redo(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let report: RunReport = serde_json::from_slice(bytes)
        .map_err(|e| format!("is not a run report this build reads: {e}"))?;
    serde_json::to_vec_pretty(&report).map_err(|e| e.to_string())
}

//! `marie up --probe DM`: `marie dm probe DM` run beside the mission — a child of `up` that
//! joins the cluster from `up`'s network (in a private one, the hub, which reaches every
//! node whatever is cut: a leader cut off from the others is read too), writes into the
//! datamanager and reads it back by name and from each replica until `up` is done, then
//! says its verdict (stale reads, the newest write read back) on one line of JSON. Its
//! standard input is a pipe `up` holds: closed, the probe stops — also when `up` dies.

use super::plan::UpPlan;
use crate::cli::children::exit_by;
use marie::dm::probe::ProbeVerdict;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long the probe may take to stop and say its verdict once told (its reads in flight,
/// then the newest write looked for, following the datamanager to its leader).
const FINISH_WITHIN: Duration = Duration::from_secs(60);

/// The probe's process.
pub(super) struct ProbeChild {
    dm: String,
    child: Child,
    stdin: Option<ChildStdin>,
    stdout: Option<JoinHandle<String>>,
    stderr: Option<JoinHandle<String>>,
}

impl ProbeChild {
    /// Start `marie dm probe DM` on `plan`'s cluster.
    pub(super) fn start(plan: &UpPlan, dm: &str) -> std::io::Result<ProbeChild> {
        let entry = plan.first_node();
        let mut child = Command::new(&plan.exe)
            .args(["dm", "probe", dm, "--json", "--stop-with-stdin", "--join"])
            .arg(entry.addr.to_string())
            .args(["--cookie", &entry.cookie])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().map(|out| {
            std::thread::spawn(move || {
                let mut all = String::new();
                let _ = BufReader::new(out).read_to_string(&mut all);
                all
            })
        });
        // its progress lines: the last few kept, for a probe that says no verdict
        let stderr = child.stderr.take().map(|err| {
            std::thread::spawn(move || {
                let mut last: Vec<String> = Vec::new();
                for line in BufReader::new(err).lines().map_while(Result::ok) {
                    last.push(line);
                    if last.len() > 10 {
                        last.remove(0);
                    }
                }
                last.join("\n")
            })
        });
        Ok(ProbeChild {
            dm: dm.to_string(),
            child,
            stdin,
            stdout,
            stderr,
        })
    }

    /// Stop the probe and read its verdict (killed if it has not said one within
    /// [`FINISH_WITHIN`]); `Err` says why there is none.
    pub(super) async fn finish(mut self) -> Result<ProbeVerdict, String> {
        self.stdin.take();
        let dm = self.dm.clone();
        tokio::task::spawn_blocking(move || self.wait())
            .await
            .map_err(|e| format!("the probe of {dm}: {e}"))?
    }

    fn wait(&mut self) -> Result<ProbeVerdict, String> {
        let status = exit_by(&mut self.child, Instant::now() + FINISH_WITHIN).ok();
        let out = self
            .stdout
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        let err = self
            .stderr
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        let said = out
            .lines()
            .rev()
            .find_map(|l| serde_json::from_str::<ProbeVerdict>(l).ok());
        match (said, status) {
            (Some(verdict), _) => Ok(verdict),
            (None, None) => Err(format!(
                "the probe of {} said no verdict within {} s (killed); its last lines:\n{err}",
                self.dm,
                FINISH_WITHIN.as_secs()
            )),
            (None, Some(status)) => Err(format!(
                "the probe of {} ended ({status}) without a verdict; its last lines:\n{err}",
                self.dm
            )),
        }
    }
}

impl Drop for ProbeChild {
    /// A probe not finished (`up` stopping on an error) is killed.
    fn drop(&mut self) {
        if self.stdin.is_some() || matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The summary's lines of a probe's outcome: the verdict, and each stale read.
pub(super) fn lines(outcome: &Result<ProbeVerdict, String>) -> Vec<String> {
    match outcome {
        Ok(v) => std::iter::once(format!("reads: {v}"))
            .chain(v.stale_reads.iter().map(|s| format!("  stale: {s}")))
            .collect(),
        Err(why) => vec![format!("reads: NOT checked: {why}")],
    }
}

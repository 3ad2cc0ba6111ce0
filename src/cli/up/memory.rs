//! The node processes' resident memory (`VmRSS` of `/proc/PID/status`), read at a soak's
//! start and at its end: a node that leaks grows over many runs and faults. A node
//! restarted meanwhile is read in its current process (which started later).

use marie::cluster::fault::NodeProcesses;
use std::collections::BTreeMap;

/// Each node's resident memory, KiB, by name (`None`: no process of it runs now, or its
/// status cannot be read).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Memory(pub(super) BTreeMap<String, Option<u64>>);

impl Memory {
    /// Read now, for every node of `processes` and every one of `names` (which may be
    /// down).
    pub(super) fn of(processes: &NodeProcesses, names: &[String]) -> Memory {
        Memory(
            names
                .iter()
                .map(|n| (n.clone(), processes.pid(n).and_then(rss_kib)))
                .collect(),
        )
    }
}

/// `VmRSS` of process `pid`, KiB.
fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    vm_rss(&status)
}

/// The `VmRSS:   1234 kB` line of a `/proc/PID/status` text, KiB.
fn vm_rss(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A size in KiB as MiB, one decimal (`-` for none).
pub(super) fn mib(kib: Option<u64>) -> String {
    match kib {
        Some(k) => format!("{:.1} MiB", k as f64 / 1024.0),
        None => "-".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resident_memory_is_read_from_a_status_text_and_of_this_process() {
        let status = "Name:\tmarie\nVmPeak:\t  999 kB\nVmRSS:\t   41236 kB\nThreads:\t9\n";
        assert_eq!(vm_rss(status), Some(41_236));
        assert_eq!(vm_rss("Name:\tx\n"), None);
        assert_eq!(mib(Some(41_236)), "40.3 MiB");
        assert_eq!(mib(None), "-");
        // this very process has some resident memory
        let me = NodeProcesses::new([("me".to_string(), std::process::id())]);
        let read = Memory::of(&me, &["me".to_string(), "gone".to_string()]);
        assert!(read.0["me"].is_some_and(|k| k > 0), "{read:?}");
        assert_eq!(read.0["gone"], None);
    }
}

//! The node processes' resident memory (`VmRSS` of `/proc/PID/status`), read at a soak's
//! start and after each of its runs: a node that leaks grows run after run and fault after
//! fault, one whose stores fill levels off once they hold what their retention keeps. A
//! node restarted meanwhile is read in its current process (which started later).
//!
//! # When memory is flat
//! A node starts empty and its datamanagers fill up to their bounds (the thesis layout's
//! feature and world keep 2000 records a class, reached in the fourth docking run; the run
//! datamanager 512 checkpoints, in the fifteenth), so the start and the end cannot be equal
//! and are not what is compared. The soak's runs after the first quarter are split in two
//! halves, and a node's memory is *flat* when the median of its readings in the second half
//! is at most [`FLAT_WITHIN`] above the median in the first: a leak of a fraction of a MiB a
//! run moves the median by that times a quarter of the runs or more. Medians, not highest
//! readings: a node read just after its restart holds what its journal's replay left
//! (some 4 MiB more until the command gives it back, `give_back.rs`), once in a while.

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

/// How much higher a node's median reading may be in the soak's second half than in its
/// first (after the first quarter) and still be flat: a tenth.
pub(super) const FLAT_WITHIN: f64 = 0.10;

/// Every node's memory at a soak's start and after each of its runs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Readings {
    /// Before the first run.
    pub(super) start: Memory,
    /// After run 1, 2, … (in order).
    pub(super) after: Vec<Memory>,
}

/// A node's memory over the soak, as the summary says it.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Trend {
    /// At the start, after the first quarter, halfway and at the end (KiB; `None`: not
    /// read).
    pub(super) marks: Vec<(String, Option<u64>)>,
    /// The medians of the first and the second half after the first quarter (KiB), when
    /// each half has a reading.
    pub(super) medians: Option<(u64, u64)>,
}

impl Trend {
    /// Whether the second half's median is within [`FLAT_WITHIN`] of the first's (a soak
    /// too short to have two halves is flat: there is nothing to compare).
    pub(super) fn flat(&self) -> bool {
        self.medians
            .is_none_or(|(first, second)| second as f64 <= first as f64 * (1.0 + FLAT_WITHIN))
    }
}

impl Readings {
    /// The runs after the first quarter, split in two halves: (first run of the first half,
    /// first run of the second, last run), 1-based. `None` for fewer than 4 runs.
    pub(super) fn halves(&self) -> Option<(usize, usize, usize)> {
        let runs = self.after.len();
        (runs >= 4).then(|| {
            let from = runs / 4 + 1;
            (from, from + (runs - from).div_ceil(2), runs)
        })
    }

    /// When the summary says a node's memory, in order: the start (`None`), then after
    /// which run (1-based) — the end of the first quarter and of the first half when the
    /// soak is long enough, and the last run — each with its words.
    fn marks(&self) -> Vec<(String, Option<usize>)> {
        let mut marks = vec![("the soak's start".to_string(), None)];
        if let Some((from, second, _)) = self.halves() {
            for run in [from - 1, second - 1] {
                marks.push((format!("after run {run}"), Some(run)));
            }
        }
        if !self.after.is_empty() {
            marks.push(("its end".to_string(), Some(self.after.len())));
        }
        marks
    }

    /// The words of [`Readings::marks`], the same for every node.
    pub(super) fn mark_words(&self) -> Vec<String> {
        self.marks().into_iter().map(|(words, _)| words).collect()
    }

    /// `node`'s trend.
    pub(super) fn trend(&self, node: &str) -> Trend {
        let at = |m: &Memory| m.0.get(node).copied().flatten();
        let after = |run: usize| self.after.get(run - 1).and_then(at);
        let marks = self
            .marks()
            .into_iter()
            .map(|(words, run)| (words, run.map_or_else(|| at(&self.start), after)))
            .collect();
        let medians = self.halves().and_then(|(from, second, last)| {
            let median = |runs: std::ops::Range<usize>| median(runs.filter_map(after).collect());
            median(from..second).zip(median(second..last + 1))
        });
        Trend { marks, medians }
    }
}

/// The middle of `values` (the upper one of an even count), `None` for none.
fn median(mut values: Vec<u64>) -> Option<u64> {
    values.sort_unstable();
    values.get(values.len() / 2).copied()
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

    fn readings(start: u64, after: &[u64]) -> Readings {
        let one = |kib: u64| Memory([("n".to_string(), Some(kib))].into_iter().collect());
        Readings {
            start: one(start),
            after: after.iter().map(|k| one(*k)).collect(),
        }
    }

    #[test]
    fn a_node_that_fills_its_stores_and_levels_off_is_flat_one_that_grows_on_is_not() {
        // 8 runs: the first quarter (runs 1-2) fills; halves runs 3-5 and 6-8
        let filled = readings(18, &[25, 30, 33, 34, 33, 34, 35, 34]);
        let t = filled.trend("n");
        assert_eq!(
            t.marks,
            vec![
                ("the soak's start".to_string(), Some(18)),
                ("after run 2".to_string(), Some(30)),
                ("after run 5".to_string(), Some(33)),
                ("its end".to_string(), Some(34)),
            ]
        );
        assert_eq!(t.medians, Some((33, 34)));
        assert!(t.flat());
        // one reading high after a restart does not move a median
        assert!(readings(18, &[25, 30, 33, 34, 33, 34, 60, 34])
            .trend("n")
            .flat());
        // a leak: 2 a run
        let leaking = readings(18, &[20, 22, 24, 26, 28, 30, 32, 34]).trend("n");
        assert_eq!(leaking.medians, Some((26, 32)));
        assert!(!leaking.flat());
        // too short to compare: start and end only, flat
        let short = readings(18, &[25, 30]).trend("n");
        assert_eq!(short.marks.len(), 2);
        assert!(short.medians.is_none() && short.flat());
        // a node never read
        assert_eq!(filled.trend("other").medians, None);
    }
}

//! The command declines transparent huge pages, so a node's resident memory is what it
//! uses. mimalloc asks the kernel for huge pages on its arena (`madvise(MADV_HUGEPAGE)`,
//! honoured where `/sys/kernel/mm/transparent_hugepage/enabled` is `madvise`, as on
//! Debian): a page touched anywhere in a 2 MiB span then holds the whole span. Measured on
//! the thesis layout (`marie up missions/clusters/thesis.toml`, `AnonHugePages` of
//! `/proc/PID/smaps_rollup`): 14–16 MiB of a fresh node's 30–34 MiB were huge pages, 28–32
//! of a node's 62–66 MiB restarted on the journals of 24 docking runs; without them the
//! same nodes held 17.5–19.5 and 33–35.5 MiB. So RSS doubled, and moved in 2 MiB steps
//! with what the kernel collapsed or split — a leak could not be told from it (issue 43's
//! "node memory flat"). A docking run at `--speed max` was no slower without them
//! (`farm-bench`, 5 interleaved runs: wall time 0.91× the median with them).
//!
//! `PR_SET_THP_DISABLE` is the process's own switch: checked when a page is faulted in, so
//! it holds for the arena mimalloc reserved before `main`, and inherited by the node
//! processes `marie up` starts. A user who wants huge pages back sets mimalloc's own
//! `MIMALLOC_ALLOW_THP=1` (any value): the command then leaves the switch alone.

/// Decline transparent huge pages for this process and the processes it starts, unless
/// `MIMALLOC_ALLOW_THP` is set. Call first in `main`. A kernel without the switch (not
/// Linux, or older than 3.15) changes nothing: the call's failure is only logged.
pub(crate) fn decline() {
    if std::env::var_os("MIMALLOC_ALLOW_THP").is_some() {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        // SAFETY: prctl with PR_SET_THP_DISABLE takes plain integers and touches only this
        // process's memory-management flags.
        let r = unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) };
        if r != 0 {
            tracing::debug!(error = %std::io::Error::last_os_error(), "huge pages not declined");
        }
    }
}

#[cfg(test)]
mod tests {
    #[cfg(target_os = "linux")]
    #[test]
    fn after_declining_the_process_says_huge_pages_are_off() {
        if std::env::var_os("MIMALLOC_ALLOW_THP").is_some() {
            return;
        }
        super::decline();
        // SAFETY: PR_GET_THP_DISABLE takes no pointers
        let off = unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) };
        assert_eq!(off, 1);
    }
}

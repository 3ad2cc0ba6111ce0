//! A long-running node gives freed memory back to the system now and then. A node started
//! again on its journals replays them on short-lived worker threads; what those threads
//! allocated and freed stays resident in their allocator's heaps after they exit
//! (mimalloc keeps an exited thread's heap "abandoned" until another thread reclaims it;
//! glibc keeps freed blocks in its arenas). Measured with `scripts/restart-memory 24`
//! (mimalloc with transparent huge pages, before this and before `huge_pages.rs`): nodes restarted on the journals of 24 docking runs came back
//! 2–16 MiB above the same nodes that ran on (features 64.7–70.9 against 54.6 MiB), and
//! with glibc `malloc_trim(0)` gave 9–10 MiB back. So once a while, and soon after the
//! start, the node asks its allocator to return what is free: `mi_collect(true)` reclaims
//! the abandoned heaps and releases their empty pages; glibc's `malloc_trim(0)` its
//! arenas' free memory. Only in `marie node`; its cost per call is not measured (it runs
//! on a blocking thread, once a minute).

use std::time::Duration;

/// The first give-back after the start (at the thesis' sizes the replay's threads have
/// exited by about then: RSS fell some 10 s after a restart; later ones run every minute).
const FIRST: Duration = Duration::from_secs(10);
/// Then every so often.
const EVERY: Duration = Duration::from_secs(60);

#[cfg(feature = "mimalloc")]
extern "C" {
    /// mimalloc's own (in the library the `mimalloc` crate links): free what can be freed,
    /// with `force` also the heaps of exited threads, and return it to the system.
    fn mi_collect(force: bool);
}

/// Return the memory the allocator holds free to the system, now.
pub(crate) fn give_back() {
    // SAFETY: both calls only walk the allocator's own free lists; they are thread-safe
    // and take no pointers.
    #[cfg(feature = "mimalloc")]
    unsafe {
        mi_collect(true);
    }
    #[cfg(not(feature = "mimalloc"))]
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Give memory back [`FIRST`] after now, then every [`EVERY`], for as long as the runtime
/// runs.
pub(crate) fn spawn() {
    tokio::spawn(async {
        tokio::time::sleep(FIRST).await;
        let mut every = tokio::time::interval(EVERY);
        loop {
            every.tick().await;
            tokio::task::spawn_blocking(give_back);
        }
    });
}

#[cfg(test)]
mod tests {
    #[test]
    fn giving_memory_back_leaves_what_is_in_use_alone() {
        let kept: Vec<Vec<u8>> = (0..1000).map(|i| vec![i as u8; 4096]).collect();
        drop((0..1000).map(|_| vec![0u8; 8192]).collect::<Vec<_>>());
        super::give_back();
        assert!(kept
            .iter()
            .enumerate()
            .all(|(i, v)| v.iter().all(|b| *b == i as u8)));
    }
}

//! The check of the datamanagers at a run's end: what the run's producers were told was
//! stored, looked up in what each datamanager's leader holds once the mission is over
//! ([`marie_dm::Ledger`] compares; this gathers and asks).
//!
//! While the run lasts, the acknowledgements come as events: this node's own on its bus
//! (a tap: none missed), every other node's through the relay ([`crate::relay::watch`]) —
//! each node publishes what its operations' stores got acknowledged (`dm_acked`,
//! `dm_deleted`). At the end, once they stop coming, each datamanager the run heard of or
//! that is published is checked, and the result is published as `dm_checked`, which the
//! run's report folds (`dm_checks`, `acknowledged_lost`).

use crate::relay;
use marie_dm::Ledger;
use marie_vocabulary::events::{EventBus, EventKind, Tap};
use marie_vocabulary::registry::{self, ModuleKind};
use std::collections::BTreeSet;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::task::JoinHandle;
use tokio::time::Instant;

/// How long a datamanager's leader has to answer the check: one being failed over as the
/// run ends is elected within a few seconds (the failure detector's 1.2 s deadline, then
/// an election); none comes when every node of its replicas is gone, and the run's end
/// should not wait long for that.
const WITHIN: Duration = Duration::from_secs(15);
/// The acknowledgements on their way from other nodes have all come once none came for
/// this long (the operations are suspended: they store nothing more)…
const QUIET: Duration = Duration::from_millis(500);
/// … or, at most, after this long.
const SETTLE: Duration = Duration::from_secs(5);
/// Events of other nodes the relay's watch holds before the checker takes them.
const CAPACITY: usize = 4096;

/// The acknowledgements of a run being gathered ([`RunAudit::start`]) and checked at its end
/// ([`RunAudit::finish`]).
pub(super) struct RunAudit {
    ledger: Arc<Mutex<Ledger>>,
    _tap: Tap,
    /// The task that takes the other nodes' acknowledgements from the relay (aborted when
    /// the audit is dropped: a run that failed to start leaves no watcher behind).
    relay: Option<JoinHandle<()>>,
    /// When the relay last brought an acknowledgement.
    heard: Arc<Mutex<Option<Instant>>>,
}

impl Drop for RunAudit {
    fn drop(&mut self) {
        if let Some(relay) = self.relay.take() {
            relay.abort();
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl RunAudit {
    /// Gather the acknowledgements published on `bus` and by every other node from now on.
    pub(super) async fn start(bus: &EventBus) -> RunAudit {
        let ledger = Arc::new(Mutex::new(Ledger::new()));
        let heard = Arc::new(Mutex::new(None));
        let tap = {
            let ledger = ledger.clone();
            bus.tap(move |event| {
                lock(&ledger).note(&event.kind);
            })
        };
        let relay = match relay::watch(CAPACITY).await {
            Ok(mut watch) => {
                let (ledger, heard) = (ledger.clone(), heard.clone());
                Some(tokio::spawn(async move {
                    while let Some(event) = watch.recv().await {
                        if lock(&ledger).note(&event.kind) {
                            *lock(&heard) = Some(Instant::now());
                        }
                    }
                }))
            }
            Err(e) => {
                tracing::warn!("the check of the datamanagers hears this node's stores only: {e}");
                None
            }
        };
        RunAudit {
            ledger,
            _tap: tap,
            relay,
            heard,
        }
    }

    /// Once the other nodes' acknowledgements have come, check every datamanager the run
    /// heard of or that is published, and publish each check on `bus` (`dm_checked`).
    pub(super) async fn finish(mut self, bus: &EventBus) {
        let (ledger, heard) = (self.ledger.clone(), self.heard.clone());
        if let Some(relay) = self.relay.take() {
            let remote = registry::list()
                .iter()
                .any(|i| !i.actor.get_id().is_local());
            if remote || lock(&heard).is_some() {
                let start = Instant::now();
                loop {
                    let last = lock(&heard).unwrap_or(start);
                    let now = Instant::now();
                    if now.duration_since(last) >= QUIET || now.duration_since(start) >= SETTLE {
                        break;
                    }
                    tokio::time::sleep(QUIET.saturating_sub(now.duration_since(last))).await;
                }
            }
            relay.abort();
        }
        // nothing more to hear
        drop(self);
        let ledger = std::mem::take(&mut *lock(&ledger));
        let mut names: BTreeSet<String> = ledger.datamanagers().into_iter().collect();
        names.extend(
            registry::list_of(ModuleKind::Datamanager)
                .into_iter()
                .map(|i| i.name),
        );
        // all at once: each may wait up to WITHIN for a leader (none comes when every
        // node of its replicas is gone), and a run's end should not wait that long per
        // datamanager; told in name order
        let ledger = Arc::new(ledger);
        let checks: Vec<_> = names
            .into_iter()
            .map(|dm| {
                let ledger = ledger.clone();
                tokio::spawn(async move { ledger.check(&dm, WITHIN).await })
            })
            .collect();
        for check in checks {
            let check = match check.await {
                Ok(check) => check,
                // a check that panicked: its panic goes on (a lost count must not pass
                // for a clean one)
                Err(e) if e.is_panic() => std::panic::resume_unwind(e.into_panic()),
                Err(_) => continue, // not cancelled: nothing aborts these tasks
            };
            if check.lost > 0 {
                tracing::warn!(
                    dm = %check.dm,
                    lost = check.lost,
                    acknowledged = check.acknowledged,
                    "acknowledged records lost"
                );
            }
            bus.publish(EventKind::DmChecked(check));
        }
    }
}

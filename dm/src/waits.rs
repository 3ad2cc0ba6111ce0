//! Pending `SelectWait`s of a datamanager.
//!
//! Waiters are filed by the class their query names (or under "any class"), so a store only
//! looks at the waiters that could match it. Each has a timer task that is aborted when the
//! waiter leaves the list, answered or not.

use super::page::Page;
use super::query::Query;
use super::record::Record;
use super::store::Store;
use ractor::RpcReplyPort;
use std::collections::HashMap;
use tokio::task::JoinHandle;

/// Aborts its task when dropped.
pub(crate) struct TimerGuard(pub(crate) JoinHandle<()>);

impl Drop for TimerGuard {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// One pending wait.
pub(crate) struct Waiter {
    pub(crate) id: u64,
    pub(crate) query: Query,
    pub(crate) reply: WaitReply,
    pub(crate) _timer: Option<TimerGuard>,
}

/// Where a wait's answer goes: whole (a caller in the datamanager's process), or its first
/// page (a caller on another node, which asks for the rest: see `page`).
pub(crate) enum WaitReply {
    Whole(RpcReplyPort<Vec<Record>>),
    Paged {
        reply: RpcReplyPort<Page>,
        max_bytes: usize,
    },
}

impl WaitReply {
    /// Answer with what matches `query` in `store` now; how many records went.
    pub(crate) fn answer(self, store: &Store, query: &Query) -> usize {
        match self {
            WaitReply::Whole(reply) => {
                let answer = store.select(query);
                let n = answer.len();
                let _ = reply.send(answer);
                n
            }
            WaitReply::Paged { reply, max_bytes } => {
                let page = store.select_page(query, max_bytes);
                let n = page.records.len();
                let _ = reply.send(page);
                n
            }
        }
    }

    /// Answer with nothing: the wait passed.
    pub(crate) fn nothing(self) {
        match self {
            WaitReply::Whole(reply) => {
                let _ = reply.send(Vec::new());
            }
            WaitReply::Paged { reply, .. } => {
                let _ = reply.send(Page::default());
            }
        }
    }

    /// Whether the caller has gone.
    pub(crate) fn is_closed(&self) -> bool {
        match self {
            WaitReply::Whole(reply) => reply.is_closed(),
            WaitReply::Paged { reply, .. } => reply.is_closed(),
        }
    }
}

/// The pending waits of one datamanager.
#[derive(Default)]
pub(crate) struct Waits {
    next_id: u64,
    by_class: HashMap<String, Vec<Waiter>>,
    any_class: Vec<Waiter>,
    /// waiter id → the class it is filed under
    filed: HashMap<u64, Option<String>>,
    /// sweep closed ports when the count reaches this
    sweep_at: usize,
}

impl Waits {
    const MIN_SWEEP: usize = 64;

    pub(crate) fn len(&self) -> usize {
        self.filed.len()
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.filed.is_empty()
    }

    /// A fresh waiter id.
    pub(crate) fn next_id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id
    }

    /// File a waiter. Now and then, drop the waiters whose caller has gone (their port is
    /// closed), so abandoned waits with long timeouts cannot pile up.
    pub(crate) fn add(&mut self, waiter: Waiter) {
        if self.len() >= self.sweep_at.max(Self::MIN_SWEEP) {
            self.sweep_closed();
            self.sweep_at = 2 * self.len();
        }
        let class = waiter.query.class.clone();
        self.filed.insert(waiter.id, class.clone());
        match class {
            Some(c) => self.by_class.entry(c).or_default().push(waiter),
            None => self.any_class.push(waiter),
        }
    }

    /// Take the waiter `id` out of the list (e.g. when its timeout passed).
    pub(crate) fn take(&mut self, id: u64) -> Option<Waiter> {
        let class = self.filed.remove(&id)?;
        let list = match &class {
            Some(c) => self.by_class.get_mut(c)?,
            None => &mut self.any_class,
        };
        let pos = list.iter().position(|w| w.id == id)?;
        let waiter = list.swap_remove(pos);
        if list.is_empty() {
            if let Some(c) = &class {
                self.by_class.remove(c);
            }
        }
        Some(waiter)
    }

    /// Take out every waiter that a new record of `class` satisfies (`satisfied` decides),
    /// dropping on the way those whose caller has gone.
    pub(crate) fn take_satisfied(
        &mut self,
        class: &str,
        mut satisfied: impl FnMut(&Query) -> bool,
    ) -> Vec<Waiter> {
        let mut out = Vec::new();
        let filed = &mut self.filed;
        let mut pick = |list: &mut Vec<Waiter>| {
            let mut i = 0;
            while i < list.len() {
                let w = &list[i];
                if w.reply.is_closed() {
                    filed.remove(&w.id);
                    list.swap_remove(i);
                } else if satisfied(&w.query) {
                    filed.remove(&w.id);
                    out.push(list.swap_remove(i));
                } else {
                    i += 1;
                }
            }
        };
        if let Some(list) = self.by_class.get_mut(class) {
            pick(list);
            if list.is_empty() {
                self.by_class.remove(class);
            }
        }
        pick(&mut self.any_class);
        out
    }

    /// Take out every waiter (their ids stay used: a late `WaitExpired` names none anew).
    pub(crate) fn take_all(&mut self) -> Vec<Waiter> {
        self.filed.clear();
        let mut all = std::mem::take(&mut self.any_class);
        all.extend(self.by_class.drain().flat_map(|(_, list)| list));
        all
    }

    /// Drop every waiter whose caller has gone.
    pub(crate) fn sweep_closed(&mut self) {
        let filed = &mut self.filed;
        let mut keep = |w: &Waiter| {
            let open = !w.reply.is_closed();
            if !open {
                filed.remove(&w.id);
            }
            open
        };
        self.any_class.retain(&mut keep);
        self.by_class.retain(|_, list| {
            list.retain(&mut keep);
            !list.is_empty()
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn waiter(w: &mut Waits, q: Query) -> (u64, ractor::concurrency::OneshotReceiver<Vec<Record>>) {
        let (tx, rx) = ractor::concurrency::oneshot();
        let id = w.next_id();
        w.add(Waiter {
            id,
            query: q,
            reply: WaitReply::Whole(tx.into()),
            _timer: None,
        });
        (id, rx)
    }

    #[test]
    fn filed_by_class() {
        let mut w = Waits::default();
        let (a, _ra) = waiter(&mut w, Query::class("sonar"));
        let (b, _rb) = waiter(&mut w, Query::all());
        let (_c, _rc) = waiter(&mut w, Query::class("map"));
        assert_eq!(w.len(), 3);
        let got: Vec<u64> = w
            .take_satisfied("sonar", |_| true)
            .iter()
            .map(|x| x.id)
            .collect();
        assert_eq!(got.len(), 2);
        assert!(got.contains(&a) && got.contains(&b));
        assert_eq!(w.len(), 1);
        assert!(w.take(a).is_none());
    }

    #[test]
    fn closed_ports_are_dropped() {
        let mut w = Waits::default();
        let (a, ra) = waiter(&mut w, Query::class("sonar"));
        let (b, _rb) = waiter(&mut w, Query::class("sonar"));
        drop(ra);
        let got = w.take_satisfied("sonar", |_| false);
        assert!(got.is_empty());
        assert_eq!(w.len(), 1);
        assert!(w.take(a).is_none());
        assert!(w.take(b).is_some());
        assert!(w.is_empty());
        for _ in 0..200 {
            let (_, rx) = waiter(&mut w, Query::all());
            drop(rx);
        }
        assert!(w.len() <= 2 * Waits::MIN_SWEEP);
    }
}

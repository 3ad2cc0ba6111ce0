//! The watcher: an actor in `pg` that takes the other nodes' numbered events, each
//! forwarder's stream in order and once, and hands them to a bounded [`Watch`].

use super::order::{Admit, Order};
use super::{WatcherMsg, GROUP, KIND, SCOPE};
use marie_vocabulary::events::Event;
use marie_vocabulary::wire::Envelope;
use ractor::{pg, Actor, ActorProcessingErr, ActorRef, SpawnErr};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::sync::mpsc;

/// The events of the other nodes, as they arrive.
pub struct Watch {
    events: mpsc::Receiver<Event>,
    lost: Arc<AtomicU64>,
    actor: Arc<Watcher>,
    /// Leave out the dispatchers' events ([`Watch::without_dispatch`]).
    without_dispatch: bool,
}

impl std::fmt::Debug for Watch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Watch")
            .field("lost", &self.lost())
            .finish_non_exhaustive()
    }
}

impl Watch {
    /// The next event of another node; `None` once the watch stopped.
    pub async fn recv(&mut self) -> Option<Event> {
        loop {
            let event = self.events.recv().await?;
            if !(self.without_dispatch && event.kind.is_dispatch()) {
                return Some(event);
            }
        }
    }

    /// The next event if one is waiting.
    pub fn try_recv(&mut self) -> Option<Event> {
        loop {
            let event = self.events.try_recv().ok()?;
            if !(self.without_dispatch && event.kind.is_dispatch()) {
                return Some(event);
            }
        }
    }

    /// Leave out what dispatchers say of their runs ([`EventKind::is_dispatch`]): for a
    /// member that follows a run dispatched elsewhere, which republishes those on its own
    /// bus (where whoever watches both would see them twice).
    ///
    /// [`EventKind::is_dispatch`]: marie_vocabulary::events::EventKind::is_dispatch
    pub fn without_dispatch(mut self) -> Watch {
        self.without_dispatch = true;
        self
    }

    /// Events lost: dropped because the watch was full or their frame did not decode, or
    /// never to come — a gap in a node's numbers, events its forwarder no longer held
    /// when this watch was in reach again (or fell behind its own bus on).
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }

    /// The watcher's actor number on this node: with the node's name, how another node
    /// knows it ([`reaches`]).
    pub fn pid(&self) -> u64 {
        self.actor.0.get_id().pid()
    }

    #[cfg(test)]
    pub(super) fn actor(&self) -> &ActorRef<WatcherMsg> {
        &self.actor.0
    }
}

/// Wait at most `within` until this node reaches the watcher `pid` of node `node` (the
/// membership of watchers spreads through the cluster a moment after a watch starts, and
/// a node forwards its events only to the watchers it knows): true once it does. A node
/// about to publish what a new watcher must not miss — a run's first events — asks first.
pub async fn reaches(node: &str, pid: u64, within: std::time::Duration) -> bool {
    let known = || {
        pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string())
            .into_iter()
            .any(|c| {
                let id = c.get_id();
                !id.is_local()
                    && id.pid() == pid
                    && marie_vocabulary::registry::node_name_of(&id) == node
            })
    };
    // watched before the first look: a change between the two is not missed
    let Ok(mut changes) = super::scope::Changes::watch().await else {
        return known();
    };
    let wait = async {
        while !known() {
            changes.next().await;
        }
    };
    tokio::time::timeout(within, wait).await.is_ok()
}

/// The watcher's actor, stopped when the last [`Watch`] of it is dropped.
struct Watcher(ActorRef<WatcherMsg>);

impl Drop for Watcher {
    fn drop(&mut self) {
        self.0.stop(None);
    }
}

/// Watch every other node's events, keeping at most `capacity` not yet taken. The
/// watcher is in `pg` when this returns: nodes forward to it from their next event on
/// (once the membership has reached them), and resend what it missed while out of their
/// reach.
pub async fn watch(capacity: usize) -> Result<Watch, SpawnErr> {
    let mut watches = watch_each(capacity, 1).await?;
    Ok(watches.remove(0))
}

/// `n` watches (at least one) of one watcher: each takes every event it takes. Followers
/// that must hold the same events — a run's events file and its MCAP file — share one
/// watcher, as the nodes reach each watcher at a moment of their own and forward to it
/// from their next event on: two watchers would each miss different early events.
pub async fn watch_each(capacity: usize, n: usize) -> Result<Vec<Watch>, SpawnErr> {
    let (outlets, ends): (Vec<Outlet>, Vec<_>) = (0..n.max(1))
        .map(|_| {
            let (tx, events) = mpsc::channel(capacity.max(1));
            let lost = Arc::new(AtomicU64::new(0));
            ((tx, lost.clone()), (events, lost))
        })
        .unzip();
    let (actor, _) = Actor::spawn(
        None,
        WatcherActor,
        WatcherState {
            outlets,
            order: Order::default(),
        },
    )
    .await?;
    let actor = Arc::new(Watcher(actor));
    Ok(ends
        .into_iter()
        .map(|(events, lost)| Watch {
            events,
            lost,
            actor: actor.clone(),
            without_dispatch: false,
        })
        .collect())
}

/// Where a watcher hands an event, and what that watch lost.
type Outlet = (mpsc::Sender<Event>, Arc<AtomicU64>);

struct WatcherActor;

struct WatcherState {
    outlets: Vec<Outlet>,
    order: Order,
}

impl WatcherState {
    /// `n` more events lost to every watch.
    fn lost(&self, n: u64) {
        for (_, lost) in &self.outlets {
            lost.fetch_add(n, Ordering::Relaxed);
        }
    }
}

impl Actor for WatcherActor {
    type Msg = WatcherMsg;
    type State = WatcherState;
    type Arguments = WatcherState;

    async fn pre_start(
        &self,
        myself: ActorRef<WatcherMsg>,
        state: WatcherState,
    ) -> Result<WatcherState, ActorProcessingErr> {
        pg::join_scoped(SCOPE.into(), GROUP.into(), vec![myself.get_cell()]);
        Ok(state)
    }

    async fn handle(
        &self,
        _myself: ActorRef<WatcherMsg>,
        msg: WatcherMsg,
        state: &mut WatcherState,
    ) -> Result<(), ActorProcessingErr> {
        let WatcherMsg::Numbered { stream, seq, frame } = msg;
        match state.order.admit(stream, seq) {
            Admit::Duplicate => return Ok(()),
            Admit::Take { missed } if missed > 0 => {
                tracing::warn!(
                    missed,
                    "events of another node never came: its forwarder no longer held them"
                );
                state.lost(missed);
            }
            Admit::Take { .. } => {}
        }
        let event = Envelope::from_bytes(&frame)
            .map_err(|e| e.to_string())
            .and_then(|env| {
                if env.kind != KIND {
                    return Err(format!("a frame of kind {:?}", env.kind));
                }
                env.payload::<Event>().map_err(|e| e.to_string())
            });
        match event {
            Ok(event) => {
                for (tx, lost) in &state.outlets {
                    if tx.try_send(event.clone()).is_err() {
                        lost.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            Err(e) => {
                state.lost(1);
                tracing::warn!(error = %e, "a forwarded event that does not decode: dropped");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::events::{EventKind, ModuleInfo};
    use marie_vocabulary::registry::ModuleKind;

    fn event(name: &str) -> Event {
        Event {
            at_ms: 7,
            node: "alpha".into(),
            kind: EventKind::Joined(ModuleInfo::new(
                ModuleKind::Operation,
                name,
                1,
                "alpha",
                "0.1",
            )),
        }
    }

    fn frame(e: &Event) -> Vec<u8> {
        Envelope::new(KIND, e).unwrap().to_bytes().unwrap()
    }

    #[tokio::test]
    async fn a_watcher_drops_what_does_not_decode_and_counts_it() {
        let mut watch = watch(8).await.unwrap();
        let first = event("sampler");
        for (seq, frame) in [
            b"garbage".to_vec(),
            Envelope::new("heartbeat", &1u64)
                .unwrap()
                .to_bytes()
                .unwrap(),
            frame(&first),
        ]
        .into_iter()
        .enumerate()
        {
            let seq = seq as u64 + 1;
            let msg = WatcherMsg::Numbered {
                stream: 1,
                seq,
                frame,
            };
            watch.actor().cast(msg).unwrap();
        }
        // the actor handles its messages in order: the two bad frames came first
        assert_eq!(watch.recv().await, Some(first));
        assert_eq!(watch.lost(), 2);
    }

    #[tokio::test]
    async fn watches_of_one_watcher_each_take_every_event_and_it_lives_until_the_last_goes() {
        let mut watches = watch_each(8, 2).await.unwrap();
        let (first, second) = (event("one"), event("two"));
        for (seq, e) in [(1, &first), (2, &second)] {
            let msg = WatcherMsg::Numbered {
                stream: 3,
                seq,
                frame: frame(e),
            };
            watches[0].actor().cast(msg).unwrap();
        }
        assert_eq!(watches[0].pid(), watches[1].pid(), "one watcher");
        let mut b = watches.pop().unwrap();
        let mut a = watches.pop().unwrap();
        assert_eq!(a.recv().await, Some(first.clone()));
        assert_eq!(a.recv().await, Some(second.clone()));
        // one watch gone: the other still has its own events, and the watcher runs on
        let actor = a.actor().clone();
        drop(a);
        assert_eq!(actor.get_status(), ractor::ActorStatus::Running);
        assert_eq!(b.recv().await, Some(first));
        assert_eq!(b.recv().await, Some(second));
        drop(b);
        actor
            .get_cell()
            .wait(Some(std::time::Duration::from_secs(10)))
            .await
            .expect("the watcher stops with its last watch");
    }

    #[tokio::test]
    async fn a_resent_backlog_gives_each_event_once_in_order_and_counts_what_it_lacked() {
        let mut watch = watch(16).await.unwrap();
        let names = ["a", "b", "c", "d", "e", "f"];
        let events: Vec<Event> = names.iter().map(|n| event(n)).collect();
        let send = |seq: u64| {
            let msg = WatcherMsg::Numbered {
                stream: 9,
                seq,
                frame: frame(&events[seq as usize - 1]),
            };
            watch.actor().cast(msg).unwrap();
        };
        // 1 and 2 arrive; 3 is lost with its session; the node's backlog, resent, holds
        // 2 to 4 (1 was pushed out); then 6 (5 fell off its bus)
        for seq in [1, 2, 2, 3, 4, 6] {
            send(seq);
        }
        let mut got = Vec::new();
        for _ in 0..5 {
            got.push(watch.recv().await.unwrap());
        }
        assert_eq!(
            got,
            [&events[0], &events[1], &events[2], &events[3], &events[5]].map(Clone::clone)
        );
        assert_eq!(watch.try_recv(), None);
        assert_eq!(watch.lost(), 1, "5 never came");
    }
}

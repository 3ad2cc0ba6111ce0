//! Heartbeats between nodes: the failure detector ractor_cluster lacks.
//!
//! ractor_cluster notices a peer's death only when its TCP connection errors, so a frozen
//! (`SIGSTOP`) or cut-off node stays "connected" for minutes. Every node runs one heartbeat
//! actor, published in `pg` (scope [`SCOPE`], group [`GROUP`]) so that every peer finds it.
//! Each period it casts a beat — a versioned [`Envelope`] naming the node and the peers it
//! sees — to every remote heartbeat actor; four times a period it asks its [`Detector`]
//! which ready peers have been silent past the deadline: those are declared down — their sessions closed (their modules leave the
//! registry with them), a [`NetEvent::PeerDown`] published — and redialled by the transport
//! with backoff, to rejoin once they answer.
//!
//! A node learns that it was frozen past its peers' deadline from its own ticks (one came
//! more than its own deadline late) or, when those did not show it — its deadline is longer
//! than theirs, or the freeze just passed theirs —, from them: a beat names the peers its
//! sender declared down ([`DownNotice`]), and a node that reads its own name there once its
//! sessions are back tells [`NetEvent::Frozen`] (see [`Detector::told`]).
//!
//! A beat of another protocol version refuses its sender for the transport's life: a
//! [`NetEvent::PeerRefused`] names both versions, its sessions are closed two periods later
//! (time for this node's own beat to tell it the same), and a later session with it is
//! closed as soon as it is authenticated, before its modules reach the registry.

use super::detector::{BeatId, Detector, DownNotice, HeartbeatConfig, Reach};
use super::events::NetEvent;
use super::sessions::{Peer, Sessions};
use marie_vocabulary::run::provenance::this_build;
use marie_vocabulary::run::Build;
use marie_vocabulary::wire::{self, Envelope};
use ractor::{pg, Actor, ActorProcessingErr, ActorRef};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Instant;

/// `pg` scope of the heartbeat actors (apart from the location table's).
pub const SCOPE: &str = "marie-net";
/// `pg` group of the heartbeat actors.
pub const GROUP: &str = "heartbeat";
/// How many times a heartbeat period the peers are judged.
const JUDGES_PER_BEAT: u32 = 4;
/// The envelope kind of a beat.
const KIND: &str = "heartbeat";

/// A beat's payload.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Beat {
    /// The sender's node name.
    node: String,
    /// Beats sent so far by the sender.
    seq: u64,
    /// The addresses of the peers the sender has a ready session with: a receiver that
    /// does not see one dials it, which keeps the cluster a full mesh (ractor_cluster's own
    /// transitive dials would be plain TCP, and duplicated). Absent from the beats of
    /// older builds, which ignore it in ours.
    #[serde(default)]
    sees: Vec<String>,
    /// The sender's life ([`BeatId::life`]; 0 from older builds).
    #[serde(default)]
    life: u64,
    /// The peers the sender declared down and that have not been back long: a receiver
    /// named here learns that it was silent past the sender's deadline, also when it did
    /// not notice it had stopped.
    #[serde(default)]
    down: Vec<DownNotice>,
    /// The sender's marie build ([`this_build`]): a run's provenance names every node's,
    /// and one of another commit (absent from older builds' beats).
    #[serde(default)]
    build: Option<Build>,
}

marie_vocabulary::remote_message! {
    /// Messages of a heartbeat actor.
    pub enum BeatMsg {
        /// A peer's beat: an [`Envelope`] of kind `heartbeat`.
        Beat {
            /// The encoded envelope.
            frame: Vec<u8>,
        },
    }
    local {
        /// Time to judge the peers, and to beat if `beat`.
        Tick {
            /// Beat to every peer too.
            beat: bool,
        },
        /// The builds the ready peers said they run ([`peer_builds`]): answered once every
        /// one has said, or once `within` has passed.
        Builds {
            /// How long the answer may wait for a peer that has not said yet.
            within: std::time::Duration,
            /// Where the answer goes.
            reply: ractor::RpcReplyPort<BTreeMap<String, Option<Build>>>,
        },
        /// Whom this node reaches now: the peers heard from within half the deadline, of
        /// all it ever heard ([`reach`]).
        Reach {
            /// Where the answer goes.
            reply: ractor::RpcReplyPort<Reach>,
        },
    }
}

/// Whom this process's heartbeat actor reaches: the peers heard from within half its
/// deadline — which a node cut off or just woken does not hear (its sessions may look ready
/// a while longer) — of all it ever heard; `None` without one (no transport) or when it
/// does not answer within a second.
pub async fn reach() -> Option<Reach> {
    let cell = pg::get_scoped_local_members(&SCOPE.to_string(), &GROUP.to_string())
        .into_iter()
        .next()?;
    let heartbeat: ActorRef<BeatMsg> = cell.into();
    match heartbeat
        .call(
            |reply| BeatMsg::Reach { reply },
            Some(std::time::Duration::from_secs(1)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(reach)) => Some(reach),
        _ => None,
    }
}

/// The marie builds of the peers this process has a ready session with, by node name
/// (`None`: it has not said within `within` — a peer just joined has not beaten yet, or
/// runs a build that does not say); answered as soon as every peer has said. Empty without
/// a transport or when its heartbeat actor does not answer in time.
pub async fn peer_builds(within: std::time::Duration) -> BTreeMap<String, Option<Build>> {
    let Some(cell) = pg::get_scoped_local_members(&SCOPE.to_string(), &GROUP.to_string())
        .into_iter()
        .next()
    else {
        return BTreeMap::new();
    };
    let heartbeat: ActorRef<BeatMsg> = cell.into();
    match heartbeat
        .call(
            |reply| BeatMsg::Builds { within, reply },
            Some(within + std::time::Duration::from_secs(1)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(builds)) => builds,
        _ => BTreeMap::new(),
    }
}

/// A [`BeatMsg::Builds`] waiting for a peer to name its build.
struct BuildsAsked {
    until: Instant,
    reply: ractor::RpcReplyPort<BTreeMap<String, Option<Build>>>,
}

/// What a heartbeat actor is started with.
pub(crate) struct HeartbeatArgs {
    pub node: String,
    pub config: HeartbeatConfig,
    pub sessions: Sessions,
    /// Where the addresses of peers that peers see go, to be dialed.
    pub learned: tokio::sync::mpsc::UnboundedSender<std::net::SocketAddr>,
    /// The protocol version it claims (another than [`PROTOCOL_VERSION`] only to test
    /// refusal).
    pub protocol: u16,
}

pub(crate) struct Heartbeat;

pub(crate) struct State {
    args: HeartbeatArgs,
    detector: Detector,
    ticker: tokio::task::JoinHandle<()>,
    greeter: tokio::task::JoinHandle<()>,
    /// The build each peer's latest beat named.
    builds: BTreeMap<String, Build>,
    /// Asks for the peers' builds waiting for one to say it.
    builds_asked: Vec<BuildsAsked>,
}

impl Drop for State {
    fn drop(&mut self) {
        self.ticker.abort();
        self.greeter.abort();
    }
}

impl Actor for Heartbeat {
    type Msg = BeatMsg;
    type State = State;
    type Arguments = HeartbeatArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<BeatMsg>,
        args: HeartbeatArgs,
    ) -> Result<State, ActorProcessingErr> {
        args.config.validate()?;
        pg::join_scoped(SCOPE.into(), GROUP.into(), vec![myself.get_cell()]);
        let period = args.config.period;
        // a new peer hears at once whom this node sees: the mesh closes without waiting
        // a period
        let (_, mut news) = args.sessions.listen();
        let me = myself.clone();
        let greeter = tokio::spawn(async move {
            loop {
                match news.recv().await {
                    Ok(NetEvent::PeerUp { .. }) => {
                        if me.cast(BeatMsg::Tick { beat: true }).is_err() {
                            return;
                        }
                    }
                    Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                    Err(tokio::sync::broadcast::error::RecvError::Closed) => return,
                }
            }
        });
        let me = myself.clone();
        // wall-clock ticks: heartbeats stay in real time whatever the cluster's speed. Peers
        // are judged JUDGES_PER_BEAT times a period, so one is declared down at most a
        // fraction of a period after its deadline, not up to a whole period after.
        let judge_every = period / JUDGES_PER_BEAT;
        let ticker = tokio::spawn(async move {
            let mut every = tokio::time::interval(judge_every);
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            for n in 0u64.. {
                every.tick().await;
                let beat = n % u64::from(JUDGES_PER_BEAT) == 0;
                if me.cast(BeatMsg::Tick { beat }).is_err() {
                    return;
                }
            }
        });
        Ok(State {
            detector: Detector::new(args.config, draw_life()),
            args,
            ticker,
            greeter,
            builds: BTreeMap::new(),
            builds_asked: Vec::new(),
        })
    }

    async fn handle(
        &self,
        _myself: ActorRef<BeatMsg>,
        msg: BeatMsg,
        state: &mut State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            BeatMsg::Tick { beat } => {
                state.tick(beat);
                state.answer_builds();
            }
            BeatMsg::Beat { frame } => {
                state.received(&frame);
                state.answer_builds();
            }
            BeatMsg::Builds { within, reply } => {
                state.builds_asked.push(BuildsAsked {
                    until: Instant::now() + within,
                    reply,
                });
                state.answer_builds();
            }
            BeatMsg::Reach { reply } => {
                let within = state.args.config.deadline / 2;
                let _ = reply.send(state.detector.reach(within, Instant::now()));
            }
        }
        Ok(())
    }
}

impl State {
    /// Answer each ask for the peers' builds that can be: every ready peer has named its
    /// build, or the ask's time is up (then the silent ones are `None`).
    fn answer_builds(&mut self) {
        if self.builds_asked.is_empty() {
            return;
        }
        let builds: BTreeMap<String, Option<Build>> = self
            .args
            .sessions
            .peers()
            .into_iter()
            .map(|p| {
                let build = self.builds.get(&p.name).cloned();
                (p.name, build)
            })
            .collect();
        let all_said = builds.values().all(Option::is_some);
        let now = Instant::now();
        let (due, waiting) = std::mem::take(&mut self.builds_asked)
            .into_iter()
            .partition(|a| all_said || a.until <= now);
        self.builds_asked = waiting;
        for asked in due {
            let _ = asked.reply.send(builds.clone());
        }
    }

    /// Cast a beat naming the `ready` peers to every remote heartbeat actor.
    fn beat(&mut self, ready: &[Peer]) {
        let beat = Beat {
            node: self.args.node.clone(),
            seq: self.detector.beat(),
            sees: ready.iter().map(|p| p.address.clone()).collect(),
            life: self.detector.life(),
            down: self.detector.notices(),
            build: Some(this_build()),
        };
        let frame = Envelope::new(KIND, &beat)
            .map(|mut env| {
                env.version = self.args.protocol;
                env
            })
            .and_then(|env| env.to_bytes());
        match frame {
            Ok(frame) => {
                for cell in pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string()) {
                    if cell.get_id().is_local() {
                        continue;
                    }
                    let to: ActorRef<BeatMsg> = cell.into();
                    let _ = to.cast(BeatMsg::Beat {
                        frame: frame.clone(),
                    });
                }
            }
            Err(e) => tracing::error!(error = %e, "cannot encode a heartbeat"),
        }
    }

    /// Beat to every remote heartbeat actor if `beat`, then judge the ready peers.
    fn tick(&mut self, beat: bool) {
        let ready = self.args.sessions.peers();
        if beat {
            self.beat(&ready);
        }
        let ready: Vec<String> = ready.into_iter().map(|p| p.name).collect();
        let overdue = self.detector.tick(&ready, Instant::now());
        if let Some(silent) = self.detector.take_freeze() {
            self.frozen(silent);
        }
        for (peer, silent) in overdue {
            // recorded and told before its sessions close: whoever sees the peer's modules
            // leave can tell why (a dispatcher blames the node)
            marie_vocabulary::registry::declare_down(&peer);
            let event = NetEvent::PeerDown {
                peer: peer.clone(),
                silent,
            };
            tracing::warn!(node = %self.args.node, "{event}");
            self.args.sessions.tell(event);
            self.args
                .sessions
                .close(&peer, "declared down: no heartbeat");
        }
    }

    /// This node was frozen `silent` past its peers' deadline (found by its own ticks, or
    /// told by a peer): tell it, so that the node restarts its operations.
    fn frozen(&self, silent: std::time::Duration) {
        let event = NetEvent::Frozen { silent };
        tracing::warn!(node = %self.args.node, "{event}");
        self.args.sessions.tell(event);
    }

    /// A beat arrived: note its sender's life, or refuse a sender of another version.
    fn received(&mut self, frame: &[u8]) {
        let env = match wire::decode::<Envelope>(frame) {
            Ok(env) if env.kind == KIND => env,
            Ok(env) => {
                tracing::warn!(kind = %env.kind, "a heartbeat actor got a frame of another kind: dropped");
                return;
            }
            Err(e) => {
                tracing::warn!(error = %e, len = frame.len(), "a heartbeat that does not decode: dropped");
                return;
            }
        };
        // the beat's two fields are read whatever the version, to name who is refused
        let beat = match env.payload::<Beat>() {
            Ok(b) => b,
            Err(e) => {
                tracing::warn!(error = %e, "a heartbeat whose payload does not decode: dropped");
                return;
            }
        };
        if env.version != self.args.protocol {
            if self.args.sessions.refuse(
                &beat.node,
                "refused: another protocol version",
                self.args.config.period * 2,
            ) {
                let event = NetEvent::PeerRefused {
                    peer: beat.node.clone(),
                    theirs: env.version,
                    ours: self.args.protocol,
                };
                tracing::error!(node = %self.args.node, "{event}");
                self.args.sessions.tell(event);
            }
            return;
        }
        let id = BeatId {
            life: beat.life,
            seq: beat.seq,
        };
        self.detector.heard(&beat.node, id, Instant::now());
        if let Some(build) = &beat.build {
            if self.builds.get(&beat.node) != Some(build) {
                self.builds.insert(beat.node.clone(), build.clone());
            }
        }
        // the sender declared this node down: if this node did not notice it had stopped
        // (its own deadline is longer than the sender's, or its freeze was just past it),
        // it learns it here
        for notice in beat.down.iter().filter(|n| n.node == self.args.node) {
            if let Some(silent) = self.detector.told(&beat.node, notice) {
                tracing::info!(node = %self.args.node, peer = %beat.node, "told by a peer that it was declared down");
                self.frozen(silent);
            }
        }
        // the dialer keeps what this node does not see yet
        for address in beat.sees {
            match address.parse() {
                Ok(addr) => {
                    let _ = self.args.learned.send(addr);
                }
                Err(_) => tracing::debug!(%address, "a peer's peer address does not parse"),
            }
        }
    }
}

/// A life for this process's heartbeat ([`BeatId::life`]): random, never 0.
fn draw_life() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    if let Ok(t) = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        h.write_u128(t.as_nanos());
    }
    h.finish().max(1)
}

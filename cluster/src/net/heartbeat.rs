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
//! A beat names the protocol versions its sender speaks (a beat of a build before ranges
//! names none: its envelope's version is its range). The receiver agrees with it on the
//! highest version both speak, kept in the session table (`Sessions::agreed`) and carried
//! by every beat for that peer — a beat for a peer not heard yet carries this node's oldest
//! version, which a node of the build before ranges (one exact version) reads. A sender
//! whose range does not meet this node's is refused for the transport's life: a
//! [`NetEvent::PeerRefused`] names both ranges and both builds, its sessions are closed two
//! periods later (time for this node's own beat to tell it the same), and a later session
//! with it is closed as soon as it is authenticated, before its modules reach the registry.

use super::detector::{BeatId, Detector, DownNotice, HeartbeatConfig, Reach};
use super::events::NetEvent;
use super::sessions::{Peer, Sessions};
use marie_vocabulary::run::provenance::this_build;
use marie_vocabulary::run::Build;
use marie_vocabulary::wire::{self, Envelope, ProtocolRange};
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
    /// The protocol versions the sender speaks; absent from the beats of builds before
    /// ranges, which speak their envelope's version alone.
    #[serde(default)]
    speaks: Option<ProtocolRange>,
}

/// What a peer's beats said: its build and protocol range, and the version agreed with it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PeerSaid {
    /// Its marie build; `None` from a build that does not say.
    pub build: Option<Build>,
    /// The protocol versions it speaks.
    pub speaks: ProtocolRange,
    /// The version this node and it agreed on: the highest both speak.
    pub agreed: u16,
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
        /// What the ready peers said of their builds and protocols ([`peers_said`]):
        /// answered once every one has named its build, or once `within` has passed.
        Said {
            /// How long the answer may wait for a peer that has not said yet.
            within: std::time::Duration,
            /// Where the answer goes.
            reply: ractor::RpcReplyPort<BTreeMap<String, Option<PeerSaid>>>,
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
    peers_said(within)
        .await
        .into_iter()
        .map(|(peer, said)| (peer, said.and_then(|s| s.build)))
        .collect()
}

/// What the peers this process has a ready session with said in their beats — build,
/// protocol range, and the version agreed with each — by node name (`None`: not heard
/// within `within`); answered as soon as every peer has named its build. Empty without a
/// transport or when its heartbeat actor does not answer in time.
pub async fn peers_said(within: std::time::Duration) -> BTreeMap<String, Option<PeerSaid>> {
    let Some(cell) = pg::get_scoped_local_members(&SCOPE.to_string(), &GROUP.to_string())
        .into_iter()
        .next()
    else {
        return BTreeMap::new();
    };
    let heartbeat: ActorRef<BeatMsg> = cell.into();
    match heartbeat
        .call(
            |reply| BeatMsg::Said { within, reply },
            Some(within + std::time::Duration::from_secs(1)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(builds)) => builds,
        _ => BTreeMap::new(),
    }
}

/// A [`BeatMsg::Said`] waiting for a peer to name its build.
struct BuildsAsked {
    until: Instant,
    reply: ractor::RpcReplyPort<BTreeMap<String, Option<PeerSaid>>>,
}

/// What a heartbeat actor is started with.
pub(crate) struct HeartbeatArgs {
    pub node: String,
    pub config: HeartbeatConfig,
    pub sessions: Sessions,
    /// Where the addresses of peers that peers see go, to be dialed.
    pub learned: tokio::sync::mpsc::UnboundedSender<std::net::SocketAddr>,
    /// The protocol versions it claims to speak (another range than this build's only to
    /// test agreement and refusal).
    pub protocol: ProtocolRange,
}

pub(crate) struct Heartbeat;

pub(crate) struct State {
    args: HeartbeatArgs,
    detector: Detector,
    ticker: tokio::task::JoinHandle<()>,
    greeter: tokio::task::JoinHandle<()>,
    /// What each peer's latest beat said.
    said: BTreeMap<String, PeerSaid>,
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
            said: BTreeMap::new(),
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
            BeatMsg::Said { within, reply } => {
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
        let builds: BTreeMap<String, Option<PeerSaid>> = self
            .args
            .sessions
            .peers()
            .into_iter()
            .map(|p| {
                let said = self.said.get(&p.name).cloned();
                (p.name, said)
            })
            .collect();
        let all_said = builds
            .values()
            .all(|s| s.as_ref().is_some_and(|s| s.build.is_some()));
        let now = Instant::now();
        let (due, waiting) = std::mem::take(&mut self.builds_asked)
            .into_iter()
            .partition(|a| all_said || a.until <= now);
        self.builds_asked = waiting;
        for asked in due {
            let _ = asked.reply.send(builds.clone());
        }
    }

    /// Cast a beat naming the `ready` peers to every remote heartbeat actor, each at the
    /// protocol version agreed with its node (this node's oldest before its first beat).
    fn beat(&mut self, ready: &[Peer]) {
        let beat = Beat {
            node: self.args.node.clone(),
            seq: self.detector.beat(),
            sees: ready.iter().map(|p| p.address.clone()).collect(),
            life: self.detector.life(),
            down: self.detector.notices(),
            build: Some(this_build()),
            speaks: Some(self.args.protocol),
        };
        // encoded once per version: the peers of one version share the frame
        let mut frames: BTreeMap<u16, Option<Vec<u8>>> = BTreeMap::new();
        for cell in pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string()) {
            let id = cell.get_id();
            if id.is_local() {
                continue;
            }
            let version = self.version_for(id.node());
            let frame = frames.entry(version).or_insert_with(|| {
                Envelope::at(version, KIND, &beat)
                    .and_then(|env| env.to_bytes())
                    .inspect_err(|e| tracing::error!(error = %e, "cannot encode a heartbeat"))
                    .ok()
            });
            if let Some(frame) = frame {
                let to: ActorRef<BeatMsg> = cell.into();
                let _ = to.cast(BeatMsg::Beat {
                    frame: frame.clone(),
                });
            }
        }
    }

    /// The protocol version of frames for the node behind session `session`: the one
    /// agreed with it, or this node's oldest before its first beat — which a peer of the
    /// build before ranges (one exact version) reads when it is that one, and a peer of a
    /// newer build judges by the range the beat names.
    fn version_for(&self, session: u64) -> u16 {
        self.args
            .sessions
            .name_of(session)
            .and_then(|name| self.args.sessions.agreed(&name))
            .unwrap_or(self.args.protocol.oldest)
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
        let Some(said) = self.agree(env.version, &beat) else {
            return;
        };
        self.args.sessions.set_agreed(&beat.node, Some(said.agreed));
        if self.said.get(&beat.node) != Some(&said) {
            tracing::debug!(node = %self.args.node, peer = %beat.node, agreed = said.agreed, speaks = %said.speaks, "protocol agreed");
            self.said.insert(beat.node.clone(), said);
        }
        let id = BeatId {
            life: beat.life,
            seq: beat.seq,
        };
        self.detector.heard(&beat.node, id, Instant::now());
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

impl State {
    /// Agree with the sender of `beat` (in an envelope of `version`) on the highest version
    /// both speak; refuse it when their ranges do not meet (`None`).
    fn agree(&mut self, version: u16, beat: &Beat) -> Option<PeerSaid> {
        let theirs = beat.speaks.unwrap_or(ProtocolRange::single(version));
        if let Some(agreed) = self.args.protocol.agree(&theirs) {
            return Some(PeerSaid {
                build: beat.build.clone(),
                speaks: theirs,
                agreed,
            });
        }
        self.args.sessions.set_agreed(&beat.node, None);
        self.said.remove(&beat.node);
        if self.args.sessions.refuse(
            &beat.node,
            "refused: no common protocol version",
            self.args.config.period * 2,
        ) {
            let event = NetEvent::PeerRefused {
                peer: beat.node.clone(),
                theirs,
                ours: self.args.protocol,
                their_build: beat.build.clone(),
                our_build: this_build(),
            };
            tracing::error!(node = %self.args.node, "{event}");
            self.args.sessions.tell(event);
        }
        None
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A beat as the build before ranges encodes it: no `speaks`.
    #[derive(Serialize)]
    struct BeatBeforeRanges {
        node: String,
        seq: u64,
        sees: Vec<String>,
        life: u64,
        down: Vec<DownNotice>,
        build: Option<Build>,
    }

    #[test]
    fn a_beat_of_the_build_before_ranges_speaks_its_envelopes_version_alone() {
        let old = BeatBeforeRanges {
            node: "old".into(),
            seq: 3,
            sees: vec![],
            life: 9,
            down: vec![],
            build: Some(Build::new("0.1.0", Some("ab"), Some(false))),
        };
        let frame = Envelope::at(2, KIND, &old).unwrap().to_bytes().unwrap();
        let env: Envelope = wire::decode(&frame).unwrap();
        let beat: Beat = env.payload().unwrap();
        assert_eq!((beat.node.as_str(), beat.speaks), ("old", None));
        let theirs = beat.speaks.unwrap_or(ProtocolRange::single(env.version));
        assert_eq!(ProtocolRange::new(2, 3).unwrap().agree(&theirs), Some(2));
        assert_eq!(ProtocolRange::single(3).agree(&theirs), None);
    }

    #[test]
    fn a_beat_with_a_range_is_read_by_the_build_before_ranges() {
        // what the build before ranges decodes: today's fields, `speaks` ignored
        #[derive(Deserialize)]
        struct Old {
            node: String,
            seq: u64,
        }
        let beat = Beat {
            node: "new".into(),
            seq: 5,
            sees: vec![],
            life: 1,
            down: vec![],
            build: None,
            speaks: Some(ProtocolRange::new(2, 3).unwrap()),
        };
        let old: Old = wire::decode(&wire::encode(&beat).unwrap()).unwrap();
        assert_eq!((old.node.as_str(), old.seq), ("new", 5));
    }

    #[test]
    fn a_refusal_names_both_ranges_both_builds_and_what_to_do() {
        let event = NetEvent::PeerRefused {
            peer: "far".into(),
            theirs: ProtocolRange::single(4),
            ours: ProtocolRange::new(2, 3).unwrap(),
            their_build: Some(Build::new("0.2.0", Some("beef"), Some(false))),
            our_build: Build::new("0.1.0", Some("cafe"), Some(false)),
        };
        let text = event.to_string();
        for said in [
            "refused far: it speaks protocol version 4 (build 0.2.0 (commit beef))",
            "this node speaks protocol versions 2..=3 (build 0.1.0 (commit cafe))",
            super::super::events::UPGRADE_ADVICE,
        ] {
            assert!(text.contains(said), "{said:?} not in {text}");
        }
    }
}

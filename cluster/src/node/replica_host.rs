//! The node's replica host ([`crate::replicas`]): starts a replica of a datamanager that
//! joins while it runs — under the node's datamanager supervisor, as the declared ones —
//! and stops and drops one that was removed: when asked (`marie dm remove-replica`), and of
//! itself when one of its replicas tells `dm_replica_out` on the node's bus — a replica
//! removed while its node was away learns it from the leader once back, and nobody is left
//! to ask for its drop (or its journal says so at its start: swept when the host starts).

use super::config::NodeConfig;
use super::tree;
use super::NodeError;
use crate::replicas::{self, Declaration, HostMsg, HostRefusal};
use marie_dm::{DmMsg, Durability};
use marie_supervision::SupervisorRef;
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::{BusError, EventBus, EventKind};
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::rpc::CallResult;
use ractor::{Actor, ActorProcessingErr, ActorRef};
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::task::JoinHandle;

/// Child id of the replica host under the node's root supervisor.
pub(crate) const REPLICA_HOST: &str = "replica-host";

/// The host as a permanent child of the node's root (restarted and published again if it
/// crashes). Added once the root runs: it starts replicas through it.
pub(crate) fn child_spec(host: Host) -> marie_supervision::ChildSpec {
    marie_supervision::ChildSpec::worker(REPLICA_HOST, move |sup| {
        let host = host.clone();
        async move {
            let (actor, _) = Actor::spawn_linked(None, ReplicaHost, host, sup).await?;
            Ok(actor.get_cell())
        }
    })
}

/// What hosting a replica needs: the node's config (its name, data directory, the
/// datamanagers it declares — one added while it runs is added to it), its clock and bus,
/// and the root supervisor.
#[derive(Clone)]
pub(crate) struct Host {
    pub(crate) config: NodeConfig,
    pub(crate) clock: SharedClock,
    pub(crate) events: EventBus,
    pub(crate) root: SupervisorRef,
    /// The replicas dropped since the host started, and whether their journal went too: a
    /// drop asked again (`remove-replica` after the replica's own word) gets the same answer.
    pub(crate) dropped: BTreeMap<String, bool>,
}

impl Host {
    fn node(&self) -> String {
        self.config.name.clone()
    }

    fn failed(&self, e: impl std::fmt::Display) -> HostRefusal {
        HostRefusal::Failed {
            node: self.node(),
            reason: e.to_string(),
        }
    }

    /// The node's datamanager supervisor, started if the node had none.
    async fn datamanagers(&self) -> Result<SupervisorRef, NodeError> {
        if let Ok(sup) = tree::child_supervisor(&self.root, tree::DATAMANAGERS).await {
            return Ok(sup);
        }
        self.root
            .start_child(tree::datamanager_supervisor(Vec::new()))
            .await?;
        tree::child_supervisor(&self.root, tree::DATAMANAGERS).await
    }

    /// See [`HostMsg::Start`].
    async fn start(
        &mut self,
        declaration: Declaration,
        voters: Vec<String>,
    ) -> Result<(), HostRefusal> {
        if self.config.data_dir.is_none() {
            return Err(HostRefusal::NoDataDir { node: self.node() });
        }
        let dm = declaration.joining(voters);
        if let Some(own) = self.config.datamanagers.iter().find(|d| d.name == dm.name) {
            if own.replicas.is_empty() {
                return Err(HostRefusal::Clash {
                    node: self.node(),
                    dm: dm.name,
                });
            }
            let sup = self.datamanagers().await.map_err(|e| self.failed(e))?;
            if running(&sup, &dm.name).await {
                return Ok(());
            }
        }
        let mut config = self.config.clone();
        config.datamanagers = vec![dm.clone()];
        if config.durability_of(&dm) == Durability::Memory {
            return Err(self.failed(format!(
                "datamanager `{}` is declared in memory: a replica keeps a journal",
                dm.name
            )));
        }
        if let Some(Err(e)) = dm.replication(&self.config.name).map(|r| r.check()) {
            return Err(self.failed(e));
        }
        let spec = tree::datamanager_child(&config, &dm, &self.clock, &[], &self.events);
        let sup = self.datamanagers().await.map_err(|e| self.failed(e))?;
        // written first: a replica that ran, even a moment, is started again with the node
        let dir = self
            .config
            .data_dir
            .as_deref()
            .map(|d| marie_dm::journal_dir(d, &dm.name));
        if let Some(dir) = &dir {
            replicas::joined::write(dir, &Declaration::of(&dm), &dm.replicas)
                .map_err(|e| self.failed(format!("writing in {}: {e}", dir.display())))?;
        }
        // a replica stopped earlier left its spec behind
        let _ = sup.delete_child(&dm.name).await;
        if let Err(e) = sup.start_child(spec).await {
            if let Some(dir) = &dir {
                let _ = std::fs::remove_file(dir.join(replicas::joined::FILE));
            }
            return Err(self.failed(e));
        }
        tracing::info!(node = %self.config.name, dm = %dm.name, "replica started: it joins the datamanager's replicas");
        self.dropped.remove(&dm.name);
        self.config.datamanagers.retain(|d| d.name != dm.name);
        self.config.datamanagers.push(dm);
        Ok(())
    }

    /// See [`HostMsg::Drop`].
    async fn drop_replica(&mut self, name: String) -> Result<bool, HostRefusal> {
        let not_hosted = || HostRefusal::NotHosted {
            node: self.node(),
            dm: name.clone(),
        };
        let Some(dm) = self
            .config
            .datamanagers
            .iter()
            .find(|d| d.name == name && !d.replicas.is_empty())
            .cloned()
        else {
            return match self.dropped.get(&name) {
                Some(journal) => Ok(*journal),
                None => Err(not_hosted()),
            };
        };
        let sup = self.datamanagers().await.map_err(|e| self.failed(e))?;
        let child = sup
            .which_children()
            .await
            .map_err(|e| self.failed(e))?
            .into_iter()
            .find(|c| c.id == name)
            .and_then(|c| c.state.actor().cloned());
        if let Some(cell) = child {
            let actor: ActorRef<DmMsg> = cell.into();
            let own = actor
                .call(|reply| DmMsg::ReplicaStats { reply }, Some(ASK))
                .await;
            let Ok(CallResult::Success(stats)) = own else {
                return Err(self.failed(format!("its replica of `{name}` does not answer")));
            };
            if let Some(r) = stats.replica.filter(|r| !r.removed) {
                return Err(HostRefusal::StillMember {
                    node: self.node(),
                    dm: name,
                    members: r.members.join(", "),
                });
            }
        }
        let _ = sup.terminate_child(&name).await;
        let _ = sup.delete_child(&name).await;
        self.config.datamanagers.retain(|d| d.name != name);
        let journal = match (dm.joined, &self.config.data_dir) {
            (true, Some(dir)) => {
                let dir = marie_dm::journal_dir(dir, &name);
                std::fs::remove_dir_all(&dir)
                    .map_err(|e| self.failed(format!("removing {}: {e}", dir.display())))?;
                true
            }
            _ => false,
        };
        tracing::info!(node = %self.config.name, dm = %name, journal, "removed replica stopped");
        self.dropped.insert(name, journal);
        Ok(journal)
    }
}

/// How long the host waits for its own replica's word.
const ASK: Duration = Duration::from_secs(3);

/// Whether supervisor `sup` runs child `id` now.
async fn running(sup: &SupervisorRef, id: &str) -> bool {
    sup.which_children()
        .await
        .map(|cs| cs.iter().any(|c| c.id == id && c.state.actor().is_some()))
        .unwrap_or(false)
}

/// The replica host actor, published under its node's name in [`replicas::SCOPE`].
pub(crate) struct ReplicaHost;

/// The host's state: what it needs, and the replacement watch of each datamanager it keeps
/// a replica of with `replace_after` ([`replicas::replace`]).
pub(crate) struct Hosting {
    host: Host,
    watches: BTreeMap<String, JoinHandle<()>>,
    /// Drops the replicas that say they are out ([`drop_the_removed`]).
    listener: JoinHandle<()>,
}

impl Hosting {
    /// Watch the replicas of every datamanager of the node's config with `replace_after`
    /// that is not watched yet; stop watching those no longer there.
    fn watch(&mut self) {
        let config = &self.host.config;
        self.watches.retain(|name, task| {
            let kept = config.datamanagers.iter().any(|d| &d.name == name);
            if !kept {
                task.abort();
            }
            kept
        });
        for dm in &config.datamanagers {
            let Some(after) = dm.replace_after.filter(|_| !dm.replicas.is_empty()) else {
                continue;
            };
            if self.watches.contains_key(&dm.name) {
                continue;
            }
            let task = tokio::spawn(replicas::replace::watch(
                dm.name.clone(),
                config.name.clone(),
                after,
                dm.spares.clone(),
                self.host.events.clone(),
            ));
            self.watches.insert(dm.name.clone(), task);
        }
    }
}

impl Actor for ReplicaHost {
    type Msg = HostMsg;
    type State = Hosting;
    type Arguments = Host;

    async fn pre_start(
        &self,
        myself: ActorRef<HostMsg>,
        host: Host,
    ) -> Result<Hosting, ActorProcessingErr> {
        replicas::publish(myself.get_cell(), &host.config.name);
        let listener = tokio::spawn(drop_the_removed(
            myself.clone(),
            host.events.subscribe(),
            host.config.name.clone(),
            host.root.clone(),
        ));
        let mut hosting = Hosting {
            host,
            watches: BTreeMap::new(),
            listener,
        };
        hosting.watch();
        Ok(hosting)
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<HostMsg>,
        hosting: &mut Hosting,
    ) -> Result<(), ActorProcessingErr> {
        for task in hosting.watches.values() {
            task.abort();
        }
        hosting.listener.abort();
        Ok(())
    }

    async fn handle(
        &self,
        _myself: ActorRef<HostMsg>,
        msg: HostMsg,
        hosting: &mut Hosting,
    ) -> Result<(), ActorProcessingErr> {
        let host = &mut hosting.host;
        match msg {
            HostMsg::Start {
                declaration,
                voters,
                reply,
            } => {
                let _ = reply.send(host.start(declaration, voters).await);
            }
            HostMsg::Drop { dm, reply } => {
                let _ = reply.send(host.drop_replica(dm).await);
            }
            HostMsg::Declared { dm, reply } => {
                let declared = host.config.datamanagers.iter().find(|d| d.name == dm);
                let _ = reply.send(declared.map(Declaration::of));
            }
        }
        hosting.watch();
        Ok(())
    }
}

/// Drop, through the host `me` of node `node`, each replica of the node that says it is out
/// (`dm_replica_out` on `events`): first every one whose journal said so at its start
/// (told before the host listened), again after the subscription fell behind, until the
/// host stops. A replica that is still one of its datamanager's replicas is kept: the host
/// asks it first.
async fn drop_the_removed(
    me: ActorRef<HostMsg>,
    mut events: marie_vocabulary::events::EventSubscription,
    node: String,
    root: SupervisorRef,
) {
    let drop_one = |dm: String| {
        let (me, node) = (me.clone(), node.clone());
        async move {
            let asked = replicas::ask_host(&me, &node, |reply| HostMsg::Drop { dm, reply });
            if let Ok(Ok(journal)) = asked.await {
                tracing::debug!(%node, journal, "a replica that said it is out dropped");
            }
        }
    };
    let sweep = || async {
        let Ok(sup) = tree::child_supervisor(&root, tree::DATAMANAGERS).await else {
            return;
        };
        for child in sup.which_children().await.unwrap_or_default() {
            drop_one(child.id).await;
        }
    };
    sweep().await;
    loop {
        match events.recv().await {
            Ok(event) => match event.kind {
                EventKind::DmReplicaOut { dm, node: on, .. } if on == node => {
                    tokio::spawn(drop_once_led_elsewhere(me.clone(), node.clone(), dm));
                }
                _ => {}
            },
            Err(BusError::Lagged { .. }) => sweep().await,
            Err(BusError::Closed) => return,
        }
    }
}

/// How long a replica that says it is out may wait for a leader of its datamanager on
/// another node before it is dropped all the same (it takes no part either way).
const LEADER_WITHIN: Duration = Duration::from_secs(60);

/// Drop the replica of `dm` (through the host `me` of node `node`) once a leader of `dm`
/// runs on another node, or after [`LEADER_WITHIN`]: a leader that removed itself lives on
/// until its successor leads — the requests its clients send it meanwhile wait in it for
/// the successor and are sent on —; an outsider the leader told finds that leader at once.
async fn drop_once_led_elsewhere(me: ActorRef<HostMsg>, node: String, dm: String) {
    let led_elsewhere = || {
        registry::lookup(ModuleKind::Datamanager, &dm)
            .iter()
            .any(|i| !i.is_local())
    };
    if !led_elsewhere() {
        if let Ok(mut watch) = registry::watch(Some(ModuleKind::Datamanager)).await {
            let _ = tokio::time::timeout(LEADER_WITHIN, async {
                // looked at again once watching: a publication may have come between
                while !led_elsewhere() {
                    if watch.next().await.is_none() {
                        return;
                    }
                }
            })
            .await;
        }
    }
    let asked = replicas::ask_host(&me, &node, |reply| HostMsg::Drop { dm, reply });
    if let Ok(Ok(journal)) = asked.await {
        tracing::debug!(%node, journal, "a replica that said it is out dropped");
    }
}

/// Whether node `config` hosts replicas on request: it has a data directory (a replica
/// journals) and a cluster to meet the others in.
pub(crate) fn hosts_replicas(config: &NodeConfig) -> bool {
    config.data_dir.is_some() && config.cluster.is_some()
}

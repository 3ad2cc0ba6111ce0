//! The node's supervision tree: what its supervisors start, built from its [`NodeConfig`],
//! and how a run learns that an operation supervisor gave up.

use super::config::{NodeConfig, DEFAULT_PERIOD, DEFAULT_RESTARTS, OPERATIONS};
use super::robot::AprioriRecord;
use super::NodeError;
use super::{NodeOptions, OPERATION_SHUTDOWN};
use marie_actors::dispatcher::DispatcherMsg;
use marie_actors::eo::{HostOptions, OperationFactory};
use marie_dm::AckSink;
use marie_dm::{self as dm, DmArgs, DmClient, DmError, Durability, NewRecord};
use marie_supervision::{
    ChildSpec, ChildTemplate, Restart, Shutdown, Supervisor, SupervisorError, SupervisorEvent,
    SupervisorRef, SupervisorSpec,
};
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::EventBus;
use ractor::{ActorRef, SpawnErr};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast;

/// The source name the node stores its a-priori records under.
const NODE_SOURCE: &str = "node";

/// Abort `dispatcher`'s mission if the operation supervisor gives up, naming the operation
/// whose exits made it give up.
pub(super) async fn abort_on_give_up(
    supervisor: String,
    mut events: broadcast::Receiver<SupervisorEvent>,
    dispatcher: ActorRef<DispatcherMsg>,
) {
    // (child id, why it exited), newest last
    let mut exits: Vec<(String, String)> = Vec::new();
    loop {
        match events.recv().await {
            Ok(SupervisorEvent::ChildExited { id, reason, .. }) => {
                exits.push((id, reason.to_string()));
            }
            Ok(SupervisorEvent::RestartFailed { id, error }) => {
                exits.push((id, format!("restart failed: {error}")));
            }
            Ok(SupervisorEvent::IntensityExceeded {
                max_restarts,
                period,
            }) => {
                let recent: Vec<&(String, String)> =
                    exits.iter().rev().take(max_restarts + 1).collect();
                let mut culprits: Vec<&str> = recent.iter().map(|(id, _)| id.as_str()).collect();
                culprits.sort_unstable();
                culprits.dedup();
                let last = recent.first().map_or_else(
                    || "unknown".to_string(),
                    |(id, why)| format!("{id} ({why})"),
                );
                let which = if supervisor == OPERATIONS {
                    "the operation supervisor".to_string()
                } else {
                    format!("operation supervisor `{supervisor}`")
                };
                let reason = format!(
                    "{which} gave up: more than {max_restarts} restarts within {:.1}s, of {} (last exit: {last})",
                    period.as_secs_f64(),
                    culprits.join(", "),
                );
                let _ = dispatcher.cast(DispatcherMsg::Abort { reason });
                return;
            }
            Ok(_) => {}
            Err(broadcast::error::RecvError::Lagged(_)) => {}
            Err(broadcast::error::RecvError::Closed) => return,
        }
    }
}

/// Child id of the datamanager supervisor in the node's tree.
pub(super) const DATAMANAGERS: &str = "datamanagers";

/// Child id of the supervisor of dynamic operation instances (simple_one_for_one).
pub(super) const DYNAMIC: &str = "dynamic";

/// What a dynamic instance is started from: the operation's factory and host options.
#[derive(Clone)]
pub(super) struct DynamicOp {
    pub(super) factory: OperationFactory,
    pub(super) host: HostOptions,
}

/// The supervisor of instances started on request ([`Node::start_instance`]): OTP's
/// `simple_one_for_one`, one template — "an operation instance" — whose argument says which
/// operation; permanent, with the default operation intensity.
///
/// [`Node::start_instance`]: super::Node::start_instance
fn dynamic_supervisor() -> ChildSpec {
    let template = ChildTemplate::worker("instance", |sup, op: DynamicOp| {
        (op.factory.start)(op.host, Some(sup))
    })
    .with_shutdown(Shutdown::Timeout(OPERATION_SHUTDOWN));
    ChildSpec::supervisor(
        DYNAMIC,
        SupervisorSpec::simple_one_for_one(template)
            .with_intensity(DEFAULT_RESTARTS, DEFAULT_PERIOD),
        Vec::new(),
    )
}

/// The root's children, in start order: datamanagers, the robot's drivers, then one
/// supervisor per operation supervisor of the config with the instances it names.
pub(super) fn children(
    config: &NodeConfig,
    options: &NodeOptions,
    events: &EventBus,
) -> Vec<ChildSpec> {
    let apriori = options
        .robot
        .as_ref()
        .map(|r| r.apriori())
        .unwrap_or_default();
    let mut children = Vec::new();
    if !config.datamanagers.is_empty() {
        children.push(datamanager_supervisor(datamanagers(
            config,
            &options.clock,
            &apriori,
            events,
        )));
    }
    if let Some(robot) = &options.robot {
        children.extend(robot.drivers(&options.clock, events));
    }
    // what the operations' stores get acknowledged is told on the bus, for the check of
    // the datamanagers at a run's end
    let host = HostOptions {
        acks: Some(AckSink::publishing_on(events.clone())),
        events: Some(events.clone()),
        ..HostOptions::with_clock(options.clock.clone())
    };
    let hosted = config.hosted(&options.catalog);
    for sup in config.operation_supervisors() {
        let mut seen = std::collections::BTreeMap::<String, usize>::new();
        let ops = hosted
            .iter()
            .filter(|(op, _)| op.supervisor == sup.name)
            .map(|(op, f)| {
                let n = seen.entry(f.key()).or_default();
                *n += 1;
                let id = if *n == 1 {
                    f.key()
                } else {
                    format!("{}#{n}", f.key())
                };
                let host = HostOptions {
                    fail_first_activations: op.fail_first_activations,
                    pinned: op.pin,
                    ..host.clone()
                };
                operation_child(id, (*f).clone(), host, op.restart)
            })
            .collect();
        children.push(ChildSpec::supervisor(
            sup.name.clone(),
            SupervisorSpec::new(sup.strategy).with_intensity(sup.max_restarts, sup.period),
            ops,
        ));
    }
    children.push(dynamic_supervisor());
    children
}

/// Start the root supervisor (one_for_one, 3 restarts in 30 s) with `children`.
pub(super) async fn start_root(
    children: Vec<ChildSpec>,
) -> Result<(SupervisorRef, ractor::concurrency::JoinHandle<()>), SupervisorError> {
    Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(3, Duration::from_secs(30)),
        children,
    )
    .await
}

/// The child spec of one operation instance: a fresh instance of `factory` at every
/// (re)start, hosted with `host`, stopped within [`OPERATION_SHUTDOWN`].
pub(super) fn operation_child(
    id: String,
    factory: OperationFactory,
    host: HostOptions,
    restart: Restart,
) -> ChildSpec {
    ChildSpec::worker(id, move |sup| (factory.start)(host.clone(), Some(sup)))
        .with_shutdown(Shutdown::Timeout(OPERATION_SHUTDOWN))
        .with_restart(restart)
}

/// The supervisor of the node's datamanagers (one_for_one, the default intensity) with
/// `children`: in the tree from the start when the config has datamanagers, else started
/// with the first replica added to the node ([`super::replica_host`]).
pub(super) fn datamanager_supervisor(children: Vec<ChildSpec>) -> ChildSpec {
    ChildSpec::supervisor(
        DATAMANAGERS,
        SupervisorSpec::one_for_one().with_intensity(DEFAULT_RESTARTS, DEFAULT_PERIOD),
        children,
    )
}

/// The datamanagers' child specs, one per datamanager of the config
/// ([`datamanager_child`]).
fn datamanagers(
    config: &NodeConfig,
    clock: &SharedClock,
    apriori: &[AprioriRecord],
    events: &EventBus,
) -> Vec<ChildSpec> {
    config
        .datamanagers
        .iter()
        .map(|spec| datamanager_child(config, spec, clock, apriori, events))
        .collect()
}

/// The child spec of datamanager `spec` on the node of `config`: at its durability, with
/// its journal in the node's data directory when it keeps one. Its start stores the
/// a-priori records meant for it before it counts as started, so they are there before any
/// operation looks for them — and are there again after a restart (left to a memory
/// datamanager by its previous incarnation, read back from the journal of a durable one).
/// Also how a replica added while the datamanager runs is started
/// ([`super::replica_host`]).
pub(super) fn datamanager_child(
    config: &NodeConfig,
    spec: &crate::node::DatamanagerConfig,
    clock: &SharedClock,
    apriori: &[AprioriRecord],
    events: &EventBus,
) -> ChildSpec {
    let clock = clock.clone();
    let events = events.clone();
    let records: Arc<Vec<_>> = Arc::new(
        apriori
            .iter()
            .filter(|a| a.datamanager == spec.name)
            .map(|a| a.record.clone())
            .collect(),
    );
    let (id, name) = (spec.id, spec.name.clone());
    let limits = spec.limits();
    let replication = spec.replication(&config.name);
    // validated: a durability other than memory comes with a data directory
    let journal = match (config.durability_of(spec), &config.data_dir) {
        (Durability::Memory, _) | (_, None) => None,
        (durability, Some(data_dir)) => Some((dm::journal_dir(data_dir, &spec.name), durability)),
    };
    // one heir for every incarnation of the child: a memory datamanager the
    // supervisor restarts takes what the one before left (`marie_dm::Heir`)
    let heir = dm::Heir::new();
    ChildSpec::worker(spec.name.clone(), move |sup| {
        let (clock, records, name) = (clock.clone(), records.clone(), name.clone());
        let (journal, heir) = (journal.clone(), heir.clone());
        let replication = replication.clone();
        let events = events.clone();
        let limits = limits.clone();
        async move {
            let mut args = DmArgs {
                id,
                name,
                clock,
                config: limits,
                durability: Durability::Memory,
                journal_dir: None,
                replication: None,
                events: Some(events),
                heir: Some(heir),
            };
            if let Some((dir, durability)) = journal {
                args = args.with_journal(dir, durability);
            }
            if let Some(replication) = replication {
                let args = args.with_replication(replication);
                let (actor, _) = dm::spawn_datamanager_linked(args.clone(), sup).await?;
                if !records.is_empty() {
                    tokio::spawn(apriori_to_primary(args.name.clone(), records.clone()));
                }
                return Ok(actor.get_cell());
            }
            let (actor, _) = dm::spawn_datamanager_linked(args, sup).await?;
            let startup = |e: DmError| SpawnErr::StartupFailed(Box::new(e));
            let client = DmClient::new(actor.clone(), NODE_SOURCE);
            // A durable datamanager read its journal back, and a memory one restarted
            // took what its previous incarnation left: the a-priori records it ever
            // stored are in it (the same seqs), and storing them again at every
            // restart would pile up copies. So they are stored only in a datamanager
            // that starts fresh — nothing was ever handed a seq, `next_seq == 1`.
            if !records.is_empty() && client.stats().await.map_err(startup)?.next_seq == 1 {
                for record in records.iter() {
                    client.store_raw(record.clone()).await.map_err(startup)?;
                }
            }
            Ok(actor.get_cell())
        }
    })
}

/// How long a replica's node waits for its replicated datamanager's leader to store the
/// a-priori records in it.
const APRIORI_WAIT: Duration = Duration::from_secs(120);

/// Store the a-priori `records` in the leader of the replicated datamanager `name`,
/// wherever it is elected. A replica is not the leader when it starts, and every node
/// hosting a replica may hold the same records: each stores them as one producer — a fixed id
/// per datamanager, numbered 1, 2, 3, … — so the leader keeps them once
/// (the datamanager's producer table), however many nodes or restarts send them.
async fn apriori_to_primary(name: String, records: Arc<Vec<NewRecord>>) {
    let producer = name
        .bytes()
        .chain(b"/marie-apriori".iter().copied())
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        })
        | 1;
    let client = match DmClient::lookup_within(&name, NODE_SOURCE, APRIORI_WAIT).await {
        Ok(c) => c,
        Err(e) => {
            tracing::warn!(dm = %name, error = %e, "a-priori records not stored: no leader");
            return;
        }
    };
    for (i, record) in records.iter().enumerate() {
        let mut record = record.clone();
        record.producer = producer;
        record.producer_seq = i as u64 + 1;
        if let Err(e) = client.store_raw(record).await {
            tracing::warn!(dm = %name, error = %e, "an a-priori record not stored");
            return;
        }
    }
    tracing::debug!(dm = %name, records = records.len(), "a-priori records stored in the leader");
}

/// The root's child supervisor `id`, as it is now (a new actor after it was restarted).
pub(crate) async fn child_supervisor(
    root: &SupervisorRef,
    id: &str,
) -> Result<SupervisorRef, NodeError> {
    root.which_children()
        .await?
        .into_iter()
        .find(|c| c.id == id)
        .and_then(|c| c.state.actor().cloned())
        .and_then(SupervisorRef::from_cell)
        .ok_or_else(|| NodeError::Supervisor(SupervisorError::NotFound(id.to_string())))
}

/// Restart every operation instance of the node rooted at `root` — as a new incarnation:
/// new actors, no activation, no state — and stop the dynamic ones; how many were
/// restarted. See [`Node::reincarnate`](super::Node::reincarnate).
pub(super) async fn reincarnate(
    root: &SupervisorRef,
    config: &NodeConfig,
) -> Result<usize, NodeError> {
    let mut restarted = 0;
    for sup in config.operation_supervisors() {
        let sup = child_supervisor(root, &sup.name).await?;
        for child in sup.which_children().await? {
            sup.terminate_child(&child.id).await?;
            sup.restart_child(&child.id).await?;
            restarted += 1;
        }
    }
    let dynamic = child_supervisor(root, DYNAMIC).await?;
    for child in dynamic.which_children().await? {
        if let Some(actor) = child.state.actor() {
            dynamic.terminate_actor(actor.get_id()).await?;
        }
    }
    tracing::warn!(node = %config.name, restarted, "operations restarted as a new incarnation");
    Ok(restarted)
}

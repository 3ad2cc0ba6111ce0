//! `marie kill NAME|ID`: kill an operation (or a datamanager) on the embedded node and watch
//! its supervisor restart it.

use super::args::RobotArgs;
use super::error::BadInput;
use super::join::{join, member_name, JoinArgs};
use super::prepare::start_node;
use marie::cluster::fault::{FaultError, Hit, Injector, Target};
use marie::cluster::node::Node;
use marie::events::EventBus;
use marie::registry::{self, Instance, ModuleKind, RegistryEvent};
use marie::run::{Aim, FaultKind};
use marie::supervision::SupervisorEvent;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Flags of `marie kill`.
#[derive(clap::Args, Debug)]
pub(crate) struct KillArgs {
    /// The operation: its name or numeric id, `NAME#VERSION` when several versions run,
    /// `NAME/NODE`, or an actor id like `0.42` — or a datamanager, by name, id or actor id.
    pub operation: String,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// `--join ADDR --cookie C`: kill an operation of a running cluster, wherever it runs,
    /// and watch the registry for its restarted instance.
    #[command(flatten)]
    pub cluster: JoinArgs,
}

/// How long `kill` waits for the restarted instance.
const RESTART_TIMEOUT: Duration = Duration::from_secs(10);

/// Start the embedded node, kill the operation's live instance and wait for the operation
/// supervisor to restart it.
pub(crate) async fn kill(args: KillArgs) -> anyhow::Result<ExitCode> {
    let KillArgs {
        operation,
        robot,
        cluster,
    } = args;
    if let Some(target) = cluster.target_alone(&robot, "kills in")? {
        let name = member_name("kill");
        let transport = join(&name, &target).await?;
        // this member's own bus: the fault is told there, as every fault is
        let bus = EventBus::new(name, marie::clock::RealClock::shared());
        let result = kill_in_cluster(&Injector::new(&bus), &operation).await;
        transport.stop().await;
        return result;
    }
    let node = start_node(robot.options(None)).await?.node;
    let result = kill_on(&node, &operation).await;
    node.shutdown().await;
    result
}

/// Kill what `operation` names, through the one road of faults (told on `injector`'s bus);
/// the instance it hit.
async fn strike(injector: &Injector, operation: &str) -> anyhow::Result<Instance> {
    let target = Target::parse(operation, Aim::Operation).map_err(|e| BadInput(e.to_string()))?;
    // outside a run a name several instances share is not guessed at: the user names one
    let done = match injector.inject(FaultKind::Kill, &target).await {
        Ok(done) => done,
        Err(e @ FaultError::Target(_)) => return Err(BadInput(e.to_string()).into()),
        Err(e) => return Err(e.into()),
    };
    match done.hit {
        Hit::Instance(inst) => Ok(inst),
        Hit::Process { node, .. } => Err(anyhow::anyhow!("{node} is a node, not an operation")),
        Hit::Cut { .. } => Err(anyhow::anyhow!("{target} is a cut, not an operation")),
    }
}

async fn kill_on(node: &Node, operation: &str) -> anyhow::Result<ExitCode> {
    // both supervisors are listened to before the strike: the target may be either kind
    let mut operations = node.operation_supervisor().await?.subscribe().await?;
    let mut datamanagers = match node.datamanager_supervisor().await {
        Ok(supervisor) => Some(supervisor.subscribe().await?),
        Err(_) => None, // a node without datamanagers
    };
    let started = std::time::Instant::now();
    let inst = strike(&Injector::new(node.events()), operation).await?;
    let killed = inst.actor_id();
    println!("killed {} ({}) at {killed}", inst.name, inst.id);
    let (events, supervisor) = match (inst.kind, datamanagers.as_mut()) {
        (ModuleKind::Datamanager, Some(events)) => (events, "datamanager"),
        _ => (&mut operations, "operation"),
    };
    let restarted = tokio::time::timeout(RESTART_TIMEOUT, async {
        loop {
            match events.recv().await {
                Ok(SupervisorEvent::ChildRestarted { old, new, .. }) if old == Some(killed) => {
                    return Some(new)
                }
                Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                Err(_) => return None,
            }
        }
    })
    .await;
    match restarted {
        Ok(Some(new)) => {
            println!(
                "restarted by the {supervisor} supervisor as {} after {:.2} ms",
                new.get_id(),
                started.elapsed().as_secs_f64() * 1000.0
            );
            Ok(ExitCode::SUCCESS)
        }
        _ => {
            println!("not restarted within {RESTART_TIMEOUT:?}");
            Ok(ExitCode::from(1))
        }
    }
}

/// Kill an instance wherever it runs (a remote one is told to die: killing its local
/// stand-in would kill the stand-in alone) and wait for an instance of the same operation to
/// appear on the same node: its supervisor's restart.
async fn kill_in_cluster(injector: &Injector, operation: &str) -> anyhow::Result<ExitCode> {
    // any kind: the target may be an operation or a datamanager
    let mut watch = registry::watch(None).await?;
    let started = Instant::now();
    let inst = strike(injector, operation).await?;
    let killed = inst.actor_id();
    println!(
        "killed {} ({}) on {} at {killed}",
        inst.name, inst.id, inst.node
    );
    let restarted = tokio::time::timeout(RESTART_TIMEOUT, async {
        while let Some(event) = watch.next().await {
            if let RegistryEvent::Joined(new) = event {
                if new.kind == inst.kind
                    && new.name == inst.name
                    && new.node == inst.node
                    && new.actor_id() != killed
                {
                    return Some(new);
                }
            }
        }
        None
    })
    .await;
    match restarted {
        Ok(Some(new)) => {
            println!(
                "restarted on {} as {} after {:.2} ms",
                new.node,
                new.actor_id(),
                started.elapsed().as_secs_f64() * 1000.0
            );
            Ok(ExitCode::SUCCESS)
        }
        _ => {
            println!("not restarted on {} within {RESTART_TIMEOUT:?}", inst.node);
            Ok(ExitCode::from(1))
        }
    }
}

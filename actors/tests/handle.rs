//! The operation handle: typed calls, epochs kept inside, restarts followed, errors that name
//! the operation and its node.
//!
//! Every test names its own operation (and numeric id): the tests of this file share one
//! process, and so one registry.

use marie_actors::eo::{
    spawn_operation, EoClient, EoMsg, HandleError, Identity, OpContext, OpError, Operation,
    OperationHandle, ParamOutcome, SetError, Step,
};
use marie_vocabulary::property::{
    param_map, ParamDecl, ParamSchema, PropertyReply, PropertyRequest, RejectReason, Value,
};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::status::FlagDecl;
use ractor::{Actor, ActorProcessingErr, ActorRef};
use semver::VersionReq;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;
use tokio::time::timeout;

/// How long a test waits for what must happen; it never waits that long when things work.
const T: Duration = Duration::from_secs(30);

/// The node name every error must carry (one per process, so every test sets the same).
const NODE: &str = "handle-test";

fn name_the_node() {
    registry::set_local_node_name(NODE);
}

/// A tank: a few parameters of every type, one flag, one property of its own.
struct Tank {
    name: &'static str,
    id: u32,
    version: &'static str,
    /// While above zero, asking the tank's own property `litres` makes it panic and counts
    /// one down (shared by a tank and its replacements: how many of them burst).
    fuse: Option<Arc<AtomicUsize>>,
}

impl Operation for Tank {
    fn identity(&self) -> Identity {
        Identity::new(self.name, self.id, self.version, "holds a level")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("level", 1.0).range(0.0, 10.0).unit("m"),
            ParamDecl::int("valves", 3).range(1.0, 8.0),
            ParamDecl::bool("heated", false),
            ParamDecl::text("fluid", "water"),
        ])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("full", "the level is reached")]
    }
    fn property(&self, name: &str) -> Option<Value> {
        let lit = |fuse: &Arc<AtomicUsize>| {
            fuse.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
                .is_ok()
        };
        if name == "litres" && self.fuse.as_ref().is_some_and(lit) {
            panic!("the tank bursts");
        }
        (name == "litres").then_some(Value::Int(420))
    }
    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
    async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
}

async fn start(
    name: &'static str,
    id: u32,
    version: &'static str,
) -> (ActorRef<EoMsg>, JoinHandle<()>) {
    start_tank(Tank {
        name,
        id,
        version,
        fuse: None,
    })
    .await
}

async fn start_tank(tank: Tank) -> (ActorRef<EoMsg>, JoinHandle<()>) {
    timeout(T, spawn_operation(tank, Default::default()))
        .await
        .unwrap()
        .unwrap()
}

/// Act as a supervisor for `name`: each time an instance leaves the registry, start a new
/// one (up to `times` times) — as `tests/rebinding.rs` does — sharing `fuse`.
async fn replace_on_death(
    name: &'static str,
    id: u32,
    times: usize,
    fuse: Option<Arc<AtomicUsize>>,
) -> JoinHandle<()> {
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.unwrap();
    tokio::spawn(async move {
        let mut left = times;
        while left > 0 {
            match watch.next().await {
                Some(RegistryEvent::Left(i)) if i.name == name => {
                    let fuse = fuse.clone();
                    start_tank(Tank {
                        name,
                        id,
                        version: "1.0.0",
                        fuse,
                    })
                    .await;
                    left -= 1;
                }
                Some(_) => {}
                None => break,
            }
        }
    })
}

#[tokio::test]
async fn typed_calls_answer_in_types_and_set_keeps_epochs_inside() {
    name_the_node();
    let (actor, _) = start("h-typed", 8101, "1.4.0").await;
    let tank = OperationHandle::lookup("h-typed").await.unwrap();
    assert_eq!(
        (tank.name(), tank.node()),
        ("h-typed".to_string(), NODE.to_string())
    );
    let by_id = OperationHandle::lookup("8101").await.unwrap();
    assert_eq!(by_id.name(), "h-typed");
    assert_eq!(by_id.actor().get_id(), actor.get_id());

    assert_eq!(
        tank.identity().await.unwrap(),
        Identity::new("h-typed", 8101, "1.4.0", "holds a level")
    );
    let schema = tank.schema().await.unwrap();
    let names: Vec<&str> = schema.params.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["level", "valves", "heated", "fluid"]);
    assert_eq!(schema.params[0].max, Some(10.0));
    assert_eq!(
        tank.flags().await.unwrap(),
        [FlagDecl::new("full", "the level is reached")]
    );
    let general = tank.general().await.unwrap();
    assert_eq!(
        (general.param_count, general.activations, general.in_use),
        (4, 0, false)
    );

    assert_eq!(tank.value::<f64>("level").await.unwrap(), 1.0);
    assert_eq!(tank.value::<i64>("valves").await.unwrap(), 3);
    assert!(!tank.value::<bool>("heated").await.unwrap());
    assert_eq!(tank.value::<String>("fluid").await.unwrap(), "water");
    assert_eq!(tank.property::<i64>("litres").await.unwrap(), 420);
    assert_eq!(tank.property::<String>("node").await.unwrap(), NODE);

    // a dispatcher drives the tank at epoch 7; the handle's set goes through without one
    let dispatcher = EoClient::new(actor.clone());
    let raised = dispatcher
        .parameterize(param_map([("valves", Value::Int(4))]), 7)
        .await
        .unwrap();
    assert_eq!(raised, ParamOutcome::Applied);
    tank.set(param_map([
        ("level", Value::Float(2.5)),
        ("heated", Value::Bool(true)),
    ]))
    .await
    .unwrap();
    assert_eq!(tank.value::<f64>("level").await.unwrap(), 2.5);
    assert!(tank.value::<bool>("heated").await.unwrap());
    assert_eq!(
        tank.general().await.unwrap().epoch,
        7,
        "the handle commands at the epoch in force and never raises it"
    );
    // ... so the dispatcher's next command at its epoch is not fenced off
    assert_eq!(
        dispatcher
            .parameterize(param_map([("valves", Value::Int(5))]), 7)
            .await
            .unwrap(),
        ParamOutcome::Applied
    );

    // the rejection path: one value out of range refuses them all, each refusal listed
    let before = tank.current().await.unwrap();
    let refused = tank
        .set(param_map([
            ("level", Value::Float(99.0)),
            ("valves", Value::Int(2)),
        ]))
        .await
        .unwrap_err();
    let SetError::Rejected {
        operation,
        node,
        rejections,
    } = &refused
    else {
        panic!("expected a rejection, got {refused:?}");
    };
    assert_eq!((operation.as_str(), node.as_str()), ("h-typed", NODE));
    assert_eq!(rejections.len(), 1, "{rejections:?}");
    assert_eq!(rejections[0].name, "level");
    assert!(
        matches!(
            rejections[0].reason,
            RejectReason::OutOfRange { value, max: Some(max), .. } if value == 99.0 && max == 10.0
        ),
        "{rejections:?}"
    );
    assert_eq!(
        refused.to_string(),
        "operation `h-typed` on node `handle-test` refused the parameters, nothing changed: \
         level: 99 is out of range [0, 10]"
    );
    assert_eq!(tank.current().await.unwrap(), before, "nothing changed");
    let unknown = tank.set(param_map([("colour", Value::from("red"))])).await;
    assert!(
        matches!(&unknown, Err(SetError::Rejected { rejections, .. })
            if rejections[0].name == "colour" && rejections[0].reason == RejectReason::UnknownName),
        "{unknown:?}"
    );

    // wrong type, no such parameter, no such property: each named
    let wrong = tank.value::<bool>("level").await.unwrap_err();
    assert_eq!(
        wrong.to_string(),
        "`level` of operation `h-typed` on node `handle-test` is float 2.5, not bool"
    );
    assert_eq!(
        tank.value::<f64>("depth").await.unwrap_err(),
        HandleError::NoParameter {
            operation: "h-typed".into(),
            node: NODE.into(),
            name: "depth".into()
        }
    );
    assert!(matches!(
        tank.property::<i64>("depth").await,
        Err(HandleError::NoProperty { .. })
    ));
    assert_eq!(
        OperationHandle::lookup("h-missing")
            .await
            .unwrap_err()
            .to_string(),
        "no running instance of operation `h-missing`"
    );
    actor.stop(None);
}

/// Speaks the eo-interface like a host whose epoch a dispatcher keeps raising: the epoch
/// property says 3, and a parameterization below `floor` is answered `Stale`.
struct Contested {
    floor: Option<u64>,
    seen: Arc<Mutex<Vec<u64>>>,
}

impl Actor for Contested {
    type Msg = EoMsg;
    type State = ();
    type Arguments = (&'static str, u32);

    async fn pre_start(
        &self,
        myself: ActorRef<EoMsg>,
        (name, id): (&'static str, u32),
    ) -> Result<(), ActorProcessingErr> {
        registry::publish(ModuleKind::Operation, id, name, myself.get_cell())?;
        Ok(())
    }

    async fn handle(
        &self,
        _myself: ActorRef<EoMsg>,
        msg: EoMsg,
        _state: &mut (),
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            EoMsg::Property { request, reply } => {
                let answer = match request {
                    PropertyRequest::Get(name) if name == "epoch" => {
                        PropertyReply::Value(Value::Int(3))
                    }
                    PropertyRequest::Get(name) => PropertyReply::NotFound(name),
                    other => PropertyReply::NotFound(format!("{other:?}")),
                };
                let _ = reply.send(answer);
            }
            EoMsg::Parameterize { epoch, reply, .. } => {
                self.seen.lock().unwrap().push(epoch);
                // without a floor, every command is answered by a newer epoch
                let floor = self.floor.unwrap_or(epoch + 1);
                let _ = reply.send(if epoch < floor {
                    ParamOutcome::Stale { current: floor }
                } else {
                    ParamOutcome::Applied
                });
            }
            _ => {}
        }
        Ok(())
    }
}

#[tokio::test]
async fn a_stale_answer_is_retried_once_at_the_epoch_it_names() {
    name_the_node();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let once = Contested {
        floor: Some(5),
        seen: seen.clone(),
    };
    let (stub, _) = Actor::spawn(None, once, ("h-stale-once", 8201))
        .await
        .unwrap();
    let handle = OperationHandle::lookup("h-stale-once").await.unwrap();
    timeout(T, handle.set(param_map([("level", Value::Float(2.0))])))
        .await
        .unwrap()
        .unwrap();
    assert_eq!(
        *seen.lock().unwrap(),
        [3, 5],
        "at the epoch read, then at the one named"
    );
    stub.stop(None);

    let seen = Arc::new(Mutex::new(Vec::new()));
    let always = Contested {
        floor: None,
        seen: seen.clone(),
    };
    let (stub, _) = Actor::spawn(None, always, ("h-stale-always", 8202))
        .await
        .unwrap();
    let handle = OperationHandle::lookup("h-stale-always").await.unwrap();
    let err = timeout(T, handle.set(param_map([("level", Value::Float(2.0))])))
        .await
        .unwrap()
        .unwrap_err();
    assert_eq!(
        err,
        SetError::Superseded {
            operation: "h-stale-always".into(),
            node: NODE.into(),
            epoch: 5
        }
    );
    assert_eq!(*seen.lock().unwrap(), [3, 4], "once more, not in a loop");
    stub.stop(None);
}

#[tokio::test]
async fn a_handle_follows_its_operation_to_the_instance_that_replaces_it() {
    name_the_node();
    let _supervisor = replace_on_death("h-restart", 8301, 1, None).await;
    let (first, first_done) = start("h-restart", 8301, "1.0.0").await;
    let tank = OperationHandle::lookup("h-restart").await.unwrap();
    let clone = tank.clone();
    tank.set(param_map([("valves", Value::Int(6))]))
        .await
        .unwrap();
    assert_eq!(tank.actor().get_id(), first.get_id());

    first.kill();
    timeout(T, first_done).await.unwrap().unwrap();
    // the next call finds the instance gone, waits for the replacement and runs there
    let general = timeout(T, tank.general()).await.unwrap().unwrap();
    assert_eq!(general.activations, 0);
    let second = tank.actor();
    assert_ne!(second.get_id(), first.get_id());
    assert_eq!(
        registry::lookup(ModuleKind::Operation, "h-restart")[0]
            .actor
            .get_id(),
        second.get_id()
    );
    assert_eq!(
        tank.value::<i64>("valves").await.unwrap(),
        3,
        "a replacement starts with its own parameters: the handle replays nothing"
    );
    tank.set(param_map([("valves", Value::Int(7))]))
        .await
        .unwrap();
    assert_eq!(tank.value::<i64>("valves").await.unwrap(), 7);
    assert_eq!(
        clone.actor().get_id(),
        second.get_id(),
        "clones follow together"
    );
    second.stop(None);
}

#[tokio::test]
async fn a_call_whose_instance_dies_under_it_runs_again_on_the_replacement() {
    name_the_node();
    // the first instance bursts when asked, its replacement does not
    let fuse = Arc::new(AtomicUsize::new(1));
    let _supervisor = replace_on_death("h-dies", 8351, 1, Some(fuse.clone())).await;
    let (first, _) = start_tank(Tank {
        name: "h-dies",
        id: 8351,
        version: "1.0.0",
        fuse: Some(fuse.clone()),
    })
    .await;
    let tank = OperationHandle::lookup("h-dies").await.unwrap();
    // alive when the call starts; the request itself crashes it, so the call fails with
    // the instance gone, follows the operation and asks the replacement
    let litres = timeout(T, tank.property::<i64>("litres")).await.unwrap();
    assert_eq!(litres, Ok(420));
    assert_eq!(
        fuse.load(Ordering::SeqCst),
        0,
        "the first instance did burst"
    );
    assert_ne!(tank.actor().get_id(), first.get_id());
    tank.actor().stop(None);
}

#[tokio::test]
async fn a_call_follows_once_and_names_a_replacement_that_is_gone_too() {
    name_the_node();
    // the first instance and its replacement both burst when asked
    let fuse = Arc::new(AtomicUsize::new(2));
    let _supervisor = replace_on_death("h-bursts", 8361, 2, Some(fuse.clone())).await;
    start_tank(Tank {
        name: "h-bursts",
        id: 8361,
        version: "1.0.0",
        fuse: Some(fuse.clone()),
    })
    .await;
    let tank = OperationHandle::lookup("h-bursts").await.unwrap();
    let err = timeout(T, tank.property::<i64>("litres"))
        .await
        .unwrap()
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "operation `h-bursts` on node `handle-test` is gone too: the instance that took the \
         place of a gone one stopped before it answered"
    );
    assert_eq!(fuse.load(Ordering::SeqCst), 0, "asked twice, not more");
    // the third instance (the supervisor's second restart) answers the next call
    assert_eq!(
        timeout(T, tank.property::<i64>("litres")).await.unwrap(),
        Ok(420)
    );
    tank.actor().stop(None);
}

#[tokio::test]
async fn a_handle_waits_for_a_replacement_only_so_long_and_names_what_is_gone() {
    name_the_node();
    let (only, only_done) = start("h-gone", 8401, "1.0.0").await;
    let tank = OperationHandle::lookup("h-gone")
        .await
        .unwrap()
        .following_for(Duration::from_millis(300));
    only.stop(None);
    timeout(T, only_done).await.unwrap().unwrap();
    let gone = timeout(T, tank.value::<f64>("level"))
        .await
        .unwrap()
        .unwrap_err();
    assert_eq!(
        gone.to_string(),
        "operation `h-gone` on node `handle-test` is gone, and no instance took its place within 300 ms"
    );
}

#[tokio::test]
async fn a_hung_operation_is_reported_by_name_and_node() {
    name_the_node();
    let (actor, _) = start("h-hang", 8501, "1.0.0").await;
    let tank = OperationHandle::lookup("h-hang")
        .await
        .unwrap()
        .with_timeout(Duration::from_millis(300));
    tank.client().inject(FaultKind::Hang).unwrap();
    let hung = timeout(T, tank.general()).await.unwrap().unwrap_err();
    assert_eq!(
        hung,
        HandleError::Timeout {
            operation: "h-hang".into(),
            node: NODE.into(),
            after: Duration::from_millis(300)
        }
    );
    assert_eq!(
        hung.to_string(),
        "operation `h-hang` on node `handle-test` did not answer within 300 ms"
    );
    assert_eq!(
        tank.actor().get_id(),
        actor.get_id(),
        "a hung instance is not left"
    );
    actor.kill();
}

#[tokio::test]
async fn a_version_requirement_holds_for_the_replacement_too() {
    name_the_node();
    start("h-versions", 8601, "1.0.0").await;
    let (v2, v2_done) = start("h-versions", 8601, "2.1.0").await;
    let want = VersionReq::parse("^2").unwrap();
    let tank = OperationHandle::lookup_version("h-versions", want.clone())
        .await
        .unwrap();
    assert_eq!(tank.actor().get_id(), v2.get_id());
    assert_eq!(tank.identity().await.unwrap().version.to_string(), "2.1.0");

    v2.kill();
    timeout(T, v2_done).await.unwrap().unwrap();
    // two come back: the version 1 does not stand in, the version 2 does
    start("h-versions", 8601, "1.0.1").await;
    let (v2_again, _) = start("h-versions", 8601, "2.2.0").await;
    let identity = timeout(T, tank.identity()).await.unwrap().unwrap();
    assert_eq!(identity.version.to_string(), "2.2.0");
    assert_eq!(tank.actor().get_id(), v2_again.get_id());

    let none = OperationHandle::lookup_version("h-versions", VersionReq::parse("^3").unwrap())
        .await
        .unwrap_err();
    assert_eq!(
        none.to_string(),
        "no running instance of operation `h-versions` with a version matching `^3`"
    );
}

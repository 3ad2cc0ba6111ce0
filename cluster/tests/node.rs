//! The node built from a `NodeConfig` as a Rust value: what it hosts, the tree it builds,
//! dynamic instances on request, and the config errors an embedder gets.
//!
//! The registry is one per process and these tests run in parallel: each owns the operation
//! names it starts.

use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, OperationFactory, Step};
use marie_cluster::node::{
    ConfigError, Node, NodeConfig, NodeError, NodeOptions, OperationConfig, SupervisorConfig,
};
use marie_supervision::Strategy;
use marie_vocabulary::status::StatusFlags;
use std::time::Duration;

macro_rules! operation {
    ($ty:ident, $name:literal, $id:literal, $version:literal) => {
        #[derive(Default)]
        struct $ty;
        impl Operation for $ty {
            fn identity(&self) -> Identity {
                Identity::new($name, $id, $version, "a test operation")
            }
            async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
                Ok(Step::Finish(StatusFlags(0)))
            }
        }
    };
}

operation!(ProbeV1, "probe", 9101, "1.0.0");
operation!(ProbeV2, "probe", 9101, "2.1.0");
operation!(Beacon, "beacon", 9102, "1.0.0");
operation!(Silent, "silent", 9103, "1.0.0");
operation!(Standby, "standby", 9104, "1.0.0");

fn catalog() -> Vec<OperationFactory> {
    vec![
        OperationFactory::of::<ProbeV1>("probe"),
        OperationFactory::of::<ProbeV2>("probe"),
        OperationFactory::of::<Beacon>("beacon"),
        OperationFactory::of::<Silent>("silent"),
        OperationFactory::of::<Standby>("standby"),
    ]
}

/// The versions the instances report through the property interface.
async fn versions(instances: &[marie_vocabulary::registry::Instance]) -> Vec<String> {
    use marie_vocabulary::property::{Group, PropertyReply, PropertyRequest};
    let mut out = Vec::new();
    for i in instances {
        let client = marie_actors::eo::EoClient::from_cell(i.actor.clone());
        match client
            .property(PropertyRequest::Group(Group::Identification))
            .await
        {
            Ok(PropertyReply::Identification(id)) => out.push(id.version.to_string()),
            other => panic!("no identification: {other:?}"),
        }
    }
    out
}

fn child_ids(children: Vec<marie_supervision::ChildInfo>) -> Vec<String> {
    children.into_iter().map(|c| c.id).collect()
}

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn a_node_hosts_exactly_its_config_and_starts_allowed_instances_on_request() {
    let mut config = NodeConfig::new("n1");
    config.supervisors.push(SupervisorConfig {
        name: "sensing".into(),
        strategy: Strategy::OneForAll,
        max_restarts: 2,
        period: Duration::from_secs(5),
    });
    config.operations.push(
        OperationConfig::new("probe")
            .with_version("^1".parse().unwrap())
            .with_instances(2),
    );
    let mut beacon = OperationConfig::new("beacon");
    beacon.supervisor = "sensing".into();
    config.operations.push(beacon);
    let node = Node::start(config, NodeOptions::with_catalog(catalog()))
        .await
        .unwrap();

    // the tree: no datamanager asked for, so none; each supervisor; the dynamic one; the
    // provisioner
    let root = child_ids(node.supervisor().which_children().await.unwrap());
    assert_eq!(root, ["operations", "sensing", "dynamic", "provisioner"]);
    let ops = node.operation_supervisor().await.unwrap();
    let ops = child_ids(ops.which_children().await.unwrap());
    assert_eq!(ops, ["probe@1.0.0", "probe@1.0.0#2"]);
    let sensing = node.child_supervisor("sensing").await.unwrap();
    assert_eq!(
        child_ids(sensing.which_children().await.unwrap()),
        ["beacon@1.0.0"]
    );
    let probes = node.instances("probe");
    assert_eq!(probes.len(), 2);
    assert_eq!(versions(&probes).await, vec!["1.0.0"; probes.len()]);
    assert_eq!(node.instances("beacon").len(), 1);

    // another instance the config allows: of the newest allowed version, under `dynamic`
    node.start_instance("probe", &semver::VersionReq::STAR)
        .await
        .unwrap();
    let probes = node.instances("probe");
    assert_eq!(probes.len(), 3);
    assert_eq!(versions(&probes).await, vec!["1.0.0"; probes.len()]);
    let dynamic = node.child_supervisor("dynamic").await.unwrap();
    assert_eq!(dynamic.which_children().await.unwrap().len(), 1);
    // version 2 is built in but this node does not host it
    match node.start_instance("probe", &"^2".parse().unwrap()).await {
        Err(NodeError::NotAllowed { operation, .. }) => assert_eq!(operation, "probe@^2"),
        other => panic!("expected NotAllowed, got {other:?}"),
    }
    match node
        .start_instance("nothing", &semver::VersionReq::STAR)
        .await
    {
        Err(NodeError::NotAllowed { allowed, .. }) => {
            assert_eq!(allowed, "probe@^1, beacon@*")
        }
        other => panic!("expected NotAllowed, got {other:?}"),
    }
    node.shutdown().await;
    assert!(node_gone("probe"));
}

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn a_crashed_provisioner_is_restarted_and_still_starts_instances_on_request() {
    let mut config = NodeConfig::new("n3");
    config
        .operations
        .push(OperationConfig::new("standby").with_instances(0));
    let node = Node::start(config, NodeOptions::with_catalog(catalog()))
        .await
        .unwrap();
    let root = node.supervisor();
    let provisioner = |children: Vec<marie_supervision::ChildInfo>| {
        children
            .into_iter()
            .find(|c| c.id == "provisioner")
            .and_then(|c| c.state.actor().cloned())
            .expect("a running provisioner")
    };
    let first = provisioner(root.which_children().await.unwrap());
    let mut events = root.subscribe().await.unwrap();
    first.kill();
    loop {
        match events.recv().await.unwrap() {
            marie_supervision::SupervisorEvent::ChildRestarted { id, .. }
                if id == "provisioner" =>
            {
                break
            }
            _ => {}
        }
    }
    let second = provisioner(root.which_children().await.unwrap());
    assert_ne!(first.get_id(), second.get_id());
    // published again: a request reaches it (no other node here allows `standby`)
    assert_eq!(node.instances("standby").len(), 0);
    let started = marie_actors::provision::request("standby", &semver::VersionReq::STAR).await;
    assert_eq!(started, Ok("n3".to_string()));
    assert_eq!(node.instances("standby").len(), 1);
    node.shutdown().await;
    assert!(node_gone("standby"));
}

fn node_gone(name: &str) -> bool {
    marie_vocabulary::registry::lookup(marie_vocabulary::registry::ModuleKind::Operation, name)
        .is_empty()
}

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn a_node_without_a_dispatcher_refuses_to_run_missions() {
    let mut config = NodeConfig::new("worker-only");
    config.dispatcher = false;
    config.operations.push(OperationConfig::new("silent"));
    let node = Node::start(config, NodeOptions::with_catalog(catalog()))
        .await
        .unwrap();
    let parsed = ParsedMission::parse(
        "[mission]\nname = \"m\"\n[[action]]\nname = \"a\"\n[action.ops.silent]\n",
        None,
    )
    .unwrap();
    let mission = node.check_mission(&parsed).await.unwrap();
    let err = node
        .run(mission, marie_cluster::node::RunOptions::new())
        .await
        .unwrap_err();
    assert!(matches!(err, NodeError::NoDispatcher(ref n) if n == "worker-only"));
    assert_eq!(
        err.to_string(),
        "node `worker-only` runs no dispatcher (its config says `dispatcher = false`)"
    );
    node.shutdown().await;
}

#[test]
fn a_config_as_a_rust_value_is_checked_against_the_catalog() {
    let catalog = catalog();
    let mut c = NodeConfig::new("n");
    c.operations.push(OperationConfig::new("probe"));
    assert_eq!(c.validate(&catalog), Ok(()));

    let mut bad = c.clone();
    bad.operations.push(OperationConfig::new("prob"));
    assert!(matches!(
        bad.validate(&catalog),
        Err(ConfigError::UnknownOperation { ref name, .. }) if name == "prob"
    ));

    let mut bad = c.clone();
    bad.operations[0].version = "^3".parse().unwrap();
    assert_eq!(
        bad.validate(&catalog).unwrap_err().to_string(),
        "operation `probe`: no version matches `^3` (available: 1.0.0, 2.1.0)"
    );

    let mut bad = c.clone();
    bad.operations[0].supervisor = "nobody".into();
    assert!(matches!(
        bad.validate(&catalog),
        Err(ConfigError::UnknownSupervisor { .. })
    ));

    let mut bad = c.clone();
    bad.operations[0].instances = 1000;
    assert!(matches!(
        bad.validate(&catalog),
        Err(ConfigError::Range { .. })
    ));

    let mut bad = c.clone();
    bad.name = " ".into();
    assert_eq!(bad.validate(&catalog), Err(ConfigError::NoName));
}

#[test]
fn the_embedded_default_hosts_one_instance_of_every_operation() {
    let catalog = catalog();
    let c = NodeConfig::everything("all", &catalog);
    assert_eq!(c.datamanagers.len(), 3);
    let hosted: Vec<String> = c.hosted(&catalog).iter().map(|(_, f)| f.key()).collect();
    assert_eq!(
        hosted,
        [
            "probe@1.0.0",
            "probe@2.1.0",
            "beacon@1.0.0",
            "silent@1.0.0",
            "standby@1.0.0"
        ]
    );
}

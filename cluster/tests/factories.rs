//! Operations built by the application: a closure (`operation_from`, `OperationFactory::
//! from_fn`) or a value cloned per instance (`operation_value`, `OperationFactory::
//! from_value`). What they capture reaches every instance — those the node starts, and
//! one its supervisor restarts after a panic — and a bad declaration is still refused
//! before anything starts. A node config that names an operation its program has no
//! factory for is refused at start, naming it.
//!
//! The registry is one per process and these tests run in parallel: each owns the operation
//! names it starts.

use marie_actors::eo::OperationFactory;
use marie_actors::eo::{EoClient, Identity, OpContext, OpError, Operation, Step};
use marie_cluster::node::{ConfigError, Node, NodeConfig, NodeError, NodeOptions, OperationConfig};
use marie_vocabulary::property::{ParamDecl, ParamSchema, PropertyReply, PropertyRequest, Value};
use marie_vocabulary::registry::{self, Instance, ModuleKind, RegistryEvent};
use marie_vocabulary::run::FaultKind;
use std::sync::Arc;
use std::time::Duration;

const T: Duration = Duration::from_secs(30);

/// What the application hands its operations: a plant, by name.
#[derive(Debug)]
struct Plant {
    name: String,
}

/// An operation that needs the application's plant; registered under `name` so each test
/// owns its registry entries.
#[derive(Clone)]
struct Tagged {
    name: &'static str,
    plant: Arc<Plant>,
    /// A declaration that is wrong on purpose, when set.
    bad: bool,
}

impl Operation for Tagged {
    fn identity(&self) -> Identity {
        Identity::new(self.name, 9301, "1.0.0", "tells its plant")
    }
    fn parameters(&self) -> ParamSchema {
        if self.bad {
            ParamSchema::new(vec![ParamDecl::float("flow", 9.0).range(0.0, 2.0)])
        } else {
            ParamSchema::default()
        }
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "plant").then(|| Value::Text(self.plant.name.clone()))
    }
}

/// The plant an instance was built with, asked through its property interface.
async fn plant_of(instance: &Instance) -> String {
    let client = EoClient::from_cell(instance.actor.clone());
    match client
        .property(PropertyRequest::Get("plant".into()))
        .await
        .expect("the instance answers")
    {
        PropertyReply::Value(Value::Text(plant)) => plant,
        other => panic!("`plant` answered {other:?}"),
    }
}

/// Every instance of `name` tells `plant`; then one panics, its supervisor builds a new
/// one with the same factory, and that one tells `plant` too.
async fn the_plant_reaches_every_instance_and_a_restarted_one(node: Node, name: &str, plant: &str) {
    let instances = registry::lookup(ModuleKind::Operation, name);
    assert_eq!(instances.len(), 2, "{instances:?}");
    for i in &instances {
        assert_eq!(plant_of(i).await, plant);
    }
    let mut watch = registry::watch(Some(ModuleKind::Operation))
        .await
        .expect("watch");
    let victim = &instances[0];
    EoClient::from_cell(victim.actor.clone())
        .inject(FaultKind::Panic)
        .expect("inject");
    let restarted = tokio::time::timeout(T, async {
        loop {
            match watch.next().await {
                Some(RegistryEvent::Joined(i))
                    if i.name == name
                        && instances
                            .iter()
                            .all(|o| o.actor.get_id() != i.actor.get_id()) =>
                {
                    return i
                }
                Some(_) => {}
                None => panic!("the registry watch ended"),
            }
        }
    })
    .await
    .expect("a restarted instance within the timeout");
    assert_eq!(plant_of(&restarted).await, plant);
    node.shutdown().await;
}

#[tokio::test]
async fn a_closures_dependency_reaches_every_instance_and_a_restarted_one() {
    let plant = Arc::new(Plant {
        name: "north".into(),
    });
    let node = Node::builder("deps-closure")
        .operation_factory(
            OperationFactory::from_fn(move || Tagged {
                name: "fx-closure",
                plant: plant.clone(),
                bad: false,
            }),
            |c| c.with_instances(2),
        )
        .start()
        .await
        .expect("starts");
    the_plant_reaches_every_instance_and_a_restarted_one(node, "fx-closure", "north").await;
}

#[tokio::test]
async fn a_values_clones_reach_every_instance_and_a_restarted_one() {
    let value = Tagged {
        name: "fx-value",
        plant: Arc::new(Plant {
            name: "south".into(),
        }),
        bad: false,
    };
    let node = Node::builder("deps-value")
        .operation_factory(OperationFactory::from_value(value), |c| c.with_instances(2))
        .start()
        .await
        .expect("starts");
    the_plant_reaches_every_instance_and_a_restarted_one(node, "fx-value", "south").await;
}

#[tokio::test]
async fn the_one_instance_shortcuts_host_one_built_instance() {
    let plant = Arc::new(Plant {
        name: "east".into(),
    });
    let from = plant.clone();
    let node = Node::builder("deps-shortcuts")
        .operation_from(move || Tagged {
            name: "fx-from",
            plant: from.clone(),
            bad: false,
        })
        .operation_value(Tagged {
            name: "fx-val",
            plant,
            bad: false,
        })
        .start()
        .await
        .expect("starts");
    for name in ["fx-from", "fx-val"] {
        let instances = registry::lookup(ModuleKind::Operation, name);
        assert_eq!(instances.len(), 1, "{name}: {instances:?}");
        assert_eq!(plant_of(&instances[0]).await, "east");
    }
    node.shutdown().await;
}

fn refused(started: Result<Node, NodeError>) -> NodeError {
    match started {
        Ok(_) => panic!("the node started"),
        Err(e) => e,
    }
}

#[tokio::test]
async fn a_built_operations_bad_declaration_is_refused_before_anything_starts() {
    let plant = Arc::new(Plant {
        name: "west".into(),
    });
    let err = refused(
        Node::builder("deps-bad")
            .operation_from(move || Tagged {
                name: "fx-bad",
                plant: plant.clone(),
                bad: true,
            })
            .start()
            .await,
    );
    let text = err.to_string();
    assert!(
        text.contains("operation `fx-bad`") && text.contains("flow"),
        "{text}"
    );
    assert!(registry::lookup(ModuleKind::Operation, "fx-bad").is_empty());
}

#[tokio::test]
async fn two_factories_of_one_operation_version_are_refused() {
    let plant = Arc::new(Plant {
        name: "twice".into(),
    });
    let (a, b) = (plant.clone(), plant);
    let err = refused(
        Node::builder("deps-twice")
            .operation_from(move || Tagged {
                name: "fx-twice",
                plant: a.clone(),
                bad: false,
            })
            .operation_from(move || Tagged {
                name: "fx-twice",
                plant: b.clone(),
                bad: false,
            })
            .start()
            .await,
    );
    assert!(
        matches!(&err, NodeError::Config(ConfigError::Duplicate { name, .. }) if name == "fx-twice@1.0.0"),
        "{err}"
    );
    assert!(registry::lookup(ModuleKind::Operation, "fx-twice").is_empty());
}

#[tokio::test]
async fn a_factory_that_panics_fails_the_start_it_was_asked_for_not_the_node() {
    let calls = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let counted = calls.clone();
    let plant = Arc::new(Plant {
        name: "flaky".into(),
    });
    // the first call names the operation; every later one panics
    let factory = OperationFactory::from_fn(move || {
        if counted.fetch_add(1, std::sync::atomic::Ordering::SeqCst) > 0 {
            panic!("no plant today");
        }
        Tagged {
            name: "fx-flaky",
            plant: plant.clone(),
            bad: false,
        }
    });
    let err = factory.check_declaration().expect_err("refused");
    assert!(err.to_string().contains("no plant today"), "{err}");
    let started = (factory.start)(Default::default(), None).await;
    let Err(e) = started else {
        panic!("an instance started")
    };
    assert!(e.to_string().contains("no plant today"), "{e}");
}

#[tokio::test]
async fn a_config_naming_an_operation_its_program_has_no_factory_for_is_refused_at_start() {
    // what a node process gets when its config names an operation its own program never
    // registered (a factory elsewhere in the cluster builds nothing here)
    let plant = Arc::new(Plant {
        name: "here".into(),
    });
    let catalog = vec![OperationFactory::from_fn(move || Tagged {
        name: "fx-known",
        plant: plant.clone(),
        bad: false,
    })];
    let mut config = NodeConfig::new("deps-missing");
    config.operations.push(OperationConfig::new("fx-elsewhere"));
    let err = refused(Node::start(config, NodeOptions::with_catalog(catalog)).await);
    let text = err.to_string();
    assert!(
        matches!(&err, NodeError::Config(ConfigError::UnknownOperation { name, .. }) if name == "fx-elsewhere"),
        "{text}"
    );
    assert!(
        text.contains("operation `fx-elsewhere` cannot be hosted")
            && text.contains("its own program registered")
            && text.contains("known: fx-known"),
        "{text}"
    );
    assert!(registry::lookup(ModuleKind::Operation, "fx-known").is_empty());
}

//! The EO host, end to end through its actor: the eo-interface and every property group and
//! collection.

use marie_actors::eo::{
    spawn_operation, EoClient, EoReport, HostOptions, Identity, OpContext, OpError, Operation,
    ParamOutcome, Step,
};
use marie_vocabulary::clock::ManualClock;
use marie_vocabulary::property::{
    param_map, Collection, Group, ParamDecl, ParamSchema, ParamType, PropertyReply,
    PropertyRequest, RejectReason, Value,
};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use std::sync::Arc;
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(10);

/// Counts steps; finishes after `steps` steps with flag bit 1 ("done"); raises bit 0
/// ("halfway") on the way; fails when `fail_at` is reached.
struct Stepper {
    name: &'static str,
    taken: i64,
}

impl Operation for Stepper {
    fn identity(&self) -> Identity {
        Identity::new(self.name, 4242, "2.1.0", "counts steps")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::int("steps", 3)
                .range(1.0, 1000.0)
                .describe("steps to take"),
            ParamDecl::float("gain", 0.5).range(0.0, 1.0).unit("1/s"),
            ParamDecl::int("fail_at", 0).range(0.0, 1000.0),
            ParamDecl::int("serial", 99).read_only(),
            ParamDecl::new(
                "pose",
                ParamType::Struct(vec![ParamDecl::float("x", 0.0), ParamDecl::float("y", 0.0)]),
                Value::Struct(
                    [
                        ("x".to_string(), Value::Float(0.0)),
                        ("y".to_string(), Value::Float(0.0)),
                    ]
                    .into(),
                ),
            ),
            ParamDecl::new(
                "gains",
                ParamType::Array {
                    item: Box::new(ParamDecl::float("item", 1.0).range(0.0, 10.0)),
                    min_len: 0,
                    max_len: 4,
                },
                Value::Array(vec![]),
            ),
        ])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![
            FlagDecl::new("halfway", "half done"),
            FlagDecl::new("done", "all done"),
        ]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(1)
    }
    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken += 1;
        let steps = ctx.params().i64("steps")?;
        if ctx.params().i64("fail_at")? == self.taken {
            return Err(OpError::failed("asked to fail"));
        }
        if self.taken * 2 >= steps {
            ctx.raise(StatusFlags(0b01));
        }
        Ok(if self.taken >= steps {
            Step::Finish(StatusFlags(0b10))
        } else {
            Step::Continue
        })
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "taken").then_some(Value::Int(self.taken))
    }
}

async fn host(name: &'static str) -> EoClient {
    let (actor, _) = spawn_operation(Stepper { name, taken: 0 }, HostOptions::default())
        .await
        .expect("host starts");
    EoClient::new(actor)
}

async fn ask(c: &EoClient, r: PropertyRequest) -> PropertyReply {
    c.property(r).await.expect("answer")
}

#[tokio::test]
async fn activation_finishes_with_flags_and_suspends() {
    let c = host("stepper-finish").await;
    let rx = c
        .activate(param_map([("steps", Value::Int(4))]), 1)
        .unwrap();
    let report = timeout(T, rx).await.unwrap().unwrap();
    assert_eq!(
        report,
        EoReport::Finished {
            flags: StatusFlags(0b11),
            epoch: 1
        }
    );
    // suspended, not stopped: it answers and can be activated again
    let PropertyReply::General(g) = ask(&c, PropertyRequest::Group(Group::General)).await else {
        panic!()
    };
    assert!(!g.in_use);
    assert_eq!(g.activations, 1);
    let rx = c.activate(Default::default(), 1).unwrap();
    assert!(matches!(
        timeout(T, rx).await.unwrap().unwrap(),
        EoReport::Finished { .. }
    ));
    assert_eq!(
        ask(&c, PropertyRequest::Get("taken".into())).await,
        PropertyReply::Value(Value::Int(4))
    );
    c.actor().stop(None);
}

#[tokio::test]
async fn suspend_reports_flags_raised_so_far() {
    let (actor, _) = spawn_operation(
        Stepper {
            name: "stepper-suspend",
            taken: 0,
        },
        HostOptions::with_clock(Arc::new(ManualClock::new())),
    )
    .await
    .unwrap();
    let c = EoClient::new(actor);
    // with a manual clock that never advances, the operation stays active after activation
    let rx = c
        .activate(param_map([("steps", Value::Int(1000))]), 7)
        .unwrap();
    let PropertyReply::General(g) = ask(&c, PropertyRequest::Group(Group::General)).await else {
        panic!()
    };
    assert!(g.in_use);
    c.suspend(7).unwrap();
    assert_eq!(
        timeout(T, rx).await.unwrap().unwrap(),
        EoReport::Suspended {
            flags: StatusFlags::EMPTY,
            epoch: 7
        }
    );
    c.actor().stop(None);
}

#[tokio::test]
async fn failure_is_reported_and_the_operation_survives() {
    let c = host("stepper-fail").await;
    let rx = c
        .activate(
            param_map([("steps", Value::Int(10)), ("fail_at", Value::Int(2))]),
            1,
        )
        .unwrap();
    match timeout(T, rx).await.unwrap().unwrap() {
        EoReport::Failed { reason, .. } => assert_eq!(reason, "asked to fail"),
        other => panic!("expected a failure, got {other:?}"),
    }
    assert!(matches!(
        ask(&c, PropertyRequest::Get("name".into())).await,
        PropertyReply::Value(Value::Text(_))
    ));
    c.actor().stop(None);
}

#[tokio::test]
async fn the_fail_first_activations_knob_fails_only_the_first_activations() {
    let opts = HostOptions {
        fail_first_activations: 2,
        ..Default::default()
    };
    let (actor, _) = spawn_operation(
        Stepper {
            name: "stepper-knob",
            taken: 0,
        },
        opts,
    )
    .await
    .unwrap();
    let c = EoClient::new(actor);
    for n in 1..=2 {
        let rx = c
            .activate(param_map([("steps", Value::Int(2))]), n)
            .unwrap();
        match timeout(T, rx).await.unwrap().unwrap() {
            EoReport::Failed { reason, epoch, .. } => {
                assert_eq!(epoch, n);
                assert!(
                    reason.contains(&format!("activation {n} of the first 2"))
                        && reason.contains("fail_first_activations"),
                    "{reason}"
                );
            }
            other => panic!("activation {n}: expected the knob's failure, got {other:?}"),
        }
    }
    // the operation itself never ran for those, and runs from the third on
    assert_eq!(
        ask(&c, PropertyRequest::Get("taken".into())).await,
        PropertyReply::Value(Value::Int(0))
    );
    let rx = c
        .activate(param_map([("steps", Value::Int(2))]), 3)
        .unwrap();
    assert!(matches!(
        timeout(T, rx).await.unwrap().unwrap(),
        EoReport::Finished { .. }
    ));
    c.actor().stop(None);
}

#[tokio::test]
async fn older_epochs_are_ignored() {
    let c = host("stepper-epoch").await;
    assert_eq!(
        c.parameterize(param_map([("gain", Value::Float(0.25))]), 5)
            .await
            .unwrap(),
        ParamOutcome::Applied
    );
    assert_eq!(
        c.parameterize(param_map([("gain", Value::Float(0.75))]), 4)
            .await
            .unwrap(),
        ParamOutcome::Stale { current: 5 }
    );
    let rx = c.activate(Default::default(), 3).unwrap();
    assert_eq!(
        timeout(T, rx).await.unwrap().unwrap(),
        EoReport::Stale {
            epoch: 3,
            current: 5
        }
    );
    assert_eq!(
        ask(&c, PropertyRequest::Get("param.gain".into())).await,
        PropertyReply::Value(Value::Float(0.25))
    );
    c.actor().stop(None);
}

#[tokio::test]
async fn reparameterization_is_atomic_with_a_reason_per_value() {
    let c = host("stepper-atomic").await;
    let before = ask(&c, PropertyRequest::Collection(Collection::Current)).await;
    let outcome = c
        .parameterize(
            param_map([
                ("gain", Value::Float(0.9)),          // fine on its own
                ("steps", Value::Int(5000)),          // out of range
                ("speed", Value::Float(1.0)),         // unknown
                ("serial", Value::Int(1)),            // read-only
                ("fail_at", Value::Text("x".into())), // wrong type
            ]),
            1,
        )
        .await
        .unwrap();
    let ParamOutcome::Rejected(rej) = outcome else {
        panic!("expected a rejection, got {outcome:?}")
    };
    let reasons: Vec<(&str, &RejectReason)> =
        rej.iter().map(|r| (r.name.as_str(), &r.reason)).collect();
    assert_eq!(reasons.len(), 4);
    assert!(matches!(
        reasons[0],
        ("fail_at", RejectReason::WrongType { .. })
    ));
    assert!(matches!(reasons[1], ("serial", RejectReason::ReadOnly)));
    assert!(matches!(reasons[2], ("speed", RejectReason::UnknownName)));
    assert!(matches!(
        reasons[3],
        ("steps", RejectReason::OutOfRange { .. })
    ));
    // every old value is still in place, including the one that was fine
    assert_eq!(
        ask(&c, PropertyRequest::Collection(Collection::Current)).await,
        before
    );
    // and an activation with a bad value does not start
    let rx = c
        .activate(param_map([("gain", Value::Float(7.0))]), 1)
        .unwrap();
    assert!(matches!(
        timeout(T, rx).await.unwrap().unwrap(),
        EoReport::Rejected { .. }
    ));
    c.actor().stop(None);
}

#[tokio::test]
async fn every_property_group_and_collection() {
    let c = host("stepper-props").await;
    assert_eq!(
        c.parameterize(
            param_map([
                ("gain", Value::Float(0.25)),
                (
                    "pose",
                    Value::Struct([("x".to_string(), Value::Int(2))].into())
                ),
                (
                    "gains",
                    Value::Array(vec![Value::Float(1.5), Value::Int(2)])
                ),
            ]),
            1
        )
        .await
        .unwrap(),
        ParamOutcome::Applied
    );

    let PropertyReply::Identification(id) =
        ask(&c, PropertyRequest::Group(Group::Identification)).await
    else {
        panic!()
    };
    assert_eq!(
        (&*id.name, id.id, &*id.version),
        ("stepper-props", 4242, "2.1.0")
    );

    let PropertyReply::Location(loc) = ask(&c, PropertyRequest::Group(Group::Location)).await
    else {
        panic!()
    };
    assert!(loc.alive);
    assert_eq!(loc.node, registry::local_node_name());
    assert_eq!(loc.address, c.actor().get_id().to_string());

    let PropertyReply::General(g) = ask(&c, PropertyRequest::Group(Group::General)).await else {
        panic!()
    };
    assert_eq!(g.param_count, 6);
    assert!(!g.in_use);

    let PropertyReply::Specific(s) = ask(&c, PropertyRequest::Group(Group::Specific)).await else {
        panic!()
    };
    assert_eq!(s.params.len(), 6);
    let gain = &s.params[1];
    assert_eq!(
        (gain.min, gain.max, gain.unit.as_deref()),
        (Some(0.0), Some(1.0), Some("1/s"))
    );
    assert!(s.params[3].read_only);
    assert!(matches!(s.params[4].ty, ParamType::Struct(_)));
    assert!(matches!(s.params[5].ty, ParamType::Array { .. }));
    assert_eq!(s.previous["gain"], Value::Float(0.5));
    assert_eq!(s.current["gain"], Value::Float(0.25));
    assert_eq!(
        s.current["pose"],
        Value::Struct(
            [
                ("x".to_string(), Value::Float(2.0)),
                ("y".to_string(), Value::Float(0.0))
            ]
            .into()
        )
    );
    assert_eq!(
        s.current["gains"],
        Value::Array(vec![Value::Float(1.5), Value::Float(2.0)])
    );
    assert_eq!(s.flags[1].name, "done");

    let PropertyReply::Address(a) = ask(&c, PropertyRequest::Collection(Collection::Address)).await
    else {
        panic!()
    };
    assert_eq!((a.name.as_str(), a.id), ("stepper-props", 4242));

    let PropertyReply::Signature(sig) =
        ask(&c, PropertyRequest::Collection(Collection::Signature)).await
    else {
        panic!()
    };
    assert_eq!(sig.count, 6);
    assert_eq!(sig.params[0], ("steps".to_string(), ParamType::Int));

    let PropertyReply::Limits(lim) = ask(&c, PropertyRequest::Collection(Collection::Limits)).await
    else {
        panic!()
    };
    assert_eq!(lim[0].default, Value::Int(3));
    assert_eq!((lim[0].min, lim[0].max), (Some(1.0), Some(1000.0)));

    let PropertyReply::Previous(prev) =
        ask(&c, PropertyRequest::Collection(Collection::Previous)).await
    else {
        panic!()
    };
    assert_eq!(prev["gain"], Value::Float(0.5));
    let PropertyReply::Current(cur) =
        ask(&c, PropertyRequest::Collection(Collection::Current)).await
    else {
        panic!()
    };
    assert_eq!(cur["gain"], Value::Float(0.25));

    for name in marie_vocabulary::property::STANDARD_PROPERTIES {
        assert!(
            matches!(
                ask(&c, PropertyRequest::Get(name.to_string())).await,
                PropertyReply::Value(_)
            ),
            "standard property {name}"
        );
    }
    assert_eq!(
        ask(&c, PropertyRequest::Get("colour".into())).await,
        PropertyReply::NotFound("colour".into())
    );
    assert_eq!(
        ask(&c, PropertyRequest::Get("param.nope".into())).await,
        PropertyReply::NotFound("param.nope".into())
    );
    c.actor().stop(None);
}

#[tokio::test]
async fn bad_declarations_and_start_up_values_fail_the_spawn() {
    struct Bad;
    impl Operation for Bad {
        fn identity(&self) -> Identity {
            Identity::new("bad-decl", 1, "0.1.0", "")
        }
        fn parameters(&self) -> ParamSchema {
            ParamSchema::new(vec![ParamDecl::float("x", 5.0).range(0.0, 1.0)])
        }
        async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
            Ok(Step::Continue)
        }
    }
    assert!(spawn_operation(Bad, HostOptions::default()).await.is_err());
    let opts = HostOptions {
        params: param_map([("steps", Value::Int(-1))]),
        ..Default::default()
    };
    assert!(spawn_operation(
        Stepper {
            name: "stepper-badstart",
            taken: 0
        },
        opts
    )
    .await
    .is_err());
    // read-only parameters can be set at start-up
    let opts = HostOptions {
        params: param_map([("serial", Value::Int(7))]),
        ..Default::default()
    };
    let (actor, _) = spawn_operation(
        Stepper {
            name: "stepper-ro",
            taken: 0,
        },
        opts,
    )
    .await
    .unwrap();
    let c = EoClient::new(actor);
    assert_eq!(
        ask(&c, PropertyRequest::Get("param.serial".into())).await,
        PropertyReply::Value(Value::Int(7))
    );
    c.actor().stop(None);
}

#[tokio::test]
async fn registry_entry_appears_and_vanishes_with_the_actor() {
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.unwrap();
    let (actor, handle) = spawn_operation(
        Stepper {
            name: "stepper-registry",
            taken: 0,
        },
        HostOptions::default(),
    )
    .await
    .unwrap();
    let me = actor.get_id();
    for key in ["stepper-registry", "4242"] {
        let found = registry::lookup(ModuleKind::Operation, key);
        assert!(found.iter().any(|i| i.actor_id() == me), "lookup {key}");
    }
    let inst = registry::lookup(ModuleKind::Operation, "stepper-registry")
        .into_iter()
        .find(|i| i.actor_id() == me)
        .unwrap();
    assert_eq!((inst.id, inst.name.as_str()), (4242, "stepper-registry"));
    assert!(inst.is_local());
    assert!(registry::render_listing(&[inst]).contains("EO found 0: ID: 4242 node: local"));
    // the watch saw the join
    loop {
        let evt = timeout(T, watch.next()).await.unwrap().unwrap();
        if let registry::RegistryEvent::Joined(i) = &evt {
            if i.actor_id() == me {
                break;
            }
        }
    }
    // crash-free stop: the entry goes away by itself
    actor.kill();
    timeout(T, handle).await.unwrap().unwrap();
    assert!(registry::lookup(ModuleKind::Operation, "stepper-registry")
        .iter()
        .all(|i| i.actor_id() != me));
    loop {
        let evt = timeout(T, watch.next()).await.unwrap().unwrap();
        if let registry::RegistryEvent::Left(i) = &evt {
            if i.actor_id() == me {
                break;
            }
        }
    }
}

/// Records when each of its steps came, on its node's clock; never finishes.
struct Metronome {
    steps: Arc<std::sync::Mutex<Vec<Duration>>>,
}

impl Operation for Metronome {
    fn identity(&self) -> Identity {
        Identity::new("metronome", 4243, "1.0.0", "steps at its period")
    }
    fn period(&self) -> Duration {
        Duration::from_millis(100)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.steps.lock().unwrap().push(ctx.clock().now());
        Ok(Step::Continue)
    }
}

#[tokio::test(start_paused = true)]
async fn a_slow_fault_stretches_the_time_between_an_operations_steps() {
    use marie_vocabulary::run::FaultKind;
    let steps = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (actor, _) = spawn_operation(
        Metronome {
            steps: steps.clone(),
        },
        HostOptions::default(),
    )
    .await
    .unwrap();
    let c = EoClient::new(actor.clone());
    let _running = c.activate(Default::default(), 1).unwrap();
    // virtual time: the paused runtime moves on whenever every task waits
    tokio::time::sleep(Duration::from_millis(1050)).await;
    c.inject(FaultKind::Slow).unwrap();
    tokio::time::sleep(Duration::from_millis(3050)).await;
    let at = steps.lock().unwrap().clone();
    let gaps: Vec<u128> = at.windows(2).map(|w| (w[1] - w[0]).as_millis()).collect();
    let slowed = gaps.iter().position(|g| *g > 100).expect("a longer gap");
    assert!(slowed >= 8, "its period before the fault: {gaps:?}");
    assert!(gaps[..slowed].iter().all(|g| *g == 100), "{gaps:?}");
    let period = 100 * u128::from(FaultKind::SLOW_FACTOR);
    assert!(gaps[slowed + 1..].iter().all(|g| *g == period), "{gaps:?}");
    assert!(gaps.len() - slowed >= 5, "{gaps:?}");
    // slow, not hung: it still answers
    assert!(matches!(
        ask(&c, PropertyRequest::Group(Group::General)).await,
        PropertyReply::General(g) if g.in_use
    ));
    actor.stop(None);
}

#[tokio::test]
async fn a_new_dispatcher_attaches_to_the_running_activation_without_disturbing_it() {
    let (actor, _) = spawn_operation(
        Stepper {
            name: "stepper-attach",
            taken: 0,
        },
        HostOptions::with_clock(Arc::new(ManualClock::new())),
    )
    .await
    .unwrap();
    let c = EoClient::new(actor);
    // the lost dispatcher's activation, under epoch 7: it runs (the clock never advances)
    let lost = c
        .activate(param_map([("steps", Value::Int(1000))]), 7)
        .unwrap();
    // an older epoch cannot attach
    let stale = c.attach(6, 7).unwrap();
    assert_eq!(
        timeout(T, stale).await.unwrap().unwrap(),
        EoReport::Stale {
            epoch: 6,
            current: 7
        }
    );
    // the standby, under epoch 8, takes the activation over: still the one activation
    let attached = c.attach(8, 7).unwrap();
    let PropertyReply::General(g) = ask(&c, PropertyRequest::Group(Group::General)).await else {
        panic!()
    };
    assert!(g.in_use);
    assert_eq!(g.activations, 1, "attaching started no new activation");
    // the lost dispatcher's port hears nothing more; its commands are stale now
    assert!(timeout(T, lost).await.unwrap().is_err());
    c.suspend(7).unwrap();
    let PropertyReply::General(g) = ask(&c, PropertyRequest::Group(Group::General)).await else {
        panic!()
    };
    assert!(g.in_use, "a suspend of the old epoch was obeyed");
    // the new one's suspend ends it, reported on the attached port
    c.suspend(8).unwrap();
    assert_eq!(
        timeout(T, attached).await.unwrap().unwrap(),
        EoReport::Suspended {
            flags: StatusFlags::EMPTY,
            epoch: 8
        }
    );
    // nothing runs now: an attach is answered at once, idle
    let idle = c.attach(9, 8).unwrap();
    assert_eq!(
        timeout(T, idle).await.unwrap().unwrap(),
        EoReport::Idle { epoch: 9 }
    );
    c.actor().stop(None);
}

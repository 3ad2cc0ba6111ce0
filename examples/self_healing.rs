//! Self-healing in an embedding application: an operation under a supervisor, a mission
//! driven by the dispatcher, and a panic injected mid-action. The supervisor restarts the
//! operation, the dispatcher rebinds to the new instance, restores its parameters and
//! re-activates it, and the mission carries on.
//!
//! `cargo run --example self_healing`

use marie::actors::dispatcher::mission::Mission;
use marie::actors::dispatcher::{run_mission, RegistryCatalog};
use marie::actors::eo::{
    spawn_operation_linked, EoClient, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie::actors::events::{EventBus, EventKind};
use marie::actors::flags::{FlagDecl, StatusFlags};
use marie::actors::property::{Group, ParamDecl, ParamSchema, PropertyReply, PropertyRequest};
use marie::actors::registry::{self, ModuleKind};
use marie::actors::run::FaultKind;
use marie::fault::{Injector, Target};
use marie::supervision::{ChildSpec, Supervisor, SupervisorSpec};
use std::time::Duration;

/// Pumps `litres` litres, one per step.
#[derive(Default)]
struct Pump {
    pumped: i64,
}

impl Operation for Pump {
    fn identity(&self) -> Identity {
        Identity::new("pump", 7001, "1.0.0", "pumps a number of litres")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("litres", 10)
            .range(1.0, 10_000.0)
            .unit("l")
            .describe("how much to pump")])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("full", "the tank is full")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(1)
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.pumped = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.pumped += 1;
        Ok(if self.pumped >= ctx.params().i64("litres")? {
            Step::Finish(StatusFlags(1))
        } else {
            Step::Continue
        })
    }
}

const MISSION: &str = r#"
[mission]
name = "fill"
success = ["full"]
[flags]
full = 0
[[action]]
name = "pump"
[action.ops.pump]
litres = 500
"#;

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A one_for_one supervisor restarts the pump whenever it dies (at most 3 times in 5 s).
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(3, Duration::from_secs(5)),
        vec![ChildSpec::worker("pump", |sup| async move {
            let (actor, _) =
                spawn_operation_linked(Pump::default(), HostOptions::default(), sup).await?;
            Ok(actor.get_cell())
        })],
    )
    .await?;

    let parsed = Mission::parse(MISSION, None)?;
    let catalog = RegistryCatalog::gather(parsed.ops()).await?;
    let mission = parsed.validate(&catalog)?;
    let clock = marie::actors::clock::RealClock::shared();
    let bus = EventBus::new("example", clock.clone());
    let mut events = bus.subscribe();
    let injector = Injector::new(&bus);
    let run = tokio::spawn(run_mission(mission, clock, Some(bus)));

    // Once the pump runs, make it panic.
    let first = registry::lookup(ModuleKind::Operation, "pump")[0]
        .actor
        .clone();
    let client = EoClient::from_cell(first.clone());
    loop {
        match client
            .property(PropertyRequest::Group(Group::General))
            .await?
        {
            PropertyReply::General(g) if g.in_use => break,
            _ => tokio::time::sleep(Duration::from_millis(1)).await,
        }
    }
    let hit = injector
        .inject(FaultKind::Panic, &Target::Bound("pump".into()))
        .await?;
    println!("injected a panic into pump ({})", hit.victim());

    let report = run.await??;
    for evt in events.drain() {
        match evt.kind {
            EventKind::Lost { operation, cause } => println!("lost {operation}: {cause}"),
            EventKind::Rebound(r) => println!(
                "rebound {}: {} -> {} after {} ms",
                r.operation, r.from, r.to, r.downtime_ms
            ),
            _ => {}
        }
    }
    println!(
        "mission {:?} with {} rebind(s)",
        report.outcome,
        report.rebinds.len()
    );
    sup.stop().await;
    if report.succeeded()
        && report.rebinds.len() == 1
        && report.rebinds[0].from == first.get_id().to_string()
    {
        Ok(())
    } else {
        Err(format!("unexpected report: {report:?}").into())
    }
}

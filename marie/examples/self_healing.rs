//! Self-healing in an application: an operation under a supervisor of the application's
//! own, a mission, and a panic injected while the operation runs. The supervisor restarts
//! the operation, the dispatcher rebinds to the new instance, restores its parameters and
//! re-activates it, and the mission carries on. The run's events are printed as they come.
//!
//! Run with `cargo run -p marie --example self_healing`.

use marie::cluster::node::SupervisorConfig;
use marie::events::EventKind;
use marie::prelude::*;
use marie::{Node, RunOptions};
use std::time::Duration;

params! {
    /// What a fill is given.
    struct FillParams {
        /// how much to pump
        litres: i64 = 10, range(1, 10_000), unit("l");
    }
}

flags! {
    /// What a fill reports.
    enum FillFlag {
        /// the tank is full
        Full = "full",
    }
}

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
        FillParams::schema()
    }
    fn flags(&self) -> Vec<FlagDecl> {
        FillFlag::decls()
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
        let fill: FillParams = ctx.params().read()?;
        Ok(if self.pumped >= fill.litres {
            Step::finish(FillFlag::Full)
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
    // a one_for_one supervisor restarts the pump whenever it dies (at most 3 times in 5 s)
    let node = Node::builder("plant")
        .supervisor(SupervisorConfig::new("pumps").with_intensity(3, Duration::from_secs(5)))
        .operation_with::<Pump>(|op| op.under("pumps"))
        .start()
        .await?;

    // a tenth of a second into the run, the pump panics; the run's events as they come
    let options = RunOptions::new()
        .fault("panic:pump@0.1".parse()?)
        .observe(|event| match &event.kind {
            EventKind::FaultInjected { fault, actor, .. } => {
                println!("injected a {fault} into pump ({actor})")
            }
            EventKind::Lost { operation, cause } => println!("lost {operation}: {cause}"),
            EventKind::Rebound(r) => println!(
                "rebound {}: {} -> {} after {} ms",
                r.operation, r.from, r.to, r.downtime_ms
            ),
            _ => {}
        });
    let report = node.run(MISSION, options).await?;
    println!(
        "mission {:?} with {} rebind(s)",
        report.outcome,
        report.rebinds.len()
    );
    node.shutdown().await;
    let hit = report.faults.first().map(|f| f.actor.clone());
    if report.succeeded()
        && report.rebinds.len() == 1
        && hit == Some(report.rebinds[0].from.clone())
    {
        Ok(())
    } else {
        Err(format!("unexpected report: {report:?}").into())
    }
}

//! Embedding marie: a user-defined operation, hosted, asked for its properties, and driven by
//! a mission — all in one process.
//!
//! Run with `cargo run --example custom_operation`.

use marie::actors::clock::RealClock;
use marie::actors::dispatcher::{self, mission::Mission, RegistryCatalog};
use marie::actors::eo::{self, EoClient, Identity, OpContext, OpError, Operation, Step};
use marie::actors::flags::{FlagDecl, StatusFlags};
use marie::actors::property::{Group, ParamDecl, ParamSchema, PropertyRequest, Value};

// --- the operation: walks the Collatz sequence from `start` down to 1 -----------------------
#[derive(Default)]
struct Collatz {
    n: i64,
    steps: i64,
}

impl Operation for Collatz {
    fn identity(&self) -> Identity {
        Identity::new("collatz", 7001, "1.0.0", "walks a Collatz sequence to 1")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("start", 27)
            .range(1.0, 1e12)
            .describe("first number")])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("reached-one", "the sequence reached 1")]
    }
    fn period(&self) -> std::time::Duration {
        std::time::Duration::from_millis(1)
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        (self.n, self.steps) = (ctx.params().i64("start")?, 0);
        Ok(Step::Continue)
    }
    async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        if self.n == 1 {
            return Ok(Step::Finish(StatusFlags(1)));
        }
        self.n = if self.n % 2 == 0 {
            self.n / 2
        } else {
            3 * self.n + 1
        };
        self.steps += 1;
        Ok(Step::Continue)
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "steps").then_some(Value::Int(self.steps))
    }
}
// ---------------------------------------------------------------------------------------------

const MISSION: &str = r#"
[mission]
name = "collatz-demo"
success = ["reached-one"]

[flags]
reached-one = 0

[[action]]
name = "walk"
[action.ops.collatz]
start = 97
"#;

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. host it: it publishes itself in the location table
    let (actor, _) = eo::spawn_operation(Collatz::default(), Default::default()).await?;
    let client = EoClient::new(actor.clone());

    // 2. ask it about itself
    let ident = client
        .property(PropertyRequest::Group(Group::Identification))
        .await?;
    let specific = client
        .property(PropertyRequest::Group(Group::Specific))
        .await?;
    println!("{ident:?}\n{specific:?}");

    // 3. drive it with a mission, checked against what is running
    let parsed = Mission::parse(MISSION, None)?;
    let catalog = RegistryCatalog::gather(parsed.ops()).await?;
    let mission = parsed.validate(&catalog)?;
    let report = dispatcher::run_mission(mission, RealClock::shared(), None).await?;
    let steps = client
        .property(PropertyRequest::Get("steps".into()))
        .await?;
    println!(
        "outcome: {:?}, flags: {:?}, steps: {steps:?}",
        report.outcome, report.flags
    );
    actor.stop(None);
    Ok(())
}

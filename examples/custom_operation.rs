//! Embedding marie: a user-defined operation, hosted, asked for its properties, and driven by
//! a mission — all in one process. Its parameters and flags are declared with
//! [`params!`](marie::actors::params) and [`flags!`](marie::actors::flags!): the operation's code
//! names them by Rust identifiers, so a typo is a compile error, not a failed run.
//!
//! Run with `cargo run --example custom_operation`.

use marie::actors::clock::RealClock;
use marie::actors::dispatcher::{self, mission::Mission, RegistryCatalog};
use marie::actors::eo::{self, EoClient};
use marie::actors::property::{Group, PropertyRequest};
use marie::prelude::*;
use std::time::Duration;

// --- the operation: walks the Collatz sequence from `start` down to 1 -----------------------
params! {
    /// What a walk is given.
    struct CollatzParams {
        /// first number
        start: i64 = 27, range(1, 1_000_000_000_000);
    }
}

flags! {
    /// What a walk reports.
    enum CollatzFlag {
        /// the sequence reached 1
        ReachedOne = "reached-one",
    }
}

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
        CollatzParams::schema()
    }
    fn flags(&self) -> Vec<FlagDecl> {
        CollatzFlag::decls()
    }
    fn period(&self) -> Duration {
        Duration::from_millis(1)
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: CollatzParams = ctx.params().read()?;
        (self.n, self.steps) = (p.start, 0);
        Ok(Step::Continue)
    }
    async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        if self.n == 1 {
            return Ok(Step::finish(CollatzFlag::ReachedOne));
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

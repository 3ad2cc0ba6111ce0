//! Your own operation, hosted on a node, asked about itself and driven by a mission — all in
//! one process. Its parameters and flags are declared with [`params!`](marie::params)
//! and [`flags!`](marie::flags!): the operation's code names them by Rust
//! identifiers, so a typo is a compile error, not a failed run.
//!
//! Run with `cargo run -p marie --example custom_operation`.

use marie::prelude::*;
use marie::property::PropertyRequest;
use marie::{Node, OperationHandle, RunOptions};
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
    /// An operation-specific property beside the standard ones: how far the walk went.
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
    // 1. host it on a node: its declarations are checked first, then it runs under
    //    supervision and publishes itself in the location table
    let node = Node::builder("collatz-node")
        .operation::<Collatz>()
        .start()
        .await?;

    // 2. ask it about itself, by name
    let collatz = OperationHandle::lookup("collatz").await?;
    println!(
        "{:?}\n{:?}",
        collatz.identity().await?,
        collatz.schema().await?
    );

    // 3. drive it with a mission, checked against what runs
    let report = node.run(MISSION, RunOptions::new()).await?;
    let steps = collatz
        .client()
        .property(PropertyRequest::Get("steps".into()))
        .await?;
    println!(
        "outcome: {:?}, flags: {:?}, steps: {steps:?}",
        report.outcome, report.flags
    );
    node.shutdown().await;
    Ok(())
}

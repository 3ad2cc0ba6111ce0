//! A complete application on marie (`cargo run --example embedding`): its own operation and
//! datamanager under its own supervisor, asked about itself, a mission built in code, and a
//! panic healed while it runs.

use marie::cluster::node::{Node, RunOptions, SupervisorConfig};
use marie::dispatcher::mission::{ActionBuilder, MissionBuilder};
use marie::eo::{OperationHandle, SetError};
use marie::prelude::*;
use std::time::Duration;

/// The application's own datamanager, and the records it keeps: tank levels in litres.
const TANKS: DmSpec = DmSpec::new("tanks", 7900);
const LEVEL: RecordKind<f64> = RecordKind::new("level");

params! {
    /// What a fill is given.
    pub struct FillParams {
        /// how much to pump
        litres: i64 = 10, range(1, 10_000), unit("l");
        /// how much per step
        rate: f64 = 1.0, range(0.1, 5.0), unit("l");
    }
}

flags! {
    /// What a fill reports.
    pub enum FillFlag {
        /// the tank is full
        Full = "full",
    }
}

/// Pumps until the tank holds `litres`, logging each level; a restart resumes at the last.
#[derive(Default)]
struct Pump {
    level: f64,
}

impl Operation for Pump {
    fn identity(&self) -> Identity {
        Identity::new("pump", 7001, "1.0.0", "fills a tank")
    }
    fn parameters(&self) -> ParamSchema {
        FillParams::schema()
    }
    fn flags(&self) -> Vec<FlagDecl> {
        FillFlag::decls()
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let last = ctx.dm(TANKS)?.newest_kind(LEVEL).await?;
        self.level = last
            .filter(|_| ctx.resumed())
            .map_or(0.0, |(_, level)| level);
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: FillParams = ctx.params().read()?;
        self.level += p.rate;
        ctx.dm(TANKS)?.store_kind(LEVEL, &self.level).await?;
        if self.level < p.litres as f64 {
            return Ok(Step::Continue);
        }
        Ok(Step::finish(FillFlag::Full))
    }
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let node = Node::builder("plant")
        .datamanager(TANKS)
        .supervisor(SupervisorConfig::new("pumps").with_intensity(3, Duration::from_secs(5)))
        .operation_with::<Pump>(|op| op.under("pumps"))
        .start()
        .await?;

    // the pump, asked about itself by name; a value out of range is refused with reasons
    let pump = OperationHandle::lookup("pump").await?;
    let (who, schema) = (pump.identity().await?, pump.schema().await?);
    println!(
        "{} {} on {}: {:?}",
        who.name,
        who.version,
        pump.node(),
        schema.names()
    );
    let too_fast = ParamMap::new().with(FillParams::rate(), 50.0);
    match pump.set(too_fast).await {
        Err(SetError::Rejected { rejections, .. }) => println!("refused: {}", rejections[0]),
        other => return Err(format!("a rate of 50 should be refused: {other:?}").into()),
    }

    // a mission built in code; half a second into it (a step every 100 ms), the pump panics
    let fill = ParamMap::new()
        .with(FillParams::litres(), 40)
        .with(FillParams::rate(), 2.0);
    let mission = MissionBuilder::new("fill")
        .flags([FillFlag::Full.name()])
        .success([FillFlag::Full.name()])
        .action(ActionBuilder::new("pump").op("pump", fill));
    let faults = RunOptions::new().fault("panic:pump@0.5".parse()?);
    let report = node.run(mission, faults).await?;
    for r in &report.rebinds {
        println!("healed: {} -> {} in {} ms", r.from, r.to, r.downtime_ms);
    }

    // every level the pump logged, the crashed instance's and the restarted one's
    let tanks = DmClient::lookup(TANKS.name, "app")?;
    let levels = tanks.select_kind(LEVEL, Query::all()).await?;
    let last = levels.last().map_or(0.0, |(_, level)| *level);
    println!(
        "{:?}: {} levels, the last {last} l",
        report.outcome,
        levels.len()
    );
    node.shutdown().await;
    assert!(report.succeeded() && report.rebinds.len() == 1 && last >= 40.0);
    Ok(())
}

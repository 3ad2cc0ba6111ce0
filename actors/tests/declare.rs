//! Typed declarations, end to end: an operation declared with `params!`, `flags!`, a
//! datamanager constant and a record kind, driven by a mission through the real dispatcher.
//! What the macros generate must mean, to the host and the dispatcher, what the hand-written
//! declarations meant.

use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_actors::eo::{spawn_operation, HostOptions};
use marie_actors::prelude::*;
use marie_dm::{self as dm, DmArgs, DmConfig};
use marie_vocabulary::clock::RealClock;
use std::time::Duration;

marie_actors::choice! {
    /// How loud the walk is.
    pub enum Mode {
        /// raise nothing extra
        Quiet = "quiet",
        /// also raise `typed-loud`
        Loud = "loud",
    }
}

marie_actors::params! {
    /// The walk's parameters.
    pub struct WalkParams {
        /// steps to take
        pub steps: i64 = 2, range(1, 100);
        /// how loud
        pub mode: Mode = Mode::Quiet;
    }
}

marie_actors::flags! {
    /// What the walk reports.
    pub enum WalkFlag {
        /// the walk started
        Started = "typed-started",
        /// the walk is done
        Done = "typed-done",
        /// the walk was loud
        Loud = "typed-loud",
    }
}

const STEPS_DM: DmSpec = DmSpec::new("typed-steps", 4901);
const TAKEN: RecordKind<i64> = RecordKind::new("walk").with_sub1("taken");

#[derive(Default)]
struct Walk {
    params: Option<WalkParams>,
    taken: i64,
}

impl Operation for Walk {
    fn identity(&self) -> Identity {
        Identity::new("typed-walk", 4902, "1.0.0", "walks, declared with types")
    }
    fn parameters(&self) -> ParamSchema {
        WalkParams::schema()
    }
    fn flags(&self) -> Vec<FlagDecl> {
        WalkFlag::decls()
    }
    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.params = Some(ctx.params().read()?);
        self.taken = 0;
        ctx.raise(WalkFlag::Started);
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = self
            .params
            .as_ref()
            .ok_or(OpError::failed("not activated"))?;
        self.taken += 1;
        ctx.dm(STEPS_DM)?.store_kind(TAKEN, &self.taken).await?;
        if self.taken < p.steps {
            return Ok(Step::Continue);
        }
        Ok(match p.mode {
            Mode::Quiet => Step::finish(WalkFlag::Done),
            Mode::Loud => Step::finish(WalkFlag::Done | WalkFlag::Loud),
        })
    }
}

#[tokio::test]
async fn a_typed_operation_reports_the_flags_the_mission_names_and_stores_typed_records() {
    let clock = RealClock::shared();
    let (dm_actor, _) = dm::spawn_datamanager(DmArgs {
        id: STEPS_DM.id,
        name: STEPS_DM.name.into(),
        clock: clock.clone(),
        config: DmConfig::default(),
        durability: Default::default(),
        journal_dir: None,
        replication: None,
        events: None,
        heir: None,
    })
    .await
    .unwrap();
    let (op, _) = spawn_operation(Walk::default(), HostOptions::default())
        .await
        .unwrap();

    // global bits unlike the local ones, so a wrong local bit shows as a wrong name
    let src = r#"
        [mission]
        name = "typed"
        success = ["typed-done", "typed-loud"]
        [flags]
        typed-loud = 4
        typed-started = 9
        typed-done = 2
        [[action]]
        name = "walk"
        [action.ops.typed-walk]
        steps = 3
        mode = "loud"
    "#;
    let parsed = ParsedMission::parse(src, None).unwrap();
    let catalog = RegistryCatalog::gather(parsed.ops()).await.unwrap();
    let mission = parsed.validate(&catalog).unwrap();
    let report = tokio::time::timeout(Duration::from_secs(30), run_mission(mission, clock, None))
        .await
        .unwrap()
        .unwrap();

    assert!(report.succeeded(), "{}", report.reason);
    assert_eq!(report.status, 1 << 4 | 1 << 9 | 1 << 2);
    let mut flags = report.flags.clone();
    flags.sort();
    assert_eq!(flags, ["typed-done", "typed-loud", "typed-started"]);

    // the mission's `steps = 3` reached the typed read; every step stored a typed record
    let client = DmClient::new(dm_actor.clone(), "test");
    let taken = client
        .select_kind(TAKEN, Query::all())
        .await
        .unwrap()
        .into_iter()
        .map(|(h, n)| (String::from(h.source), n))
        .collect::<Vec<_>>();
    assert_eq!(
        taken,
        [1, 2, 3].map(|n| ("typed-walk".to_string(), n)).to_vec()
    );
    op.stop(None);
    dm_actor.stop(None);
}

#[test]
fn a_datamanager_error_becomes_an_op_error_naming_the_datamanager_where_known() {
    // a DM absent at the call is an unreachable module (the host waits for it), in the
    // words of any DM error
    let missing: OpError = DmError::NotRegistered("nowhere".into()).into();
    assert_eq!(missing.datamanager(), Some("nowhere"));
    assert_eq!(
        missing.to_string(),
        "datamanager nowhere: no datamanager \"nowhere\" is registered"
    );
    assert!(
        matches!(missing, OpError::Unreachable { .. }),
        "{missing:?}"
    );
    let refused: OpError = DmError::InvalidRecord("empty class".into()).into();
    assert_eq!(refused.datamanager(), Some("?"));
    let decode: OpError = DmError::Decode("bad".into()).into();
    assert_eq!(
        decode.to_string(),
        "datamanager ?: cannot decode payload: bad"
    );
}

//! A plain enum actor of the application, beside a marie operation in the same process: both
//! are spawned, both answer, and the application's actor is fed what the operation reports.

use marie::eo::{self, EoClient, EoReport, Identity, OpContext, OpError, Operation, Step};
use marie::property::{param_map, ParamDecl, ParamSchema, PropertyReply, PropertyRequest, Value};
use marie::status::{FlagDecl, StatusFlags};
use marie_plain_actor_check::{Tally, TallyMsg};
use ractor::Actor;
use std::time::Duration;

const T: Duration = Duration::from_secs(30);

/// Counts up to `to`, one per step, then raises `done`.
#[derive(Default)]
struct CountUp {
    at: i64,
}

impl Operation for CountUp {
    fn identity(&self) -> Identity {
        Identity::new("count-up", 7301, "1.0.0", "counts up to a number")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::int("to", 3).range(1.0, 1000.0)])
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("done", "reached the number")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(1)
    }
    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.at = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.at += 1;
        Ok(if self.at >= ctx.params().i64("to")? {
            Step::Finish(StatusFlags(1))
        } else {
            Step::Continue
        })
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "at").then_some(Value::Int(self.at))
    }
}

#[tokio::test]
async fn a_plain_enum_actor_runs_beside_a_marie_operation() {
    let (tally, tally_done) = Actor::spawn(None, Tally, ()).await.unwrap();
    let (op, op_done) = eo::spawn_operation(CountUp::default(), Default::default())
        .await
        .unwrap();
    let client = EoClient::new(op.clone());

    // the application's actor: casts, then calls, answered in order
    tally.cast(TallyMsg::Add(2)).unwrap();
    tally.cast(TallyMsg::Add(5)).unwrap();
    let total = ractor::call_t!(tally, TallyMsg::Total, T.as_millis() as u64).unwrap();
    assert_eq!(total, 7);

    // the operation, driven through marie, in the same process
    let report = client
        .activate(param_map([("to", Value::Int(4))]), 1)
        .unwrap();
    let report = tokio::time::timeout(T, report).await.unwrap().unwrap();
    assert!(
        matches!(
            report,
            EoReport::Finished {
                flags: StatusFlags(1),
                epoch: 1
            }
        ),
        "{report:?}"
    );
    let at = match client
        .property(PropertyRequest::Get("at".into()))
        .await
        .unwrap()
    {
        PropertyReply::Value(Value::Int(at)) => at,
        other => panic!("`at` answered {other:?}"),
    };
    assert_eq!(at, 4);

    // what the operation reported, into the application's actor
    let total = tally
        .call(|reply| TallyMsg::AddAndGet { by: at, reply }, Some(T))
        .await
        .unwrap()
        .success_or("the tally did not answer")
        .unwrap();
    assert_eq!(total, 11);
    tally.cast(TallyMsg::Reset).unwrap();
    let total = ractor::call_t!(tally, TallyMsg::Total, T.as_millis() as u64).unwrap();
    assert_eq!(total, 0);

    tally.stop(None);
    op.stop(None);
    tokio::time::timeout(T, tally_done).await.unwrap().unwrap();
    tokio::time::timeout(T, op_done).await.unwrap().unwrap();
}

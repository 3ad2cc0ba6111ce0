//! The test operation several files start instances of, and a look at an instance.

use marie_actors::eo::{
    spawn_operation, EoClient, EoMsg, HostOptions, Identity, OpContext, OpError, Operation, Step,
};
use marie_vocabulary::property::{
    General, Group, ParamDecl, ParamSchema, PropertyReply, PropertyRequest, Value,
};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use ractor::ActorRef;
use std::time::Duration;

/// Finishes after `steps` steps of 2 ms, raising its one flag `done`. Its `resumed`
/// property says whether its last activation took over a lost one's.
pub(crate) struct Worker {
    name: String,
    id: u32,
    version: &'static str,
    /// It declares `gain` (and from version 3 `mode`) besides `steps`.
    gain: bool,
    /// Its deadline, if not the framework's default.
    deadline: Option<Duration>,
    taken: i64,
    resumed: bool,
}

impl Worker {
    /// Operation `name` (id `id`) in `version`: it declares `steps` and `gain`, and version 3
    /// also a `mode` — a compatible superset of the others' schema.
    pub(crate) fn new(name: &str, id: u32, version: &'static str) -> Worker {
        Worker {
            name: name.to_string(),
            id,
            version,
            gain: true,
            deadline: None,
            taken: 0,
            resumed: false,
        }
    }

    /// The same, declaring `steps` alone.
    pub(crate) fn steps_only(self) -> Worker {
        Worker {
            gain: false,
            ..self
        }
    }

    /// The same, answering each command within `deadline`.
    pub(crate) fn deadline(self, deadline: Duration) -> Worker {
        Worker {
            deadline: Some(deadline),
            ..self
        }
    }

    /// Host it, unsupervised.
    pub(crate) async fn start(self) -> EoClient {
        let (actor, _): (ActorRef<EoMsg>, _) =
            spawn_operation(self, HostOptions::default()).await.unwrap();
        EoClient::new(actor)
    }
}

impl Operation for Worker {
    fn identity(&self) -> Identity {
        Identity::new(
            &self.name,
            self.id,
            self.version,
            "finishes after a number of steps",
        )
    }
    fn parameters(&self) -> ParamSchema {
        let mut params = vec![ParamDecl::int("steps", 2).range(1.0, 100_000.0)];
        if self.gain {
            params.push(ParamDecl::float("gain", 0.5).range(0.0, 10.0));
            if self.version.starts_with("3.") {
                params.push(ParamDecl::choice("mode", &["fast", "slow"], "fast"));
            }
        }
        ParamSchema::new(params)
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("done", "finished")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }
    fn deadline(&self) -> Duration {
        self.deadline.unwrap_or(marie_actors::eo::DEFAULT_DEADLINE)
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken = 0;
        self.resumed = ctx.resumed();
        Ok(Step::Continue)
    }
    fn property(&self, name: &str) -> Option<Value> {
        (name == "resumed").then_some(Value::Bool(self.resumed))
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.taken += 1;
        Ok(if self.taken >= ctx.params().i64("steps")? {
            Step::Finish(StatusFlags(1))
        } else {
            Step::Continue
        })
    }
}

/// The general property group of instance `c`.
pub(crate) async fn general(c: &EoClient) -> General {
    match c
        .property(PropertyRequest::Group(Group::General))
        .await
        .unwrap()
    {
        PropertyReply::General(g) => g,
        other => panic!("{other:?}"),
    }
}

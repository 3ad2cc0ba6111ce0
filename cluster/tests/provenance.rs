//! A run's provenance as a node tells it: the first event of the run, this process's build
//! and the node, the caller's own fields kept, and every parameter value an operation ran
//! with and where it came from — the mission, a default, or a change while it ran.

use marie_actors::eo::{Identity, OpContext, OpError, Operation, OperationHandle, Step};
use marie_cluster::node::{Node, RunOptions};
use marie_vocabulary::events::EventKind;
use marie_vocabulary::property::{param_map, ParamDecl, ParamSchema, Value};
use marie_vocabulary::run::{ParamSource, Provenance};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Runs 40 steps of 10 ms, then finishes with `pumped`.
#[derive(Default)]
struct Pump {
    steps: u32,
}

impl Operation for Pump {
    fn identity(&self) -> Identity {
        Identity::new("pv-pump", 9301, "1.2.0", "pumps for a while")
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("pumped", "done pumping")]
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("rate", 1.0).range(0.0, 10.0),
            ParamDecl::int("stages", 2).range(1.0, 8.0),
        ])
    }
    fn period(&self) -> Duration {
        Duration::from_millis(10)
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.steps += 1;
        Ok(match self.steps >= 40 {
            true => Step::Finish(StatusFlags(1)),
            false => Step::Continue,
        })
    }
}

const MISSION: &str = "[mission]\nname = \"pumping\"\nsuccess = [\"pumped\"]\n\
                       [flags]\npumped = 0\n\
                       [[action]]\nname = \"pump\"\n[action.ops.pv-pump]\nrate = 2.5\n";

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn a_runs_provenance_comes_first_and_names_every_value_and_its_source() {
    let node = Node::builder("provenance-node")
        .operation::<Pump>()
        .start()
        .await
        .expect("starts");
    // an application turns the rate up once the action runs
    let kinds = Arc::new(Mutex::new(Vec::<String>::new()));
    let seen = kinds.clone();
    let options = RunOptions::new()
        .provenance(Provenance {
            command: vec!["my-app".into(), "--pump".into()],
            seed: Some(11),
            ..Provenance::default()
        })
        .observe(move |event| {
            // the kind's name, as its Debug text begins
            let kind = format!("{:?}", event.kind);
            let name = kind.split(|c: char| !c.is_alphanumeric()).next();
            seen.lock().unwrap().push(name.unwrap_or("?").to_string());
            if matches!(event.kind, EventKind::ActionStarted { .. }) {
                tokio::spawn(async {
                    let pump = OperationHandle::lookup("pv-pump").await.expect("found");
                    pump.set(param_map([("rate", Value::Float(4.0))]))
                        .await
                        .expect("a rate of 4 is in range");
                });
            }
        });
    let report = node.run(MISSION, options).await.expect("runs");
    assert!(report.succeeded(), "{report:?}");
    let kinds = kinds.lock().unwrap().clone();
    assert_eq!(
        kinds.first().map(String::as_str),
        Some("Provenance"),
        "{kinds:?}"
    );
    let p = report.provenance.expect("a provenance section");
    assert_eq!(
        p.command,
        vec!["my-app", "--pump"],
        "the caller's fields are kept"
    );
    assert_eq!(p.seed, Some(11));
    assert_eq!(
        p.marie.as_ref(),
        Some(&marie_vocabulary::run::provenance::this_build())
    );
    assert_eq!(p.nodes.len(), 1);
    assert_eq!(p.nodes[0].node, "provenance-node");
    assert!(p.started.starts_with("20"), "{}", p.started);
    let told: Vec<(String, String, ParamSource)> = p
        .parameters
        .iter()
        .map(|s| (s.name.clone(), s.value.to_string(), s.source))
        .collect();
    assert_eq!(
        told,
        vec![
            ("rate".to_string(), "2.5".to_string(), ParamSource::Mission),
            ("stages".to_string(), "2".to_string(), ParamSource::Default),
            (
                "rate".to_string(),
                "4".to_string(),
                ParamSource::Reparameterized
            ),
        ]
    );
    assert!(p.parameters.iter().all(|s| s.action == "pump"));
    assert!(p.parameters[2].at_ms.is_some());
    node.shutdown().await;
}

//! Select once, on a node: `Node::check_mission` hands its choices to the run of the
//! checked mission, and a choice that no longer holds when the run starts — its instance
//! was restarted by its supervisor in between — is made again, never bound to the dead
//! instance.
//!
//! The registry is one per process and these tests run in parallel: each owns the operation
//! names it starts.

use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::eo::{EoClient, Identity, OpContext, OpError, Operation, Step};
use marie_cluster::node::{Node, RunOptions};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use std::time::Duration;

const T: Duration = Duration::from_secs(30);

/// Raises `ticked` after a few steps.
#[derive(Default)]
struct Ticker {
    n: u32,
}

impl Operation for Ticker {
    fn identity(&self) -> Identity {
        Identity::new("so-ticker", 9401, "1.0.0", "ticks a few times")
    }
    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("ticked", "done")]
    }
    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }
    async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.n = 0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.n += 1;
        Ok(if self.n >= 5 {
            Step::Finish(StatusFlags(1))
        } else {
            Step::Continue
        })
    }
}

const MISSION: &str = "[mission]\nname = \"m\"\nsuccess = [\"ticked\"]\n[flags]\nticked = 0\n\
                       [[action]]\nname = \"a\"\n[action.ops.so-ticker]\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_checked_missions_instance_restarted_before_the_run_is_chosen_again_not_bound_dead() {
    let node = Node::builder("select-once")
        .operation::<Ticker>()
        .start()
        .await
        .expect("starts");
    let parsed = ParsedMission::parse(MISSION, None).unwrap();
    let mission = node.check_mission(&parsed).await.unwrap();
    let first = node.instances("so-ticker");
    assert_eq!(first.len(), 1);
    let old = first[0].actor_id().to_string();
    let checked = mission.checked().choice("so-ticker").cloned().unwrap();
    assert_eq!(checked.chosen().unwrap().address, old);

    // the chosen instance panics; its supervisor starts a new one before the run
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.unwrap();
    EoClient::from_cell(first[0].actor.clone())
        .inject(FaultKind::Panic)
        .unwrap();
    let restarted = tokio::time::timeout(T, async {
        loop {
            match watch.next().await {
                Some(RegistryEvent::Joined(i)) if i.name == "so-ticker" => return i,
                Some(_) => {}
                None => panic!("the registry watch ended"),
            }
        }
    })
    .await
    .expect("the supervisor restarts it");
    let new = restarted.actor_id().to_string();
    assert_ne!(new, old);

    let report = node.run(mission, RunOptions::new()).await.unwrap();
    assert!(report.succeeded(), "{}", report.reason);
    let choice = &report.selection[0];
    assert_eq!(choice.chosen().unwrap().address, new, "{choice:?}");
    assert!(choice.candidates.iter().all(|c| c.address != old));
    assert!(report.rebinds.is_empty(), "{:?}", report.rebinds);
    assert_eq!(report.actions[0].operations[0].address, new);

    // checked again and run at once: the run binds the check's choice as it was made
    let mission = node.check_mission(&parsed).await.unwrap();
    let checked = mission.checked().choice("so-ticker").cloned().unwrap();
    let report = node.run(mission, RunOptions::new()).await.unwrap();
    assert!(report.succeeded(), "{}", report.reason);
    assert_eq!(report.selection, vec![checked]);
    node.shutdown().await;
}

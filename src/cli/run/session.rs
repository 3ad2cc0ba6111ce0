//! A planned run from its node's start to its node's stop: the pacer and the node started,
//! the run made ready, the mission run with its followers, the node stopped — what the run
//! leaves is an [`Ended`].

use super::ended::Ended;
use super::plan::Plan;
use super::ready::ready;
use super::taps::Taps;
use crate::cli::prepare::{prepare, Prepared};
use marie::clock::Paced;
use marie::report::RunReport;
use marie_missions::robot::RobotReport;

/// A run whose node has started and is ready to run the mission.
pub(super) struct Session {
    plan: Plan,
    prepared: Prepared,
    /// Holds the mission clock back to the speed, from before the node starts to the end.
    pace: Option<Paced>,
}

impl Session {
    /// Start the pacer and the node (or join the cluster), and make the run ready on it; a
    /// refusal stops the node again.
    pub(super) async fn start(mut plan: Plan) -> anyhow::Result<Session> {
        let pace = plan.pace();
        let prepared = prepare(&plan.mission, plan.robot.clone(), plan.joining.as_ref()).await?;
        if let Err(e) = ready(&mut plan, &prepared).await {
            prepared.shutdown().await;
            return Err(e);
        }
        Ok(Session {
            plan,
            prepared,
            pace,
        })
    }

    /// Run the mission, followed by the lines, the files and the page; then draw the picture
    /// and stop the node. A run that fails leaves the cluster and is the error.
    pub(super) async fn follow(self) -> anyhow::Result<Ended> {
        let Session {
            mut plan,
            prepared,
            pace,
        } = self;
        let Prepared {
            node,
            robot,
            mission,
            transport,
            ..
        } = prepared;
        let taps = Taps::start(&plan, node.events(), transport.as_ref(), &mission.name).await?;
        let options = std::mem::take(&mut plan.options);
        let report = node.run(mission, options).await;
        let (files, relays, page) = taps.finish().await;
        let picture = match (&report, &plan.outputs.svg, &robot) {
            (Ok(report), Some(_), Some(robot)) => Some(robot.picture(report).await),
            _ => None,
        };
        let world = robot.as_ref().map(|r| r.world().clone());
        node.shutdown().await;
        relays.stop();
        // a monitor's page still reaches the cluster after the run (its properties, its
        // faults, the other nodes' news): the membership ends with the page
        let transport = match (transport, &page) {
            (Some(t), None) => {
                t.stop().await;
                None
            }
            (t, _) => t,
        };
        let report = match report {
            Ok(report) => with_robot_section(report),
            Err(e) => {
                if let Some(t) = transport {
                    t.stop().await;
                }
                return Err(e.into());
            }
        };
        Ok(Ended {
            plan,
            report,
            files,
            picture,
            world,
            page,
            transport,
            pace,
        })
    }
}

/// The report of `marie run` always holds the simulated robot's fields (null without one).
fn with_robot_section(mut report: RunReport) -> RunReport {
    if report.robot.is_empty() {
        report.robot = RobotReport::default().section();
    }
    report
}

//! What the simulated robot says of a run — the report's robot section, typed.
//!
//! The framework's report carries a robot's judgement as fields it does not type
//! ([`RobotSection`]); this is the simulated cart's own reading of them, for whoever knows
//! it is that robot (the `marie` command's outcome line, the picture, tests).

use marie_vocabulary::fence::Late;
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::RobotSection;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The simulated cart's judgement of a run: its part of a report, written beside the
/// report's own fields (`final_pose`, `collisions`, `seed`, `inside_goal`, `judgement`,
/// `refused_commands`, `obeyed_late`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RobotReport {
    /// Final pose `[x, y, heading]`: metres, and the heading in radians.
    #[serde(default)]
    pub final_pose: Option<[f64; 3]>,
    /// Collisions the simulation counted.
    #[serde(default)]
    pub collisions: Option<u64>,
    /// Seed of the simulation.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Whether the cart's footprint ended inside the world's goal area (none without a
    /// goal area).
    #[serde(default)]
    pub inside_goal: Option<bool>,
    /// The world's verdict on the cart's final state (e.g. `success: inside the goal area,
    /// heading error 2.1°, 0 collision(s)`).
    #[serde(default)]
    pub judgement: Option<String>,
    /// Commands the cart refused because they came from a replaced incarnation of an
    /// operation (an older epoch than its stand-in's: fencing), by operation name — e.g. a
    /// wall follower on a node cut off from the dispatcher, still driving after its
    /// binding moved.
    #[serde(default)]
    pub refused_commands: Option<BTreeMap<String, u64>>,
    /// Epochs the cart obeyed after the run had bound a newer epoch of their operation —
    /// each at least one command of a replaced incarnation obeyed, so fencing failed — with
    /// how late ([`Late`]); empty when fencing held. `None` when the cart did not say.
    #[serde(default)]
    pub obeyed_late: Option<Vec<Late>>,
}

impl RobotReport {
    /// The cart's part of `report` (every field `None` where the report has none: a run
    /// without the simulated robot).
    pub fn of(report: &RunReport) -> RobotReport {
        let section = serde_json::Value::Object(report.robot.clone());
        serde_json::from_value(section).unwrap_or_else(|e| {
            tracing::warn!("the report's robot section is not the simulated cart's: {e}");
            RobotReport::default()
        })
    }

    /// As a report's robot section: every field, `null` where it has none — so a report of
    /// the `marie` command always holds them (the README's report), with or without a robot.
    pub fn section(&self) -> RobotSection {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(map)) => map,
            _ => RobotSection::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::run::Outcome;

    #[test]
    fn the_carts_section_reads_back_from_a_report() {
        let said = RobotReport {
            final_pose: Some([1.0, 2.0, 0.5]),
            collisions: Some(0),
            seed: Some(7),
            inside_goal: Some(true),
            judgement: Some("success".into()),
            refused_commands: Some([("wall-follower".to_string(), 3)].into()),
            obeyed_late: Some(vec![Late {
                operation: "wall-follower".into(),
                epoch: 5,
                replaced_by: 6,
                replaced_clock_ms: 100,
                last_clock_ms: 120,
            }]),
        };
        let mut report = RunReport::new("m", Outcome::Succeeded, "");
        report.robot = said.section();
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["final_pose"][0], 1.0);
        assert_eq!(json["refused_commands"]["wall-follower"], 3);
        assert_eq!(json["obeyed_late"][0]["replaced_by"], 6);
        let back: RunReport = serde_json::from_value(json).unwrap();
        assert_eq!(RobotReport::of(&back), said);
        // without a robot: every key, null
        let none = RobotReport::default().section();
        assert_eq!(none.len(), 7);
        assert!(none.values().all(serde_json::Value::is_null));
        assert_eq!(
            RobotReport::of(&RunReport::new("m", Outcome::Failed, "")),
            RobotReport::default()
        );
    }
}

//! The checker: judges the newest statistics in the world DM.

use super::{Statistics, STATS_CLASS};
use marie_actors::dm::Query;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_actors::flags::{FlagDecl, StatusFlags};
use marie_actors::property::{ParamDecl, ParamSchema};

/// Finishes with `verified` when the newest statistics match the expected mean and variance
/// within their tolerances; fails otherwise.
#[derive(Debug, Default)]
pub struct Checker;

impl Operation for Checker {
    fn identity(&self) -> Identity {
        Identity::new(
            "checker",
            1603,
            "1.0.0",
            "checks signal statistics against expectations",
        )
    }

    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::float("expected_mean", 0.0).describe("expected mean"),
            ParamDecl::float("mean_tolerance", 0.1)
                .range(0.0, 1e6)
                .describe("accepted distance from the expected mean"),
            ParamDecl::float("expected_variance", 0.5)
                .range(0.0, 1e6)
                .describe("expected variance (a sine of amplitude A has A²/2)"),
            ParamDecl::float("variance_tolerance", 0.1)
                .range(0.0, 1e6)
                .describe("accepted distance from the expected variance"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new("verified", "the statistics are as expected")]
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let records = ctx
            .dm("world")?
            .select(Query::class(STATS_CLASS).newest(1))
            .await
            .map_err(|e| OpError::Datamanager {
                dm: "world".into(),
                problem: e.to_string(),
            })?;
        let Some(rec) = records.last() else {
            return Ok(Step::Continue); // nothing to judge yet
        };
        let stats: Statistics = rec.decode().map_err(|e| OpError::Datamanager {
            dm: "world".into(),
            problem: e.to_string(),
        })?;
        let p = ctx.params();
        let mean_err = (stats.mean - p.f64("expected_mean")?).abs();
        let var_err = (stats.variance - p.f64("expected_variance")?).abs();
        if mean_err > p.f64("mean_tolerance")? || var_err > p.f64("variance_tolerance")? {
            return Err(OpError::failed(format!(
                "statistics out of bounds: mean {:.4} (off by {mean_err:.4}), variance {:.4} (off by {var_err:.4}) over {} samples",
                stats.mean, stats.variance, stats.n
            )));
        }
        Ok(Step::Finish(StatusFlags(1)))
    }
}

//! The checker: judges the newest statistics in the world DM.

use super::STATISTICS;
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::{DmError, WORLD};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;

marie_actors::params! {
    /// The checker's parameters.
    pub struct CheckerParams {
        /// expected mean
        pub expected_mean: f64 = 0.0;
        /// accepted distance from the expected mean
        pub mean_tolerance: f64 = 0.1, range(0.0, 1e6);
        /// expected variance (a sine of amplitude A has A²/2)
        pub expected_variance: f64 = 0.5, range(0.0, 1e6);
        /// accepted distance from the expected variance
        pub variance_tolerance: f64 = 0.1, range(0.0, 1e6);
    }
}

marie_actors::flags! {
    /// What the checker reports.
    pub enum CheckerFlag {
        /// the statistics are as expected
        Verified = "verified",
    }
}

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
        CheckerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        CheckerFlag::decls()
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let in_world = |e: DmError| OpError::of_dm(WORLD.name, &e);
        let newest = ctx
            .dm(WORLD)?
            .newest_kind(STATISTICS)
            .await
            .map_err(in_world)?;
        let Some((_, stats)) = newest else {
            return Ok(Step::Continue); // nothing to judge yet
        };
        let p: CheckerParams = ctx.params().read()?;
        let mean_err = (stats.mean - p.expected_mean).abs();
        let var_err = (stats.variance - p.expected_variance).abs();
        if mean_err > p.mean_tolerance || var_err > p.variance_tolerance {
            return Err(OpError::failed(format!(
                "statistics out of bounds: mean {:.4} (off by {mean_err:.4}), variance {:.4} (off by {var_err:.4}) over {} samples",
                stats.mean, stats.variance, stats.n
            )));
        }
        Ok(Step::finish(CheckerFlag::Verified))
    }
}

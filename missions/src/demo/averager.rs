//! The averager: mean and variance of the samples in the feature DM, into the world DM.

use super::{SAMPLES, STATISTICS};
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::{Query, FEATURE, WORLD};
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use serde::{Deserialize, Serialize};
use std::time::Duration;

marie_actors::params! {
    /// The averager's parameters.
    pub struct AveragerParams {
        /// samples to average before finishing
        pub window: i64 = 200, range(1, 100_000);
    }
}

marie_actors::flags! {
    /// What the averager reports.
    pub enum AveragerFlag {
        /// stored the statistics of a full window
        Averaged = "averaged",
    }
}

/// Statistics of a window of samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Statistics {
    /// Number of samples.
    pub n: u64,
    /// Mean.
    pub mean: f64,
    /// Population variance.
    pub variance: f64,
    /// Smallest sample.
    pub min: f64,
    /// Largest sample.
    pub max: f64,
}

/// Reads samples stored since its activation; after `window` of them stores their statistics.
#[derive(Debug, Default)]
pub struct Averager {
    since: Duration,
    last_seq: u64,
    n: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
}

fn dm_err(e: impl std::fmt::Display) -> OpError {
    OpError::Datamanager {
        dm: "feature/world".into(),
        problem: e.to_string(),
    }
}

impl Operation for Averager {
    fn identity(&self) -> Identity {
        Identity::new(
            "averager",
            1602,
            "1.0.0",
            "mean and variance of sampled signals",
        )
    }

    fn parameters(&self) -> ParamSchema {
        AveragerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        AveragerFlag::decls()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(5)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        *self = Averager {
            since: ctx.now(),
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            ..Default::default()
        };
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let window = ctx.params().value(AveragerParams::window())? as u64;
        let query = Query::all()
            .time_from(self.since)
            .seq_from(self.last_seq + 1);
        let samples = ctx
            .dm(FEATURE)?
            .select_kind(SAMPLES, query)
            .await
            .map_err(dm_err)?;
        for (header, s) in samples {
            self.last_seq = header.seq;
            // Welford's online algorithm
            self.n += 1;
            let delta = s.value - self.mean;
            self.mean += delta / self.n as f64;
            self.m2 += delta * (s.value - self.mean);
            self.min = self.min.min(s.value);
            self.max = self.max.max(s.value);
            if self.n >= window {
                break;
            }
        }
        if self.n < window {
            return Ok(Step::Continue);
        }
        let stats = Statistics {
            n: self.n,
            mean: self.mean,
            variance: self.m2 / self.n as f64,
            min: self.min,
            max: self.max,
        };
        ctx.dm(WORLD)?
            .store_kind(STATISTICS, &stats)
            .await
            .map_err(dm_err)?;
        Ok(Step::finish(AveragerFlag::Averaged))
    }
}

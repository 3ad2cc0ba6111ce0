//! The sampler: a noisy sine wave into the feature DM.

use super::SAMPLE_CLASS;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_actors::flags::{FlagDecl, StatusFlags};
use marie_actors::property::{ParamDecl, ParamSchema};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// One sample record.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Index within the activation.
    pub index: u64,
    /// Signal time in seconds.
    pub t: f64,
    /// Value.
    pub value: f64,
}

/// Samples `amplitude * sin(2π f t) + noise` at `rate` samples per second.
#[derive(Debug, Default)]
pub struct Sampler {
    index: u64,
    rng: u64,
}

impl Sampler {
    fn uniform(&mut self) -> f64 {
        // xorshift64*: small, seeded, good enough for sensor noise
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        let x = self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

impl Operation for Sampler {
    fn identity(&self) -> Identity {
        Identity::new(
            "sampler",
            1601,
            "1.0.0",
            "samples a noisy sine wave into the feature DM",
        )
    }

    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![
            ParamDecl::int("count", 400)
                .range(1.0, 100_000.0)
                .describe("samples to take before finishing"),
            ParamDecl::float("rate", 100.0)
                .range(1.0, 10_000.0)
                .unit("Hz")
                .describe("samples per second of signal time"),
            ParamDecl::float("frequency", 2.0)
                .range(0.0, 1_000.0)
                .unit("Hz")
                .describe("frequency of the sine"),
            ParamDecl::float("amplitude", 1.0)
                .range(0.0, 1_000.0)
                .describe("amplitude of the sine"),
            ParamDecl::float("noise", 0.1)
                .range(0.0, 100.0)
                .describe("half-width of the uniform noise"),
            ParamDecl::int("seed", 1)
                .range(0.0, 1e15)
                .describe("noise seed: equal seeds give equal samples"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "sampled",
            "took every sample it was asked for",
        )]
    }

    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.index = 0;
        self.rng = (ctx.params().i64("seed")? as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let (count, rate) = (p.i64("count")? as u64, p.f64("rate")?);
        let (freq, amp, noise) = (p.f64("frequency")?, p.f64("amplitude")?, p.f64("noise")?);
        let t = self.index as f64 / rate;
        let value = amp * (std::f64::consts::TAU * freq * t).sin() + noise * self.uniform();
        let sample = Sample {
            index: self.index,
            t,
            value,
        };
        ctx.dm("feature")?
            .store(SAMPLE_CLASS, Some("sine"), None, &sample)
            .await
            .map_err(|e| OpError::Datamanager {
                dm: "feature".into(),
                problem: e.to_string(),
            })?;
        self.index += 1;
        Ok(if self.index >= count {
            Step::Finish(StatusFlags(1))
        } else {
            Step::Continue
        })
    }
}

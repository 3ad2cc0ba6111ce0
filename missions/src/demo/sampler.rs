//! The sampler: a noisy sine wave into the feature DM.

use super::SAMPLES;
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::FEATURE;
use marie_vocabulary::property::ParamSchema;
use marie_vocabulary::status::FlagDecl;
use serde::{Deserialize, Serialize};
use std::time::Duration;

marie_actors::params! {
    /// The sampler's parameters.
    pub struct SamplerParams {
        /// samples to take before finishing
        pub count: i64 = 400, range(1, 100_000);
        /// samples per second of signal time
        pub rate: f64 = 100.0, range(1.0, 10_000.0), unit("Hz");
        /// frequency of the sine
        pub frequency: f64 = 2.0, range(0.0, 1_000.0), unit("Hz");
        /// amplitude of the sine
        pub amplitude: f64 = 1.0, range(0.0, 1_000.0);
        /// half-width of the uniform noise
        pub noise: f64 = 0.1, range(0.0, 100.0);
        /// noise seed: equal seeds give equal samples
        pub seed: i64 = 1, range(0.0, 1e15);
    }
}

marie_actors::flags! {
    /// What the sampler reports.
    pub enum SamplerFlag {
        /// took every sample it was asked for
        Sampled = "sampled",
    }
}

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
        SamplerParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        SamplerFlag::decls()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(2)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.index = 0;
        let seed = ctx.params().value(SamplerParams::seed())?;
        self.rng = (seed as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: SamplerParams = ctx.params().read()?;
        let (count, rate) = (p.count as u64, p.rate);
        let (freq, amp, noise) = (p.frequency, p.amplitude, p.noise);
        let t = self.index as f64 / rate;
        let value = amp * (std::f64::consts::TAU * freq * t).sin() + noise * self.uniform();
        let sample = Sample {
            index: self.index,
            t,
            value,
        };
        ctx.dm(FEATURE)?
            .store_kind(SAMPLES, &sample)
            .await
            .map_err(|e| OpError::of_dm(FEATURE.name, &e))?;
        self.index += 1;
        Ok(if self.index >= count {
            Step::finish(SamplerFlag::Sampled)
        } else {
            Step::Continue
        })
    }
}

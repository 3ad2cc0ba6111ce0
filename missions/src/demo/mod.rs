//! Demo operations: small, real signal processing through the datamanagers.
//!
//! - [`Sampler`] (1601) samples a sine wave with seeded noise into the feature DM;
//! - [`Averager`] (1602) reads those samples back, computes mean and variance (Welford) over a
//!   window and stores the statistics in the world DM;
//! - [`Checker`] (1603) judges the newest statistics against the expected values and fails
//!   the mission when they are off.
//!
//! They never talk to each other: only to datamanagers, as the thesis requires.

mod averager;
mod checker;
mod sampler;

pub use averager::{Averager, AveragerFlag, AveragerParams, Statistics};
pub use checker::{Checker, CheckerFlag, CheckerParams};
pub use sampler::{Sample, Sampler, SamplerFlag, SamplerParams};

use marie_dm::RecordKind;

/// The sampler's samples of its sine, in the feature DM.
pub const SAMPLES: RecordKind<Sample> = RecordKind::new("sample").with_sub1("sine");
/// The averager's statistics of the sine's samples, in the world DM.
pub const STATISTICS: RecordKind<Statistics> = RecordKind::new("statistics").with_sub1("sine");

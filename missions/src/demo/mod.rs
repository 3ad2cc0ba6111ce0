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

pub use averager::{Averager, Statistics};
pub use checker::Checker;
pub use sampler::{Sample, Sampler};

/// Class of the sample records in the feature DM.
pub const SAMPLE_CLASS: &str = "sample";
/// Class of the statistics records in the world DM.
pub const STATS_CLASS: &str = "statistics";

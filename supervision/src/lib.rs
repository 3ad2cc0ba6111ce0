//! # marie-supervision
//!
//! Supervision for marie's actors with Erlang/OTP semantics (DESIGN.md §5). ractor links
//! actors and reports failures, but has no strategies, restart intensity or backoff; this
//! crate adds them. It starts with the piece every strategy rests on: the sliding-window
//! restart intensity ([`Intensity`]); the supervisor actor, strategies and shutdown specs
//! build on it.
//!
//! ```
//! use marie_supervision::Intensity;
//! use std::time::Duration;
//! // at most 3 restarts in any 5 seconds
//! let mut window = Intensity::new(3, Duration::from_secs(5));
//! let t = Duration::from_secs(100);
//! assert!(window.record(t));
//! assert!(window.record(t));
//! assert!(window.record(t));
//! assert!(!window.record(t), "the fourth restart within 5 s exceeds the intensity");
//! ```

#![warn(missing_docs)]

mod intensity;

pub use intensity::Intensity;

//! Supervision needs panics that unwind; a supervisor refuses to start in a build whose panics
//! abort.
//!
//! Why: ractor catches a panicking handler (`pre_start`, `handle`, ...) and reports it to the
//! actor's parent as `SupervisionEvent::ActorFailed` — the event a [`crate::Supervisor`]
//! restarts from. Catching a panic is only possible when panics unwind. Built with
//! `panic = "abort"`, the first panic in any supervised actor ends the whole process: nothing
//! is restarted, and a robot that was meant to heal itself simply stops. That would only show
//! at the first fault, in the field, so the supervisor says so when it starts instead.
//!
//! How: `cfg!(panic = "abort")` is how *this* crate was compiled. Cargo compiles every crate
//! of a build with the profile's `panic` setting (a profile's per-package overrides may not
//! change it), and `RUSTFLAGS="-C panic=abort"` reaches every crate too, so this crate's
//! strategy is the program's. (Test and bench targets always unwind: cargo ignores
//! `panic = "abort"` for them, and the check agrees.)
//!
//! ```
//! // this doctest unwinds, like any test
//! assert!(marie_supervision::PANICS_UNWIND);
//! assert_eq!(marie_supervision::require_unwinding(), Ok(()));
//! ```

use crate::error::SupervisorError;

/// True when this build's panics unwind (`panic = "unwind"`, Rust's default), so that a
/// panicking actor reaches its supervisor as a failure; false under `panic = "abort"`.
///
/// ```
/// if !marie_supervision::PANICS_UNWIND {
///     eprintln!("a panic will end the process: supervisors will refuse to start");
/// }
/// ```
pub const PANICS_UNWIND: bool = !cfg!(panic = "abort");

/// `Ok` when panics unwind; [`SupervisorError::PanicsAbort`] (saying why and how to fix the
/// build) when they abort. Every supervisor start calls it first; call it yourself to refuse
/// earlier, before anything else of yours starts.
///
/// ```
/// # fn main() -> Result<(), marie_supervision::SupervisorError> {
/// marie_supervision::require_unwinding()?;
/// # Ok(()) }
/// ```
pub fn require_unwinding() -> Result<(), SupervisorError> {
    if PANICS_UNWIND {
        Ok(())
    } else {
        Err(SupervisorError::PanicsAbort)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_refusal_says_why_and_how_to_fix_it() {
        let text = SupervisorError::PanicsAbort.to_string();
        for needed in [
            "panic = \"abort\"",
            "panic = \"unwind\"",
            "restart",
            "Cargo.toml",
        ] {
            assert!(text.contains(needed), "{needed:?} missing from: {text}");
        }
    }
}

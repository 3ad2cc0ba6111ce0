//! Checking supervisor flags and child specs before anything starts (OTP's `sup_flags` and
//! `check_childspecs`).
//!
//! Rust's types already rule out most of what OTP checks at run time (an unknown restart type,
//! a negative intensity, a malformed start function). What is left are values that type-check
//! but cannot work: a restart period of zero, two children with one id, a shutdown timeout of
//! zero, a simple-one-for-one supervisor without its template. A bad spec is refused with a
//! typed [`SpecError`] — by [`crate::Supervisor::start`] before it spawns anything, and by
//! [`crate::SupervisorRef::start_child`] before it adds the child — rather than failing later,
//! in the middle of a restart, or with a panic.

use std::collections::HashSet;
use std::time::Duration;

use crate::backoff::Backoff;
use crate::child::{ChildSpec, Shutdown};
use crate::error::SpecError;
use crate::simple::ChildTemplate;
use crate::spec::{SupervisorSpec, MAX_BACKOFF, MAX_EVENT_CAPACITY};
use crate::strategy::Strategy;

impl SupervisorSpec {
    /// Check the supervisor's own flags: a period longer than zero, an event capacity within
    /// `1..=`[`MAX_EVENT_CAPACITY`], a backoff that can work, and a template exactly when the
    /// strategy is simple-one-for-one.
    pub fn validate(&self) -> Result<(), SpecError> {
        if self.period.is_zero() {
            return Err(SpecError::ZeroPeriod);
        }
        if self.event_capacity == 0 || self.event_capacity > MAX_EVENT_CAPACITY {
            return Err(SpecError::EventCapacity(self.event_capacity));
        }
        if let Some(backoff) = &self.backoff {
            validate_backoff(backoff)?;
        }
        match (&self.strategy, &self.template) {
            (Strategy::SimpleOneForOne, None) => Err(SpecError::MissingTemplate),
            (Strategy::SimpleOneForOne, Some(template)) => template.validate(),
            (other, Some(_)) => Err(SpecError::TemplateWithoutSimpleOneForOne(*other)),
            (_, None) => Ok(()),
        }
    }
}

impl ChildSpec {
    /// Check one child spec: a non-empty id and no zero timeouts.
    pub fn validate(&self) -> Result<(), SpecError> {
        validate_child(&self.id, self.shutdown, self.start_timeout)
    }
}

impl ChildTemplate {
    /// Check the template as a child spec: a non-empty id and no zero timeouts.
    pub fn validate(&self) -> Result<(), SpecError> {
        validate_child(&self.id, self.shutdown, self.start_timeout)
    }
}

/// Check child specs as a group, as OTP's `supervisor:check_childspecs`: each valid, and no
/// two with the same id.
pub fn check_child_specs(children: &[ChildSpec]) -> Result<(), SpecError> {
    let mut seen = HashSet::with_capacity(children.len());
    for child in children {
        child.validate()?;
        if !seen.insert(child.id.as_str()) {
            return Err(SpecError::DuplicateChildId(child.id.clone()));
        }
    }
    Ok(())
}

/// Everything a supervisor checks before it starts: its flags, its children, and that a
/// simple-one-for-one supervisor has no static children.
pub(crate) fn validate_start(
    spec: &SupervisorSpec,
    children: &[ChildSpec],
) -> Result<(), SpecError> {
    spec.validate()?;
    if spec.strategy == Strategy::SimpleOneForOne && !children.is_empty() {
        return Err(SpecError::SimpleOneForOneChildren(children.len()));
    }
    check_child_specs(children)
}

fn validate_child(
    id: &str,
    shutdown: Shutdown,
    start_timeout: Option<Duration>,
) -> Result<(), SpecError> {
    if id.trim().is_empty() {
        return Err(SpecError::EmptyId);
    }
    if shutdown == Shutdown::Timeout(Duration::ZERO) {
        return Err(SpecError::ZeroShutdownTimeout(id.to_string()));
    }
    if start_timeout == Some(Duration::ZERO) {
        return Err(SpecError::ZeroStartTimeout(id.to_string()));
    }
    Ok(())
}

fn validate_backoff(b: &Backoff) -> Result<(), SpecError> {
    let bad = |why: String| Err(SpecError::Backoff(why));
    if !b.multiplier.is_finite() || b.multiplier < 1.0 {
        return bad(format!(
            "multiplier {} is not a finite number >= 1",
            b.multiplier
        ));
    }
    if !(0.0..=1.0).contains(&b.jitter) {
        return bad(format!("jitter {} is not within [0, 1]", b.jitter));
    }
    if b.base > b.max {
        return bad(format!("base {:?} exceeds max {:?}", b.base, b.max));
    }
    if b.max > MAX_BACKOFF {
        return bad(format!("max {:?} exceeds {MAX_BACKOFF:?}", b.max));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::child::{ChildKind, ChildStart, StartFn};
    use std::sync::Arc;

    fn child(id: &str) -> ChildSpec {
        let start: StartFn = Arc::new(|_| Box::pin(async { Ok(ChildStart::Ignore) }));
        ChildSpec::new(id, ChildKind::Worker, start)
    }

    #[test]
    fn flags() {
        assert_eq!(SupervisorSpec::one_for_one().validate(), Ok(()));
        let zero = SupervisorSpec::one_for_one().with_intensity(3, Duration::ZERO);
        assert_eq!(zero.validate(), Err(SpecError::ZeroPeriod));
        let huge = SupervisorSpec::one_for_one().with_intensity(usize::MAX, Duration::MAX);
        assert_eq!(huge.validate(), Ok(()), "huge limits are absurd but work");
        let mut spec = SupervisorSpec::one_for_one();
        spec.event_capacity = 0;
        assert_eq!(spec.validate(), Err(SpecError::EventCapacity(0)));
        spec.event_capacity = usize::MAX;
        assert_eq!(spec.validate(), Err(SpecError::EventCapacity(usize::MAX)));
        let mut sofo = SupervisorSpec::one_for_one();
        sofo.strategy = Strategy::SimpleOneForOne;
        assert_eq!(sofo.validate(), Err(SpecError::MissingTemplate));
    }

    #[test]
    fn backoffs() {
        let ok = Backoff::exponential(Duration::from_millis(10), Duration::from_secs(1));
        assert_eq!(validate_backoff(&ok), Ok(()));
        for bad in [
            Backoff {
                multiplier: f64::NAN,
                ..ok.clone()
            },
            Backoff {
                multiplier: 0.5,
                ..ok.clone()
            },
            Backoff {
                jitter: 2.0,
                ..ok.clone()
            },
            Backoff {
                jitter: f64::NAN,
                ..ok.clone()
            },
            Backoff {
                base: Duration::from_secs(5),
                ..ok.clone()
            },
            Backoff::exponential(Duration::from_secs(1), Duration::MAX),
        ] {
            assert!(
                matches!(validate_backoff(&bad), Err(SpecError::Backoff(_))),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn children() {
        assert_eq!(check_child_specs(&[child("a"), child("b")]), Ok(()));
        assert_eq!(
            check_child_specs(&[child("a"), child("a")]),
            Err(SpecError::DuplicateChildId("a".into()))
        );
        assert_eq!(child(" ").validate(), Err(SpecError::EmptyId));
        assert_eq!(
            child("z")
                .with_shutdown(Shutdown::Timeout(Duration::ZERO))
                .validate(),
            Err(SpecError::ZeroShutdownTimeout("z".into()))
        );
        assert_eq!(
            child("z").with_start_timeout(Duration::ZERO).validate(),
            Err(SpecError::ZeroStartTimeout("z".into()))
        );
        assert_eq!(
            child("i").with_shutdown(Shutdown::Infinity).validate(),
            Ok(()),
            "infinity is fine for workers too"
        );
    }
}

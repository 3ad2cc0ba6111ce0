//! What an operation's report means for its action: how its part ended, the flags it
//! raised, and — if the report breaks the action — the reason of the full stop.

use crate::eo::EoReport;
use marie_vocabulary::run::OpEnd;
use marie_vocabulary::status::StatusFlags;

/// What an operation's report does to its action: how its part ended, its flags, whether the run must stop.
pub(super) struct Effect {
    /// How its part ended.
    pub(super) ended: OpEnd,
    /// Its own flag bits (not yet the mission's).
    pub(super) flags: StatusFlags,
    /// Why the run must stop, if it must.
    pub(super) failure: Option<String>,
}

impl Effect {
    /// Judge `report` (`None`: the instance died) of operation `key` in action
    /// `action_name`; `ending` says the action had suspended it.
    pub(super) fn of(
        report: Option<EoReport>,
        ending: bool,
        key: &str,
        action_name: &str,
    ) -> Effect {
        let (ended, flags, failure) = match report {
            Some(EoReport::Finished { flags, .. }) => (OpEnd::Finished, flags, None),
            Some(EoReport::Suspended { flags, .. }) if ending => (OpEnd::Suspended, flags, None),
            Some(EoReport::Suspended { flags, .. }) => (
                OpEnd::Suspended,
                flags,
                Some(format!(
                    "operation `{key}` was suspended by another party during action `{action_name}`"
                )),
            ),
            Some(EoReport::Failed { reason, flags, .. }) => (
                OpEnd::Failed,
                flags,
                Some(format!(
                    "operation `{key}` failed in action `{action_name}`: {reason}"
                )),
            ),
            Some(EoReport::Rejected { rejections, .. }) => (
                OpEnd::Failed,
                StatusFlags::EMPTY,
                Some(format!(
                    "operation `{key}` refused its parameters in action `{action_name}`: {}",
                    rejections
                        .iter()
                        .map(|r| r.to_string())
                        .collect::<Vec<_>>()
                        .join("; ")
                )),
            ),
            Some(EoReport::Stale { current, .. }) => (
                OpEnd::Failed,
                StatusFlags::EMPTY,
                Some(format!(
                    "operation `{key}` is now bound by another dispatcher (epoch {current})"
                )),
            ),
            // only an `Attach` is answered so, and a takeover handles it before
            Some(EoReport::Idle { .. }) | None => (OpEnd::Lost, StatusFlags::EMPTY, None),
        };
        Effect {
            ended,
            flags,
            failure,
        }
    }
}

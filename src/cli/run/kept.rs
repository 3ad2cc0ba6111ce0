//! A run's report handed back to whoever ran it from this process (`marie up --runs`, whose
//! soak sums up every run's verdict), beside the files it writes.

use marie::report::RunReport;
use std::sync::{Arc, Mutex};

/// Where a run leaves its report once its mission has ended; empty until then, and for a
/// run that ended without one (refused, or failed before its mission ran). Cheap to clone;
/// clones share it.
#[derive(Clone, Debug, Default)]
pub(crate) struct KeptReport(Arc<Mutex<Option<RunReport>>>);

impl KeptReport {
    pub(super) fn keep(&self, report: &RunReport) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(report.clone());
    }

    /// Whether no report was left (the run's mission did not end, or it was taken).
    pub(crate) fn is_empty(&self) -> bool {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).is_none()
    }

    /// The report the run left, taken.
    pub(crate) fn take(&self) -> Option<RunReport> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
}

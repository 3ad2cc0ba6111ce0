//! Kinds of fault injected on purpose, as one serializable type for the injector (which
//! does it) and the run report and event stream (which record it).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// What is done to an operation to test self-healing. Serialized as `kill`, `panic` or
/// `hang` — stable names, read back by reports and event files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Kill its actor.
    Kill,
    /// Make its host panic ([`Fault::Panic`](super::Fault::Panic)).
    Panic,
    /// Make its host stop answering ([`Fault::Hang`](super::Fault::Hang)).
    Hang,
}

impl FaultKind {
    /// Every kind, in a stable order (for seeded chaos).
    pub const ALL: [FaultKind; 3] = [FaultKind::Kill, FaultKind::Panic, FaultKind::Hang];

    /// The stable name: the serialized form and what `--fault` accepts.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Kill => "kill",
            FaultKind::Panic => "panic",
            FaultKind::Hang => "hang",
        }
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fault name that is none of `kill`, `panic`, `hang` (e.g. in a `--fault` spec).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown fault `{0}` (expected kill, panic or hang)")]
pub struct UnknownFault(pub String);

impl FromStr for FaultKind {
    type Err = UnknownFault;

    /// Parse a name a user typed (a command-line flag); reports and events are read with
    /// serde instead.
    fn from_str(s: &str) -> Result<Self, UnknownFault> {
        FaultKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| UnknownFault(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_display_and_serialize_alike() {
        for kind in FaultKind::ALL {
            assert_eq!(kind.to_string().parse::<FaultKind>(), Ok(kind));
            let json = serde_json::to_string(&kind).unwrap();
            assert_eq!(json, format!("\"{kind}\""));
            assert_eq!(serde_json::from_str::<FaultKind>(&json).unwrap(), kind);
        }
        assert_eq!(
            "boom".parse::<FaultKind>().unwrap_err().to_string(),
            "unknown fault `boom` (expected kill, panic or hang)"
        );
    }
}

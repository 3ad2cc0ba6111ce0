//! What a [`super::Probe`] saw: per road, how its reads fared, the stale ones among them, and
//! whether its newest acknowledged write was read back at the end — and the one rule that
//! tells a stale read ([`stale`]), kept apart from the tasks so it can be tested alone.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// The road [`super::Probe`]'s reads take when they go through the datamanager's name, as
/// an application's [`crate::DmClient`] does (the others are named by the replica's node).
pub const BY_NAME: &str = "by name";

/// Whether a read is stale: it showed the probe's newest record as number `seen` (`None`:
/// none of its records), while `acked_before` of its writes (numbered 0, 1, 2, …) had been
/// acknowledged before the read was sent. A read may show a write not yet acknowledged
/// (committed, its answer on the way); it may never show less than every write acknowledged
/// before it began — that is what makes the reads linearizable against the writes.
pub fn stale(acked_before: u64, seen: Option<u64>) -> bool {
    match seen {
        Some(n) => n + 1 < acked_before,
        None => acked_before > 0,
    }
}

/// How the reads of one road fared.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RoadTally {
    /// Reads answered.
    pub answered: u64,
    /// Reads refused: the reply dropped unanswered (a replica that could not confirm it
    /// leads, or one that stopped), or for the road by name no leader found in time.
    pub refused: u64,
    /// Reads not answered within the probe's patience (a frozen node, a cut).
    pub unanswered: u64,
    /// Reads not sent: no replica of the datamanager found on that node at that moment
    /// (its node down or restarting).
    pub absent: u64,
    /// Answered reads that were stale ([`stale`]).
    pub stale: u64,
}

/// A stale read, told as it was seen.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StaleRead {
    /// The road it took: [`BY_NAME`] or a replica's node.
    pub road: String,
    /// The newest of the probe's records it showed (`None`: none).
    pub seen: Option<u64>,
    /// The newest of the probe's writes acknowledged before it was sent.
    pub newest_acked: u64,
    /// Milliseconds from the probe's start to when it was sent.
    pub at_ms: u64,
    /// The seq of the record it showed, as the datamanager numbered it.
    #[serde(default)]
    pub seen_seq: Option<u64>,
    /// The seq the newest acknowledged write was acknowledged with.
    #[serde(default)]
    pub acked_seq: Option<u64>,
}

/// An acknowledged write not found among the probe's records at its end, though newer
/// than the oldest one found (retention drops the oldest: those are not looked for).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LostWrite {
    /// The write's number.
    pub number: u64,
    /// The seq it was acknowledged with.
    pub acked_seq: u64,
    /// The seq it was found under instead (`None`: not found at all).
    pub found_seq: Option<u64>,
}

/// Every acknowledged write looked for at the probe's end: the datamanager's records of the
/// probe, as its leader holds them, against the seqs the writes were acknowledged with.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Survivors {
    /// Acknowledged writes looked for (those not older than the oldest record found).
    pub looked_for: u64,
    /// Of them, not found under the seq they were acknowledged with (at most
    /// [`super::STALE_KEPT`] described; `lost` counts them all).
    pub missing: Vec<LostWrite>,
    /// How many were not found under their seq.
    pub lost: u64,
}

/// The newest acknowledged write, looked for at the probe's end (by name, following the
/// datamanager to its leader).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "is")]
pub enum ReadBack {
    /// Nothing was acknowledged: nothing to look for.
    NothingWritten,
    /// Found: the newest record shown is at least the newest acknowledged.
    Found,
    /// Missing: the newest record shown is older (or none).
    Missing {
        /// The newest acknowledged.
        newest_acked: u64,
        /// What the read showed.
        seen: Option<u64>,
    },
    /// No answer: why.
    Unreachable {
        /// The error.
        error: String,
    },
}

/// Everything a probe saw, from its start to its stop.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProbeVerdict {
    /// The datamanager probed.
    pub dm: String,
    /// How long the probe ran, ms.
    pub ran_ms: u64,
    /// Writes acknowledged.
    pub writes: u64,
    /// Write attempts that failed (each tried again with the same producer number, so it
    /// is stored once).
    pub write_failures: u64,
    /// Reads, per road: [`BY_NAME`] and each replica's node.
    pub roads: BTreeMap<String, RoadTally>,
    /// The first stale reads (at most [`super::STALE_KEPT`]); their count is in the
    /// roads.
    pub stale_reads: Vec<StaleRead>,
    /// The newest acknowledged write, looked for at the end (`None` while it runs).
    pub read_back: Option<ReadBack>,
    /// Every acknowledged write the datamanager still keeps, looked for at the end (`None`
    /// while it runs, or if the records could not be read: see `read_back`).
    #[serde(default)]
    pub survivors: Option<Survivors>,
}

impl ProbeVerdict {
    /// Stale reads, over every road.
    pub fn stale(&self) -> u64 {
        self.roads.values().map(|r| r.stale).sum()
    }

    /// Reads answered, over every road.
    pub fn answered(&self) -> u64 {
        self.roads.values().map(|r| r.answered).sum()
    }

    /// The probe found nothing wrong: no stale read, and its newest acknowledged write read
    /// back (when it has been looked for).
    pub fn holds(&self) -> bool {
        self.stale() == 0
            && self.survivors.as_ref().is_none_or(|s| s.lost == 0)
            && !matches!(
                self.read_back,
                Some(ReadBack::Missing { .. } | ReadBack::Unreachable { .. })
            )
    }
}

impl fmt::Display for ProbeVerdict {
    /// `probe of feature, 12.0 s: 240 writes acknowledged (0 failed), reads: by name 500
    /// answered; spare 480 answered, 20 refused; …; 0 stale; the newest acknowledged write
    /// read back`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "probe of {}, {:.1} s: {} writes acknowledged ({} failed and tried again), reads: ",
            self.dm,
            self.ran_ms as f64 / 1000.0,
            self.writes,
            self.write_failures
        )?;
        let roads: Vec<String> = self
            .roads
            .iter()
            .map(|(road, t)| {
                let mut parts = vec![format!("{} answered", t.answered)];
                for (n, what) in [
                    (t.refused, "refused"),
                    (t.unanswered, "unanswered"),
                    (t.absent, "not sent (no replica)"),
                ] {
                    if n > 0 {
                        parts.push(format!("{n} {what}"));
                    }
                }
                format!("{road} {}", parts.join(", "))
            })
            .collect();
        match roads.is_empty() {
            true => write!(f, "none")?,
            false => write!(f, "{}", roads.join("; "))?,
        }
        write!(f, "; {} stale", self.stale())?;
        if let Some(s) = &self.survivors {
            write!(
                f,
                "; {} of the {} acknowledged writes still kept lost",
                s.lost, s.looked_for
            )?;
            for m in &s.missing {
                match m.found_seq {
                    Some(seq) => write!(
                        f,
                        " (number {} acknowledged as seq {}, found as seq {seq})",
                        m.number, m.acked_seq
                    )?,
                    None => write!(
                        f,
                        " (number {} acknowledged as seq {}, NOT found)",
                        m.number, m.acked_seq
                    )?,
                }
            }
        }
        match &self.read_back {
            None => Ok(()),
            Some(ReadBack::NothingWritten) => write!(f, "; nothing written to read back"),
            Some(ReadBack::Found) => write!(f, "; the newest acknowledged write read back"),
            Some(ReadBack::Missing { newest_acked, seen }) => write!(
                f,
                "; the newest acknowledged write (number {newest_acked}) is MISSING: the \
                 newest read back is {}",
                seen.map_or("none".to_string(), |n| format!("number {n}"))
            ),
            Some(ReadBack::Unreachable { error }) => {
                write!(
                    f,
                    "; the newest acknowledged write could not be read back: {error}"
                )
            }
        }
    }
}

impl fmt::Display for StaleRead {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a read {} sent {:.3} s into the probe showed {}, though number {} had been \
             acknowledged before it was sent",
            match self.road.as_str() {
                BY_NAME => "by name".to_string(),
                node => format!("of the replica on {node}"),
            },
            self.at_ms as f64 / 1000.0,
            self.seen
                .map_or("none of the probe's records".to_string(), |n| format!(
                    "record number {n}"
                )),
            self.newest_acked
        )?;
        if let (Some(seen), Some(acked)) = (self.seen_seq, self.acked_seq) {
            write!(f, " (seen as seq {seen}, acknowledged as seq {acked})")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_read_is_stale_when_it_shows_less_than_every_write_acknowledged_before_it_began() {
        // nothing acknowledged yet: anything goes, none included
        assert!(!stale(0, None));
        assert!(!stale(0, Some(0)));
        // writes 0..=4 acknowledged: 4 or a newer one not yet acknowledged is fresh
        assert!(!stale(5, Some(4)));
        assert!(!stale(5, Some(6)));
        // an older one, or none at all, is stale
        assert!(stale(5, Some(3)));
        assert!(stale(5, None));
    }

    #[test]
    fn a_verdict_sums_its_roads_says_what_went_wrong_and_reads_back_as_json() {
        let mut v = ProbeVerdict {
            dm: "feature".into(),
            ran_ms: 12_000,
            writes: 240,
            write_failures: 2,
            roads: BTreeMap::new(),
            stale_reads: Vec::new(),
            read_back: Some(ReadBack::Found),
            survivors: Some(Survivors {
                looked_for: 240,
                ..Survivors::default()
            }),
        };
        v.roads.insert(
            BY_NAME.into(),
            RoadTally {
                answered: 500,
                ..RoadTally::default()
            },
        );
        v.roads.insert(
            "spare".into(),
            RoadTally {
                answered: 480,
                refused: 20,
                absent: 3,
                ..RoadTally::default()
            },
        );
        assert!(v.holds());
        assert_eq!(v.answered(), 980);
        let said = v.to_string();
        assert!(
            said.contains("240 writes acknowledged (2 failed")
                && said
                    .contains("by name 500 answered; spare 480 answered, 20 refused, 3 not sent")
                && said.contains(
                    "; 0 stale; 0 of the 240 acknowledged writes still kept lost; the newest \
                     acknowledged write read back"
                ),
            "{said}"
        );
        let json = serde_json::to_string(&v).unwrap();
        assert_eq!(serde_json::from_str::<ProbeVerdict>(&json).unwrap(), v);

        v.roads.get_mut("spare").unwrap().stale = 1;
        v.stale_reads.push(StaleRead {
            road: "spare".into(),
            seen: Some(3),
            newest_acked: 7,
            at_ms: 1500,
            seen_seq: Some(30),
            acked_seq: Some(34),
        });
        assert!(!v.holds());
        assert!(v.to_string().contains("; 1 stale"));
        assert_eq!(
            v.stale_reads[0].to_string(),
            "a read of the replica on spare sent 1.500 s into the probe showed record number \
             3, though number 7 had been acknowledged before it was sent (seen as seq 30, \
             acknowledged as seq 34)"
        );
        v.roads.get_mut("spare").unwrap().stale = 0;
        v.survivors = Some(Survivors {
            looked_for: 240,
            missing: vec![LostWrite {
                number: 7,
                acked_seq: 34,
                found_seq: None,
            }],
            lost: 1,
        });
        assert!(!v.holds());
        assert!(
            v.to_string().contains(
                "; 1 of the 240 acknowledged writes still kept lost (number 7 acknowledged as \
                 seq 34, NOT found)"
            ),
            "{v}"
        );
        v.survivors = None;
        v.roads.get_mut("spare").unwrap().stale = 0;
        v.read_back = Some(ReadBack::Missing {
            newest_acked: 239,
            seen: None,
        });
        assert!(!v.holds());
        assert!(v.to_string().contains("(number 239) is MISSING"), "{v}");
    }
}

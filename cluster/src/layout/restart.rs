//! How `marie up` restarts a node whose process ended: OTP's restart types, intensity and a
//! backoff, per node in the cluster file — and the bookkeeping that applies them, pure (time
//! is passed in), so its rules are tested without processes.
//!
//! ```toml
//! [cluster]
//! cookie = "c"
//! restart = "permanent"   # every node's default: permanent, transient or temporary
//! max_restarts = 5        # more restarts of one node than this ...
//! restart_period = 60     # ... within this many seconds: `up` gives the node up
//! backoff = 0.1           # seconds before a restart, doubled for each recent one ...
//! max_backoff = 5         # ... up to this
//!
//! [[node]]
//! config = "cart.toml"
//! restart = "temporary"   # a node's own keys win
//! ```
//!
//! Why intensity gives one node up and not the cluster (OTP's supervisor would exit and
//! take its children with it): the other nodes of a robot's cluster still serve the
//! mission, and a run that needed the lost node ends on its own deadlines, with a reason.

use marie_vocabulary::diagnostic::toml::{Reader, Rule, Tbl};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The keys a `[cluster]` table (defaults) or a `[[node]]` (its own) may give.
pub(crate) const KEYS: [&str; 5] = [
    "restart",
    "max_restarts",
    "restart_period",
    "backoff",
    "max_backoff",
];

/// When a node whose process ended is started again (OTP's restart types).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RestartPolicy {
    /// Always (the default): a node of the cluster is meant to run.
    #[default]
    Permanent,
    /// Only when it ended abnormally: killed by a signal, or an exit code other than 0.
    Transient,
    /// Never.
    Temporary,
}

impl RestartPolicy {
    /// The word the cluster file uses.
    pub fn word(self) -> &'static str {
        match self {
            RestartPolicy::Permanent => "permanent",
            RestartPolicy::Transient => "transient",
            RestartPolicy::Temporary => "temporary",
        }
    }

    fn parse(word: &str) -> Option<RestartPolicy> {
        [
            RestartPolicy::Permanent,
            RestartPolicy::Transient,
            RestartPolicy::Temporary,
        ]
        .into_iter()
        .find(|p| p.word() == word)
    }
}

/// A node's restart settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeRestart {
    /// When it is started again.
    pub policy: RestartPolicy,
    /// More restarts than this within [`period`](Self::period): the node is given up.
    pub max_restarts: u32,
    /// The window restarts are counted in.
    pub period: Duration,
    /// The wait before a restart when none happened within the period; doubled for each
    /// one that did.
    pub backoff: Duration,
    /// The longest wait before a restart.
    pub max_backoff: Duration,
}

impl Default for NodeRestart {
    /// Permanent, 5 restarts in 60 s, waits from 0.1 s up to 5 s: a node killed once is
    /// back as fast as it starts; one that dies on every start is given up within seconds.
    fn default() -> Self {
        NodeRestart {
            policy: RestartPolicy::Permanent,
            max_restarts: 5,
            period: Duration::from_secs(60),
            backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(5),
        }
    }
}

impl NodeRestart {
    /// `self` with the restart keys `t` gives (a `[cluster]` table or a `[[node]]`); a bad
    /// value is a diagnostic at its line and leaves the setting as it was.
    pub(crate) fn read(mut self, r: &mut Reader<'_>, t: &Tbl<'_, '_>) -> NodeRestart {
        if let Some(v) = t.get("restart") {
            if let Some(word) = r.string_value(v, "restart") {
                match RestartPolicy::parse(&word) {
                    Some(p) => self.policy = p,
                    None => r.err(
                        &v.span(),
                        format!(
                            "`restart` must be \"permanent\", \"transient\" or \"temporary\", \
                             found \"{word}\""
                        ),
                    ),
                }
            }
        }
        if t.get("max_restarts").is_some() {
            if let Some(n) = r.integer(t, "max_restarts", None, 0..=1000) {
                self.max_restarts = n as u32;
            }
        }
        let secs = |r: &mut Reader<'_>, key: &str, rule: Rule| {
            t.get(key)?;
            r.num(t, key, None, rule).map(Duration::from_secs_f64)
        };
        if let Some(d) = secs(r, "restart_period", Rule::AboveUpTo(0.0, 86_400.0)) {
            self.period = d;
        }
        if let Some(d) = secs(r, "backoff", Rule::Within(0.0, 600.0)) {
            self.backoff = d;
        }
        if let Some(d) = secs(r, "max_backoff", Rule::Within(0.0, 600.0)) {
            self.max_backoff = d;
        }
        if self.max_backoff < self.backoff {
            let span = t
                .get("max_backoff")
                .or_else(|| t.get("backoff"))
                .map(|v| v.span())
                .unwrap_or(t.span.clone());
            r.err(
                &span,
                format!(
                    "`max_backoff` ({} s) must be at least `backoff` ({} s)",
                    self.max_backoff.as_secs_f64(),
                    self.backoff.as_secs_f64()
                ),
            );
            self.max_backoff = self.backoff;
        }
        self
    }
}

/// How a node's process ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// It exited with this code.
    Code(i32),
    /// A signal killed it.
    Signal(i32),
}

impl Exit {
    /// Whether it ended as asked to: exit code 0.
    pub fn is_normal(self) -> bool {
        self == Exit::Code(0)
    }
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Exit::Code(c) => write!(f, "exited with code {c}"),
            Exit::Signal(9) => write!(f, "was killed (SIGKILL)"),
            Exit::Signal(s) => write!(f, "was killed by signal {s}"),
        }
    }
}

/// What to do with a node whose process ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Start it again after `after`; it is the `nth` restart within the period.
    Restart {
        /// The wait first.
        after: Duration,
        /// Restarts within the period, this one included.
        nth: u32,
    },
    /// Its policy says it stays down.
    StaysDown,
    /// It was restarted more than `max_restarts` times within `period`: given up.
    GiveUp {
        /// The intensity's restarts.
        max_restarts: u32,
        /// The intensity's window.
        period: Duration,
    },
}

/// One node's restarts: its settings and when it was last restarted.
#[derive(Clone, Debug)]
pub struct RestartTracker {
    settings: NodeRestart,
    /// When each restart within the period was decided, oldest first.
    recent: VecDeque<Instant>,
}

impl RestartTracker {
    /// A node that has not been restarted yet.
    pub fn new(settings: NodeRestart) -> Self {
        RestartTracker {
            settings,
            recent: VecDeque::new(),
        }
    }

    /// Its settings.
    pub fn settings(&self) -> &NodeRestart {
        &self.settings
    }

    /// Its process ended (`exit`) at `now`: restart it, leave it down, or give it up.
    pub fn ended(&mut self, exit: Exit, now: Instant) -> Verdict {
        let s = self.settings;
        let restart = match s.policy {
            RestartPolicy::Permanent => true,
            RestartPolicy::Transient => !exit.is_normal(),
            RestartPolicy::Temporary => false,
        };
        if !restart {
            return Verdict::StaysDown;
        }
        while let Some(&t) = self.recent.front() {
            if now.saturating_duration_since(t) >= s.period {
                self.recent.pop_front();
            } else {
                break;
            }
        }
        if self.recent.len() as u32 >= s.max_restarts {
            return Verdict::GiveUp {
                max_restarts: s.max_restarts,
                period: s.period,
            };
        }
        let doublings = self.recent.len().min(30) as u32;
        let after = s
            .backoff
            .saturating_mul(1u32 << doublings)
            .min(s.max_backoff);
        self.recent.push_back(now);
        Verdict::Restart {
            after,
            nth: self.recent.len() as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(policy: RestartPolicy) -> NodeRestart {
        NodeRestart {
            policy,
            max_restarts: 3,
            period: Duration::from_secs(10),
            backoff: Duration::from_millis(100),
            max_backoff: Duration::from_millis(300),
        }
    }

    const KILLED: Exit = Exit::Signal(9);

    #[test]
    fn a_permanent_node_is_restarted_with_a_doubling_wait_until_the_intensity_gives_it_up() {
        let t0 = Instant::now();
        let mut r = RestartTracker::new(settings(RestartPolicy::Permanent));
        let ms = Duration::from_millis;
        assert_eq!(
            r.ended(KILLED, t0),
            Verdict::Restart {
                after: ms(100),
                nth: 1
            }
        );
        assert_eq!(
            r.ended(Exit::Code(0), t0 + ms(500)),
            Verdict::Restart {
                after: ms(200),
                nth: 2
            }
        );
        // doubled again, but never past the longest wait
        assert_eq!(
            r.ended(Exit::Code(1), t0 + ms(900)),
            Verdict::Restart {
                after: ms(300),
                nth: 3
            }
        );
        assert_eq!(
            r.ended(KILLED, t0 + ms(1200)),
            Verdict::GiveUp {
                max_restarts: 3,
                period: Duration::from_secs(10)
            }
        );
    }

    #[test]
    fn restarts_older_than_the_period_no_longer_count_and_the_wait_falls_back() {
        let t0 = Instant::now();
        let mut r = RestartTracker::new(settings(RestartPolicy::Permanent));
        for i in 0..3 {
            assert!(matches!(
                r.ended(KILLED, t0 + Duration::from_secs(i)),
                Verdict::Restart { .. }
            ));
        }
        // 10 s after the first: it has left the window, one slot is free again
        assert!(matches!(
            r.ended(KILLED, t0 + Duration::from_secs(10)),
            Verdict::Restart { nth: 3, .. }
        ));
        // long after all of them: the first wait again
        assert_eq!(
            r.ended(KILLED, t0 + Duration::from_secs(100)),
            Verdict::Restart {
                after: Duration::from_millis(100),
                nth: 1
            }
        );
    }

    #[test]
    fn a_transient_node_is_restarted_only_after_an_abnormal_end_and_a_temporary_one_never() {
        let now = Instant::now();
        let mut r = RestartTracker::new(settings(RestartPolicy::Transient));
        assert_eq!(r.ended(Exit::Code(0), now), Verdict::StaysDown);
        assert!(matches!(
            r.ended(Exit::Code(2), now),
            Verdict::Restart { .. }
        ));
        assert!(matches!(r.ended(KILLED, now), Verdict::Restart { .. }));
        let mut r = RestartTracker::new(settings(RestartPolicy::Temporary));
        assert_eq!(r.ended(KILLED, now), Verdict::StaysDown);
    }

    #[test]
    fn no_restart_at_all_gives_a_node_up_at_its_first_end() {
        let mut s = settings(RestartPolicy::Permanent);
        s.max_restarts = 0;
        let mut r = RestartTracker::new(s);
        assert!(matches!(
            r.ended(KILLED, Instant::now()),
            Verdict::GiveUp { .. }
        ));
    }

    #[test]
    fn an_exit_says_how_the_process_ended() {
        assert_eq!(KILLED.to_string(), "was killed (SIGKILL)");
        assert_eq!(Exit::Signal(15).to_string(), "was killed by signal 15");
        assert_eq!(Exit::Code(3).to_string(), "exited with code 3");
        assert!(Exit::Code(0).is_normal() && !KILLED.is_normal());
    }
}

//! A supervisor's own specification: strategy, restart intensity, backoff — and the bounds
//! its event channel and backoff must keep.

use std::time::Duration;

use crate::backoff::Backoff;
use crate::simple::ChildTemplate;
use crate::strategy::Strategy;

/// The largest event channel a supervisor accepts. tokio's broadcast channel allocates its
/// whole capacity up front, so an absurd capacity would abort the process on allocation.
pub const MAX_EVENT_CAPACITY: usize = 1 << 20;

/// The longest backoff delay a supervisor accepts: a restart put off for more than a day is a
/// unit mistake, not a policy.
pub const MAX_BACKOFF: Duration = Duration::from_secs(24 * 3600);

/// How a supervisor treats its children as a group (OTP's supervisor flags).
#[derive(Clone, Debug, PartialEq)]
pub struct SupervisorSpec {
    /// Which children restart together.
    pub strategy: Strategy,
    /// Restart intensity: more than `max_restarts` restarts within any `period` and the
    /// supervisor gives up — it stops its children in reverse start order and fails with
    /// [`crate::REACHED_MAX_RESTART_INTENSITY`], escalating to its parent. Every restart
    /// attempt counts, including attempts whose start failed.
    pub max_restarts: usize,
    /// The sliding window of the restart intensity.
    pub period: Duration,
    /// Delay between restart attempts; `None` (the default, as in OTP) restarts at once.
    pub backoff: Option<Backoff>,
    /// Capacity of the event channel ([`crate::SupervisorRef::subscribe`]); a subscriber that
    /// falls further behind misses events (it gets `RecvError::Lagged`). At most
    /// [`MAX_EVENT_CAPACITY`].
    pub event_capacity: usize,
    /// The child template of a [`Strategy::SimpleOneForOne`] supervisor (and only of one):
    /// its single child spec, of which every child is an instance.
    pub template: Option<ChildTemplate>,
}

impl SupervisorSpec {
    /// A spec with `strategy` and OTP's default intensity (1 restart in 5 s).
    pub fn new(strategy: Strategy) -> Self {
        SupervisorSpec {
            strategy,
            max_restarts: 1,
            period: Duration::from_secs(5),
            backoff: None,
            event_capacity: 1024,
            template: None,
        }
    }

    /// One-for-one with the default intensity.
    pub fn one_for_one() -> Self {
        Self::new(Strategy::OneForOne)
    }

    /// One-for-all with the default intensity.
    pub fn one_for_all() -> Self {
        Self::new(Strategy::OneForAll)
    }

    /// Rest-for-one with the default intensity.
    pub fn rest_for_one() -> Self {
        Self::new(Strategy::RestForOne)
    }

    /// Simple-one-for-one over instances of `template`, with the default intensity. The
    /// supervisor starts with no children (give it none); each
    /// [`crate::SupervisorRef::start_dynamic`] starts one more instance:
    ///
    /// ```
    /// # use marie_supervision::{ChildTemplate, Supervisor, SupervisorSpec};
    /// # use ractor::{Actor, ActorProcessingErr, ActorRef};
    /// # struct Op;
    /// # impl Actor for Op {
    /// #     type Msg = (); type State = (); type Arguments = String;
    /// #     async fn pre_start(&self, _: ActorRef<()>, _: String) -> Result<(), ActorProcessingErr> { Ok(()) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")]
    /// # async fn main() {
    /// let template = ChildTemplate::actor("op", |params: String| (Op, params));
    /// let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
    ///     .await
    ///     .unwrap();
    /// let first = sup.start_dynamic("north wall".to_string()).await.unwrap();
    /// let second = sup.start_dynamic("south wall".to_string()).await.unwrap();
    /// assert_ne!(first, second);
    /// assert_eq!(sup.count_children().await.unwrap().active, 2);
    /// sup.stop().await;
    /// # }
    /// ```
    pub fn simple_one_for_one(template: ChildTemplate) -> Self {
        SupervisorSpec {
            template: Some(template),
            ..Self::new(Strategy::SimpleOneForOne)
        }
    }

    /// The same spec allowing `max_restarts` restarts in any `period`.
    pub fn with_intensity(mut self, max_restarts: usize, period: Duration) -> Self {
        self.max_restarts = max_restarts;
        self.period = period;
        self
    }

    /// The same spec with a delay between restart attempts.
    pub fn with_backoff(mut self, backoff: Backoff) -> Self {
        self.backoff = Some(backoff);
        self
    }

    /// The same spec with another event channel capacity (clamped to
    /// `1..=`[`MAX_EVENT_CAPACITY`]).
    pub fn with_event_capacity(mut self, capacity: usize) -> Self {
        self.event_capacity = capacity.clamp(1, MAX_EVENT_CAPACITY);
        self
    }
}

impl Default for SupervisorSpec {
    fn default() -> Self {
        Self::one_for_one()
    }
}

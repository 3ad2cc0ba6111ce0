//! Time for operations and datamanagers.
//!
//! Everything in marie that reads the time or waits goes through a [`Clock`], so a simulation
//! can run faster than real time (the robot issue drives a simulated clock) and tests can step
//! time by hand. Time is a [`Duration`] since the clock's epoch (its creation), which is what
//! record timestamps, up-times and step periods need.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio::time::Instant;

/// A boxed future returned by [`Clock::sleep`].
pub type Sleep = Pin<Box<dyn Future<Output = ()> + Send>>;

/// A source of time shared by the actors of one node.
pub trait Clock: Send + Sync + 'static {
    /// Time elapsed since the clock's epoch.
    fn now(&self) -> Duration;
    /// A future that completes once `now()` has advanced by at least `d`.
    fn sleep(&self, d: Duration) -> Sleep;
}

/// A shared clock handle.
pub type SharedClock = Arc<dyn Clock>;

/// Send `msg` to `to` after `d` of `clock` time — the actors' timers (steps, deadlines,
/// timeouts), so that they follow a simulated clock too. The returned handle may be aborted to
/// cancel the timer; a message to an actor that has stopped meanwhile is dropped.
pub fn cast_after<M: ractor::Message>(
    clock: &SharedClock,
    d: Duration,
    to: &ractor::ActorRef<M>,
    msg: M,
) -> tokio::task::JoinHandle<()> {
    let to = to.clone();
    let sleep = clock.sleep(d);
    ractor::concurrency::spawn(async move {
        sleep.await;
        let _ = to.cast(msg);
    })
}

/// A timer that is cancelled when dropped: keep it where the state it belongs to lives (an
/// action, a binding, an actor's state), so that no sleeping task outlives what it was for.
#[derive(Debug)]
pub struct Timer(tokio::task::JoinHandle<()>);

impl Timer {
    /// Like [`cast_after`], cancelled when the returned timer is dropped.
    pub fn cast_after<M: ractor::Message>(
        clock: &SharedClock,
        d: Duration,
        to: &ractor::ActorRef<M>,
        msg: M,
    ) -> Timer {
        Timer(cast_after(clock, d, to, msg))
    }

    /// A task that ends in a message of its own making (e.g. a wait for something to
    /// appear), cancelled like a timer when the returned value is dropped.
    pub fn task(task: tokio::task::JoinHandle<()>) -> Timer {
        Timer(task)
    }
}

impl Drop for Timer {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// Runtime time: tokio's clock and timer.
///
/// On a normal runtime this is wall-clock time. On a current-thread runtime started with
/// tokio's paused clock (`start_paused`), time jumps to the next timer whenever every task is
/// idle — a discrete-event simulation clock that runs as fast as the CPU allows and, being
/// single-threaded, repeatably. `marie run` runs that way at every `--speed`, a [`Pacer`]
/// holding virtual time back to the speed asked for.
#[derive(Debug, Clone)]
pub struct RealClock {
    epoch: Instant,
}

impl RealClock {
    /// A clock whose epoch is now.
    pub fn new() -> Self {
        RealClock {
            epoch: Instant::now(),
        }
    }

    /// A shared handle to a new real clock.
    pub fn shared() -> SharedClock {
        Arc::new(Self::new())
    }

    /// The process's clock: one real clock every default shares (an operation host's,
    /// a node's), so that modules started without a clock of their own still agree on
    /// what time it is — a record stamped by one is found by another's query for the last
    /// second. Its epoch is its first use.
    ///
    /// ```
    /// use marie_vocabulary::clock::RealClock;
    /// let (a, b) = (RealClock::process(), RealClock::process());
    /// assert!(std::sync::Arc::ptr_eq(&a, &b));
    /// ```
    pub fn process() -> SharedClock {
        static PROCESS: std::sync::OnceLock<SharedClock> = std::sync::OnceLock::new();
        PROCESS.get_or_init(RealClock::shared).clone()
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for RealClock {
    fn now(&self) -> Duration {
        self.epoch.elapsed()
    }
    fn sleep(&self, d: Duration) -> Sleep {
        Box::pin(tokio::time::sleep(d))
    }
}

/// How often, in virtual time, a [`Pacer`] compares virtual with real time. The same at
/// every speed, so the set of timers a paced run has does not depend on its speed.
pub const PACER_PERIOD: Duration = Duration::from_millis(5);

/// How far virtual time may run ahead of the pace before a [`Pacer`] holds it back (shorter
/// thread sleeps would be mostly the OS's own granularity).
const PACER_SLACK: Duration = Duration::from_millis(1);

/// Paces virtual time: on a current-thread runtime with tokio's paused clock (see
/// [`RealClock`]), keeps virtual time from running ahead of `speed` × real time.
///
/// Its task wakes every [`PACER_PERIOD`] of virtual time and, when virtual time is ahead of
/// `speed` × the real time elapsed since it started, blocks the runtime's only thread
/// (`std::thread::sleep`) until real time has caught up. Blocking the thread, not sleeping
/// on a timer, is the point: nothing else runs and virtual time stands still meanwhile, so
/// pacing changes *when* (in real time) things happen, never *what* happens. At
/// [`Pacer::max`] the task runs just the same but never blocks: the tasks and timers of a run
/// are the same at every speed, and so is its outcome. Virtual time never runs ahead of the
/// actors that still have work at the current instant either — tokio only advances a paused
/// clock when every task is idle.
///
/// `marie run --speed X` runs this way; `--speed 1` is real time.
///
/// ```
/// use marie_vocabulary::clock::Pacer;
/// # let rt = tokio::runtime::Builder::new_current_thread().enable_all().start_paused(true).build().unwrap();
/// # rt.block_on(async {
/// let _pace = Pacer::new(100.0).spawn(); // paces until dropped
/// let real = std::time::Instant::now();
/// tokio::time::sleep(std::time::Duration::from_millis(500)).await; // virtual
/// // 500 ms / 100 = 5 ms, less one pacer period (5 ms / 100) and the slack (1 ms)
/// assert!(real.elapsed() >= std::time::Duration::from_millis(3));
/// # });
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pacer {
    speed: f64,
}

impl Pacer {
    /// Pace virtual time at `speed` × real time. A speed that is not a positive number
    /// (NaN, zero, negative) is taken as 1 (real time); `f64::INFINITY` is [`Pacer::max`].
    pub fn new(speed: f64) -> Pacer {
        let speed = if speed > 0.0 { speed } else { 1.0 };
        Pacer { speed }
    }

    /// Never hold virtual time back: as fast as the CPU allows.
    pub fn max() -> Pacer {
        Pacer {
            speed: f64::INFINITY,
        }
    }

    /// The speed factor (`f64::INFINITY` for [`Pacer::max`]).
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Start pacing on the current runtime, counting from now; pacing stops when the
    /// returned handle is dropped.
    pub fn spawn(self) -> Paced {
        Paced(tokio::spawn(self.run()))
    }

    /// The pacing loop (what [`Pacer::spawn`] runs).
    pub async fn run(self) {
        let (real0, virtual0) = (std::time::Instant::now(), Instant::now());
        let mut next = virtual0;
        loop {
            next += PACER_PERIOD;
            tokio::time::sleep_until(next).await;
            // at max the tick stays (the same timers at every speed) but reads no clock: a
            // system clock read per tick was 2 % of a docking run at --speed max
            if !self.speed.is_finite() {
                continue;
            }
            if let Some(ahead) = self.ahead(virtual0.elapsed(), real0.elapsed()) {
                std::thread::sleep(ahead);
            }
        }
    }

    /// How long to hold virtual time back after `virtual_elapsed` of it in `real_elapsed`
    /// of real time; `None` when it is not ahead by more than the slack.
    fn ahead(&self, virtual_elapsed: Duration, real_elapsed: Duration) -> Option<Duration> {
        if !self.speed.is_finite() {
            return None;
        }
        let ahead = virtual_elapsed
            .div_f64(self.speed)
            .saturating_sub(real_elapsed);
        (ahead >= PACER_SLACK).then_some(ahead)
    }
}

/// A running [`Pacer`]; pacing stops when it is dropped.
#[derive(Debug)]
pub struct Paced(tokio::task::JoinHandle<()>);

impl Drop for Paced {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// Real time scaled by a constant factor: at speed 10, one real second is ten clock seconds.
///
/// For a multi-threaded runtime on the wall clock (an embedder's node given one as
/// `NodeOptions::clock`, a cluster whose nodes share one factor). What happens then depends
/// on the scheduling of real threads; a single process that should run the same way at every
/// speed paces a paused clock with a [`Pacer`] instead.
///
/// [`ScaledClock::cluster`] counts from the Unix epoch instead of its own creation, so that
/// the nodes of a cluster — separate processes, each with its own clock — read the same time:
/// a record stamped by a datamanager on one node is found by a `since` query from an
/// operation on another.
#[derive(Debug, Clone)]
pub struct ScaledClock {
    epoch: Instant,
    /// Time at `epoch`, before scaling: zero, or the time since the Unix epoch.
    origin: Duration,
    speed: f64,
}

impl ScaledClock {
    /// A clock running `speed` times faster than real time. Non-finite or non-positive speeds
    /// are clamped to 1.
    pub fn new(speed: f64) -> Self {
        let speed = if speed.is_finite() && speed > 0.0 {
            speed
        } else {
            1.0
        };
        ScaledClock {
            epoch: Instant::now(),
            origin: Duration::ZERO,
            speed,
        }
    }

    /// The clock of a cluster member: wall-clock time since the Unix epoch, times `speed`.
    /// Every node of a cluster runs at the same factor and so reads the same time (up to the
    /// hosts' wall clocks: on several machines, keep them in sync with NTP). It never runs
    /// backwards: after creation it advances with the monotonic clock.
    pub fn cluster(speed: f64) -> Self {
        let origin = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        ScaledClock {
            origin,
            ..ScaledClock::new(speed)
        }
    }

    /// The speed factor.
    pub fn speed(&self) -> f64 {
        self.speed
    }
}

impl Clock for ScaledClock {
    fn now(&self) -> Duration {
        (self.origin + self.epoch.elapsed()).mul_f64(self.speed)
    }
    fn sleep(&self, d: Duration) -> Sleep {
        Box::pin(tokio::time::sleep(d.div_f64(self.speed)))
    }
}

/// A clock that moves only when told to: for tests and for simulations that step time
/// themselves. Sleepers wake when [`ManualClock::advance`] carries time past their deadline.
#[derive(Clone)]
pub struct ManualClock {
    inner: Arc<ManualInner>,
}

impl std::fmt::Debug for ManualClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ManualClock")
            .field("now", &self.now())
            .finish()
    }
}

struct ManualInner {
    now: Mutex<Duration>,
    tick: watch::Sender<Duration>,
}

impl ManualClock {
    /// A manual clock at time zero.
    pub fn new() -> Self {
        let (tick, _) = watch::channel(Duration::ZERO);
        ManualClock {
            inner: Arc::new(ManualInner {
                now: Mutex::new(Duration::ZERO),
                tick,
            }),
        }
    }

    /// Move time forward by `d`, waking every sleeper whose deadline has passed.
    pub fn advance(&self, d: Duration) {
        let now = {
            let mut now = self.inner.now.lock().unwrap_or_else(|e| e.into_inner());
            *now += d;
            *now
        };
        self.inner.tick.send_replace(now);
    }
}

impl Default for ManualClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Duration {
        *self.inner.now.lock().unwrap_or_else(|e| e.into_inner())
    }
    fn sleep(&self, d: Duration) -> Sleep {
        let deadline = self.now() + d;
        let mut rx = self.inner.tick.subscribe();
        Box::pin(async move {
            // `wait_for` checks the current value first, so an advance between `now()` and
            // `subscribe()` is not missed.
            let _ = rx.wait_for(|now| *now >= deadline).await;
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn manual_clock_wakes_sleepers_only_past_deadline() {
        let clock = ManualClock::new();
        let sleeper = tokio::spawn(clock.sleep(Duration::from_secs(5)));
        clock.advance(Duration::from_secs(4));
        tokio::task::yield_now().await;
        assert!(!sleeper.is_finished());
        clock.advance(Duration::from_secs(1));
        tokio::time::timeout(Duration::from_secs(10), sleeper)
            .await
            .expect("sleeper woke")
            .unwrap();
        assert_eq!(clock.now(), Duration::from_secs(5));
    }

    #[tokio::test]
    async fn scaled_clock_runs_faster() {
        let clock = ScaledClock::new(1000.0);
        let before = clock.now();
        clock.sleep(Duration::from_secs(1)).await;
        assert!(clock.now() - before >= Duration::from_secs(1));
    }
    #[test]
    fn cluster_clocks_created_apart_read_the_same_time() {
        let a = ScaledClock::cluster(4.0);
        std::thread::sleep(Duration::from_millis(20));
        let b = ScaledClock::cluster(4.0);
        let (ta, tb) = (a.now(), b.now());
        let apart = ta.abs_diff(tb);
        // read one after the other: a few microseconds apart, times 4; never the 80 ms a
        // per-process epoch would put between them
        assert!(apart < Duration::from_millis(10), "{apart:?}");
        assert!(ScaledClock::new(4.0).now() < Duration::from_secs(1));
    }

    #[test]
    fn a_pacer_holds_back_only_time_ahead_of_its_pace() {
        let ms = Duration::from_millis;
        let p = Pacer::new(10.0);
        // 100 ms of virtual time at 10× is 10 ms of real time
        assert_eq!(p.ahead(ms(100), ms(2)), Some(ms(8)));
        assert_eq!(p.ahead(ms(100), ms(10)), None);
        assert_eq!(p.ahead(ms(100), ms(50)), None);
        // within the slack: not worth a sleep
        assert_eq!(p.ahead(ms(100), Duration::from_micros(9_500)), None);
        assert_eq!(Pacer::max().ahead(ms(100), Duration::ZERO), None);
        assert_eq!(Pacer::new(f64::NAN).speed(), 1.0);
        assert_eq!(Pacer::new(-3.0).speed(), 1.0);
        assert!(Pacer::new(f64::INFINITY).speed().is_infinite());
    }

    #[test]
    fn a_paced_paused_clock_keeps_to_real_time() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(true)
            .build()
            .unwrap();
        let real = std::time::Instant::now();
        rt.block_on(async {
            let _pace = Pacer::new(2.0).spawn();
            tokio::time::sleep(Duration::from_millis(200)).await;
        });
        // 200 ms of virtual time at 2× take at least 100 ms, less the slack and a period
        assert!(
            real.elapsed() >= Duration::from_millis(90),
            "{:?}",
            real.elapsed()
        );
        // at max it never holds time back, however far ahead virtual time is (checked on
        // `ahead` itself: a wall-clock bound would make the test flaky on a loaded machine)
        for virtual_s in [1, 3600, 86_400] {
            assert_eq!(
                Pacer::max().ahead(Duration::from_secs(virtual_s), Duration::ZERO),
                None
            );
        }
    }
}

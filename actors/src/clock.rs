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
/// single-threaded, repeatably. `marie run --speed max` runs that way.
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

/// Real time scaled by a constant factor: at speed 10, one real second is ten clock seconds.
#[derive(Debug, Clone)]
pub struct ScaledClock {
    epoch: Instant,
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
            speed,
        }
    }

    /// The speed factor.
    pub fn speed(&self) -> f64 {
        self.speed
    }
}

impl Clock for ScaledClock {
    fn now(&self) -> Duration {
        self.epoch.elapsed().mul_f64(self.speed)
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
}

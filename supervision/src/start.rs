//! Running a child's start function: bounded by its start timeout, and with a panic in it
//! turned into a start error instead of taking the supervisor down.

use std::any::Any;
use std::future::Future;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use ractor::ActorCell;

use crate::child::{ChildStart, StartFn};
use crate::error::StartError;

/// Call `start` with the supervisor's cell and await the child, at most `timeout`. A start
/// that is dropped (timeout, supervisor shutdown) is abandoned at whatever `.await` it was in;
/// ractor cleans up an actor abandoned during its `pre_start`.
pub(crate) async fn run_start(
    start: &StartFn,
    supervisor: ActorCell,
    timeout: Option<Duration>,
) -> Result<ChildStart, StartError> {
    let started = match catch_unwind(AssertUnwindSafe(|| start(supervisor))) {
        Ok(future) => CatchUnwind(future),
        Err(panic) => return Err(panicked(panic)),
    };
    let outcome = match timeout {
        Some(limit) => match tokio::time::timeout(limit, started).await {
            Ok(outcome) => outcome,
            Err(_) => return Err(StartError::TimedOut { limit }),
        },
        None => started.await,
    };
    match outcome {
        Ok(Ok(started)) => Ok(started),
        Ok(Err(e)) => Err(StartError::from(e)),
        Err(panic) => Err(panicked(panic)),
    }
}

fn panicked(panic: Box<dyn Any + Send>) -> StartError {
    let message = panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown panic".to_string());
    StartError::Panicked { message }
}

/// A future that catches a panic while it is polled (std has no async `catch_unwind`).
struct CatchUnwind<F>(F);

impl<F: Future + Unpin> Future for CatchUnwind<F> {
    type Output = Result<F::Output, Box<dyn Any + Send>>;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        let inner = &mut self.0;
        match catch_unwind(AssertUnwindSafe(|| Pin::new(&mut *inner).poll(cx))) {
            Ok(Poll::Pending) => Poll::Pending,
            Ok(Poll::Ready(v)) => Poll::Ready(Ok(v)),
            Err(panic) => Poll::Ready(Err(panic)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ractor::SpawnErr;
    use std::sync::Arc;

    async fn cell() -> ActorCell {
        struct Nop;
        impl ractor::Actor for Nop {
            type Msg = ();
            type State = ();
            type Arguments = ();
            async fn pre_start(
                &self,
                _: ractor::ActorRef<()>,
                _: (),
            ) -> Result<(), ractor::ActorProcessingErr> {
                Ok(())
            }
        }
        let (a, _) = ractor::Actor::spawn(None, Nop, ()).await.unwrap();
        a.get_cell()
    }

    #[tokio::test]
    async fn panics_and_errors_become_start_errors() {
        let sup = cell().await;
        let panics_in_future: StartFn = Arc::new(|_| Box::pin(async { panic!("in the future") }));
        let err = run_start(&panics_in_future, sup.clone(), None)
            .await
            .unwrap_err();
        assert!(err.to_string().contains("in the future"), "{err}");
        assert_eq!(
            err,
            StartError::Panicked {
                message: "in the future".into()
            }
        );

        let panics_at_call: StartFn = Arc::new(|_| panic!("at the call"));
        let err = run_start(&panics_at_call, sup.clone(), None)
            .await
            .unwrap_err();
        assert!(err.to_string().contains("at the call"), "{err}");
        assert_eq!(err.to_string(), "start function panicked: at the call");

        let fails: StartFn =
            Arc::new(|_| Box::pin(async { Err(SpawnErr::StartupFailed("nope".into())) }));
        let err = run_start(&fails, sup.clone(), None).await.unwrap_err();
        assert!(err.to_string().contains("nope"), "{err}");
        assert!(
            matches!(&err, StartError::StartupFailed { reason } if reason == "nope"),
            "{err:?}"
        );
        assert_eq!(err.to_string(), "Actor panicked during startup 'nope'");

        let refused: StartFn =
            Arc::new(|_| Box::pin(async { Err(SpawnErr::ActorAlreadyRegistered("taken".into())) }));
        let err = run_start(&refused, sup.clone(), None).await.unwrap_err();
        assert_eq!(
            err,
            StartError::NameTaken {
                name: "taken".into()
            }
        );
        assert_eq!(
            err.to_string(),
            "Actor 'taken' is already registered in the actor registry"
        );
        sup.stop(None);
    }

    #[tokio::test(start_paused = true)]
    async fn a_hanging_start_times_out() {
        let sup = cell().await;
        let hangs: StartFn = Arc::new(|_| Box::pin(std::future::pending()));
        let err = run_start(&hangs, sup.clone(), Some(Duration::from_secs(3)))
            .await
            .unwrap_err();
        assert!(err.to_string().contains("timed out"), "{err}");
        assert_eq!(
            err,
            StartError::TimedOut {
                limit: Duration::from_secs(3)
            }
        );
        assert_eq!(err.to_string(), "start timed out after 3s");
        sup.stop(None);
    }
}

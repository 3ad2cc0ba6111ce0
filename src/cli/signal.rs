//! How a long-running verb (`node`, `up`) learns it should stop.

use std::future::Future;

/// SIGINT or SIGTERM, by name — or, with `stdin`, standard input closing.
///
/// The signals are watched from this call on, not from the future's first poll: call it
/// before printing the line that says the process now waits for Ctrl-C, so that a signal
/// sent right after that line (by a person or a test) is never missed. (Once a process
/// watches SIGINT, a SIGINT nobody watches at that moment is lost: the process neither
/// stops nor hears of it.) Must be called on a tokio runtime.
pub(crate) fn shutdown_signal(stdin: bool) -> impl Future<Output = &'static str> {
    use tokio::signal::unix::{signal, Signal, SignalKind};
    let watch = |kind: SignalKind, name: &str| {
        signal(kind)
            .map_err(|e| tracing::warn!("cannot watch {name}: {e}"))
            .ok()
    };
    let int = watch(SignalKind::interrupt(), "SIGINT");
    let term = watch(SignalKind::terminate(), "SIGTERM");
    async fn received(signal: Option<Signal>) {
        match signal {
            Some(mut s) => {
                s.recv().await;
            }
            None => std::future::pending().await,
        }
    }
    async move {
        let stdin_closed = async move {
            if !stdin {
                return std::future::pending().await;
            }
            // read until end of file on a detached thread (stdin is blocking; a runtime
            // would wait for a blocking task at exit, a detached thread ends with the
            // process)
            let (tx, rx) = tokio::sync::oneshot::channel::<()>();
            std::thread::spawn(move || {
                let mut buf = [0u8; 256];
                while matches!(std::io::Read::read(&mut std::io::stdin().lock(), &mut buf), Ok(n) if n > 0)
                {
                }
                let _ = tx.send(());
            });
            let _ = rx.await;
            "standard input closed"
        };
        tokio::select! {
            _ = received(int) => "SIGINT",
            _ = received(term) => "SIGTERM",
            why = stdin_closed => why,
        }
    }
}

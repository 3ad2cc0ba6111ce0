//! How a long-running verb (`node`, `up`) learns it should stop.

/// SIGINT or SIGTERM, by name — or, with `stdin`, standard input closing.
pub async fn shutdown_signal(stdin: bool) -> &'static str {
    use tokio::signal::unix::{signal, SignalKind};
    let stdin_closed = async move {
        if !stdin {
            return std::future::pending().await;
        }
        // read until end of file on a detached thread (stdin is blocking; a runtime would
        // wait for a blocking task at exit, a detached thread ends with the process)
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
    let mut term = match signal(SignalKind::terminate()) {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cannot watch SIGTERM: {e}");
            let _ = tokio::signal::ctrl_c().await;
            return "SIGINT";
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => "SIGINT",
        _ = term.recv() => "SIGTERM",
        why = stdin_closed => why,
    }
}

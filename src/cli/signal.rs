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

/// A watch of SIGINT and SIGTERM (or standard input closing) shared by everyone who stops on
/// it: it watches from [`Shutdown::watch`] on and remembers, so [`Shutdown::wait`] ends at
/// once for a signal that came before it was called, in every clone. Two watches made one
/// after the other would each miss what came before it was made: `marie up --run` and its
/// run share one (see `run::MissionOver`), so one Ctrl-C stops both whenever it comes.
#[derive(Clone, Debug)]
pub(crate) struct Shutdown {
    heard: tokio::sync::watch::Receiver<Option<&'static str>>,
    _watching: std::sync::Arc<Watching>,
}

/// The task that watches, stopped with the last clone.
#[derive(Debug)]
struct Watching(tokio::task::JoinHandle<()>);

impl Drop for Watching {
    fn drop(&mut self) {
        self.0.abort();
    }
}

impl Shutdown {
    /// Watch from now on (see [`shutdown_signal`]). Must be called on a tokio runtime.
    pub(crate) fn watch(stdin: bool) -> Shutdown {
        let signal = shutdown_signal(stdin);
        let (tell, heard) = tokio::sync::watch::channel(None);
        let task = tokio::spawn(async move {
            let _ = tell.send(Some(signal.await));
        });
        Shutdown {
            heard,
            _watching: std::sync::Arc::new(Watching(task)),
        }
    }

    /// The signal's name if one came (or standard input closed) since [`Shutdown::watch`].
    pub(crate) fn heard(&self) -> Option<&'static str> {
        *self.heard.borrow()
    }

    /// The signal's name once one came (or standard input closed) since [`Shutdown::watch`].
    pub(crate) async fn wait(&self) -> &'static str {
        let mut heard = self.heard.clone();
        let why = heard
            .wait_for(Option::is_some)
            .await
            .ok()
            .and_then(|why| *why);
        match why {
            Some(why) => why,
            // the watching task ended without a word: it was aborted, nothing will come
            None => std::future::pending().await,
        }
    }
}

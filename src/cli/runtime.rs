//! The tokio runtime a command runs on, and its diagnostics (tracing on stderr).

use clap::ValueEnum;
use std::io::IsTerminal;

/// Diagnostics format on stderr.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line.
    Json,
}

/// The runtime. In virtual time (`marie run`, at every `--speed`): a single thread with
/// tokio's paused clock, which jumps to the next timer whenever every actor is idle — a
/// discrete-event clock, repeatable, that a [`marie::clock::Pacer`] holds back to the
/// speed asked for. Otherwise (verbs that measure or wait in real time) multi-threaded on
/// the wall clock.
///
/// A virtual-time run without `io` (no socket, no signal to watch) has no I/O driver: with
/// one, every jump of the clock polled it with a system call (`epoll_wait`) and every timer
/// that became the next one woke it with another (an `eventfd` write) — some 36 000 system
/// calls and an eighth of a docking run's time at `--speed max`.
pub(crate) fn build(virtual_time: bool, io: bool) -> std::io::Result<tokio::runtime::Runtime> {
    if virtual_time {
        let mut builder = tokio::runtime::Builder::new_current_thread();
        if io {
            builder.enable_io();
        }
        builder.enable_time().start_paused(true).build()
    } else {
        tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
    }
}

/// Diagnostics on stderr, filtered by `RUST_LOG` (default `warn`, and `error` for ractor_cluster, whose warnings are routine session ends).
pub(crate) fn init_tracing(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,ractor_cluster=error"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        // colours only for a terminal: not in files, pipes or CI logs
        .with_ansi(std::io::stderr().is_terminal());
    match format {
        LogFormat::Text => builder.init(),
        LogFormat::Json => builder.json().init(),
    }
}

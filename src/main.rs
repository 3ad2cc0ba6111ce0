//! The `marie` command: run missions, list the location table, ask operations about
//! themselves. Results go to stdout, diagnostics (tracing) to stderr.
//!
//! Exit codes (the README's): 0 success, 1 mission failed, 2 bad input. The verbs live in
//! [`cli`], one module each; this file only parses, sets up and dispatches.

mod cli;

use clap::Parser;
use std::process::ExitCode;

/// The binary's allocator. A mission run makes and drops a great many small blocks (records,
/// messages, timers, tasks): with glibc's malloc, allocation and freeing were about a tenth
/// of the samples of a docking run at `--speed max`, and mimalloc made that run about 6 %
/// faster (interleaved runs, same binary). Only the binary: the library sets no allocator.
#[cfg(feature = "mimalloc")]
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, which turns a closed stdout (`marie ls | head`) into a panic in
    // the next println!; a command-line tool should just end, as others do.
    // SAFETY: called first, before any thread exists; SIG_DFL is a valid handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = cli::Cli::parse();
    cli::runtime::init_tracing(cli.log_format);
    cli::huge_pages::decline();
    cli.command.set_build();
    // dropped last: the private network outlives the runtime and the nodes in it
    let _network = match cli.command.before_runtime() {
        Ok(guard) => guard,
        Err(e) => return cli::error::report(&e),
    };
    let runtime = match cli::runtime::build(cli.command.virtual_time(), cli.command.io()) {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("marie: cannot start the runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(cli.command.execute()) {
        Ok(code) => code,
        Err(e) => cli::error::report(&e),
    }
}

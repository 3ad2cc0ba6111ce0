//! The `marie` command: run missions, list the location table, ask operations about
//! themselves. Results go to stdout, diagnostics (tracing) to stderr.
//!
//! Exit codes (DESIGN.md §8): 0 success, 1 mission failed, 2 bad input. The verbs live in
//! [`cli`], one module each; this file only parses, sets up and dispatches.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, which turns a closed stdout (`marie ls | head`) into a panic in
    // the next println!; a command-line tool should just end, as others do.
    // SAFETY: called first, before any thread exists; SIG_DFL is a valid handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = cli::Cli::parse();
    cli::runtime::init_tracing(cli.log_format);
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

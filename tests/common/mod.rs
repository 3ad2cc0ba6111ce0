//! Helpers shared by the end-to-end tests of the `marie` binary.

use std::process::{Command, Output};

/// Run the built `marie` with `args` from the package root, without `RUST_LOG`.
pub fn marie(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .output()
        .expect("marie runs")
}

/// Command output as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

//! How a failed command ends: bad input is exit 2 (see the README's exit codes), everything else exit 1.

use marie::cluster::node::NodeError;
use marie_missions::embedded::EmbeddedError;
use std::process::ExitCode;

/// Input the command refuses (a flag, a file, a name): exit 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct BadInput(pub String);

/// Print `e` on stderr and give its exit code.
pub(crate) fn report(e: &anyhow::Error) -> ExitCode {
    if let Some(NodeError::Mission(diags)) = e.downcast_ref::<NodeError>() {
        eprintln!("{diags}");
        return ExitCode::from(2);
    }
    if let Some(err) = e.downcast_ref::<EmbeddedError>() {
        if err.is_bad_input() {
            match err {
                // no file to point into: said as the command's own refusal
                EmbeddedError::Node(
                    node @ (NodeError::DataDir { .. } | NodeError::DataDirInUse { .. }),
                ) => eprintln!("marie: {node}"),
                _ => eprintln!("{err}"),
            }
            return ExitCode::from(2);
        }
    }
    eprintln!("marie: {e:#}");
    if e.downcast_ref::<BadInput>().is_some() {
        return ExitCode::from(2);
    }
    ExitCode::from(1)
}

//! The private network of Linux namespaces `marie up`'s nodes run in when they may be cut
//! apart, made before the runtime's threads exist (see [`netns`](crate::cli::netns)).

use super::UpArgs;
use crate::cli::error::BadInput;
use crate::cli::netns::{NetGuard, PrivateNet};
use marie::cluster::layout::ClusterLayout;
use marie::run::FaultKind;

/// Make the private network `args` need, and move this thread into it (see [`netns`]):
/// when a partition is planned or `--private-network` given — refused (exit 2) where it
/// cannot be made — and, where it can be, for `--chaos-nodes`.
///
/// [`netns`]: crate::cli::netns
pub(crate) fn private_network(args: &UpArgs) -> anyhow::Result<Option<NetGuard>> {
    let partitions = args.faults.iter().any(|f| f.kind == FaultKind::Partition);
    if !(partitions || args.private_network || args.chaos_nodes.is_some()) {
        return Ok(None);
    }
    let catalog = marie_missions::catalog();
    // a bad file is said by `up` itself, as without a network
    let Ok(layout) = ClusterLayout::load(&args.cluster, &catalog) else {
        return Ok(None);
    };
    let names: Vec<String> = layout.nodes.iter().map(|n| n.config.name.clone()).collect();
    match PrivateNet::enter(&names) {
        Ok(guard) => Ok(Some(guard)),
        Err(e) if partitions || args.private_network => Err(BadInput(format!(
            "{}: the nodes must run in a private network of namespaces, and none can be made \
             here (it needs root and `ip`): {e}",
            if partitions {
                "--fault partition"
            } else {
                "--private-network"
            }
        ))
        .into()),
        Err(e) => {
            tracing::info!("--chaos-nodes without partitions: no private network ({e})");
            Ok(None)
        }
    }
}

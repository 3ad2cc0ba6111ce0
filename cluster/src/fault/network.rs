//! The network between the nodes a process started, as a fault cuts it: what makes a
//! [`FaultKind::Partition`](marie_vocabulary::run::FaultKind::Partition) possible here.
//!
//! The node crate does not make networks: whoever starts the nodes in one it can cut
//! (`marie up`, in a private network of Linux namespaces) hands an implementation to
//! [`NodeProcesses::with_network`](super::NodeProcesses::with_network).

use std::fmt;

/// A network in which two groups of nodes can be cut apart and healed again.
pub trait NodeNetwork: Send + Sync + fmt::Debug {
    /// Cut every node of `a` off from every node of `b`, both ways: their packets vanish
    /// silently, as behind a cut cable. The nodes of each group still reach each other,
    /// and whoever started them still reaches all.
    fn cut(&self, a: &[String], b: &[String]) -> std::io::Result<()>;

    /// Undo a [`cut`](Self::cut) of the same groups. A pair of nodes that another cut still
    /// separates stays cut.
    fn heal(&self, a: &[String], b: &[String]) -> std::io::Result<()>;
}

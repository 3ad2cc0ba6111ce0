//! An application's own ractor actor, written as an embedder of marie writes it.
//!
//! Linking marie turns on ractor's `cluster` feature for the whole build (ractor_cluster
//! forces it), and with it every message type needs its own `ractor::Message` impl. This
//! crate holds a plain enum actor whose only concession to that is
//! `#[derive(marie::RactorMessage)]`, and depends on nothing but marie, ractor and tokio:
//! if marie stopped offering the derive, or the derive expanded to a path such a crate
//! cannot name, this crate would no longer compile. `tests/plain_actor.rs` runs the actor
//! beside a marie operation.
//!
//! ```
//! use marie_plain_actor_check::{Tally, TallyMsg};
//! # #[tokio::main(flavor = "current_thread")] async fn main() {
//! let (tally, handle) = ractor::Actor::spawn(None, Tally, ()).await.unwrap();
//! tally.cast(TallyMsg::Add(4)).unwrap();
//! assert_eq!(ractor::call!(tally, TallyMsg::Total).unwrap(), 4);
//! tally.stop(None);
//! handle.await.unwrap();
//! # }
//! ```

use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};

/// The messages of [`Tally`]: a plain enum, casts and calls, no serialization.
#[derive(marie::RactorMessage)]
pub enum TallyMsg {
    /// Add to the total (cast).
    Add(i64),
    /// Forget everything (cast).
    Reset,
    /// The total so far (call).
    Total(RpcReplyPort<i64>),
    /// Add `by` and answer the new total (call with an argument).
    AddAndGet {
        /// What to add.
        by: i64,
        /// Where the new total goes.
        reply: RpcReplyPort<i64>,
    },
}

impl std::fmt::Debug for TallyMsg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TallyMsg::Add(n) => f.debug_tuple("Add").field(n).finish(),
            TallyMsg::Reset => f.write_str("Reset"),
            TallyMsg::Total(_) => f.write_str("Total"),
            TallyMsg::AddAndGet { by, .. } => f.debug_struct("AddAndGet").field("by", by).finish(),
        }
    }
}

/// An actor that sums what it is sent.
#[derive(Debug)]
pub struct Tally;

impl Actor for Tally {
    type Msg = TallyMsg;
    type State = i64;
    type Arguments = ();

    async fn pre_start(
        &self,
        _myself: ActorRef<TallyMsg>,
        _args: (),
    ) -> Result<i64, ActorProcessingErr> {
        Ok(0)
    }

    async fn handle(
        &self,
        _myself: ActorRef<TallyMsg>,
        msg: TallyMsg,
        total: &mut i64,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            TallyMsg::Add(n) => *total += n,
            TallyMsg::Reset => *total = 0,
            TallyMsg::Total(reply) => {
                let _ = reply.send(*total);
            }
            TallyMsg::AddAndGet { by, reply } => {
                *total += by;
                let _ = reply.send(*total);
            }
        }
        Ok(())
    }
}

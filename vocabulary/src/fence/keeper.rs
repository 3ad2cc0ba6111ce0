//! A receiver's fence keeper: how a dispatcher tells the receivers a new epoch before any
//! command carries it.
//!
//! Why: a receiver learns a rebind from the stand-in's first command. Between the rebind
//! and that command — a few ms, more while the stand-in's node is loaded — a replaced
//! incarnation that wakes up (a frozen node, a healed partition) is still obeyed. So a
//! receiver that obeys fenced commands (the simulated cart's drivers) shares its
//! [`FenceTable`] with a keeper actor, in `pg` (scope [`SCOPE`], group [`GROUP`]) where a
//! dispatcher on any node finds it; the dispatcher, once an epoch is recorded and before
//! its first command, [`announce`]s it, and every keeper in reach raises its table.
//!
//! A keeper that does not answer within [`ANNOUNCE_TIMEOUT`] (its node frozen, not yet declared
//! down) is passed over: the rebind goes on, and the stand-in's first command fences as
//! before. A keeper on a node the failure detector declared down is not asked.
//!
//! ```
//! use marie_vocabulary::fence::{announce, spawn_keeper, Fence, FenceTable};
//! use std::sync::{Arc, Mutex};
//! # marie_vocabulary::remote_message! { enum CartMsg { Drive { fence: Fence } } }
//! # struct Cart;
//! # impl ractor::Actor for Cart {
//! #     type Msg = CartMsg;
//! #     type State = ();
//! #     type Arguments = ();
//! #     async fn pre_start(
//! #         &self,
//! #         _: ractor::ActorRef<CartMsg>,
//! #         _: (),
//! #     ) -> Result<(), ractor::ActorProcessingErr> {
//! #         Ok(())
//! #     }
//! # }
//! # #[tokio::main]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let (cart, _) = ractor::Actor::spawn(None, Cart, ()).await?;
//! // the receiver (here a cart) shares its table with a keeper linked to it
//! let table = Arc::new(Mutex::new(FenceTable::default()));
//! spawn_keeper(table.clone(), cart.get_cell()).await?;
//! // a dispatcher binds wall-follower at epoch 8 and says so before any command
//! let told = announce(&[Fence::new("wall-follower", 8)]).await;
//! assert_eq!((told.keepers, told.told), (1, 1));
//! // the replaced incarnation's next command is refused
//! assert!(table.lock().unwrap().admit(&Fence::new("wall-follower", 7)).is_err());
//! # Ok(()) }
//! ```

use super::{Fence, FenceTable};
use crate::registry;
use ractor::rpc::CallResult;
use ractor::{pg, Actor, ActorCell, ActorProcessingErr, ActorRef, SpawnErr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The `pg` scope of fence keepers.
pub const SCOPE: &str = "marie-fences";
/// The `pg` group of fence keepers.
pub const GROUP: &str = "keepers";
/// How long an announcement waits for one keeper (real time).
pub const ANNOUNCE_TIMEOUT: Duration = Duration::from_millis(500);

crate::remote_message! {
    /// Messages of a fence keeper.
    pub enum FenceMsg {
        /// Raise each operation's newest epoch to the one given (never lower it); answers
        /// once the table holds them.
        Advance {
            /// The operations and their new epochs.
            fences: Vec<Fence>,
        } -> (),
    }
}

/// A fence keeper: raises a shared [`FenceTable`] when a dispatcher announces epochs.
#[derive(Debug)]
pub struct FenceKeeper;

impl Actor for FenceKeeper {
    type Msg = FenceMsg;
    type State = Arc<Mutex<FenceTable>>;
    type Arguments = Arc<Mutex<FenceTable>>;

    async fn pre_start(
        &self,
        myself: ActorRef<FenceMsg>,
        table: Arc<Mutex<FenceTable>>,
    ) -> Result<Self::State, ActorProcessingErr> {
        pg::join_scoped(SCOPE.into(), GROUP.into(), vec![myself.get_cell()]);
        Ok(table)
    }

    async fn handle(
        &self,
        _myself: ActorRef<FenceMsg>,
        msg: FenceMsg,
        table: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            FenceMsg::Advance { fences, reply } => {
                {
                    let mut table = table.lock().unwrap_or_else(|e| e.into_inner());
                    for fence in &fences {
                        table.advance(fence);
                    }
                }
                tracing::debug!(?fences, "fences raised by the dispatcher");
                let _ = reply.send(());
            }
        }
        Ok(())
    }
}

/// Spawn a keeper of `table`, linked to `receiver` (the actor that admits commands with
/// it): it stops with the receiver, and its stopping reaches the receiver's supervision
/// events (override `handle_supervisor_evt`: ractor's default stops the receiver).
pub async fn spawn_keeper(
    table: Arc<Mutex<FenceTable>>,
    receiver: ActorCell,
) -> Result<ActorRef<FenceMsg>, SpawnErr> {
    let (keeper, _) = Actor::spawn_linked(None, FenceKeeper, table, receiver).await?;
    Ok(keeper)
}

/// What an [`announce`] reached.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Announced {
    /// Keepers asked (those on nodes not declared down).
    pub keepers: usize,
    /// Keepers that raised their tables.
    pub told: usize,
}

/// Tell every fence keeper in reach the epochs of `fences`, all at once, and wait until
/// each raised its table or [`ANNOUNCE_TIMEOUT`] passed.
pub async fn announce(fences: &[Fence]) -> Announced {
    let members = pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string());
    let asks: Vec<_> = members
        .into_iter()
        .filter(|cell| {
            let id = cell.get_id();
            id.is_local() || !registry::is_declared_down(&registry::node_name_of(&id))
        })
        .map(|cell| {
            let keeper: ActorRef<FenceMsg> = cell.into();
            let fences = fences.to_vec();
            ractor::concurrency::spawn(async move {
                let answer = keeper
                    .call(|reply| FenceMsg::Advance { fences, reply }, Some(ANNOUNCE_TIMEOUT))
                    .await;
                let told = matches!(answer, Ok(CallResult::Success(())));
                if !told {
                    tracing::warn!(keeper = %keeper.get_id(), "a fence keeper did not answer the announcement of new epochs");
                }
                told
            })
        })
        .collect();
    let mut announced = Announced {
        keepers: asks.len(),
        told: 0,
    };
    for ask in asks {
        if matches!(ask.await, Ok(true)) {
            announced.told += 1;
        }
    }
    announced
}

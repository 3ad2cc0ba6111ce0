//! The robot's elementary operations (thesis ids), each an [`Operation`] wrapping an algorithm
//! of [`crate::algo`]. They exchange data only through the datamanagers (see [`records`]) and
//! reach the virtual hardware through the registry.
//!
//! [`Operation`]: marie_actors::eo::Operation

mod avoidance;
mod localization;
mod motion;
mod perception;
pub mod records;
mod ultrasonic;

pub use avoidance::CollisionAvoidance;
pub use localization::Localizer;
pub use motion::{
    PathPlanner, SensorBasedController, TrajectoryController, WallFollowerV1, WallFollowerV2,
};
pub use perception::{DockingDetector, SegmentExtractor, WallSensor};
pub use ultrasonic::Ultrasonic;

use crate::hardware::CartClient;
use marie_actors::dm::DmError;
use marie_actors::eo::{OpContext, OpError};

/// The cart client, found in the registry on first use and again after the cart restarted,
/// carrying the running activation's fence: the cart obeys only the newest incarnation of
/// an operation ([`marie_actors::fence`]).
pub(crate) fn cart<'s>(
    slot: &'s mut Option<CartClient>,
    ctx: &OpContext,
) -> Result<&'s CartClient, OpError> {
    if !slot.as_ref().is_some_and(CartClient::is_alive) {
        *slot = Some(CartClient::lookup().map_err(|e| OpError::failed(e.to_string()))?);
    }
    let client = slot
        .as_mut()
        .ok_or_else(|| OpError::failed("no virtual cart is running"))?;
    // the slot is one operation's: only the epoch changes, once per activation
    if client.fence().epoch != ctx.epoch() {
        client.set_fence(ctx.fence());
    }
    Ok(client)
}

/// Turn a cart error into an operation error.
pub(crate) fn cart_err(e: crate::hardware::CartError) -> OpError {
    OpError::failed(e.to_string())
}

/// The newest record of `class` in datamanager `dm`, decoded; `None` when there is none.
pub(crate) async fn newest<T: marie_actors::dm::PayloadType>(
    ctx: &mut marie_actors::eo::OpContext,
    dm: &'static str,
    class: &str,
) -> Result<Option<T>, OpError> {
    Ok(newest_with_seq(ctx, dm, class).await?.map(|(_, v)| v))
}

/// Like [`newest`], with the record's sequence number.
pub(crate) async fn newest_with_seq<T: marie_actors::dm::PayloadType>(
    ctx: &mut marie_actors::eo::OpContext,
    dm: &'static str,
    class: &str,
) -> Result<Option<(u64, T)>, OpError> {
    let records = ctx
        .dm(dm)?
        .select(marie_actors::dm::Query::class(class).newest(1))
        .await
        .map_err(dm_err(dm))?;
    match records.last() {
        Some(r) => Ok(Some((r.seq, r.decode().map_err(dm_err(dm))?))),
        None => Ok(None),
    }
}

/// Turn a datamanager error into an operation error naming the DM.
pub(crate) fn dm_err(dm: &'static str) -> impl Fn(DmError) -> OpError {
    move |e| OpError::Datamanager {
        dm: dm.to_string(),
        problem: e.to_string(),
    }
}

/// The localizer's newest odometry correction ([`records::LocationRecord`]); the identity
/// when there is none yet (the odometry starts at the world's start pose).
pub(crate) async fn correction(
    ctx: &mut marie_actors::eo::OpContext,
) -> Result<crate::geom::Pose, OpError> {
    Ok(
        newest::<records::LocationRecord>(ctx, "world", records::LOCATION)
            .await?
            .map(|r| r.correction)
            .unwrap_or_default(),
    )
}

/// The cart's pose in the map frame: its `odometry` under the localizer's newest correction.
/// Every operation that places things in the world or drives to a place uses this, never the
/// raw odometry, which drifts.
pub(crate) async fn located(
    ctx: &mut marie_actors::eo::OpContext,
    odometry: &crate::geom::Pose,
) -> Result<crate::geom::Pose, OpError> {
    Ok(crate::algo::localize::corrected(
        &correction(ctx).await?,
        odometry,
    ))
}

//! What a handle changes: parameters, all or none, at the instance's current epoch.

use super::follow::{Attempt, Bound};
use super::OperationHandle;
use crate::eo::handle_error::SetError;
use crate::eo::messages::ParamOutcome;
use marie_vocabulary::property::{ParamMap, PropertyReply, PropertyRequest, Value};

impl OperationHandle {
    /// Change parameters: all of `values` or none. Refused values come back as
    /// [`SetError::Rejected`], one [`marie_vocabulary::property::Rejection`] each, and nothing changed.
    ///
    /// The command goes at the instance's current epoch, read just before (see
    /// [`OperationHandle`]); answered `Stale` — a dispatcher raised the epoch in between — it is sent
    /// once more at the epoch the answer names, then [`SetError::Superseded`].
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0), ParamDecl::int("stages", 1)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// use marie_actors::eo::{OperationHandle, SetError};
    /// use marie_vocabulary::property::{param_map, RejectReason, Value};
    /// let pump = OperationHandle::lookup("pump").await.unwrap();
    /// pump.set(param_map([("rate", Value::Float(4.0)), ("stages", Value::Int(2))])).await.unwrap();
    ///
    /// let Err(SetError::Rejected { rejections, .. }) =
    ///     pump.set(param_map([("rate", Value::Float(12.0)), ("stages", Value::Int(3))])).await
    /// else { panic!("a rate of 12 is out of range") };
    /// assert_eq!(rejections.len(), 1);
    /// assert_eq!(rejections[0].name, "rate");
    /// assert!(matches!(rejections[0].reason, RejectReason::OutOfRange { .. }));
    /// assert_eq!(pump.value::<i64>("stages").await.unwrap(), 2, "nothing changed");
    /// # }
    /// ```
    pub async fn set(&self, values: ParamMap) -> Result<(), SetError> {
        self.call(|bound| {
            let values = values.clone();
            async move { set_at_current_epoch(&bound, values).await }
        })
        .await?
    }
}

/// Read the instance's epoch, parameterize at it; if it moved on in between, once more at
/// the epoch the answer names.
async fn set_at_current_epoch(
    bound: &Bound,
    values: ParamMap,
) -> Result<Result<(), SetError>, Attempt> {
    let mut epoch = match bound
        .client
        .property(PropertyRequest::Get("epoch".into()))
        .await?
    {
        PropertyReply::Value(Value::Int(e)) => u64::try_from(e).unwrap_or(0),
        other => return Err(bound.unexpected("its epoch", other).into()),
    };
    for _ in 0..2 {
        match bound.client.parameterize(values.clone(), epoch).await? {
            ParamOutcome::Applied => return Ok(Ok(())),
            ParamOutcome::Rejected(rejections) => {
                return Ok(Err(SetError::Rejected {
                    operation: bound.name.clone(),
                    node: bound.node.clone(),
                    rejections,
                }))
            }
            ParamOutcome::Stale { current } => epoch = current,
        }
    }
    Ok(Err(SetError::Superseded {
        operation: bound.name.clone(),
        node: bound.node.clone(),
        epoch,
    }))
}

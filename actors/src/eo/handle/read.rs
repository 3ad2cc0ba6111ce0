//! What a handle reads: the operation's identity, parameter schema, flags, general
//! properties, current values (typed), and any property by name.

use super::follow::Bound;
use super::OperationHandle;
use crate::eo::handle_error::HandleError;
use crate::eo::operation::Identity;
use marie_vocabulary::property::{
    Collection, FromValue, General, Group, ParamMap, ParamSchema, PropertyReply, PropertyRequest,
    Specific, Value,
};
use marie_vocabulary::status::FlagDecl;

impl OperationHandle {
    /// Who the operation is: name, id, version, description.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.identity().await.unwrap(), Identity::new("pump", 7101, "1.2.0", "pumps"));
    /// # }
    /// ```
    pub async fn identity(&self) -> Result<Identity, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::Identification))
                .await?
            {
                PropertyReply::Identification(i) => Ok(Identity {
                    name: i.name.to_string(),
                    id: i.id,
                    version: semver::Version::parse(&i.version)
                        .map_err(|_| bound.unexpected("its identity", &i))?,
                    description: i.description.to_string(),
                }),
                other => Err(bound.unexpected("its identity", other).into()),
            }
        })
        .await
    }

    /// The parameters it declares: names, types, defaults, ranges.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// let schema = pump.schema().await.unwrap();
    /// assert_eq!(schema.params[0].name, "rate");
    /// assert_eq!(schema.params[0].max, Some(10.0));
    /// # }
    /// ```
    pub async fn schema(&self) -> Result<ParamSchema, HandleError> {
        Ok(ParamSchema::new(self.specific().await?.params))
    }

    /// The status flags it can raise, in bit order.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::status::FlagDecl;
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn flags(&self) -> Vec<FlagDecl> { vec![FlagDecl::new("primed", "pressure reached")] }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.flags().await.unwrap()[0].name, "primed");
    /// # }
    /// ```
    pub async fn flags(&self) -> Result<Vec<FlagDecl>, HandleError> {
        Ok(self.specific().await?.flags)
    }

    async fn specific(&self) -> Result<Specific, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::Specific))
                .await?
            {
                PropertyReply::Specific(s) => Ok(s),
                other => Err(bound.unexpected("its parameter declarations", other).into()),
            }
        })
        .await
    }

    /// Its general properties: up-time, whether an activation runs, how many ran, its
    /// epoch, its declared deadline.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// let general = pump.general().await.unwrap();
    /// assert!(!general.in_use);
    /// assert_eq!(general.activations, 0);
    /// # }
    /// ```
    pub async fn general(&self) -> Result<General, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Group(Group::General))
                .await?
            {
                PropertyReply::General(g) => Ok(g),
                other => Err(bound.unexpected("its general properties", other).into()),
            }
        })
        .await
    }

    /// Every parameter's current value.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0).range(0.0, 10.0)])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.current().await.unwrap()["rate"], Value::Float(1.0));
    /// # }
    /// ```
    pub async fn current(&self) -> Result<ParamMap, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Collection(Collection::Current))
                .await?
            {
                PropertyReply::Current(values) => Ok(values),
                other => Err(bound.unexpected("its current values", other).into()),
            }
        })
        .await
    }

    /// The current value of the parameter `key` names, of the key's type — the typed form
    /// of [`OperationHandle::value`].
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// use marie_actors::prelude::*;
    /// params! {
    ///     struct PumpParams {
    ///         /// litres per minute
    ///         rate: f64 = 1.0, range(0.0, 10.0);
    ///     }
    /// }
    /// struct Pump;
    /// impl Operation for Pump {
    ///     fn identity(&self) -> Identity { Identity::new("typed-pump", 7102, "1.0.0", "pumps") }
    ///     fn parameters(&self) -> ParamSchema { PumpParams::schema() }
    ///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = eo::OperationHandle::lookup("typed-pump").await.unwrap();
    /// pump.set(ParamMap::new().with(PumpParams::rate(), 2.5)).await.unwrap();
    /// let rate: f64 = pump.param(PumpParams::rate()).await.unwrap();
    /// assert_eq!(rate, 2.5);
    /// # }
    /// ```
    pub async fn param<T: crate::declare::ParamValue>(
        &self,
        key: crate::declare::Param<T>,
    ) -> Result<T, HandleError> {
        self.value::<T>(key.name()).await
    }

    /// The current value of parameter `name`, as a `T`: [`HandleError::NoParameter`] if it
    /// declares none of that name, [`HandleError::WrongType`] if it is no `T`.
    ///
    /// With a parameter declared by [`params!`](crate::params), [`OperationHandle::param`]
    /// takes its typed key instead: a typo is then a compile error.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::property::{ParamDecl, ParamSchema};
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn parameters(&self) -> ParamSchema {
    /// #         ParamSchema::new(vec![ParamDecl::float("rate", 1.0), ParamDecl::text("fluid", "water")])
    /// #     }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// use marie_actors::eo::{HandleError, OperationHandle};
    /// let pump = OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.value::<f64>("rate").await.unwrap(), 1.0);
    /// assert_eq!(pump.value::<String>("fluid").await.unwrap(), "water");
    /// assert!(matches!(pump.value::<bool>("rate").await, Err(HandleError::WrongType { .. })));
    /// assert!(matches!(pump.value::<f64>("speed").await, Err(HandleError::NoParameter { .. })));
    /// # }
    /// ```
    pub async fn value<T: FromValue>(&self, name: &str) -> Result<T, HandleError> {
        let asked = format!("param.{name}");
        self.call(|bound| {
            let asked = asked.clone();
            async move {
                match bound.client.property(PropertyRequest::Get(asked)).await? {
                    PropertyReply::Value(v) => Ok(typed(&bound, name, v)?),
                    PropertyReply::NotFound(_) => Err(HandleError::NoParameter {
                        operation: bound.name.clone(),
                        node: bound.node.clone(),
                        name: name.to_string(),
                    }
                    .into()),
                    other => Err(bound
                        .unexpected(&format!("parameter `{name}`"), other)
                        .into()),
                }
            }
        })
        .await
    }

    /// Property `name` as a `T`: a standard one ([`marie_vocabulary::property::STANDARD_PROPERTIES`]:
    /// `uptime_ms`, `in_use`, ...), `param.NAME`, or one the operation adds
    /// ([`Operation::property`](crate::eo::Operation::property)). [`HandleError::NoProperty`] if it has none of that
    /// name.
    ///
    /// ```
    /// # use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step};
    /// # use marie_vocabulary::property::Value;
    /// # struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("pump", 7101, "1.2.0", "pumps") }
    /// #     fn property(&self, name: &str) -> Option<Value> { (name == "litres").then_some(Value::Float(0.0)) }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main(flavor = "current_thread")] async fn main() {
    /// # eo::spawn_operation(Pump, Default::default()).await.unwrap();
    /// let pump = marie_actors::eo::OperationHandle::lookup("pump").await.unwrap();
    /// assert_eq!(pump.property::<f64>("litres").await.unwrap(), 0.0);
    /// assert_eq!(pump.property::<String>("version").await.unwrap(), "1.2.0");
    /// assert!(!pump.property::<bool>("in_use").await.unwrap());
    /// # }
    /// ```
    pub async fn property<T: FromValue>(&self, name: &str) -> Result<T, HandleError> {
        self.call(|bound| async move {
            match bound
                .client
                .property(PropertyRequest::Get(name.to_string()))
                .await?
            {
                PropertyReply::Value(v) => Ok(typed(&bound, name, v)?),
                PropertyReply::NotFound(_) => Err(HandleError::NoProperty {
                    operation: bound.name.clone(),
                    node: bound.node.clone(),
                    name: name.to_string(),
                }
                .into()),
                other => Err(bound
                    .unexpected(&format!("property `{name}`"), other)
                    .into()),
            }
        })
        .await
    }
}

/// `value` (of `name`) as a `T`, or the error naming what it is instead.
fn typed<T: FromValue>(bound: &Bound, name: &str, value: Value) -> Result<T, HandleError> {
    T::from_value(&value).ok_or_else(|| HandleError::WrongType {
        operation: bound.name.clone(),
        node: bound.node.clone(),
        name: name.to_string(),
        expected: T::EXPECTED,
        got: value,
    })
}

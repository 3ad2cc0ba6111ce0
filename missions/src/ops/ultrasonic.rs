//! Ultrasonic (1516): reads every sonar of the cart and stores the echoes in the feature DM,
//! placed in the map frame with the localizer's newest odometry correction.

use super::records::{Echo, EchoScan, SONAR};
use super::{cart, correction, dm_err};
use crate::hardware::CartClient;
use marie_actors::declare::DeclaredParams;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::FEATURE;
use marie_vocabulary::property::{ParamSchema, Value};
use std::time::Duration;

marie_actors::params! {
    /// The ultrasonic operation's parameters.
    pub struct UltrasonicParams {
        /// echoes nearer than this are discarded as cross-talk
        pub min_range: f64 = 0.05, range(0.0, 2.0), unit("m");
    }
}

/// Reads the sonar ring at a fixed rate; never finishes by itself (it is suspended when its
/// action ends).
#[derive(Debug, Default)]
pub struct Ultrasonic {
    cart: Option<CartClient>,
    scans: u64,
}

impl Operation for Ultrasonic {
    fn identity(&self) -> Identity {
        Identity::new(
            "ultrasonic",
            1516,
            "1.0.0",
            "reads the ultrasonic sensors into the feature DM",
        )
    }

    fn parameters(&self) -> ParamSchema {
        UltrasonicParams::schema()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(100)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let UltrasonicParams { min_range } = ctx.params().read()?;
        let scan = cart(&mut self.cart, ctx)?
            .scan()
            .await
            .map_err(|e| OpError::failed(e.to_string()))?;
        let fix = correction(ctx).await?;
        let pose = fix.compose(scan.odometry);
        let echoes = scan
            .readings
            .iter()
            .filter_map(|r| {
                let range = r.range.filter(|d| *d >= min_range)?;
                // the mount pose is ground truth; the robot knows it only through its
                // (corrected) odometry
                let mount = pose.compose(*scan.mounts.get(r.sensor)?);
                Some(Echo {
                    sensor: r.sensor,
                    narrow: r.beam == crate::world::Beam::Narrow,
                    bearing: mount.theta,
                    range,
                    point: mount.point() + mount.heading() * range,
                })
            })
            .collect();
        let record = EchoScan {
            time: scan.time,
            pose,
            echoes,
            correction: fix,
        };
        ctx.dm(FEATURE)?
            .put_kind(SONAR, &record)
            .map_err(dm_err(FEATURE))?;
        self.scans += 1;
        Ok(Step::Continue)
    }

    fn property(&self, name: &str) -> Option<Value> {
        (name == "scans").then_some(Value::Int(self.scans as i64))
    }
}

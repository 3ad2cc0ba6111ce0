//! Ultrasonic sensors: each beam is a cone of rays cast against the world with parry2d; the
//! echo is the nearest ray that comes back.
//!
//! A ray that meets a surface more obliquely than [`SimSettings::incidence_limit`] (the angle
//! between the ray and the surface normal) is reflected away and lost — the specular
//! reflection that makes real sonar miss walls seen at a grazing angle. The reading is the
//! nearest hit among the cone's remaining rays, plus Gaussian noise; with a small probability
//! the whole reading is spuriously lost. A lost reading has no range (the sensor's max range).

use super::rng::Rng;
use crate::geom::{Point, Pose, Vector};
use crate::world::{Beam, SimSettings, SonarMount, WorldGeometry};
use serde::{Deserialize, Serialize};

/// One reading of one ultrasonic sensor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarReading {
    /// Index of the sensor in the world's sonar list.
    pub sensor: usize,
    /// The sensor's beam.
    pub beam: Beam,
    /// Half the opening angle of its beam cone, radians: the sensor's own (data sheet)
    /// figure, so whoever places the echo on its arc uses the cone it was heard in.
    pub half_angle: f64,
    /// The sensor's pose in the world at the time of the reading (its beam axis as heading).
    pub mount: Pose,
    /// Measured range, metres (noisy); `None` when no echo came back (max range).
    pub range: Option<f64>,
    /// The sensor's max range, metres.
    pub max_range: f64,
    /// Where the echoing ray really hit (world frame, noise-free); `None` when lost. Ground
    /// truth for tests and pictures: a real sonar only knows the range.
    pub hit: Option<Point>,
    /// Simulated time of the reading, seconds.
    pub time: f64,
}

impl SonarReading {
    /// The range, or the max range when no echo came back.
    pub fn range_or_max(&self) -> f64 {
        self.range.unwrap_or(self.max_range)
    }

    /// The point at the measured range on the beam's axis — what a sonar-based feature
    /// extractor assumes; `None` when lost.
    pub fn axis_point(&self) -> Option<Point> {
        self.range
            .map(|r| self.mount.point() + self.mount.heading() * r)
    }
}

/// Ray directions of a cone: `rays` angles spread evenly over ±`half_angle` around 0 (just 0
/// for one ray).
pub fn cone_offsets(half_angle: f64, rays: u32) -> impl Iterator<Item = f64> {
    let rays = rays.max(1);
    (0..rays).map(move |k| {
        if rays == 1 {
            0.0
        } else {
            -half_angle + 2.0 * half_angle * f64::from(k) / f64::from(rays - 1)
        }
    })
}

/// Read one sensor `mount` (index `sensor`) on a cart at `cart`, at time `time`. Always draws
/// the same amount of randomness from `rng` (one uniform for the dropout, one Gaussian).
pub fn read_sensor(
    geometry: &WorldGeometry,
    settings: &SimSettings,
    rng: &mut Rng,
    cart: &Pose,
    sensor: usize,
    mount: &SonarMount,
    time: f64,
) -> SonarReading {
    let mount_pose = cart.compose(mount.pose());
    let origin = mount_pose.point();
    let cos_limit = settings.incidence_limit.cos();
    let mut best: Option<(f64, Point)> = None;
    let half_angle = settings.half_angle(mount.beam);
    if mount.range > 0.0 && mount.range.is_finite() {
        for offset in cone_offsets(half_angle, settings.rays_per_beam) {
            let a = mount_pose.theta + offset;
            let dir = Vector::new(a.cos(), a.sin());
            if let Some(hit) = geometry.cast_ray(origin, dir, mount.range) {
                // |cos| of the angle between the ray and the normal, whichever side was hit
                let cos_incidence = dir.dot(&hit.normal).abs();
                if cos_incidence >= cos_limit && best.is_none_or(|(d, _)| hit.distance < d) {
                    best = Some((hit.distance, hit.point));
                }
            }
        }
    }
    let dropped = rng.chance(settings.sonar_dropout);
    let noise = rng.gaussian(settings.sonar_sigma);
    let (range, hit) = match best {
        Some((d, p)) if !dropped => {
            let r = (d + noise).max(0.0);
            if r <= mount.range {
                (Some(r), Some(p))
            } else {
                (None, None)
            }
        }
        _ => (None, None),
    };
    SonarReading {
        sensor,
        beam: mount.beam,
        half_angle,
        mount: mount_pose,
        range,
        max_range: mount.range,
        hit,
        time,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_offsets_span_the_cone() {
        let v: Vec<f64> = cone_offsets(0.5, 5).collect();
        assert_eq!(v.len(), 5);
        assert!((v[0] + 0.5).abs() < 1e-12 && (v[4] - 0.5).abs() < 1e-12 && v[2].abs() < 1e-12);
        assert_eq!(cone_offsets(0.5, 1).collect::<Vec<_>>(), vec![0.0]);
        assert_eq!(cone_offsets(0.5, 0).count(), 1);
    }
}

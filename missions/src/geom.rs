//! Plane geometry shared by the world, the simulation and the algorithms: f64 nalgebra types
//! and the few shapes the robot reasons about.

use nalgebra::{Isometry2, Point2, Vector2};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// A point in the plane, metres.
pub type Point = Point2<f64>;
/// A vector in the plane, metres.
pub type Vector = Vector2<f64>;

/// Wrap an angle to (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a <= -PI {
        a += 2.0 * PI;
    } else if a > PI {
        a -= 2.0 * PI;
    }
    a
}

/// A pose: position (m) and heading (rad, counter-clockwise from +x).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading, radians in (-π, π].
    pub theta: f64,
}

impl Pose {
    /// A pose; the heading is wrapped.
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Pose {
            x,
            y,
            theta: wrap_angle(theta),
        }
    }

    /// Position.
    pub fn point(&self) -> Point {
        Point::new(self.x, self.y)
    }

    /// Unit vector along the heading.
    pub fn heading(&self) -> Vector {
        Vector::new(self.theta.cos(), self.theta.sin())
    }

    /// As a rigid transform (robot frame → world frame).
    pub fn isometry(&self) -> Isometry2<f64> {
        Isometry2::new(Vector::new(self.x, self.y), self.theta)
    }

    /// A point given in this pose's frame, in world coordinates.
    pub fn transform(&self, local: Point) -> Point {
        self.isometry() * local
    }

    /// Compose: `local` given in this pose's frame.
    pub fn compose(&self, local: Pose) -> Pose {
        let p = self.transform(local.point());
        Pose::new(p.x, p.y, self.theta + local.theta)
    }
}

/// A line segment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// One end.
    pub a: Point,
    /// The other end.
    pub b: Point,
}

impl Segment {
    /// A segment from `a` to `b`.
    pub fn new(a: Point, b: Point) -> Self {
        Segment { a, b }
    }

    /// Length, metres.
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }

    /// Direction angle of `a → b`.
    pub fn angle(&self) -> f64 {
        let d = self.b - self.a;
        d.y.atan2(d.x)
    }

    /// Distance from `p` to the segment.
    pub fn distance_to(&self, p: Point) -> f64 {
        let d = self.b - self.a;
        let len2 = d.norm_squared();
        if len2 == 0.0 {
            return (p - self.a).norm();
        }
        let t = ((p - self.a).dot(&d) / len2).clamp(0.0, 1.0);
        (p - (self.a + d * t)).norm()
    }

    /// Midpoint.
    pub fn midpoint(&self) -> Point {
        nalgebra::center(&self.a, &self.b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_into_the_half_open_interval() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn poses_transform_and_compose() {
        let p = Pose::new(1.0, 2.0, PI / 2.0);
        let q = p.transform(Point::new(1.0, 0.0));
        assert!((q - Point::new(1.0, 3.0)).norm() < 1e-12);
        let c = p.compose(Pose::new(1.0, 0.0, PI / 2.0));
        assert!((c.theta - PI).abs() < 1e-12);
    }

    #[test]
    fn segment_distance() {
        let s = Segment::new(Point::new(0.0, 0.0), Point::new(2.0, 0.0));
        assert!((s.distance_to(Point::new(1.0, 1.0)) - 1.0).abs() < 1e-12);
        assert!((s.distance_to(Point::new(3.0, 0.0)) - 1.0).abs() < 1e-12);
    }
}

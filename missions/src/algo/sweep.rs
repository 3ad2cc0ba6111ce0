//! Which sonar echoes trace a wall: the segments a sensor saw while moving *along* a wall and
//! looking square on at it, fitted to the part of its track recent enough in *distance driven*
//! for the odometry's drift within it to be negligible.
//!
//! The localizer ([`super::localize`]) matches these segments to the map. A time window alone
//! does not serve it: a cart crawling along a wall (the collision avoidance slows it near
//! walls) covers so little ground in it that its segments are too short to give a heading,
//! while the heading drifts per metre driven, not per second. [`recent_travel`] keeps the
//! echoes of the last metres a sensor travelled instead.

use super::segments::{extract_segments, Line, SegmentParams};
use crate::geom::{wrap_angle, Point, Segment};
use serde::{Deserialize, Serialize};

/// One sonar echo with the position of the sensor that heard it (same frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensedPoint {
    /// Where the sensor was.
    pub origin: Point,
    /// The echo point.
    pub point: Point,
}

/// Least fraction of a segment's length the sensor must have moved along it for the segment
/// to count as a wall seen sideways.
const MIN_SWEEP: f64 = 0.7;

/// Largest angle between a beam's axis and a segment's normal for the echo to be trusted,
/// radians (≈ 10°, a narrow cone's half angle and a bit): within it the nearest echo is the
/// foot of the perpendicular and lies on the segment's line; beyond it the echo comes off the
/// cone's edge and the point, placed on the axis, is off the wall.
const MAX_INCIDENCE: f64 = 0.17;

/// Least distance (m) a sensor must have moved since the echo kept before for its next echo
/// to count.
const MIN_STEP: f64 = 0.015;

/// Least fraction of a segment's echoes that must have been heard square on.
const MIN_SQUARE: f64 = 0.8;

/// Segments fitted to one sensor's echoes (in the order heard) that the sensor saw while
/// moving *along* them and looking *square on* at them — the only sonar segments that trace
/// a wall. A sensor looking along its direction of travel (or turning on the spot) puts its
/// echoes on a line that is the trace of its own motion or of a pose error (a heading error
/// sweeps a distant echo sideways), not a wall; taking that for a wall would feed the error
/// back into the pose. Echoes heard obliquely (a turning cart, a wall's edge) are placed off
/// the wall.
pub fn swept_segments(track: &[SensedPoint], params: &SegmentParams) -> Vec<Segment> {
    // a standing cart hears the same spot over and over: keep one echo per step of the sensor
    let mut moving: Vec<SensedPoint> = Vec::with_capacity(track.len());
    for s in track {
        if moving
            .last()
            .is_none_or(|last| (s.origin - last.origin).norm() >= MIN_STEP)
        {
            moving.push(*s);
        }
    }
    let track = &moving[..];
    let points: Vec<Point> = track.iter().map(|s| s.point).collect();
    extract_segments(&points, params)
        .into_iter()
        .filter_map(|fitted| {
            let segment = fitted.segment;
            let line = Line::of_segment(&segment)?;
            let length = segment.length();
            let (t0, t1) = (line.project(segment.a), line.project(segment.b));
            let (lo, hi) = (t0.min(t1), t0.max(t1));
            let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
            let (mut on_count, mut square) = (0usize, 0usize);
            for s in track {
                let t = line.project(s.point);
                let on = line.distance(s.point) <= params.distance_threshold
                    && t >= lo - 1e-9
                    && t <= hi + 1e-9;
                if !on {
                    continue;
                }
                on_count += 1;
                let o = line.project(s.origin);
                min = min.min(o);
                max = max.max(o);
                let axis = s.point - s.origin;
                let norm = axis.norm();
                if norm > 1e-9 {
                    // |sin| of the angle between the axis and the normal
                    let sin = (axis.dot(&line.direction) / norm).abs();
                    if sin <= MAX_INCIDENCE.sin() {
                        square += 1;
                    }
                }
            }
            let swept = max - min >= MIN_SWEEP * length;
            let square_on = square as f64 >= MIN_SQUARE * on_count as f64 && on_count > 0;
            (swept && square_on).then_some(segment)
        })
        .collect()
}

/// The tail of one sensor's `track` (oldest first) heard over the last `distance` metres the
/// sensor travelled, and since it last turned by more than `max_turn` radians (the angle of its
/// beam, origin to echo, against the newest one's).
///
/// The odometry's heading drift grows with the distance driven, so a window in distance bounds
/// the bend it puts into a fitted wall however slowly the cart moved, and gives a crawling cart
/// segments as long as a fast one's. A turn ends the window too: wheels slip most while the
/// cart turns, so echoes from before a turn, brought into the frame of after it, are off by
/// the slip — a stale wall that would rotate a good pose. A non-finite or negative `distance`
/// or `max_turn` leaves that limit off.
pub fn recent_travel(track: &[SensedPoint], distance: f64, max_turn: f64) -> &[SensedPoint] {
    let Some(newest) = track.last() else {
        return track;
    };
    let axis = |s: &SensedPoint| {
        let v = s.point - s.origin;
        v.y.atan2(v.x)
    };
    let heading = axis(newest);
    let turned = |s: &SensedPoint| {
        max_turn.is_finite()
            && max_turn >= 0.0
            && heading.is_finite()
            && wrap_angle(axis(s) - heading).abs() > max_turn
    };
    let limited = distance.is_finite() && distance >= 0.0;
    let mut travelled = 0.0;
    let mut start = track.len();
    while start > 0 {
        let i = start - 1;
        if let Some(next) = track.get(start) {
            let step = (next.origin - track[i].origin).norm();
            if step.is_finite() {
                travelled += step;
            }
        }
        if (limited && travelled > distance) || turned(&track[i]) {
            break;
        }
        start = i;
    }
    &track[start..]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_walls_swept_sideways_make_segments() {
        // a side sensor driving along y = 0 at 1 m: a wall
        let side: Vec<SensedPoint> = (0..30)
            .map(|i| {
                let x = 10.0 - i as f64 * 0.03;
                SensedPoint {
                    origin: Point::new(x, 1.0),
                    point: Point::new(x, 0.0),
                }
            })
            .collect();
        assert_eq!(swept_segments(&side, &SegmentParams::default()).len(), 1);
        // a rear sensor driving away from x = 14 with a heading error: its echoes sweep along
        // the wall, but the sensor moved across it
        let rear: Vec<SensedPoint> = (0..30)
            .map(|i| {
                let x = 13.0 - i as f64 * 0.03;
                SensedPoint {
                    origin: Point::new(x, 1.5),
                    point: Point::new(14.0, 1.5 + (14.0 - x) * 0.1),
                }
            })
            .collect();
        assert!(swept_segments(&rear, &SegmentParams::default()).is_empty());
        assert!(swept_segments(&[], &SegmentParams::default()).is_empty());
    }
    #[test]
    fn the_travel_window_keeps_the_last_metres_however_slow_the_cart() {
        // 4 m driven in 2 cm steps, then 100 echoes standing still at the end
        let mut track: Vec<SensedPoint> = (0..=200)
            .map(|i| {
                let x = i as f64 * 0.02;
                SensedPoint {
                    origin: Point::new(x, 1.0),
                    point: Point::new(x, 0.0),
                }
            })
            .collect();
        let end = *track.last().unwrap();
        track.extend(std::iter::repeat_n(end, 100));
        let recent = recent_travel(&track, 1.5, f64::NAN);
        let first = recent.first().unwrap().origin.x;
        assert!((first - 2.5).abs() < 0.021, "starts 1.5 m back: {first}");
        assert_eq!(recent.len(), 76 + 100);
        assert_eq!(recent_travel(&track, f64::NAN, f64::NAN).len(), track.len());
        assert_eq!(recent_travel(&track, 100.0, 0.2).len(), track.len());
        assert!(recent_travel(&[], 1.0, 0.2).is_empty());
    }

    #[test]
    fn the_travel_window_ends_where_the_sensor_turned() {
        // a side sensor looks at y = 0 for 2 m, the cart turns 30 degrees, then drives on
        let mut track: Vec<SensedPoint> = (0..100)
            .map(|i| {
                let x = i as f64 * 0.02;
                SensedPoint {
                    origin: Point::new(x, 1.0),
                    point: Point::new(x, 0.0),
                }
            })
            .collect();
        let (s, c) = (-30f64).to_radians().sin_cos();
        track.extend((1..=20).map(|i| {
            let o = Point::new(2.0 + i as f64 * 0.02, 1.0);
            SensedPoint {
                origin: o,
                point: o + crate::geom::Vector::new(s, -c),
            }
        }));
        assert_eq!(recent_travel(&track, 3.0, 0.2).len(), 20);
        assert_eq!(recent_travel(&track, 3.0, 0.6).len(), 120);
    }
}

//! Tracking one wall while the cart follows it: the wall sensor's continuous mode.
//!
//! A wall first seen in a short glimpse has a poor direction, and the pose it was placed with
//! drifts until the localizer corrects it. Refitting the line to *everything* seen so far
//! (the old wall weighted by its length) keeps that first direction for ever: the longer the
//! tracked wall, the less a new segment moves it, and a follower steering along it carries
//! the early error down the whole wall. [`track_wall`] instead refits the line to the
//! segments seen *now* (placed with the newest correction) once they are long enough to give
//! a direction, and keeps the old wall only for the extent already seen (a docking spot's far
//! side must still be measured from where the wall began) and as a gate: only segments on
//! its line extend it, so a recess's back wall never becomes the wall.

use super::segments::Line;
use crate::geom::{Point, Segment};

/// Parameters of the wall tracking.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackParams {
    /// Largest distance of a segment's ends from the tracked wall's line for it to belong to
    /// the wall, m. Default 0.2: a docking recess's back wall lies much deeper.
    pub offset: f64,
    /// Least total length of the segments seen now for them alone to set the wall's direction,
    /// m; below it, the old wall (its weight cut to this length) steadies the fit. Default 1.0.
    pub refit_length: f64,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            offset: 0.2,
            refit_length: 1.0,
        }
    }
}

/// The tracked `wall` updated with the `segments` seen now: the segments on its line set its
/// direction and offset (length-weighted fit of their ends; the old wall joins the fit with
/// at most [`TrackParams::refit_length`] of weight while they are shorter than that), and its
/// extent grows to cover both the old wall and them. Keeps the wall's direction of travel;
/// `None` when no segment lies on its line.
pub fn track_wall(wall: &Segment, segments: &[Segment], params: &TrackParams) -> Option<Segment> {
    let line = Line::of_segment(wall)?;
    let support: Vec<Segment> = segments
        .iter()
        .filter(|s| line.distance(s.a) <= params.offset && line.distance(s.b) <= params.offset)
        .copied()
        .collect();
    if support.is_empty() {
        return None;
    }
    let seen: f64 = support.iter().map(Segment::length).sum();
    let mut weighted: Vec<(Point, f64)> = support
        .iter()
        .flat_map(|s| [(s.a, s.length()), (s.b, s.length())])
        .collect();
    let shortfall = params.refit_length - seen;
    if shortfall > 0.0 || !shortfall.is_finite() {
        let w = wall.length().min(params.refit_length.max(0.0));
        // the old wall's part nearest the new segments, so its far end has no leverage
        let near = nearest_part(wall, &support, params.refit_length.max(0.0));
        weighted.extend([(near.a, w), (near.b, w)]);
    }
    let mut fitted = Line::fit_weighted(&weighted)?;
    if fitted.direction.dot(&(wall.b - wall.a)) < 0.0 {
        fitted = fitted.reversed();
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in support
        .iter()
        .flat_map(|s| [s.a, s.b])
        .chain([wall.a, wall.b])
    {
        let t = fitted.project(p);
        lo = lo.min(t);
        hi = hi.max(t);
    }
    (lo.is_finite() && hi.is_finite()).then(|| Segment::new(fitted.at(lo), fitted.at(hi)))
}

/// The stretch of `wall`, `length` long, centred where the `support` segments project onto it
/// (clipped to the wall).
fn nearest_part(wall: &Segment, support: &[Segment], length: f64) -> Segment {
    let Some(line) = Line::of_segment(wall) else {
        return *wall;
    };
    let span = wall.length();
    let n = (support.len() * 2) as f64;
    let centre = support
        .iter()
        .flat_map(|s| [s.a, s.b])
        .map(|p| line.project(p))
        .sum::<f64>()
        / n;
    let half = (length / 2.0).min(span / 2.0);
    let centre = centre.clamp(half, span - half);
    if !centre.is_finite() {
        return *wall;
    }
    Segment::new(line.at(centre - half), line.at(centre + half))
}

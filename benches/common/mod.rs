//! What several benches share: the property target, a sonar record, percentiles, and an
//! allocator that counts the live heap and its peak (each bench that wants it installs it
//! with `#[global_allocator]`; the criterion benches do not pay for counting).

#![allow(dead_code)] // each bench uses a part

use marie::dm::{NewRecord, Payload};
use marie::eo::{Identity, OpContext, OpError, Operation, Step};
use marie::property::{ParamDecl, ParamSchema};
use serde::Serialize;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicIsize, Ordering};
use std::time::Duration;

/// The property target: does nothing, has one parameter.
#[derive(Default)]
pub(crate) struct Idle;

impl Operation for Idle {
    fn identity(&self) -> Identity {
        Identity::new("bench-idle", 9900, "1.0.0", "does nothing")
    }
    fn parameters(&self) -> ParamSchema {
        ParamSchema::new(vec![ParamDecl::float("x", 1.0).range(0.0, 2.0)])
    }
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        Ok(Step::Continue)
    }
}

#[derive(Serialize)]
struct Echo {
    range_m: f32,
    bearing_rad: f32,
}

const SUB1: [&str; 4] = ["front", "rear", "left", "right"];
const SUB2: [&str; 2] = ["narrow", "wide"];

/// A sonar reading as the ultrasonic EO stores it (four directions, two beams), from
/// `source`.
pub(crate) fn sonar(i: u64, source: &str) -> NewRecord {
    let payload = Payload::encode(&Echo {
        range_m: (i % 500) as f32 / 100.0,
        bearing_rad: 0.1,
    })
    .unwrap_or_default();
    NewRecord::new("sonar", payload)
        .with_sub1(SUB1[(i % 4) as usize])
        .with_sub2(SUB2[(i % 2) as usize])
        .with_source(source)
}

/// The `p`-quantile (0..=1) of `sorted`, nearest rank.
pub(crate) fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// The system allocator, counting the bytes live on the heap and their peak: RSS alone
/// cannot tell a leak from memory the allocator keeps for reuse.
pub(crate) struct Counting;

static LIVE: AtomicIsize = AtomicIsize::new(0);
static PEAK: AtomicIsize = AtomicIsize::new(0);

fn grew(by: isize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    // a load first: the peak is rarely exceeded, and a plain load costs next to nothing
    if now > PEAK.load(Ordering::Relaxed) {
        PEAK.fetch_max(now, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size() as isize);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size() as isize, Ordering::Relaxed);
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        grew(new_size as isize - layout.size() as isize);
        System.realloc(ptr, layout, new_size)
    }
}

/// Bytes live on the heap now (with [`Counting`] installed).
pub(crate) fn live() -> isize {
    LIVE.load(Ordering::Relaxed)
}

/// Start a new peak at the current live heap; gives that base.
pub(crate) fn reset_peak() -> u64 {
    let live = LIVE.load(Ordering::Relaxed);
    PEAK.store(live, Ordering::Relaxed);
    live.max(0) as u64
}

/// The live heap's peak since [`reset_peak`].
pub(crate) fn peak() -> u64 {
    PEAK.load(Ordering::Relaxed).max(0) as u64
}

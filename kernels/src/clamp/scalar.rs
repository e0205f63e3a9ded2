//! The scalar reference of the neighbourhood clamp: one pixel at a time.

use std::ops::Range;

use super::{ClampInput, ClampParams, ClampStats, HistoryRow};
use crate::reproject::Reason;

/// The neighbourhood moments of one channel: sum, sum of squares, minimum, maximum.
#[derive(Clone, Copy)]
struct Moments {
    sum: f32,
    squares: f32,
    min: f32,
    max: f32,
}

impl Moments {
    const EMPTY: Self = Self { sum: 0.0, squares: 0.0, min: f32::INFINITY, max: f32::NEG_INFINITY };

    #[inline(always)]
    fn add(&mut self, v: f32) {
        self.sum += v;
        self.squares += v * v;
        // Compare and select, as the SIMD body does (samples are finite: no NaN rule).
        self.min = if v < self.min { v } else { self.min };
        self.max = if v > self.max { v } else { self.max };
    }
}

/// The new sample at `(x, y)`, if there is one (a sample this frame, every channel finite).
#[inline(always)]
fn sample(input: &ClampInput<'_>, x: usize, y: usize) -> Option<[f32; 3]> {
    let present = input.has_new.as_ref().is_none_or(|m| m.row(y)[x] != 0);
    let v = input.new.get(x, y);
    (present && v.iter().all(|c| c.is_finite())).then_some(v)
}

/// The box `(lo, hi)` of one channel from `n` samples' moments (module notes).
#[inline(always)]
fn bounds(m: Moments, n: f32, gamma: f32) -> (f32, f32) {
    let mean = m.sum / n;
    let variance = m.squares / n - mean * mean;
    if !variance.is_finite() {
        return (m.min, m.max);
    }
    let sigma = if variance > 0.0 { variance.sqrt() } else { 0.0 };
    let d = gamma * sigma;
    (clamp_into(mean - d, m.min, m.max), clamp_into(mean + d, m.min, m.max))
}

/// `h` clamped into `[lo, hi]` (compare and select).
#[inline(always)]
fn clamp_into(h: f32, lo: f32, hi: f32) -> f32 {
    let h = if h < lo { lo } else { h };
    if h > hi { hi } else { h }
}

/// Pixels `columns` of row `y`.
pub(super) fn clamp_row(
    input: &ClampInput<'_>,
    params: &ClampParams,
    y: usize,
    columns: Range<usize>,
    history: &mut HistoryRow<'_>,
) -> ClampStats {
    let (w, h) = (input.new.extent().width(), input.new.extent().height());
    let reason = input.reason.row(y);
    let mut stats = ClampStats::default();
    for x in columns {
        let old = [history[0][x], history[1][x], history[2][x]];
        if reason[x] != Reason::Reprojected as u8 || sample(input, x, y).is_none() || !old.iter().all(|c| c.is_finite())
        {
            continue;
        }
        let mut moments = [Moments::EMPTY; 3];
        let mut n = 0.0f32;
        for ny in y.saturating_sub(1)..(y + 2).min(h) {
            for nx in x.saturating_sub(1)..(x + 2).min(w) {
                if let Some(v) = sample(input, nx, ny) {
                    n += 1.0;
                    for c in 0..3 {
                        moments[c].add(v[c]);
                    }
                }
            }
        }
        if n < params.min_samples as f32 {
            continue;
        }
        stats.checked += 1;
        let mut moved = false;
        for c in 0..3 {
            let (lo, hi) = bounds(moments[c], n, params.gamma);
            let clamped = clamp_into(old[c], lo, hi);
            moved |= clamped != old[c];
            history[c][x] = clamped;
        }
        stats.clamped += u64::from(moved);
    }
    stats
}

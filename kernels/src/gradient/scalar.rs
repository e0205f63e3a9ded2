//! The scalar reference of the gradient kernel: one stratum at a time.

use std::ops::Range;

use super::{GradientInput, GradientStats, LUMA_MAX, StrataRowOut, confidence_of};

/// One stratum's signed change and maximum `(d, m)` from its luminance pair: `(0, 0)`
/// without a pair (NaN).
#[inline(always)]
pub(super) fn pair(old: f32, new: f32) -> (f32, f32) {
    if old.is_nan() || new.is_nan() {
        return (0.0, 0.0);
    }
    let (old, new) = (old.clamp(0.0, LUMA_MAX), new.clamp(0.0, LUMA_MAX));
    // A compare and select, as the SIMD body does (no `max` with its signed-zero freedom).
    (new - old, if new > old { new } else { old })
}

/// The neighbourhood sums `(Σd, Σm)` of stratum `(sx, sy)`, rows then columns in order.
#[inline(always)]
pub(super) fn sums(input: &GradientInput<'_>, sx: usize, sy: usize) -> (f32, f32) {
    let (w, h) = (input.old.width(), input.old.height());
    let (mut sum_d, mut sum_m) = (0.0f32, 0.0f32);
    for y in sy.saturating_sub(1)..(sy + 2).min(h) {
        let (old, new) = (input.old.row(y), input.new.row(y));
        for x in sx.saturating_sub(1)..(sx + 2).min(w) {
            let (d, m) = pair(old[x], new[x]);
            sum_d += d;
            sum_m += m;
        }
    }
    (sum_d, sum_m)
}

/// Strata `columns` of row `sy`.
pub(super) fn strata_row(
    input: &GradientInput<'_>,
    sy: usize,
    columns: Range<usize>,
    out: &mut StrataRowOut<'_>,
) -> GradientStats {
    let mut stats = GradientStats::default();
    let (old, new) = (input.old.row(sy), input.new.row(sy));
    for sx in columns {
        stats.samples += u64::from(!(old[sx].is_nan() || new[sx].is_nan()));
        let (sum_d, sum_m) = sums(input, sx, sy);
        let c = confidence_of(sum_d, sum_m, input.gain);
        stats.changed += u64::from(c < 1.0);
        out.write(sx, c);
    }
    stats
}

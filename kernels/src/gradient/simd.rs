//! The SIMD body of the gradient kernel: eight strata of a row at a time, the same sums in
//! the same order as [`super::scalar`] lane for lane.

use super::scalar;
use super::{GradientInput, GradientStats, LUMA_MAX, StrataRowOut};
use crate::simd::{F32s, LANES, bits, load};

/// [`scalar::pair`] on eight lanes.
#[inline(always)]
fn pair(old: F32s, new: F32s) -> (F32s, F32s) {
    let absent = old.simd_ne(old) | new.simd_ne(new);
    let clamp = |v: F32s| {
        let v = v.simd_lt(F32s::ZERO).select(F32s::ZERO, v);
        v.simd_gt(F32s::splat(LUMA_MAX)).select(F32s::splat(LUMA_MAX), v)
    };
    let (old, new) = (clamp(old), clamp(new));
    let d = new - old;
    let m = new.simd_gt(old).select(new, old);
    (absent.select(F32s::ZERO, d), absent.select(F32s::ZERO, m))
}

/// Row `sy` of strata: the first stratum and those whose neighbourhood reaches
/// past the row's end through the scalar reference, the rest eight at a time.
pub(super) fn strata_row(input: &GradientInput<'_>, sy: usize, out: &mut StrataRowOut<'_>) -> GradientStats {
    let (w, h) = (input.old.width(), input.old.height());
    // The first stratum's left neighbour is outside: the reference's sums skip it.
    let mut stats = scalar::strata_row(input, sy, 0..1.min(w), out);
    let mut sx = 1;
    let rows = sy.saturating_sub(1)..(sy + 2).min(h);
    while sx + LANES < w {
        let (mut sum_d, mut sum_m) = (F32s::ZERO, F32s::ZERO);
        for y in rows.clone() {
            let (old, new) = (input.old.row(y), input.new.row(y));
            for x in [sx - 1, sx, sx + 1] {
                let (d, m) = pair(load(old, x), load(new, x));
                sum_d += d;
                sum_m += m;
            }
        }
        let ratio = (sum_d.abs() / sum_m) * F32s::splat(input.gain);
        let lambda = sum_m.simd_gt(F32s::ZERO).select(ratio.min(F32s::ONE), F32s::ZERO);
        let confidence = F32s::ONE - lambda;
        let (old, new) = (load(input.old.row(sy), sx), load(input.new.row(sy), sx));
        let present = !(old.simd_ne(old) | new.simd_ne(new));
        stats.samples += u64::from(bits(present).count_ones());
        stats.changed += u64::from(bits(confidence.simd_lt(F32s::ONE)).count_ones());
        // Whole strata: `sx + 7 < w − 1`, and only the last stratum of a row may be narrow.
        out.write8(sx, confidence.to_array());
        sx += LANES;
    }
    stats.merged(scalar::strata_row(input, sy, sx.min(w)..w, out))
}

//! The SIMD body of the neighbourhood clamp: eight pixels of a row at a time, the same sums
//! in the same order as [`super::scalar`] lane for lane.

use super::scalar;
use super::{ClampInput, ClampParams, ClampStats, HistoryRow};
use crate::accumulate::byte_mask_eq;
use crate::reproject::Reason;
use crate::simd::{F32s, LANES, bits, load, store};

/// The moments of one channel over eight pixels' neighbourhoods.
struct Moments {
    sum: F32s,
    squares: F32s,
    min: F32s,
    max: F32s,
}

/// Where the eight pixels from `x` of row `y` have a new sample (present, finite), and the
/// samples.
#[inline(always)]
fn samples(input: &ClampInput<'_>, x: usize, y: usize) -> (F32s, [F32s; 3]) {
    let v = input.new.channels().map(|p| load(p.row(y), x));
    let present =
        input.has_new.as_ref().map_or(F32s::splat(f32::from_bits(u32::MAX)), |m| !byte_mask_eq(&m.row(y)[x..], 0));
    (present & v[0].is_finite() & v[1].is_finite() & v[2].is_finite(), v)
}

/// [`scalar::bounds`] on eight lanes.
#[inline(always)]
fn bounds(m: &Moments, n: F32s, gamma: F32s) -> (F32s, F32s) {
    let mean = m.sum / n;
    let variance = m.squares / n - mean * mean;
    let finite = variance.is_finite();
    let sigma = variance.simd_gt(F32s::ZERO).select(variance.sqrt(), F32s::ZERO);
    let d = gamma * sigma;
    let (lo, hi) = (clamp_into(mean - d, m.min, m.max), clamp_into(mean + d, m.min, m.max));
    (finite.select(lo, m.min), finite.select(hi, m.max))
}

/// [`scalar::clamp_into`] on eight lanes.
#[inline(always)]
fn clamp_into(h: F32s, lo: F32s, hi: F32s) -> F32s {
    let h = h.simd_lt(lo).select(lo, h);
    h.simd_gt(hi).select(hi, h)
}

/// Row `y`: the first pixel and those whose neighbourhood reaches past the row's end through
/// the scalar reference, the rest eight at a time.
pub(super) fn clamp_row(
    input: &ClampInput<'_>,
    params: &ClampParams,
    y: usize,
    history: &mut HistoryRow<'_>,
) -> ClampStats {
    let (w, h) = (input.new.extent().width(), input.new.extent().height());
    // The first pixel's left neighbour is outside: the reference's sums skip it.
    let mut stats = scalar::clamp_row(input, params, y, 0..1.min(w), history);
    let rows = y.saturating_sub(1)..(y + 2).min(h);
    let reason = input.reason.row(y);
    let (gamma, min_samples) = (F32s::splat(params.gamma), F32s::splat(params.min_samples as f32));
    let mut x = 1;
    while x + LANES < w {
        let old = [0, 1, 2].map(|c| load(history[c], x));
        let (own, _) = samples(input, x, y);
        let eligible = byte_mask_eq(&reason[x..], Reason::Reprojected as u8)
            & own
            & old[0].is_finite()
            & old[1].is_finite()
            & old[2].is_finite();
        if bits(eligible) == 0 {
            x += LANES;
            continue;
        }
        let empty = || Moments {
            sum: F32s::ZERO,
            squares: F32s::ZERO,
            min: F32s::splat(f32::INFINITY),
            max: F32s::splat(f32::NEG_INFINITY),
        };
        let mut moments = [empty(), empty(), empty()];
        let mut n = F32s::ZERO;
        for ny in rows.clone() {
            for nx in [x - 1, x, x + 1] {
                let (valid, v) = samples(input, nx, ny);
                n += valid.select(F32s::ONE, F32s::ZERO);
                for (m, v) in moments.iter_mut().zip(v) {
                    // An absent sample adds +0 (which leaves every sum as skipping it does:
                    // no sum is ever −0) and cannot win the minimum or the maximum.
                    let v0 = valid.select(v, F32s::ZERO);
                    m.sum += v0;
                    m.squares += v0 * v0;
                    m.min = (valid & v.simd_lt(m.min)).select(v, m.min);
                    m.max = (valid & v.simd_gt(m.max)).select(v, m.max);
                }
            }
        }
        let apply = eligible & n.simd_ge(min_samples);
        let mut moved = F32s::ZERO;
        for c in 0..3 {
            let (lo, hi) = bounds(&moments[c], n, gamma);
            let out = apply.select(clamp_into(old[c], lo, hi), old[c]);
            // Only applied lanes can move (a NaN elsewhere compares unequal to itself).
            moved |= apply & out.simd_ne(old[c]);
            store(history[c], x, out);
        }
        stats.checked += u64::from(bits(apply).count_ones());
        stats.clamped += u64::from(bits(moved).count_ones());
        x += LANES;
    }
    stats.merged(scalar::clamp_row(input, params, y, x.min(w)..w, history))
}

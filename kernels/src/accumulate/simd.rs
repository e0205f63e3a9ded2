//! The SIMD bodies of the EMA and the stereo blend: eight pixels at a time, the same
//! expressions as [`super::scalar`] lane for lane.

use super::scalar::{blend_scalar_at, ema_scalar_at};
use super::{AccumulateStats, BlendWeights, EmaInput, EmaParams, EmaRow};
use crate::frame::{Plane, RgbPlanes};
use crate::reproject::Reason;
use crate::simd::{F32s, I32s, LANES, any_nonzero, clamp_finite, flush_subnormal, leading_zero_bytes, load, store};

/// SIMD twin of [`super::lerp`].
#[inline(always)]
pub fn lerp_simd(a: F32s, b: F32s, t: F32s) -> F32s {
    let d = b - a;
    let overflow = !d.is_finite() & a.is_finite() & b.is_finite();
    let general = overflow.select(a * (F32s::ONE - t) + b * t, a + t * d);
    let v = t.simd_eq(F32s::ZERO).select(a, t.simd_eq(F32s::ONE).select(b, general));
    finish_simd(v)
}

#[inline(always)]
pub(super) fn finish_simd(v: F32s) -> F32s {
    flush_subnormal(clamp_finite(v))
}

/// All-ones lanes where the three channels of `value` and of the difference `d` are all
/// finite: the EMA's and the blend's common case, where `lerp` is `a + t·d`. One product
/// by zero per value, summed: NaN exactly where any of them is NaN or infinite.
#[inline(always)]
fn finite_with_difference(value: &[F32s; 3], d: &[F32s; 3]) -> F32s {
    let zero = F32s::ZERO;
    let poison = (value[0] * zero + value[1] * zero + value[2] * zero) + (d[0] * zero + d[1] * zero + d[2] * zero);
    poison.simd_eq(zero)
}

/// All-ones lanes where the byte equals `value` (the first `LANES` bytes).
#[inline(always)]
pub(crate) fn byte_mask_eq(bytes: &[u8], value: u8) -> F32s {
    let b: [u8; LANES] = bytes[..LANES].try_into().expect("LANES bytes");
    // Widened in one vector instruction (`vpmovzxbd`); a per-lane loop building the mask
    // from scalar compares was 30 instructions.
    let lanes = I32s::from([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]].map(i32::from));
    bytemuck::cast(lanes.simd_eq(I32s::splat(i32::from(value))))
}

/// One row of [`super::ema`]: eight pixels at a time, the tail through the scalar reference.
#[inline(always)]
pub(super) fn ema_row<'r>(
    input: &EmaInput<'_>,
    params: &EmaParams,
    y: usize,
    acc: &mut EmaRow<'r>,
    len: &mut Option<&'r mut [f32]>,
    stats: &mut AccumulateStats,
) {
    let width = acc[0].len();
    let reason = input.reason.row(y);
    let has_new = input.has_new.as_ref().map(|m| m.row(y));
    let confidence = input.confidence.as_ref().map(|c| c.row(y));
    let pixel_mask = input.pixel_mask.as_ref().map(|m| m.row(y));
    let new = input.new.channels().map(|p| p.row(y));
    // Every row has the extent's width; stated once so that the loop's loads and stores
    // need no bounds checks.
    assert!(
        reason.len() == width
            && (0..3).all(|c| acc[c].len() == width && new[c].len() == width)
            && has_new.is_none_or(|m| m.len() == width)
            && confidence.is_none_or(|c| c.len() == width)
            && pixel_mask.is_none_or(|m| m.len() == width)
            && len.as_deref().is_none_or(|l| l.len() == width)
    );
    let mut x = 0;
    let all = F32s::splat(f32::from_bits(u32::MAX));
    while x + LANES <= width {
        // Lanes outside the pixel mask are left as they were: a group with none inside is
        // skipped whole (the masked caller's common case), the others select per lane.
        let active = match pixel_mask {
            Some(m) if !any_nonzero(&m[x..x + LANES]) => {
                x += leading_zero_bytes(&m[x..width - width % LANES]) / LANES * LANES;
                continue;
            }
            Some(m) => !byte_mask_eq(&m[x..x + LANES], 0),
            None => all,
        };
        let valid = byte_mask_eq(&reason[x..x + LANES], Reason::Reprojected as u8);
        let sampled = has_new.map_or(all, |m| !byte_mask_eq(&m[x..x + LANES], 0));
        let new_v = [load(new[0], x), load(new[1], x), load(new[2], x)];
        let hist = [load(acc[0], x), load(acc[1], x), load(acc[2], x)];
        let c = confidence.map_or(F32s::ONE, |c| load(c, x));
        // The history's weight scaled by its confidence (the reference's operations; at c = 1
        // every one of them is exact, so the plain EMA's bits).
        let n = len.as_deref().map_or(F32s::ZERO, |l| load(l, x)) * c;
        let base = if params.ramp {
            F32s::splat(params.alpha).max(F32s::ONE / (n + F32s::ONE))
        } else {
            F32s::splat(params.alpha)
        };
        let alpha = c.simd_le(F32s::ZERO).select(F32s::ONE, base + (F32s::ONE - base) * (F32s::ONE - c));
        // The common case: every lane has a valid history and a finite new sample, and
        // `new − history` is finite (so neither is infinite). Then `lerp` is
        // `a + t·(b − a)` (or `b` where t = 1) and there is nothing to count: the same
        // bits with about a third of the instructions (with the byte masks below,
        // 353 → 134 per 8 pixels; 2.5 → 1.2 ms per 1280×720 frame on one thread). The
        // result still goes through `finish`: next to ±f32::MAX, `a + t·d` can round
        // past the largest finite value (found by the fuzzer), and the reference clamps.
        let d = [new_v[0] - hist[0], new_v[1] - hist[1], new_v[2] - hist[2]];
        if (active & valid & sampled & finite_with_difference(&new_v, &d)).all() {
            let one = alpha.simd_eq(F32s::ONE);
            for c in 0..3 {
                let v = one.select(new_v[c], hist[c] + alpha * d[c]);
                store(acc[c], x, finish_simd(v));
            }
            if let Some(l) = len.as_deref_mut() {
                store(l, x, n + F32s::ONE);
            }
            x += LANES;
            continue;
        }
        let finite = new_v[0].is_finite() & new_v[1].is_finite() & new_v[2].is_finite();
        let use_new = sampled & finite;
        let blend = active & use_new & valid;
        let reset = active & use_new & !valid;
        let hole = active & !use_new & !valid;
        let kept = active & !use_new & valid;
        for c in 0..3 {
            let mixed = lerp_simd(hist[c], new_v[c], alpha);
            let out = blend.select(
                mixed,
                reset
                    .select(finish_simd(new_v[c]), hole.select(F32s::ZERO, kept.select(finish_simd(hist[c]), hist[c]))),
            );
            store(acc[c], x, out);
        }
        if let Some(l) = len.as_deref_mut() {
            // Kept without a new sample (or outside the mask): the stored length, not the
            // confidence-weighted one.
            let stored = load(l, x);
            let n_out = blend.select(n + F32s::ONE, reset.select(F32s::ONE, hole.select(F32s::ZERO, stored)));
            store(l, x, n_out);
        }
        stats.non_finite += u64::from((active & sampled & !finite).to_bitmask().count_ones());
        stats.resets += u64::from(reset.to_bitmask().count_ones());
        stats.holes += u64::from(hole.to_bitmask().count_ones());
        x += LANES;
    }
    for x in x..width {
        ema_scalar_at(input, params, y, x, acc, len.as_deref_mut(), stats);
    }
}

/// [`super::variance_blend_toward`] on eight lanes.
#[inline(always)]
pub(super) fn variance_blend_toward_simd(own_len: F32s, other_len: F32s, alpha: f32) -> F32s {
    let steady = F32s::splat((2.0 - alpha) / alpha);
    let count = |n: F32s| {
        let n = n.simd_ge(F32s::ONE).select(n, F32s::ONE);
        n.simd_lt(steady).select(n, steady)
    };
    let half = F32s::splat(0.5);
    let (own, other) = (half * count(own_len), half * count(other_len));
    other / (own + other)
}

/// One row of [`super::blend`] and [`super::blend_by_variance`] (the reprojection's weight
/// per pixel from `weights`): eight pixels at a time, the tail through the scalar reference.
#[inline(always)]
pub(super) fn blend_row(
    own: &RgbPlanes<'_>,
    reason: &Plane<'_, u8>,
    weights: &BlendWeights<'_>,
    y: usize,
    out: &mut EmaRow<'_>,
    stats: &mut AccumulateStats,
) {
    let width = out[0].len();
    let reason_row = reason.row(y);
    let own_rows = own.channels().map(|p| p.row(y));
    let all_reprojected = u64::from_ne_bytes([Reason::Reprojected as u8; LANES]);
    let mut x = 0;
    while x + LANES <= width {
        let reasons: [u8; LANES] = reason_row[x..x + LANES].try_into().expect("LANES bytes");
        let mine = own_rows.map(|p| load(p, x));
        let theirs = [0, 1, 2].map(|c| load(out[c], x));
        let t = weights.toward_reprojected_simd(x, y);
        // The common case, as in the EMA: all eight reprojected, and both images and their
        // difference finite. Then `lerp` is `a + t·(b − a)` (or an end where t is 0 or 1)
        // and there is nothing to count: the same bits with a third of the selects.
        let d = [0, 1, 2].map(|c| theirs[c] - mine[c]);
        if u64::from_ne_bytes(reasons) == all_reprojected && finite_with_difference(&mine, &d).all() {
            let (at_own, at_theirs) = (t.simd_eq(F32s::ZERO), t.simd_eq(F32s::ONE));
            for c in 0..3 {
                let v = at_own.select(mine[c], at_theirs.select(theirs[c], mine[c] + t * d[c]));
                store(out[c], x, finish_simd(v));
            }
            x += LANES;
            continue;
        }
        let valid = byte_mask_eq(&reasons, Reason::Reprojected as u8);
        let finite = mine[0].is_finite() & mine[1].is_finite() & mine[2].is_finite();
        let hole = !finite & !valid;
        for c in 0..3 {
            let mixed = lerp_simd(mine[c], theirs[c], t);
            let v = finite
                .select(valid.select(mixed, finish_simd(mine[c])), valid.select(finish_simd(theirs[c]), F32s::ZERO));
            store(out[c], x, v);
        }
        stats.non_finite += u64::from((!finite).to_bitmask().count_ones());
        stats.holes += u64::from(hole.to_bitmask().count_ones());
        x += LANES;
    }
    for x in x..width {
        blend_scalar_at(own, reason, weights, x, y, out, stats);
    }
}

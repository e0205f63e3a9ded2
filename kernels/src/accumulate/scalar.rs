//! The scalar references of the EMA and the stereo blend: one pixel at a time, the
//! definitions of the module notes; [`super::simd`] computes the same bits.

use super::{AccumulateStats, BlendParams, BlendWeights, EmaInput, EmaParams, EmaRow};
use crate::frame::{Plane, RgbPlanes};
use crate::reproject::Reason;
use crate::simd::{clamp_finite1, flush_subnormal1};

/// `a + t·(b − a)`, with `t = 0` returning `a` and `t = 1` returning `b` exactly, clamped
/// and flushed (see module docs). Where `b − a` overflows (values near ±`f32::MAX` of
/// opposite sign) it falls back to `a·(1 − t) + b·t`, which cannot overflow.
#[inline(always)]
pub fn lerp(a: f32, b: f32, t: f32) -> f32 {
    let d = b - a;
    let v = if t == 0.0 {
        a
    } else if t == 1.0 {
        b
    } else if d.is_finite() || !(a.is_finite() && b.is_finite()) {
        a + t * d
    } else {
        a * (1.0 - t) + b * t
    };
    finish(v)
}

/// Clamp to the finite range and flush subnormals to zero (NaN passes through).
#[inline(always)]
pub(super) fn finish(v: f32) -> f32 {
    flush_subnormal1(clamp_finite1(v))
}

/// The variance of an EMA's mean over `n` samples, as a multiple of one sample's:
/// `Σw²`, which is `1/n` while the samples are few and `α/(2 − α)` once the EMA's weights
/// take over (the larger of the two: the exact sum lies between them and both limits). A
/// length below 1 (a hole, a restart) counts as 1. It is `1 /` [`effective_samples`].
#[inline(always)]
pub fn mean_variance_factor(n: f32, alpha: f32) -> f32 {
    1.0 / effective_samples(n, alpha)
}

/// The number of independent samples an EMA's mean over `n` samples is worth: `n` while
/// the samples are few, at most `(2 − α)/α` once the EMA's weights take over, at least 1 (a
/// hole, a restart). The inverse of [`mean_variance_factor`].
#[inline(always)]
pub fn effective_samples(n: f32, alpha: f32) -> f32 {
    let n = if n >= 1.0 { n } else { 1.0 };
    let steady = (2.0 - alpha) / alpha;
    if n < steady { n } else { steady }
}

/// The reprojection's weight in the variance-guided blend: inverse-variance weights
/// `w_own = v_other / (v_own + v_other)`, so `t = v_own / (v_own + v_other)`, which with
/// each eye's variance `1 / m` ([`effective_samples`] `m`) is `m_other / (m_own + m_other)`:
/// one division (a sample's own variance is taken as the same in both eyes: one surface
/// seen twice). Both counts are halved first (exactly), so that their sum stays finite even
/// for lengths near `f32::MAX` under a tiny `α`. Equal lengths give exactly ½.
#[inline(always)]
pub fn variance_blend_toward(own_len: f32, other_len: f32, alpha: f32) -> f32 {
    let (own, other) = (0.5 * effective_samples(own_len, alpha), 0.5 * effective_samples(other_len, alpha));
    other / (own + other)
}

/// One pixel of the EMA (scalar reference) with a history confidence of 1. Returns the new
/// accumulation and history length and updates `stats`.
#[inline]
pub fn ema_pixel(
    history: [f32; 3],
    history_len: f32,
    new: [f32; 3],
    history_valid: bool,
    has_new: bool,
    params: &EmaParams,
    stats: &mut AccumulateStats,
) -> ([f32; 3], f32) {
    ema_pixel_trusting(history, history_len, new, history_valid, has_new, 1.0, params, stats)
}

/// [`ema_pixel`] with the history's `confidence` in [0, 1] (see the module notes): the
/// history counts as `c·n` samples, and its weight `1 − α` is scaled by `c`, computed as
/// `α' = α + (1 − α)·(1 − c)` (exactly `α` at `c = 1`; `c = 0` takes the new sample).
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn ema_pixel_trusting(
    history: [f32; 3],
    history_len: f32,
    new: [f32; 3],
    history_valid: bool,
    has_new: bool,
    confidence: f32,
    params: &EmaParams,
    stats: &mut AccumulateStats,
) -> ([f32; 3], f32) {
    let finite = new.iter().all(|v| v.is_finite());
    if has_new && !finite {
        stats.non_finite += 1;
    }
    match (has_new && finite, history_valid) {
        (true, true) => {
            let n = history_len * confidence;
            let base = if params.ramp { params.alpha.max(1.0 / (n + 1.0)) } else { params.alpha };
            let alpha = if confidence <= 0.0 { 1.0 } else { base + (1.0 - base) * (1.0 - confidence) };
            ([0, 1, 2].map(|c| lerp(history[c], new[c], alpha)), n + 1.0)
        }
        (true, false) => {
            stats.resets += 1;
            (new.map(finish), 1.0)
        }
        (false, true) => (history.map(finish), history_len),
        (false, false) => {
            stats.holes += 1;
            ([0.0; 3], 0.0)
        }
    }
}

#[inline(always)]
pub(super) fn ema_scalar_at(
    input: &EmaInput<'_>,
    params: &EmaParams,
    y: usize,
    x: usize,
    acc: &mut [&mut [f32]; 3],
    len: Option<&mut [f32]>,
    stats: &mut AccumulateStats,
) {
    if input.pixel_mask.as_ref().is_some_and(|m| m.row(y)[x] == 0) {
        return;
    }
    let history = [acc[0][x], acc[1][x], acc[2][x]];
    let n = len.as_ref().map_or(0.0, |l| l[x]);
    let valid = input.reason.row(y)[x] == Reason::Reprojected as u8;
    let has_new = input.has_new.as_ref().is_none_or(|m| m.row(y)[x] != 0);
    let new = input.new.get(x, y);
    let confidence = input.confidence.as_ref().map_or(1.0, |c| c.row(y)[x]);
    let (out, n_out) = ema_pixel_trusting(history, n, new, valid, has_new, confidence, params, stats);
    for c in 0..3 {
        acc[c][x] = out[c];
    }
    if let Some(l) = len {
        l[x] = n_out;
    }
}

/// One pixel of the blend (scalar reference): `own + (1 − w)·(reprojected − own)` where the
/// reprojection is valid, `own` elsewhere; a non-finite `own` falls back to the reprojection
/// (or a hole).
#[inline]
pub fn blend_pixel(
    own: [f32; 3],
    reprojected: [f32; 3],
    valid: bool,
    params: &BlendParams,
    stats: &mut AccumulateStats,
) -> [f32; 3] {
    blend_pixel_toward(own, reprojected, valid, 1.0 - params.own_weight, stats)
}

/// [`blend_pixel`] with the reprojection's weight `t` given: `lerp(own, reprojected, t)`.
#[inline]
pub(super) fn blend_pixel_toward(
    own: [f32; 3],
    reprojected: [f32; 3],
    valid: bool,
    t: f32,
    stats: &mut AccumulateStats,
) -> [f32; 3] {
    let finite = own.iter().all(|v| v.is_finite());
    if !finite {
        stats.non_finite += 1;
    }
    match (finite, valid) {
        (true, true) => [0, 1, 2].map(|c| lerp(own[c], reprojected[c], t)),
        (true, false) => own.map(finish),
        (false, true) => reprojected.map(finish),
        (false, false) => {
            stats.holes += 1;
            [0.0; 3]
        }
    }
}

#[inline(always)]
pub(super) fn blend_scalar_at(
    own: &RgbPlanes<'_>,
    reason: &Plane<'_, u8>,
    weights: &BlendWeights<'_>,
    x: usize,
    y: usize,
    out: &mut EmaRow<'_>,
    stats: &mut AccumulateStats,
) {
    let valid = reason.row(y)[x] == Reason::Reprojected as u8;
    let t = weights.toward_reprojected(x, y);
    let v = blend_pixel_toward(own.get(x, y), [out[0][x], out[1][x], out[2][x]], valid, t, stats);
    for c in 0..3 {
        out[c][x] = v[c];
    }
}

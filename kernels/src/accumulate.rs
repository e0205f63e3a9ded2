//! Temporal accumulation (exponential moving average) and the stereo blend.
//!
//! **EMA.** Where the history was reprojected, `acc = (1 − α)·history + α·new`; where it was
//! discarded, `acc = new` (the history resets). α = 0.2 by default. With `ramp`, each pixel
//! uses `α = max(α, 1/(n + 1))` where `n` is its (reprojected) history length, so a pixel
//! with `n` samples of history takes the exact running mean until the EMA weight takes over;
//! it converges faster after disocclusions and is off for paper reproduction.
//!
//! **Stereo blend.** Where the other eye's reprojection is valid,
//! `out = w·own + (1 − w)·reprojected` (w = 0.5 in the paper); elsewhere `out = own`.
//!
//! Both are evaluated as `lerp(a, b, t) = a + t·(b − a)`, which equals the formulas above
//! algebraically and is exact where it matters: a constant stays that constant (`b − a = 0`),
//! `t = 0` returns `a`; `t = 1` is special-cased to return `b` exactly.
//!
//! **Non-finite samples.** A new sample with a non-finite channel never enters the history:
//! it is counted, and the pixel keeps its reprojected history if that is valid, or becomes a
//! *hole* (written as 0 with history length 0, and counted) if not. A pixel without a new
//! sample this frame (the budgeted runtime did not trace it) is treated the same way but is
//! not counted as non-finite.
//!
//! **Range.** Results are clamped to ±`f32::MAX` (finite inputs give finite outputs) and
//! results below `f32::MIN_POSITIVE` in magnitude are flushed to 0: an EMA decaying towards 0
//! would otherwise walk through subnormals, which are slow on x86 and flush-to-zero cannot be
//! relied on.
//!
//! Tail strategy: `LANES` pixels at a time, the remaining `width % LANES` through the scalar
//! reference.

use crate::bands::{SharedRows, for_each_band};
use crate::frame::{FrameError, Plane, PlaneMut, RgbPlanes, RgbPlanesMut, same_extent};
use crate::reproject::Reason;
use crate::simd::{F32s, I32s, LANES, clamp_finite, clamp_finite1, load, store};

/// EMA parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmaParams {
    /// Weight of the new sample, in (0, 1].
    pub alpha: f32,
    /// Use `α = max(α, 1/(n + 1))` with the per-pixel history length (needs a history-length
    /// plane).
    pub ramp: bool,
    /// Rows per parallel band.
    pub band_rows: usize,
}

impl Default for EmaParams {
    /// The paper's α = 0.2, no ramp.
    fn default() -> Self {
        Self { alpha: 0.2, ramp: false, band_rows: 16 }
    }
}

/// Inputs of one EMA step.
#[derive(Clone, Copy)]
pub struct EmaInput<'a> {
    /// This frame's samples.
    pub new: RgbPlanes<'a>,
    /// Reason codes of the history's reprojection: the history is valid where the code is
    /// [`Reason::Reprojected`].
    pub reason: Plane<'a, u8>,
    /// Optional: non-zero where a new sample exists this frame (absent: everywhere).
    pub has_new: Option<Plane<'a, u8>>,
}

/// The accumulation buffers, updated in place.
pub struct EmaState<'a> {
    /// In: the reprojected history. Out: the new accumulation.
    pub accum: RgbPlanesMut<'a>,
    /// In: the reprojected history length in samples. Out: the updated length (0 for holes).
    /// Required when `ramp` is on.
    pub history_len: Option<PlaneMut<'a>>,
}

/// What an EMA step or a blend saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AccumulateStats {
    /// New samples with a non-finite channel (kept out of the history).
    pub non_finite: u64,
    /// Pixels left without any valid value (written as 0).
    pub holes: u64,
    /// Pixels whose history was discarded (reset to the new sample).
    pub resets: u64,
}

impl AccumulateStats {
    fn merged(self, o: Self) -> Self {
        Self { non_finite: self.non_finite + o.non_finite, holes: self.holes + o.holes, resets: self.resets + o.resets }
    }
}

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
fn finish(v: f32) -> f32 {
    let v = clamp_finite1(v);
    if v.abs() < f32::MIN_POSITIVE { 0.0 } else { v }
}

/// SIMD twin of [`lerp`].
#[inline(always)]
pub fn lerp_simd(a: F32s, b: F32s, t: F32s) -> F32s {
    let d = b - a;
    let overflow = !d.is_finite() & a.is_finite() & b.is_finite();
    let general = overflow.select(a * (F32s::ONE - t) + b * t, a + t * d);
    let v = t.simd_eq(F32s::ZERO).select(a, t.simd_eq(F32s::ONE).select(b, general));
    finish_simd(v)
}

#[inline(always)]
fn finish_simd(v: F32s) -> F32s {
    flush_subnormal(clamp_finite(v))
}

/// The flushing half of [`finish_simd`] (what it does to a finite value).
#[inline(always)]
fn flush_subnormal(v: F32s) -> F32s {
    v.abs().simd_lt(F32s::splat(f32::MIN_POSITIVE)).select(F32s::ZERO, v)
}

fn check_params(params: &EmaParams, has_len: bool) -> Result<(), FrameError> {
    if !(params.alpha > 0.0 && params.alpha <= 1.0) {
        return Err(FrameError::InvalidParameter("EMA alpha must be in (0, 1]"));
    }
    if params.ramp && !has_len {
        return Err(FrameError::InvalidParameter("the alpha ramp needs a history-length plane"));
    }
    Ok(())
}

fn check_ema(input: &EmaInput<'_>, state: &EmaState<'_>, params: &EmaParams) -> Result<(), FrameError> {
    check_params(params, state.history_len.is_some())?;
    let e = state.accum.extent();
    same_extent("new samples", e, input.new.extent())?;
    same_extent("reason plane", e, input.reason.extent())?;
    if let Some(h) = &input.has_new {
        same_extent("new-sample mask", e, h.extent())?;
    }
    if let Some(n) = &state.history_len {
        same_extent("history length plane", e, n.extent())?;
    }
    Ok(())
}

/// One pixel of the EMA (scalar reference). Returns the new accumulation and history length
/// and updates `stats`.
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
    let finite = new.iter().all(|v| v.is_finite());
    if has_new && !finite {
        stats.non_finite += 1;
    }
    match (has_new && finite, history_valid) {
        (true, true) => {
            let alpha = if params.ramp { params.alpha.max(1.0 / (history_len + 1.0)) } else { params.alpha };
            ([0, 1, 2].map(|c| lerp(history[c], new[c], alpha)), history_len + 1.0)
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

/// Scalar reference EMA step.
pub fn ema_scalar(
    input: &EmaInput<'_>,
    state: EmaState<'_>,
    params: &EmaParams,
) -> Result<AccumulateStats, FrameError> {
    check_ema(input, &state, params)?;
    Ok(run_ema(input, state, params, |input, y, acc, len, stats| {
        for x in 0..acc[0].len() {
            ema_scalar_at(input, params, y, x, acc, len.as_deref_mut(), stats);
        }
    }))
}

#[inline(always)]
fn ema_scalar_at(
    input: &EmaInput<'_>,
    params: &EmaParams,
    y: usize,
    x: usize,
    acc: &mut [&mut [f32]; 3],
    len: Option<&mut [f32]>,
    stats: &mut AccumulateStats,
) {
    let history = [acc[0][x], acc[1][x], acc[2][x]];
    let n = len.as_ref().map_or(0.0, |l| l[x]);
    let valid = input.reason.row(y)[x] == Reason::Reprojected as u8;
    let has_new = input.has_new.as_ref().is_none_or(|m| m.row(y)[x] != 0);
    let new = input.new.get(x, y);
    let (out, n_out) = ema_pixel(history, n, new, valid, has_new, params, stats);
    for c in 0..3 {
        acc[c][x] = out[c];
    }
    if let Some(l) = len {
        l[x] = n_out;
    }
}

/// SIMD EMA step, bit-identical to [`ema_scalar`].
///
/// ```
/// use stereotrace_kernels::accumulate::{self, EmaInput, EmaParams, EmaState};
/// use stereotrace_kernels::reproject::Reason;
/// use stereotrace_kernels::{Extent, PlaneBuf, RgbBuf};
///
/// let extent = Extent::new(16, 4)?;
/// let mut history = RgbBuf::new(extent, 1.0); // the reprojected history
/// let samples = RgbBuf::new(extent, 0.0); // this frame's samples
/// let valid = PlaneBuf::new(extent, Reason::Reprojected as u8);
/// let input = EmaInput { new: samples.view(), reason: valid.view(), has_new: None };
/// let state = EmaState { accum: history.view_mut(), history_len: None };
/// accumulate::ema(&input, state, &EmaParams::default())?; // alpha 0.2
/// assert_eq!(history.get(3, 2), [0.8; 3]);
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn ema(input: &EmaInput<'_>, mut state: EmaState<'_>, params: &EmaParams) -> Result<AccumulateStats, FrameError> {
    check_ema(input, &state, params)?;
    #[cfg(feature = "check-scalar")]
    let before = snapshot(&state);
    let stats = run_ema(input, state.reborrow(), params, |input, y, acc, len, stats| {
        let width = acc[0].len();
        let reason = input.reason.row(y);
        let has_new = input.has_new.as_ref().map(|m| m.row(y));
        let new = input.new.channels().map(|p| p.row(y));
        // Every row has the extent's width; stated once so that the loop's loads and stores
        // need no bounds checks.
        assert!(
            reason.len() == width
                && (0..3).all(|c| acc[c].len() == width && new[c].len() == width)
                && has_new.is_none_or(|m| m.len() == width)
                && len.as_deref().is_none_or(|l| l.len() == width)
        );
        let mut x = 0;
        while x + LANES <= width {
            let valid = byte_mask_eq(&reason[x..x + LANES], Reason::Reprojected as u8);
            let sampled = has_new.map_or(F32s::splat(f32::from_bits(u32::MAX)), |m| !byte_mask_eq(&m[x..x + LANES], 0));
            let new_v = [load(new[0], x), load(new[1], x), load(new[2], x)];
            let hist = [load(acc[0], x), load(acc[1], x), load(acc[2], x)];
            let n = len.as_deref().map_or(F32s::ZERO, |l| load(l, x));
            let alpha = if params.ramp {
                F32s::splat(params.alpha).max(F32s::ONE / (n + F32s::ONE))
            } else {
                F32s::splat(params.alpha)
            };
            // The common case: every lane has a valid history and a finite new sample, and
            // `new − history` is finite (so neither is infinite). Then `lerp` is
            // `a + t·(b − a)` (or `b` where t = 1) and there is nothing to count: the same
            // bits with about a third of the instructions (with the byte masks below,
            // 353 → 134 per 8 pixels; 2.5 → 1.2 ms per 1280×720 frame on one thread). The
            // result still goes through `finish`: next to ±f32::MAX, `a + t·d` can round
            // past the largest finite value (found by the fuzzer), and the reference clamps.
            let d = [new_v[0] - hist[0], new_v[1] - hist[1], new_v[2] - hist[2]];
            let zero = F32s::ZERO;
            let poison =
                (new_v[0] * zero + new_v[1] * zero + new_v[2] * zero) + (d[0] * zero + d[1] * zero + d[2] * zero);
            if (valid & sampled & poison.simd_eq(zero)).all() {
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
            let blend = use_new & valid;
            let reset = use_new & !valid;
            let hole = !use_new & !valid;
            for c in 0..3 {
                let mixed = lerp_simd(hist[c], new_v[c], alpha);
                let out = blend
                    .select(mixed, reset.select(finish_simd(new_v[c]), hole.select(F32s::ZERO, finish_simd(hist[c]))));
                store(acc[c], x, out);
            }
            if let Some(l) = len.as_deref_mut() {
                let n_out = blend.select(n + F32s::ONE, reset.select(F32s::ONE, hole.select(F32s::ZERO, n)));
                store(l, x, n_out);
            }
            stats.non_finite += u64::from((sampled & !finite).to_bitmask().count_ones());
            stats.resets += u64::from(reset.to_bitmask().count_ones());
            stats.holes += u64::from(hole.to_bitmask().count_ones());
            x += LANES;
        }
        for x in x..width {
            ema_scalar_at(input, params, y, x, acc, len.as_deref_mut(), stats);
        }
    });
    #[cfg(feature = "check-scalar")]
    {
        let (mut colour, mut len) = before;
        let reference = ema_scalar(
            input,
            EmaState { accum: colour.view_mut(), history_len: len.as_mut().map(|l| l.view_mut()) },
            params,
        )
        .expect("validated input");
        assert_eq!(stats, reference, "EMA stats differ");
        let simd = state.accum.as_planes().channels();
        for (c, plane) in colour.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("EMA colour", c, &simd[c], plane);
        }
        if let (Some(a), Some(b)) = (&state.history_len, &len) {
            crate::check::assert_planes_equal("EMA history length", 0, &a.as_plane(), &b.view());
        }
    }
    Ok(stats)
}

#[cfg(feature = "check-scalar")]
fn snapshot(state: &EmaState<'_>) -> (crate::frame::RgbBuf, Option<crate::frame::PlaneBuf>) {
    use crate::frame::{PlaneBuf, RgbBuf};
    let e = state.accum.extent();
    let mut colour = RgbBuf::new(e, 0.0);
    let src = state.accum.as_planes();
    for y in 0..e.height() {
        for x in 0..e.width() {
            colour.set(x, y, src.get(x, y));
        }
    }
    let len = state.history_len.as_ref().map(|l| {
        let mut buf = PlaneBuf::new(e, 0.0f32);
        for y in 0..e.height() {
            buf.view_mut().row_mut(y).copy_from_slice(l.row(y));
        }
        buf
    });
    (colour, len)
}

impl EmaState<'_> {
    /// A shorter-lived view of the same buffers.
    pub fn reborrow(&mut self) -> EmaState<'_> {
        EmaState { accum: self.accum.reborrow(), history_len: self.history_len.as_mut().map(|l| l.reborrow()) }
    }
}

/// All-ones lanes where the byte equals `value` (the first `LANES` bytes).
#[inline(always)]
fn byte_mask_eq(bytes: &[u8], value: u8) -> F32s {
    let b: [u8; LANES] = bytes[..LANES].try_into().expect("LANES bytes");
    // Widened in one vector instruction (`vpmovzxbd`); a per-lane loop building the mask
    // from scalar compares was 30 instructions.
    let lanes = I32s::from([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]].map(i32::from));
    bytemuck::cast(lanes.simd_eq(I32s::splat(i32::from(value))))
}

type EmaRow<'r> = [&'r mut [f32]; 3];

fn run_ema<F>(input: &EmaInput<'_>, state: EmaState<'_>, params: &EmaParams, body: F) -> AccumulateStats
where
    F: for<'r> Fn(&EmaInput<'_>, usize, &mut EmaRow<'r>, &mut Option<&'r mut [f32]>, &mut AccumulateStats) + Sync,
{
    let height = state.accum.extent().height();
    let [r, g, b] = state.accum.into_channels();
    let acc = [r, g, b].map(SharedRows::new);
    let len = state.history_len.map(SharedRows::new);
    for_each_band(
        height,
        params.band_rows,
        |rows| {
            let mut stats = AccumulateStats::default();
            for y in rows {
                // SAFETY: `for_each_band` hands each row to exactly one band.
                let mut row = [0, 1, 2].map(|c| unsafe { acc[c].row(y) });
                // SAFETY: as above.
                let mut l = len.as_ref().map(|l| unsafe { l.row(y) });
                body(input, y, &mut row, &mut l, &mut stats);
            }
            stats
        },
        AccumulateStats::merged,
    )
}

/// Stereo blend parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlendParams {
    /// Weight of the eye's own samples, in [0, 1] (the paper: 0.5).
    pub own_weight: f32,
    /// Rows per parallel band.
    pub band_rows: usize,
}

impl Default for BlendParams {
    fn default() -> Self {
        Self { own_weight: 0.5, band_rows: 16 }
    }
}

fn check_blend(
    own: &RgbPlanes<'_>,
    reprojected: &RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    params: &BlendParams,
) -> Result<(), FrameError> {
    if !(0.0..=1.0).contains(&params.own_weight) {
        return Err(FrameError::InvalidParameter("blend weight must be in [0, 1]"));
    }
    let e = own.extent();
    same_extent("reprojected image", e, reprojected.extent())?;
    same_extent("reason plane", e, reason.extent())
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
    let finite = own.iter().all(|v| v.is_finite());
    if !finite {
        stats.non_finite += 1;
    }
    let t = 1.0 - params.own_weight;
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

/// Scalar reference stereo blend; writes the result over `reprojected`.
pub fn blend_scalar(
    own: &RgbPlanes<'_>,
    reprojected: RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    params: &BlendParams,
) -> Result<AccumulateStats, FrameError> {
    check_blend(own, &reprojected, reason, params)?;
    Ok(run_blend(reprojected, params, |y, out, stats| {
        for x in 0..out[0].len() {
            blend_scalar_at(own, reason, params, x, y, out, stats);
        }
    }))
}

#[inline(always)]
fn blend_scalar_at(
    own: &RgbPlanes<'_>,
    reason: &Plane<'_, u8>,
    params: &BlendParams,
    x: usize,
    y: usize,
    out: &mut EmaRow<'_>,
    stats: &mut AccumulateStats,
) {
    let valid = reason.row(y)[x] == Reason::Reprojected as u8;
    let v = blend_pixel(own.get(x, y), [out[0][x], out[1][x], out[2][x]], valid, params, stats);
    for c in 0..3 {
        out[c][x] = v[c];
    }
}

/// SIMD stereo blend, bit-identical to [`blend_scalar`]; writes the result over
/// `reprojected`.
pub fn blend(
    own: &RgbPlanes<'_>,
    mut reprojected: RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    params: &BlendParams,
) -> Result<AccumulateStats, FrameError> {
    check_blend(own, &reprojected, reason, params)?;
    #[cfg(feature = "check-scalar")]
    let before = snapshot(&EmaState { accum: reprojected.reborrow(), history_len: None }).0;
    let t = F32s::splat(1.0 - params.own_weight);
    let stats = run_blend(reprojected.reborrow(), params, |y, out, stats| {
        let width = out[0].len();
        let reason_row = reason.row(y);
        let own_rows = own.channels().map(|p| p.row(y));
        let mut x = 0;
        while x + LANES <= width {
            let valid = byte_mask_eq(&reason_row[x..x + LANES], Reason::Reprojected as u8);
            let mine = own_rows.map(|p| load(p, x));
            let theirs = [0, 1, 2].map(|c| load(out[c], x));
            let finite = mine[0].is_finite() & mine[1].is_finite() & mine[2].is_finite();
            let hole = !finite & !valid;
            for c in 0..3 {
                let mixed = lerp_simd(mine[c], theirs[c], t);
                let v = finite.select(
                    valid.select(mixed, finish_simd(mine[c])),
                    valid.select(finish_simd(theirs[c]), F32s::ZERO),
                );
                store(out[c], x, v);
            }
            stats.non_finite += u64::from((!finite).to_bitmask().count_ones());
            stats.holes += u64::from(hole.to_bitmask().count_ones());
            x += LANES;
        }
        for x in x..width {
            blend_scalar_at(own, reason, params, x, y, out, stats);
        }
    });
    #[cfg(feature = "check-scalar")]
    {
        let mut reference = before;
        let expected = blend_scalar(own, reference.view_mut(), reason, params).expect("validated input");
        assert_eq!(stats, expected, "blend stats differ");
        let simd = reprojected.as_planes().channels();
        for (c, plane) in reference.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("blend colour", c, &simd[c], plane);
        }
    }
    Ok(stats)
}

fn run_blend<F>(out: RgbPlanesMut<'_>, params: &BlendParams, body: F) -> AccumulateStats
where
    F: for<'r> Fn(usize, &mut EmaRow<'r>, &mut AccumulateStats) + Sync,
{
    let height = out.extent().height();
    let [r, g, b] = out.into_channels();
    let rows = [r, g, b].map(SharedRows::new);
    for_each_band(
        height,
        params.band_rows,
        |range| {
            let mut stats = AccumulateStats::default();
            for y in range {
                // SAFETY: `for_each_band` hands each row to exactly one band.
                let mut row = [0, 1, 2].map(|c| unsafe { rows[c].row(y) });
                body(y, &mut row, &mut stats);
            }
            stats
        },
        AccumulateStats::merged,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lerp_is_exact_at_the_ends_and_for_constants() {
        for &v in &[0.1f32, 1e10, -3.5, 1e-30, 65504.0] {
            assert_eq!(lerp(v, v, 0.2), v);
            assert_eq!(lerp(v, 7.0, 0.0), v);
            assert_eq!(lerp(1e10, v, 1.0), v);
        }
    }

    #[test]
    fn lerp_flushes_subnormals_and_clamps() {
        assert_eq!(lerp(1e-38, 0.0, 0.5), 0.0);
        assert_eq!(lerp(f32::MAX, -f32::MAX, 0.5), 0.0);
        assert!((lerp(-f32::MAX, f32::MAX, 0.75) / (f32::MAX * 0.5) - 1.0).abs() < 1e-6);
        assert!(lerp(-f32::MAX, f32::MAX, 0.999).is_finite());
    }

    #[test]
    fn ema_pixel_cases() {
        let p = EmaParams::default();
        let mut s = AccumulateStats::default();
        let (v, n) = ema_pixel([1.0; 3], 3.0, [2.0; 3], true, true, &p, &mut s);
        assert_eq!(v, [1.2; 3]);
        assert_eq!(n, 4.0);
        let (v, n) = ema_pixel([1.0; 3], 3.0, [f32::NAN, 0.0, 0.0], true, true, &p, &mut s);
        assert_eq!((v, n), ([1.0; 3], 3.0));
        let (v, n) = ema_pixel([1.0; 3], 3.0, [f32::INFINITY; 3], false, true, &p, &mut s);
        assert_eq!((v, n), ([0.0; 3], 0.0));
        let (v, n) = ema_pixel([1.0; 3], 3.0, [5.0; 3], false, true, &p, &mut s);
        assert_eq!((v, n), ([5.0; 3], 1.0));
        assert_eq!(s, AccumulateStats { non_finite: 2, holes: 1, resets: 1 });
    }

    #[test]
    fn ramp_takes_the_running_mean_first() {
        let p = EmaParams { ramp: true, ..EmaParams::default() };
        let mut s = AccumulateStats::default();
        // One sample of history: alpha = max(0.2, 1/2) = 0.5.
        let (v, _) = ema_pixel([0.0; 3], 1.0, [1.0; 3], true, true, &p, &mut s);
        assert_eq!(v, [0.5; 3]);
        // Nine samples: 1/10 < 0.2, the EMA weight wins.
        let (v, _) = ema_pixel([0.0; 3], 9.0, [1.0; 3], true, true, &p, &mut s);
        assert_eq!(v, [0.2; 3]);
    }
}

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

mod scalar;
mod simd;

use crate::bands::{SharedRows, first_bad_row, for_each_band};
use crate::frame::{FrameError, Plane, PlaneMut, RgbPlanes, RgbPlanesMut, same_extent};
use crate::reproject::check_reason_plane;
use crate::simd::F32s;
pub use scalar::{
    blend_pixel, effective_samples, ema_pixel, ema_pixel_trusting, lerp, mean_variance_factor, variance_blend_toward,
};
use scalar::{blend_scalar_at, ema_scalar_at};
pub(crate) use simd::byte_mask_eq;
pub use simd::lerp_simd;

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
    /// [`crate::reproject::Reason::Reprojected`]. A code outside the defined set (6 and up)
    /// is refused ([`crate::reproject::check_reason_plane`]).
    pub reason: Plane<'a, u8>,
    /// Optional: non-zero where a new sample exists this frame (absent: everywhere).
    pub has_new: Option<Plane<'a, u8>>,
    /// Optional: how far each pixel's history can be trusted, in [0, 1] (absent: 1
    /// everywhere), for what reprojection cannot see (a light that moved, an engine's own
    /// disocclusion test). Where the history is valid and a new sample arrives, it counts as
    /// `c·n` samples and `α' = α + (1 − α)·(1 − c)`: `c = 1` is the plain EMA, bit for bit,
    /// `c = 0` restarts from the new sample. NaN or values outside [0, 1] are refused (with a
    /// pixel mask, where the mask is set: the only values read).
    pub confidence: Option<Plane<'a, f32>>,
    /// Optional: only pixels where it is non-zero are updated (absent: every pixel). The
    /// others keep their accumulation and history length as they were and are not counted;
    /// their confidence and history length are neither read nor checked.
    /// A caller that has already written most of the frame (the paper-order left eye, whose
    /// stereo samples are its restarted history) then pays for the rest only.
    pub pixel_mask: Option<Plane<'a, u8>>,
}

/// The accumulation buffers, updated in place.
pub struct EmaState<'a> {
    /// In: the reprojected history. Out: the new accumulation.
    pub accum: RgbPlanesMut<'a>,
    /// In: the reprojected history length in samples (finite and ≥ 0: anything else is
    /// refused, where [`EmaInput::pixel_mask`] is set if there is one). Out: the updated
    /// length (0 for holes). Required when `ramp` is on.
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
    if let Some(m) = &input.pixel_mask {
        same_extent("pixel mask", e, m.extent())?;
    }
    // With a pixel mask the EMA reads the confidence and the length only where the mask is
    // set (the lanes of a group outside it are selected away), so only those values are
    // checked: under a budget, a few percent of the frame instead of two whole planes.
    let mask = input.pixel_mask.as_ref();
    if let Some(c) = &input.confidence {
        same_extent("history confidence plane", e, c.extent())?;
        check_values(c, mask, unit_interval("history confidence plane"))?;
    }
    if let Some(n) = &state.history_len {
        same_extent("history length plane", e, n.extent())?;
        check_values(&n.as_plane(), mask, history_length())?;
    }
    check_reason_plane("reason plane", &input.reason)
}

/// What a checked plane's values must be (`ok`, inlined into the folds: a function pointer
/// there costs a call per pixel), and how an error names them.
#[derive(Clone, Copy)]
struct ValueRule<F> {
    what: &'static str,
    allowed: &'static str,
    ok: F,
}

/// A confidence: in [0, 1] (NaN fails).
fn unit_interval(what: &'static str) -> ValueRule<impl Fn(f32) -> bool + Copy + Sync> {
    ValueRule { what, allowed: "in [0, 1]", ok: |v: f32| (0.0..=1.0).contains(&v) }
}

/// A history length is a count: finite and ≥ 0. Negative, NaN or infinite lengths would give
/// the ramp's `1/(n + 1)` a negative, infinite or NaN weight.
fn history_length() -> ValueRule<impl Fn(f32) -> bool + Copy + Sync> {
    ValueRule {
        what: "history length plane",
        allowed: "a finite sample count >= 0",
        ok: |v: f32| (0.0..=f32::MAX).contains(&v),
    }
}

/// Refuses a confidence outside [0, 1] (or NaN) in the plane called `what`, naming the
/// first such pixel.
pub(crate) fn check_unit_interval(what: &'static str, plane: &Plane<'_>) -> Result<(), FrameError> {
    check_values(plane, None, unit_interval(what))
}

fn check_history_len(len: &Plane<'_>) -> Result<(), FrameError> {
    check_values(len, None, history_length())
}

/// Refuses a value of `plane` that breaks `rule`, naming the first such pixel; with a `mask`,
/// only where it is non-zero.
fn check_values<F: Fn(f32) -> bool + Copy + Sync>(
    plane: &Plane<'_>,
    mask: Option<&Plane<'_, u8>>,
    rule: ValueRule<F>,
) -> Result<(), FrameError> {
    let ok = rule.ok;
    let row_ok = |y: usize| match mask {
        // Folded without an early exit so the pass vectorises.
        None => plane.row(y).iter().fold(true, |all, &v| all & ok(v)),
        Some(mask) => masked_row_ok(plane.row(y), mask.row(y), ok),
    };
    let Some(y) = first_bad_row(plane.height(), row_ok) else {
        return Ok(());
    };
    let (row, mask_row) = (plane.row(y), mask.map(|m| m.row(y)));
    let checked = |x: usize| mask_row.is_none_or(|m| m[x] != 0);
    let x = (0..row.len()).find(|&x| checked(x) && !ok(row[x])).expect("a bad value is in the row");
    Err(FrameError::ValueOutOfRange { what: rule.what, x, y, value: f64::from(row[x]), allowed: rule.allowed })
}

/// Whether every value of `values` where `mask` is non-zero passes `ok`: the mask's empty
/// stretches skipped, each stretch of [`MASKED_CHECK_STRETCH`] after a set byte folded whole.
#[inline(always)]
fn masked_row_ok(values: &[f32], mask: &[u8], ok: impl Fn(f32) -> bool) -> bool {
    let mut x = 0;
    while x < values.len() {
        x += crate::simd::leading_zero_bytes(&mask[x..]);
        let end = (x + MASKED_CHECK_STRETCH).min(values.len());
        let stretch = values[x..end].iter().zip(&mask[x..end]);
        if !stretch.fold(true, |all, (&v, &m)| all & ((m == 0) | ok(v))) {
            return false;
        }
        x = end;
    }
    true
}

/// Pixels a masked check folds after each set byte it finds.
const MASKED_CHECK_STRETCH: usize = 32;

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
/// let input = EmaInput { new: samples.view(), reason: valid.view(), has_new: None, confidence: None, pixel_mask: None };
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
        simd::ema_row(input, params, y, acc, len, stats)
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
    use crate::frame::PlaneBuf;
    let e = state.accum.extent();
    let colour = crate::check::rgb_copy(&state.accum.as_planes());
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

/// The history lengths the variance-guided blend weighs by ([`blend_by_variance`]).
#[derive(Clone, Copy)]
pub struct BlendLengths<'a> {
    /// The eye's own history length per pixel (samples; finite and ≥ 0, else refused).
    pub own: Plane<'a>,
    /// The other eye's history length, reprojected with its image (the same rule).
    pub other: Plane<'a>,
    /// The EMA's α, in (0, 1]: it sets the variance of a long history.
    pub alpha: f32,
}

/// How a blend weighs the reprojection per pixel (`t` in `lerp(own, reprojected, t)`).
#[derive(Clone, Copy)]
pub(crate) enum BlendWeights<'a> {
    /// The same everywhere: `1 − own_weight`.
    Fixed(f32),
    /// Inverse variance by history length ([`variance_blend_toward`]).
    ByLength(BlendLengths<'a>),
}

impl BlendWeights<'_> {
    #[inline(always)]
    pub(crate) fn toward_reprojected(&self, x: usize, y: usize) -> f32 {
        match self {
            BlendWeights::Fixed(t) => *t,
            BlendWeights::ByLength(l) => variance_blend_toward(l.own.row(y)[x], l.other.row(y)[x], l.alpha),
        }
    }

    /// [`BlendWeights::toward_reprojected`] of the eight pixels from `x`.
    #[inline(always)]
    pub(crate) fn toward_reprojected_simd(&self, x: usize, y: usize) -> F32s {
        match self {
            BlendWeights::Fixed(t) => F32s::splat(*t),
            BlendWeights::ByLength(l) => {
                let (own, other) = (crate::simd::load(l.own.row(y), x), crate::simd::load(l.other.row(y), x));
                simd::variance_blend_toward_simd(own, other, l.alpha)
            }
        }
    }
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
    same_extent("reason plane", e, reason.extent())?;
    check_reason_plane("reason plane", reason)
}

/// Scalar reference stereo blend; writes the result over `reprojected`.
pub fn blend_scalar(
    own: &RgbPlanes<'_>,
    reprojected: RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    params: &BlendParams,
) -> Result<AccumulateStats, FrameError> {
    check_blend(own, &reprojected, reason, params)?;
    let weights = BlendWeights::Fixed(1.0 - params.own_weight);
    Ok(run_blend(reprojected, params.band_rows, |y, out, stats| {
        for x in 0..out[0].len() {
            blend_scalar_at(own, reason, &weights, x, y, out, stats);
        }
    }))
}

fn check_lengths(own: &RgbPlanes<'_>, lengths: &BlendLengths<'_>) -> Result<(), FrameError> {
    if !(lengths.alpha > 0.0 && lengths.alpha <= 1.0) {
        return Err(FrameError::InvalidParameter("EMA alpha must be in (0, 1]"));
    }
    same_extent("own history length plane", own.extent(), lengths.own.extent())?;
    same_extent("other eye's history length plane", own.extent(), lengths.other.extent())?;
    check_history_len(&lengths.own)?;
    check_history_len(&lengths.other)
}

/// The one boundary check of both variance-blend bodies: the blend's planes and the lengths.
fn check_variance_blend(
    own: &RgbPlanes<'_>,
    reprojected: &RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    lengths: &BlendLengths<'_>,
    band_rows: usize,
) -> Result<(), FrameError> {
    check_blend(own, reprojected, reason, &BlendParams { own_weight: 0.5, band_rows })?;
    check_lengths(own, lengths)
}

/// Scalar reference of [`blend_by_variance`].
pub fn blend_by_variance_scalar(
    own: &RgbPlanes<'_>,
    reprojected: RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    lengths: &BlendLengths<'_>,
    band_rows: usize,
) -> Result<AccumulateStats, FrameError> {
    check_variance_blend(own, &reprojected, reason, lengths, band_rows)?;
    let weights = BlendWeights::ByLength(*lengths);
    Ok(run_blend(reprojected, band_rows, |y, out, stats| {
        for x in 0..out[0].len() {
            blend_scalar_at(own, reason, &weights, x, y, out, stats);
        }
    }))
}

/// The variance-guided stereo blend (SIMD, bit-identical to [`blend_by_variance_scalar`]):
/// [`blend`] with each pixel's weights by inverse variance of the two estimates, the
/// variance of an EMA's mean following from its history length
/// ([`variance_blend_toward`]). An eye whose history restarted (a disocclusion) leans on the
/// other eye's longer one; equal lengths give the paper's 50/50 bit for bit. Lengths that are
/// not finite counts ≥ 0 are refused.
pub fn blend_by_variance(
    own: &RgbPlanes<'_>,
    mut reprojected: RgbPlanesMut<'_>,
    reason: &Plane<'_, u8>,
    lengths: &BlendLengths<'_>,
    band_rows: usize,
) -> Result<AccumulateStats, FrameError> {
    check_variance_blend(own, &reprojected, reason, lengths, band_rows)?;
    #[cfg(feature = "check-scalar")]
    let before = snapshot(&EmaState { accum: reprojected.reborrow(), history_len: None }).0;
    let weights = BlendWeights::ByLength(*lengths);
    let stats = run_blend(reprojected.reborrow(), band_rows, |y, out, stats| {
        simd::blend_row(own, reason, &weights, y, out, stats)
    });
    #[cfg(feature = "check-scalar")]
    {
        let mut reference = before;
        let expected =
            blend_by_variance_scalar(own, reference.view_mut(), reason, lengths, band_rows).expect("validated input");
        assert_eq!(stats, expected, "variance blend stats differ");
        let simd = reprojected.as_planes().channels();
        for (c, plane) in reference.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("variance blend colour", c, &simd[c], plane);
        }
    }
    Ok(stats)
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
    let weights = BlendWeights::Fixed(1.0 - params.own_weight);
    let stats = run_blend(reprojected.reborrow(), params.band_rows, |y, out, stats| {
        simd::blend_row(own, reason, &weights, y, out, stats)
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

fn run_blend<F>(out: RgbPlanesMut<'_>, band_rows: usize, body: F) -> AccumulateStats
where
    F: for<'r> Fn(usize, &mut EmaRow<'r>, &mut AccumulateStats) + Sync,
{
    let height = out.extent().height();
    let [r, g, b] = out.into_channels();
    let rows = [r, g, b].map(SharedRows::new);
    for_each_band(
        height,
        band_rows,
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

//! SSIM and RMSE between two linear RGB images, in one fused pass.
//!
//! # Definition
//! The paper's "SSIM over the RGB image as a 3D volume" is MATLAB's `ssim` on an H×W×3
//! array, [`SsimVariant::Volume`]:
//!
//! * an 11-tap Gaussian window, σ = 1.5, along x, y **and** the channel axis
//!   ([`gaussian_weights`]: `exp(−k²/2σ²)` for `k = −5‥5`, normalised to sum 1);
//! * replicate padding on every axis (`imfilter(…, 'replicate')` / `imgaussfilt3`);
//! * `μ`, `σ² = E[x²] − μ²`, `σxy = E[xy] − μxμy` from that filter, `C1 = (0.01·L)²`,
//!   `C2 = (0.03·L)²`, `L = 1`, and the map
//!   `((2μxμy + C1)(2σxy + C2)) / ((μx² + μy² + C1)(σx² + σy² + C2))`;
//! * the result is the mean of the map over all H·W·3 voxels.
//!
//! Along the channel axis (length 3) the replicate-padded 11-tap window collapses to a fixed
//! 3×3 matrix ([`channel_mixing_matrix`]): voxel `(p, c)` sees channel `c'` with weight
//! `M[c][c'] = Σ { w_k : clamp(c + k, 0, 2) = c' }`. So the 3-D statistics are the per-channel
//! 2-D windowed statistics mixed by `M`. Every `M` entry is positive: every 3-D window spans
//! all three channels. The rows of `M` sum to 1, so on a grey image (all channels equal)
//! the 3-D statistics equal the 2-D ones and the two variants give the same value; the
//! kernels mix in the form `q_c + Σ_{c'≠c} M[c][c']·(q_c' − q_c)`, which keeps that equality
//! exact in floating point too.
//!
//! [`SsimVariant::PerChannel`] is MATLAB's `ssim` on each channel separately (11×11 window),
//! averaged over the channels. It is an explicit option, never a fallback: on colour images
//! the two give very different numbers.
//!
//! RMSE is `sqrt(mean((x − y)²))` over all H·W·3 values.
//!
//! # Numerics
//! Inputs are linear HDR radiance; fireflies reach 10³–10⁶. `E[x²] − μ²` in f32 loses every
//! digit of a small variance under a large mean (at μ = 1000 one ulp of `E[x²]` is 0.06,
//! against `C2 = 9·10⁻⁴`). The fast kernel keeps it well conditioned in four ways:
//!
//! 1. **Difference form.** With `d = x − y`, the map is
//!    `(1 − μd²/(μx² + μy² + C1)) · (1 − σd²/(σx² + σy² + C2))`
//!    (since `2μxμy = μx² + μy² − μd²` and `2σxy = σx² + σy² − σd²`). The deficits from 1
//!    come from `d` directly, so nearly equal images (the case SSIM is used for) are
//!    computed from small numbers, identical images give exactly 1, and swapping the
//!    arguments gives bit-identical results.
//! 2. **Local shift.** Variance is shift invariant: each tile (64 rows × 64 columns) and
//!    channel subtracts a robust local level (median of 9 samples, so fireflies do not move
//!    it) from `x` and `y`, and another from `d`, before squaring.
//! 3. **Exact channel mixing.** The 3-D variances are mixed with the law of total variance,
//!    `σ²₃ = Σ M·σ²_c' + Σ M·(μ_c' − μ₃)²`, so each channel may use its own shift.
//! 4. **Conditioning check and refinement.** Every voxel's rounding error is estimated from
//!    the magnitudes that were cancelled (structure term:
//!    `γu·(E[d'²] + deficit·E[x'² + y'²]) / (σx² + σy² + C2)`, luminance term:
//!    `6γu·(|μx'| + |μy'|)·|μd| / (μx² + μy² + C1)`, `γu = 4·2⁻²⁴`). A voxel above
//!    [`REFINE_THRESHOLD`] is recomputed with its tile re-shifted to the local means of the
//!    worst such voxel (up to two more passes), and if still above, by the exact f64 window
//!    formula. [`SsimResult::refined`] counts them: 0 on LDR content; on a synthetic HDR frame
//!    (a 1000-level emitter above 0.01–10 shading, fireflies to 10⁶) about 0.4%, the dark
//!    windows of the tiles the emitter's edge crosses. The 3-D variant first runs a cheaper
//!    conservative *screen* (each mixed magnitude bounded by the largest per-channel one, with
//!    slack for rounding); only vectors it fires on pay for the exact estimate, and it never
//!    passes a voxel the estimate would flag, so the refined voxels are the same.
//!
//! Accuracy, measured against the exact formula voxel by voxel on adversarial HDR images
//! (levels from 0.02 to 10⁵ in blocks of 5–38 px, noise down to 10⁻⁴ relative): the worst
//! voxel is off by 5e-5, the estimate is within 1.6× of the actual error, and the mean
//! (the result) by at most 5e-7; on ordinary images the mean agrees to about 1e-9. (These
//! figures predate the fused multiply-adds below; the tests' bounds, 1e-6 against the f64
//! reference and the brute-force oracle with the HDR cases included, hold at both builds.)
//! The mean is that accurate because many voxels average their rounding away: on an image
//! of a few pixels it is only as good as a voxel, within [`CHECK_TOLERANCE`] (a property
//! test found a 2×1 image 1.8e-6 off).
//!
//! Variances are clamped at 0, `σd²` at `2(σx² + σy² + C2)` (what keeps the structure term
//! ≥ −1; the tighter exact bound `2(σx² + σy²)` would trust the possibly ill-conditioned
//! `σx² + σy²`), and every voxel is clamped to [−1, 1]. Means are accumulated in f64 in a
//! fixed order (bands, then tiles, then rows), so the result does not depend on the thread
//! count; it does depend, in the last bits, on [`SsimParams::band_rows`] (tile boundaries
//! move the shifts).
//!
//! # Refused images
//! Both images must have the same extent, at least [`MIN_SIDE`] (11, the window) on each
//! side: smaller images are refused with [`FrameError::SmallerThanWindow`] by the fast kernel
//! and the reference alike.
//!
//! # Excluded samples
//! A sample is *unusable* if it is NaN, ±∞, or larger than [`MAX_SAMPLE`] in magnitude (its
//! square would overflow the f32 statistics). [`SsimResult::non_finite`] counts the
//! unusable samples of both images (each of the H·W·3 positions counts once per image).
//! * SSIM: a voxel whose window contains an unusable sample of either image is excluded from
//!   the mean; [`SsimResult::voxels`] counts the voxels that were used. The window of a 3-D
//!   voxel is its 11×11 neighbourhood in *all three* channels, the window of a per-channel
//!   voxel only its own channel's.
//! * RMSE: a position where either image's sample is unusable is excluded;
//!   [`SsimResult::rmse_samples`] counts the positions that were used.
//!
//! With nothing usable, `ssim` (or `rmse`) is NaN and its count is 0.
//!
//! # Fused multiply-add: the one exception to the determinism policy
//! Every other kernel of the crate is bit-identical to its scalar reference and computes
//! `a·b + c` with two roundings (see [`crate::simd`]). SSIM is checked against its f64
//! reference to a tolerance (`|Δssim| ≤ 1e-6`), not bitwise, so its fast kernel may and does
//! use fused multiply-add (`wide`'s `mul_add` / `mul_neg_add`) in the two filter passes, the
//! channel mixing and the map: one instruction and one rounding instead of two. `wide` fuses
//! only where the build targets FMA (x86-64-v3, the workspace default, and above); at the
//! SSE2 baseline the same calls round twice, so the two builds differ in the last bits of
//! the result, well within the tolerance (the tests run at both levels). A given build is
//! still deterministic (independent of the thread count) and symmetric bit for bit: sums
//! whose operands trade places when the images are swapped (`x'² + y'²`, `μx² + μy²`) stay
//! unfused.
//!
//! # Kernels
//! [`ssim`] is the fused SIMD kernel (16 lanes on AVX-512 CPUs, 8 otherwise, chosen at run
//! time: [`crate::isa`]; [`ssim_with`] picks one): per row band (on the caller's rayon pool) and
//! 64-column tile, a horizontal pass per input row into a ring of 14 filtered rows (43 KB),
//! then a vertical pass for 4 output rows at a time, the channel mixing, the map and the
//! accumulation; the intermediates never leave L1/L2. It allocates nothing. [`ssim_scalar`] is the
//! reference: f64, whole-image planes, centred (two-level) variances, exclusion by an
//! explicit dilated mask. The two agree to about 1e-8 on ordinary images (the tests assert
//! `|Δssim| ≤ 1e-6`, `|Δrmse| ≤ 1e-6·rmse` and equal counts); they are not bitwise equal,
//! since the summation orders and precisions differ by design.

mod scalar;
mod simd;

use crate::frame::{FrameError, RgbPlanes, same_extent};
use crate::isa::Isa;

pub use scalar::exact_voxel;

/// Window radius: 11 taps.
pub const RADIUS: usize = 5;
/// Window length along each axis.
pub const TAPS: usize = 2 * RADIUS + 1;
/// Gaussian standard deviation (pixels, and channels for the 3-D window).
pub const SIGMA: f64 = 1.5;
/// Dynamic range `L` (linear radiance, MATLAB's value for floating point images).
pub const DYNAMIC_RANGE: f64 = 1.0;
/// `C1 = (0.01·L)²`.
pub const C1: f64 = (0.01 * DYNAMIC_RANGE) * (0.01 * DYNAMIC_RANGE);
/// `C2 = (0.03·L)²`.
pub const C2: f64 = (0.03 * DYNAMIC_RANGE) * (0.03 * DYNAMIC_RANGE);
/// Samples larger than this in magnitude are treated as non-finite (see the module docs).
/// 10⁹ keeps every f32 statistic of the fast kernel finite (the largest intermediate,
/// `(μx²+μy²+C1)·(σx²+σy²+C2)`, stays below 10³⁸) with three decades above the brightest
/// fireflies.
pub const MAX_SAMPLE: f32 = 1.0e9;
/// Estimated per-voxel rounding error above which the fast kernel refines a voxel. The
/// errors of the accepted voxels are unbiased rounding noise, so the mean is far more
/// accurate than this bound (see the module docs). 1e-5 refined 7% of the voxels of a
/// synthetic HDR frame and cost 20× the time; 1e-4 refines 0.4%.
pub const REFINE_THRESHOLD: f64 = 1.0e-4;
/// `|Δssim|` that the `check-scalar` feature tolerates between [`ssim`] and [`ssim_scalar`].
/// Far looser than the tests' 1e-6: fuzz inputs are adversarial and tiny (a 1×1 image has
/// three voxels, each allowed an estimated error up to [`REFINE_THRESHOLD`]).
pub const CHECK_TOLERANCE: f64 = 10.0 * REFINE_THRESHOLD;

/// Which SSIM.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SsimVariant {
    /// The paper's: MATLAB `ssim` on the H×W×3 array (Gaussian window along x, y and the
    /// channel axis).
    #[default]
    Volume,
    /// MATLAB `ssim` on each channel separately (11×11 window), averaged over the channels.
    PerChannel,
}

/// Parameters of [`ssim`] / [`ssim_scalar`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SsimParams {
    /// Which SSIM.
    pub variant: SsimVariant,
    /// Rows per parallel band (rounded up so that a frame has at most 256 bands). Each band
    /// recomputes 10 halo rows of the horizontal pass, so small bands cost time.
    pub band_rows: usize,
}

impl Default for SsimParams {
    /// The paper's 3-D variant, 64-row bands (32 were 4% slower: more halo rows).
    fn default() -> Self {
        Self { variant: SsimVariant::Volume, band_rows: 64 }
    }
}

impl SsimParams {
    /// Default parameters for `variant`.
    pub fn with_variant(variant: SsimVariant) -> Self {
        Self { variant, ..Self::default() }
    }
}

/// What [`ssim`] measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsimResult {
    /// Mean SSIM over the used voxels (per-channel variant: the mean of the per-channel
    /// means). NaN if no voxel was usable.
    pub ssim: f64,
    /// Mean SSIM over the used voxels of each channel (for the 3-D variant, each channel's
    /// slice of the 3-D map). NaN for a channel without usable voxels.
    pub per_channel: [f64; 3],
    /// RMSE over the positions where both samples are usable. NaN if there are none.
    pub rmse: f64,
    /// Voxels whose SSIM entered the mean (at most H·W·3).
    pub voxels: u64,
    /// Positions that entered the RMSE (at most H·W·3).
    pub rmse_samples: u64,
    /// Unusable input samples (NaN, ±∞, |v| > [`MAX_SAMPLE`]), both images together.
    pub non_finite: u64,
    /// Voxels whose first-pass value was ill-conditioned and was recomputed (counted in
    /// `voxels` as well). Always 0 for [`ssim_scalar`].
    pub refined: u64,
}

impl SsimResult {
    /// H·W·3 minus the used voxels.
    pub fn excluded_voxels(&self, extent: crate::frame::Extent) -> u64 {
        3 * extent.pixels() as u64 - self.voxels
    }
}

/// The 11 Gaussian window weights (σ = 1.5), normalised to sum 1, for offsets −5‥5.
pub fn gaussian_weights() -> [f64; TAPS] {
    let mut w = [0.0f64; TAPS];
    for (i, w) in w.iter_mut().enumerate() {
        let k = i as f64 - RADIUS as f64;
        *w = (-(k * k) / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = w.iter().sum();
    w.map(|v| v / sum)
}

/// The channel-axis window of the 3-D variant: `M[c][c']` is the weight with which the
/// replicate-padded 11-tap Gaussian centred on channel `c` reads channel `c'`.
pub fn channel_mixing_matrix() -> [[f64; 3]; 3] {
    let w = gaussian_weights();
    let mut m = [[0.0f64; 3]; 3];
    for (c, row) in m.iter_mut().enumerate() {
        // Smallest weights first (|k| = 5, 4, …, 0): more accurate, and the matrix comes out
        // exactly mirror-symmetric (`M[c][c'] = M[2−c][2−c']`).
        for k in (0..=RADIUS as isize).rev() {
            let pair = [-k, k];
            for &k in if k == 0 { &pair[..1] } else { &pair[..] } {
                let src = (c as isize + k).clamp(0, 2) as usize;
                row[src] += w[(k + RADIUS as isize) as usize];
            }
        }
    }
    m
}

/// True if `v` is a usable sample (finite and within ±[`MAX_SAMPLE`]).
#[inline(always)]
pub fn usable(v: f32) -> bool {
    v.abs() <= MAX_SAMPLE
}

/// Sums of one part of the image, merged in a fixed order.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Partial {
    sum: [f64; 3],
    count: [u64; 3],
    sq: f64,
    sq_n: u64,
    non_finite: u64,
    refined: u64,
}

impl Partial {
    fn merged(mut self, o: &Self) -> Self {
        for c in 0..3 {
            self.sum[c] += o.sum[c];
            self.count[c] += o.count[c];
        }
        self.sq += o.sq;
        self.sq_n += o.sq_n;
        self.non_finite += o.non_finite;
        self.refined += o.refined;
        self
    }

    fn finish(&self, variant: SsimVariant) -> SsimResult {
        let per_channel = [0, 1, 2].map(|c| self.sum[c] / self.count[c] as f64);
        let voxels: u64 = self.count.iter().sum();
        let total: f64 = self.sum.iter().sum();
        let equal_counts = self.count[0] == self.count[1] && self.count[1] == self.count[2];
        let ssim = match variant {
            SsimVariant::Volume => total / voxels as f64,
            // The mean of the channel means. With equal counts that is the overall mean;
            // computing it the same way as the 3-D variant makes grey images give the same
            // bits under both variants.
            SsimVariant::PerChannel if equal_counts => total / voxels as f64,
            SsimVariant::PerChannel => {
                let used = per_channel.iter().filter(|v| !v.is_nan());
                used.clone().sum::<f64>() / used.count() as f64
            }
        };
        SsimResult {
            ssim,
            per_channel,
            rmse: (self.sq / self.sq_n as f64).sqrt(),
            voxels,
            rmse_samples: self.sq_n,
            non_finite: self.non_finite,
            refined: self.refined,
        }
    }
}

/// The smallest width and height [`ssim`] accepts: the window's. Below it every window
/// reaches past the image on both sides and the statistics come mostly from replicated
/// border samples (a 1×1 image would score 0.8 against a different 1×1 image), which is
/// not a measurement of the image.
pub const MIN_SIDE: usize = TAPS;

fn check(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>) -> Result<(), FrameError> {
    same_extent("second image", a.extent(), b.extent())?;
    let e = a.extent();
    if e.width() < MIN_SIDE || e.height() < MIN_SIDE {
        return Err(FrameError::SmallerThanWindow { extent: e, window: MIN_SIDE });
    }
    Ok(())
}

/// SSIM ([`SsimParams::variant`]) and RMSE of `a` against `b`: the fused SIMD kernel, run in
/// row bands on the current rayon pool, with the instruction set of [`Isa::active`] (16 lanes
/// on AVX-512 CPUs, 8 otherwise; [`ssim_with`] picks one). Symmetric in its arguments: bit for bit, except in the
/// last bits where voxels were refined (`SsimResult::refined`). See the module docs for the
/// definition, the numerics and what is excluded.
///
/// ```
/// use stereotrace_kernels::ssim::{SsimParams, ssim};
/// use stereotrace_kernels::{Extent, RgbBuf};
///
/// let extent = Extent::new(32, 32)?;
/// let mut a = RgbBuf::new(extent, 0.5);
/// a.set(10, 10, [1.0, 0.0, 0.25]);
/// let same = ssim(&a.view(), &a.view(), &SsimParams::default())?;
/// assert_eq!((same.ssim, same.rmse), (1.0, 0.0));
/// let b = RgbBuf::new(extent, 0.5);
/// assert!(ssim(&a.view(), &b.view(), &SsimParams::default())?.ssim < 1.0);
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn ssim(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, params: &SsimParams) -> Result<SsimResult, FrameError> {
    ssim_with(a, b, params, Isa::active())
}

/// [`ssim`] with the body for `isa` (the 8-lane body where this CPU lacks `isa`:
/// [`Isa::is_supported`]). The bodies compute every voxel to the same bits; the means can
/// differ in their last bits, because lanes sum the voxels of a row in a different order.
pub fn ssim_with(
    a: &RgbPlanes<'_>,
    b: &RgbPlanes<'_>,
    params: &SsimParams,
    isa: Isa,
) -> Result<SsimResult, FrameError> {
    let result = ssim_unchecked(a, b, params, isa)?;
    #[cfg(feature = "check-scalar")]
    {
        let reference = ssim_scalar(a, b, params).expect("validated input");
        assert_agrees(&result, &reference, CHECK_TOLERANCE);
    }
    Ok(result)
}

/// [`ssim`] without the `check-scalar` comparison, for checks that need only the fast body
/// (the fuzz target's symmetry check: one scalar reference per input is enough).
pub(crate) fn ssim_unchecked(
    a: &RgbPlanes<'_>,
    b: &RgbPlanes<'_>,
    params: &SsimParams,
    isa: Isa,
) -> Result<SsimResult, FrameError> {
    check(a, b)?;
    Ok(simd::run(a, b, params, isa))
}

/// The scalar reference of [`ssim`]: f64 throughout, whole-image planes (allocates about
/// 150 bytes per pixel), centred variances. Same definition and exclusions.
pub fn ssim_scalar(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, params: &SsimParams) -> Result<SsimResult, FrameError> {
    check(a, b)?;
    Ok(scalar::run(a, b, params.variant).finish(params.variant))
}

/// The absolute part of the RMSE agreement of [`assert_agrees`]. The SIMD body squares the
/// differences in f32, where a square below the smallest subnormal (1.4e-45) is 0, so an RMSE
/// made only of differences below about 4e-23 comes out 0 (the f64 reference keeps them: the
/// fuzzer found 0 against 1.1e-38). Above this floor the relative tolerance rules.
pub const RMSE_FLOOR: f64 = 1e-21;

/// Panics unless the counts agree exactly, `|Δssim| ≤ tol` (and per channel) and the RMSEs
/// agree to `tol` relative (plus [`RMSE_FLOOR`]). NaNs (nothing usable) must match.
pub fn assert_agrees(fast: &SsimResult, reference: &SsimResult, tol: f64) {
    assert_eq!(
        (fast.voxels, fast.rmse_samples, fast.non_finite),
        (reference.voxels, reference.rmse_samples, reference.non_finite),
        "SSIM counts differ: fast {fast:?}, reference {reference:?}"
    );
    assert_means_close(fast, reference, tol, "fast against reference");
}

/// The mean checks of [`assert_agrees`] and [`assert_isas_agree`]: `|Δssim| ≤ tol` (and per
/// channel), RMSEs within `tol` relative to `b`'s plus [`RMSE_FLOOR`]; NaNs must match.
fn assert_means_close(a: &SsimResult, b: &SsimResult, tol: f64, what: &str) {
    let close = |x: f64, y: f64, t: f64| (x.is_nan() && y.is_nan()) || (x - y).abs() <= t;
    assert!(close(a.ssim, b.ssim, tol), "SSIM differs ({what}): {a:?} vs {b:?}");
    for c in 0..3 {
        assert!(close(a.per_channel[c], b.per_channel[c], tol), "SSIM channel {c} differs ({what}): {a:?} vs {b:?}");
    }
    assert!(close(a.rmse, b.rmse, tol * b.rmse.abs() + RMSE_FLOOR), "RMSE differs ({what}): {a:?} vs {b:?}");
}

/// How far the means of two instruction sets' bodies may differ ([`assert_isas_agree`]). Every
/// voxel and squared difference has the same bits in both; each lane sums at most 8 voxels of
/// a tile row (30 squares of an RMSE row) in f32 before the f64 sum, in an order that depends
/// on the lane count. With `u = 2⁻²⁴` and voxels in [−1, 1] the mean moves by at most
/// `2 · 7u ≈ 8.3e-7`, and the RMSE by at most `29u ≈ 1.7e-6` relative; this leaves 2× margin.
pub const ISA_TOLERANCE: f64 = 4e-6;

/// Panics unless two instruction sets' results ([`ssim_with`]) count the same voxels, samples,
/// non-finite samples and refined voxels, and their means agree to [`ISA_TOLERANCE`].
pub fn assert_isas_agree(a: &SsimResult, b: &SsimResult) {
    assert_eq!(
        (a.voxels, a.rmse_samples, a.non_finite, a.refined),
        (b.voxels, b.rmse_samples, b.non_finite, b.refined),
        "instruction sets count differently: {a:?} vs {b:?}"
    );
    assert_means_close(a, b, ISA_TOLERANCE, "two instruction sets");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_a_normalised_symmetric_gaussian() {
        let w = gaussian_weights();
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for k in 0..TAPS {
            assert_eq!(w[k], w[TAPS - 1 - k]);
        }
        // exp(−1/4.5) between neighbours of the centre.
        assert!((w[RADIUS + 1] / w[RADIUS] - (-1.0f64 / 4.5).exp()).abs() < 1e-15);
    }

    #[test]
    fn mixing_matrix_is_stochastic_positive_and_mirror_symmetric() {
        let m = channel_mixing_matrix();
        let w = gaussian_weights();
        for c in 0..3 {
            assert!((m[c].iter().sum::<f64>() - 1.0).abs() < 1e-15);
            for c2 in 0..3 {
                assert!(m[c][c2] > 0.0);
                assert_eq!(m[c][c2], m[2 - c][2 - c2]);
            }
        }
        // Centre channel: the taps at offsets 0, and ±1..±5 pile up on the two edges.
        assert_eq!(m[1][1], w[RADIUS]);
        assert!((m[1][0] - w[..RADIUS].iter().sum::<f64>()).abs() < 1e-16);
        // Edge channel: offsets −5..0 all land on channel 0.
        assert!((m[0][0] - w[..=RADIUS].iter().sum::<f64>()).abs() < 1e-16);
        assert_eq!(m[0][1], w[RADIUS + 1]);
    }
}

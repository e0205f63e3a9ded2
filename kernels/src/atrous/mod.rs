//! An edge-avoiding à-trous filter after accumulation (Dammertz et al. 2010, with SVGF's
//! edge-stopping functions, Schied et al. 2017): the study of the paper's open question, at
//! what input spp reprojection alone is good enough to leave a denoising filter out.
//!
//! The filter reads an image, the G-buffer's depth and normals, and writes the filtered
//! image. It does not feed back into any history: it is a display filter.
//!
//! **Pre-pass.** Per pixel: the colour with each channel clamped to [0, [`VALUE_MAX`]] (NaN
//! becomes 0, +∞ the maximum; [`AtrousStats::out_of_range`] counts them); the unit normal
//! (decoded where the G-buffer's are octahedral); the depth slope `|∂z/∂x| + |∂z/∂y|`, each
//! the smaller one-sided difference to a neighbour that is a surface (0 where neither is);
//! and the luminance variance over the 3×3 neighbourhood inside the frame,
//! `max(0, E[l²] − E[l]²)` (SVGF's spatial estimate).
//!
//! **Iterations.** Iteration `i` (step `s = 2^i` pixels) replaces each surface pixel `p`
//! (depth in (0, ∞)) by the weighted mean of the 5×5 taps `q = p + s·(dx, dy)` inside the
//! frame that are surfaces:
//!
//! ```text
//! w = h(dx)·h(dy) · exp(−(|l_p − l_q| / (σ_l·√var_p + ε_l) + |z_p − z_q| / (σ_z·slope_p·s·d + ε_z·z_p)))
//!                 · min(1, max(0, n_p·n_q))^128
//! ```
//!
//! with `h = [1, 4, 6, 4, 1]/16` (the B3 spline), `d = max(|dx|, |dy|)`, `l` the Rec. 709
//! luminance, and the variance filtered alongside with the squared weights
//! (`var' = Σw²·var_q / (Σw)²`), so later iterations stop at smaller luminance edges. The
//! centre tap's weight is `h(0)²`; a mean that rounds above [`VALUE_MAX`] is clamped to it. Pixels
//! that are no surface (the sky) keep their colour.
//!
//! **Exactness.** The exponential is a short polynomial with exact range reduction ([`exp_neg`]),
//! the same operations in the same order in both bodies, so the SIMD body equals the scalar
//! reference bit for bit. Exponents are capped at [`EXPONENT_MAX`], normal terms below
//! [`NORMAL_MIN_COS`] and weights below [`WEIGHT_MIN`] are 0 (no denormals in the sums).
//!
//! The SIMD body filters eight pixels of a row at a time where every tap is inside the frame;
//! pixels nearer the borders go through the scalar reference. Rows run in parallel bands,
//! iterations one after the other (each reads the last one's whole image).

mod scalar;
mod simd;

use crate::bands::{SharedRows, for_each_band};
use crate::frame::{Extent, FrameError, Plane, PlaneBuf, RgbBuf, RgbPlanes, RgbPlanesMut, same_extent};

/// The B3-spline taps, `[1, 4, 6, 4, 1] / 16` (dyadic: their products are exact).
pub const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Colour values are clamped to [0, `VALUE_MAX`] on entry: a firefly's squared luminance
/// (the variance) still sums without overflowing.
pub const VALUE_MAX: f32 = 1e18;

/// The largest edge-stopping exponent: `exp(−40)` is far below [`WEIGHT_MIN`] for any tap.
pub const EXPONENT_MAX: f32 = 40.0;

/// Normals whose cosine is below this weigh 0 (`0.8^128 ≈ 4e-13`; keeps the power normal).
pub const NORMAL_MIN_COS: f32 = 0.8;

/// Weights below this are 0.
pub const WEIGHT_MIN: f32 = 1e-10;

/// The most iterations (the last step, `2^(n−1)` pixels, spans 2·512 pixels either side).
pub const MAX_ITERATIONS: u32 = 10;

/// `ε_l`: keeps the luminance term finite where the variance is 0.
const LUMINANCE_EPSILON: f32 = 1e-10;

/// `ε_z`: a relative depth difference the depth term tolerates on a surface whose slope is
/// 0 (float noise of a plane facing the camera).
const DEPTH_EPSILON: f32 = 1e-4;

/// How the filter weighs its taps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtrousParams {
    /// Passes, each with twice the last one's step (SVGF: 5). 0 copies the clamped input.
    pub iterations: u32,
    /// `σ_l`, luminance differences in standard deviations (SVGF: 4). Finite and > 0.
    pub sigma_luminance: f32,
    /// `σ_z`, depth differences in units of the local depth slope (SVGF: 1). Finite and > 0.
    pub sigma_depth: f32,
    /// Rows per parallel band.
    pub band_rows: usize,
}

impl Default for AtrousParams {
    /// SVGF's settings.
    fn default() -> Self {
        Self { iterations: 5, sigma_luminance: 4.0, sigma_depth: 1.0, band_rows: 16 }
    }
}

/// The G-buffer's normals, as the pipeline's two layouts store them.
#[derive(Clone, Copy)]
pub enum GuideNormals<'a> {
    /// Octahedral, `gbuffer::encode_normal` (`NO_NORMAL` where there is no surface).
    Octahedral(Plane<'a, u32>),
    /// Unit normals x, y, z (NaN where there is no surface).
    Planes([Plane<'a>; 3]),
}

/// What guides the filter's edges.
#[derive(Clone, Copy)]
pub struct AtrousGuide<'a> {
    /// View-axis depth; a pixel is a surface where it is in (0, ∞).
    pub depth: Plane<'a>,
    /// Shading normals.
    pub normals: GuideNormals<'a>,
}

/// The planes a filter call works in, allocated once (no allocation per frame).
#[derive(Clone, Debug)]
pub struct AtrousScratch {
    normal: [PlaneBuf; 3],
    slope: PlaneBuf,
    variance: [PlaneBuf; 2],
    colour: RgbBuf,
}

impl AtrousScratch {
    /// Scratch planes for frames of `extent`, or [`FrameError::OutOfMemory`].
    pub fn try_new(extent: Extent) -> Result<Self, FrameError> {
        let plane = || PlaneBuf::try_new(extent, 0.0);
        Ok(Self {
            normal: [plane()?, plane()?, plane()?],
            slope: plane()?,
            variance: [plane()?, plane()?],
            colour: RgbBuf::try_new(extent, 0.0)?,
        })
    }

    /// The extent it was made for.
    pub fn extent(&self) -> Extent {
        self.slope.extent()
    }

    /// The luminance variance the last iteration left (after a call; the pre-pass's with 0
    /// iterations).
    pub fn variance(&self, iterations: u32) -> &PlaneBuf {
        &self.variance[variance_written_by(iterations)]
    }
}

/// Which of the two variance buffers holds the variance after `iterations` passes: the
/// pre-pass writes buffer 0, and pass `i` reads buffer `i % 2` and writes the other.
fn variance_written_by(iterations: u32) -> usize {
    iterations as usize % 2
}

/// What a filter call saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AtrousStats {
    /// Colour values outside [0, [`VALUE_MAX`]] (NaN, ±∞, negative, huge) that were clamped.
    pub out_of_range: u64,
}

impl AtrousStats {
    fn merged(self, o: Self) -> Self {
        Self { out_of_range: self.out_of_range + o.out_of_range }
    }
}

/// `exp(−x)` for `x` in [0, [`EXPONENT_MAX`]]: `2^(−t)`, `t = x·log₂e`, split into an exact
/// power of two `2^(−n)` (`n` the nearest integer) and `e^(−u)`, `u = (t − n)·ln 2` in
/// [−0.35, 0.35], by its degree-5 Taylor polynomial in Estrin's form (relative error below
/// 5e-6: a weight's shape, not a value anyone reads; Estrin's form keeps the dependency chain
/// short, which is what the filter waits on). Scalar twin of the SIMD body's.
#[inline(always)]
pub fn exp_neg(x: f32) -> f32 {
    let t = x * core::f32::consts::LOG2_E;
    let n = t.round_ties_even();
    let u = (t - n) * core::f32::consts::LN_2;
    let [c0, c1, c2, c3, c4, c5] = EXP_TAYLOR;
    let u2 = u * u;
    let p = (c0 + c1 * u) + u2 * ((c2 + c3 * u) + u2 * (c4 + c5 * u));
    p * f32::from_bits(((127 - n as i32) as u32) << 23)
}

/// `(−1)^k / k!`, k = 0..=5: the Taylor coefficients of `e^(−u)`.
pub(crate) const EXP_TAYLOR: [f32; 6] = [1.0, -1.0, 1.0 / 2.0, -1.0 / 6.0, 1.0 / 24.0, -1.0 / 120.0];

fn check(
    input: &RgbPlanes<'_>,
    guide: &AtrousGuide<'_>,
    params: &AtrousParams,
    scratch: &AtrousScratch,
    out: &RgbPlanesMut<'_>,
) -> Result<(), FrameError> {
    let extent = out.extent();
    same_extent("à-trous input image", extent, input.extent())?;
    same_extent("à-trous depth plane", extent, guide.depth.extent())?;
    match &guide.normals {
        GuideNormals::Octahedral(n) => same_extent("à-trous normal plane", extent, n.extent())?,
        GuideNormals::Planes(n) => {
            for p in n {
                same_extent("à-trous normal plane", extent, p.extent())?;
            }
        }
    }
    same_extent("à-trous scratch planes", extent, scratch.extent())?;
    if params.iterations > MAX_ITERATIONS {
        return Err(FrameError::InvalidParameter("à-trous iterations must be at most 10"));
    }
    let positive = |v: f32| v.is_finite() && v > 0.0;
    if !(positive(params.sigma_luminance) && positive(params.sigma_depth)) {
        return Err(FrameError::InvalidParameter("à-trous sigmas must be finite and > 0"));
    }
    Ok(())
}

/// One body's two passes: the pre-pass over a row, and an iteration over a row.
pub(crate) trait Body: Sync {
    fn prepass_row(pre: &Prepass<'_>, y: usize, out: &mut PrepassRow<'_>) -> AtrousStats;
    fn filter_row(src: &Source<'_>, y: usize, step: usize, out: &mut FilterRow<'_>);
}

/// The pre-pass's inputs.
pub(crate) struct Prepass<'a> {
    pub input: RgbPlanes<'a>,
    pub depth: Plane<'a>,
    pub normals: GuideNormals<'a>,
}

/// One row of the pre-pass's outputs.
pub(crate) struct PrepassRow<'r> {
    pub colour: [&'r mut [f32]; 3],
    pub normal: [&'r mut [f32]; 3],
    pub slope: &'r mut [f32],
    pub variance: &'r mut [f32],
}

/// What an iteration reads.
pub(crate) struct Source<'a> {
    pub colour: [Plane<'a>; 3],
    pub variance: Plane<'a>,
    pub depth: Plane<'a>,
    pub normal: [Plane<'a>; 3],
    pub slope: Plane<'a>,
    pub sigma_luminance: f32,
    pub sigma_depth: f32,
}

/// One row of an iteration's outputs.
pub(crate) struct FilterRow<'r> {
    pub colour: [&'r mut [f32]; 3],
    pub variance: &'r mut [f32],
}

/// Scalar reference of [`atrous`].
pub fn atrous_scalar(
    input: &RgbPlanes<'_>,
    guide: &AtrousGuide<'_>,
    params: &AtrousParams,
    scratch: &mut AtrousScratch,
    out: RgbPlanesMut<'_>,
) -> Result<AtrousStats, FrameError> {
    check(input, guide, params, scratch, &out)?;
    Ok(run::<scalar::Scalar>(input, guide, params, scratch, out))
}

/// The edge-avoiding à-trous filter of `input` into `out` (module notes); SIMD,
/// bit-identical to [`atrous_scalar`]. `scratch` must be of the frame's extent. Refuses
/// planes of the wrong size, more than [`MAX_ITERATIONS`] and sigmas that are not finite and
/// positive; any colour, depth and normal is accepted.
///
/// ```
/// use stereotrace_kernels::atrous::{self, AtrousGuide, AtrousParams, AtrousScratch, GuideNormals};
/// use stereotrace_kernels::{Extent, PlaneBuf, RgbBuf};
///
/// let extent = Extent::new(16, 16)?;
/// let mut noisy = RgbBuf::new(extent, 0.5);
/// noisy.r_mut()[8 * 16 + 8] = 8.0; // a firefly on a flat wall
/// let depth = PlaneBuf::new(extent, 2.0);
/// let [nx, ny, nz] = [0.0, 0.0, 1.0].map(|v| PlaneBuf::new(extent, v));
/// let guide = AtrousGuide {
///     depth: depth.view(),
///     normals: GuideNormals::Planes([nx.view(), ny.view(), nz.view()]),
/// };
/// let mut scratch = AtrousScratch::try_new(extent)?;
/// let mut out = RgbBuf::new(extent, 0.0);
/// atrous::atrous(&noisy.view(), &guide, &AtrousParams::default(), &mut scratch, out.view_mut())?;
/// assert!(out.r().view().get(8, 8) < 4.0); // spread over its neighbours
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn atrous(
    input: &RgbPlanes<'_>,
    guide: &AtrousGuide<'_>,
    params: &AtrousParams,
    scratch: &mut AtrousScratch,
    mut out: RgbPlanesMut<'_>,
) -> Result<AtrousStats, FrameError> {
    check(input, guide, params, scratch, &out)?;
    let stats = run::<simd::Simd>(input, guide, params, scratch, out.reborrow());
    #[cfg(feature = "check-scalar")]
    {
        let mut reference_scratch = AtrousScratch::try_new(out.extent()).expect("scratch");
        let mut reference = RgbBuf::new(out.extent(), 0.0);
        let expected =
            atrous_scalar(input, guide, params, &mut reference_scratch, reference.view_mut()).expect("validated input");
        assert_eq!(stats, expected, "à-trous stats differ");
        let simd = out.as_planes().channels();
        for (c, plane) in reference.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("à-trous colour", c, &simd[c], plane);
        }
    }
    Ok(stats)
}

/// The pre-pass into the colour buffer the iterations start from (chosen so that the last
/// iteration writes `out`), then the iterations, ping-ponging.
fn run<B: Body>(
    input: &RgbPlanes<'_>,
    guide: &AtrousGuide<'_>,
    params: &AtrousParams,
    scratch: &mut AtrousScratch,
    mut out: RgbPlanesMut<'_>,
) -> AtrousStats {
    let AtrousScratch { normal, slope, variance, colour } = scratch;
    let [variance_a, variance_b] = variance;
    let band_rows = params.band_rows.max(1);
    let height = out.extent().height();
    // Iteration i writes buffer (i + 1) % 2; buffer n % 2 must be `out`.
    let out_is_first = params.iterations.is_multiple_of(2);
    let pre = Prepass { input: *input, depth: guide.depth, normals: guide.normals };
    let stats = {
        let colour_rows =
            if out_is_first { out.reborrow() } else { colour.view_mut() }.into_channels().map(SharedRows::new);
        let normal_rows = normal.each_mut().map(|n| SharedRows::new(n.view_mut()));
        let (slope_rows, variance_rows) = (SharedRows::new(slope.view_mut()), SharedRows::new(variance_a.view_mut()));
        for_each_band(
            height,
            band_rows,
            |rows| {
                let mut stats = AtrousStats::default();
                for y in rows {
                    // SAFETY: `for_each_band` hands each row to exactly one band.
                    let mut row = unsafe {
                        PrepassRow {
                            colour: [0, 1, 2].map(|c| colour_rows[c].row(y)),
                            normal: [0, 1, 2].map(|c| normal_rows[c].row(y)),
                            slope: slope_rows.row(y),
                            variance: variance_rows.row(y),
                        }
                    };
                    stats = stats.merged(B::prepass_row(&pre, y, &mut row));
                }
                stats
            },
            AtrousStats::merged,
        )
    };
    for i in 0..params.iterations {
        let writes_out = (i + 1) % 2 == params.iterations % 2;
        let (variance_src, variance_dst) = if variance_written_by(i) == 0 {
            (&*variance_a, &mut *variance_b)
        } else {
            (&*variance_b, &mut *variance_a)
        };
        let (colour_src, colour_dst) = if writes_out {
            (colour.view().channels(), out.reborrow())
        } else {
            (out.as_planes().channels(), colour.view_mut())
        };
        let src = Source {
            colour: colour_src,
            variance: variance_src.view(),
            depth: guide.depth,
            normal: normal.each_ref().map(|n| n.view()),
            slope: slope.view(),
            sigma_luminance: params.sigma_luminance,
            sigma_depth: params.sigma_depth,
        };
        let colour_rows = colour_dst.into_channels().map(SharedRows::new);
        let variance_rows = SharedRows::new(variance_dst.view_mut());
        let step = 1usize << i;
        for_each_band(
            height,
            band_rows,
            |rows| {
                for y in rows {
                    // SAFETY: `for_each_band` hands each row to exactly one band.
                    let mut row = unsafe {
                        FilterRow { colour: [0, 1, 2].map(|c| colour_rows[c].row(y)), variance: variance_rows.row(y) }
                    };
                    B::filter_row(&src, y, step, &mut row);
                }
            },
            |(), ()| (),
        );
    }
    stats
}

//! Temporal gradients: how far a pixel's history can still be trusted after the lighting
//! changed (after A-SVGF, Schied et al. 2018, the paper's reference \[14\]).
//!
//! Reprojection sees only geometry, so an EMA history keeps the old lighting for about
//! 1/α frames after a light moves or switches off. A temporal gradient measures the change
//! directly: in each 3×3 stratum of pixels the caller re-shades one sample of the last frame
//! with the last frame's random numbers under this frame's lights and geometry, so the
//! difference between the re-shaded and the old luminance is the change of the lighting,
//! free of the samples' noise. This kernel turns those pairs into a per-pixel history
//! confidence for [`crate::accumulate::EmaInput::confidence`]:
//!
//! - per stratum, the signed change `d = new − old` and `m = max(new, old)`, luminances
//!   clamped to [0, [`LUMA_MAX`]]; a stratum without a pair (NaN in either plane) gives
//!   `d = m = 0`;
//! - per stratum, the change `λ = min(1, gain·|Σd|/Σm)` over its 3×3 neighbourhood of
//!   strata (9×9 pixels). The differences are summed with their signs, as A-SVGF filters
//!   them: one pair is one path, and when a light moves, some paths' shadow rays go dark and
//!   others light up, changes that cancel in the mean the history holds; a light switched off
//!   or a shadow sweeping in darkens all of them alike. `λ = 0` where `Σm = 0`. A-SVGF's gain
//!   is 1; `|d| ≤ m`, so `λ` is in [0, 1] whatever the gain;
//! - per pixel, `confidence = prior · (1 − λ)` of its stratum, with `prior` the engine's
//!   own confidence where given (1 otherwise).
//!
//! With the EMA's rule `α' = α + (1 − α)·(1 − c)` this is A-SVGF's `α' = (1 − λ)·α + λ`: a
//! light switched off (`new = 0`) gives `λ = 1` and the history restarts; unchanged
//! lighting gives `λ = 0` and the plain EMA.
//!
//! The SIMD body works on eight strata of a row at a time (the same sums in the same order
//! as the scalar reference, so the two agree bit for bit); strata at the row ends and the
//! tail go through the scalar reference. Rows of strata run in parallel bands.

mod scalar;
mod simd;

use crate::bands::{SharedRows, for_each_band};
use crate::frame::{Extent, FrameError, Plane, PlaneMut, same_extent};

/// Pixels per side of a stratum (A-SVGF's 3×3).
pub const STRATUM: usize = 3;

/// The largest luminance a pair counts with: above it, values are clamped, so nine of them
/// sum without overflowing (a firefly still gives a bounded `λ`).
pub const LUMA_MAX: f32 = 1e30;

/// The strata grid of a frame of `extent`: `⌈w/3⌉ × ⌈h/3⌉` (the last column and row of
/// strata may be narrower).
pub fn strata_extent(extent: Extent) -> Extent {
    Extent::new(extent.width().div_ceil(STRATUM), extent.height().div_ceil(STRATUM))
        .expect("a frame's strata grid is a valid extent")
}

/// The inputs: one luminance pair per stratum, and the engine's own confidence.
#[derive(Clone, Copy)]
pub struct GradientInput<'a> {
    /// Last frame's luminance of each stratum's gradient sample ([`strata_extent`]); NaN
    /// where the stratum has none.
    pub old: Plane<'a>,
    /// The same sample re-shaded under this frame's lights; NaN where there is none.
    pub new: Plane<'a>,
    /// Optional per-pixel confidence in [0, 1] the result is multiplied by (an engine's own
    /// history confidence); absent: 1.
    pub prior: Option<Plane<'a>>,
    /// How strongly a relative change shortens the history: `λ = min(1, gain·Σd/Σm)`
    /// (A-SVGF's is 1). Finite and ≥ 0, else refused.
    pub gain: f32,
}

/// What a gradient pass saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GradientStats {
    /// Strata with a gradient sample.
    pub samples: u64,
    /// Strata whose change `λ` is above zero (the history is shortened there).
    pub changed: u64,
}

impl GradientStats {
    fn merged(self, o: Self) -> Self {
        Self { samples: self.samples + o.samples, changed: self.changed + o.changed }
    }
}

/// Strata rows per parallel band.
const BAND_STRATA_ROWS: usize = 8;

fn check(input: &GradientInput<'_>, out: &PlaneMut<'_>) -> Result<(), FrameError> {
    let strata = strata_extent(out.extent());
    same_extent("gradient strata (old luminance)", strata, input.old.extent())?;
    same_extent("gradient strata (new luminance)", strata, input.new.extent())?;
    if !(input.gain.is_finite() && input.gain >= 0.0) {
        return Err(FrameError::InvalidParameter("the gradient gain must be finite and >= 0"));
    }
    if let Some(prior) = &input.prior {
        same_extent("prior history confidence plane", out.extent(), prior.extent())?;
        crate::accumulate::check_unit_interval("prior history confidence plane", prior)?;
    }
    Ok(())
}

/// Scalar reference of [`history_confidence`].
pub fn history_confidence_scalar(input: &GradientInput<'_>, out: PlaneMut<'_>) -> Result<GradientStats, FrameError> {
    check(input, &out)?;
    Ok(run(input, out, |input, sy, row_out| scalar::strata_row(input, sy, 0..input.old.width(), row_out)))
}

/// The per-pixel history confidence from the strata's luminance pairs (module notes); SIMD,
/// bit-identical to [`history_confidence_scalar`]. Refuses planes of the wrong size and a
/// prior outside [0, 1]; any luminance is accepted (NaN marks a stratum without a sample).
///
/// ```
/// use stereotrace_kernels::gradient::{self, GradientInput};
/// use stereotrace_kernels::{Extent, PlaneBuf};
///
/// let extent = Extent::new(12, 9)?;
/// let strata = gradient::strata_extent(extent); // 4 × 3
/// let old = PlaneBuf::new(strata, 1.0);
/// let mut new = PlaneBuf::new(strata, 1.0);
/// new.view_mut().row_mut(1)[0] = 0.0; // a light went out over one stratum
/// let mut confidence = PlaneBuf::new(extent, 0.0);
/// let input = GradientInput { old: old.view(), new: new.view(), prior: None, gain: 1.0 };
/// gradient::history_confidence(&input, confidence.view_mut())?;
/// assert_eq!(confidence.view().get(11, 0), 1.0); // nothing changed in its neighbourhood
/// assert!(confidence.view().get(1, 4) < 1.0); // its neighbourhood lost light
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn history_confidence(input: &GradientInput<'_>, mut out: PlaneMut<'_>) -> Result<GradientStats, FrameError> {
    check(input, &out)?;
    let stats = run(input, out.reborrow(), simd::strata_row);
    #[cfg(feature = "check-scalar")]
    {
        let mut reference = crate::frame::PlaneBuf::new(out.extent(), 0.0f32);
        let expected = history_confidence_scalar(input, reference.view_mut()).expect("validated input");
        assert_eq!(stats, expected, "gradient stats differ");
        crate::check::assert_planes_equal("history confidence", 0, &out.as_plane(), &reference.view());
    }
    Ok(stats)
}

/// The rows of pixels of one row of strata, and the prior's rows beside them.
pub(crate) struct StrataRowOut<'r> {
    rows: [Option<&'r mut [f32]>; STRATUM],
    prior: [Option<&'r [f32]>; STRATUM],
}

impl StrataRowOut<'_> {
    /// Writes stratum `sx`'s confidence `c` to its pixels (times the prior's).
    #[inline(always)]
    pub(crate) fn write(&mut self, sx: usize, c: f32) {
        for (row, prior) in self.rows.iter_mut().zip(&self.prior) {
            let Some(row) = row else { continue };
            let span = sx * STRATUM..((sx + 1) * STRATUM).min(row.len());
            match prior {
                Some(p) => row[span.clone()].iter_mut().zip(&p[span]).for_each(|(o, &p)| *o = p * c),
                None => row[span].fill(c),
            }
        }
    }

    /// Writes the confidences of the eight whole strata from `sx` (each three pixels wide):
    /// 24 pixels a row in one copy, where [`StrataRowOut::write`] would make eight.
    #[inline(always)]
    pub(crate) fn write8(&mut self, sx: usize, c: [f32; 8]) {
        let spread: [f32; 8 * STRATUM] = core::array::from_fn(|i| c[i / STRATUM]);
        let span = sx * STRATUM..(sx + 8) * STRATUM;
        for (row, prior) in self.rows.iter_mut().zip(&self.prior) {
            let Some(row) = row else { continue };
            match prior {
                Some(p) => {
                    row[span.clone()].iter_mut().zip(&p[span.clone()]).zip(spread).for_each(|((o, &p), c)| *o = p * c)
                }
                None => row[span.clone()].copy_from_slice(&spread),
            }
        }
    }
}

/// The confidence `1 − λ` of one stratum from its neighbourhood sums (signed changes,
/// maxima).
#[inline(always)]
pub(crate) fn confidence_of(sum_d: f32, sum_m: f32, gain: f32) -> f32 {
    let lambda = if sum_m > 0.0 { ((sum_d.abs() / sum_m) * gain).min(1.0) } else { 0.0 };
    1.0 - lambda
}

/// Runs `strata_row(input, sy, out)` over every row of strata in parallel bands;
/// the body counts its own strata.
fn run<F>(input: &GradientInput<'_>, out: PlaneMut<'_>, strata_row: F) -> GradientStats
where
    F: Fn(&GradientInput<'_>, usize, &mut StrataRowOut<'_>) -> GradientStats + Sync,
{
    let height = out.height();
    let strata_rows = input.old.height();
    let rows = SharedRows::new(out);
    for_each_band(
        strata_rows,
        BAND_STRATA_ROWS,
        |band| {
            let mut stats = GradientStats::default();
            for sy in band {
                let pixel_row = |i: usize| {
                    let y = sy * STRATUM + i;
                    // SAFETY: strata row `sy` owns pixel rows 3·sy .. 3·sy + 3 alone, and each
                    // band holds distinct strata rows.
                    (y < height).then(|| unsafe { rows.row(y) })
                };
                let prior_row = |i: usize| {
                    let y = sy * STRATUM + i;
                    input.prior.as_ref().filter(|_| y < height).map(|p| p.row(y))
                };
                let mut row_out = StrataRowOut {
                    rows: [pixel_row(0), pixel_row(1), pixel_row(2)],
                    prior: [prior_row(0), prior_row(1), prior_row(2)],
                };
                stats = stats.merged(strata_row(input, sy, &mut row_out));
            }
            stats
        },
        GradientStats::merged,
    )
}

//! Neighbourhood clamp of a reprojected history (TAA's variance clipping, Salvi 2016; FSR2
//! clamps the same way): where a history disagrees with what this frame's samples around
//! the pixel allow, it is pulled into their range before the EMA.
//!
//! Reprojection keeps a history wherever the geometry matches, so a light that moved or a
//! shadow that swept in leaves the old colour behind for about 1/α frames. TAA's answer is to
//! trust the history only as far as this frame's neighbourhood says the colour can be. Per
//! pixel and channel, over the pixel's 3×3 neighbourhood of *new samples* (inside the frame,
//! with a sample this frame, every channel finite):
//!
//! - `n` samples, mean `μ = Σv/n`, variance `σ² = Σv²/n − μ²`, minimum and maximum;
//! - the box `[μ − γσ, μ + γσ]`, each end clamped into `[min, max]`: the variance box, never
//!   beyond what was observed (so a constant neighbourhood gives exactly its constant, and
//!   the box is the min–max one where `σ²` overflows);
//! - the history clamped into the box, where the history is valid (the reason code is
//!   `Reprojected`), finite, the pixel itself has a new sample, and `n ≥ min_samples`.
//!   Elsewhere the history is left as it is.
//!
//! At 1 spp the neighbourhood is nine single paths. Where the light transport is
//! heavy-tailed (most paths darker than their mean, a few much brighter) their box usually
//! sits below the true mean, and the clamp pulls a converged history down: the image is
//! biased dark. RESULTS.md measures both what it buys and that bias (`--history clamp`).
//!
//! The SIMD body works on eight pixels of a row at a time with the same sums in the same
//! order as the scalar reference (bit-identical); the first column, the last and the tail go
//! through the scalar reference. Rows run in parallel bands.

mod scalar;
mod simd;

use crate::bands::{SharedRows, for_each_band};
use crate::frame::{FrameError, Plane, RgbPlanes, RgbPlanesMut, same_extent};
use crate::reproject::check_reason_plane;

/// What the clamp reads.
#[derive(Clone, Copy)]
pub struct ClampInput<'a> {
    /// This frame's samples.
    pub new: RgbPlanes<'a>,
    /// Optional: non-zero where a new sample exists this frame (absent: everywhere).
    pub has_new: Option<Plane<'a, u8>>,
    /// Reason codes of the history's reprojection: only `Reprojected` pixels are clamped. A
    /// code outside the defined set is refused.
    pub reason: Plane<'a, u8>,
}

/// The clamp's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClampParams {
    /// Half-width of the box in standard deviations (Salvi's γ; finite and > 0).
    pub gamma: f32,
    /// The fewest neighbourhood samples (the pixel's own included) that make a box, 1–9:
    /// fewer leave the history alone.
    pub min_samples: u32,
    /// Rows per parallel band.
    pub band_rows: usize,
}

impl Default for ClampParams {
    /// γ = 1 (Salvi's), at least four samples (a frame corner's whole neighbourhood).
    fn default() -> Self {
        Self { gamma: 1.0, min_samples: 4, band_rows: 16 }
    }
}

/// What a clamp pass saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClampStats {
    /// Pixels whose history was checked against a box.
    pub checked: u64,
    /// Pixels whose history moved (some channel was outside its box).
    pub clamped: u64,
}

impl ClampStats {
    fn merged(self, o: Self) -> Self {
        Self { checked: self.checked + o.checked, clamped: self.clamped + o.clamped }
    }
}

fn check(input: &ClampInput<'_>, history: &RgbPlanesMut<'_>, params: &ClampParams) -> Result<(), FrameError> {
    if !(params.gamma.is_finite() && params.gamma > 0.0) {
        return Err(FrameError::InvalidParameter("the clamp's gamma must be finite and > 0"));
    }
    if !(1..=9).contains(&params.min_samples) {
        return Err(FrameError::InvalidParameter("the clamp's min_samples must be 1 to 9"));
    }
    let e = history.extent();
    same_extent("new samples", e, input.new.extent())?;
    same_extent("reason plane", e, input.reason.extent())?;
    if let Some(h) = &input.has_new {
        same_extent("new-sample mask", e, h.extent())?;
    }
    check_reason_plane("reason plane", &input.reason)
}

/// Scalar reference of [`clamp_history`].
pub fn clamp_history_scalar(
    input: &ClampInput<'_>,
    history: RgbPlanesMut<'_>,
    params: &ClampParams,
) -> Result<ClampStats, FrameError> {
    check(input, &history, params)?;
    Ok(run(input, history, params, |input, params, y, row| scalar::clamp_row(input, params, y, 0..row[0].len(), row)))
}

/// Clamps the reprojected `history` into this frame's neighbourhood boxes (module notes);
/// SIMD, bit-identical to [`clamp_history_scalar`]. Refuses planes of different sizes, a
/// reason code outside the defined set and parameters out of range; any sample value is
/// accepted (a non-finite one is not a sample).
///
/// ```
/// use stereotrace_kernels::clamp::{self, ClampInput, ClampParams};
/// use stereotrace_kernels::reproject::Reason;
/// use stereotrace_kernels::{Extent, PlaneBuf, RgbBuf};
///
/// let extent = Extent::new(16, 4)?;
/// let mut history = RgbBuf::new(extent, 1.0); // the old light
/// let samples = RgbBuf::new(extent, 0.25); // this frame: darker everywhere
/// let valid = PlaneBuf::new(extent, Reason::Reprojected as u8);
/// let input = ClampInput { new: samples.view(), has_new: None, reason: valid.view() };
/// let stats = clamp::clamp_history(&input, history.view_mut(), &ClampParams::default())?;
/// assert_eq!(history.get(5, 2), [0.25; 3]); // a constant neighbourhood's box is its value
/// assert_eq!(stats.clamped, 64);
/// # Ok::<(), stereotrace_kernels::FrameError>(())
/// ```
pub fn clamp_history(
    input: &ClampInput<'_>,
    mut history: RgbPlanesMut<'_>,
    params: &ClampParams,
) -> Result<ClampStats, FrameError> {
    check(input, &history, params)?;
    #[cfg(feature = "check-scalar")]
    let before = crate::check::rgb_copy(&history.as_planes());
    let stats = run(input, history.reborrow(), params, simd::clamp_row);
    #[cfg(feature = "check-scalar")]
    {
        let mut reference = before;
        let expected = clamp_history_scalar(input, reference.view_mut(), params).expect("validated input");
        assert_eq!(stats, expected, "clamp stats differ");
        let simd = history.as_planes().channels();
        for (c, plane) in reference.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("clamped history", c, &simd[c], plane);
        }
    }
    Ok(stats)
}

/// One row of the history's three channels.
pub(crate) type HistoryRow<'r> = [&'r mut [f32]; 3];

/// Runs `row_body(input, params, y, row)` over every row in parallel bands.
fn run<F>(input: &ClampInput<'_>, history: RgbPlanesMut<'_>, params: &ClampParams, row_body: F) -> ClampStats
where
    F: for<'r> Fn(&ClampInput<'_>, &ClampParams, usize, &mut HistoryRow<'r>) -> ClampStats + Sync,
{
    let height = history.extent().height();
    let channels = history.into_channels().map(SharedRows::new);
    for_each_band(
        height,
        params.band_rows,
        |rows| {
            let mut stats = ClampStats::default();
            for y in rows {
                // SAFETY: `for_each_band` hands each row to exactly one band.
                let mut row = [0, 1, 2].map(|c| unsafe { channels[c].row(y) });
                stats = stats.merged(row_body(input, params, y, &mut row));
            }
            stats
        },
        ClampStats::merged,
    )
}

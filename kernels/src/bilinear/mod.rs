//! Bilinear resampling: footprints, weights and the four-tap gather, with a per-tap accept
//! mask and renormalisation over the accepted taps.
//!
//! Conventions. Positions are continuous pixel coordinates: pixel `(i, j)` covers
//! `[i, i+1) × [j, j+1)` and has its centre at `(i + 0.5, j + 0.5)`. A position `(sx, sy)`
//! has the footprint `x0 = floor(sx − 0.5)`, `y0 = floor(sy − 0.5)`, `fx = sx − 0.5 − x0`,
//! `fy = sy − 0.5 − y0` and the taps
//!
//! | tap | pixel | weight |
//! |---|---|---|
//! | 0 | `(x0, y0)` | `(1−fx)(1−fy)` |
//! | 1 | `(x0+1, y0)` | `fx(1−fy)` |
//! | 2 | `(x0, y0+1)` | `(1−fx)fy` |
//! | 3 | `(x0+1, y0+1)` | `fx·fy` |
//!
//! Two numerical policies make exact cases exact:
//! * **Snapping.** A fractional offset within [`SNAP`] (1/1024 px) of a pixel centre is
//!   snapped to it. A camera that maps pixel centres onto pixel centres (identity, or an
//!   integer shift) then copies pixels exactly instead of mixing in 10⁻⁴ of a neighbour, which
//!   f32 projection rounding would otherwise cause (one ulp at x = 1280 is 1.2·10⁻⁴ px).
//!   The largest change snapping makes to a weight is 1/1024.
//! * **Zero-weight taps take no part.** A tap whose weight is exactly 0 is neither accepted
//!   nor counted as failing, and its value is never multiplied (so an infinite value under a
//!   zero weight cannot turn into NaN).
//!
//! Renormalisation: `value = Σ_accepted wᵢ·vᵢ · (1 / Σ_accepted wᵢ)`. The sum runs over the taps in
//! the order 0‥3 in both the scalar reference and the SIMD body, so they agree bit for bit.
//! Results are clamped to ±`f32::MAX`: finite inputs never give an infinite output.
//!
//! The whole-image kernel [`resample`] warps an RGB image by a coordinate map; it is what the
//! bilinear bench measures and the fuzz target exercises. Reprojection uses the same
//! footprint functions.
//!
//! Tail strategy: rows are processed `LANES` pixels at a time; the remaining `width % LANES`
//! pixels go through the scalar reference, which gives identical results.

mod scalar;
mod simd;

use crate::bands::{SharedRows, for_each_band};
use crate::frame::{Extent, FrameError, Plane, PlaneMut, RgbPlanes, RgbPlanesMut, same_extent};
use crate::simd::{F32s, LANES, clamp_finite, clamp_finite1, lane_offsets};
pub use scalar::resample_pixel;

/// Fractional offsets closer than this to a pixel centre snap to it.
pub const SNAP: f32 = 1.0 / 1024.0;

/// Rows per parallel band. 16 rows of 1280 f32 pixels keep a band's source rows (about
/// 17 rows × 1280 px × 16 B ≈ 350 KB) in one core's L2.
pub const DEFAULT_BAND_ROWS: usize = 16;

/// The four taps around one position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Column of the top-left tap (may be −1: left of the frame).
    pub x0: i32,
    /// Row of the top-left tap (may be −1: above the frame).
    pub y0: i32,
    /// Horizontal offset from the top-left tap, in [0, 1) (snapped near 0).
    pub fx: f32,
    /// Vertical offset from the top-left tap, in [0, 1) (snapped near 0).
    pub fy: f32,
}

impl Footprint {
    /// The footprint of continuous position `(sx, sy)` in a frame of `extent`, or `None`
    /// when the position is not finite or so far outside that no tap can be in frame.
    #[inline]
    pub fn new(sx: f32, sy: f32, extent: Extent) -> Option<Self> {
        let (u, v) = (sx - 0.5, sy - 0.5);
        let (w, h) = (extent.width() as f32, extent.height() as f32);
        // Written so that NaN fails: at least one tap column/row can be in frame only if
        // -1 <= u < width (and likewise for v).
        if !(u >= -1.0 && u < w && v >= -1.0 && v < h) {
            return None;
        }
        let (x0, fx) = snap(u);
        let (y0, fy) = snap(v);
        Some(Self { x0: x0 as i32, y0: y0 as i32, fx, fy })
    }

    /// Tap weights in tap order.
    #[inline]
    pub fn weights(&self) -> [f32; 4] {
        let (fx, fy) = (self.fx, self.fy);
        [(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy]
    }

    /// Tap pixel coordinates in tap order (may lie outside the frame).
    #[inline]
    pub fn taps(&self) -> [(i32, i32); 4] {
        let (x, y) = (self.x0, self.y0);
        [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]
    }

    /// Whether each tap lies inside `extent`.
    #[inline]
    pub fn in_frame(&self, extent: Extent) -> [bool; 4] {
        let (w, h) = (extent.width() as i32, extent.height() as i32);
        self.taps().map(|(x, y)| x >= 0 && x < w && y >= 0 && y < h)
    }
}

/// Splits `u` into `floor(u)` and the fraction, snapping fractions within [`SNAP`] of 0 or 1.
#[inline(always)]
fn snap(u: f32) -> (f32, f32) {
    let base = u.floor();
    let f = u - base;
    if f < SNAP {
        (base, 0.0)
    } else if f > 1.0 - SNAP {
        (base + 1.0, 0.0)
    } else {
        (base, f)
    }
}

/// `LANES` footprints. Lanes where `inside` is clear hold `x0 = y0 = fx = fy = 0`.
#[derive(Clone, Copy, Debug)]
pub struct Footprints {
    /// Column of each lane's top-left tap (as f32).
    pub x0: F32s,
    /// Row of each lane's top-left tap (as f32).
    pub y0: F32s,
    /// Horizontal offsets, as [`Footprint::fx`].
    pub fx: F32s,
    /// Vertical offsets, as [`Footprint::fy`].
    pub fy: F32s,
    /// All-ones where a footprint exists (see [`Footprint::new`]).
    pub inside: F32s,
}

impl Footprints {
    /// SIMD twin of [`Footprint::new`].
    #[inline(always)]
    pub fn new(sx: F32s, sy: F32s, extent: Extent) -> Self {
        Self::new_splat(sx, sy, F32s::splat(extent.width() as f32), F32s::splat(extent.height() as f32))
    }

    /// [`Footprints::new`] with the extent's width and height already splatted (`w`, `h`).
    #[inline(always)]
    pub fn new_splat(sx: F32s, sy: F32s, w: F32s, h: F32s) -> Self {
        let half = F32s::splat(0.5);
        let (u, v) = (sx - half, sy - half);
        let minus_one = F32s::splat(-1.0);
        let inside = u.simd_ge(minus_one) & u.simd_lt(w) & v.simd_ge(minus_one) & v.simd_lt(h);
        let u = inside.select(u, F32s::ZERO);
        let v = inside.select(v, F32s::ZERO);
        let (x0, fx) = snap_simd(u);
        let (y0, fy) = snap_simd(v);
        Self { x0, y0, fx, fy, inside }
    }

    /// Tap weights in tap order (zero in lanes without a footprint).
    #[inline(always)]
    pub fn weights(&self) -> [F32s; 4] {
        let one = F32s::ONE;
        let (fx, fy) = (self.fx, self.fy);
        let w = [(one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy];
        w.map(|wi| self.inside.select(wi, F32s::ZERO))
    }

    /// Tap coordinates in tap order as float lanes.
    #[inline(always)]
    pub fn taps(&self) -> [(F32s, F32s); 4] {
        let one = F32s::ONE;
        let (x, y) = (self.x0, self.y0);
        [(x, y), (x + one, y), (x, y + one), (x + one, y + one)]
    }

    /// Per-tap in-frame masks (cleared in lanes without a footprint).
    #[inline(always)]
    pub fn in_frame(&self, extent: Extent) -> [F32s; 4] {
        let (w, h) = (F32s::splat(extent.width() as f32), F32s::splat(extent.height() as f32));
        self.taps()
            .map(|(x, y)| self.inside & x.simd_ge(F32s::ZERO) & x.simd_lt(w) & y.simd_ge(F32s::ZERO) & y.simd_lt(h))
    }
}

/// If every lane's footprint starts on the same source row at consecutive columns and all
/// lanes are `active`, with all four taps of all lanes inside the frame, returns the first
/// lane's `(x0, y0)`: the taps can then be loaded as contiguous rows (columns
/// `x0 ..= x0 + LANES`, rows `y0 ..= y0 + 1`).
#[inline(always)]
pub(crate) fn coherent_row(fp: &Footprints, active: F32s, extent: Extent) -> Option<(usize, usize)> {
    if !active.all() {
        return None;
    }
    let x_base = fp.x0 - lane_offsets();
    let x0 = x_base.to_array()[0];
    let y0 = fp.y0.to_array()[0];
    let same = x_base.simd_eq(F32s::splat(x0)) & fp.y0.simd_eq(F32s::splat(y0));
    let fits =
        x0 >= 0.0 && y0 >= 0.0 && x0 + (LANES as f32) < extent.width() as f32 && y0 + 1.0 < extent.height() as f32;
    (same.all() && fits).then_some((x0 as usize, y0 as usize))
}

#[inline(always)]
fn snap_simd(u: F32s) -> (F32s, F32s) {
    let base = u.floor();
    let f = u - base;
    let low = f.simd_lt(F32s::splat(SNAP));
    let high = f.simd_gt(F32s::splat(1.0 - SNAP));
    let base = high.select(base + F32s::ONE, base);
    let f = (low | high).select(F32s::ZERO, f);
    (base, f)
}

/// Renormalises an accumulated value: `sum · (1 / total)`, clamped to the finite range.
/// Callers compute `inv_total = 1 / total` once per pixel and scale every channel by it
/// (one division instead of one per channel; the result is within an ulp of `sum / total`
/// and exact when `total` is a power of two, e.g. 1).
#[inline(always)]
pub fn renormalise(sum: f32, inv_total: f32) -> f32 {
    clamp_finite1(sum * inv_total)
}

/// SIMD twin of [`renormalise`].
#[inline(always)]
pub fn renormalise_simd(sum: F32s, inv_total: F32s) -> F32s {
    clamp_finite(sum * inv_total)
}

/// Inputs of the whole-image resampling kernel.
#[derive(Clone, Copy)]
pub struct ResampleInput<'a> {
    /// The image to sample.
    pub source: RgbPlanes<'a>,
    /// Optional per-source-pixel accept mask: taps on pixels where it is 0 are rejected.
    pub source_valid: Option<Plane<'a, u8>>,
    /// Continuous x position to sample for each output pixel.
    pub map_x: Plane<'a>,
    /// Continuous y position to sample for each output pixel.
    pub map_y: Plane<'a>,
}

/// Outputs of the resampling kernel: the renormalised colour (0 where no tap was accepted)
/// and the accepted weight `Σ_accepted wᵢ` in [0, 1].
pub struct ResampleOutput<'a> {
    /// The resampled colour.
    pub colour: RgbPlanesMut<'a>,
    /// The accepted weight per pixel.
    pub weight: PlaneMut<'a>,
}

fn check_resample(input: &ResampleInput<'_>, out: &ResampleOutput<'_>) -> Result<(), FrameError> {
    let target = input.map_x.extent();
    same_extent("map_y", target, input.map_y.extent())?;
    same_extent("output colour", target, out.colour.extent())?;
    same_extent("output weight", target, out.weight.extent())?;
    if let Some(valid) = &input.source_valid {
        same_extent("source accept mask", input.source.extent(), valid.extent())?;
    }
    Ok(())
}

/// Scalar reference: resamples `input.source` at the mapped positions.
pub fn resample_scalar(input: &ResampleInput<'_>, out: ResampleOutput<'_>) -> Result<(), FrameError> {
    check_resample(input, &out)?;
    run_rows(input, out, DEFAULT_BAND_ROWS, |input, y, colour, weight| {
        for x in 0..weight.len() {
            let (rgb, w) = resample_pixel(input, x, y);
            for c in 0..3 {
                colour[c][x] = rgb[c];
            }
            weight[x] = w;
        }
    });
    Ok(())
}

/// SIMD body: resamples `input.source` at the mapped positions, bit-identical to
/// [`resample_scalar`].
pub fn resample(input: &ResampleInput<'_>, mut out: ResampleOutput<'_>) -> Result<(), FrameError> {
    check_resample(input, &out)?;
    run_rows(input, out.reborrow(), DEFAULT_BAND_ROWS, |input, y, colour, weight| {
        simd::resample_row(input, y, colour, weight)
    });
    #[cfg(feature = "check-scalar")]
    {
        let extent = out.weight.extent();
        let mut rgb = crate::frame::RgbBuf::new(extent, 0.0);
        let mut weight = crate::frame::PlaneBuf::new(extent, 0.0f32);
        resample_scalar(input, ResampleOutput { colour: rgb.view_mut(), weight: weight.view_mut() })?;
        let simd = out.colour.as_planes().channels();
        for (c, reference) in rgb.view().channels().iter().enumerate() {
            crate::check::assert_planes_equal("resample colour", c, &simd[c], reference);
        }
        crate::check::assert_planes_equal("resample weight", 0, &out.weight.as_plane(), &weight.view());
    }
    Ok(())
}

impl ResampleOutput<'_> {
    fn reborrow(&mut self) -> ResampleOutput<'_> {
        ResampleOutput { colour: self.colour.reborrow(), weight: self.weight.reborrow() }
    }
}

/// Runs `row` on every output row, in parallel bands.
fn run_rows<F>(input: &ResampleInput<'_>, out: ResampleOutput<'_>, band_rows: usize, row: F)
where
    F: Fn(&ResampleInput<'_>, usize, [&mut [f32]; 3], &mut [f32]) + Sync,
{
    let height = out.weight.height();
    let colour = out.colour.into_channels().map(SharedRows::new);
    let weight = SharedRows::new(out.weight);
    for_each_band(
        height,
        band_rows,
        |rows| {
            for y in rows {
                // SAFETY: `for_each_band` gives each row to one band only.
                let rgb = [0, 1, 2].map(|c| unsafe { colour[c].row(y) });
                // SAFETY: as above.
                row(input, y, rgb, unsafe { weight.row(y) });
            }
        },
        |(), ()| (),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ext(w: usize, h: usize) -> Extent {
        Extent::new(w, h).unwrap()
    }

    #[test]
    fn footprint_at_a_pixel_centre_is_one_tap() {
        let fp = Footprint::new(3.5, 2.5, ext(8, 8)).unwrap();
        assert_eq!((fp.x0, fp.y0, fp.fx, fp.fy), (3, 2, 0.0, 0.0));
        assert_eq!(fp.weights(), [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn footprint_between_centres_is_a_quarter_each() {
        let fp = Footprint::new(4.0, 3.0, ext(8, 8)).unwrap();
        assert_eq!((fp.x0, fp.y0), (3, 2));
        assert_eq!(fp.weights(), [0.25; 4]);
    }

    #[test]
    fn snapping_rounds_to_the_nearer_centre() {
        let fp = Footprint::new(3.5 + 1e-4, 2.5 - 1e-4, ext(8, 8)).unwrap();
        assert_eq!((fp.x0, fp.y0, fp.fx, fp.fy), (3, 2, 0.0, 0.0));
    }

    #[test]
    fn far_and_non_finite_positions_have_no_footprint() {
        let e = ext(4, 4);
        assert!(Footprint::new(f32::NAN, 1.0, e).is_none());
        assert!(Footprint::new(1.0, f32::INFINITY, e).is_none());
        assert!(Footprint::new(-0.6, 1.0, e).is_none());
        assert!(Footprint::new(4.5, 1.0, e).is_none());
        // Half a pixel outside the left edge still touches column 0.
        let fp = Footprint::new(-0.4, 1.5, e).unwrap();
        assert_eq!(fp.in_frame(e), [false, true, false, true]);
    }
}

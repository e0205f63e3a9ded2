//! Temporal gradients (`History::Gradient`): each eye's history confidence from re-shaded
//! samples of the last frame, after A-SVGF (Schied et al. 2018).
//!
//! Per 3×3 stratum of this frame, one pixel whose history was reprojected is followed back
//! to the last frame's pixel its surface came from. That pixel is traced again with the last
//! frame's camera and random numbers (the same paths) under this frame's lights and
//! geometry, and its luminance compared with the sample the last frame traced there: any
//! difference is a change of the lighting, not noise. The kernel
//! (`kernels::gradient::history_confidence`) turns the pairs into a per-pixel confidence the
//! EMA reads. A scene that cannot change ([`FrameSource::scene_changes`]) skips all of it.

use std::time::Instant;

use super::{Eye, GradientInput, Lent, Pipeline, PipelineError, STRATUM, gradient, is_reprojected};
use crate::kernels::frame::Plane;
use rayon::prelude::*;

use super::GBufferView;
use crate::kernels::{CameraModel, Extent, FrameError, GBufferBuf, PlaneBuf, RgbBuf};
use crate::source::{FrameSource, PixelSelection, TraceRequest};

/// How strongly a relative change of the lighting shortens the history (the kernel's
/// `gain`): A-SVGF's 1. Measured on the quick preset's moving-light scenes (RESULTS.md),
/// gains of 2–4 buy more at 4 spp and lose more at 1 spp, where the gradient of single paths
/// is mostly noise; below 1 they give back what 1 buys at 4 spp.
const GRADIENT_GAIN: f32 = 1.0;

/// A stratum without a gradient sample.
const NONE: u32 = u32::MAX;

/// One eye's buffers for temporal gradients, allocated with the pipeline.
pub(super) struct GradientBuffers {
    /// Per stratum: the last frame's pixel (`y·w + x`) re-shaded for it, or [`NONE`].
    source_pixel: PlaneBuf<u32>,
    /// Per stratum: the last frame's luminance there, and the re-shaded one (NaN: none).
    old: PlaneBuf,
    new: PlaneBuf,
    /// The last frame's pixels to re-shade (cleared again after each frame).
    mask: PlaneBuf<u8>,
    /// The re-shaded samples, at the last frame's pixels.
    reshaded: RgbBuf,
    /// The per-pixel history confidence the EMA reads.
    pub(super) confidence: PlaneBuf,
    /// Per stratum: whether any of its pixels has a new sample this frame; then whether any
    /// stratum of its 3×3 neighbourhood has (only those strata's gradients reach a pixel the
    /// EMA blends: see [`Pipeline::temporal_gradients`]).
    new_in_stratum: PlaneBuf<u8>,
    needed: PlaneBuf<u8>,
}

impl GradientBuffers {
    pub(super) fn try_new(extent: Extent) -> Result<Self, FrameError> {
        let strata = gradient::strata_extent(extent);
        Ok(Self {
            source_pixel: PlaneBuf::try_new(strata, NONE)?,
            old: PlaneBuf::try_new(strata, f32::NAN)?,
            new: PlaneBuf::try_new(strata, f32::NAN)?,
            mask: PlaneBuf::try_new(extent, 0)?,
            reshaded: RgbBuf::try_new(extent, 0.0)?,
            confidence: PlaneBuf::try_new(extent, 1.0)?,
            new_in_stratum: PlaneBuf::try_new(strata, 0)?,
            needed: PlaneBuf::try_new(strata, 0)?,
        })
    }
}

/// Writes `value` into `mask` at every stratum's chosen pixel (set before the re-shade,
/// cleared after it); returns how many strata chose one.
fn mark_chosen(mask: &mut PlaneBuf<u8>, chosen: &PlaneBuf<u32>, value: u8) -> u64 {
    let mut count = 0;
    for &pixel in chosen.as_slice().iter().filter(|&&p| p != NONE) {
        mask.as_mut_slice()[pixel as usize] = value;
        count += 1;
    }
    count
}

/// Marks in `needed` the strata whose gradient can reach a pixel the EMA blends with its
/// history (a new sample, `has_new`, and a reprojected history, `reason`): those with such a
/// pixel in their 3×3 neighbourhood of strata, the kernel's reach (a pixel's confidence is
/// its stratum's `λ`, summed over that neighbourhood). `new_in_stratum` is scratch of the
/// strata's extent.
pub(super) fn mark_needed(
    has_new: &PlaneBuf<u8>,
    reason: &PlaneBuf<u8>,
    new_in_stratum: &mut PlaneBuf<u8>,
    needed: &mut PlaneBuf<u8>,
) {
    let (w, h) = (has_new.extent().width(), has_new.extent().height());
    let sw = new_in_stratum.extent().width();
    new_in_stratum.as_mut_slice().par_chunks_mut(sw).enumerate().for_each(|(sy, row)| {
        let rows = sy * STRATUM..((sy + 1) * STRATUM).min(h);
        // A stretch of the stratum row at a time: its pixel rows OR-ed column by column (a
        // loop the compiler vectorises), then each stratum's three columns.
        let mut blended = [0u8; BLENDED_CHUNK];
        for (chunk, flags) in row.chunks_mut(BLENDED_CHUNK / STRATUM).enumerate() {
            let x0 = chunk * BLENDED_CHUNK;
            let columns = BLENDED_CHUNK.min(w - x0);
            let blended = &mut blended[..columns];
            blended.fill(0);
            for y in rows.clone() {
                let at = y * w + x0;
                let pixels = &has_new.as_slice()[at..at + columns];
                let reasons = &reason.as_slice()[at..at + columns];
                for ((b, &n), &r) in blended.iter_mut().zip(pixels).zip(reasons) {
                    *b |= n & u8::from(is_reprojected(r));
                }
            }
            for (flag, stratum) in flags.iter_mut().zip(blended.chunks(STRATUM)) {
                *flag = stratum.iter().fold(0, |any, &b| any | b);
            }
        }
    });
    let sh = new_in_stratum.extent().height();
    let new_in = new_in_stratum.as_slice();
    needed.as_mut_slice().par_chunks_mut(sw).enumerate().for_each(|(sy, row)| {
        // The 3×3 neighbourhood as two passes of three: the rows above and below (vectorised),
        // then each stratum's left and right neighbours in place.
        row.copy_from_slice(&new_in[sy * sw..(sy + 1) * sw]);
        for ny in [sy.wrapping_sub(1), sy + 1].into_iter().filter(|&ny| ny < sh) {
            for (flag, &f) in row.iter_mut().zip(&new_in[ny * sw..(ny + 1) * sw]) {
                *flag |= f;
            }
        }
        let mut left = 0;
        for sx in 0..sw {
            let (own, right) = (row[sx], row.get(sx + 1).copied().unwrap_or(0));
            row[sx] = left | own | right;
            left = own;
        }
    });
}

/// Pixel columns [`mark_needed`] ORs at a time (a multiple of [`STRATUM`], on the stack).
const BLENDED_CHUNK: usize = 96 * STRATUM;

/// Rec. 709 luminance (`kernels::colour::luminance`) of a texel.
fn luminance([r, g, b]: [f32; 3]) -> f32 {
    crate::kernels::colour::luminance(r, g, b)
}

/// Where a stratum's candidates start (so the sample moves around its stratum from frame to
/// frame, as A-SVGF's does): the column from a hash of the frame and the stratum, the row
/// from a hash of the frame and the row of strata. One pixel row in three per row of strata
/// is then read (G-buffer, masks, samples), a third of the memory traffic of a row per
/// stratum.
fn first_candidate(frame: u32, sx: usize, sy: usize) -> usize {
    let hash = |v: u64| {
        let h = (u64::from(frame) << 32) ^ v;
        ((h ^ (h >> 31)).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40) as usize
    };
    let row = hash(sy as u64 | 1 << 31) % STRATUM;
    let column = hash((sy as u64) << 16 ^ sx as u64) % STRATUM;
    row * STRATUM + column
}

/// A stratum's pixel offsets, twice over: the candidates from offset `k` are
/// `CANDIDATES[k..k + 9]` (no division per candidate).
const CANDIDATES: [(usize, usize); 2 * STRATUM * STRATUM] = {
    let mut c = [(0, 0); 2 * STRATUM * STRATUM];
    let mut i = 0;
    while i < c.len() {
        let k = i % (STRATUM * STRATUM);
        c[i] = (k % STRATUM, k / STRATUM);
        i += 1;
    }
    c
};

/// What choosing a stratum's gradient sample reads.
struct Chooser<'a> {
    frame: u32,
    /// This frame's G-buffer camera (jittered, as the depth is) and the last frame's camera.
    camera: CameraModel,
    last_camera: CameraModel,
    planes: &'a GBufferView<'a>,
    reasons: Plane<'a, u8>,
    /// The last frame's traced-pixel mask.
    traced_before: Plane<'a, u8>,
    extent: Extent,
}

impl Chooser<'_> {
    /// The last frame's pixel (`y·w + x`) whose traced sample stratum `(sx, sy)` re-shades:
    /// from the first of its pixels (from a per-frame offset) whose history was reprojected,
    /// the pixel its surface lay under last frame, if that pixel was traced; [`NONE`] if no
    /// pixel of the stratum qualifies.
    fn in_stratum(&self, sx: usize, sy: usize) -> u32 {
        let e = self.extent;
        let first = first_candidate(self.frame, sx, sy);
        let (x0, y0) = (sx * STRATUM, sy * STRATUM);
        for &(dx, dy) in &CANDIDATES[first..first + STRATUM * STRATUM] {
            let (x, y) = (x0 + dx, y0 + dy);
            if x >= e.width() || y >= e.height() || !is_reprojected(self.reasons.row(y)[x]) {
                continue;
            }
            let depth = self.planes.depth.get(x, y);
            if !depth.is_finite() {
                continue;
            }
            // The surface's position last frame: where it is now, less its motion.
            let mut p = self.camera.unproject_pixel(x, y, depth);
            if let Some(motion) = &self.planes.motion {
                for (c, m) in p.iter_mut().zip(motion) {
                    *c -= m.get(x, y);
                }
            }
            let Some(([qx, qy], _)) = self.last_camera.project(p) else { continue };
            if !(qx >= 0.0 && qy >= 0.0 && qx < e.width() as f32 && qy < e.height() as f32) {
                continue;
            }
            let (px, py) = (qx as usize, qy as usize);
            if self.traced_before.get(px, py) != 0 {
                return (py * e.width() + px) as u32;
            }
        }
        NONE
    }
}

impl<S: FrameSource> Pipeline<S> {
    /// The engine's own history confidence of `eye` this frame, if its G-buffer has one.
    pub(super) fn engine_confidence<'a>(
        own: &'a GBufferBuf,
        eye: Eye,
        lent: Option<&'a Lent<'a>>,
    ) -> Option<Plane<'a>> {
        match lent {
            Some(l) => l.current[eye as usize].history_confidence,
            None => own.history_confidence.as_ref().map(|c| c.view()),
        }
    }

    /// Whether this eye's new samples of the last frame are in its `work` image (the left
    /// eye filled from the right one) rather than in `traced`.
    fn samples_in_work(&self, eye: Eye) -> bool {
        eye == Eye::Left
            && super::plan(self.config.mode, self.config.order)
                .iter()
                .any(|step| matches!(step, super::Step::StereoFillLeft(_)))
    }

    /// Measures `eye`'s temporal gradients into its confidence plane, before its EMA.
    /// Returns whether it did: with `History::Paper`, on a frame without history, or for a
    /// scene that cannot change, it does nothing.
    ///
    /// The EMA reads the confidence only where it blends a new sample with a reprojected
    /// history (`source` names the EMA's validity plane), and a pixel's confidence comes from
    /// the 3×3 strata around its own, so only strata with such a pixel in that neighbourhood
    /// choose and re-shade a gradient sample. Without a budget that is nearly every stratum
    /// of the right eye; under one, where an eye traces a few percent of its pixels (most of
    /// them without history), it leaves out most of the choosing (up to nine projections a
    /// stratum, most of them failing on the last frame's untraced pixels) and of the
    /// re-shading, and the images are the same bits.
    pub(super) fn temporal_gradients(
        &mut self,
        eye: Eye,
        source: super::Source,
        stats: &mut super::FrameStats,
        lent: Option<&Lent<'_>>,
    ) -> Result<bool, PipelineError> {
        if self.eyes[eye as usize].gradient.is_none() || self.frames_done == 0 || !self.source.scene_changes() {
            return Ok(false);
        }
        let t = Instant::now();
        let in_work = self.samples_in_work(eye);
        let fused = self.ema_is_fused(source);
        let e = self.extent;
        let frame = stats.frame;
        let s = &mut self.eyes[eye as usize];
        let g = s.gradient.as_mut().expect("checked above");
        let planes = match lent {
            Some(l) => l.current[eye as usize],
            None => super::planes_of(&s.cur.gbuffer),
        };
        let (camera, last_camera) = (s.cur.gbuffer.camera, s.last_camera);
        let (traced_before, reasons) = (s.prev.traced_mask.view(), s.cur.temporal_reason.view());
        let strata = g.source_pixel.extent();
        // One gradient sample per needed stratum, the rows of strata in parallel; then the mask of
        // the pixels to re-shade, serially (they are the last frame's, anywhere).
        let choose = Chooser { frame, camera, last_camera, planes: &planes, reasons, traced_before, extent: e };
        if self.gradients_where_needed {
            let reason = super::ema_validity(&s.ema_reason, &s.cur.temporal_reason, source, fused);
            mark_needed(&s.has_new, reason, &mut g.new_in_stratum, &mut g.needed);
        } else {
            g.needed.as_mut_slice().fill(1);
        }
        let needed = &g.needed;
        g.source_pixel.as_mut_slice().par_chunks_mut(strata.width()).enumerate().for_each(|(sy, row)| {
            let needed = &needed.as_slice()[sy * strata.width()..(sy + 1) * strata.width()];
            for (sx, (found, &need)) in row.iter_mut().zip(needed).enumerate() {
                *found = if need != 0 { choose.in_stratum(sx, sy) } else { NONE };
            }
        });
        let chosen = mark_chosen(&mut g.mask, &g.source_pixel, 1);
        let chose = t.elapsed();

        // Re-shade them: the last frame's camera and random numbers, this frame's scene.
        let trace_start = Instant::now();
        let request =
            TraceRequest { eye, frame: self.last_frame, spp: self.config.spp, seed: self.config.seed, first_sample: 0 };
        let traced =
            self.source.trace(&last_camera, &request, PixelSelection::Mask(&g.mask), 0..e.height(), &mut g.reshaded);
        // The mask is all zeros between frames, a refused one included.
        mark_chosen(&mut g.mask, &g.source_pixel, 0);
        stats.trace = stats.trace + traced?;
        stats.gradient_samples[eye as usize] += chosen;
        stats.times.tracing += trace_start.elapsed();

        let t = Instant::now();
        // A stratum's pixel is the index `y·w + x` into both images' packed planes.
        let before = if in_work { s.prev.work.slices() } else { s.prev.traced.slices() };
        let reshaded = g.reshaded.slices();
        let texel = |planes: &[&[f32]; 3], i: usize| [planes[0][i], planes[1][i], planes[2][i]];
        let pair = |pixel: u32| {
            if pixel == NONE {
                return (f32::NAN, f32::NAN);
            }
            let i = pixel as usize;
            (luminance(texel(&before, i)), luminance(texel(&reshaded, i)))
        };
        let w = strata.width();
        (
            g.source_pixel.as_slice().par_chunks(w),
            g.old.as_mut_slice().par_chunks_mut(w),
            g.new.as_mut_slice().par_chunks_mut(w),
        )
            .into_par_iter()
            .for_each(|(pixels, old, new)| {
                for ((&pixel, old), new) in pixels.iter().zip(old).zip(new) {
                    (*old, *new) = pair(pixel);
                }
            });
        let prior = Self::engine_confidence(&s.cur.gbuffer, eye, lent);
        let input = GradientInput { old: g.old.view(), new: g.new.view(), prior, gain: GRADIENT_GAIN };
        let measured = gradient::history_confidence(&input, g.confidence.view_mut())?;
        stats.gradient_changed[eye as usize] += measured.changed;
        stats.times.gradients += chose + t.elapsed();
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::Extent;
    use crate::kernels::reproject::Reason;
    use crate::kernels::synth::Rng;

    /// [`mark_needed`] by its definition, a stratum at a time: any pixel of the 3×3
    /// neighbourhood of strata with a new sample and a reprojected history.
    fn mark_needed_by_definition(has_new: &PlaneBuf<u8>, reason: &PlaneBuf<u8>, strata: Extent) -> Vec<u8> {
        let (w, h) = (has_new.extent().width(), has_new.extent().height());
        let blended =
            |x: usize, y: usize| has_new.as_slice()[y * w + x] != 0 && is_reprojected(reason.as_slice()[y * w + x]);
        let mut needed = vec![0; strata.pixels()];
        for sy in 0..strata.height() {
            for sx in 0..strata.width() {
                let ys = (sy.saturating_sub(1) * STRATUM)..((sy + 2) * STRATUM).min(h);
                let xs = (sx.saturating_sub(1) * STRATUM)..((sx + 2) * STRATUM).min(w);
                let any = ys.flat_map(|y| xs.clone().map(move |x| (x, y))).any(|(x, y)| blended(x, y));
                needed[sy * strata.width() + sx] = u8::from(any);
            }
        }
        needed
    }

    /// Odd sizes (a partial last stratum each way), a frame wider than one stretch of
    /// [`BLENDED_CHUNK`] columns with a partial last stretch, sparse and dense masks.
    #[test]
    fn the_needed_strata_match_their_definition() {
        let mut rng = Rng::new(0x6d61_726b);
        for (w, h) in [(1, 1), (2, 5), (3, 3), (7, 4), (97, 52), (290, 7), (577, 11), (1280, 9)] {
            let e = Extent::new(w, h).unwrap();
            let strata = gradient::strata_extent(e);
            for density in [200, 30, 3] {
                let has_new: Vec<u8> = (0..e.pixels()).map(|_| u8::from(rng.below(density) == 0)).collect();
                let reasons: Vec<u8> = (0..e.pixels())
                    .map(|_| if rng.below(3) == 0 { Reason::DepthOrPosition } else { Reason::Reprojected } as u8)
                    .collect();
                let (has_new, reason) =
                    (PlaneBuf::from_vec(has_new, e).unwrap(), PlaneBuf::from_vec(reasons, e).unwrap());
                // Scratch and output start dirty: every value must be written.
                let (mut scratch, mut needed) = (PlaneBuf::new(strata, 7u8), PlaneBuf::new(strata, 9u8));
                mark_needed(&has_new, &reason, &mut scratch, &mut needed);
                let expected = mark_needed_by_definition(&has_new, &reason, strata);
                assert_eq!(needed.as_slice(), &expected[..], "{w}×{h}, one new sample in {density}");
            }
        }
    }
}

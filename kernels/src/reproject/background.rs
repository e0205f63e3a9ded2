//! Background pixels reprojected by direction (the module notes' item 6), eight at a time:
//! the SIMD twin of [`super::scalar::background_pixel`]. It runs over a row after the
//! surface bodies wrote it, on the pixels they marked [`Reason::Background`], and does the
//! reference's lane-wise operations in its order, so it gives the reference's bits.

use super::scalar::{background_pixel, put_pixel};
use super::simd::{all_finite_simd, footprints_at};
use super::{Prepared, Reason, ReasonCounts, RowOut};
use crate::bilinear::{coherent_row, renormalise_simd};
use crate::camera::CameraModel;
use crate::gbuffer::SurfaceLayout;
use crate::simd::{F32s, LANES, TapCoords, flush_subnormal, lane_offsets, store};

/// A lane bit set with every lane.
const ALL_LANES: u32 = (1 << LANES) - 1;

/// The target camera, and its pixel rays' corner and steps as lanes.
pub(super) struct BackgroundRays {
    pub(super) camera: CameraModel,
    corner: [F32s; 3],
    dx: [F32s; 3],
    dy: [F32s; 3],
}

impl BackgroundRays {
    pub(super) fn new(camera: CameraModel) -> Self {
        let splat = |v: [f32; 3]| v.map(F32s::splat);
        Self { camera, corner: splat(camera.ray_origin_corner), dx: splat(camera.ray_dx), dy: splat(camera.ray_dy) }
    }
}

/// Reprojects the background pixels of row `y` by direction, where the input asks for it:
/// those of `0 .. end`, the part the SIMD bodies wrote (the row's tail went through the
/// scalar reference, which already treated its background pixels).
#[inline(always)]
pub(super) fn background_row<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    y: usize,
    end: usize,
    row: &mut RowOut<'_>,
    counts: &mut ReasonCounts,
) {
    let Some(rays) = &p.background else {
        return;
    };
    let background = Reason::Background as u8;
    let mut x = 0;
    // Most rows of most frames hold no sky, or a few runs of it: jump from run to run.
    while let Some(offset) = row.reason[x..end].iter().position(|&r| r == background) {
        x += offset;
        if x + LANES > end {
            for x in x..end {
                if row.reason[x] == background {
                    keep(row, counts, x, background_pixel(p, &rays.camera, x, y));
                }
            }
            return;
        }
        let wanted = row.reason[x..x + LANES]
            .iter()
            .enumerate()
            .fold(0u32, |bits, (i, &r)| bits | (u32::from(r == background) << i));
        let lanes = background_lanes::<L, C>(p, rays, x, y);
        let kept = wanted & lanes.ok_bits;
        if kept == ALL_LANES {
            // The common case inside a sky: eight pixels kept, written as vectors.
            for c in 0..C {
                store(row.channels[c], x, lanes.channels[c]);
            }
            if let Some(w) = row.weight.as_deref_mut() {
                store(w, x, lanes.weight);
            }
            row.reason[x..x + LANES].fill(Reason::Reprojected as u8);
            counts.0[Reason::Background as usize] -= LANES as u64;
            counts.0[Reason::Reprojected as usize] += LANES as u64;
        } else if kept != 0 {
            let channels = lanes.channels.map(|v| v.to_array());
            let weight = lanes.weight.to_array();
            for i in (0..LANES).filter(|i| kept & (1 << i) != 0) {
                let mut values = [0.0; super::MAX_CHANNELS];
                values[..C].copy_from_slice(&core::array::from_fn::<f32, C, _>(|c| channels[c][i]));
                keep(row, counts, x + i, (Reason::Reprojected, values, weight[i]));
            }
        }
        x += LANES;
    }
}

/// Writes a background pixel that was reprojected (and nothing for one that was not).
#[inline(always)]
fn keep(row: &mut RowOut<'_>, counts: &mut ReasonCounts, x: usize, result: super::PixelResult) {
    if result.0 == Reason::Reprojected {
        put_pixel(row, x, result);
        counts.0[Reason::Background as usize] -= 1;
        counts.0[Reason::Reprojected as usize] += 1;
    }
}

/// The eight pixels `x .. x + LANES` of row `y` as background: their channels, weights and
/// which lanes had an accepted tap.
struct BackgroundLanes<const C: usize> {
    channels: [F32s; C],
    weight: F32s,
    ok_bits: u32,
}

#[inline(always)]
fn background_lanes<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    rays: &BackgroundRays,
    x: usize,
    y: usize,
) -> BackgroundLanes<C> {
    let zero = F32s::ZERO;
    let half = F32s::splat(0.5);
    // The reference's `ray(x + 0.5, y + 0.5)`: integers below 2^24 are exact in f32.
    let px = F32s::splat(x as f32) + lane_offsets() + half;
    let py = F32s::splat(y as f32 + 0.5);
    let d: [F32s; 3] = core::array::from_fn(|i| rays.corner[i] + px * rays.dx[i] + py * rays.dy[i]);
    let r = &p.v.rows;
    let clip = |i: usize| r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2];
    let (cx, cy, cw) = (clip(0), clip(1), clip(2));
    let mut fp = footprints_at(p, cx, cy, cw);
    let active = cw.simd_gt(zero) & fp.inside;
    fp.inside = active;
    let weights = fp.weights();
    let in_frame = fp.in_frame(p.source_extent);
    let coherent = coherent_row(&fp, active, p.source_extent);
    let inf = F32s::splat(f32::INFINITY);
    let (mut sum, mut total) = ([zero; C], zero);
    let (mut any_accepted, mut any_failed) = (zero, zero);
    let taps = fp.taps();
    for tap in 0..4 {
        let weight = weights[tap];
        let participates = active & weight.simd_gt(zero);
        if participates.none() {
            continue;
        }
        let (depth, values): (F32s, [F32s; C]) = match coherent {
            // Tap `tap` of lane `i` is source pixel (x0 + i + (tap & 1), y0 + (tap >> 1)),
            // inside the frame (`coherent_row` checked it).
            Some((x0, y0)) => {
                let (tx, ty) = (x0 + (tap & 1), y0 + (tap >> 1));
                (p.source.depth_row(tx, ty), core::array::from_fn(|c| F32s::from(p.channels[c].lanes::<LANES>(tx, ty))))
            }
            None => {
                let (tx, ty) = taps[tap];
                let coords = TapCoords::clamped(tx, ty, p.source_extent.width(), p.source_extent.height());
                (p.source.depths_gather(&coords), core::array::from_fn(|c| coords.gather_f32(&p.channels[c])))
            }
        };
        let accepted = participates & in_frame[tap] & depth.simd_eq(inf) & all_finite_simd(values);
        any_failed |= participates & !accepted;
        any_accepted |= accepted;
        for c in 0..C {
            sum[c] += accepted.select(weight * values[c], zero);
        }
        total += accepted.select(weight, zero);
    }
    let ok = if p.strict { any_accepted & !any_failed } else { any_accepted };
    let inv_total = F32s::ONE / total;
    BackgroundLanes {
        channels: sum.map(|s| ok.select(flush_subnormal(renormalise_simd(s, inv_total)), zero)),
        weight: ok.select(total.min(F32s::ONE), zero),
        ok_bits: ok.to_bitmask(),
    }
}

//! The scalar reference of backward reprojection: one target pixel at a time, the
//! definition of the module notes written out; [`super::simd`] computes the same values.

use super::{
    MAX_CHANNELS, PixelResult, Prepared, Reason, ReasonCounts, RowOut, TapVerdict, len2, normals_agree, usable,
};
use crate::bilinear::{Footprint, renormalise};
use crate::camera::CameraModel;
use crate::gbuffer::SurfaceLayout;
use crate::simd::flush_subnormal1;

/// Writes the scalar reference result for pixel `(x, y)`.
#[inline]
pub(super) fn write_pixel<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    x: usize,
    y: usize,
    row: &mut RowOut<'_>,
    counts: &mut ReasonCounts,
) {
    if p.pixel_mask.is_some_and(|m| m.get(x, y) == 0) {
        row.reason[x] = Reason::Invalid as u8;
        return;
    }
    let result = reproject_pixel_prepared(p, x, y);
    put_pixel(row, x, result);
    counts.0[result.0 as usize] += 1;
}

/// Stores one pixel's result (its channels, weight and reason) in the output row.
#[inline(always)]
pub(super) fn put_pixel(row: &mut RowOut<'_>, x: usize, (reason, values, weight): PixelResult) {
    for c in 0..row.count {
        row.channels[c][x] = values[c];
    }
    if let Some(w) = row.weight.as_deref_mut() {
        w[x] = weight;
    }
    row.reason[x] = reason as u8;
}

pub(super) fn reproject_pixel_prepared<L: SurfaceLayout>(p: &Prepared<'_, L>, x: usize, y: usize) -> PixelResult {
    const NONE: [f32; MAX_CHANNELS] = [0.0; MAX_CHANNELS];
    let mut t = p.target.surfel(x, y);
    if let Some(motion) = &p.motion {
        // Where the surface was when the source frame was rendered.
        for i in 0..3 {
            t.position[i] -= motion[i].get(x, y);
        }
    }
    if t.depth == f32::INFINITY {
        return match &p.background {
            Some(rays) => background_pixel(p, &rays.camera, x, y),
            None => (Reason::Background, NONE, 0.0),
        };
    }
    let t_len2 = len2(t.normal);
    if !usable(&t, t_len2) {
        return (Reason::Invalid, NONE, 0.0);
    }
    let [cx, cy, _, cw] = p.camera.clip(t.position);
    if !(cw > 0.0) {
        return (Reason::OutOfFrame, NONE, 0.0);
    }
    let Some(fp) = footprint_at(p, cx, cy, cw) else {
        return (Reason::OutOfFrame, NONE, 0.0);
    };
    let weights = fp.weights();
    let in_frame = fp.in_frame(p.source_extent);
    // Clamped so that an infinite tap depth can never pass (see `evaluate_taps`).
    let depth_tolerance = (p.depth_relative * cw).min(f32::MAX);

    let mut sum = NONE;
    let mut total = 0.0f32;
    let (mut any_accepted, mut any_failed) = (false, false);
    let (mut fail_geometry, mut fail_normal, mut fail_invalid) = (false, false, false);
    for (tap, &(tx, ty)) in fp.taps().iter().enumerate() {
        if weights[tap] == 0.0 {
            continue;
        }
        if !in_frame[tap] {
            any_failed = true;
            continue;
        }
        let (tx, ty) = (tx as usize, ty as usize);
        let s = p.source.surfel(tx, ty);
        let values = tap_values(p, tx, ty);
        let s_len2 = len2(s.normal);
        let verdict = if s.depth == f32::INFINITY {
            TapVerdict::Geometry
        } else if !usable(&s, s_len2) || !values[..p.channel_count].iter().all(|v| v.is_finite()) {
            TapVerdict::Invalid
        } else {
            let d = [0, 1, 2].map(|i| s.position[i] - t.position[i]);
            let distance2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let dot = s.normal[0] * t.normal[0] + s.normal[1] * t.normal[1] + s.normal[2] * t.normal[2];
            if !(distance2 <= p.position2) || !((s.depth - cw).abs() <= depth_tolerance) {
                TapVerdict::Geometry
            } else if !normals_agree(dot, s_len2 * t_len2, p.normal_cos2, p.normal_cos_positive) {
                TapVerdict::Normal
            } else {
                TapVerdict::Accepted
            }
        };
        match verdict {
            TapVerdict::Accepted => {
                any_accepted = true;
                for c in 0..MAX_CHANNELS {
                    sum[c] += weights[tap] * values[c];
                }
                total += weights[tap];
            }
            TapVerdict::Geometry => fail_geometry = true,
            TapVerdict::Normal => fail_normal = true,
            TapVerdict::Invalid => fail_invalid = true,
        }
        any_failed |= verdict != TapVerdict::Accepted;
    }
    let ok = any_accepted && !(p.strict && any_failed);
    if ok {
        let inv_total = 1.0 / total;
        return (Reason::Reprojected, sum.map(|s| flush_subnormal1(renormalise(s, inv_total))), total.min(1.0));
    }
    let reason = if fail_geometry {
        Reason::DepthOrPosition
    } else if fail_normal {
        Reason::Normal
    } else if fail_invalid {
        Reason::Invalid
    } else {
        Reason::OutOfFrame
    };
    (reason, NONE, 0.0)
}

/// A background pixel reprojected by its view direction (the module notes' item 6):
/// [`Reason::Reprojected`] with the renormalised samples of its accepted taps, or
/// [`Reason::Background`] with nothing where no tap is accepted.
pub(super) fn background_pixel<L: SurfaceLayout>(
    p: &Prepared<'_, L>,
    target_camera: &CameraModel,
    x: usize,
    y: usize,
) -> PixelResult {
    const NONE: [f32; MAX_CHANNELS] = [0.0; MAX_CHANNELS];
    let refused = (Reason::Background, NONE, 0.0);
    let d = target_camera.ray(x as f32 + 0.5, y as f32 + 0.5);
    // The source clip coordinates of the point at infinity (d, 0): no translation column.
    let r = &p.camera.rows;
    let dot = |i: usize| r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2];
    let (cx, cy, cw) = (dot(0), dot(1), dot(3));
    if !(cw > 0.0) {
        return refused;
    }
    let Some(fp) = footprint_at(p, cx, cy, cw) else {
        return refused;
    };
    let weights = fp.weights();
    let in_frame = fp.in_frame(p.source_extent);
    let mut sum = NONE;
    let mut total = 0.0f32;
    let (mut any_accepted, mut any_failed) = (false, false);
    for (tap, &(tx, ty)) in fp.taps().iter().enumerate() {
        if weights[tap] == 0.0 {
            continue;
        }
        if !in_frame[tap] {
            any_failed = true;
            continue;
        }
        let (tx, ty) = (tx as usize, ty as usize);
        let values = tap_values(p, tx, ty);
        let accepted =
            p.source.depth(tx, ty) == f32::INFINITY && values[..p.channel_count].iter().all(|v| v.is_finite());
        if accepted {
            any_accepted = true;
            for c in 0..MAX_CHANNELS {
                sum[c] += weights[tap] * values[c];
            }
            total += weights[tap];
        }
        any_failed |= !accepted;
    }
    if !any_accepted || (p.strict && any_failed) {
        return refused;
    }
    let inv_total = 1.0 / total;
    (Reason::Reprojected, sum.map(|s| flush_subnormal1(renormalise(s, inv_total))), total.min(1.0))
}

/// The bilinear footprint in the source of clip coordinates `(cx, cy, ·, cw)` with `cw > 0`
/// (moved by the jitter's shift where there is one), or `None` outside the source frame.
#[inline(always)]
fn footprint_at<L: SurfaceLayout>(p: &Prepared<'_, L>, cx: f32, cy: f32, cw: f32) -> Option<Footprint> {
    let (hw, hh) = (p.half_width, p.half_height);
    let inv_w = 1.0 / cw;
    let mut sx = (cx * inv_w) * hw + hw;
    let mut sy = (-(cy * inv_w)) * hh + hh;
    if let Some([dx, dy]) = p.jitter_shift {
        // Where the target pixel's unjittered centre lands on the unjittered colour grid.
        (sx, sy) = (sx + dx, sy + dy);
    }
    Footprint::new(sx, sy, p.source_extent)
}

/// The source samples of tap `(tx, ty)` (0 in the channels the input lacks).
#[inline(always)]
fn tap_values<L: SurfaceLayout>(p: &Prepared<'_, L>, tx: usize, ty: usize) -> [f32; MAX_CHANNELS] {
    let mut values = [0.0; MAX_CHANNELS];
    for c in 0..p.channel_count {
        values[c] = p.channels[c].get(tx, ty);
    }
    values
}

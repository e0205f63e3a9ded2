//! The AVX-512 body's 16-pixel path: the common case of [`super::simd`]'s coherent path,
//! sixteen target pixels at a time in one `zmm` register, with `k` masks for every test.
//!
//! It takes a group only when every lane is an ordinary reprojection: both G-buffers in the
//! compact layout, no pixel mask, every lane's footprint in frame on one source row at
//! consecutive columns, and every lane reprojected. Any other group returns `false` before
//! writing anything, and the 8-lane body does it. Per lane it runs the 8-lane body's
//! operations in the same order (unfused products and sums, the same compare-and-select
//! clamps), so it gives the same bits; the reprojection tests hold every body to the scalar
//! reference.

use core::arch::x86_64::*;

use super::{Prepared, Reason, ReasonCounts, RowOut};
use crate::bilinear::SNAP;
use crate::gbuffer::{CompactGBuffer, SNORM_MAX, SurfaceLayout};
use crate::lanes::Lanes;
use crate::lanes::avx512::F32x16;

/// Pixels per group.
pub(super) const WIDE: usize = 16;

type V = F32x16;
/// One bit per lane.
type M = __mmask16;
const ALL: M = 0xffff;

#[inline(always)]
fn splat(v: f32) -> V {
    V::splat(v)
}

#[inline(always)]
fn cmp<const P: i32>(a: V, b: V) -> M {
    // SAFETY: callers run only inside the target-feature function below.
    unsafe { _mm512_cmp_ps_mask::<P>(a.0, b.0) }
}

/// `t` where `m` is set, `f` elsewhere.
#[inline(always)]
fn sel(m: M, t: V, f: V) -> V {
    // SAFETY: as for `cmp`.
    F32x16(unsafe { _mm512_mask_blend_ps(m, f.0, t.0) })
}

#[inline(always)]
fn load(s: &[f32], x: usize) -> V {
    V::load(&s[x..x + WIDE])
}

/// The surface of 16 consecutive pixels, as [`crate::gbuffer::Surfels`] holds eight.
struct Surface {
    depth: V,
    position: [V; 3],
    normal: [V; 3],
}

/// [`CompactGBuffer`]'s row decode (depth, rebuilt position, raw octahedral normal) for
/// pixels `x .. x + 16` of row `y`.
#[inline(always)]
fn decode(g: &CompactGBuffer<'_>, x: usize, y: usize) -> Surface {
    let depth = load(g.depth().row(y), x);
    let c = g.camera();
    let px = splat(x as i32 as f32) + V::lane_offsets() + splat(0.5);
    let py = splat(y as i32 as f32 + 0.5);
    // The order of `CameraModel::unproject_pixel`: (corner + px·dx) + py·dy. (No closures
    // in this module: a closure does not take the target features of the function it is in,
    // so the intrinsics in it would not be inlined.)
    let mut position = [V::zero(); 3];
    for i in 0..3 {
        position[i] = splat(c.centre[i])
            + depth * ((splat(c.ray_origin_corner[i]) + px * splat(c.ray_dx[i])) + py * splat(c.ray_dy[i]));
    }
    let packed = &g.normal().row(y)[x..x + WIDE];
    Surface { depth, position, normal: decode_normals(packed) }
}

/// [`crate::gbuffer::decode_normals_raw`] of 16 packed normals.
#[inline(always)]
fn decode_normals(packed: &[u32]) -> [V; 3] {
    // SAFETY: as for `cmp`; `packed` holds 16 values (sliced by the caller).
    unsafe {
        let bits = _mm512_loadu_si512(packed.as_ptr().cast());
        let lo = _mm512_srai_epi32::<16>(_mm512_slli_epi32::<16>(bits));
        let hi = _mm512_srai_epi32::<16>(bits);
        let min = _mm512_set1_epi32(i32::from(i16::MIN));
        let invalid = _mm512_cmpeq_epi32_mask(lo, min) | _mm512_cmpeq_epi32_mask(hi, min);
        let scale = splat(1.0 / SNORM_MAX);
        let mut x = F32x16(_mm512_cvtepi32_ps(lo)) * scale;
        let mut y = F32x16(_mm512_cvtepi32_ps(hi)) * scale;
        let z = V::one() - x.abs() - y.abs();
        let t = (-z).fast_max(V::zero());
        x += sel(cmp::<_CMP_GE_OQ>(x, V::zero()), -t, t);
        y += sel(cmp::<_CMP_GE_OQ>(y, V::zero()), -t, t);
        let nan = splat(f32::NAN);
        [sel(invalid, nan, x), sel(invalid, nan, y), sel(invalid, nan, z)]
    }
}

/// Row `r` of the view-projection applied to `position` (the 8-lane body's order).
#[inline(always)]
fn clip(r: &[f32; 4], position: &[V; 3]) -> V {
    splat(r[0]) * position[0] + splat(r[1]) * position[1] + splat(r[2]) * position[2] + splat(r[3])
}

#[inline(always)]
fn len2(v: &[V; 3]) -> V {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// Lanes where every value is finite (as the 8-lane body's `all_finite_simd`).
#[inline(always)]
fn all_finite<const N: usize>(values: &[V; N]) -> M {
    let mut poison = V::zero();
    for &v in values {
        poison += v * V::zero();
    }
    cmp::<_CMP_EQ_OQ>(poison, V::zero())
}

/// Bilinear snap of one axis (as `bilinear::snap_simd`): the tap base and fraction.
#[inline(always)]
fn snap(u: V) -> (V, V) {
    // SAFETY: as for `cmp`. Rounds towards −∞, as `floor` does.
    let base = F32x16(unsafe { _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(u.0) });
    let f = u - base;
    let low = cmp::<_CMP_LT_OQ>(f, splat(SNAP));
    let high = cmp::<_CMP_GT_OQ>(f, splat(1.0 - SNAP));
    (sel(high, base + V::one(), base), sel(low | high, V::zero(), f))
}

/// A source row's surface and samples, decoded for the tap tests.
struct Source<const C: usize> {
    surface: Surface,
    len2: V,
    /// Lanes that can be accepted at all (see the 8-lane body's `SourceLanes`).
    usable: M,
    values: [V; C],
}

#[inline(always)]
fn source<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    g: &CompactGBuffer<'_>,
    x: usize,
    y: usize,
) -> Source<C> {
    let surface = decode(g, x, y);
    let mut values = [V::zero(); C];
    for c in 0..C {
        values[c] = load(p.channels[c].row(y), x);
    }
    let len2 = len2(&surface.normal);
    let usable = cmp::<_CMP_GT_OQ>(surface.depth, V::zero())
        & cmp::<_CMP_GT_OQ>(len2, V::zero())
        & cmp::<_CMP_LE_OQ>(len2, splat(f32::MAX))
        & all_finite(&values);
    Source { surface, len2, usable, values }
}

/// The target side of the group, as the 8-lane body's `TargetLanes`.
struct Target {
    surface: Surface,
    normal_len2: V,
    depth_in_source: V,
    depth_tolerance: V,
    weights: [V; 4],
}

/// Accumulated over the taps.
struct Totals<const C: usize> {
    sum: [V; C],
    total: V,
    any_accepted: M,
    any_failed: M,
}

/// One tap: the 8-lane body's `tap_test` (geometry, normal and usability) on 16 lanes.
#[inline(always)]
fn tap<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    t: &Target,
    s: &Source<C>,
    weight: V,
    participates: M,
    acc: &mut Totals<C>,
) {
    let tp = &t.surface.position;
    let sp = &s.surface.position;
    let d = [sp[0] - tp[0], sp[1] - tp[1], sp[2] - tp[2]];
    let distance2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let geometry_ok = cmp::<_CMP_LE_OQ>(distance2, splat(p.position2))
        & cmp::<_CMP_LE_OQ>((s.surface.depth - t.depth_in_source).abs(), t.depth_tolerance);
    let (sn, tn) = (&s.surface.normal, &t.surface.normal);
    let dot = sn[0] * tn[0] + sn[1] * tn[1] + sn[2] * tn[2];
    let bound = splat(p.normal_cos2) * (s.len2 * t.normal_len2);
    let facing = cmp::<_CMP_GE_OQ>(dot, V::zero());
    let normal_ok = if p.normal_cos_positive {
        facing & cmp::<_CMP_GE_OQ>(dot * dot, bound)
    } else {
        facing | cmp::<_CMP_LE_OQ>(dot * dot, bound)
    };
    let accepted = participates & geometry_ok & normal_ok & s.usable;
    acc.any_failed |= participates & !accepted;
    acc.any_accepted |= accepted;
    for c in 0..C {
        acc.sum[c] += sel(accepted, weight * s.values[c], V::zero());
    }
    acc.total += sel(accepted, weight, V::zero());
}

/// Reprojects target pixels `x .. x + 16` of row `y` if the group is an ordinary one (see
/// the module notes) and writes them to `row`; returns `false`, having written nothing,
/// otherwise.
///
/// # Safety
/// The CPU must have AVX-512 F/BW/DQ/VL ([`crate::isa::Isa::Avx512`] supported), and
/// `x + 16 <= width`.
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
pub(super) unsafe fn group<L: SurfaceLayout, const C: usize>(
    p: &Prepared<'_, L>,
    target: &CompactGBuffer<'_>,
    source_g: &CompactGBuffer<'_>,
    x: usize,
    y: usize,
    row: &mut RowOut<'_>,
    counts: &mut ReasonCounts,
) -> bool {
    let mut surface = decode(target, x, y);
    if let Some(motion) = &p.motion {
        for i in 0..3 {
            surface.position[i] = surface.position[i] - load(motion[i].row(y), x);
        }
    }
    let inf = splat(f32::INFINITY);
    let normal_len2 = len2(&surface.normal);
    let plausible = cmp::<_CMP_GT_OQ>(surface.depth, V::zero())
        & cmp::<_CMP_LT_OQ>(surface.depth, inf)
        & cmp::<_CMP_GT_OQ>(normal_len2, V::zero())
        & cmp::<_CMP_LT_OQ>(normal_len2, inf);
    if plausible != ALL {
        return false;
    }
    let r = &p.camera.rows;
    let (cx, cy, cw) = (clip(&r[0], &surface.position), clip(&r[1], &surface.position), clip(&r[3], &surface.position));
    let (hw, hh) = (splat(p.half_width), splat(p.half_height));
    let inv_w = V::one() / cw;
    let mut sx = (cx * inv_w) * hw + hw;
    let mut sy = (-(cy * inv_w)) * hh + hh;
    if let Some([dx, dy]) = p.jitter_shift {
        (sx, sy) = (sx + splat(dx), sy + splat(dy));
    }
    // `Footprints::new_splat`, with every lane required inside.
    let (u, v) = (sx - splat(0.5), sy - splat(0.5));
    let (w, h) = (p.source_extent.width(), p.source_extent.height());
    let minus_one = splat(-1.0);
    let inside = cmp::<_CMP_GE_OQ>(u, minus_one)
        & cmp::<_CMP_LT_OQ>(u, splat(w as f32))
        & cmp::<_CMP_GE_OQ>(v, minus_one)
        & cmp::<_CMP_LT_OQ>(v, splat(h as f32));
    if inside & cmp::<_CMP_GT_OQ>(cw, V::zero()) != ALL {
        return false;
    }
    let ((x0, fx), (y0, fy)) = (snap(u), snap(v));
    // `coherent_row` at 16 lanes: one source row, consecutive columns, all taps in frame.
    let first = x0 - V::lane_offsets();
    let (col, src_row) = (first.lane(0), y0.lane(0));
    if cmp::<_CMP_EQ_OQ>(first, splat(col)) & cmp::<_CMP_EQ_OQ>(y0, splat(src_row)) != ALL
        || !(col >= 0.0 && src_row >= 0.0 && col + (WIDE as f32) < w as f32 && src_row + 1.0 < h as f32)
    {
        return false;
    }
    let (col, src_row) = (col as usize, src_row as usize);
    let one = V::one();
    let weights = [(one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy];
    let t = Target {
        normal_len2,
        depth_in_source: cw,
        depth_tolerance: (splat(p.depth_relative) * cw).fast_min(splat(f32::MAX)),
        weights,
        surface,
    };
    let mut acc = Totals::<C> { sum: [V::zero(); C], total: V::zero(), any_accepted: 0, any_failed: 0 };
    for r in 0..2 {
        let (w0, w1) = (t.weights[2 * r], t.weights[2 * r + 1]);
        let (p0, p1) = (cmp::<_CMP_GT_OQ>(w0, V::zero()), cmp::<_CMP_GT_OQ>(w1, V::zero()));
        let sy = src_row + r;
        // Each tap's 16 source pixels decoded on their own: keeping the next group's tap-0
        // row and shifting it into tap 1 (as the 8-lane body does) measured slower here.
        if p0 != 0 {
            tap(p, &t, &source::<L, C>(p, source_g, col, sy), w0, p0, &mut acc);
        }
        if p1 != 0 {
            tap(p, &t, &source::<L, C>(p, source_g, col + 1, sy), w1, p1, &mut acc);
        }
    }
    let ok = if p.strict { acc.any_accepted & !acc.any_failed } else { acc.any_accepted };
    if ok != ALL {
        return false;
    }
    let inv_total = one / acc.total;
    let (max, smallest) = (splat(f32::MAX), splat(f32::MIN_POSITIVE));
    for c in 0..C {
        // `renormalise_simd`: the compare-and-select clamp to the finite range, then
        // `flush_subnormal`.
        let v = acc.sum[c] * inv_total;
        let v = sel(cmp::<_CMP_GT_OQ>(v, max), max, v);
        let v = sel(cmp::<_CMP_LT_OQ>(v, -max), -max, v);
        let v = sel(cmp::<_CMP_LT_OQ>(v.abs(), smallest), V::zero(), v);
        v.store(&mut row.channels[c][x..x + WIDE]);
    }
    if let Some(weight) = row.weight.as_deref_mut() {
        acc.total.fast_min(one).store(&mut weight[x..x + WIDE]);
    }
    row.reason[x..x + WIDE].fill(Reason::Reprojected as u8);
    counts.0[Reason::Reprojected as usize] += WIDE as u64;
    true
}

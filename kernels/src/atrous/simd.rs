//! The SIMD body of the à-trous filter: eight pixels of a row at a time where every tap is
//! inside the frame, the same operations in the same order as [`super::scalar`] lane for
//! lane; the pixels nearer a border go through the scalar reference.

use super::scalar::{self, Scalar};
use super::{
    AtrousStats, Body, DEPTH_EPSILON, EXP_TAYLOR, EXPONENT_MAX, FilterRow, GuideNormals, KERNEL, LUMINANCE_EPSILON,
    NORMAL_MIN_COS, Prepass, PrepassRow, Source, VALUE_MAX, WEIGHT_MIN,
};
use crate::colour::REC709_LUMINANCE;
use crate::gbuffer::decode_normals;
use crate::simd::{F32s, I32s, LANES, bits, load, store, u32x8};

pub(super) struct Simd;

/// Eight pixels of row `y` from `x` in each of three planes (written out: `array::map`
/// is not inlined here, and it would run once per tap).
#[inline(always)]
fn load3(planes: &[crate::frame::Plane<'_>; 3], y: usize, x: usize) -> [F32s; 3] {
    [load(planes[0].row(y), x), load(planes[1].row(y), x), load(planes[2].row(y), x)]
}

/// [`super::exp_neg`] on eight lanes (`t ≥ 0` and small: the plain conversion rounds to
/// nearest, ties to even, as the scalar `round_ties_even`).
#[inline(always)]
fn exp_neg(x: F32s) -> F32s {
    let t = x * F32s::splat(core::f32::consts::LOG2_E);
    let n = t.fast_round_int();
    let u = (t - n.round_float()) * F32s::splat(core::f32::consts::LN_2);
    let [c0, c1, c2, c3, c4, c5] = EXP_TAYLOR.map(F32s::splat);
    let u2 = u * u;
    let p = (c0 + c1 * u) + u2 * ((c2 + c3 * u) + u2 * (c4 + c5 * u));
    let scale: F32s = bytemuck::cast((I32s::splat(127) - n) << 23);
    p * scale
}

/// [`crate::colour::luminance`] on eight lanes.
#[inline(always)]
fn luminance(r: F32s, g: F32s, b: F32s) -> F32s {
    let [wr, wg, wb] = REC709_LUMINANCE.map(F32s::splat);
    wr * r + wg * g + wb * b
}

/// [`scalar::clamp_value`] on eight lanes: the clamped values and the mask of those outside.
#[inline(always)]
fn clamp_value(v: F32s) -> (F32s, F32s) {
    let max = F32s::splat(VALUE_MAX);
    let inside = v.simd_ge(F32s::ZERO) & v.simd_le(max);
    let clamped = v.simd_gt(max).select(max, v.simd_gt(F32s::ZERO).select(v, F32s::ZERO));
    (clamped, !inside)
}

#[inline(always)]
fn is_surface(z: F32s) -> F32s {
    z.simd_gt(F32s::ZERO) & z.simd_lt(F32s::splat(f32::INFINITY))
}

/// [`scalar::one_sided`] with both neighbours inside the frame.
#[inline(always)]
fn one_sided(z: F32s, a: F32s, b: F32s) -> F32s {
    let inf = F32s::splat(f32::INFINITY);
    let da = is_surface(a).select((z - a).abs(), inf);
    let db = is_surface(b).select((z - b).abs(), inf);
    da.simd_lt(db).select(da, db)
}

/// [`scalar::normal_term`] on eight lanes.
#[inline(always)]
fn normal_term(cos: F32s) -> F32s {
    let cos = cos.simd_gt(F32s::ONE).select(F32s::ONE, cos);
    let mut p = cos.simd_ge(F32s::splat(NORMAL_MIN_COS)).select(cos, F32s::ZERO);
    for _ in 0..7 {
        p = p * p;
    }
    p
}

impl Body for Simd {
    fn prepass_row(pre: &Prepass<'_>, y: usize, out: &mut PrepassRow<'_>) -> AtrousStats {
        let (w, h) = (pre.depth.width(), pre.depth.height());
        if y == 0 || y + 1 >= h || w < LANES + 2 {
            return Scalar::prepass_row(pre, y, out);
        }
        let mut stats = scalar::prepass_span(pre, y, 0..1, out);
        let mut x = 1;
        let channels = pre.input.channels();
        let depth = |x: usize, y: usize| load(pre.depth.row(y), x);
        while x + LANES < w {
            let mut outside = 0u32;
            for (c, plane) in channels.iter().enumerate() {
                let (v, o) = clamp_value(load(plane.row(y), x));
                store(out.colour[c], x, v);
                outside += bits(o).count_ones();
            }
            stats.out_of_range += u64::from(outside);
            let n = match &pre.normals {
                GuideNormals::Octahedral(p) => {
                    let packed: [u32; LANES] = p.row(y)[x..x + LANES].try_into().expect("LANES normals");
                    decode_normals(u32x8::from(packed))
                }
                GuideNormals::Planes(p) => load3(p, y, x),
            };
            for c in 0..3 {
                store(out.normal[c], x, n[c]);
            }
            let z = depth(x, y);
            let sx = one_sided(z, depth(x - 1, y), depth(x + 1, y));
            let sy = one_sided(z, depth(x, y - 1), depth(x, y + 1));
            let inf = F32s::splat(f32::INFINITY);
            let finite = |d: F32s| d.simd_lt(inf).select(d, F32s::ZERO);
            let slope = is_surface(z).select(finite(sx) + finite(sy), F32s::ZERO);
            store(out.slope, x, slope);
            let (mut sum, mut sum_sq) = (F32s::ZERO, F32s::ZERO);
            for ty in y - 1..y + 2 {
                for tx in x - 1..x + 2 {
                    let [r, g, b] = load3(&channels, ty, tx);
                    let (r, g, b) = (clamp_value(r).0, clamp_value(g).0, clamp_value(b).0);
                    let l = luminance(r, g, b);
                    sum += l;
                    sum_sq += l * l;
                }
            }
            let count = F32s::splat(9.0);
            let mean = sum / count;
            let v = sum_sq / count - mean * mean;
            store(out.variance, x, v.simd_gt(F32s::ZERO).select(v, F32s::ZERO));
            x += LANES;
        }
        stats.merged(scalar::prepass_span(pre, y, x..w, out))
    }

    fn filter_row(src: &Source<'_>, y: usize, step: usize, out: &mut FilterRow<'_>) {
        let (w, h) = (src.depth.width(), src.depth.height());
        let reach = 2 * step;
        if y < reach || y + reach >= h || w < 2 * reach + LANES {
            return Scalar::filter_row(src, y, step, out);
        }
        scalar::filter_span(src, y, step, 0..reach, out);
        let mut x = reach;
        while x + LANES - 1 + reach < w {
            filter_block(src, y, x, step, out);
            x += LANES;
        }
        scalar::filter_span(src, y, step, x..w, out);
    }
}

/// One row of an iteration's input planes.
struct TapRow<'a> {
    colour: [&'a [f32]; 3],
    variance: &'a [f32],
    depth: &'a [f32],
    normal: [&'a [f32]; 3],
}

impl<'a> TapRow<'a> {
    #[inline(always)]
    fn of(src: &Source<'a>, y: usize) -> Self {
        Self {
            colour: [src.colour[0].row(y), src.colour[1].row(y), src.colour[2].row(y)],
            variance: src.variance.row(y),
            depth: src.depth.row(y),
            normal: [src.normal[0].row(y), src.normal[1].row(y), src.normal[2].row(y)],
        }
    }
}

/// Pixels `x .. x + 8` of row `y`, every tap inside the frame.
#[inline(always)]
fn filter_block(src: &Source<'_>, y: usize, x: usize, step: usize, out: &mut FilterRow<'_>) {
    let colour = |x: usize, y: usize| load3(&src.colour, y, x);
    let z = load(src.depth.row(y), x);
    let c = colour(x, y);
    let var = load(src.variance.row(y), x);
    let l = luminance(c[0], c[1], c[2]);
    let n = load3(&src.normal, y, x);
    // `scalar::inverse_scales`.
    let inv_l = F32s::ONE / (F32s::splat(src.sigma_luminance) * var.sqrt() + F32s::splat(LUMINANCE_EPSILON));
    let a = F32s::splat(src.sigma_depth) * load(src.slope.row(y), x) * F32s::splat(step as f32);
    let b = F32s::splat(DEPTH_EPSILON) * z;
    let inv_z = [F32s::ONE / (a + b), F32s::ONE / (a * F32s::splat(2.0) + b)];
    let (mut sum, mut sum_w, mut sum_var) = ([F32s::ZERO; 3], F32s::ZERO, F32s::ZERO);
    for (dy, hy) in (-2isize..=2).zip(KERNEL) {
        let ty = (y as isize + dy * step as isize) as usize;
        // The tap row's slices once per row of taps, not once per tap and plane.
        let rows = TapRow::of(src, ty);
        for (dx, hx) in (-2isize..=2).zip(KERNEL) {
            let tx = (x as isize + dx * step as isize) as usize;
            let hh = F32s::splat(hy * hx);
            let tc = [load(rows.colour[0], tx), load(rows.colour[1], tx), load(rows.colour[2], tx)];
            let tv = load(rows.variance, tx);
            let weight = if dx == 0 && dy == 0 {
                hh
            } else {
                let tz = load(rows.depth, tx);
                let tn = [load(rows.normal[0], tx), load(rows.normal[1], tx), load(rows.normal[2], tx)];
                let dl = (l - luminance(tc[0], tc[1], tc[2])).abs();
                let dz = (z - tz).abs();
                let cos = n[0] * tn[0] + n[1] * tn[1] + n[2] * tn[2];
                let d = dx.unsigned_abs().max(dy.unsigned_abs());
                // `scalar::tap_weight`.
                let e = dl * inv_l + dz * inv_z[d - 1];
                let e = e.simd_lt(F32s::splat(EXPONENT_MAX)).select(e, F32s::splat(EXPONENT_MAX));
                let w = hh * exp_neg(e) * normal_term(cos);
                (is_surface(tz) & w.simd_ge(F32s::splat(WEIGHT_MIN))).select(w, F32s::ZERO)
            };
            for ch in 0..3 {
                sum[ch] += weight * tc[ch];
            }
            sum_w += weight;
            sum_var += weight * weight * tv;
        }
    }
    let surface = is_surface(z);
    let max = F32s::splat(VALUE_MAX);
    for ch in 0..3 {
        // `scalar::at_most_max`.
        let mean = sum[ch] / sum_w;
        store(out.colour[ch], x, surface.select(mean.simd_gt(max).select(max, mean), c[ch]));
    }
    store(out.variance, x, surface.select(sum_var / (sum_w * sum_w), var));
}

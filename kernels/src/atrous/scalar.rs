//! The scalar reference of the à-trous filter: one pixel at a time, taps in row order.

use std::ops::Range;

use super::{
    AtrousStats, Body, DEPTH_EPSILON, EXPONENT_MAX, FilterRow, GuideNormals, KERNEL, LUMINANCE_EPSILON, NORMAL_MIN_COS,
    Prepass, PrepassRow, Source, VALUE_MAX, WEIGHT_MIN, exp_neg,
};
use crate::colour::luminance;
use crate::gbuffer::decode_normal;

pub(super) struct Scalar;

impl Body for Scalar {
    fn prepass_row(pre: &Prepass<'_>, y: usize, out: &mut PrepassRow<'_>) -> AtrousStats {
        prepass_span(pre, y, 0..pre.depth.width(), out)
    }

    fn filter_row(src: &Source<'_>, y: usize, step: usize, out: &mut FilterRow<'_>) {
        filter_span(src, y, step, 0..src.depth.width(), out);
    }
}

/// A colour value clamped into [0, `VALUE_MAX`] (NaN → 0), and whether it was outside.
#[inline(always)]
pub(super) fn clamp_value(v: f32) -> (f32, bool) {
    let inside = (0.0..=VALUE_MAX).contains(&v);
    // Compare and select, as the SIMD body does: NaN fails `v > 0` and becomes 0.
    let clamped = if v > VALUE_MAX {
        VALUE_MAX
    } else if v > 0.0 {
        v
    } else {
        0.0
    };
    (clamped, !inside)
}

/// A weighted mean of values in [0, `VALUE_MAX`] may round above the maximum by an ulp: kept
/// inside, so every pass reads what the pre-pass guarantees.
#[inline(always)]
pub(super) fn at_most_max(v: f32) -> f32 {
    if v > VALUE_MAX { VALUE_MAX } else { v }
}

/// Whether a depth is a surface's.
#[inline(always)]
pub(super) fn is_surface(z: f32) -> bool {
    z > 0.0 && z < f32::INFINITY
}

/// The luminance of pixel `x` of row `y` with its channels clamped.
#[inline(always)]
fn clamped_luminance(input: &crate::frame::RgbPlanes<'_>, x: usize, y: usize) -> f32 {
    let [r, g, b] = input.get(x, y).map(|v| clamp_value(v).0);
    luminance(r, g, b)
}

/// The smaller one-sided depth difference to the neighbours `a` and `b` that are surfaces
/// (∞ where neither is).
#[inline(always)]
pub(super) fn one_sided(z: f32, a: Option<f32>, b: Option<f32>) -> f32 {
    let diff = |n: Option<f32>| match n {
        Some(n) if is_surface(n) => (z - n).abs(),
        _ => f32::INFINITY,
    };
    let (da, db) = (diff(a), diff(b));
    if da < db { da } else { db }
}

/// `|∂z/∂x| + |∂z/∂y|` from one-sided differences (module notes): 0 where a direction has
/// no surface neighbour, and where `z` is no surface.
#[inline(always)]
pub(super) fn slope_of(sx: f32, sy: f32, z: f32) -> f32 {
    let finite = |d: f32| if d < f32::INFINITY { d } else { 0.0 };
    if is_surface(z) { finite(sx) + finite(sy) } else { 0.0 }
}

/// Mean and variance from the sums of `n` luminances and their squares.
#[inline(always)]
pub(super) fn variance_of(sum: f32, sum_sq: f32, n: f32) -> f32 {
    let mean = sum / n;
    let v = sum_sq / n - mean * mean;
    if v > 0.0 { v } else { 0.0 }
}

/// The pre-pass over pixels `columns` of row `y`.
pub(super) fn prepass_span(
    pre: &Prepass<'_>,
    y: usize,
    columns: Range<usize>,
    out: &mut PrepassRow<'_>,
) -> AtrousStats {
    let (w, h) = (pre.depth.width(), pre.depth.height());
    let mut stats = AtrousStats::default();
    let depth = |x: usize, y: usize| pre.depth.get(x, y);
    for x in columns {
        for (c, plane) in pre.input.channels().iter().enumerate() {
            let (v, outside) = clamp_value(plane.get(x, y));
            out.colour[c][x] = v;
            stats.out_of_range += u64::from(outside);
        }
        let n = match &pre.normals {
            GuideNormals::Octahedral(p) => decode_normal(p.get(x, y)),
            GuideNormals::Planes(p) => [p[0].get(x, y), p[1].get(x, y), p[2].get(x, y)],
        };
        for c in 0..3 {
            out.normal[c][x] = n[c];
        }
        let z = depth(x, y);
        let sx = one_sided(z, (x > 0).then(|| depth(x - 1, y)), (x + 1 < w).then(|| depth(x + 1, y)));
        let sy = one_sided(z, (y > 0).then(|| depth(x, y - 1)), (y + 1 < h).then(|| depth(x, y + 1)));
        out.slope[x] = slope_of(sx, sy, z);
        let (mut sum, mut sum_sq, mut count) = (0.0f32, 0.0f32, 0.0f32);
        for ty in y.saturating_sub(1)..(y + 2).min(h) {
            for tx in x.saturating_sub(1)..(x + 2).min(w) {
                let l = clamped_luminance(&pre.input, tx, ty);
                sum += l;
                sum_sq += l * l;
                count += 1.0;
            }
        }
        out.variance[x] = variance_of(sum, sum_sq, count);
    }
    stats
}

/// The per-pixel factors of the edge-stopping exponent: `1/(σ_l·√var + ε_l)` and the depth
/// term's `1/(σ_z·slope·s·d + ε_z·z)` for tap distances `d` = 1 and 2.
#[inline(always)]
pub(super) fn inverse_scales(src: &Source<'_>, var: f32, slope: f32, z: f32, step: usize) -> (f32, [f32; 2]) {
    let inv_l = 1.0 / (src.sigma_luminance * var.sqrt() + LUMINANCE_EPSILON);
    let a = src.sigma_depth * slope * step as f32;
    let b = DEPTH_EPSILON * z;
    (inv_l, [1.0 / (a + b), 1.0 / (a * 2.0 + b)])
}

/// `n^128` of a cosine, 0 below [`NORMAL_MIN_COS`] (NaN included), and 1 above 1 (normals
/// that are not unit, as a G-buffer may hold, cannot weigh a tap above the centre).
#[inline(always)]
pub(super) fn normal_term(cos: f32) -> f32 {
    let cos = if cos > 1.0 { 1.0 } else { cos };
    let mut p = if cos >= NORMAL_MIN_COS { cos } else { 0.0 };
    for _ in 0..7 {
        p = p * p;
    }
    p
}

/// One tap's weight (its surface test included).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn tap_weight(hh: f32, dl: f32, inv_l: f32, dz: f32, inv_z: f32, cos: f32, surface: bool) -> f32 {
    let x = dl * inv_l + dz * inv_z;
    let x = if x < EXPONENT_MAX { x } else { EXPONENT_MAX };
    let w = hh * exp_neg(x) * normal_term(cos);
    if surface && w >= WEIGHT_MIN { w } else { 0.0 }
}

/// One iteration over pixels `columns` of row `y` with step `step`.
pub(super) fn filter_span(src: &Source<'_>, y: usize, step: usize, columns: Range<usize>, out: &mut FilterRow<'_>) {
    let (w, h) = (src.depth.width(), src.depth.height());
    let colour = |x: usize, y: usize| src.colour.each_ref().map(|p| p.get(x, y));
    for x in columns {
        let z = src.depth.get(x, y);
        let c = colour(x, y);
        let var = src.variance.get(x, y);
        if !is_surface(z) {
            for ch in 0..3 {
                out.colour[ch][x] = c[ch];
            }
            out.variance[x] = var;
            continue;
        }
        let l = luminance(c[0], c[1], c[2]);
        let n = src.normal.each_ref().map(|p| p.get(x, y));
        let (inv_l, inv_z) = inverse_scales(src, var, src.slope.get(x, y), z, step);
        let (mut sum, mut sum_w, mut sum_var) = ([0.0f32; 3], 0.0f32, 0.0f32);
        for (dy, hy) in (-2isize..=2).zip(KERNEL) {
            let ty = y as isize + dy * step as isize;
            if ty < 0 || ty >= h as isize {
                continue;
            }
            let ty = ty as usize;
            for (dx, hx) in (-2isize..=2).zip(KERNEL) {
                let tx = x as isize + dx * step as isize;
                if tx < 0 || tx >= w as isize {
                    continue;
                }
                let tx = tx as usize;
                let hh = hy * hx;
                let (tc, tv) = (colour(tx, ty), src.variance.get(tx, ty));
                let weight = if dx == 0 && dy == 0 {
                    hh
                } else {
                    let tz = src.depth.get(tx, ty);
                    let tn = src.normal.each_ref().map(|p| p.get(tx, ty));
                    let dl = (l - luminance(tc[0], tc[1], tc[2])).abs();
                    let dz = (z - tz).abs();
                    let cos = n[0] * tn[0] + n[1] * tn[1] + n[2] * tn[2];
                    let d = dx.unsigned_abs().max(dy.unsigned_abs());
                    tap_weight(hh, dl, inv_l, dz, inv_z[d - 1], cos, is_surface(tz))
                };
                for ch in 0..3 {
                    sum[ch] += weight * tc[ch];
                }
                sum_w += weight;
                sum_var += weight * weight * tv;
            }
        }
        for ch in 0..3 {
            out.colour[ch][x] = at_most_max(sum[ch] / sum_w);
        }
        out.variance[x] = sum_var / (sum_w * sum_w);
    }
}

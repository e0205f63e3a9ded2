//! The watertight ray–triangle test (Woop, Benthin and Wald 2013) with its double-precision
//! edge fallback and pbrt-v4's bound on the rounding error of `t`: the scalar reference, and
//! the same operations in eight lanes for single rays against eight triangles
//! ([`TriangleLanes`]) and packets against one triangle.

use crate::simd::{F32s, LANES};

use super::ray::{PreparedRay, Tri};

/// A triangle in BVH order: `v0, v1, v2` as nine floats (36 bytes, no padding) so that a
/// node's leaf triangles are one contiguous run.
pub type TriVerts = [f32; 9];

/// `tri`'s vertices as the triangle tests take them.
#[inline(always)]
pub fn tri_verts(tri: &Tri) -> TriVerts {
    let [a, b, c] = *tri;
    [a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]
}

/// Result of the watertight test before the barycentric division.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit (already divided by `det`).
    pub t: f32,
    /// Edge functions (unnormalised barycentrics of v0, v1, v2) and their sum.
    pub e: [f32; 3],
    /// The determinant (the edge functions' sum).
    pub det: f32,
}

impl TriHit {
    /// `(u, v)`: the weights of `v1` and `v2`.
    #[inline]
    pub fn uv(&self) -> (f32, f32) {
        (self.e[1] / self.det, self.e[2] / self.det)
    }
}

/// The edge function `ax·by − ay·bx` recomputed in double precision, where products of floats
/// are exact and the difference is rounded once, so its sign (and zero) is exact.
#[cold]
#[inline(never)]
pub(crate) fn edge_f64(ax: f32, ay: f32, bx: f32, by: f32) -> f32 {
    (ax as f64 * by as f64 - ay as f64 * bx as f64) as f32
}

/// Watertight ray–triangle test (Woop, Benthin, Wald 2013), scalar reference. Returns the
/// hit if `ray.tmin ≤ t < tmax` (`tmax` is passed separately so closest-hit search can shrink
/// it). Shared vertices give bit-identical transformed coordinates and the edge functions of a
/// shared edge are exact negatives, so a ray through an edge hits at least one triangle.
#[inline(always)]
pub fn intersect_triangle(r: &PreparedRay, tri: &TriVerts, tmax: f32) -> Option<TriHit> {
    let Watertight { hit, t_scaled, x, y, z } = watertight(r, tri)?;
    // NaN fails both comparisons.
    if !(hit.t >= r.tmin && hit.t < tmax) {
        return None;
    }
    let bound = t_rounding_bound(x, y, z, hit.det);
    if t_scaled.abs() > bound { Some(hit) } else { None }
}

/// The watertight test alone: the hit of the ray's *line* with the triangle (any `t`, no
/// rounding check), for a caller that already knows the ray sees this triangle and wants
/// its `t` and barycentrics exactly as [`intersect_triangle`] computes them (the
/// rasterised G-buffer's resolve).
#[inline(always)]
pub fn intersect_triangle_line(r: &PreparedRay, tri: &TriVerts) -> Option<TriHit> {
    watertight(r, tri).map(|w| w.hit)
}

/// Up to eight triangles of consecutive BVH slots as nine coordinate vectors
/// (`coords[3·vertex + axis][lane]`, unused lanes zero): the 288 contiguous bytes one
/// single-ray triangle test reads. [`TriangleBvh`](crate::bvh::TriangleBvh) keeps one block per eight slots of each
/// node's leaf run, so a node's leaves cost a few adjacent cache lines instead of one line
/// in each of nine scene-wide arrays (measured in `BENCHMARKS.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct TriangleLanes {
    /// Vertex coordinates per lane.
    pub coords: [[f32; LANES]; 9],
}

impl TriangleLanes {
    /// The block of `tris` (at most [`LANES`]; the lanes after them hold zeros).
    ///
    /// # Panics
    /// If `tris` holds more than [`LANES`] triangles.
    pub fn new(tris: &[TriVerts]) -> Self {
        assert!(tris.len() <= LANES, "a block holds at most {LANES} triangles");
        let mut coords = [[0.0; LANES]; 9];
        for (lane, tri) in tris.iter().enumerate() {
            for (c, &v) in tri.iter().enumerate() {
                coords[c][lane] = v;
            }
        }
        Self { coords }
    }
}

/// [`intersect_triangle`] of one ray against the triangles of `block` in `lanes` (bit `i`:
/// lane `i`): the same operations in the same order per lane, so each lane's hit, `t`, edge
/// functions and determinant equal the scalar test's bit for bit. Returns the hit with the
/// smallest `t` (the lowest lane on equal `t`, as testing the lanes one by one with a
/// shrinking `tmax` finds) and its lane.
#[inline(always)]
pub fn intersect_triangles_lanes(
    r: &PreparedRay,
    block: &TriangleLanes,
    lanes: u32,
    tmax: f32,
) -> Option<(u32, TriHit)> {
    let [kx, ky, kz] = r.k;
    let load = |vertex: usize, axis: usize| -> F32s { F32s::from(block.coords[3 * vertex + axis]) };
    let sp = F32s::splat;
    let vertices = [
        [load(0, kx), load(0, ky), load(0, kz)],
        [load(1, kx), load(1, ky), load(1, kz)],
        [load(2, kx), load(2, ky), load(2, kz)],
    ];
    let (mut hits, t, [u, v, w], det) =
        watertight_lanes(vertices, r.origin_k.map(sp), r.shear.map(sp), sp(r.tmin), sp(tmax), lanes);
    if hits == 0 {
        return None;
    }
    let (t, u, v, w, det) = (t.to_array(), u.to_array(), v.to_array(), w.to_array(), det.to_array());
    let mut best = hits.trailing_zeros() as usize;
    hits &= hits - 1;
    while hits != 0 {
        let i = hits.trailing_zeros() as usize;
        hits &= hits - 1;
        if t[i] < t[best] {
            best = i;
        }
    }
    Some((best as u32, TriHit { t: t[best], e: [u[best], v[best], w[best]], det: det[best] }))
}

/// [`intersect_triangle`] in eight lanes, operation for operation, shared by single rays
/// against eight triangles ([`intersect_triangles_lanes`]) and packets of eight rays against
/// one triangle. `vertices` are already permuted to the ray's axes (`[x, y, z]` = the
/// coordinates along `k`); origin and shear are the [`PreparedRay`]'s, per lane. Returns the
/// lanes of `m` hit with `tmin ≤ t < tmax` (and passing the rounding check), then `t`, the
/// edge functions and the determinant, meaningful in the hit lanes only.
#[inline(always)]
pub(crate) fn watertight_lanes(
    vertices: [[F32s; 3]; 3],
    origin_k: [F32s; 3],
    shear: [F32s; 3],
    tmin: F32s,
    tmax: F32s,
    m: u32,
) -> (u32, F32s, [F32s; 3], F32s) {
    let [[a_x, a_y, a_zk], [b_x, b_y, b_zk], [c_x, c_y, c_zk]] = vertices;
    let [ox, oy, oz] = origin_k;
    let [sx, sy, sz] = shear;
    // Relative to the origin, then sheared so the ray is the +z axis.
    let a_z = a_zk - oz;
    let b_z = b_zk - oz;
    let c_z = c_zk - oz;
    let ax = (a_x - ox) - sx * a_z;
    let ay = (a_y - oy) - sy * a_z;
    let bx = (b_x - ox) - sx * b_z;
    let by = (b_y - oy) - sy * b_z;
    let cx = (c_x - ox) - sx * c_z;
    let cy = (c_y - oy) - sy * c_z;
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    let zero = F32s::ZERO;
    let on_edge = (u.simd_eq(zero) | v.simd_eq(zero) | w.simd_eq(zero)).to_bitmask() & m;
    if on_edge != 0 {
        recompute_edges_lanes(on_edge, [ax, ay, bx, by, cx, cy], &mut u, &mut v, &mut w);
    }
    let neg = u.simd_lt(zero) | v.simd_lt(zero) | w.simd_lt(zero);
    let pos = u.simd_gt(zero) | v.simd_gt(zero) | w.simd_gt(zero);
    let det = u + v + w;
    let candidates = (!(neg & pos) & det.simd_ne(zero)).to_bitmask() & m;
    if candidates == 0 {
        return (0, zero, [zero; 3], zero);
    }
    let (z0, z1, z2) = (sz * a_z, sz * b_z, sz * c_z);
    let t_scaled = u * z0 + v * z1 + w * z2;
    let t = t_scaled / det;
    let in_range = (t.simd_ge(tmin) & t.simd_lt(tmax)).to_bitmask() & candidates;
    if in_range == 0 {
        return (0, t, [u, v, w], det);
    }
    let bound = t_rounding_bound_lanes([ax, bx, cx], [ay, by, cy], [z0, z1, z2], det);
    let hits = t_scaled.abs().simd_gt(bound).to_bitmask() & in_range;
    (hits, t, [u, v, w], det)
}

/// [`t_rounding_bound`] for every lane, operation for operation.
#[inline(always)]
fn t_rounding_bound_lanes(x: [F32s; 3], y: [F32s; 3], z: [F32s; 3], det: F32s) -> F32s {
    let max3 = |v: [F32s; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
    let (max_x, max_y, max_z, max_e) = (max3(x), max3(y), max3(z), det.abs());
    let g = |n| F32s::splat(gamma(n));
    let delta_z = g(3) * max_z;
    let delta_x = g(5) * (max_x + max_z);
    let delta_y = g(5) * (max_y + max_z);
    let delta_e = F32s::splat(2.0) * (g(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    F32s::splat(3.0) * (g(3) * max_e * max_z + delta_e * max_z + delta_z * max_e)
}

/// Lanes whose f32 edge functions hit exactly zero get all three recomputed in f64, as the
/// scalar test does.
#[cold]
#[inline(never)]
fn recompute_edges_lanes(lanes: u32, c: [F32s; 6], u: &mut F32s, v: &mut F32s, w: &mut F32s) {
    let [ax, ay, bx, by, cx, cy] = c.map(|x| x.to_array());
    let (mut ua, mut va, mut wa) = (u.to_array(), v.to_array(), w.to_array());
    for i in 0..LANES {
        if lanes & (1 << i) != 0 {
            ua[i] = edge_f64(cx[i], cy[i], bx[i], by[i]);
            va[i] = edge_f64(ax[i], ay[i], cx[i], cy[i]);
            wa[i] = edge_f64(bx[i], by[i], ax[i], ay[i]);
        }
    }
    (*u, *v, *w) = (F32s::from(ua), F32s::from(va), F32s::from(wa));
}

/// The shared body's result: the hit, `t·det`, and the sheared vertex coordinates the
/// rounding bound needs.
struct Watertight {
    hit: TriHit,
    t_scaled: f32,
    x: [f32; 3],
    y: [f32; 3],
    z: [f32; 3],
}

#[inline(always)]
fn watertight(r: &PreparedRay, tri: &TriVerts) -> Option<Watertight> {
    let [kx, ky, kz] = r.k;
    let [ox, oy, oz] = r.origin_k;
    let [sx, sy, sz] = r.shear;
    // Vertices relative to the origin, permuted, then sheared so the ray is the +z axis.
    let a_z = tri[kz] - oz;
    let b_z = tri[3 + kz] - oz;
    let c_z = tri[6 + kz] - oz;
    let ax = (tri[kx] - ox) - sx * a_z;
    let ay = (tri[ky] - oy) - sy * a_z;
    let bx = (tri[3 + kx] - ox) - sx * b_z;
    let by = (tri[3 + ky] - oy) - sy * b_z;
    let cx = (tri[6 + kx] - ox) - sx * c_z;
    let cy = (tri[6 + ky] - oy) - sy * c_z;
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = edge_f64(cx, cy, bx, by);
        v = edge_f64(ax, ay, cx, cy);
        w = edge_f64(bx, by, ax, ay);
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let (z0, z1, z2) = (sz * a_z, sz * b_z, sz * c_z);
    let t_scaled = u * z0 + v * z1 + w * z2;
    let t = t_scaled / det;
    Some(Watertight {
        hit: TriHit { t, e: [u, v, w], det },
        t_scaled,
        x: [ax, bx, cx],
        y: [ay, by, cy],
        z: [z0, z1, z2],
    })
}

/// `γ(n) = n·u / (1 − n·u)` with the unit roundoff `u = 2⁻²⁴`: the relative error bound of a
/// result of `n` rounded f32 operations (Higham; pbrt-v4 §6.8.1).
pub const fn gamma(n: u32) -> f32 {
    let nu = n as f32 * f32::EPSILON * 0.5;
    nu / (1.0 - nu)
}

/// An upper bound on the rounding error of the watertight test's `t`, times `|det|`
/// (pbrt-v4 §6.8.4): a hit whose `|t·det| = |Σ eᵢ zᵢ|` is at or below it may really lie
/// at or behind the origin. The shear arithmetic above matches pbrt's operation for
/// operation, so its bound applies: `x`, `y` are the sheared vertex coordinates, `z` the
/// scaled depths. Two simplifications, both absorbed by the bound's factor-3 slack: the
/// largest edge function is replaced by `|det|` (for a hit all three have one sign, so each
/// is at most their sum), and `t·|det|` is compared as `|t_scaled|` (equal up to one
/// rounding), which saves the maximum of three and a product per candidate. Identical in
/// [`crate::traverse`]'s lane version.
#[inline(always)]
pub(crate) fn t_rounding_bound(x: [f32; 3], y: [f32; 3], z: [f32; 3], det: f32) -> f32 {
    let max3 = |v: [f32; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
    let (max_x, max_y, max_z, max_e) = (max3(x), max3(y), max3(z), det.abs());
    let delta_z = gamma(3) * max_z;
    let delta_x = gamma(5) * (max_x + max_z);
    let delta_y = gamma(5) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    3.0 * (gamma(3) * max_e * max_z + delta_e * max_z + delta_z * max_e)
}

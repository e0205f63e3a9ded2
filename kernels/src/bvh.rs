//! Triangle BVH (obvhs CWBVH): the build, rays, the watertight triangle test and the robust
//! node test. Traversal (single rays and packets, closest and any hit) is in [`crate::traverse`].
//!
//! # What obvhs does and what this module does
//! The binary tree is ours by default (a binned SAH build, [`build_bvh2_binned_sah`]; its
//! SAH cost is 6–30 % below obvhs's PLOC tree on the built-in scenes, `BENCHMARKS.md`) or
//! obvhs's PLOC ([`BuildQuality::Fast`], `Medium`, `High`); obvhs then reinserts, collapses
//! it to its compressed 8-wide BVH (80-byte [`CwBvhNode`]s) and owns that layout; this module copies the triangles into BVH order
//! (one 36-byte record per `primitive_indices` slot, so a node's up-to-24 leaf triangles are
//! one contiguous run) and traverses the nodes itself. Single rays read each node again in
//! an uncompressed form with exact f32 child boxes ([`crate::bvh8`]: 256 bytes per node
//! beside the CWBVH's 80, and the triangles again in 288-byte blocks of eight per node's leaf
//! run, [`TriangleLanes`]), which traces them 1.1–1.6× faster on scenes of 67k–700k triangles (`BENCHMARKS.md`);
//! packets keep the CWBVH. obvhs's own traversal has four properties a path tracer cannot
//! live with:
//!
//! * its Möller–Trumbore test is not watertight: rays aimed exactly at an edge shared by two
//!   triangles can miss both. Here: Woop, Benthin and Wald 2013, *Watertight Ray/Triangle
//!   Intersection* (JCGT 2(1)), with its double-precision fallback for edge functions that
//!   round to exactly zero ([`intersect_triangle`]);
//! * its node test clamps the entry distance to a fixed 1e-4, so hits nearer than that are
//!   never found. Here the node test uses the ray's own `tmin` (0 by default);
//! * its traversal stack holds 32 groups and overflows silently on a deep tree (thousands of
//!   coincident triangles make PLOC produce a chain). Here the build measures the depth and,
//!   if it exceeds [`MAX_DEPTH`], rebuilds from a median-split binary tree (depth ≤ log₂ n),
//!   so the fixed-size stacks of both traversals provably cannot overflow;
//! * an empty triangle list and zero/NaN/inf directions are not handled. Here an empty BVH
//!   answers every query with a miss, and invalid rays ([`Ray::is_valid`]) miss without
//!   traversal.
//!
//! # Robust node test
//! A child box of a CWBVH node is `p + q·e` per axis (`q` an 8-bit integer, `e` a power of
//! two), and the slab distance is computed as `q·(e·inv) + (p − o)·inv`. obvhs quantises
//! child boxes outwards, but in floating point: decoding can land inside the true box by
//! about one ulp of `|cmin − p|`, and the slab arithmetic adds a few more rounding errors.
//! Together they are at most about `6·2⁻²⁴·|inv|·(|p − o| + 255·e)` (one rounding each in
//! `1/d`, `e·inv`, `p − o`, `·inv`, `q·a`, the sums, plus the decoding error). Each slab
//! interval is widened by `δ = 16·2⁻²⁴·|inv|·(|p − o| + 255·e)`, so the node test is
//! conservative with a margin of ~2.5×; since `δ` is also ≥ 2⁻²⁰ of the slab distance
//! itself, it covers the few-ulp error of the triangle test's `t` that closest-hit culling
//! compares against. The widening is about a millionth of the node size and costs nothing
//! measurable; traversal finds exactly what brute force over all triangles finds (tested on
//! random soups, Sponza and the bunny).
//!
//! Directions use a safe reciprocal: components with `|d| < 2⁻⁸⁰` become `±2⁸⁰` (sign of
//! `d`, so `−0.0` gives `−2⁸⁰`), never `±inf`, so no `0·inf = NaN` enters the slab test.
//! Together with the coordinate limits ([`MAX_COORD`], [`MAX_ORIGIN`] and the direction
//! range of [`Ray::is_valid`]) every quantity in the node test stays finite and no NaN can
//! occur, which is why the node test may use the `fast_min`/`fast_max` instructions.
//!
//! # Hit convention
//! A ray hits a triangle at `t` when `tmin ≤ t < tmax` (half-open: a shadow ray with
//! `tmax` = light distance does not see the light's own surface). Both faces count. The hit
//! point is `(1 − u − v)·v0 + u·v1 + v·v2`. A ray through an edge or vertex shared by
//! several triangles hits at least one of them: the edge functions of a shared edge are
//! computed from bit-identical transformed vertices and are exact negatives of each other,
//! and values that round to exactly zero are recomputed in double precision, so rays never
//! slip through a closed mesh. Ties in `t` between triangles are
//! resolved by traversal order, which differs between traversal kinds; everything else
//! (hit or miss, `t` bit for bit, `u`, `v`) is the same for single rays, packets and brute
//! force.
//!
//! A hit also needs `t` above the bound on its own rounding error (`t_rounding_bound`,
//! pbrt-v4's conservative test), so a ray leaving a surface never finds that surface again
//! however far the scene sits from the origin.
//!
//! # Determinism
//! Plain `a * b + c` (see [`crate::simd`]); `t = T / det` and the barycentrics are IEEE
//! divisions, never approximate reciprocals. The SIMD node test and its scalar reference
//! ([`node_hits`], [`node_hits_scalar`]) agree bit for bit.

use core::fmt;
use std::time::{Duration, Instant};

use glam::{Vec3, Vec3A};
pub use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ploc::PlocBuilder;
use obvhs::splits::split_aabbs_preset;
use obvhs::triangle::Triangle as ObvhsTriangle;

use crate::bvh8::{WideNode, wide_nodes};
use crate::simd::{F32s, LANES};

/// Largest accepted `|coordinate|` of a triangle vertex (2²⁴ m ≈ 16 800 km).
pub const MAX_COORD: f32 = 16_777_216.0;
/// Largest accepted `|coordinate|` of a ray origin (2²⁶ m); rays starting farther away miss.
pub const MAX_ORIGIN: f32 = 67_108_864.0;
/// Smallest accepted largest-direction-component magnitude (2⁻³²).
pub const MIN_DIR: f32 = 1.0 / 4_294_967_296.0;
/// Largest accepted direction component magnitude (2³²).
pub const MAX_DIR: f32 = 4_294_967_296.0;
/// Deepest CWBVH (levels, root = 1) the traversal stacks are sized for. Trees deeper than
/// this (PLOC's or the SAH build's) are rebuilt by median split. Sponza's PLOC tree is 10 levels deep, the bench's 700k
/// procedural scene 12; 5000 coincident triangles give PLOC a chain 714 levels deep.
pub const MAX_DEPTH: usize = 40;

/// Components of a direction below this magnitude use `±1/RCP_CLAMP` as their reciprocal.
pub(crate) const RCP_CLAMP: f32 = f32::from_bits((127 - 80) << 23); // 2^-80
/// Relative widening of every slab interval (see the module notes).
pub(crate) const NODE_PAD: f32 = f32::from_bits((127 - 20) << 23); // 2^-20

/// A triangle as three vertices (counter-clockwise winding gives the front face, though both
/// faces are hit).
pub type Tri = [Vec3; 3];

/// Build quality presets, mapped onto obvhs's `BvhBuildParams`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BuildQuality {
    /// `fast_build`: PLOC search distance 6, little reinsertion.
    Fast,
    /// `medium_build`: search distance 14, "about Embree's build time with faster traversal"
    /// per obvhs.
    Medium,
    /// `slow_build`: spatial pre-splits of large triangles, search distance 24, more
    /// reinsertion. A triangle may then appear in several leaves.
    High,
    /// The default: a top-down binned SAH build (ours, [`build_bvh2_binned_sah`]) instead of
    /// PLOC, then the medium preset's reinsertion and obvhs's collapse to the 8-wide tree.
    /// It builds in about twice PLOC-medium's time and traces single rays 1.0–1.6× as fast
    /// on the scenes measured (`BENCHMARKS.md`, the attribution table).
    #[default]
    Sah,
}

impl BuildQuality {
    /// The obvhs parameters of this preset (a starting point for
    /// [`TriangleBvh::build_with`]).
    pub fn params(self) -> BvhBuildParams {
        match self {
            BuildQuality::Fast => BvhBuildParams::fast_build(),
            BuildQuality::Medium => BvhBuildParams::medium_build(),
            BuildQuality::High => BvhBuildParams::slow_build(),
            BuildQuality::Sah => BvhBuildParams::medium_build(),
        }
    }
}

/// Why a triangle list was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhError {
    /// A vertex coordinate is NaN, infinite or larger than [`MAX_COORD`] in magnitude.
    BadVertex {
        /// Index of the offending triangle.
        triangle: usize,
    },
    /// More triangles than the `u32` indices can address (2³¹ − 1 is the limit).
    TooManyTriangles {
        /// How many were given.
        count: usize,
    },
    /// Build parameters outside what [`TriangleBvh::build_with`] accepts.
    BadParams {
        /// Which parameter, and what it must be.
        reason: &'static str,
    },
}

impl fmt::Display for BvhError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BvhError::BadVertex { triangle } => {
                write!(f, "triangle {triangle} has a vertex coordinate that is not finite or exceeds ±{MAX_COORD}")
            }
            BvhError::TooManyTriangles { count } => {
                write!(f, "{count} triangles: at most {} are supported", i32::MAX)
            }
            BvhError::BadParams { reason } => write!(f, "BVH build parameters: {reason}"),
        }
    }
}

impl std::error::Error for BvhError {}

/// What a build produced and what it cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildStats {
    /// Input triangles.
    pub triangles: usize,
    /// Leaf references (more than `triangles` with spatial splits).
    pub references: usize,
    /// CWBVH nodes.
    pub nodes: usize,
    /// CWBVH depth in levels (root = 1; 0 for an empty BVH).
    pub depth: usize,
    /// Depth of the first tree built, PLOC's or the SAH build's (equal to `depth` unless the
    /// median fallback replaced it).
    pub ploc_depth: usize,
    /// The preset used (`None` for parameters given to [`TriangleBvh::build_with`]).
    pub quality: Option<BuildQuality>,
    /// True if the first tree was deeper than [`MAX_DEPTH`] and the median-split fallback was
    /// used.
    pub median_fallback: bool,
    /// Time in obvhs's builder (PLOC, reinsertion, CWBVH conversion), without the fallback.
    pub obvhs_time: Duration,
    /// Wall time of the whole build: validation, obvhs, fallback and the triangle layout.
    pub total_time: Duration,
}

/// A ray `origin + t·dir` for `t ∈ [tmin, tmax)`. `dir` need not be normalised; `t` is in
/// units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction (any non-zero length).
    pub dir: Vec3,
    /// Nearest accepted `t`.
    pub tmin: f32,
    /// Farthest `t` (exclusive): a hit must be nearer.
    pub tmax: f32,
}

impl Ray {
    /// An infinite ray (`tmin = 0`, `tmax = inf`).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir, tmin: 0.0, tmax: f32::INFINITY }
    }

    /// A ray restricted to `[tmin, tmax)`.
    #[inline]
    pub fn segment(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Self { origin, dir, tmin, tmax }
    }

    /// Whether queries trace this ray; an invalid ray is reported as a miss. Valid: every
    /// origin coordinate finite with magnitude ≤ [`MAX_ORIGIN`]; every direction component
    /// finite, at least one of magnitude ≥ [`MIN_DIR`] and none above [`MAX_DIR`];
    /// `0 ≤ tmin < tmax` with `tmin` finite (`tmax` may be `+inf`). NaN anywhere is invalid.
    #[inline]
    pub fn is_valid(&self) -> bool {
        let o = self.origin.abs();
        let d = self.dir.abs();
        // Written so that NaN fails every comparison.
        let origin_ok = o.x <= MAX_ORIGIN && o.y <= MAX_ORIGIN && o.z <= MAX_ORIGIN;
        let dir_ok = d.x <= MAX_DIR && d.y <= MAX_DIR && d.z <= MAX_DIR && d.max_element() >= MIN_DIR;
        let t_ok = self.tmin >= 0.0 && self.tmin < f32::INFINITY && self.tmin < self.tmax;
        origin_ok && dir_ok && t_ok
    }
}

/// A closest hit: distance, the caller's triangle index and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit (in units of the ray's direction).
    pub t: f32,
    /// Index into the triangle list the BVH was built from.
    pub prim: u32,
    /// Weight of `v1`.
    pub u: f32,
    /// Weight of `v2`.
    pub v: f32,
}

impl Hit {
    /// The "no hit" record (`prim == u32::MAX`, `t = inf`).
    pub const NONE: Hit = Hit { t: f32::INFINITY, prim: u32::MAX, u: 0.0, v: 0.0 };

    /// Whether this is a hit (not [`Hit::NONE`]).
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.prim != u32::MAX
    }
}

/// Per-ray constants shared by the node test and the watertight triangle test. One lane of a
/// packet holds exactly these values, so packet and single-ray arithmetic are identical.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedRay {
    /// The ray's origin.
    pub origin: Vec3A,
    /// Safe reciprocal of the direction (never 0, inf or NaN).
    pub inv: Vec3A,
    /// `NODE_PAD · |inv|` per axis: the slab widening per unit of `|p − o| + 255·e`.
    pub pad: Vec3A,
    /// obvhs's inverted octant: bit 2/1/0 set when `inv.x/y/z` is positive. Children are
    /// visited in descending `slot ^ oct_inv` order (front to back for this octant).
    pub oct_inv: u32,
    /// Axis permutation of the watertight test: `kz` is the dominant direction axis.
    pub k: [usize; 3],
    /// Shear constants `(d[kx]/d[kz], d[ky]/d[kz], 1/d[kz])`.
    pub shear: [f32; 3],
    /// The origin permuted: `(o[kx], o[ky], o[kz])`.
    pub origin_k: [f32; 3],
    /// Nearest accepted `t`.
    pub tmin: f32,
    /// Farthest `t` (exclusive); closest-hit traversal shrinks it.
    pub tmax: f32,
}

/// Reciprocal that is never 0, infinite or NaN for finite input (see the module notes).
#[inline(always)]
pub fn safe_rcp(d: f32) -> f32 {
    if d.abs() < RCP_CLAMP { (1.0 / RCP_CLAMP).copysign(d) } else { 1.0 / d }
}

impl PreparedRay {
    /// `None` for an invalid ray (see [`Ray::is_valid`]).
    #[inline]
    pub fn new(ray: &Ray) -> Option<Self> {
        let mut r = Self::for_triangles(ray)?;
        let inv = ray.dir.to_array().map(safe_rcp);
        r.inv = Vec3A::from_array(inv);
        r.pad = Vec3A::from_array(inv.map(|i| NODE_PAD * i.abs()));
        r.oct_inv = (if inv[0] < 0.0 { 0 } else { 4 })
            | (if inv[1] < 0.0 { 0 } else { 2 })
            | (if inv[2] < 0.0 { 0 } else { 1 });
        Some(r)
    }

    /// The fields [`intersect_triangle`] reads (axis permutation, shear, origin, `t` range)
    /// without the node test's reciprocals ([`PreparedRay::new`] adds them): for callers
    /// that test single triangles (the rasteriser's exact path). `None` for an invalid ray.
    #[inline]
    pub fn for_triangles(ray: &Ray) -> Option<Self> {
        if !ray.is_valid() {
            return None;
        }
        let o = ray.origin.to_array();
        let d = ray.dir.to_array();
        let a = d.map(f32::abs);
        let kz = if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding (and so the sign convention of the edge functions) per ray.
        if d[kz] < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        Some(Self {
            origin: Vec3A::from_array(o),
            inv: Vec3A::ZERO,
            pad: Vec3A::ZERO,
            oct_inv: 0,
            k: [kx, ky, kz],
            shear: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
            origin_k: [o[kx], o[ky], o[kz]],
            tmin: ray.tmin,
            tmax: ray.tmax,
        })
    }

    /// Dominant-axis class used to group packet lanes: `oct_inv | kz << 3` (0..24). Lanes
    /// of one class share the node-test plane choice and the triangle-test permutation.
    #[inline]
    pub fn class(&self) -> u32 {
        self.oct_inv | ((self.k[2] as u32) << 3)
    }
}

/// A triangle in BVH order: `v0, v1, v2` as nine floats (36 bytes, no padding) so that a
/// node's leaf triangles are one contiguous run.
pub type TriVerts = [f32; 9];

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
/// single-ray triangle test reads. [`TriangleBvh`] keeps one block per eight slots of each
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

/// Slab constants of one node for one ray: per axis `a = e·inv`, `bn = (p−o)·inv − δ`,
/// `bf = (p−o)·inv + δ` with `δ = pad·(255·e + |p−o|)`. Computed with SSE `Vec3A`
/// arithmetic (one instruction per operation for all three axes; the per-axis scalar version
/// was ~15 % of a primary ray's time); each lane is the same IEEE operation as the scalar
/// formula, so packets (which compute it per lane in `F32s`) agree bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct NodeSlabs {
    /// Per axis, `e·inv`: the ray parameter per quantisation step of the node.
    pub a: Vec3A,
    /// Per axis, `(p − o)·inv − δ`: the ray parameter of the node's origin plane, lowered by
    /// the rounding pad (for the near planes).
    pub bn: Vec3A,
    /// Per axis, `(p − o)·inv + δ`: the same, raised by the pad (for the far planes).
    pub bf: Vec3A,
}

/// The node's per-axis quantisation step `e` (a power of two).
#[inline(always)]
pub fn node_extent(node: &CwBvhNode) -> [f32; 3] {
    node.e.map(|e| f32::from_bits((e as u32) << 23))
}

/// The slab constants of `node` for ray `r` (see [`NodeSlabs`]).
#[inline(always)]
pub fn node_slabs(node: &CwBvhNode, r: &PreparedRay) -> NodeSlabs {
    let e = Vec3A::from_array(node_extent(node));
    let po = Vec3A::from(node.p) - r.origin;
    let b = po * r.inv;
    let delta = r.pad * (Vec3A::splat(255.0) * e + po.abs());
    NodeSlabs { a: e * r.inv, bn: b - delta, bf: b + delta }
}

/// Near and far quantised planes of every child for a ray whose reciprocal direction has the
/// given signs: `(near_x, near_y, near_z, far_x, far_y, far_z)`.
#[inline(always)]
pub fn child_planes(node: &CwBvhNode, neg: [bool; 3]) -> [&[u8; 8]; 6] {
    let (nx, fx) = if neg[0] { (&node.child_max_x, &node.child_min_x) } else { (&node.child_min_x, &node.child_max_x) };
    let (ny, fy) = if neg[1] { (&node.child_max_y, &node.child_min_y) } else { (&node.child_min_y, &node.child_max_y) };
    let (nz, fz) = if neg[2] { (&node.child_max_z, &node.child_min_z) } else { (&node.child_min_z, &node.child_max_z) };
    [nx, ny, nz, fx, fy, fz]
}

/// Bit `s` set when child slot `s` is occupied (inner or leaf). Both kinds have a non-zero
/// high 3-bit field in `child_meta`; empty slots are all zero.
#[inline(always)]
pub fn occupied_slots(node: &CwBvhNode) -> u32 {
    let m = u64::from_le_bytes(node.child_meta) & 0xE0E0_E0E0_E0E0_E0E0;
    // Fold the three flag bits of every byte into its bit 7, then gather bit 7 of each byte.
    let b = (m | (m << 1) | (m << 2)) & 0x8080_8080_8080_8080;
    ((b >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

/// `if a > b { a } else { b }`: the scalar twin of `maxps` (and of `F32s::fast_max`).
#[inline(always)]
pub(crate) fn max1(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// `if a < b { a } else { b }`: the scalar twin of `minps`.
#[inline(always)]
pub(crate) fn min1(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

#[inline(always)]
fn neg_axes(r: &PreparedRay) -> [bool; 3] {
    [r.oct_inv & 4 == 0, r.oct_inv & 2 == 0, r.oct_inv & 1 == 0]
}

/// Scalar reference of [`node_hits`]: bit `s` set when the ray overlaps child `s` within
/// `[tmin, tmax]` (occupied slots only).
pub fn node_hits_scalar(node: &CwBvhNode, r: &PreparedRay, tmax: f32) -> u32 {
    let s = node_slabs(node, r);
    let planes = child_planes(node, neg_axes(r));
    let mut hits = 0;
    for c in 0..8 {
        let q = planes.map(|p| p[c] as f32);
        let nx = q[0] * s.a[0] + s.bn[0];
        let ny = q[1] * s.a[1] + s.bn[1];
        let nz = q[2] * s.a[2] + s.bn[2];
        let fx = q[3] * s.a[0] + s.bf[0];
        let fy = q[4] * s.a[1] + s.bf[1];
        let fz = q[5] * s.a[2] + s.bf[2];
        let tn = max1(max1(nx, ny), max1(nz, r.tmin));
        let tf = min1(min1(fx, fy), min1(fz, tmax));
        if tn <= tf {
            hits |= 1 << c;
        }
    }
    hits & occupied_slots(node)
}

/// Eight bytes as eight floats (`vpmovzxbd` + `vcvtdq2ps` with AVX2).
#[inline(always)]
pub fn bytes_to_f32s(b: &[u8; 8]) -> F32s {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        use core::arch::x86_64::{__m128i, _mm_loadl_epi64, _mm256_cvtepi32_ps, _mm256_cvtepu8_epi32};
        // SAFETY: `_mm_loadl_epi64` reads exactly 8 bytes (unaligned is fine) from `b`, which
        // is a valid `[u8; 8]`; AVX2 is enabled at compile time (cfg above).
        unsafe {
            let v = _mm_loadl_epi64(b.as_ptr().cast::<__m128i>());
            F32s::from(_mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(v)))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        F32s::from(b.map(|x| x as f32))
    }
}

/// SIMD node test (one ray, eight children at once); bit-identical to [`node_hits_scalar`].
#[inline(always)]
pub fn node_hits(node: &CwBvhNode, r: &PreparedRay, tmax: f32) -> u32 {
    let s = node_slabs(node, r);
    let [pnx, pny, pnz, pfx, pfy, pfz] = child_planes(node, neg_axes(r));
    let sp = F32s::splat;
    let nx = bytes_to_f32s(pnx) * sp(s.a[0]) + sp(s.bn[0]);
    let ny = bytes_to_f32s(pny) * sp(s.a[1]) + sp(s.bn[1]);
    let nz = bytes_to_f32s(pnz) * sp(s.a[2]) + sp(s.bn[2]);
    let fx = bytes_to_f32s(pfx) * sp(s.a[0]) + sp(s.bf[0]);
    let fy = bytes_to_f32s(pfy) * sp(s.a[1]) + sp(s.bf[1]);
    let fz = bytes_to_f32s(pfz) * sp(s.a[2]) + sp(s.bf[2]);
    // No NaN can occur (module notes), so the plain max/min instructions are exact here.
    let tn = nx.fast_max(ny).fast_max(nz.fast_max(sp(r.tmin)));
    let tf = fx.fast_min(fy).fast_min(fz.fast_min(sp(tmax)));
    let hits = tn.simd_le(tf).to_bitmask() & occupied_slots(node);
    #[cfg(feature = "check-scalar")]
    assert_eq!(hits, node_hits_scalar(node, r, tmax), "SIMD node test disagrees with its scalar reference");
    hits
}

/// Index of inner child `slot` of a node with `imask` whose children start at `base`.
#[inline(always)]
pub fn inner_child_index(base: u32, imask: u32, slot: u32) -> u32 {
    base + (imask & ((1u32 << slot) - 1)).count_ones()
}

/// First BVH slot and count of the leaf in child `slot`.
#[inline(always)]
pub fn leaf_range(node: &CwBvhNode, slot: usize) -> (u32, u32) {
    let (offset, count) = leaf_meta(node.child_meta[slot]);
    (node.primitive_base_idx + offset, count)
}

/// A leaf child's `child_meta` byte decoded: its first slot's offset in the node's run (low
/// five bits) and its triangle count (the high three bits, unary).
#[inline(always)]
pub fn leaf_meta(meta: u8) -> (u32, u32) {
    (u32::from(meta & 0x1F), (meta >> 5).count_ones())
}

/// A BVH over a triangle list, with the triangles stored in BVH order.
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    cwbvh: CwBvh,
    /// Triangles in `cwbvh.primitive_indices` order.
    tris: Vec<TriVerts>,
    /// The same triangles in blocks of eight for single rays ([`TriangleLanes`]): each
    /// node's leaf run, from its `primitive_base_idx`, in `ceil(run / 8)` consecutive blocks
    /// from its wide node's `block_base`.
    blocks: Vec<TriangleLanes>,
    /// The nodes again for single rays, with exact f32 child boxes ([`crate::bvh8`]).
    wide: Vec<WideNode>,
    /// The exact bounds of every triangle (`[min, max]`; zeros when empty).
    bounds: [[f32; 3]; 2],
    /// `primitive_indices` (BVH slot → caller's triangle index), kept as its own array.
    prim_ids: Vec<u32>,
    stats: BuildStats,
}

impl TriangleBvh {
    /// Builds the BVH. Empty input gives an empty BVH (every query misses). Degenerate and
    /// zero-area triangles are accepted (they are never hit).
    pub fn build(tris: &[Tri], quality: BuildQuality) -> Result<(Self, BuildStats), BvhError> {
        Self::build_from(tris, &quality.params(), Some(quality))
    }

    /// [`build`](Self::build) with obvhs's parameters given one by one, for tuning the tree
    /// (the traversal bench sweeps them). A CWBVH leaf holds at most 3 triangles per child, so
    /// `max_prims_per_leaf` above 3 acts as 3; `Bvh2`-only fields
    /// (`post_collapse_reinsertion_batch_ratio_multiplier`, `collapse_traversal_cost`) are
    /// ignored, as obvhs ignores them for a CWBVH.
    ///
    /// # Errors
    /// Those of [`build`](Self::build), and [`BvhError::BadParams`] for
    /// `max_prims_per_leaf == 0` or a reinsertion ratio that is not finite or outside
    /// `[0, 16]` (16 passes over every node are already far past any gain).
    pub fn build_with(tris: &[Tri], params: &BvhBuildParams) -> Result<(Self, BuildStats), BvhError> {
        if params.max_prims_per_leaf == 0 {
            return Err(BvhError::BadParams { reason: "max_prims_per_leaf must be at least 1" });
        }
        if !(0.0..=16.0).contains(&params.reinsertion_batch_ratio) {
            return Err(BvhError::BadParams { reason: "reinsertion_batch_ratio must be within [0, 16]" });
        }
        Self::build_from(tris, params, None)
    }

    fn build_from(
        tris: &[Tri],
        params: &BvhBuildParams,
        quality: Option<BuildQuality>,
    ) -> Result<(Self, BuildStats), BvhError> {
        let start = Instant::now();
        if tris.len() > i32::MAX as usize {
            return Err(BvhError::TooManyTriangles { count: tris.len() });
        }
        for (i, t) in tris.iter().enumerate() {
            let ok = t.iter().all(|v| v.abs().cmple(Vec3::splat(MAX_COORD)).all());
            if !ok {
                return Err(BvhError::BadVertex { triangle: i });
            }
        }
        let mut obvhs_time = Duration::ZERO;
        let mut median_fallback = false;
        let mut ploc_depth = 0;
        let cwbvh = if tris.is_empty() {
            CwBvh::default()
        } else {
            let t0 = Instant::now();
            let bvh = match quality {
                Some(BuildQuality::Sah) => build_cwbvh_sah(tris, params),
                _ => build_cwbvh_ploc(tris, params),
            };
            obvhs_time = t0.elapsed();
            ploc_depth = cwbvh_depth(&bvh);
            if ploc_depth > MAX_DEPTH {
                median_fallback = true;
                let bvh = bvh2_to_cwbvh(&build_bvh2_median(tris), 3, true, false);
                assert!(cwbvh_depth(&bvh) <= MAX_DEPTH, "median-split CWBVH deeper than MAX_DEPTH");
                bvh
            } else {
                bvh
            }
        };
        let prim_ids = cwbvh.primitive_indices.clone();
        let tris_bvh: Vec<TriVerts> = prim_ids
            .iter()
            .map(|&i| {
                let [a, b, c] = tris[i as usize];
                [a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]
            })
            .collect();
        let stats = BuildStats {
            triangles: tris.len(),
            references: prim_ids.len(),
            nodes: cwbvh.nodes.len(),
            depth: cwbvh_depth(&cwbvh),
            ploc_depth,
            quality,
            median_fallback,
            obvhs_time,
            total_time: start.elapsed(),
        };
        let (blocks, block_bases) = leaf_blocks(&cwbvh.nodes, &tris_bvh);
        let (wide, bounds) = wide_nodes(&cwbvh.nodes, &tris_bvh, &block_bases);
        Ok((Self { cwbvh, tris: tris_bvh, blocks, wide, bounds, prim_ids, stats }, stats))
    }

    /// The build statistics.
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }

    /// The obvhs tree (for peer baselines and tools; do not traverse it with obvhs's own
    /// traversal where exactness matters, see the module notes).
    pub fn cwbvh(&self) -> &CwBvh {
        &self.cwbvh
    }

    /// The CWBVH nodes.
    #[inline]
    pub fn nodes(&self) -> &[CwBvhNode] {
        &self.cwbvh.nodes
    }

    /// Triangles in BVH order (slot `i` is the caller's triangle [`Self::original_index`]`(i)`).
    #[inline]
    pub fn triangles_bvh_order(&self) -> &[TriVerts] {
        &self.tris
    }

    /// The caller's triangle index of BVH slot `slot`.
    #[inline]
    pub fn original_index(&self, slot: u32) -> u32 {
        self.prim_ids[slot as usize]
    }

    /// True if the BVH holds no triangle.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.cwbvh.nodes.is_empty()
    }

    #[inline(always)]
    pub(crate) fn tri(&self, slot: u32) -> &TriVerts {
        &self.tris[slot as usize]
    }

    /// The exact bounds of every triangle (`[min, max]`; zeros for an empty BVH).
    #[inline]
    pub fn bounds(&self) -> &[[f32; 3]; 2] {
        &self.bounds
    }

    /// The nodes for single rays (index `i` is CWBVH node `i`).
    #[inline]
    pub fn wide_nodes(&self) -> &[WideNode] {
        &self.wide
    }

    /// The tree's surface-area-heuristic cost: the expected cost of a ray through the root
    /// box, `node_cost` per node read (one 8-wide box test) and `triangle_cost` per triangle
    /// test, each weighted by the probability `area(box) / area(root box)` that a random ray
    /// through the root enters the box (the root's node counted once). The quality measure a
    /// builder minimises, comparable between trees of the same triangles and width; 0 for an
    /// empty tree.
    pub fn sah_cost(&self, node_cost: f64, triangle_cost: f64) -> f64 {
        fn area(lo: [f32; 3], hi: [f32; 3]) -> f64 {
            let d = [0, 1, 2].map(|k| (f64::from(hi[k]) - f64::from(lo[k])).max(0.0));
            2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
        }
        let root = area(self.bounds[0], self.bounds[1]);
        if self.is_empty() || root <= 0.0 {
            return 0.0;
        }
        let mut cost = node_cost;
        for node in &self.wide {
            for slot in 0..LANES {
                if node.occupied & (1 << slot) == 0 {
                    continue;
                }
                let p = &node.planes;
                let a = area([p[0][slot], p[1][slot], p[2][slot]], [p[3][slot], p[4][slot], p[5][slot]]) / root;
                cost += if node.imask & (1 << slot) != 0 {
                    node_cost * a
                } else {
                    triangle_cost * f64::from(leaf_meta(node.child_meta[slot]).1) * a
                };
            }
        }
        cost
    }

    /// Block `chunk` of `node`'s leaf run (slots `primitive_base + 8·chunk ..`).
    #[inline(always)]
    pub(crate) fn leaf_block(&self, node: &WideNode, chunk: u32) -> &TriangleLanes {
        &self.blocks[(node.block_base + chunk) as usize]
    }
}

/// The [`TriangleLanes`] blocks of every node's leaf run and each node's first block.
fn leaf_blocks(nodes: &[CwBvhNode], tris: &[TriVerts]) -> (Vec<TriangleLanes>, Vec<u32>) {
    let mut blocks = Vec::new();
    let node_blocks = nodes
        .iter()
        .map(|node| {
            let first = u32::try_from(blocks.len()).expect("fewer than 2³² blocks");
            let leaves = occupied_slots(node) & !u32::from(node.imask);
            let run = (0..8)
                .filter(|s| leaves & (1 << s) != 0)
                .map(|s| {
                    let (start, count) = leaf_range(node, s);
                    start + count - node.primitive_base_idx
                })
                .max()
                .unwrap_or(0) as usize;
            let base = node.primitive_base_idx as usize;
            for chunk in (0..run).step_by(LANES) {
                blocks.push(TriangleLanes::new(&tris[base + chunk..base + run.min(chunk + LANES)]));
            }
            first
        })
        .collect();
    (blocks, node_blocks)
}

/// obvhs's `build_cwbvh_from_tris` without its debug-build validation (which asserts a depth
/// below 32 and would panic on the degenerate trees the median fallback exists for).
fn build_cwbvh_ploc(tris: &[Tri], config: &BvhBuildParams) -> CwBvh {
    let mut aabbs: Vec<Aabb> =
        tris.iter().map(|t| Aabb::from_points(&[Vec3A::from(t[0]), Vec3A::from(t[1]), Vec3A::from(t[2])])).collect();
    let mut indices: Vec<u32> = (0..tris.len() as u32).collect();
    if config.pre_split {
        let otris: Vec<ObvhsTriangle> =
            tris.iter().map(|t| ObvhsTriangle { v0: t[0].into(), v1: t[1].into(), v2: t[2].into() }).collect();
        let mut largest = 0.0f32;
        let mut sum = 0.0f32;
        for a in &aabbs {
            largest = largest.max(a.half_area());
            sum += a.half_area();
        }
        split_aabbs_preset(&mut aabbs, &mut indices, &otris, sum / tris.len() as f32, largest);
    }
    let mut bvh2 = PlocBuilder::with_capacity(aabbs.len()).build(
        config.ploc_search_distance,
        &aabbs,
        indices,
        config.sort_precision,
        config.search_depth_threshold,
    );
    bvh2.uses_spatial_splits = config.pre_split;
    ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
    bvh2_to_cwbvh(&bvh2, config.max_prims_per_leaf.clamp(1, 3), true, false)
}

/// The CWBVH of a binned SAH binary tree ([`build_bvh2_binned_sah`]), improved by
/// `config`'s reinsertion and collapsed by obvhs as the PLOC tree is.
fn build_cwbvh_sah(tris: &[Tri], config: &BvhBuildParams) -> CwBvh {
    let mut bvh2 = build_bvh2_binned_sah(tris);
    ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
    bvh2_to_cwbvh(&bvh2, config.max_prims_per_leaf.clamp(1, 3), true, false)
}

/// Depth of a CWBVH in levels. obvhs allocates children after their parent, so one forward
/// pass over the nodes finds every depth.
pub fn cwbvh_depth(bvh: &CwBvh) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut depth = vec![0u32; bvh.nodes.len()];
    depth[0] = 1;
    let mut max = 1;
    for (i, node) in bvh.nodes.iter().enumerate() {
        let d = depth[i];
        let imask = node.imask as u32;
        for slot in 0..8 {
            if imask & (1 << slot) != 0 {
                let c = inner_child_index(node.child_base_idx, imask, slot) as usize;
                assert!(c > i, "CWBVH child stored before its parent");
                depth[c] = d + 1;
                max = max.max(d + 1);
            }
        }
    }
    max as usize
}

/// A binary BVH by median split of centroids along the widest centroid axis, one triangle
/// per leaf (what obvhs's CWBVH converter expects). Depth ⌈log₂ n⌉ + 1 whatever the
/// geometry, so coincident triangles cannot make it deep. Only used as the fallback.
fn build_bvh2_median(tris: &[Tri]) -> Bvh2 {
    build_bvh2_top_down(tris, |_, _, _| None)
}

/// Bins per axis of the binned SAH build.
pub const SAH_BINS: usize = 32;

/// A binary BVH by the surface-area heuristic, binned (Wald 2007, *On fast construction of
/// SAH-based bounding volume hierarchies*): each node's triangles are split where, over
/// [`SAH_BINS`] bins of centroid position on each axis, `area(left)·count(left) +
/// area(right)·count(right)` is least; one triangle per leaf (obvhs's collapse to the 8-wide
/// tree decides the leaves). Where every centroid coincides, or a split would leave a side
/// empty, it splits at the median, so the depth stays bounded.
pub fn build_bvh2_binned_sah(tris: &[Tri]) -> Bvh2 {
    build_bvh2_top_down(tris, |prims, bounds, centroids| {
        let mut cb = Aabb::empty();
        for &p in prims.iter() {
            cb.extend(centroids[p as usize]);
        }
        let extent = cb.diagonal();
        // The bin of triangle `p` on `axis` (the one rule both the sweep and the partition use).
        let bin = |axis: usize, p: u32| {
            let scale = SAH_BINS as f32 / extent[axis];
            (((centroids[p as usize][axis] - cb.min[axis]) * scale) as usize).min(SAH_BINS - 1)
        };
        let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, last bin on the left)
        for axis in 0..3 {
            if !(extent[axis] > 0.0) {
                continue;
            }
            let mut counts = [0u32; SAH_BINS];
            let mut boxes = [Aabb::empty(); SAH_BINS];
            for &p in prims.iter() {
                let b = bin(axis, p);
                counts[b] += 1;
                boxes[b] = boxes[b].union(&bounds[p as usize]);
            }
            // Right-to-left sweep: the cost of everything right of each plane.
            let mut right_cost = [0.0f32; SAH_BINS];
            let (mut acc, mut n) = (Aabb::empty(), 0u32);
            for b in (1..SAH_BINS).rev() {
                acc = acc.union(&boxes[b]);
                n += counts[b];
                right_cost[b] = acc.half_area() * n as f32;
            }
            let (mut acc, mut n) = (Aabb::empty(), 0u32);
            for b in 0..SAH_BINS - 1 {
                acc = acc.union(&boxes[b]);
                n += counts[b];
                if n == 0 || n as usize == prims.len() {
                    continue;
                }
                let cost = acc.half_area() * n as f32 + right_cost[b + 1];
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, b));
                }
            }
        }
        let (_, axis, last) = best?;
        let mid = partition_in_place(prims, |p| bin(axis, *p) <= last);
        (mid > 0 && mid < prims.len()).then_some(mid)
    })
}

/// Moves the elements of `v` for which `left` holds to the front; returns how many.
fn partition_in_place(v: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut i = 0;
    for j in 0..v.len() {
        if left(&v[j]) {
            v.swap(i, j);
            i += 1;
        }
    }
    i
}

/// A binary BVH built top down, one triangle per leaf: `split` partitions a node's
/// triangles in place and returns the size of the left part, or `None` for a median split
/// along the widest centroid axis.
fn build_bvh2_top_down(tris: &[Tri], split: impl Fn(&mut [u32], &[Aabb], &[Vec3A]) -> Option<usize>) -> Bvh2 {
    let n = tris.len();
    let bounds: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(&[t[0].into(), t[1].into(), t[2].into()])).collect();
    let centroids: Vec<Vec3A> = bounds.iter().map(Aabb::center).collect();
    let centroid = |i: u32| centroids[i as usize];
    let mut prims: Vec<u32> = (0..n as u32).collect();
    let mut nodes = vec![Bvh2Node::default(); 2 * n - 1];
    let mut next = 1usize;
    // (node index, range of `prims`)
    let mut work = vec![(0usize, 0usize, n)];
    while let Some((node, lo, hi)) = work.pop() {
        let mut aabb = Aabb::empty();
        for &p in &prims[lo..hi] {
            aabb = aabb.union(&bounds[p as usize]);
        }
        if hi - lo == 1 {
            nodes[node] = Bvh2Node::new(aabb, 1, lo as u32);
            continue;
        }
        let mid = match split(&mut prims[lo..hi], &bounds, &centroids) {
            Some(left) => lo + left,
            None => {
                let mut cb = Aabb::empty();
                for &p in &prims[lo..hi] {
                    cb.extend(centroid(p));
                }
                let axis = cb.largest_axis();
                let mid = lo + (hi - lo) / 2;
                prims[lo..hi]
                    .select_nth_unstable_by(mid - lo, |&a, &b| centroid(a)[axis].total_cmp(&centroid(b)[axis]));
                mid
            }
        };
        nodes[node] = Bvh2Node::new(aabb, 0, next as u32);
        work.push((next, lo, mid));
        work.push((next + 1, mid, hi));
        next += 2;
    }
    debug_assert_eq!(next, 2 * n - 1);
    Bvh2 { nodes, primitive_indices: prims, ..Bvh2::default() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Tri {
        [Vec3::from(a), Vec3::from(b), Vec3::from(c)]
    }

    #[test]
    fn occupied_slots_matches_loop() {
        let mut node = CwBvhNode::default();
        for pattern in 0u32..256 {
            for s in 0..8 {
                node.child_meta[s] = if pattern & (1 << s) != 0 { [0x20, 0x61, 0xE2, 0x3B][s % 4] } else { 0 };
            }
            assert_eq!(occupied_slots(&node), pattern);
        }
    }

    #[test]
    fn safe_rcp_never_inf_or_nan() {
        for d in [0.0f32, -0.0, 1e-30, -1e-30, f32::MIN_POSITIVE, 1e-45, 1.0, -3.0] {
            let r = safe_rcp(d);
            assert!(r.is_finite() && r != 0.0, "{d} -> {r}");
            assert_eq!(r.is_sign_negative(), d.is_sign_negative());
        }
        assert_eq!(safe_rcp(2.0), 0.5);
    }

    #[test]
    fn bytes_to_f32s_exact() {
        let b = [0u8, 1, 2, 127, 128, 200, 254, 255];
        assert_eq!(bytes_to_f32s(&b).to_array(), b.map(|x| x as f32));
    }

    #[test]
    fn ray_validity() {
        let o = Vec3::ZERO;
        assert!(Ray::new(o, Vec3::X).is_valid());
        assert!(!Ray::new(o, Vec3::ZERO).is_valid());
        assert!(!Ray::new(o, Vec3::new(f32::NAN, 1.0, 0.0)).is_valid());
        assert!(!Ray::new(o, Vec3::new(f32::INFINITY, 1.0, 0.0)).is_valid());
        assert!(!Ray::new(Vec3::splat(f32::NAN), Vec3::X).is_valid());
        assert!(!Ray::segment(o, Vec3::X, 1.0, 1.0).is_valid());
        assert!(!Ray::segment(o, Vec3::X, -1.0, 1.0).is_valid());
        assert!(!Ray::segment(o, Vec3::X, 0.0, f32::NAN).is_valid());
        assert!(Ray::new(o, Vec3::new(0.0, -0.0, 1e-9)).is_valid());
    }

    #[test]
    fn watertight_single_triangle() {
        let t = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
        let tv = [t[0].x, t[0].y, t[0].z, t[1].x, t[1].y, t[1].z, t[2].x, t[2].y, t[2].z];
        let r = PreparedRay::new(&Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 0.0, -1.0))).unwrap();
        let h = intersect_triangle(&r, &tv, f32::INFINITY).unwrap();
        assert_eq!(h.t, 2.0);
        let (u, v) = h.uv();
        // (0,0) = 0.25·v0 + 0.25·v1 + 0.5·v2
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6, "{u} {v}");
        // Exactly through a vertex and an edge midpoint (exactly representable rays, so the
        // ray really passes through the point).
        for target in [t[0], t[1], t[2], (t[0] + t[1]) * 0.5] {
            for d in [Vec3::new(0.0, 0.0, -1.0), Vec3::new(-0.5, -0.25, -1.0), Vec3::new(0.25, 0.5, 1.0)] {
                let r = PreparedRay::new(&Ray::new(target - d, d)).unwrap();
                let h = intersect_triangle(&r, &tv, f32::INFINITY);
                assert_eq!(h.map(|h| h.t), Some(1.0), "{target} {d}");
            }
        }
    }

    /// The eight-triangle lane test equals the scalar test slot by slot: the same hit, `t`,
    /// edge functions and determinant bit for bit, the nearest hit (first slot on equal `t`)
    /// returned, for random triangles, slivers, triangles sharing edges and vertices with
    /// rays through them (the f64 fallback), masked lanes and any `tmax`.
    #[test]
    fn triangle_lanes_equal_the_scalar_test() {
        let mut rng = crate::synth::Rng::new(11);
        let mut unit = || rng.next_f32();
        for case in 0..4000 {
            // A fan of triangles around a shared vertex, some duplicated (equal t), some random.
            let centre = Vec3::new(unit(), unit(), unit()) * 4.0 - 2.0;
            let tris: Vec<TriVerts> = (0..13)
                .map(|i| {
                    let a = centre + (Vec3::new(unit(), unit(), unit()) - 0.5) * [2.0, 1e-3, 0.0][case % 3];
                    let b = centre + (Vec3::new(unit(), unit(), unit()) - 0.5) * 2.0;
                    let c = if i % 4 == 3 { centre } else { centre + (Vec3::new(unit(), unit(), unit()) - 0.5) * 2.0 };
                    [a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]
                })
                .chain([[0.0; 9]; LANES])
                .collect();
            let mut tris = tris;
            tris[5] = tris[2];
            // Rays from random points, through the shared vertex or a random point.
            let origin = centre + (Vec3::new(unit(), unit(), unit()) - 0.5) * 8.0;
            let target = if case % 2 == 0 { centre } else { centre + (Vec3::new(unit(), unit(), unit()) - 0.5) };
            let tmin = [0.0, 0.5][case % 2];
            let Some(r) = PreparedRay::new(&Ray::segment(origin, target - origin, tmin, f32::INFINITY)) else {
                continue;
            };
            let tmax = [f32::INFINITY, 1.0, 0.999][case % 3];
            for first in [0, 5] {
                let lanes = [0xFF, 0b1010_0110, 0][case % 3] as u32;
                let mut expected: Option<(u32, TriHit)> = None;
                for i in 0..LANES as u32 {
                    if lanes & (1 << i) == 0 {
                        continue;
                    }
                    let bound = expected.map_or(tmax, |e| e.1.t);
                    if let Some(h) = intersect_triangle(&r, &tris[first + i as usize], bound) {
                        expected = Some((i, h));
                    }
                }
                let got = intersect_triangles_lanes(&r, &TriangleLanes::new(&tris[first..first + LANES]), lanes, tmax);
                let bits = |h: Option<(u32, TriHit)>| {
                    h.map(|(i, h)| (i, h.t.to_bits(), h.e.map(f32::to_bits), h.det.to_bits()))
                };
                assert_eq!(bits(got), bits(expected), "case {case}, first {first}");
            }
        }
    }

    #[test]
    fn median_fallback_tree_is_shallow() {
        let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let tris = vec![t; 5000];
        let bvh = bvh2_to_cwbvh(&build_bvh2_median(&tris), 3, true, false);
        let d = cwbvh_depth(&bvh);
        assert!(d <= 14, "depth {d}");
        let mut seen: Vec<u32> = bvh.primitive_indices.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..5000).collect::<Vec<_>>());
    }
}

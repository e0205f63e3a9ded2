//! The robust node test of a compressed CWBVH node (obvhs's 80-byte [`CwBvhNode`]): slab
//! constants, the scalar reference and the SIMD body (bit-identical), and the decoding of
//! child slots and leaf ranges (see "Robust node test" in [`crate::bvh`]).

use glam::Vec3A;
use obvhs::cwbvh::node::CwBvhNode;

use crate::simd::F32s;

use super::ray::PreparedRay;

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

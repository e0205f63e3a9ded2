//! The single-ray node layout: every CWBVH node again, with its children's boxes as exact
//! f32 planes instead of quantised bytes.
//!
//! # Why a second layout
//! A CWBVH node (80 bytes) stores each child box as bytes relative to a per-node origin and
//! power-of-two scale. Testing a ray against it means, per node: the slab constants of that
//! origin and scale, six byte-to-float conversions, and the rounding pad that covers
//! obvhs's float quantisation ([`crate::bvh`]). A [`WideNode`] (256 bytes, four cache lines)
//! holds the boxes as f32 planes, so the node test is a subtraction and a multiplication per
//! plane. Packets keep the CWBVH: they amortise its decoding over eight rays.
//!
//! # Exact boxes, and the two margins
//! The planes are not decoded from the quantised bytes: they are the exact bounds of what
//! each child holds (the min and max vertex coordinates of a leaf's triangles; the union
//! of an inner child's own children, bottom up). A leaf of a tree with spatial splits holds
//! only a part of a cut triangle, so its box is the triangles' bounds cut down to the
//! (slightly widened) CWBVH child box, which bounds that part (`within_child_box`; for a
//! tree without splits the cut changes nothing). Empty slots are masked out
//! ([`WideNode::occupied`]).
//!
//! Exact boxes are not enough, because the tracer's triangle test is not exact geometry: it
//! works on vertices taken relative to the ray's origin and sheared, each rounded, so it can
//! report a hit on a ray that passes a few ulps of `|v − o|` outside the triangle (a ray
//! grazing an edge, or lying in the plane of an axis-aligned face with a zero direction
//! component, where the box test sees only the clamped reciprocal of
//! [`crate::bvh::safe_rcp`]). A box that such a hit lies in must not be culled. So every box
//! is widened on each axis by `shift` = [`POSITION_PAD`] (2⁻¹⁶, several hundred times the
//! unit roundoff) times the ray's reach: the largest `|b − o|` over the tree's root box and
//! `|o|` itself, which bounds every `|v − o|` the triangle test works with. The widening is
//! done once per ray, not per node: the near planes are measured from `o + sgn(inv)·shift`
//! and the far planes from `o − sgn(inv)·shift` ([`SlabOrigins`]), which subtracts
//! `shift·|inv_k|` from every near distance and adds it to every far one at no cost per node.
//! With a zero direction component `|inv_k| = 2⁸⁰` and the slab becomes all of `t`, as it is
//! for a ray lying in the plane (a fuzz finding: such a ray missed an edge hit before this
//! pad). Measured cost against no pad: 5–21 % of single-ray throughput (`BENCHMARKS.md`).
//!
//! The slab distance itself, `(b − o) · inv`, carries two roundings plus the one in `inv`:
//! the computed value is the exact `(b − o)/d` times `(1 + θ)` with `|θ| ≤ γ₃` (Higham's
//! `γₙ = n·u/(1 − n·u)`), a relative error that keeps signs. Following Ize (*Robust BVH Ray
//! Traversal*, JCGT 2013), the far end of the interval is scaled up by [`FAR_SCALE`] before the
//! comparison: `1 + 2γ₃` would make the slab test conservative; `1 + 2⁻¹⁸` (about `10·γ₃`)
//! also covers the few-ulp error of the triangle test's `t` that a closest-hit search compares
//! boxes against. The traversal's later comparisons with a lowered far bound use the same
//! scaled test ([`in_reach`]). Every quantity stays finite (coordinates are bounded by
//! [`crate::bvh::MAX_COORD`], `inv` by `2⁸⁰`): no NaN can occur, so the node test may use the
//! plain `min`/`max` instructions.

use obvhs::cwbvh::node::CwBvhNode;

use super::node::{leaf_meta, leaf_range, max1, min1, node_extent, occupied_slots};
use super::ray::PreparedRay;
use super::triangle::TriVerts;
use crate::simd::{F32s, LANES};

/// The far end of every slab interval is multiplied by this (see the module notes).
pub const FAR_SCALE: f32 = 1.0 + 1.0 / 262_144.0;

/// Every box is widened on each axis by this times the ray's reach (see the module notes).
pub const POSITION_PAD: f32 = 1.0 / 65_536.0;

/// The ray's origin moved by the position pad ([`POSITION_PAD`] times its reach), toward the
/// boxes for their near planes and away for their far planes, so that a node test costs
/// nothing more than the exact slab test (module notes). Computed once per traversal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabOrigins {
    /// Origin for the near planes: `o + sgn(inv)·shift` per axis.
    pub near: [f32; 3],
    /// Origin for the far planes: `o − sgn(inv)·shift` per axis.
    pub far: [f32; 3],
}

impl SlabOrigins {
    /// The origins of ray `r` in a tree whose root box is `bounds` (`[min, max]`): the shift
    /// is `POSITION_PAD · max(|b − o|, |o|)` over the box's six planes and the origin's
    /// coordinates (the largest offset the triangle test works with, and at least 2⁷ ulps of
    /// the origin, so adding it to the origin cannot round it away).
    pub fn new(r: &PreparedRay, bounds: &[[f32; 3]; 2]) -> Self {
        // In vectors of three: every value is finite, so the order of the maxima and the
        // vector `max` give the same bits as a scalar fold.
        let o = r.origin;
        let (lo, hi) = (glam::Vec3A::from_array(bounds[0]) - o, glam::Vec3A::from_array(bounds[1]) - o);
        let reach = lo.abs().max(hi.abs()).max(o.abs()).max_element();
        let shift = glam::Vec3A::splat(reach * POSITION_PAD).copysign(r.inv);
        Self { near: (o + shift).to_array(), far: (o - shift).to_array() }
    }
}

/// One CWBVH node for single rays (see the module notes). Index `i` of
/// [`crate::bvh::TriangleBvh`]'s wide nodes is CWBVH node `i`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode {
    /// Child box planes per slot: minima x, y, z, then maxima x, y, z.
    pub planes: [[f32; LANES]; 6],
    /// Index of the first inner child (inner children are consecutive, in slot order).
    pub child_base: u32,
    /// Bit `s` set when slot `s` is an inner child.
    pub imask: u32,
    /// The CWBVH node's `primitive_base_idx`: the first BVH slot of its leaf run.
    pub primitive_base: u32,
    /// Index of the first [`crate::bvh::TriangleLanes`] block of the leaf run.
    pub block_base: u32,
    /// The CWBVH node's `child_meta` (a leaf's offset in the run and its triangle count).
    pub child_meta: [u8; LANES],
    /// Bit `s` set when slot `s` holds a child (empty slots' planes are 0 and never hit).
    pub occupied: u32,
}

impl WideNode {
    /// The leaf run of the children in `leaves` (a slot mask) as bits over the node's run of
    /// slots from [`Self::primitive_base`] (up to 24: at most three per child).
    #[inline(always)]
    pub fn leaf_lanes(&self, mut leaves: u32) -> u32 {
        let mut lanes = 0;
        while leaves != 0 {
            let slot = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            let (offset, count) = leaf_meta(self.child_meta[slot]);
            lanes |= ((1u32 << count) - 1) << offset;
        }
        lanes
    }
}

/// The wide nodes of `nodes`, whose leaves index `tris` (BVH order), with each node's first
/// triangle block from `block_bases`, and the exact bounds of the whole tree (`[min, max]`).
pub fn wide_nodes(nodes: &[CwBvhNode], tris: &[TriVerts], block_bases: &[u32]) -> (Vec<WideNode>, [[f32; 3]; 2]) {
    let mut wide = vec![
        WideNode {
            planes: [[0.0; LANES]; 6],
            child_base: 0,
            imask: 0,
            primitive_base: 0,
            block_base: 0,
            child_meta: [0; LANES],
            occupied: 0,
        };
        nodes.len()
    ];
    let bounds = if nodes.is_empty() { [[0.0; 3]; 2] } else { node_box(0, nodes, tris, block_bases, &mut wide) };
    (wide, bounds)
}

/// Fills `wide[i]` and returns node `i`'s exact box (children first: depth ≤ MAX_DEPTH).
fn node_box(
    i: usize,
    nodes: &[CwBvhNode],
    tris: &[TriVerts],
    block_bases: &[u32],
    wide: &mut [WideNode],
) -> [[f32; 3]; 2] {
    let node = &nodes[i];
    let occupied = occupied_slots(node);
    let imask = u32::from(node.imask);
    let mut planes = [[0.0; LANES]; 6];
    let mut whole: Option<[[f32; 3]; 2]> = None;
    let mut inner_rank = 0;
    for slot in 0..LANES {
        if occupied & (1 << slot) == 0 {
            continue;
        }
        let child = if imask & (1 << slot) != 0 {
            let c = node.child_base_idx as usize + inner_rank;
            inner_rank += 1;
            node_box(c, nodes, tris, block_bases, wide)
        } else {
            let (first, count) = leaf_range(node, slot);
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for t in &tris[first as usize..(first + count) as usize] {
                for v in 0..3 {
                    for k in 0..3 {
                        lo[k] = lo[k].min(t[3 * v + k]);
                        hi[k] = hi[k].max(t[3 * v + k]);
                    }
                }
            }
            within_child_box(node, slot, [lo, hi])
        };
        for k in 0..3 {
            planes[k][slot] = child[0][k];
            planes[3 + k][slot] = child[1][k];
        }
        whole = Some(match whole {
            None => child,
            Some([lo, hi]) => [[0, 1, 2].map(|k| lo[k].min(child[0][k])), [0, 1, 2].map(|k| hi[k].max(child[1][k]))],
        });
    }
    wide[i] = WideNode {
        planes,
        child_base: node.child_base_idx,
        imask,
        primitive_base: node.primitive_base_idx,
        block_base: block_bases[i],
        child_meta: node.child_meta,
        occupied,
    };
    whole.unwrap_or([[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]])
}

/// A leaf's exact triangle bounds cut down to its CWBVH child box, widened by far more than
/// obvhs's float quantisation can land inside the binary tree's box (2⁻²⁰ of the coordinates'
/// magnitude). Where a triangle was split in space (an SBVH reference bounds only its own
/// slab of the triangle), this keeps the leaf's box that slab's; elsewhere the child box
/// contains the triangles and the bounds stay as they were, bit for bit.
fn within_child_box(node: &CwBvhNode, slot: usize, [lo, hi]: [[f32; 3]; 2]) -> [[f32; 3]; 2] {
    let e = node_extent(node);
    let q_lo = [node.child_min_x[slot], node.child_min_y[slot], node.child_min_z[slot]];
    let q_hi = [node.child_max_x[slot], node.child_max_y[slot], node.child_max_z[slot]];
    let mut out = [lo, hi];
    for k in 0..3 {
        let (b_lo, b_hi) = (node.p[k] + f32::from(q_lo[k]) * e[k], node.p[k] + f32::from(q_hi[k]) * e[k]);
        let pad = (node.p[k].abs() + 255.0 * e[k]) * CHILD_BOX_PAD;
        out[0][k] = lo[k].max(b_lo - pad);
        out[1][k] = hi[k].min(b_hi + pad);
        if out[0][k] > out[1][k] {
            // Cannot happen for a box obvhs quantised outwards; keep the triangles' bounds.
            return [lo, hi];
        }
    }
    out
}

/// The relative widening of a decoded CWBVH child box in [`within_child_box`].
const CHILD_BOX_PAD: f32 = 1.0 / (1 << 20) as f32;

/// Whether a child entered at `tnear` can still hold a hit below the far bound `tfar`: the
/// node test's own comparison (far end scaled by [`FAR_SCALE`]), for the traversal's checks
/// after a node test (a leaf hit that lowered the bound, a child popped later).
#[inline(always)]
pub fn in_reach(tnear: f32, tfar: f32) -> bool {
    tnear <= tfar * FAR_SCALE
}

/// Plane indices (near x, y, z, far x, y, z) for a ray with the given octant bits
/// ([`PreparedRay::oct_inv`]: bit `4 >> axis` set when the direction is non-negative).
#[inline(always)]
fn plane_order(oct_inv: u32) -> [usize; 6] {
    let near = |axis: usize| if oct_inv & (4 >> axis) != 0 { axis } else { 3 + axis };
    let far = |axis: usize| if oct_inv & (4 >> axis) != 0 { 3 + axis } else { axis };
    [near(0), near(1), near(2), far(0), far(1), far(2)]
}

/// Scalar reference of [`wide_node_hits`]: bit `s` set when the ray overlaps child `s`
/// within `[tmin, tfar]` (with the far end scaled by [`FAR_SCALE`]), and each child's entry
/// distance.
pub fn wide_node_hits_scalar(node: &WideNode, r: &PreparedRay, o: &SlabOrigins, tfar: f32) -> (u32, [f32; LANES]) {
    let order = plane_order(r.oct_inv);
    let inv = r.inv.to_array();
    let mut hits = 0;
    let mut entry = [0.0; LANES];
    for s in 0..LANES {
        let near = |k: usize| (node.planes[order[k]][s] - o.near[k]) * inv[k];
        let far = |k: usize| (node.planes[order[3 + k]][s] - o.far[k]) * inv[k];
        let tn = max1(max1(near(0), near(1)), max1(near(2), r.tmin));
        let tf = min1(min1(far(0), far(1)), min1(far(2), tfar)) * FAR_SCALE;
        if tn <= tf {
            hits |= 1 << s;
        }
        entry[s] = tn;
    }
    (hits & node.occupied, entry)
}

/// SIMD node test (one ray, eight children): the hit slots and each child's entry distance
/// (meaningful in hit slots); bit-identical to [`wide_node_hits_scalar`].
#[inline(always)]
pub fn wide_node_hits(node: &WideNode, r: &PreparedRay, o: &SlabOrigins, tfar: f32) -> (u32, F32s) {
    let [nx, ny, nz, fx, fy, fz] = plane_order(r.oct_inv);
    let sp = F32s::splat;
    // Written out axis by axis: `array::map` closures here went out of line (half the speed).
    let t = |i: usize, origin: f32, inv: f32| (F32s::from(node.planes[i]) - sp(origin)) * sp(inv);
    let [ix, iy, iz] = r.inv.to_array();
    // No NaN can occur (module notes), so the plain max/min instructions are exact here.
    let tn = t(nx, o.near[0], ix).fast_max(t(ny, o.near[1], iy)).fast_max(t(nz, o.near[2], iz).fast_max(sp(r.tmin)));
    let tf = t(fx, o.far[0], ix).fast_min(t(fy, o.far[1], iy)).fast_min(t(fz, o.far[2], iz).fast_min(sp(tfar)))
        * sp(FAR_SCALE);
    let hits = tn.simd_le(tf).to_bitmask() & node.occupied;
    #[cfg(feature = "check-scalar")]
    {
        let (h, e) = wide_node_hits_scalar(node, r, o, tfar);
        assert_eq!(hits, h, "SIMD wide node test disagrees with its scalar reference");
        let te = tn.to_array();
        for s in 0..LANES {
            if h & (1 << s) != 0 {
                assert_eq!(te[s].to_bits(), e[s].to_bits(), "wide node entry distance differs");
            }
        }
    }
    (hits, tn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildQuality, Ray, Tri, TriangleBvh, intersect_triangle};
    use crate::synth::Rng;
    use glam::Vec3;

    /// Random triangles in a cube, with axis-aligned ones (flat boxes) and shared corners.
    fn soup(rng: &mut Rng, n: usize) -> Vec<Tri> {
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0 - 10.0;
        (0..n)
            .map(|i| {
                let a = v();
                let (b, c) = (a + (v() * 0.1), a + (v() * 0.1));
                match i % 4 {
                    // Flat in y: a box of zero thickness.
                    0 => [a, Vec3::new(b.x, a.y, b.z), Vec3::new(c.x, a.y, c.z)],
                    _ => [a, b, c],
                }
            })
            .collect()
    }

    /// Rays from random points toward triangle corners and edges (grazing box faces), along
    /// the axes (zero direction components, the reciprocal clamp), and lying in the plane of
    /// a corner (flat boxes seen edge-on), some from inside the soup's bounds.
    fn rays(rng: &mut Rng, tris: &[Tri], n: usize) -> Vec<Ray> {
        (0..n)
            .map(|i| {
                let t = &tris[(rng.next_f32() * tris.len() as f32) as usize % tris.len()];
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0 - 15.0;
                let target = match i % 3 {
                    0 => t[i % 3],
                    1 => (t[0] + t[1]) * 0.5,
                    _ => (t[0] + t[1] + t[2]) / 3.0,
                };
                let mut d = target - o;
                if i % 5 == 0 {
                    d = [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::new(-0.0, 1.0, 0.0)][i % 4];
                }
                let mut o = o;
                if i % 7 == 1 {
                    // In the plane x = target.x, toward the target: a zero x component (the
                    // fuzz finding of the module notes).
                    o.x = target.x;
                    d = target - o;
                }
                Ray::segment(o, d, [0.0, 0.3][i % 2], f32::INFINITY)
            })
            .collect()
    }

    #[test]
    fn the_node_test_equals_its_scalar_reference() {
        let mut rng = Rng::new(21);
        let tris = soup(&mut rng, 3000);
        let (bvh, _) = TriangleBvh::build(&tris, BuildQuality::Medium).unwrap();
        for ray in rays(&mut rng, &tris, 300) {
            let Some(r) = PreparedRay::new(&ray) else { continue };
            let origins = SlabOrigins::new(&r, bvh.bounds());
            for (i, node) in bvh.wide_nodes().iter().enumerate() {
                for tfar in [f32::INFINITY, 3.0, 0.0] {
                    let (hits, tn) = wide_node_hits(node, &r, &origins, tfar);
                    let (want, entry) = wide_node_hits_scalar(node, &r, &origins, tfar);
                    assert_eq!(hits, want, "node {i}, {ray:?}");
                    let tn = tn.to_array();
                    for s in (0..LANES).filter(|s| hits & (1 << s) != 0) {
                        assert_eq!(tn[s].to_bits(), entry[s].to_bits(), "node {i} slot {s}, {ray:?}");
                    }
                }
            }
        }
    }

    /// The exact bounds of what each slot holds: a leaf's triangles, or the union of the
    /// inner child's occupied slots.
    #[test]
    fn child_boxes_are_the_exact_bounds_of_their_contents() {
        let mut rng = Rng::new(22);
        let tris = soup(&mut rng, 2000);
        let (bvh, _) = TriangleBvh::build(&tris, BuildQuality::Medium).unwrap();
        let nodes = bvh.wide_nodes();
        let slot_box =
            |n: &WideNode, s: usize| [[0, 1, 2].map(|k| n.planes[k][s]), [0, 1, 2].map(|k| n.planes[3 + k][s])];
        for (i, (node, cw)) in nodes.iter().zip(bvh.nodes()).enumerate() {
            let occupied = occupied_slots(cw);
            let mut rank = 0;
            for s in 0..LANES {
                let mut want = [[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]];
                let mut grow = |b: [[f32; 3]; 2]| {
                    for k in 0..3 {
                        want[0][k] = want[0][k].min(b[0][k]);
                        want[1][k] = want[1][k].max(b[1][k]);
                    }
                };
                if occupied & (1 << s) == 0 {
                    assert_eq!(slot_box(node, s), [[0.0; 3]; 2], "node {i} empty slot {s}");
                    continue;
                } else if node.imask & (1 << s) != 0 {
                    let child = &nodes[node.child_base as usize + rank];
                    rank += 1;
                    (0..LANES).filter(|c| child.occupied & (1 << c) != 0).for_each(|c| grow(slot_box(child, c)));
                } else {
                    let (first, count) = leaf_range(cw, s);
                    for t in &bvh.triangles_bvh_order()[first as usize..(first + count) as usize] {
                        (0..3).for_each(|v| grow([[t[3 * v], t[3 * v + 1], t[3 * v + 2]]; 2]));
                    }
                }
                assert_eq!(slot_box(node, s), want, "node {i} slot {s}");
            }
        }
    }

    /// Every triangle a ray hits at `t` lies in boxes the node test keeps with the far bound
    /// at exactly that `t`, and whose entry distance [`in_reach`] keeps too: a closest-hit
    /// search that found it (or one at the same `t`) never culls the box that holds it.
    #[test]
    fn boxes_holding_a_hit_survive_a_far_bound_at_that_hit() {
        let mut rng = Rng::new(23);
        let tris = soup(&mut rng, 1500);
        let (bvh, _) = TriangleBvh::build(&tris, BuildQuality::Medium).unwrap();
        let (nodes, cw) = (bvh.wide_nodes(), bvh.nodes());
        // Each BVH slot's path from the root: (node, child slot) pairs.
        let mut paths: Vec<Vec<(usize, usize)>> = vec![Vec::new(); bvh.triangles_bvh_order().len()];
        let mut todo = vec![(0usize, Vec::new())];
        while let Some((i, path)) = todo.pop() {
            let mut rank = 0;
            for s in 0..LANES {
                if occupied_slots(&cw[i]) & (1 << s) == 0 {
                    continue;
                }
                let mut p: Vec<(usize, usize)> = path.clone();
                p.push((i, s));
                if nodes[i].imask & (1 << s) != 0 {
                    todo.push((nodes[i].child_base as usize + rank, p));
                    rank += 1;
                } else {
                    let (first, count) = leaf_range(&cw[i], s);
                    (first..first + count).for_each(|slot| paths[slot as usize] = p.clone());
                }
            }
        }
        let mut checked = 0;
        for ray in rays(&mut rng, &tris, 3000) {
            let Some(r) = PreparedRay::new(&ray) else { continue };
            let origins = SlabOrigins::new(&r, bvh.bounds());
            for (slot, tri) in bvh.triangles_bvh_order().iter().enumerate() {
                let Some(hit) = intersect_triangle(&r, tri, r.tmax) else { continue };
                for &(i, s) in &paths[slot] {
                    let (hits, tnear) = wide_node_hits(&nodes[i], &r, &origins, hit.t);
                    assert!(hits & (1 << s) != 0, "node {i} slot {s} culled a hit at t = {} for {ray:?}", hit.t);
                    // The traversal's later checks (after a leaf hit, on pop) agree.
                    let (_, far) = wide_node_hits(&nodes[i], &r, &origins, f32::INFINITY);
                    assert!(in_reach(far.to_array()[s], hit.t), "node {i} slot {s} out of reach of t = {}", hit.t);
                    assert_eq!(tnear.to_array()[s].to_bits(), far.to_array()[s].to_bits());
                }
                checked += 1;
            }
        }
        assert!(checked > 1000, "only {checked} hits checked");
    }
}

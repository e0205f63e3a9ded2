//! The body: packets of eight rays, one traversal loop generic over the search (see the
//! module notes of [`super`]).

use super::scalar::{AnyHit, Best};
use super::{ALL_LANES, FixedStack, PACKET_STACK, PacketHits, RayPacket, SINGLE_RAY_THRESHOLD};
use crate::bvh::{
    MAX_DIR, MAX_ORIGIN, MIN_DIR, NODE_PAD, PreparedRay, RCP_CLAMP, TriHit, TriVerts, TriangleBvh, bytes_to_f32s,
    child_planes, inner_child_index, leaf_range, node_extent, occupied_slots, watertight_lanes,
};
use crate::simd::{F32s, LANES};

/// The prepared lanes of a packet, structure of arrays: lane `i` holds exactly the values
/// of [`PreparedRay::new`] for that lane's ray (computed here with the same IEEE operations in
/// SIMD; the `lanes_match_prepared_ray` test checks it bit for bit). Preparing lanes one by
/// one in scalar code and transposing took a third of a shadow packet's time.
struct Lanes {
    origin: [F32s; 3],
    inv: [F32s; 3],
    pad: [F32s; 3],
    origin_k: [F32s; 3],
    shear: [F32s; 3],
    tmin: F32s,
    tmax: F32s,
    /// [`PreparedRay::class`] per lane (meaningful in valid lanes).
    class: [u32; LANES],
    /// Lanes that are active and valid.
    valid: u32,
}

impl Lanes {
    fn new(p: &RayPacket, active: u32) -> Self {
        let sp = F32s::splat;
        let zero = F32s::ZERO;
        let [ox, oy, oz] = p.origin;
        let [dx, dy, dz] = p.dir;
        let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
        // `Ray::is_valid`, written so that NaN fails.
        let o_ok =
            ox.abs().simd_le(sp(MAX_ORIGIN)) & oy.abs().simd_le(sp(MAX_ORIGIN)) & oz.abs().simd_le(sp(MAX_ORIGIN));
        let d_ok = ax.simd_le(sp(MAX_DIR))
            & ay.simd_le(sp(MAX_DIR))
            & az.simd_le(sp(MAX_DIR))
            & (ax.simd_ge(sp(MIN_DIR)) | ay.simd_ge(sp(MIN_DIR)) | az.simd_ge(sp(MIN_DIR)));
        let t_ok = p.tmin.simd_ge(zero) & p.tmin.simd_lt(sp(f32::INFINITY)) & p.tmin.simd_lt(p.tmax);
        let valid = (o_ok & d_ok & t_ok).to_bitmask() & active;
        // `safe_rcp`: ±2^80 (sign of d) below the clamp, else 1/d.
        let big = sp(1.0 / RCP_CLAMP);
        let rcp = |d: F32s| d.abs().simd_lt(sp(RCP_CLAMP)).select(big | (d & sp(-0.0)), F32s::ONE / d);
        let inv = [rcp(dx), rcp(dy), rcp(dz)];
        let pad = inv.map(|i| sp(NODE_PAD) * i.abs());
        // Dominant axis and the watertight permutation, as in `PreparedRay::new`.
        let kz0 = ax.simd_ge(ay) & ax.simd_ge(az);
        let kz1 = !kz0 & ay.simd_ge(az);
        let pick = |v: [F32s; 3]| -> [F32s; 3] {
            // (kx, ky, kz) before the winding swap: kz = 0 → (1, 2, 0), 1 → (2, 0, 1), 2 → (0, 1, 2).
            let z = kz0.select(v[0], kz1.select(v[1], v[2]));
            let x = kz0.select(v[1], kz1.select(v[2], v[0]));
            let y = kz0.select(v[2], kz1.select(v[0], v[1]));
            [x, y, z]
        };
        let [dkx, dky, dkz] = pick(p.dir);
        let [okx, oky, okz] = pick(p.origin);
        let swap = dkz.simd_lt(zero);
        let (dkx, dky) = (swap.select(dky, dkx), swap.select(dkx, dky));
        let (okx, oky) = (swap.select(oky, okx), swap.select(okx, oky));
        let shear = [dkx / dkz, dky / dkz, F32s::ONE / dkz];
        let neg = inv.map(|i| i.simd_lt(zero).to_bitmask());
        let (b0, b1) = (kz0.to_bitmask(), kz1.to_bitmask());
        let class = core::array::from_fn(|i| {
            let bit = |m: u32| (m >> i) & 1;
            let oct_inv = ((bit(neg[0]) ^ 1) << 2) | ((bit(neg[1]) ^ 1) << 1) | (bit(neg[2]) ^ 1);
            let kz = if bit(b0) == 1 {
                0
            } else if bit(b1) == 1 {
                1
            } else {
                2
            };
            oct_inv | (kz << 3)
        });
        Lanes { origin: p.origin, inv, pad, origin_k: [okx, oky, okz], shear, tmin: p.tmin, tmax: p.tmax, class, valid }
    }

    /// Lane `i` as the single-ray [`PreparedRay`] (for the single-ray fallback).
    fn lane(&self, i: usize) -> PreparedRay {
        let g3 = |v: &[F32s; 3]| v.map(|x| x.to_array()[i]);
        let class = self.class[i];
        let oct_inv = class & 7;
        let kz = (class >> 3) as usize;
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        // d[kz] is never zero here, so its sign is the sign of the octant bit.
        if oct_inv & (4 >> kz) == 0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        PreparedRay {
            origin: g3(&self.origin).into(),
            inv: g3(&self.inv).into(),
            pad: g3(&self.pad).into(),
            oct_inv,
            k: [kx, ky, kz],
            shear: g3(&self.shear),
            origin_k: g3(&self.origin_k),
            tmin: self.tmin.to_array()[i],
            tmax: self.tmax.to_array()[i],
        }
    }
}

/// Per-lane closest-hit state: `t` (the current `tfar`), edge functions and determinant of
/// the best triangle, and its BVH slot (bit-cast into float lanes so one blend updates it).
struct LaneBest {
    t: F32s,
    e1: F32s,
    e2: F32s,
    det: F32s,
    slot: F32s,
}

impl LaneBest {
    fn lane(&self, i: usize) -> Best {
        let g = |v: &F32s| v.to_array()[i];
        Best {
            slot: g(&self.slot).to_bits(),
            hit: TriHit { t: g(&self.t), e: [0.0, g(&self.e1), g(&self.e2)], det: g(&self.det) },
        }
    }

    fn set_lane(&mut self, i: usize, b: &Best) {
        let put = |v: &mut F32s, x: f32| {
            let mut a = v.to_array();
            a[i] = x;
            *v = F32s::from(a);
        };
        put(&mut self.t, b.hit.t);
        put(&mut self.e1, b.hit.e[1]);
        put(&mut self.e2, b.hit.e[2]);
        put(&mut self.det, b.hit.det);
        put(&mut self.slot, f32::from_bits(b.slot));
    }
}

/// What a packet search keeps per lane: its far bounds, which lanes still search, what a
/// triangle hit does, and the single-ray fallback.
trait PacketSearch {
    /// Each lane's far bound (exclusive).
    fn tfar(&self) -> F32s;
    /// The lanes of a popped entry (`mask`, with entry distances `tnear`) worth descending.
    fn live(&self, mask: u32, tnear: F32s) -> u32;
    /// The lanes of `mask` still searching.
    fn searching(&self, mask: u32) -> u32;
    /// Tests the triangle in BVH slot `slot` against `lanes` and records their hits.
    fn triangle(&mut self, l: &Lanes, k: [usize; 3], tri: &TriVerts, slot: u32, lanes: u32);
    /// Finishes lane `i` in the subtree at `node` as a single ray.
    fn single(&mut self, bvh: &TriangleBvh, l: &Lanes, i: usize, node: u32);
    /// True when no lane searches any more.
    fn done(&self) -> bool;
}

impl PacketSearch for LaneBest {
    #[inline(always)]
    fn tfar(&self) -> F32s {
        self.t
    }

    /// Lanes whose entry distance lies beyond their closest hit so far drop out.
    #[inline(always)]
    fn live(&self, mask: u32, tnear: F32s) -> u32 {
        mask & tnear.simd_le(self.t).to_bitmask()
    }

    #[inline(always)]
    fn searching(&self, mask: u32) -> u32 {
        mask
    }

    #[inline(always)]
    fn triangle(&mut self, l: &Lanes, k: [usize; 3], tri: &TriVerts, slot: u32, lanes: u32) {
        let (h, t, e, det) = intersect_triangle_lanes(l, k, tri, self.t, lanes);
        if h != 0 {
            let sel = mask_of(h);
            self.t = sel.select(t, self.t);
            self.e1 = sel.select(e[1], self.e1);
            self.e2 = sel.select(e[2], self.e2);
            self.det = sel.select(det, self.det);
            self.slot = sel.select(F32s::splat(f32::from_bits(slot)), self.slot);
        }
    }

    #[inline(always)]
    fn single(&mut self, bvh: &TriangleBvh, l: &Lanes, i: usize, node: u32) {
        let mut b = self.lane(i);
        if bvh.traverse(&l.lane(i), node, &mut b, &mut super::scalar::NoCounts) {
            self.set_lane(i, &b);
        }
    }

    #[inline(always)]
    fn done(&self) -> bool {
        false
    }
}

/// Any hit (occlusion) for a packet: the lanes not yet occluded, and every lane's `tmax`.
struct LanesAlive {
    alive: u32,
    tfar: F32s,
}

impl PacketSearch for LanesAlive {
    #[inline(always)]
    fn tfar(&self) -> F32s {
        self.tfar
    }

    #[inline(always)]
    fn live(&self, mask: u32, _: F32s) -> u32 {
        mask & self.alive
    }

    #[inline(always)]
    fn searching(&self, mask: u32) -> u32 {
        mask & self.alive
    }

    #[inline(always)]
    fn triangle(&mut self, l: &Lanes, k: [usize; 3], tri: &TriVerts, _: u32, lanes: u32) {
        let (h, ..) = intersect_triangle_lanes(l, k, tri, self.tfar, lanes);
        self.alive &= !h;
    }

    #[inline(always)]
    fn single(&mut self, bvh: &TriangleBvh, l: &Lanes, i: usize, node: u32) {
        let r = l.lane(i);
        if bvh.traverse(&r, node, &mut AnyHit { tmax: r.tmax }, &mut super::scalar::NoCounts) {
            self.alive &= !(1 << i);
        }
    }

    #[inline(always)]
    fn done(&self) -> bool {
        self.alive == 0
    }
}

/// A pending subtree: node index, live lanes and each lane's entry distance.
#[derive(Clone, Copy, Default)]
struct Entry {
    node: u32,
    mask: u32,
    tnear: [f32; LANES],
}

#[inline(always)]
fn mask_of(bits: u32) -> F32s {
    F32s::from(core::array::from_fn::<f32, LANES, _>(
        |i| if bits & (1 << i) != 0 { f32::from_bits(u32::MAX) } else { 0.0 },
    ))
}

/// Watertight test of one triangle against the lanes in `m` (all of one class, permutation
/// `k`): [`crate::bvh::intersect_triangle`] in lanes. Returns the lanes hit with
/// `tmin ≤ t < tmax` and the hit data (meaningful in those lanes only).
#[inline(always)]
fn intersect_triangle_lanes(
    l: &Lanes,
    k: [usize; 3],
    tri: &TriVerts,
    tmax: F32s,
    m: u32,
) -> (u32, F32s, [F32s; 3], F32s) {
    let [kx, ky, kz] = k;
    let vertex = |i: usize| [F32s::splat(tri[3 * i + kx]), F32s::splat(tri[3 * i + ky]), F32s::splat(tri[3 * i + kz])];
    watertight_lanes([vertex(0), vertex(1), vertex(2)], l.origin_k, l.shear, l.tmin, tmax, m)
}

/// Slab constants of one node for all lanes (the SIMD twin of `node_slabs`).
#[inline(always)]
fn lane_slabs(node: &obvhs::cwbvh::node::CwBvhNode, l: &Lanes) -> ([F32s; 3], [F32s; 3], [F32s; 3]) {
    let e = node_extent(node);
    let p = node.p.to_array();
    let mut a = [F32s::ZERO; 3];
    let mut bn = [F32s::ZERO; 3];
    let mut bf = [F32s::ZERO; 3];
    for i in 0..3 {
        let po = F32s::splat(p[i]) - l.origin[i];
        let b = po * l.inv[i];
        let delta = l.pad[i] * (F32s::splat(255.0) * F32s::splat(e[i]) + po.abs());
        a[i] = F32s::splat(e[i]) * l.inv[i];
        bn[i] = b - delta;
        bf[i] = b + delta;
    }
    (a, bn, bf)
}

/// Per-child lane masks and entry distances of one node for the lanes in `m`.
#[inline(always)]
fn node_lanes(
    node: &obvhs::cwbvh::node::CwBvhNode,
    l: &Lanes,
    oct_inv: u32,
    tfar: F32s,
    m: u32,
    masks: &mut [u32; 8],
    tnear: &mut [F32s; 8],
) -> u32 {
    let (a, bn, bf) = lane_slabs(node, l);
    let neg = [oct_inv & 4 == 0, oct_inv & 2 == 0, oct_inv & 1 == 0];
    // Converting the six plane arrays once (6 × vpmovzxbd + vcvtdq2ps) and broadcasting from
    // memory per child is cheaper than a scalar byte → float conversion per child and plane.
    let planes = child_planes(node, neg).map(|p| bytes_to_f32s(p).to_array());
    let mut any = 0;
    let mut occ = occupied_slots(node);
    while occ != 0 {
        let c = occ.trailing_zeros() as usize;
        occ &= occ - 1;
        // A closure rather than `planes.map(..)`: LLVM has left that array map out of line
        // here after unrelated changes elsewhere in the crate (13 % of a glossy frame).
        let q = |k: usize| F32s::splat(planes[k][c]);
        let nx = q(0) * a[0] + bn[0];
        let ny = q(1) * a[1] + bn[1];
        let nz = q(2) * a[2] + bn[2];
        let fx = q(3) * a[0] + bf[0];
        let fy = q(4) * a[1] + bf[1];
        let fz = q(5) * a[2] + bf[2];
        let tn = nx.fast_max(ny).fast_max(nz.fast_max(l.tmin));
        let tf = fx.fast_min(fy).fast_min(fz.fast_min(tfar));
        let hit = tn.simd_le(tf).to_bitmask() & m;
        masks[c] = hit;
        tnear[c] = tn;
        if hit != 0 {
            any |= 1 << c;
        }
    }
    any
}

impl TriangleBvh {
    /// Closest hits of the active lanes of a packet. For every active lane, `hits` receives its
    /// hit or [`PacketHits::NONE`]'s values; inactive lanes are left untouched. Returns the mask
    /// of lanes that hit. Each lane's result equals [`TriangleBvh::intersect`] of that lane's ray
    /// (up to exact ties in `t`).
    pub fn intersect_packet(&self, rays: &RayPacket, active: u32, hits: &mut PacketHits) -> u32 {
        self.intersect_packet_with(rays, active, hits, SINGLE_RAY_THRESHOLD)
    }

    /// Lanes (among the active ones) that hit anything in `[tmin, tmax)`. Equals
    /// [`TriangleBvh::occluded`] per lane.
    pub fn occluded_packet(&self, rays: &RayPacket, active: u32) -> u32 {
        self.occluded_packet_with(rays, active, SINGLE_RAY_THRESHOLD)
    }

    /// [`Self::intersect_packet`] with an explicit single-ray threshold (for the bench's
    /// threshold sweep; `0` never falls back, `8` always traces single rays).
    pub fn intersect_packet_with(&self, rays: &RayPacket, active: u32, hits: &mut PacketHits, threshold: u32) -> u32 {
        let active = active & ALL_LANES;
        let l = Lanes::new(rays, active);
        let mut best = LaneBest {
            t: l.tmax,
            e1: F32s::ZERO,
            e2: F32s::ZERO,
            det: F32s::ONE,
            slot: F32s::splat(f32::from_bits(u32::MAX)),
        };
        if !self.is_empty() {
            for group in classes(&l) {
                self.packet_search(&l, group, &mut best, threshold);
            }
        }
        let mut hit_mask = 0;
        for i in lane_iter(active) {
            let h = self.finish(&best.lane(i));
            if h.is_some() {
                hit_mask |= 1 << i;
            }
            hits.set(i, h);
        }
        #[cfg(feature = "check-scalar")]
        self.check_packet_closest(rays, active, hits);
        hit_mask
    }

    /// [`Self::occluded_packet`] with an explicit single-ray threshold.
    pub fn occluded_packet_with(&self, rays: &RayPacket, active: u32, threshold: u32) -> u32 {
        let active = active & ALL_LANES;
        let l = Lanes::new(rays, active);
        let mut occluded = 0;
        if !self.is_empty() {
            for group in classes(&l) {
                let mut search = LanesAlive { alive: group, tfar: l.tmax };
                self.packet_search(&l, group, &mut search, threshold);
                occluded |= group & !search.alive;
            }
        }
        #[cfg(feature = "check-scalar")]
        for i in lane_iter(active) {
            assert_eq!(occluded & (1 << i) != 0, self.occluded(&rays.ray(i)), "packet occlusion lane {i}");
        }
        occluded
    }

    /// The lanes of `group` (one class) through the tree for `search`: as single rays when
    /// there are at most `threshold` of them, else as a packet whose entries drop to single
    /// rays once at most `threshold` lanes are left in them.
    ///
    /// Runs the loop's AVX-512 build where the tree's [`TriangleBvh::isa`] says so.
    fn packet_search<S: PacketSearch>(&self, l: &Lanes, group: u32, search: &mut S, threshold: u32) {
        #[cfg(target_arch = "x86_64")]
        if self.isa() == crate::isa::Isa::Avx512 {
            // SAFETY: `set_isa` and the build store `Avx512` only where the CPU has it.
            unsafe { self.packet_search_avx512(l, group, search, threshold) };
            return;
        }
        self.packet_search_loop(l, group, search, threshold);
    }

    /// [`Self::packet_search_loop`] compiled with AVX-512 (F, BW, DQ, VL): the same eight-lane
    /// source, so the same hits, with 32 vector registers and compares into mask registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
    fn packet_search_avx512<S: PacketSearch>(&self, l: &Lanes, group: u32, search: &mut S, threshold: u32) {
        self.packet_search_loop(l, group, search, threshold);
    }

    /// The loop of [`Self::packet_search`], inlined into each instruction set's build.
    #[inline(always)]
    fn packet_search_loop<S: PacketSearch>(&self, l: &Lanes, group: u32, search: &mut S, threshold: u32) {
        if group.count_ones() <= threshold {
            for i in lane_iter(group) {
                search.single(self, l, i, 0);
            }
            return;
        }
        let r0 = l.lane(group.trailing_zeros() as usize);
        let (oct_inv, k) = (r0.oct_inv, r0.k);
        let nodes = self.nodes();
        let mut stack: FixedStack<Entry, PACKET_STACK> = FixedStack::new();
        stack.push(Entry { node: 0, mask: group, tnear: l.tmin.to_array() });
        let mut masks = [0u32; 8];
        let mut tnear = [F32s::ZERO; 8];
        while let Some(entry) = stack.pop() {
            let m = search.live(entry.mask, F32s::from(entry.tnear));
            if m == 0 {
                continue;
            }
            if m.count_ones() <= threshold {
                for i in lane_iter(m) {
                    search.single(self, l, i, entry.node);
                }
                if search.done() {
                    break;
                }
                continue;
            }
            let node = &nodes[entry.node as usize];
            let hit_children = node_lanes(node, l, oct_inv, search.tfar(), m, &mut masks, &mut tnear);
            let imask = node.imask as u32;
            let mut leaves = hit_children & !imask;
            while leaves != 0 {
                let slot = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (first, count) = leaf_range(node, slot);
                for i in first..first + count {
                    let lm = search.searching(masks[slot]);
                    if lm == 0 {
                        break;
                    }
                    search.triangle(l, k, self.tri(i), i, lm);
                }
            }
            if search.done() {
                break;
            }
            let inner = hit_children & imask;
            if inner != 0 {
                for key in 0..8u32 {
                    let slot = key ^ oct_inv;
                    if inner & (1 << slot) != 0 {
                        let s = slot as usize;
                        stack.push(Entry {
                            node: inner_child_index(node.child_base_idx, imask, slot),
                            mask: masks[s],
                            tnear: tnear[s].to_array(),
                        });
                    }
                }
            }
        }
    }

    #[cfg(feature = "check-scalar")]
    fn check_packet_closest(&self, rays: &RayPacket, active: u32, hits: &PacketHits) {
        for i in lane_iter(active) {
            let ray = rays.ray(i);
            let single = self.intersect(&ray);
            let packet = hits.get(i);
            match (packet, single) {
                (None, None) => {}
                (Some(p), Some(s)) => {
                    assert_eq!(p.t.to_bits(), s.t.to_bits(), "packet lane {i}: t {} vs single {}", p.t, s.t);
                    if p.prim != s.prim {
                        // Only an exact tie may pick another triangle.
                        use crate::bvh::intersect_triangle;
                        let r = PreparedRay::new(&ray).expect("hit implies valid");
                        let slot = (0..self.triangles_bvh_order().len() as u32)
                            .find(|&j| self.original_index(j) == p.prim)
                            .expect("prim");
                        let h = intersect_triangle(&r, self.tri(slot), f32::INFINITY).map(|h| h.t);
                        assert_eq!(h, Some(s.t), "packet lane {i}: prim {} vs single {}", p.prim, s.prim);
                    }
                }
                (p, s) => panic!("packet lane {i}: {p:?} vs single {s:?}"),
            }
        }
    }
}

/// Lanes of `candidates` whose class is `class`.
#[inline(always)]
fn lanes_of_class(l: &Lanes, candidates: u32, class: u32) -> u32 {
    let mut m = 0;
    for i in lane_iter(candidates) {
        if l.class[i] == class {
            m |= 1 << i;
        }
    }
    m
}

/// The valid lanes of a packet split by class (see the module notes), lowest lane's first.
#[inline(always)]
fn classes(l: &Lanes) -> impl Iterator<Item = u32> + '_ {
    let mut rest = l.valid;
    core::iter::from_fn(move || {
        if rest == 0 {
            return None;
        }
        let group = lanes_of_class(l, rest, l.class[rest.trailing_zeros() as usize]);
        rest &= !group;
        Some(group)
    })
}

/// Indices of the set bits of `mask`, lowest first.
#[inline(always)]
fn lane_iter(mask: u32) -> impl Iterator<Item = usize> {
    let mut m = mask;
    core::iter::from_fn(move || {
        if m == 0 {
            None
        } else {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            Some(i)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildQuality, Hit, PreparedRay, Ray, intersect_triangle};
    use glam::Vec3;

    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut rng = crate::synth::Rng::new(seed);
        move || rng.next_f32()
    }

    /// The SIMD triangle test equals the scalar reference lane for lane, bit for bit,
    /// including rays exactly through vertices and edges (the f64 path).
    #[test]
    fn triangle_lanes_match_scalar() {
        let mut r = rng(7);
        for case in 0..2000 {
            let v: Vec<Vec3> = (0..3).map(|_| Vec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0)).collect();
            let tri: TriVerts = crate::bvh::tri_verts(&[v[0], v[1], v[2]]);
            // One class per packet: a shared base direction with small perturbations, and every
            // other case aims lanes exactly at the vertices (axis-aligned rays).
            let base = Vec3::new(r() - 0.5, r() - 0.5, 1.0 + r());
            let rays: [Ray; LANES] = core::array::from_fn(|i| {
                if case % 2 == 1 {
                    let target = v[i % 3];
                    Ray::new(target + Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 0.0, -1.0))
                } else {
                    let o = Vec3::new(r() - 0.5, r() - 0.5, -3.0);
                    Ray::new(o, base + Vec3::new(r(), r(), 0.0) * 0.1)
                }
            });
            let packet = RayPacket::from_rays(&rays);
            let l = Lanes::new(&packet, ALL_LANES);
            let class = l.class[0];
            let m = lanes_of_class(&l, l.valid, class);
            let tmax = F32s::splat(f32::INFINITY);
            let (h, t, e, det) = intersect_triangle_lanes(&l, l.lane(0).k, &tri, tmax, m);
            for i in lane_iter(m) {
                let s = intersect_triangle(&PreparedRay::new(&rays[i]).unwrap(), &tri, f32::INFINITY);
                assert_eq!(h & (1 << i) != 0, s.is_some(), "case {case} lane {i}");
                if let Some(s) = s {
                    assert_eq!(t.to_array()[i].to_bits(), s.t.to_bits());
                    assert_eq!(det.to_array()[i].to_bits(), s.det.to_bits());
                    for j in 0..3 {
                        assert_eq!(e[j].to_array()[i].to_bits(), s.e[j].to_bits());
                    }
                }
            }
        }
    }

    fn same_bits(a: &PreparedRay, b: &PreparedRay) -> bool {
        let f = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        f(&a.origin.to_array()) == f(&b.origin.to_array())
            && f(&a.inv.to_array()) == f(&b.inv.to_array())
            && f(&a.pad.to_array()) == f(&b.pad.to_array())
            && f(&a.shear) == f(&b.shear)
            && f(&a.origin_k) == f(&b.origin_k)
            && a.oct_inv == b.oct_inv
            && a.k == b.k
            && a.tmin.to_bits() == b.tmin.to_bits()
            && a.tmax.to_bits() == b.tmax.to_bits()
            && a.class() == b.class()
    }

    /// The SIMD lane preparation equals `PreparedRay::new` bit for bit, and agrees on which
    /// rays are valid, for random rays and edge values (±0, tiny, huge, inf, NaN components).
    #[test]
    fn lanes_match_prepared_ray() {
        let mut r = rng(3);
        let specials = [0.0, -0.0, 1e-30, -1e-30, 1e-10, 2.3283064e-10, -5e9, 4e9, f32::INFINITY, f32::NAN, 1.0, -1.0];
        for case in 0..5000 {
            let mut pick = |scale: f32| {
                if r() < 0.3 {
                    specials[(r() * specials.len() as f32) as usize % specials.len()]
                } else {
                    (r() * 2.0 - 1.0) * scale
                }
            };
            let rays: [Ray; LANES] = core::array::from_fn(|_| Ray {
                origin: Vec3::new(pick(10.0), pick(10.0), pick(10.0)),
                dir: Vec3::new(pick(1.0), pick(1.0), pick(1.0)),
                tmin: if case % 3 == 0 { pick(1.0) } else { 0.0 },
                tmax: if case % 2 == 0 { pick(100.0) } else { f32::INFINITY },
            });
            let active = (case as u32 * 37) & ALL_LANES;
            let l = Lanes::new(&RayPacket::from_rays(&rays), active);
            for i in 0..LANES {
                let s = PreparedRay::new(&rays[i]);
                assert_eq!(l.valid & (1 << i) != 0, s.is_some() && active & (1 << i) != 0, "{:?}", rays[i]);
                if let Some(s) = s.filter(|_| active & (1 << i) != 0) {
                    assert!(same_bits(&l.lane(i), &s), "{:?}\n{:?}\n{:?}", rays[i], l.lane(i), s);
                }
            }
        }
    }

    #[test]
    fn packet_hits_round_trip() {
        let mut p = PacketHits::NONE;
        let h = Hit { t: 1.5, prim: 3, u: 0.25, v: 0.5 };
        p.set(2, Some(h));
        assert_eq!(p.get(2), Some(h));
        assert_eq!(p.get(1), None);
    }

    #[test]
    fn one_triangle_packet() {
        let tris = [[Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]];
        let (bvh, _) = TriangleBvh::build(&tris, BuildQuality::Medium).unwrap();
        let rays: [Ray; LANES] =
            core::array::from_fn(|i| Ray::new(Vec3::new(i as f32 * 0.1 - 0.35, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)));
        let mut hits = PacketHits::NONE;
        let m = bvh.intersect_packet_with(&RayPacket::from_rays(&rays), ALL_LANES, &mut hits, 0);
        assert_eq!(m, ALL_LANES);
        for i in 0..LANES {
            assert_eq!(hits.get(i), bvh.intersect(&rays[i]));
        }
    }
}

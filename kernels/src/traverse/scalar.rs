//! Single-ray traversal (obvhs's compact group stack, written for our watertight triangle
//! test and robust node test) and brute force over every triangle, the oracle of both
//! traversals.
//!
//! A node's hit leaf children hold up to 24 triangles in one run of slots; a single ray tests
//! them eight slots at a time ([`intersect_triangles_lanes`], bit for bit the scalar test
//! per slot, the nearest hit and the first slot on equal `t`, as testing them one by one
//! finds). Measured against one at a time on one thread (three alternating pairs, criterion
//! medians, `benches/traversal.rs`): Sponza diffuse rays 1.28 → 1.64 Mrays/s, the 700k
//! scene's primary, shadow and diffuse rays 5–8 % faster, Sponza primary and shadow within the
//! noise (`BENCHMARKS.md`).

use super::ALL_LANES;
use super::{FixedStack, Search};
use crate::bvh::{
    Hit, MAX_DEPTH, PreparedRay, Ray, Tri, TriHit, TriangleBvh, inner_child_index, intersect_triangle,
    intersect_triangles_lanes, leaf_range, node_hits, slots_to_keys,
};
use crate::simd::LANES;
use obvhs::cwbvh::node::CwBvhNode;

/// The triangles of a node's leaf children in `leaves` (a child-slot mask), as bits over the
/// node's run of slots from `primitive_base_idx` (up to 24: at most three per child, each
/// child's run following the previous one's).
#[inline(always)]
fn leaf_lanes(node: &CwBvhNode, mut leaves: u32) -> u32 {
    let mut lanes = 0;
    while leaves != 0 {
        let slot = leaves.trailing_zeros() as usize;
        leaves &= leaves - 1;
        let (first, count) = leaf_range(node, slot);
        lanes |= ((1u32 << count) - 1) << (first - node.primitive_base_idx);
    }
    lanes
}

/// A set of not-yet-visited inner children of one node, as obvhs's traversal keeps them:
/// `keys` has bit `slot ^ oct_inv` set for each, visited highest key first. One 12-byte
/// entry per node instead of one per child.
#[derive(Clone, Copy, Default)]
struct Group {
    base: u32,
    imask: u32,
    keys: u32,
}

/// The group that visits exactly node `root`: key 7 with an empty `imask` resolves to
/// `base + 0` whatever the octant.
#[inline(always)]
fn root_group(root: u32) -> Group {
    Group { base: root, imask: 0, keys: 0x80 }
}

/// What a single-ray search keeps: its far bound, and what a hit below it does.
pub(crate) trait SingleSearch {
    /// The current far bound (exclusive): triangles and boxes at or beyond it are skipped.
    fn tfar(&self) -> f32;
    /// Records a hit on the triangle in BVH slot `slot` (its `t` is below [`Self::tfar`]).
    /// Returns [`Search::Stop`] to end the traversal.
    fn hit(&mut self, slot: u32, hit: TriHit) -> Search;
}

/// Closest hit: the BVH slot of the best triangle so far and its hit; its `t` is the far
/// bound, so each hit shrinks the search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Best {
    pub(crate) slot: u32,
    pub(crate) hit: TriHit,
}

impl Best {
    pub(crate) fn none(tmax: f32) -> Self {
        Best { slot: u32::MAX, hit: TriHit { t: tmax, e: [0.0; 3], det: 1.0 } }
    }
}

impl SingleSearch for Best {
    #[inline(always)]
    fn tfar(&self) -> f32 {
        self.hit.t
    }

    #[inline(always)]
    fn hit(&mut self, slot: u32, hit: TriHit) -> Search {
        *self = Best { slot, hit };
        Search::GoOn
    }
}

/// Any hit below a fixed `tmax` (occlusion): the first one ends the search.
pub(crate) struct AnyHit {
    pub(crate) tmax: f32,
}

impl SingleSearch for AnyHit {
    #[inline(always)]
    fn tfar(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn hit(&mut self, _: u32, _: TriHit) -> Search {
        Search::Stop
    }
}

impl TriangleBvh {
    /// Closest hit along the ray, or `None` (also for an invalid ray).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let r = PreparedRay::new(ray)?;
        let mut best = Best::none(r.tmax);
        if !self.is_empty() {
            self.traverse(&r, 0, &mut best);
        }
        self.finish(&best)
    }

    /// True if any triangle is hit with `tmin ≤ t < tmax` (false for an invalid ray).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        match PreparedRay::new(ray) {
            Some(r) if !self.is_empty() => self.traverse(&r, 0, &mut AnyHit { tmax: r.tmax }),
            _ => false,
        }
    }

    /// Closest hit by testing every stored triangle (the oracle for tests).
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<Hit> {
        let r = PreparedRay::new(ray)?;
        let mut best = Best::none(r.tmax);
        for (i, tri) in self.triangles_bvh_order().iter().enumerate() {
            if let Some(h) = intersect_triangle(&r, tri, best.hit.t) {
                best = Best { slot: i as u32, hit: h };
            }
        }
        self.finish(&best)
    }

    /// The hit record of a search's best triangle (`None` if it found none).
    #[inline]
    pub(super) fn finish(&self, best: &Best) -> Option<Hit> {
        if best.slot == u32::MAX {
            return None;
        }
        let (u, v) = best.hit.uv();
        Some(Hit { t: best.hit.t, prim: self.original_index(best.slot), u, v })
    }

    /// Single-ray traversal of the subtree at node `root` for `search` (closest or any hit).
    /// Returns true if `search` recorded a hit.
    pub(crate) fn traverse<S: SingleSearch>(&self, r: &PreparedRay, root: u32, search: &mut S) -> bool {
        let nodes = self.nodes();
        let mut found = false;
        let mut stack: FixedStack<Group, MAX_DEPTH> = FixedStack::new();
        let mut group = root_group(root);
        loop {
            if group.keys == 0 {
                match stack.pop() {
                    Some(g) => group = g,
                    None => return found,
                }
            }
            let key = 31 - group.keys.leading_zeros();
            group.keys &= !(1 << key);
            let idx = inner_child_index(group.base, group.imask, key ^ r.oct_inv);
            if group.keys != 0 {
                stack.push(group);
            }
            let node = &nodes[idx as usize];
            let hits = node_hits(node, r, search.tfar());
            let imask = node.imask as u32;
            let leaves = hits & !imask;
            if leaves != 0 {
                // The hit leaves' triangles, as bits over the node's run of up to 24 slots,
                // tested eight slots at a time.
                let mut lanes = leaf_lanes(node, leaves);
                while lanes != 0 {
                    let chunk = lanes.trailing_zeros() / LANES as u32;
                    let first = node.primitive_base_idx + chunk * LANES as u32;
                    let chunk_lanes = (lanes >> (chunk * LANES as u32)) & ALL_LANES;
                    lanes &= !(ALL_LANES << (chunk * LANES as u32));
                    let tested =
                        intersect_triangles_lanes(r, self.planes(), first as usize, chunk_lanes, search.tfar());
                    if let Some((lane, h)) = tested {
                        found = true;
                        if search.hit(first + lane, h) == Search::Stop {
                            return true;
                        }
                    }
                }
            }
            group = Group { base: node.child_base_idx, imask, keys: slots_to_keys(hits & imask, r.oct_inv) };
        }
    }
}

/// Closest hit over a plain triangle list by brute force (the test oracle; `prim` is the index
/// into `tris`).
pub fn intersect_brute_force(tris: &[Tri], ray: &Ray) -> Option<Hit> {
    let r = PreparedRay::new(ray)?;
    let mut best: Option<(u32, TriHit)> = None;
    for (i, t) in tris.iter().enumerate() {
        let tv = [t[0].x, t[0].y, t[0].z, t[1].x, t[1].y, t[1].z, t[2].x, t[2].y, t[2].z];
        let tmax = best.map_or(r.tmax, |b| b.1.t);
        if let Some(h) = intersect_triangle(&r, &tv, tmax) {
            best = Some((i as u32, h));
        }
    }
    best.map(|(i, h)| {
        let (u, v) = h.uv();
        Hit { t: h.t, prim: i, u, v }
    })
}

//! Single-ray traversal (front to back over the uncompressed [`WideNode`]s, with our
//! watertight triangle test) and brute force over every triangle, the oracle of both
//! traversals.
//!
//! Per node: one test of the ray against the eight child boxes ([`wide_node_hits`], which
//! also gives each child's entry distance); the hit leaf children's triangles (up to 24, one
//! run of slots) tested eight at a time ([`intersect_triangles_lanes`], bit for bit the
//! scalar test per slot: the nearest hit, the first slot on equal `t`); then the hit inner
//! children still in reach visited nearest first, the rest pushed with their entry distance
//! and skipped on pop, without reading their node, once a nearer hit has put them out of
//! reach. A node's triangles are 288-byte blocks of eight ([`crate::bvh::TriangleLanes`]),
//! so a leaf test reads adjacent lines.
//!
//! What each step measured, one thread, `benches/traverse.rs`, single rays, Mrays/s, the
//! builds run alternately on the same machine (`BENCHMARKS.md` has the whole table):
//!
//! | step | atrium primary | atrium shadow | atrium diffuse | Sponza diffuse |
//! |---|--:|--:|--:|--:|
//! | obvhs's octant-ordered group stack over CWBVH nodes | 3.53 | 4.04 | 2.06 | 2.71 |
//! | children ordered and culled by entry distance | 3.87 | 4.69 | 2.19 | 2.69 |
//! | leaf triangles in per-node blocks of eight | 3.91 | 5.02 | 2.21 | 2.79 |
//! | uncompressed nodes with exact boxes | 5.52 | 7.83 | 2.70 | 3.48 |
//! | the same boxes widened by the position pad ([`crate::bvh::wide`]: a fuzz finding) | **5.07** | **6.60** | **2.27** | **2.86** |
//!
//! (The last two rows come from a later alternated pair than the others: 5.67, 7.74, 2.62,
//! 3.41 unpadded against the padded row.)
//!
//! Tried and not kept: prefetching a child's first triangle block while fetching the child
//! (and on pop). It cost 10–25 % on primary and shadow rays, whose blocks are already cached,
//! and gained nothing measurable on diffuse ones.

use super::ALL_LANES;
use super::{FixedStack, Search};
use crate::bvh::wide::{SlabOrigins, WideNode, in_reach, wide_node_hits};
use crate::bvh::{
    Hit, MAX_DEPTH, PreparedRay, Ray, Tri, TriHit, TriangleBvh, inner_child_index, intersect_triangle,
    intersect_triangles_lanes, tri_verts,
};
use crate::simd::LANES;

/// A child waiting on the single-ray stack: its node and the distance at which the ray
/// enters its box (popped nearest first; skipped when a hit nearer than that was found).
#[derive(Clone, Copy)]
struct Entry {
    node: u32,
    tnear: f32,
}

/// At most seven siblings wait per level of the tree (the nearest is visited at once).
const SINGLE_STACK: usize = 7 * MAX_DEPTH + 1;

/// What a traversal counts as it goes (the attribution of its cost, `BENCHMARKS.md`).
/// Production traversal uses [`NoCounts`], whose methods are empty and compile away.
pub(crate) trait Counter {
    /// A node was read and its `children` occupied child boxes tested; `leaves` and `inner`
    /// of them were hit.
    fn node(&mut self, children: u32, leaves: u32, inner: u32);
    /// `triangles` triangle tests ran (a block of lanes of a hit leaf run).
    fn triangles(&mut self, triangles: u32);
    /// A waiting child was popped and skipped: a hit found since put it out of reach.
    fn skipped(&mut self);
}

/// No counting (production traversal).
pub(crate) struct NoCounts;

impl Counter for NoCounts {
    #[inline(always)]
    fn node(&mut self, _: u32, _: u32, _: u32) {}
    #[inline(always)]
    fn triangles(&mut self, _: u32) {}
    #[inline(always)]
    fn skipped(&mut self) {}
}

impl Counter for super::TraversalCounts {
    fn node(&mut self, children: u32, leaves: u32, inner: u32) {
        self.nodes += 1;
        self.box_tests += u64::from(children);
        self.leaves += u64::from(leaves);
        self.inner_hits += u64::from(inner);
    }
    fn triangles(&mut self, triangles: u32) {
        self.triangles += u64::from(triangles);
        self.triangle_blocks += 1;
    }
    fn skipped(&mut self) {
        self.skipped += 1;
    }
}

/// What a single-ray search keeps: its far bound, and what a hit below it does.
pub(crate) trait SingleSearch {
    /// Whether the search wants the closest hit. Its far bound then shrinks with each hit, so
    /// waiting children are visited nearest first and re-checked against it after a leaf hit.
    /// An any-hit search ends at its first hit and its far bound never changes: it visits
    /// children in slot order, with neither the sort nor the re-check (Embree's any-hit order).
    const CLOSEST: bool;
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
    const CLOSEST: bool = true;

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
    const CLOSEST: bool = false;

    #[inline(always)]
    fn tfar(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn hit(&mut self, _: u32, _: TriHit) -> Search {
        Search::Stop
    }
}

/// Any hit below a fixed `tmax` that `blocks` (given the BVH slot and the hit) accepts; the
/// others are skipped, as if their triangles were not there.
pub(crate) struct AnyHitWhere<F> {
    pub(crate) tmax: f32,
    pub(crate) blocks: F,
}

impl<F: FnMut(u32, &TriHit) -> bool> SingleSearch for AnyHitWhere<F> {
    const CLOSEST: bool = false;

    #[inline(always)]
    fn tfar(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn hit(&mut self, slot: u32, hit: TriHit) -> Search {
        if (self.blocks)(slot, &hit) { Search::Stop } else { Search::Skip }
    }
}

impl TriangleBvh {
    /// Closest hit along the ray, or `None` (also for an invalid ray).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let r = PreparedRay::new(ray)?;
        let mut best = Best::none(r.tmax);
        if !self.is_empty() {
            self.traverse(&r, 0, &mut best, &mut NoCounts);
        }
        self.finish(&best)
    }

    /// [`TriangleBvh::intersect`] that adds what the traversal did to `counts` (the same
    /// loop, counting: slower, for attribution only).
    pub fn intersect_counted(&self, ray: &Ray, counts: &mut super::TraversalCounts) -> Option<Hit> {
        counts.rays += 1;
        let r = PreparedRay::new(ray)?;
        let mut best = Best::none(r.tmax);
        if !self.is_empty() {
            self.traverse(&r, 0, &mut best, counts);
        }
        self.finish(&best)
    }

    /// [`TriangleBvh::occluded`] that adds what the traversal did to `counts`.
    pub fn occluded_counted(&self, ray: &Ray, counts: &mut super::TraversalCounts) -> bool {
        counts.rays += 1;
        match PreparedRay::new(ray) {
            Some(r) if !self.is_empty() => self.traverse(&r, 0, &mut AnyHit { tmax: r.tmax }, counts),
            _ => false,
        }
    }

    /// True if any triangle is hit with `tmin ≤ t < tmax` (false for an invalid ray).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        match PreparedRay::new(ray) {
            Some(r) if !self.is_empty() => self.traverse(&r, 0, &mut AnyHit { tmax: r.tmax }, &mut NoCounts),
            _ => false,
        }
    }

    /// True if a triangle that `blocks(prim, u, v)` accepts is hit with `tmin ≤ t < tmax`
    /// (false for an invalid ray): occlusion where some surfaces are holes (cut-out
    /// materials). The same any-hit search as [`TriangleBvh::occluded`], which ends at the
    /// first accepted hit; a refused hit is skipped without lowering the far bound, where a
    /// closest-hit search restarted past each hole would read the tree again per hole and
    /// could not stop early.
    #[inline]
    pub fn occluded_where(&self, ray: &Ray, mut blocks: impl FnMut(u32, f32, f32) -> bool) -> bool {
        match PreparedRay::new(ray) {
            Some(r) if !self.is_empty() => {
                let accepts = |slot: u32, hit: &TriHit| {
                    let (u, v) = hit.uv();
                    blocks(self.original_index(slot), u, v)
                };
                self.traverse(&r, 0, &mut AnyHitWhere { tmax: r.tmax, blocks: accepts }, &mut NoCounts)
            }
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
    ///
    /// Front to back by distance: a node's hit leaves are tested first (so a hit shrinks the
    /// far bound before anything is pushed); its hit inner children nearer than the far bound
    /// are visited nearest first, the others pushed with their entry distance, and a popped
    /// child whose entry lies beyond the far bound found since is skipped without reading
    /// its node (see the module notes for what this measured against obvhs's octant order).
    ///
    /// Runs the loop's AVX-512 build where the tree's [`TriangleBvh::isa`] says so.
    pub(crate) fn traverse<S: SingleSearch, C: Counter>(
        &self,
        r: &PreparedRay,
        root: u32,
        search: &mut S,
        counter: &mut C,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.isa() == crate::isa::Isa::Avx512 {
            // SAFETY: `set_isa` and the build store `Avx512` only where the CPU has it.
            return unsafe { self.traverse_avx512(r, root, search, counter) };
        }
        self.traverse_loop(r, root, search, counter)
    }

    /// [`Self::traverse_loop`] compiled with AVX-512 (F, BW, DQ, VL): the same eight-lane
    /// source, so the same hits, with 32 vector registers and compares into mask registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
    fn traverse_avx512<S: SingleSearch, C: Counter>(
        &self,
        r: &PreparedRay,
        root: u32,
        search: &mut S,
        counter: &mut C,
    ) -> bool {
        self.traverse_loop(r, root, search, counter)
    }

    /// The loop of [`Self::traverse`], inlined into each instruction set's build.
    #[inline(always)]
    fn traverse_loop<S: SingleSearch, C: Counter>(
        &self,
        r: &PreparedRay,
        root: u32,
        search: &mut S,
        counter: &mut C,
    ) -> bool {
        let nodes = self.wide_nodes();
        let origins = SlabOrigins::new(r, self.bounds());
        let mut found = false;
        let mut stack: FixedStack<Entry, SINGLE_STACK> = FixedStack::new();
        let mut idx = root;
        loop {
            let node = &nodes[idx as usize];
            let (hits, tnear) = wide_node_hits(node, r, &origins, search.tfar());
            let imask = node.imask;
            let leaves = hits & !imask;
            counter.node(node.occupied.count_ones(), leaves.count_ones(), (hits & imask).count_ones());
            if leaves != 0 {
                // The hit leaves' triangles, as bits over the node's run of up to 24 slots,
                // tested eight slots at a time.
                let mut lanes = node.leaf_lanes(leaves);
                while lanes != 0 {
                    let chunk = lanes.trailing_zeros() / LANES as u32;
                    let first = node.primitive_base + chunk * LANES as u32;
                    let mut chunk_lanes = (lanes >> (chunk * LANES as u32)) & ALL_LANES;
                    lanes &= !(ALL_LANES << (chunk * LANES as u32));
                    counter.triangles(chunk_lanes.count_ones());
                    let block = self.leaf_block(node, chunk);
                    // Once for the closest and any-hit searches (whose `hit` never skips);
                    // a filtered search tests the block again without each hit it skips.
                    while let Some((lane, h)) = intersect_triangles_lanes(r, block, chunk_lanes, search.tfar()) {
                        match search.hit(first + lane, h) {
                            Search::Stop => return true,
                            Search::GoOn => {
                                found = true;
                                break;
                            }
                            Search::Skip => chunk_lanes &= !(1 << lane),
                        }
                    }
                }
            }
            let mut inner = hits & imask;
            if inner != 0 {
                let tnear = tnear.to_array();
                let tfar = search.tfar();
                if S::CLOSEST && leaves != 0 {
                    // A leaf hit may have brought the far bound below some children.
                    inner &= tnear.iter().enumerate().fold(0, |m, (s, &t)| m | (u32::from(in_reach(t, tfar)) << s));
                }
                if inner.is_power_of_two() {
                    // One child: no stack traffic.
                    idx = inner_child_index(node.child_base, imask, inner.trailing_zeros());
                    continue;
                }
                if inner != 0 {
                    idx = if S::CLOSEST {
                        push_children_nearest_last(&mut stack, node, inner, &tnear)
                    } else {
                        push_children_in_slot_order(&mut stack, node, inner, &tnear)
                    };
                    continue;
                }
            }
            // Nothing below this node: the nearest waiting child still in reach.
            loop {
                match stack.pop() {
                    None => return found,
                    Some(e) if in_reach(e.tnear, search.tfar()) => {
                        idx = e.node;
                        break;
                    }
                    Some(_) => counter.skipped(),
                }
            }
        }
    }
}

/// Pushes the children in `inner` (at least two) so that the stack's top holds the nearest
/// after the one returned (the nearest, visited at once): sorted by entry distance, farthest
/// deepest (of equal distances, the later slot is visited first).
#[inline(always)]
fn push_children_nearest_last(
    stack: &mut FixedStack<Entry, SINGLE_STACK>,
    node: &WideNode,
    mut inner: u32,
    tnear: &[f32; LANES],
) -> u32 {
    let mut sorted = [Entry { node: 0, tnear: 0.0 }; LANES];
    let mut n = 0;
    while inner != 0 {
        let slot = inner.trailing_zeros();
        inner &= inner - 1;
        let e = Entry { node: inner_child_index(node.child_base, node.imask, slot), tnear: tnear[slot as usize] };
        // Insertion into descending order of entry distance (at most eight children).
        let mut i = n;
        while i > 0 && sorted[i - 1].tnear < e.tnear {
            sorted[i] = sorted[i - 1];
            i -= 1;
        }
        sorted[i] = e;
        n += 1;
    }
    for e in &sorted[..n - 1] {
        stack.push(*e);
    }
    sorted[n - 1].node
}

/// Pushes the children in `inner` (at least two) in slot order, all but the last slot's,
/// which is returned to be visited at once: the any-hit order, without a sort.
#[inline(always)]
fn push_children_in_slot_order(
    stack: &mut FixedStack<Entry, SINGLE_STACK>,
    node: &WideNode,
    mut inner: u32,
    tnear: &[f32; LANES],
) -> u32 {
    loop {
        let slot = inner.trailing_zeros();
        inner &= inner - 1;
        let child = inner_child_index(node.child_base, node.imask, slot);
        if inner == 0 {
            return child;
        }
        stack.push(Entry { node: child, tnear: tnear[slot as usize] });
    }
}

/// Closest hit over a plain triangle list by brute force (the test oracle; `prim` is the index
/// into `tris`).
pub fn intersect_brute_force(tris: &[Tri], ray: &Ray) -> Option<Hit> {
    let r = PreparedRay::new(ray)?;
    let mut best: Option<(u32, TriHit)> = None;
    for (i, t) in tris.iter().enumerate() {
        let tv = tri_verts(t);
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

//! The binary trees and their collapse to obvhs's CWBVH: our binned SAH build (the default),
//! obvhs's PLOC, and the median split that bounds the depth of a degenerate tree.

use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocBuilder;
use obvhs::splits::split_aabbs_preset;
use obvhs::triangle::Triangle as ObvhsTriangle;

use super::node::inner_child_index;
use super::ray::Tri;

/// Deepest CWBVH (levels, root = 1) the traversal stacks are sized for. Trees deeper than
/// this (PLOC's or the SAH build's) are rebuilt by median split. Sponza's PLOC tree is 10 levels deep, the bench's 700k
/// procedural scene 12; 5000 coincident triangles give PLOC a chain 714 levels deep.
pub const MAX_DEPTH: usize = 40;

/// obvhs's `build_cwbvh_from_tris` without its debug-build validation (which asserts a depth
/// below 32 and would panic on the degenerate trees the median fallback exists for).
pub(super) fn build_cwbvh_ploc(tris: &[Tri], config: &BvhBuildParams) -> CwBvh {
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
pub(super) fn build_cwbvh_sah(tris: &[Tri], config: &BvhBuildParams) -> CwBvh {
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
pub(super) fn build_bvh2_median(tris: &[Tri]) -> Bvh2 {
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

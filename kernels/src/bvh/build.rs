//! The binary trees and their collapse to obvhs's CWBVH: our binned SAH build, with or
//! without spatial splits, obvhs's PLOC, and the median split that bounds the depth of a
//! degenerate tree.

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

/// The CWBVH of a binned SAH binary tree ([`build_bvh2_binned_sah`], or
/// [`build_bvh2_spatial_splits`] with `spatial_splits`), improved by `config`'s reinsertion
/// and collapsed by obvhs as the PLOC tree is.
pub(super) fn build_cwbvh_sah(tris: &[Tri], config: &BvhBuildParams, spatial_splits: bool) -> CwBvh {
    let mut bvh2 = if spatial_splits { build_bvh2_spatial_splits(tris) } else { build_bvh2_binned_sah(tris) };
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

/// Object bins per axis of the binned SAH build.
pub const SAH_BINS: usize = 32;

/// Spatial bins per axis of the spatial-split build (fewer than object bins, as Embree
/// has: every reference is clipped into each bin it crosses, the build's largest cost).
pub const SPATIAL_BINS: usize = 16;

/// Where a spatial split is tried: where the best object split's two boxes overlap by more
/// than this share of the root box's area (Stich, Friedrich and Dietrich 2009, *Spatial
/// Splits in Bounding Volume Hierarchies*, who found 10⁻⁵ a good threshold).
pub const SPLIT_OVERLAP: f32 = 1e-5;

/// The spatial-split build's budget of extra leaf references, as a share of the triangles:
/// once it is spent, nodes split by object only.
pub const SPLIT_BUDGET: f32 = 0.5;

/// One leaf reference of the top-down build: a triangle and the part of its box this
/// reference stands for (the whole box, or a slab of it after spatial splits).
#[derive(Clone, Copy, Debug)]
struct Reference {
    tri: u32,
    bounds: Aabb,
}

/// A binary BVH by the surface-area heuristic, binned (Wald 2007, *On fast construction of
/// SAH-based bounding volume hierarchies*): each node's triangles are split where, over
/// [`SAH_BINS`] bins of centroid position on each axis, `area(left)·count(left) +
/// area(right)·count(right)` is least; one triangle per leaf (obvhs's collapse to the 8-wide
/// tree decides the leaves). Where every centroid coincides, or a split would leave a side
/// empty, it splits at the median, so the depth stays bounded.
pub fn build_bvh2_binned_sah(tris: &[Tri]) -> Bvh2 {
    build_bvh2_sah(tris, 0.0)
}

/// [`build_bvh2_binned_sah`] with spatial splits (an SBVH, Stich et al. 2009): where the
/// best object split's children overlap ([`SPLIT_OVERLAP`]), the node is also binned in
/// space ([`SPATIAL_BINS`]), each triangle clipped into every bin it crosses, and a plane
/// that cuts triangles wins when its SAH cost is lower. A cut triangle is referenced on both sides, each
/// reference bounding only its own slab of the triangle (unless putting it whole on one side
/// costs less, Stich's unsplitting). At most `SPLIT_BUDGET`·n extra references are made.
/// Long thin triangles crossing open space (an atrium's floor, a column) then stop making
/// every box they sit in large.
pub fn build_bvh2_spatial_splits(tris: &[Tri]) -> Bvh2 {
    build_bvh2_sah(tris, SPLIT_BUDGET)
}

/// The top-down SAH build, with `split_budget`·n spatial-split references allowed (0: none).
/// Subtrees of at least [`PARALLEL_REFERENCES`] references build in parallel (rayon, on the
/// caller's pool); the tree does not depend on the schedule: each node's share of the split
/// budget is its parent's remainder divided by reference count, not a shared counter.
fn build_bvh2_sah(tris: &[Tri], split_budget: f32) -> Bvh2 {
    let n = tris.len();
    let refs: Vec<Reference> =
        tris.iter().enumerate().map(|(i, t)| Reference { tri: i as u32, bounds: tri_box(t) }).collect();
    let min_overlap = SPLIT_OVERLAP * bounds_of(&refs).half_area();
    let budget = (n as f32 * split_budget) as usize;
    let tree = build_subtree(tris, refs, budget, min_overlap);
    Bvh2 {
        nodes: tree.nodes,
        primitive_indices: tree.primitive_indices,
        uses_spatial_splits: split_budget > 0.0,
        ..Bvh2::default()
    }
}

/// Subtrees at least this large are split off to build in parallel.
const PARALLEL_REFERENCES: usize = 8192;

/// A binary subtree: its root is `nodes[0]`, child and primitive indices are its own.
struct Subtree {
    nodes: Vec<Bvh2Node>,
    primitive_indices: Vec<u32>,
}

/// The subtree over `refs` with `budget` spatial-split references to spend.
fn build_subtree(tris: &[Tri], refs: Vec<Reference>, budget: usize, min_overlap: f32) -> Subtree {
    if refs.len() < PARALLEL_REFERENCES {
        return build_subtree_serial(tris, refs, budget, min_overlap);
    }
    let aabb = bounds_of(&refs);
    let (left, right, budgets) = split_node(tris, refs, &aabb, budget, min_overlap);
    let (l, r) = rayon::join(
        || build_subtree(tris, left, budgets[0], min_overlap),
        || build_subtree(tris, right, budgets[1], min_overlap),
    );
    // The serial build's layout, so a tree does not depend on where the parallel part ends
    // (obvhs's reinsertion depends on node order: numbering the left subtree first gave
    // courtyard a 3 % worse tree): the root, its two children (adjacent, as obvhs requires),
    // then the rest of the right subtree, then the rest of the left one, and the right
    // subtree's primitives first. obvhs also finds a sibling by parity (first children at odd
    // indices), so every moved index keeps its parity: a right subtree's node k ≥ 1 lands at
    // k + 2, a left one's at k + R + 1 (the right subtree's size R is odd). Inner nodes' child
    // indices are ≥ 1 and move the same way.
    let size_r = r.nodes.len() as u32;
    let left_prims = r.primitive_indices.len() as u32;
    let moved = |node: &Bvh2Node, node_offset: u32, prim_offset: u32| {
        let offset = if node.is_leaf() { prim_offset } else { node_offset };
        Bvh2Node::new(*node.aabb(), node.prim_count, node.first_index + offset)
    };
    let mut nodes = Vec::with_capacity(1 + l.nodes.len() + r.nodes.len());
    nodes.push(Bvh2Node::new(aabb, 0, 1));
    nodes.push(moved(&l.nodes[0], size_r + 1, left_prims));
    nodes.push(moved(&r.nodes[0], 2, 0));
    nodes.extend(r.nodes[1..].iter().map(|node| moved(node, 2, 0)));
    nodes.extend(l.nodes[1..].iter().map(|node| moved(node, size_r + 1, left_prims)));
    let mut primitive_indices = r.primitive_indices;
    primitive_indices.extend(l.primitive_indices);
    Subtree { nodes, primitive_indices }
}

fn build_subtree_serial(tris: &[Tri], refs: Vec<Reference>, budget: usize, min_overlap: f32) -> Subtree {
    let mut nodes = vec![Bvh2Node::default()];
    let mut primitive_indices = Vec::with_capacity(refs.len());
    // (node index, its references, its split budget); the right child is popped first (the
    // order the SAH build has always numbered nodes in, which obvhs's reinsertion is
    // sensitive to).
    let mut work = vec![(0usize, refs, budget)];
    while let Some((node, refs, budget)) = work.pop() {
        let aabb = bounds_of(&refs);
        if let [only] = refs[..] {
            nodes[node] = Bvh2Node::new(aabb, 1, primitive_indices.len() as u32);
            primitive_indices.push(only.tri);
            continue;
        }
        let (left, right, budgets) = split_node(tris, refs, &aabb, budget, min_overlap);
        let first = nodes.len();
        nodes.extend([Bvh2Node::default(); 2]);
        nodes[node] = Bvh2Node::new(aabb, 0, first as u32);
        work.push((first, left, budgets[0]));
        work.push((first + 1, right, budgets[1]));
    }
    Subtree { nodes, primitive_indices }
}

fn vertices(t: &Tri) -> [Vec3A; 3] {
    [t[0].into(), t[1].into(), t[2].into()]
}

fn tri_box(t: &Tri) -> Aabb {
    Aabb::from_points(&vertices(t))
}

fn bounds_of(refs: &[Reference]) -> Aabb {
    refs.iter().fold(Aabb::empty(), |a, r| a.union(&r.bounds))
}

/// The best object split: SAH cost, axis, last bin on the left, and the two sides' boxes.
struct ObjectSplit {
    cost: f32,
    axis: usize,
    last: usize,
    left: Aabb,
    right: Aabb,
}

/// Bins `refs` by centroid on each axis and sweeps for the cheapest plane; `None` when every
/// centroid coincides. `bin(axis, r)` is the one rule both the sweep and the partition use.
fn best_object_split(
    refs: &[Reference],
    bin: &impl Fn(usize, &Reference) -> usize,
    extent: Vec3A,
) -> Option<ObjectSplit> {
    let mut best: Option<ObjectSplit> = None;
    for axis in 0..3 {
        if !(extent[axis] > 0.0) {
            continue;
        }
        let mut counts = [0u32; SAH_BINS];
        let mut boxes = [Aabb::empty(); SAH_BINS];
        for r in refs {
            let b = bin(axis, r);
            counts[b] += 1;
            boxes[b] = boxes[b].union(&r.bounds);
        }
        let sweep = Sweep::new(&boxes, &counts, &counts);
        if let Some((cost, last)) = sweep.best(refs.len())
            && best.as_ref().is_none_or(|b| cost < b.cost)
        {
            best = Some(ObjectSplit { cost, axis, last, left: sweep.left[last], right: sweep.right[last + 1] });
        }
    }
    best
}

/// Running boxes and counts of a binned sweep: `left[b]` bounds bins `0..=b`, `right[b]`
/// bins `b..`; `enter[b]` counts what starts in a bin, `exit[b]` what ends there (equal for
/// object bins).
struct Sweep<const BINS: usize> {
    left: [Aabb; BINS],
    right: [Aabb; BINS],
    n_left: [u32; BINS],
    n_right: [u32; BINS],
}

impl<const BINS: usize> Sweep<BINS> {
    fn new(boxes: &[Aabb; BINS], enter: &[u32; BINS], exit: &[u32; BINS]) -> Self {
        let mut s =
            Self { left: [Aabb::empty(); BINS], right: [Aabb::empty(); BINS], n_left: [0; BINS], n_right: [0; BINS] };
        let (mut acc, mut n) = (Aabb::empty(), 0u32);
        for b in 0..BINS {
            acc = acc.union(&boxes[b]);
            n += enter[b];
            (s.left[b], s.n_left[b]) = (acc, n);
        }
        let (mut acc, mut n) = (Aabb::empty(), 0u32);
        for b in (0..BINS).rev() {
            acc = acc.union(&boxes[b]);
            n += exit[b];
            (s.right[b], s.n_right[b]) = (acc, n);
        }
        s
    }

    /// The cheapest plane between bins `last` and `last + 1` that leaves each side fewer than
    /// all `total` references and more than none (so every split shrinks both children and
    /// the build ends), and its cost.
    fn best(&self, total: usize) -> Option<(f32, usize)> {
        let mut best: Option<(f32, usize)> = None;
        for last in 0..BINS - 1 {
            let (nl, nr) = (self.n_left[last], self.n_right[last + 1]);
            if nl == 0 || nr == 0 || nl as usize >= total || nr as usize >= total {
                continue;
            }
            let cost = self.left[last].half_area() * nl as f32 + self.right[last + 1].half_area() * nr as f32;
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, last));
            }
        }
        best
    }
}

/// The best spatial split of a node with box `aabb`: cost, axis, plane position, and the
/// sweep's sides at that plane (for unsplitting).
struct SpatialSplit {
    cost: f32,
    axis: usize,
    plane: f32,
    left: Aabb,
    right: Aabb,
    n_left: u32,
    n_right: u32,
}

/// The position of spatial plane `i` (between bins `i − 1` and `i`) on `axis`: the one
/// formula both the binning and the partition use.
#[inline]
fn plane_at(aabb: &Aabb, axis: usize, i: usize) -> f32 {
    aabb.min[axis] + (aabb.max[axis] - aabb.min[axis]) * (i as f32 / SPATIAL_BINS as f32)
}

fn best_spatial_split(tris: &[Tri], refs: &[Reference], aabb: &Aabb) -> Option<SpatialSplit> {
    let mut best: Option<SpatialSplit> = None;
    let extent = aabb.diagonal();
    for axis in 0..3 {
        if !(extent[axis] > 0.0) {
            continue;
        }
        let scale = SPATIAL_BINS as f32 / extent[axis];
        let bin = |x: f32| (((x - aabb.min[axis]) * scale).max(0.0) as usize).min(SPATIAL_BINS - 1);
        let mut boxes = [Aabb::empty(); SPATIAL_BINS];
        let (mut enter, mut exit) = ([0u32; SPATIAL_BINS], [0u32; SPATIAL_BINS]);
        for r in refs {
            let (first, last) = (bin(r.bounds.min[axis]), bin(r.bounds.max[axis]));
            let mut rest = Some(r.bounds);
            if first < last {
                let v = vertices(&tris[r.tri as usize]);
                for b in first..last {
                    let Some(part) = rest else { break };
                    let (l, right) = split_reference(&v, &part, axis, plane_at(aabb, axis, b + 1));
                    if let Some(l) = l {
                        boxes[b] = boxes[b].union(&l);
                    }
                    rest = right;
                }
            }
            if let Some(part) = rest {
                boxes[last] = boxes[last].union(&part);
            }
            enter[first] += 1;
            exit[last] += 1;
        }
        let sweep = Sweep::new(&boxes, &enter, &exit);
        if let Some((cost, last)) = sweep.best(refs.len())
            && best.as_ref().is_none_or(|b| cost < b.cost)
        {
            best = Some(SpatialSplit {
                cost,
                axis,
                plane: plane_at(aabb, axis, last + 1),
                left: sweep.left[last],
                right: sweep.right[last + 1],
                n_left: sweep.n_left[last],
                n_right: sweep.n_right[last + 1],
            });
        }
    }
    best
}

/// The boxes of the parts of triangle `v` on either side of the plane at `plane` on `axis`,
/// within `bounds` (the part of the triangle the reference stands for); `None` for a side
/// the part has no point on. Conservative: each box holds the vertices on its side and the
/// edge–plane intersections, padded for their rounding, so it holds the triangle's part on
/// that side; cut to `bounds`, it holds the reference's part there, and where that cut is
/// empty so is the part.
#[inline]
fn split_reference(v: &[Vec3A; 3], bounds: &Aabb, axis: usize, plane: f32) -> (Option<Aabb>, Option<Aabb>) {
    let (mut left, mut right) = (Aabb::empty(), Aabb::empty());
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let (da, db) = (a[axis] - plane, b[axis] - plane);
        if da <= 0.0 {
            left.extend(a);
        }
        if da >= 0.0 {
            right.extend(a);
        }
        if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
            let s = ((plane - a[axis]) / (b[axis] - a[axis])).clamp(0.0, 1.0);
            let p = a + (b - a) * s;
            // A few roundings in `p`: pad it by far more than they can be.
            let pad = a.abs().max(b.abs()) * PAD_SPLIT_POINT;
            let (mut lo, mut hi) = (p - pad, p + pad);
            (lo[axis], hi[axis]) = (plane, plane);
            let crossing = Aabb::new(lo, hi);
            left = left.union(&crossing);
            right = right.union(&crossing);
        }
    }
    left.max[axis] = left.max[axis].min(plane);
    right.min[axis] = right.min[axis].max(plane);
    let within = |side: Aabb| {
        let cut = side.intersection(bounds);
        // obvhs's `valid` is not inlined: 8 % of a spatial-split build.
        cut.min.cmple(cut.max).all().then_some(cut)
    };
    (within(left), within(right))
}

/// Relative pad of an edge–plane intersection point (2⁻¹⁸: hundreds of times the rounding
/// of its two operations).
const PAD_SPLIT_POINT: f32 = 1.0 / (1 << 18) as f32;

/// Splits one node's references into two non-empty sides: by the cheaper of the best object
/// split and (where the object split's sides overlap by more than `min_overlap` and `budget`
/// is left) the best spatial split, or at the median where neither exists. Returns the sides
/// and their shares of what is left of the budget (in proportion to their sizes).
fn split_node(
    tris: &[Tri],
    refs: Vec<Reference>,
    aabb: &Aabb,
    budget: usize,
    min_overlap: f32,
) -> (Vec<Reference>, Vec<Reference>, [usize; 2]) {
    let shares = |left: &Vec<Reference>, right: &Vec<Reference>, left_over: usize| {
        let l = (left_over as u64 * left.len() as u64 / (left.len() + right.len()) as u64) as usize;
        [l, left_over - l]
    };
    let centroid_box = refs.iter().fold(Aabb::empty(), |mut a, r| {
        a.extend(r.bounds.center());
        a
    });
    let extent = centroid_box.diagonal();
    let bin = |axis: usize, r: &Reference| {
        let scale = SAH_BINS as f32 / extent[axis];
        (((r.bounds.center()[axis] - centroid_box.min[axis]) * scale) as usize).min(SAH_BINS - 1)
    };
    let object = best_object_split(&refs, &bin, extent);
    if budget > 0 {
        let overlap = object.as_ref().map_or(f32::INFINITY, |o| {
            let both = o.left.intersection(&o.right);
            if both.valid() { both.half_area() } else { 0.0 }
        });
        if overlap > min_overlap
            && let Some(spatial) = best_spatial_split(tris, &refs, aabb)
            && object.as_ref().is_none_or(|o| spatial.cost < o.cost)
            && let Some((left, right)) = partition_spatial(tris, &refs, &spatial)
        {
            let made = left.len() + right.len() - refs.len();
            let budgets = shares(&left, &right, budget.saturating_sub(made));
            return (left, right, budgets);
        }
    }
    if let Some(o) = object {
        let (left, right): (Vec<_>, Vec<_>) = refs.iter().partition(|r| bin(o.axis, r) <= o.last);
        if !left.is_empty() && !right.is_empty() {
            let budgets = shares(&left, &right, budget);
            return (left, right, budgets);
        }
    }
    // Every centroid coincides (or the bins could not separate them): the median.
    let axis = centroid_box.largest_axis();
    let mut refs = refs;
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| a.bounds.center()[axis].total_cmp(&b.bounds.center()[axis]));
    let right = refs.split_off(mid);
    let budgets = shares(&refs, &right, budget);
    (refs, right, budgets)
}

/// The references on either side of a spatial split's plane: those wholly on one side go
/// there; a reference crossing it goes whole to one side where that costs less than
/// splitting it (unsplitting), else is split into both. `None` if a side would be empty.
fn partition_spatial(tris: &[Tri], refs: &[Reference], s: &SpatialSplit) -> Option<(Vec<Reference>, Vec<Reference>)> {
    let (axis, plane) = (s.axis, s.plane);
    let (mut left, mut right) = (Vec::with_capacity(s.n_left as usize), Vec::with_capacity(s.n_right as usize));
    let (mut left_box, mut right_box) = (s.left, s.right);
    let (mut nl, mut nr) = (s.n_left as f32, s.n_right as f32);
    for r in refs {
        if r.bounds.max[axis] <= plane {
            left.push(*r);
        } else if r.bounds.min[axis] >= plane {
            right.push(*r);
        } else {
            let split_cost = left_box.half_area() * nl + right_box.half_area() * nr;
            let all_left = left_box.union(&r.bounds).half_area() * nl + right_box.half_area() * (nr - 1.0);
            let all_right = left_box.half_area() * (nl - 1.0) + right_box.union(&r.bounds).half_area() * nr;
            if all_left < split_cost && all_left <= all_right {
                left_box = left_box.union(&r.bounds);
                nr -= 1.0;
                left.push(*r);
            } else if all_right < split_cost {
                right_box = right_box.union(&r.bounds);
                nl -= 1.0;
                right.push(*r);
            } else {
                // A side the triangle's part has no point on gets no reference.
                let part = |bounds| Reference { tri: r.tri, bounds };
                match split_reference(&vertices(&tris[r.tri as usize]), &r.bounds, axis, plane) {
                    (Some(l), Some(rr)) => {
                        left.push(part(l));
                        right.push(part(rr));
                    }
                    (Some(l), None) => left.push(part(l)),
                    (None, Some(rr)) => right.push(part(rr)),
                    // Not for a reference whose part is not empty; kept whole all the same.
                    (None, None) => right.push(*r),
                }
            }
        }
    }
    let shrinks = |side: &Vec<Reference>| !side.is_empty() && side.len() < refs.len();
    (shrinks(&left) && shrinks(&right)).then_some((left, right))
}

/// A binary BVH by median split of centroids along the widest centroid axis, one triangle
/// per leaf (what obvhs's CWBVH converter expects). Depth ⌈log₂ n⌉ + 1 whatever the
/// geometry, so coincident triangles cannot make it deep. Only used as the fallback.
pub(super) fn build_bvh2_median(tris: &[Tri]) -> Bvh2 {
    let n = tris.len();
    let bounds: Vec<Aabb> = tris.iter().map(tri_box).collect();
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
        let mut cb = Aabb::empty();
        for &p in &prims[lo..hi] {
            cb.extend(centroid(p));
        }
        let axis = cb.largest_axis();
        let mid = lo + (hi - lo) / 2;
        prims[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| centroid(a)[axis].total_cmp(&centroid(b)[axis]));
        nodes[node] = Bvh2Node::new(aabb, 0, next as u32);
        work.push((next, lo, mid));
        work.push((next + 1, mid, hi));
        next += 2;
    }
    debug_assert_eq!(next, 2 * n - 1);
    Bvh2 { nodes, primitive_indices: prims, ..Bvh2::default() }
}

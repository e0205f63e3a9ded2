//! Triangle BVH (obvhs CWBVH): the build, rays, the watertight triangle test and the robust
//! node test. Traversal (single rays and packets, closest and any hit) is in [`crate::traverse`].
//!
//! # What obvhs does and what this module does
//! The binary tree is ours by default (a binned SAH build, [`build_bvh2_binned_sah`]; its
//! SAH cost is 6–30 % below obvhs's PLOC tree on the built-in scenes, `BENCHMARKS.md`), ours
//! with spatial splits ([`BuildQuality::SahSplits`], [`build_bvh2_spatial_splits`]: a
//! triangle may then be in several leaves, each leaf's box bounding only its part) or
//! obvhs's PLOC ([`BuildQuality::Fast`], `Medium`, `High`); obvhs then reinserts, collapses
//! it to its compressed 8-wide BVH (80-byte [`CwBvhNode`]s) and owns that layout; this module copies the triangles into BVH order
//! (one 36-byte record per `primitive_indices` slot, so a node's up-to-24 leaf triangles are
//! one contiguous run) and traverses the nodes itself. Single rays read each node again in
//! an uncompressed form with exact f32 child boxes ([`crate::bvh::wide`]: 256 bytes per node
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

mod build;
mod node;
mod ray;
mod triangle;
pub mod wide;

use core::fmt;
use std::time::{Duration, Instant};

use glam::Vec3;

pub use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;

pub use build::{
    MAX_DEPTH, SAH_BINS, SPATIAL_BINS, SPLIT_BUDGET, SPLIT_OVERLAP, build_bvh2_binned_sah, build_bvh2_spatial_splits,
    cwbvh_depth,
};
use build::{build_bvh2_median, build_cwbvh_ploc, build_cwbvh_sah};
pub use node::{
    NodeSlabs, bytes_to_f32s, child_planes, inner_child_index, leaf_meta, leaf_range, node_extent, node_hits,
    node_hits_scalar, node_slabs, occupied_slots,
};
pub use ray::{Hit, MAX_COORD, MAX_DIR, MAX_ORIGIN, MIN_DIR, PreparedRay, Ray, Tri, safe_rcp};
pub(crate) use ray::{NODE_PAD, RCP_CLAMP};
pub(crate) use triangle::watertight_lanes;
pub use triangle::{
    TriHit, TriVerts, TriangleLanes, gamma, intersect_triangle, intersect_triangle_line, intersect_triangles_lanes,
    tri_verts,
};
use wide::{WideNode, wide_nodes};

use crate::isa::Isa;
use crate::simd::LANES;

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
    /// [`Sah`](Self::Sah) with spatial splits ([`build_bvh2_spatial_splits`], an SBVH): a
    /// triangle crossing open space may be cut into several leaves, each bounding its own
    /// part, at most [`SPLIT_BUDGET`] extra references per triangle.
    SahSplits,
}

impl BuildQuality {
    /// The obvhs parameters of this preset (a starting point for
    /// [`TriangleBvh::build_with`]).
    pub fn params(self) -> BvhBuildParams {
        match self {
            BuildQuality::Fast => BvhBuildParams::fast_build(),
            BuildQuality::Medium => BvhBuildParams::medium_build(),
            BuildQuality::High => BvhBuildParams::slow_build(),
            BuildQuality::Sah | BuildQuality::SahSplits => BvhBuildParams::medium_build(),
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
    /// The nodes again for single rays, with exact f32 child boxes ([`crate::bvh::wide`]).
    wide: Vec<WideNode>,
    /// The exact bounds of every triangle (`[min, max]`; zeros when empty).
    bounds: [[f32; 3]; 2],
    /// `primitive_indices` (BVH slot → caller's triangle index), kept as its own array.
    prim_ids: Vec<u32>,
    stats: BuildStats,
    /// The instruction set the traversal loops run with ([`TriangleBvh::set_isa`]).
    isa: Isa,
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
                Some(BuildQuality::Sah) => build_cwbvh_sah(tris, params, false),
                Some(BuildQuality::SahSplits) => build_cwbvh_sah(tris, params, true),
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
        let tris_bvh: Vec<TriVerts> = prim_ids.iter().map(|&i| tri_verts(&tris[i as usize])).collect();
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
        Ok((Self { cwbvh, tris: tris_bvh, blocks, wide, bounds, prim_ids, stats, isa: Isa::active() }, stats))
    }

    /// The instruction set the traversal loops (single rays and packets) run with:
    /// [`Isa::active`] when the tree is built.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Runs the traversal loops with `isa`'s build of them, or the 8-lane build where the CPU
    /// lacks it ([`Isa::is_supported`]). Both builds are the same source compiled twice, the
    /// second with AVX-512 enabled (32 vector registers and mask compares, still eight lanes),
    /// so they give the same hits bit for bit; this lets tests and benches run both in one
    /// process.
    pub fn set_isa(&mut self, isa: Isa) {
        self.isa = if isa.is_supported() { isa } else { Isa::Avx2 };
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
        let tv = tri_verts(&t);
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
                    tri_verts(&[a, b, c])
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

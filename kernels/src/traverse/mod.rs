//! Ray traversal of the CWBVH of [`TriangleBvh`](crate::bvh::TriangleBvh): closest hit and
//! any hit (occlusion), for single rays and for 8-lane packets.
//!
//! | file | what |
//! |---|---|
//! | `mod.rs` | packet types, the search kinds, the fixed stack |
//! | `scalar.rs` | single-ray traversal (`TriangleBvh::intersect`, `occluded`; a node's hit leaves are tested eight triangles at a time, [`crate::bvh::intersect_triangles_lanes`]) and brute force over every triangle with the scalar test ([`intersect_brute_force`], `TriangleBvh::intersect_brute_force`), the oracle of both traversals |
//! | `simd.rs` | the body: packets of eight rays (`TriangleBvh::intersect_packet`, `occluded_packet`) |
//!
//! The BVH, rays, the watertight triangle test and the robust node test are in
//! [`crate::bvh`]; the bench is `benches/traverse.rs`, the tests `kernels/tests/traversal.rs`,
//! the fuzz target `fuzz/fuzz_targets/traverse.rs` (build and traversal together).
//!
//! # One loop per layout, generic over the search
//! Closest hit and any hit differ only in their far bound (the best hit so far, or the ray's
//! `tmax`) and in what a triangle hit does (shrink the bound and go on, or stop), so each
//! layout has one traversal loop generic over the search (`SingleSearch` and `PacketSearch`,
//! implemented by the closest-hit and any-hit states). The two layouts keep their own loops
//! because their nodes and stacks differ where it costs: a single ray reads the uncompressed
//! [`WideNode`](crate::bvh::wide::WideNode)s and keeps one 8-byte entry per waiting child (node,
//! entry distance), while a packet reads the CWBVH, whose decoding it shares among eight rays,
//! and needs each child's lane mask and per-lane entry distances (one 40-byte entry per
//! child). Sharing one loop would give single rays, which are most of the diffuse and glossy
//! bounces, the packet's stack. Generic code is monomorphised: each (layout, search) pair
//! compiles to the loop that was written out by hand before, and traces at the same speed
//! (`BENCHMARKS.md`).
//!
//! # How a packet is traced
//! 1. **Lanes.** Each active lane is prepared exactly as a single ray ([`PreparedRay`](crate::bvh::PreparedRay)), then
//!    transposed to structure-of-arrays `F32s`. Invalid lanes (NaN, zero or infinite
//!    directions, see [`Ray::is_valid`]) drop out of the active mask and report a miss.
//! 2. **Classes.** Active lanes are grouped by [`PreparedRay::class`](crate::bvh::PreparedRay::class): the sign octant of
//!    the direction and its dominant axis. Inside a class every lane picks the same near/far
//!    child planes and the watertight test's axis permutation is uniform, so both are scalar
//!    decisions instead of per-lane blends. Coherent packets (a 8×1 or 4×2 tile of primary
//!    rays, shadow rays toward one light) are almost always one class.
//! 3. **Node test** (ray-parallel): per child slot, its six quantised planes are broadcast and
//!    tested against the eight lanes at once with the same conservative slab arithmetic as
//!    the single-ray test (`q·(e·inv) + (p − o)·inv ∓ δ`, see [`crate::bvh`]), against
//!    each lane's current `tfar` (closest hit so far). The result is a lane mask per child.
//! 4. **Order and stack.** Leaf children are intersected immediately (shrinking `tfar`
//!    before anything is pushed). Inner children with a non-empty lane mask are pushed in
//!    ascending `slot ^ oct_inv` key, so the child nearest for the class octant is popped first
//!    (obvhs's CWBVH stores children so that this key order is front to back). An entry is
//!    `(node, lane mask, per-lane entry distance)`; on pop, lanes whose entry distance is
//!    beyond their current `tfar` are removed, and the entry is skipped if none are left.
//!    The stack has a fixed `7·MAX_DEPTH + 1` entries (at most seven siblings wait per
//!    level), which the build's depth guarantee makes sufficient.
//! 5. **Fallback.** When a popped entry (or a class at the start) has at most
//!    [`SINGLE_RAY_THRESHOLD`] live lanes, its subtree is finished by the single-ray
//!    traversal, one lane at a time, starting at that node with the lane's current best hit.
//! 6. **Triangles** are tested eight lanes at a time with the watertight test written in the
//!    same operation order as the scalar [`crate::bvh::intersect_triangle`], including the
//!    double-precision recomputation of edge functions that round to zero (done per lane, in
//!    scalar code, which is rare). So a lane's `t`, `u` and `v` equal the single-ray results
//!    bit for bit; only which of two triangles at exactly the same `t` wins may differ.
//!
//! # Two builds of each loop
//! The single-ray loop and the packet loop are each compiled twice: for the binary's
//! x86-64-v3 baseline, and inside `#[target_feature]` functions with AVX-512 (F, BW, DQ, VL),
//! taken at run time where the CPU has it ([`crate::isa`]; `STEREOTRACE_ISA=avx2` forces the
//! first). The source is the same, so the hits are the same bits; the second build has 32
//! vector registers and compares into mask registers. It measured 0.88–1.04× the first's time
//! (median 0.95×) on Zen 4 (`BENCHMARKS.md`).
//!
//! Inactive lanes are never written: their entries of [`PacketHits`] keep whatever the caller
//! put there.
//!
//! # Threshold
//! [`SINGLE_RAY_THRESHOLD`] = 2 lanes. Measured by sweeping the threshold (0, 1, 2, 3, 4, 6)
//! over primary and shadow rays in 8×1 tiles at 1280×720 on Sponza and on the bench's 700k
//! procedural scene, one thread, thread CPU time, best of 15 interleaved repetitions (the
//! machine is shared, so wall time varies 2× between runs). Thresholds 0–2 were within 1 % of
//! each other (Sponza primary 8.73 / 8.73 / 8.66 Mrays/s, shadow 9.35 / 9.46 / 9.42;
//! procedural primary 9.41 / 9.50 / 9.39, shadow 6.97 / 7.16 / 7.17), 3 was 1–3 % slower and
//! 4–6 were 3–19 % slower. Of the equal choices, 2 is kept for the less coherent packets
//! (secondary rays) that the sweep does not cover, where dropping to single rays earlier
//! helps. The bench's `traversal/threshold` group repeats the sweep.
//!
//! # Cost of the pieces (measured the same way)
//! * Preparing lanes one at a time in scalar code and transposing took a third of a shadow
//!   packet's time; the SIMD preparation in `Lanes::new` made shadow packets ~2× faster.
//! * The packet stack (281 entries × 40 bytes) is left uninitialised: zero-initialising it per
//!   packet was the largest single cost after that (an 11 KB memset/memmove per packet).

mod scalar;
mod simd;

use crate::bvh::{Hit, MAX_DEPTH, Ray};
use crate::simd::{F32s, LANES};
pub use scalar::intersect_brute_force;

/// What a search does after a triangle hit.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Search {
    /// Keep looking (closest hit).
    GoOn,
    /// Done (any hit).
    Stop,
    /// The hit does not count (a filtered any-hit search): the rest of its block is tested
    /// again without it, and the search goes on with its far bound unchanged.
    Skip,
}

/// Lanes at or below which a packet continues as single rays (see the module notes).
pub const SINGLE_RAY_THRESHOLD: u32 = 2;

/// Lane mask with every lane active.
pub const ALL_LANES: u32 = (1 << LANES) - 1;

const PACKET_STACK: usize = 7 * MAX_DEPTH + 1;

/// What single-ray traversal did over some rays (`TriangleBvh::intersect_counted`,
/// `occluded_counted`): the attribution of its cost. Divide by `rays` for per-ray figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Rays traced.
    pub rays: u64,
    /// Nodes read (one 8-wide box test each).
    pub nodes: u64,
    /// Child boxes tested (the occupied slots of the nodes read).
    pub box_tests: u64,
    /// Leaf children hit (entered).
    pub leaves: u64,
    /// Inner children hit (before culling by a nearer hit).
    pub inner_hits: u64,
    /// Triangle tests.
    pub triangles: u64,
    /// Triangle blocks tested: one SIMD test of up to eight of a node's leaf triangles each
    /// (the unit Embree's counters count, in its blocks of up to four).
    pub triangle_blocks: u64,
    /// Waiting children popped and skipped without reading their node.
    pub skipped: u64,
}

impl std::ops::AddAssign for TraversalCounts {
    fn add_assign(&mut self, o: Self) {
        self.rays += o.rays;
        self.nodes += o.nodes;
        self.box_tests += o.box_tests;
        self.leaves += o.leaves;
        self.inner_hits += o.inner_hits;
        self.triangles += o.triangles;
        self.triangle_blocks += o.triangle_blocks;
        self.skipped += o.skipped;
    }
}

/// Eight rays, structure of arrays. Lane `i` is the ray `origin[·][i] + t·dir[·][i]`,
/// `t ∈ [tmin[i], tmax[i])`.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket {
    /// Origins x, y, z.
    pub origin: [F32s; 3],
    /// Directions x, y, z (any non-zero length).
    pub dir: [F32s; 3],
    /// Nearest accepted `t` per lane.
    pub tmin: F32s,
    /// Farthest `t` per lane (exclusive).
    pub tmax: F32s,
}

impl RayPacket {
    /// Transposes eight rays.
    pub fn from_rays(rays: &[Ray; LANES]) -> Self {
        let c = |f: &dyn Fn(&Ray) -> f32| F32s::from(core::array::from_fn::<f32, LANES, _>(|i| f(&rays[i])));
        RayPacket {
            origin: [c(&|r| r.origin.x), c(&|r| r.origin.y), c(&|r| r.origin.z)],
            dir: [c(&|r| r.dir.x), c(&|r| r.dir.y), c(&|r| r.dir.z)],
            tmin: c(&|r| r.tmin),
            tmax: c(&|r| r.tmax),
        }
    }

    /// Lane `i` as a single ray.
    pub fn ray(&self, i: usize) -> Ray {
        let g = |v: &F32s| v.to_array()[i];
        Ray {
            origin: glam::Vec3::new(g(&self.origin[0]), g(&self.origin[1]), g(&self.origin[2])),
            dir: glam::Vec3::new(g(&self.dir[0]), g(&self.dir[1]), g(&self.dir[2])),
            tmin: g(&self.tmin),
            tmax: g(&self.tmax),
        }
    }
}

/// Closest hits of a packet, structure of arrays. A miss is `prim == u32::MAX`, `t = inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PacketHits {
    /// Ray parameter of each lane's hit.
    pub t: [f32; LANES],
    /// Triangle index of each lane's hit (`u32::MAX`: miss).
    pub prim: [u32; LANES],
    /// Barycentric weight of `v1`.
    pub u: [f32; LANES],
    /// Barycentric weight of `v2`.
    pub v: [f32; LANES],
}

impl Default for PacketHits {
    fn default() -> Self {
        Self::NONE
    }
}

impl PacketHits {
    /// Every lane a miss.
    pub const NONE: PacketHits =
        PacketHits { t: [f32::INFINITY; LANES], prim: [u32::MAX; LANES], u: [0.0; LANES], v: [0.0; LANES] };

    /// Lane `i` as a hit record.
    pub fn get(&self, i: usize) -> Option<Hit> {
        (self.prim[i] != u32::MAX).then(|| Hit { t: self.t[i], prim: self.prim[i], u: self.u[i], v: self.v[i] })
    }

    fn set(&mut self, i: usize, hit: Option<Hit>) {
        let h = hit.unwrap_or(Hit::NONE);
        self.t[i] = h.t;
        self.prim[i] = h.prim;
        self.u[i] = h.u;
        self.v[i] = h.v;
    }
}

/// A fixed-capacity stack. `push` beyond the capacity panics (the build guarantees it cannot
/// happen: see [`MAX_DEPTH`]); it never overflows silently. The storage is left
/// uninitialised: zeroing the 11 KB packet stack for every packet cost ~8 % of a shadow
/// packet's time (measured with perf: a memmove of the whole array per call).
pub(crate) struct FixedStack<T: Copy, const N: usize> {
    items: [core::mem::MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> FixedStack<T, N> {
    #[inline(always)]
    pub(crate) fn new() -> Self {
        Self { items: [const { core::mem::MaybeUninit::uninit() }; N], len: 0 }
    }

    #[inline(always)]
    pub(crate) fn push(&mut self, v: T) {
        assert!(self.len < N, "traversal stack overflow: BVH deeper than MAX_DEPTH");
        self.items[self.len] = core::mem::MaybeUninit::new(v);
        self.len += 1;
    }

    #[inline(always)]
    pub(crate) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            None
        } else {
            self.len -= 1;
            // SAFETY: every index below `len` was written by `push` (and `T: Copy`, so reading
            // it out leaves nothing to drop).
            Some(unsafe { self.items[self.len].assume_init() })
        }
    }
}

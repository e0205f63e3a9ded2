//! Embree 3 as a peer in the traversal bench (feature `peer-embree`; Debian's
//! `libembree-dev`, Embree 3.13): the few calls needed to build a scene from our triangles
//! and trace our rays through it, single rays and 8-wide packets, closest hit and occlusion.
//!
//! The declarations follow `embree3/rtcore_*.h` of that version (checked against its
//! `rtcore_config.h`: one instance level, no minimum-width curves, so the intersect context is
//! flags + filter + one instance id). Only what the bench calls is declared; a hit is
//! `geomID != RTC_INVALID_GEOMETRY_ID`, an occluded ray comes back with `tfar = −∞`.

use std::ffi::{c_char, c_int, c_uint, c_void};

use stereotrace_kernels::bvh::{Ray, Tri};
use stereotrace_kernels::traverse::RayPacket;

type Device = *mut c_void;
type Scene = *mut c_void;
type Geometry = *mut c_void;

const INVALID_GEOMETRY_ID: c_uint = c_uint::MAX;
const GEOMETRY_TYPE_TRIANGLE: c_int = 0;
const BUFFER_TYPE_INDEX: c_int = 0;
const BUFFER_TYPE_VERTEX: c_int = 1;
const FORMAT_UINT3: c_int = 0x5003;
const FORMAT_FLOAT3: c_int = 0x9003;
/// `RTC_SCENE_FLAG_ROBUST` (rtcore_scene.h).
const SCENE_FLAG_ROBUST: c_int = 1 << 2;
const BUILD_QUALITY_HIGH: c_int = 2;
/// `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`: set for the packets of neighbouring pixels.
const CONTEXT_COHERENT: c_int = 1;

#[repr(C)]
struct IntersectContext {
    flags: c_int,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct Ray1 {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: c_uint,
    id: c_uint,
    flags: c_uint,
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct Hit1 {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: c_uint,
    geom_id: c_uint,
    inst_id: [c_uint; 1],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct RayHit1 {
    ray: Ray1,
    hit: Hit1,
}

#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct Ray8 {
    org: [[f32; 8]; 3],
    tnear: [f32; 8],
    dir: [[f32; 8]; 3],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [c_uint; 8],
    id: [c_uint; 8],
    flags: [c_uint; 8],
}

#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct Hit8 {
    ng: [[f32; 8]; 3],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [c_uint; 8],
    geom_id: [c_uint; 8],
    inst_id: [[c_uint; 8]; 1],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct RayHit8 {
    ray: Ray8,
    hit: Hit8,
}

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewDevice(config: *const c_char) -> Device;
    fn rtcReleaseDevice(device: Device);
    fn rtcNewScene(device: Device) -> Scene;
    fn rtcSetSceneBuildQuality(scene: Scene, quality: c_int);
    fn rtcSetSceneFlags(scene: Scene, flags: c_int);
    fn rtcCommitScene(scene: Scene);
    fn rtcReleaseScene(scene: Scene);
    fn rtcNewGeometry(device: Device, kind: c_int) -> Geometry;
    fn rtcSetNewGeometryBuffer(
        geometry: Geometry,
        kind: c_int,
        slot: c_uint,
        format: c_int,
        byte_stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: Geometry);
    fn rtcAttachGeometry(scene: Scene, geometry: Geometry) -> c_uint;
    fn rtcReleaseGeometry(geometry: Geometry);
    fn rtcIntersect1(scene: Scene, context: *mut IntersectContext, rayhit: *mut RayHit1);
    fn rtcOccluded1(scene: Scene, context: *mut IntersectContext, ray: *mut Ray1);
    fn rtcIntersect8(valid: *const c_int, scene: Scene, context: *mut IntersectContext, rayhit: *mut RayHit8);
    fn rtcOccluded8(valid: *const c_int, scene: Scene, context: *mut IntersectContext, ray: *mut Ray8);
}

/// An Embree device and a committed scene of one triangle mesh.
pub struct EmbreeScene {
    device: Device,
    scene: Scene,
}

// SAFETY: a committed Embree scene may be traced from any thread (Embree's documented
// contract); the handles are only released in `drop`.
unsafe impl Send for EmbreeScene {}
// SAFETY: as above: tracing takes the scene by shared reference.
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Builds Embree's BVH over `tris` (high build quality, Embree's best for tracing). With
    /// `robust`, Embree's robust mode (`RTC_SCENE_FLAG_ROBUST`: watertight Plücker triangle
    /// tests and conservative node tests, the like-for-like peer of our watertight tracer);
    /// without it, its fast default (Möller–Trumbore).
    pub fn new(tris: &[Tri], robust: bool) -> Self {
        // Embree's device configuration string from `STEREOTRACE_BENCH_EMBREE_CONFIG` (for
        // example `verbose=1`, which prints the ISA, builder and leaf format it picked).
        let config = std::env::var("STEREOTRACE_BENCH_EMBREE_CONFIG")
            .ok()
            .map(|c| std::ffi::CString::new(c).expect("STEREOTRACE_BENCH_EMBREE_CONFIG without NUL bytes"));
        // SAFETY: each call gets the handles the previous ones returned (checked non-null)
        // and buffers of exactly the declared size, filled before the commit.
        unsafe {
            let device = rtcNewDevice(config.as_ref().map_or(std::ptr::null(), |c| c.as_ptr()));
            assert!(!device.is_null(), "rtcNewDevice failed");
            let scene = rtcNewScene(device);
            rtcSetSceneBuildQuality(scene, BUILD_QUALITY_HIGH);
            if robust {
                rtcSetSceneFlags(scene, SCENE_FLAG_ROBUST);
            }
            let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
            let n = tris.len();
            let vertices =
                rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3, 12, 3 * n) as *mut f32;
            let indices = rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, n) as *mut u32;
            assert!(!vertices.is_null() && !indices.is_null(), "Embree buffer allocation failed");
            for (i, t) in tris.iter().enumerate() {
                for (k, v) in t.iter().enumerate() {
                    for c in 0..3 {
                        *vertices.add(9 * i + 3 * k + c) = v[c];
                    }
                    *indices.add(3 * i + k) = (3 * i + k) as u32;
                }
            }
            rtcCommitGeometry(geometry);
            rtcAttachGeometry(scene, geometry);
            rtcReleaseGeometry(geometry);
            rtcCommitScene(scene);
            Self { device, scene }
        }
    }

    fn context(coherent: bool) -> IntersectContext {
        IntersectContext {
            flags: if coherent { CONTEXT_COHERENT } else { 0 },
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        }
    }

    fn ray1(r: &Ray) -> Ray1 {
        Ray1 {
            org: r.origin.to_array(),
            tnear: r.tmin,
            dir: r.dir.to_array(),
            time: 0.0,
            tfar: r.tmax,
            mask: c_uint::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// The closest hit of each ray; returns how many hit.
    pub fn intersect(&self, rays: &[Ray]) -> u32 {
        let mut context = Self::context(false);
        let mut hits = 0;
        for r in rays {
            let mut rh = RayHit1 {
                ray: Self::ray1(r),
                hit: Hit1 { ng: [0.0; 3], u: 0.0, v: 0.0, prim_id: 0, geom_id: INVALID_GEOMETRY_ID, inst_id: [0] },
            };
            // SAFETY: a committed scene, an initialised context and ray-hit.
            unsafe { rtcIntersect1(self.scene, &mut context, &mut rh) };
            hits += u32::from(rh.hit.geom_id != INVALID_GEOMETRY_ID);
        }
        hits
    }

    /// Whether anything blocks each ray; returns how many are blocked.
    pub fn occluded(&self, rays: &[Ray]) -> u32 {
        let mut context = Self::context(false);
        let mut blocked = 0;
        for r in rays {
            let mut ray = Self::ray1(r);
            // SAFETY: as in `intersect`.
            unsafe { rtcOccluded1(self.scene, &mut context, &mut ray) };
            blocked += u32::from(ray.tfar == f32::NEG_INFINITY);
        }
        blocked
    }

    fn ray8(p: &RayPacket, active: u32) -> ([c_int; 8], Ray8) {
        let lanes = |v: &stereotrace_kernels::simd::F32s| v.to_array();
        let valid = core::array::from_fn(|i| if active & (1 << i) != 0 { -1 } else { 0 });
        let ray = Ray8 {
            org: [lanes(&p.origin[0]), lanes(&p.origin[1]), lanes(&p.origin[2])],
            tnear: lanes(&p.tmin),
            dir: [lanes(&p.dir[0]), lanes(&p.dir[1]), lanes(&p.dir[2])],
            time: [0.0; 8],
            tfar: lanes(&p.tmax),
            mask: [c_uint::MAX; 8],
            id: [0; 8],
            flags: [0; 8],
        };
        (valid, ray)
    }

    /// Closest hits of 8-wide packets (`rtcIntersect8`, coherent context); returns how many
    /// active lanes hit.
    pub fn intersect8(&self, packets: &[(RayPacket, u32)]) -> u32 {
        let mut context = Self::context(true);
        let mut hits = 0;
        for (p, active) in packets {
            let (valid, ray) = Self::ray8(p, *active);
            let hit = Hit8 {
                ng: [[0.0; 8]; 3],
                u: [0.0; 8],
                v: [0.0; 8],
                prim_id: [0; 8],
                geom_id: [INVALID_GEOMETRY_ID; 8],
                inst_id: [[0; 8]],
            };
            let mut rh = RayHit8 { ray, hit };
            // SAFETY: a committed scene; `valid` and the packet are 32-byte aligned and
            // initialised (the type's alignment).
            unsafe { rtcIntersect8(valid.as_ptr(), self.scene, &mut context, &mut rh) };
            hits +=
                (0..8).filter(|&i| active & (1 << i) != 0 && rh.hit.geom_id[i] != INVALID_GEOMETRY_ID).count() as u32;
        }
        hits
    }

    /// Occlusion of 8-wide packets (`rtcOccluded8`, coherent context); returns how many active
    /// lanes are blocked.
    pub fn occluded8(&self, packets: &[(RayPacket, u32)]) -> u32 {
        let mut context = Self::context(true);
        let mut blocked = 0;
        for (p, active) in packets {
            let (valid, mut ray) = Self::ray8(p, *active);
            // SAFETY: as in `intersect8`.
            unsafe { rtcOccluded8(valid.as_ptr(), self.scene, &mut context, &mut ray) };
            blocked += (0..8).filter(|&i| active & (1 << i) != 0 && ray.tfar[i] == f32::NEG_INFINITY).count() as u32;
        }
        blocked
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: the handles came from `new` and are released once.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}

// ---- Embree's BVH builder (rtcore_builder.h), for the tree-quality attribution ----------

/// `RTCBuildPrimitive`.
#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct BuildPrimitive {
    lower: [f32; 3],
    geom_id: c_uint,
    upper: [f32; 3],
    prim_id: c_uint,
}

/// `RTCBounds`.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct Bounds {
    lower: [f32; 3],
    align0: f32,
    upper: [f32; 3],
    align1: f32,
}

type Allocator = *mut c_void;

/// `RTCBuildArguments` of Embree 3.13.
#[repr(C)]
struct BuildArguments {
    byte_size: usize,
    build_quality: c_int,
    build_flags: c_int,
    max_branching_factor: c_uint,
    max_depth: c_uint,
    sah_block_size: c_uint,
    min_leaf_size: c_uint,
    max_leaf_size: c_uint,
    traversal_cost: f32,
    intersection_cost: f32,
    bvh: *mut c_void,
    primitives: *mut BuildPrimitive,
    primitive_count: usize,
    primitive_array_capacity: usize,
    create_node: unsafe extern "C" fn(Allocator, c_uint, *mut c_void) -> *mut c_void,
    set_node_children: unsafe extern "C" fn(*mut c_void, *mut *mut c_void, c_uint, *mut c_void),
    set_node_bounds: unsafe extern "C" fn(*mut c_void, *const *const Bounds, c_uint, *mut c_void),
    create_leaf: unsafe extern "C" fn(Allocator, *const BuildPrimitive, usize, *mut c_void) -> *mut c_void,
    split_primitive:
        Option<unsafe extern "C" fn(*const BuildPrimitive, c_uint, f32, *mut Bounds, *mut Bounds, *mut c_void)>,
    build_progress: *const c_void,
    user: *mut c_void,
}

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewBVH(device: Device) -> *mut c_void;
    fn rtcBuildBVH(args: *const BuildArguments) -> *mut c_void;
    fn rtcThreadLocalAlloc(allocator: Allocator, bytes: usize, align: usize) -> *mut c_void;
    fn rtcReleaseBVH(bvh: *mut c_void);
}

/// A node of the tree Embree's builder makes through our callbacks: an inner node (its
/// children and their boxes) or a leaf (its primitive count).
#[repr(C)]
struct BuiltNode {
    leaf_count: usize,
    children: usize,
    child: [*mut BuiltNode; 8],
    bounds: [Bounds; 8],
}

unsafe extern "C" fn create_node(alloc: Allocator, children: c_uint, _: *mut c_void) -> *mut c_void {
    // SAFETY: Embree's allocator returns memory of the size and alignment asked, alive until
    // the BVH is released; it is initialised here before Embree hands it back.
    unsafe {
        let node = rtcThreadLocalAlloc(alloc, size_of::<BuiltNode>(), 32) as *mut BuiltNode;
        node.write(BuiltNode {
            leaf_count: 0,
            children: children as usize,
            child: [std::ptr::null_mut(); 8],
            bounds: [Bounds { lower: [0.0; 3], align0: 0.0, upper: [0.0; 3], align1: 0.0 }; 8],
        });
        node.cast()
    }
}

unsafe extern "C" fn set_node_children(node: *mut c_void, children: *mut *mut c_void, count: c_uint, _: *mut c_void) {
    // SAFETY: `node` is one of ours, `children` holds `count` (≤ 8) of our nodes.
    unsafe {
        let node = &mut *(node as *mut BuiltNode);
        for i in 0..count as usize {
            node.child[i] = *children.add(i) as *mut BuiltNode;
        }
    }
}

unsafe extern "C" fn set_node_bounds(node: *mut c_void, bounds: *const *const Bounds, count: c_uint, _: *mut c_void) {
    // SAFETY: as above, with `count` bounds.
    unsafe {
        let node = &mut *(node as *mut BuiltNode);
        for i in 0..count as usize {
            node.bounds[i] = **bounds.add(i);
        }
    }
}

unsafe extern "C" fn create_leaf(
    alloc: Allocator,
    _: *const BuildPrimitive,
    count: usize,
    _: *mut c_void,
) -> *mut c_void {
    // SAFETY: as in `create_node`.
    unsafe {
        let node = create_node(alloc, 0, std::ptr::null_mut()) as *mut BuiltNode;
        (*node).leaf_count = count;
        node.cast()
    }
}

/// Splits a triangle's box at `position` on axis `dim`: each side's box is the triangle's
/// part on that side (its vertices there and the edge crossings), clipped to the primitive's
/// current box (it may already be a piece of a split).
unsafe extern "C" fn split_primitive(
    prim: *const BuildPrimitive,
    dim: c_uint,
    position: f32,
    left: *mut Bounds,
    right: *mut Bounds,
    user: *mut c_void,
) {
    // SAFETY: Embree passes a valid primitive and two writable boxes; `user` is the
    // triangle slice the build was started with, alive for the whole build.
    unsafe {
        let tris = &*(user as *const Vec<Tri>);
        let p = &*prim;
        let t = tris[p.prim_id as usize];
        let d = dim as usize;
        let mut sides = [([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]); 2];
        let mut add = |side: usize, v: glam::Vec3| {
            for k in 0..3 {
                sides[side].0[k] = sides[side].0[k].min(v[k]);
                sides[side].1[k] = sides[side].1[k].max(v[k]);
            }
        };
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            if a[d] <= position {
                add(0, a);
            }
            if a[d] >= position {
                add(1, a);
            }
            if (a[d] < position && b[d] > position) || (a[d] > position && b[d] < position) {
                let x = a + (b - a) * ((position - a[d]) / (b[d] - a[d]));
                add(0, x);
                add(1, x);
            }
        }
        for (side, out) in sides.into_iter().zip([left, right]) {
            let (mut lo, mut hi) = side;
            for k in 0..3 {
                lo[k] = lo[k].max(p.lower[k]);
                hi[k] = hi[k].min(p.upper[k]);
            }
            lo[d] = if out == left { lo[d] } else { lo[d].max(position) };
            hi[d] = if out == left { hi[d].min(position) } else { hi[d] };
            for k in 0..3 {
                if lo[k] > hi[k] {
                    // No part of the triangle on this side (rounding): an empty box there.
                    let at = if k == d { position } else { p.lower[k] };
                    (lo[k], hi[k]) = (at, at);
                }
            }
            out.write(Bounds { lower: lo, align0: 0.0, upper: hi, align1: 0.0 });
        }
    }
}

/// The quality of the tree Embree's builder makes for `tris`: its SAH cost in our measure
/// (`TriangleBvh::sah_cost`: node cost 1 per node read, triangle cost 1 per triangle test,
/// by area over the root box), its leaf references and its build time.
pub struct BuiltTree {
    pub sah: f64,
    pub references: usize,
    pub build: std::time::Duration,
}

/// Builds an 8-wide tree over `tris` with Embree's builder (`rtcBuildBVH`): `quality` 2 is
/// its high-quality SAH build with spatial splits (a split budget of `split_budget` × the
/// triangles), 1 its binned SAH build without; leaves of 1 to `max_leaf` triangles, SAH
/// costs 1 and 1 as in our measure.
pub fn embree_tree(tris: &[Tri], quality: c_int, split_budget: f32, max_leaf: u32) -> BuiltTree {
    let owned: Vec<Tri> = tris.to_vec();
    let n = tris.len();
    let capacity = if quality == BUILD_QUALITY_HIGH { ((1.0 + split_budget) * n as f32) as usize } else { n };
    let mut prims: Vec<BuildPrimitive> = tris
        .iter()
        .enumerate()
        .map(|(i, t)| BuildPrimitive {
            lower: [0, 1, 2].map(|k| t[0][k].min(t[1][k]).min(t[2][k])),
            geom_id: 0,
            upper: [0, 1, 2].map(|k| t[0][k].max(t[1][k]).max(t[2][k])),
            prim_id: i as c_uint,
        })
        .collect();
    prims.resize(capacity, prims[0]);
    // SAFETY: the arguments point to live buffers (primitives with the stated capacity, the
    // triangles for the split callback) for the whole build; the tree's nodes live in the
    // BVH's memory, read before it is released.
    unsafe {
        let device = rtcNewDevice(std::ptr::null());
        assert!(!device.is_null(), "rtcNewDevice failed");
        let bvh = rtcNewBVH(device);
        let args = BuildArguments {
            byte_size: size_of::<BuildArguments>(),
            build_quality: quality,
            build_flags: 0,
            max_branching_factor: 8,
            max_depth: 64,
            sah_block_size: 1,
            min_leaf_size: 1,
            max_leaf_size: max_leaf,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            bvh,
            primitives: prims.as_mut_ptr(),
            primitive_count: n,
            primitive_array_capacity: capacity,
            create_node,
            set_node_children,
            set_node_bounds,
            create_leaf,
            split_primitive: (quality == BUILD_QUALITY_HIGH).then_some(split_primitive),
            build_progress: std::ptr::null(),
            user: &owned as *const Vec<Tri> as *mut c_void,
        };
        let start = std::time::Instant::now();
        let root = rtcBuildBVH(&args) as *const BuiltNode;
        let build = start.elapsed();
        assert!(!root.is_null(), "rtcBuildBVH failed");
        let area = |b: &Bounds| {
            let d = [0, 1, 2].map(|k| f64::from((b.upper[k] - b.lower[k]).max(0.0)));
            2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
        };
        let whole = Bounds {
            lower: [0, 1, 2].map(|k| tris.iter().flatten().map(|v| v[k]).fold(f32::INFINITY, f32::min)),
            align0: 0.0,
            upper: [0, 1, 2].map(|k| tris.iter().flatten().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max)),
            align1: 0.0,
        };
        let root_area = area(&whole);
        let (mut sah, mut references) = (1.0, 0);
        if (*root).children == 0 {
            // The whole scene is one leaf.
            sah += (*root).leaf_count as f64;
            references = (*root).leaf_count;
        }
        let mut stack = vec![root];
        while let Some(node) = stack.pop() {
            let node = &*node;
            for i in 0..node.children {
                let child = &*node.child[i];
                let a = area(&node.bounds[i]) / root_area;
                if child.children == 0 {
                    sah += child.leaf_count as f64 * a;
                    references += child.leaf_count;
                } else {
                    sah += a;
                    stack.push(child);
                }
            }
        }
        rtcReleaseBVH(bvh);
        rtcReleaseDevice(device);
        BuiltTree { sah, references, build }
    }
}

/// `RTC_BUILD_QUALITY_MEDIUM`: Embree's binned SAH build, no spatial splits.
pub const BUILD_QUALITY_MEDIUM: c_int = 1;
/// `RTC_BUILD_QUALITY_HIGH`: with spatial splits.
pub const BUILD_QUALITY_HIGH_SPLITS: c_int = BUILD_QUALITY_HIGH;

//! Embree 3 as a peer in the traversal bench (feature `peer-embree`; Debian's
//! `libembree-dev`, Embree 3.13): the few calls needed to build a scene from our triangles
//! and trace our rays through it, single rays and 8-wide packets, closest hit and occlusion.
//!
//! The declarations follow `embree3/rtcore_*.h` of that version (checked against its
//! `rtcore_config.h`: one instance level, no minimum-width curves, so the intersect context is
//! flags + filter + one instance id). Only what the bench calls is declared; a hit is
//! `geomID != RTC_INVALID_GEOMETRY_ID`, an occluded ray comes back with `tfar = −∞`.

use std::ffi::{c_char, c_int, c_uint, c_void};

use stereotrace::kernels::bvh::{Ray, Tri};
use stereotrace::kernels::traverse::RayPacket;

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
        // SAFETY: each call gets the handles the previous ones returned (checked non-null)
        // and buffers of exactly the declared size, filled before the commit.
        unsafe {
            let device = rtcNewDevice(std::ptr::null());
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
        let lanes = |v: &stereotrace::kernels::simd::F32s| v.to_array();
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

//! Ray traversal throughput on one thread: coherent primary rays at 1280×720 (8-wide packets
//! in 8×1 and 4×2 pixel tiles, and single rays), shadow rays from the primary hits toward one
//! point light (packets and single), and cosine-distributed diffuse rays from the primary hits
//! (single). obvhs's own single-ray CWBVH traversal (its Möller–Trumbore test, same tree,
//! triangles in BVH order) runs on identical rays as the peer baseline, and with the feature
//! `peer-embree` (Debian's `libembree-dev`, Embree 3.13) Embree traces them too, single rays
//! and 8-wide packets (`rtcIntersect8`/`rtcOccluded8`), on a scene built from the same
//! triangles (`benches/peers/embree.rs`).
//!
//! Scenes: Sponza from `../shared/scenes/sponza` (67k triangles; skipped with a message if
//! absent) and a built-in procedural scene of ~700k triangles (a tessellated terrain and a field
//! of UV spheres), the size of the reference measurements (Embree 4, AVX-512, per thread:
//! 9.6 Mrays/s 16-wide coherent primary packets, 4.9 single primary, 2.6 diffuse, 6.3–7.9
//! shadow; obvhs single rays 1.9 primary, 1.0 diffuse, 2.6 shadow).
//!
//! Throughput is in rays (criterion's "elem/s"). Rays are generated outside the timed loop
//! from fixed seeds; one iteration traces a whole frame of them.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench traverse -- --warm-up-time 1
//! --measurement-time 3`, with `--features peer-embree` for the Embree rows (add a filter
//! such as `sponza/primary` to pick groups; `threshold` sweeps the packet single-ray fallback
//! threshold). To attribute a gap: `STEREOTRACE_BENCH_BVH` = `fast`, `medium`, `high`, `sah`
//! or `splits` (SAH with spatial splits) sets our tree's build quality (default: the renderer's, `BuildQuality::default()`),
//! and `EMBREE_ROBUST=1` puts Embree in its robust mode (watertight triangle tests, like ours).
//!
//! Tree quality: `STEREOTRACE_BENCH_TREES=1 cargo bench -p stereotrace-kernels --bench
//! traverse -- tree` builds one tree per obvhs parameter set of `tree_settings` on each scene
//! (three builds, the median build time printed with the tree's size and depth) and traces
//! the same single rays (primary, shadow, diffuse) through it, in groups
//! `traversal/{scene}/tree/{setting}`. It is off by default: the builds take minutes whatever
//! criterion's filter selects.
//!
//! Attribution: `STEREOTRACE_BENCH_ATTRIBUTION=1 cargo bench -p stereotrace-kernels --bench
//! traverse --features peer-embree -- attribution` prints, per scene and ray kind, what the
//! single-ray traversal does per ray (nodes, boxes, leaves, triangles) and the tree's SAH
//! cost beside other builders' trees of the same triangles (Embree's with spatial splits
//! among them).

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use obvhs::ray::{Ray as ORay, RayHit};
use obvhs::triangle::Triangle as OTri;
use stereotrace_kernels::bvh::wide::SlabOrigins;
use stereotrace_kernels::bvh::{BuildQuality, BvhBuildParams, PreparedRay, Ray, Tri, TriangleBvh};
use stereotrace_kernels::traverse::{PacketHits, RayPacket};

#[cfg(feature = "peer-embree")]
#[path = "peers/embree.rs"]
mod embree;

const WIDTH: usize = 1280;
const HEIGHT: usize = 720;

struct Camera {
    eye: Vec3,
    fwd: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half: f32,
}

impl Camera {
    fn look_at(eye: Vec3, target: Vec3, up: Vec3, vfov_deg: f32) -> Self {
        let fwd = (target - eye).normalize();
        let right = fwd.cross(up).normalize();
        let up = right.cross(fwd);
        Camera { eye, fwd, right, up, tan_half: (vfov_deg.to_radians() * 0.5).tan() }
    }

    /// The primary ray through the centre of pixel `(x, y)` (unnormalised direction).
    fn ray(&self, x: usize, y: usize) -> Ray {
        let aspect = WIDTH as f32 / HEIGHT as f32;
        let sx = ((x as f32 + 0.5) / WIDTH as f32 * 2.0 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - (y as f32 + 0.5) / HEIGHT as f32 * 2.0) * self.tan_half;
        Ray::new(self.eye, self.fwd + self.right * sx + self.up * sy)
    }
}

/// A packet and its active lanes.
type Packet = (RayPacket, u32);

struct Fixture {
    /// The scene's triangles (for rebuilding the tree with other parameters).
    tris: Vec<Tri>,
    bvh: TriangleBvh,
    /// The same triangles in Embree (feature `peer-embree`).
    #[cfg(feature = "peer-embree")]
    embree: embree::EmbreeScene,
    /// obvhs triangles in BVH order (as obvhs's own examples lay them out).
    otris: Vec<OTri>,
    primary: Vec<Ray>,
    primary_8x1: Vec<Packet>,
    primary_4x2: Vec<Packet>,
    shadow: Vec<Ray>,
    shadow_8x1: Vec<Packet>,
    shadow_4x2: Vec<Packet>,
    diffuse: Vec<Ray>,
    /// Shadow and diffuse rays in stream order ([`stream_order`]), single and as 8-ray
    /// packets of consecutive rays.
    shadow_stream: Vec<Ray>,
    shadow_stream_8: Vec<Packet>,
    diffuse_stream: Vec<Ray>,
    diffuse_stream_8: Vec<Packet>,
    /// The primary directions from outside the scene's bounds, going away: every ray misses.
    miss: Vec<Ray>,
}

/// Pixel order of a tile of `tw × th` pixels.
fn tile_pixels(tw: usize, th: usize) -> Vec<(usize, usize)> {
    let mut v = Vec::with_capacity(WIDTH * HEIGHT);
    for ty in (0..HEIGHT).step_by(th) {
        for tx in (0..WIDTH).step_by(tw) {
            for y in ty..ty + th {
                for x in tx..tx + tw {
                    v.push((x, y));
                }
            }
        }
    }
    v
}

fn packets(order: &[(usize, usize)], ray_at: &dyn Fn(usize, usize) -> Option<Ray>) -> Vec<Packet> {
    order
        .chunks(8)
        .map(|c| {
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::X); 8];
            let mut active = 0;
            for (i, &(x, y)) in c.iter().enumerate() {
                if let Some(r) = ray_at(x, y) {
                    rays[i] = r;
                    active |= 1 << i;
                }
            }
            (RayPacket::from_rays(&rays), active)
        })
        .filter(|p| p.1 != 0)
        .collect()
}

/// Ray-stream order: direction octant first, then the Morton code of the origin (10 bits per
/// axis over the origins' bounding box), so rays next to each other in the order start near
/// each other and visit a node's children in the same order.
fn stream_order(rays: &[Ray]) -> Vec<Ray> {
    let (lo, hi) = rays
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), r| (lo.min(r.origin), hi.max(r.origin)));
    let scale = Vec3::splat(1023.0) / (hi - lo).max(Vec3::splat(1e-20));
    assert!(rays.len() < 1 << 24, "stream_order packs ray indices in 24 bits");
    // One u64 per ray: 3 octant bits, 30 Morton bits, then the ray's index.
    let mut keyed: Vec<u64> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let q = ((r.origin - lo) * scale).as_uvec3();
            let octant = u64::from(r.dir.x < 0.0) | u64::from(r.dir.y < 0.0) << 1 | u64::from(r.dir.z < 0.0) << 2;
            let morton = spread_bits(q.x) | spread_bits(q.y) << 1 | spread_bits(q.z) << 2;
            (octant << 30 | morton) << 24 | i as u64
        })
        .collect();
    keyed.sort_unstable();
    keyed.iter().map(|&k| rays[(k & 0xff_ffff) as usize]).collect()
}

/// The low 10 bits of `v`, spread to every third bit (a 3-D Morton code's one axis).
fn spread_bits(v: u32) -> u64 {
    let mut x = u64::from(v.min(1023));
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

/// Packets of eight consecutive rays (the last one partial).
fn consecutive_packets(rays: &[Ray]) -> Vec<Packet> {
    rays.chunks(8)
        .map(|c| {
            let mut lanes = [Ray::new(Vec3::ZERO, Vec3::X); 8];
            lanes[..c.len()].copy_from_slice(c);
            (RayPacket::from_rays(&lanes), (1u32 << c.len()) - 1)
        })
        .collect()
}

/// Our tree's build quality from `STEREOTRACE_BENCH_BVH` (default: the renderer's,
/// `BuildQuality::default()`; or fast, medium, high, sah, splits).
fn build_quality() -> BuildQuality {
    match std::env::var("STEREOTRACE_BENCH_BVH").as_deref() {
        Err(_) => BuildQuality::default(),
        Ok("medium") => BuildQuality::Medium,
        Ok("fast") => BuildQuality::Fast,
        Ok("high") => BuildQuality::High,
        Ok("sah") => BuildQuality::Sah,
        Ok("splits") => BuildQuality::SahSplits,
        Ok(other) => panic!("STEREOTRACE_BENCH_BVH: expected fast, medium, high, sah or splits, got '{other}'"),
    }
}

/// xorshift64* for the diffuse directions.
struct Rng(u64);

impl Rng {
    fn f(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32
    }
}

impl Fixture {
    /// `light_clear`: distance from the light point at which shadow rays stop (Sponza's light
    /// point is the centre of its emitting sphere, which is geometry).
    fn new(name: &str, tris: Vec<Tri>, cam: Camera, light: Vec3, light_clear: f32) -> Self {
        let quality = build_quality();
        let (bvh, stats) = TriangleBvh::build(&tris, quality).expect("valid scene");
        eprintln!("[{name}] {quality:?} build: {stats:?}");
        let otris = bvh
            .triangles_bvh_order()
            .iter()
            .map(|t| OTri {
                v0: [t[0], t[1], t[2]].into(),
                v1: [t[3], t[4], t[5]].into(),
                v2: [t[6], t[7], t[8]].into(),
            })
            .collect();
        let primary: Vec<Ray> =
            (0..HEIGHT).flat_map(|y| (0..WIDTH).map(move |x| (x, y))).map(|(x, y)| cam.ray(x, y)).collect();
        // Primary hits, computed once: position and geometric normal facing the viewer.
        let hits: Vec<Option<(Vec3, Vec3)>> = primary
            .iter()
            .map(|r| {
                bvh.intersect(r).map(|h| {
                    let t = &tris[h.prim as usize];
                    let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
                    let n = if n.dot(r.dir) > 0.0 { -n } else { n };
                    (r.origin + r.dir * h.t, n)
                })
            })
            .collect();
        let at = |x: usize, y: usize| hits[y * WIDTH + x];
        // Shadow rays: from the hit toward the light, over [1e-4, 1 − clear) of the segment.
        let shadow_ray = |x: usize, y: usize| {
            at(x, y).map(|(p, _)| Ray::segment(p, light - p, 1e-4, 1.0 - light_clear.max(1e-4) / (light - p).length()))
        };
        let mut rng = Rng(0x5EED_0000_0000_0001);
        let diffuse: Vec<Ray> = hits
            .iter()
            .flatten()
            .map(|&(p, n)| {
                // Cosine-weighted hemisphere around n (Malley's method).
                let (u1, u2) = (rng.f(), rng.f());
                let r = u1.sqrt();
                let phi = std::f32::consts::TAU * u2;
                let t = n.any_orthonormal_vector();
                let b = n.cross(t);
                let d = t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt();
                Ray::segment(p, d, 1e-4, f32::INFINITY)
            })
            .collect();
        let shadow: Vec<Ray> =
            (0..HEIGHT).flat_map(|y| (0..WIDTH).map(move |x| (x, y))).filter_map(|(x, y)| shadow_ray(x, y)).collect();
        // Rays that miss the scene's bounds: the primary directions from outside the bounds,
        // going away (each point of such a ray is farther from the centre than any vertex).
        // What a ray costs before any node below the root: its setup and one node test.
        let (lo, hi) = (Vec3::from_array(bvh.bounds()[0]), Vec3::from_array(bvh.bounds()[1]));
        let (centre, reach) = ((lo + hi) * 0.5, (hi - lo).length() + 1.0);
        let miss: Vec<Ray> = primary
            .iter()
            .map(|r| {
                let d = r.dir.normalize();
                Ray::segment(centre + d * reach, d, 0.0, f32::INFINITY)
            })
            .collect();
        assert_eq!(trace_single(&bvh, &miss), 0, "rays that leave the bounds hit nothing");
        let (shadow_stream, diffuse_stream) = (stream_order(&shadow), stream_order(&diffuse));
        let primary_at = |x: usize, y: usize| Some(cam.ray(x, y));
        let (o8, o42) = (tile_pixels(8, 1), tile_pixels(4, 2));
        let fixture = Fixture {
            primary_8x1: packets(&o8, &primary_at),
            primary_4x2: packets(&o42, &primary_at),
            shadow,
            shadow_8x1: packets(&o8, &shadow_ray),
            shadow_4x2: packets(&o42, &shadow_ray),
            shadow_stream_8: consecutive_packets(&shadow_stream),
            shadow_stream,
            diffuse_stream_8: consecutive_packets(&diffuse_stream),
            diffuse_stream,
            diffuse,
            primary,
            miss,
            otris,
            #[cfg(feature = "peer-embree")]
            embree: embree::EmbreeScene::new(&tris, std::env::var_os("EMBREE_ROBUST").is_some_and(|v| v == "1")),
            bvh,
            tris,
        };
        let bvh = &fixture.bvh;
        let (occluded, diffuse_hits) = (occlude_single(bvh, &fixture.shadow), trace_single(bvh, &fixture.diffuse));
        eprintln!(
            "[{name}] {} primary rays, {} hits (= shadow and diffuse rays), {occluded} shadow rays occluded",
            fixture.primary.len(),
            fixture.shadow.len(),
        );
        // A sanity check that the reordered sets are the same rays: the same number of hits
        // (packets against single rays are checked ray by ray in `kernels/tests/traversal.rs`).
        assert_eq!(occlude_single(bvh, &fixture.shadow_stream), occluded);
        assert_eq!(occlude_packets(bvh, &fixture.shadow_stream_8, 2), occluded);
        assert_eq!(trace_single(bvh, &fixture.diffuse_stream), diffuse_hits);
        assert_eq!(trace_packets(bvh, &fixture.diffuse_stream_8, 2), diffuse_hits);
        // Skipped when counting Embree's work: its counters would take these rays in too.
        #[cfg(feature = "peer-embree")]
        if embree_count_request().is_none() {
            eprintln!(
                "[{name}] Embree on the same rays: {} primary hits, {} shadow rays occluded, {} diffuse hits (ours: {})",
                fixture.embree.intersect(&fixture.primary),
                fixture.embree.occluded(&fixture.shadow),
                fixture.embree.intersect(&fixture.diffuse),
                diffuse_hits
            );
        }
        fixture
    }
}

fn shared_dir() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    [root.join("../../shared"), PathBuf::from("/work/shared")].into_iter().find(|p| p.join("scenes").is_dir())
}

/// Whether the shared Sponza scene is beside the project.
fn have_sponza() -> bool {
    shared_dir().is_some_and(|d| d.join("scenes/sponza/scene.obj").is_file())
}

fn load_obj(path: &Path) -> Vec<Tri> {
    let (models, _) =
        tobj::load_obj(path, &tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() })
            .expect("scene.obj");
    let mut tris = Vec::new();
    for m in models {
        let p = &m.mesh.positions;
        let v = |i: u32| Vec3::new(p[3 * i as usize], p[3 * i as usize + 1], p[3 * i as usize + 2]);
        for f in m.mesh.indices.chunks(3) {
            tris.push([v(f[0]), v(f[1]), v(f[2])]);
        }
    }
    tris
}

fn sponza() -> Option<&'static Fixture> {
    static F: OnceLock<Option<Fixture>> = OnceLock::new();
    F.get_or_init(|| {
        let Some(dir) = shared_dir().map(|d| d.join("scenes/sponza")) else {
            eprintln!("SKIPPED sponza benches: ../shared/scenes/sponza not found");
            return None;
        };
        let cam: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("camera.json")).ok()?).ok()?;
        let v3 = |k: &str| {
            let a = cam[k].as_array().expect("vec3");
            Vec3::new(a[0].as_f64().unwrap() as f32, a[1].as_f64().unwrap() as f32, a[2].as_f64().unwrap() as f32)
        };
        let camera = Camera::look_at(v3("eye"), v3("target"), v3("up"), cam["vfov_deg"].as_f64().unwrap() as f32);
        // lights.json: the area light is a small sphere at (0, 17, 0); its centre is the point light.
        Some(Fixture::new("sponza", load_obj(&dir.join("scene.obj")), camera, Vec3::new(0.0, 17.0, 0.0), 0.11))
    })
    .as_ref()
}

/// Terrain of 420×420 quads (352,800 triangles) plus a 6×6 field of UV spheres of 96×50
/// segments (345,600 triangles): 698,400 triangles.
fn procedural_tris() -> Vec<Tri> {
    let height = |x: f32, z: f32| 2.0 * (0.15 * x).sin() * (0.12 * z).cos() + 0.5 * (0.7 * x + 0.3 * z).sin();
    let n = 420;
    let size = 100.0;
    let p = |i: usize, j: usize| {
        let (x, z) = (i as f32 / n as f32 * size - size * 0.5, j as f32 / n as f32 * size - size * 0.5);
        Vec3::new(x, height(x, z), z)
    };
    let mut tris = Vec::with_capacity(700_000);
    for i in 0..n {
        for j in 0..n {
            tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    let (seg_u, seg_v, radius) = (96, 50, 3.0f32);
    for a in 0..6 {
        for b in 0..6 {
            let (cx, cz) = (-30.0 + a as f32 * 12.0, -20.0 + b as f32 * 12.0);
            let c = Vec3::new(cx, height(cx, cz) + radius, cz);
            let s = |i: usize, j: usize| {
                let (th, ph) =
                    (i as f32 / seg_u as f32 * std::f32::consts::TAU, j as f32 / seg_v as f32 * std::f32::consts::PI);
                c + Vec3::new(ph.sin() * th.cos(), ph.cos(), ph.sin() * th.sin()) * radius
            };
            for i in 0..seg_u {
                for j in 0..seg_v {
                    tris.push([s(i, j), s(i + 1, j), s(i + 1, j + 1)]);
                    tris.push([s(i, j), s(i + 1, j + 1), s(i, j + 1)]);
                }
            }
        }
    }
    tris
}

/// The geometries of the built-in scenes (the glossy, mirror and moving-light variants share
/// them): their own triangles, seen by their camera path's first pose, with shadow rays
/// toward a point just under the top centre of the scene's bounds.
const BUILTINS: [&str; 5] = ["cornell", "atrium", "living-room", "classroom", "courtyard"];

fn builtin(name: &'static str) -> &'static Fixture {
    static FIXTURES: [OnceLock<Fixture>; BUILTINS.len()] = [const { OnceLock::new() }; BUILTINS.len()];
    let i = BUILTINS.iter().position(|b| *b == name).expect("a built-in scene");
    FIXTURES[i].get_or_init(|| {
        let scene = stereotrace_runtime::scene::resolve(name).expect("built-in scenes load");
        let pose = scene.camera.pose_at(0.0);
        let camera = Camera::look_at(pose.eye, pose.eye + pose.forward, pose.up, pose.vfov_deg);
        let bounds = scene.bounds();
        let light = Vec3::new(bounds.centre().x, bounds.max.y - 0.02 * bounds.extent().y, bounds.centre().z);
        Fixture::new(name, scene.mesh.positions.clone(), camera, light, 0.0)
    })
}

fn procedural() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        // Looking down over the terrain toward the spheres: 82 % of the pixels hit geometry.
        let camera = Camera::look_at(Vec3::new(0.0, 24.0, -38.0), Vec3::ZERO, Vec3::Y, 50.0);
        Fixture::new("procedural700k", procedural_tris(), camera, Vec3::new(25.0, 60.0, -20.0), 0.0)
    })
}

/// The pool of the two-thread groups: the rays are split into chunks that two workers take in
/// turn, ours and Embree's alike.
fn two_threads() -> &'static rayon::ThreadPool {
    static POOL: OnceLock<rayon::ThreadPool> = OnceLock::new();
    POOL.get_or_init(|| rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool of two threads"))
}

/// Rays per chunk in the two-thread groups: large enough that scheduling costs nothing, small
/// enough that the two workers finish together.
const CHUNK: usize = 4096;

/// `trace` over `rays` on the two-thread pool, chunk by chunk; the sum of its counts.
fn on_two_threads<T: Sync>(items: &[T], trace: impl Fn(&[T]) -> u32 + Sync) -> u32 {
    use rayon::prelude::*;
    two_threads().install(|| items.par_chunks(CHUNK).map(&trace).sum())
}

/// What every single ray computes before the root node: [`PreparedRay::new`] and its
/// [`SlabOrigins`] (a sum of their fields, so that none is optimised away).
fn ray_setup(bvh: &TriangleBvh, rays: &[Ray]) -> f32 {
    rays.iter()
        .filter_map(PreparedRay::new)
        .map(|r| {
            let o = SlabOrigins::new(&r, bvh.bounds());
            o.near[0] + o.far[2] + r.inv.x + r.shear[1] + r.pad.z
        })
        .sum()
}

fn trace_single(bvh: &TriangleBvh, rays: &[Ray]) -> u32 {
    rays.iter().map(|r| bvh.intersect(r).is_some() as u32).sum()
}

fn trace_packets(bvh: &TriangleBvh, packets: &[Packet], threshold: u32) -> u32 {
    let mut hits = PacketHits::NONE;
    packets.iter().map(|(p, m)| bvh.intersect_packet_with(p, *m, &mut hits, threshold).count_ones()).sum()
}

fn occlude_single(bvh: &TriangleBvh, rays: &[Ray]) -> u32 {
    rays.iter().map(|r| bvh.occluded(r) as u32).sum()
}

fn occlude_packets(bvh: &TriangleBvh, packets: &[Packet], threshold: u32) -> u32 {
    packets.iter().map(|(p, m)| bvh.occluded_packet_with(p, *m, threshold).count_ones()).sum()
}

fn oray(r: &Ray) -> ORay {
    ORay::new(r.origin.into(), r.dir.into(), r.tmin, r.tmax)
}

/// obvhs's `ray_traverse` (closest hit) with its own triangle test.
fn obvhs_single(f: &Fixture, rays: &[Ray]) -> u32 {
    let cw = f.bvh.cwbvh();
    rays.iter()
        .map(|r| {
            let mut hit = RayHit::none();
            cw.ray_traverse(oray(r), &mut hit, |ray, id| f.otris[id].intersect(ray)) as u32
        })
        .sum()
}

/// obvhs's `ray_traverse_miss` (any hit).
fn obvhs_occlude(f: &Fixture, rays: &[Ray]) -> u32 {
    let cw = f.bvh.cwbvh();
    rays.iter().map(|r| !cw.ray_traverse_miss(oray(r), |ray, id| f.otris[id].intersect(ray)) as u32).sum()
}

/// Registers the groups of one scene (the fixture is built at registration: the shadow and
/// diffuse ray counts are needed for the throughput).
fn bench_scene(c: &mut Criterion, name: &str, available: bool, fixture: &dyn Fn() -> Option<&'static Fixture>) {
    if !available {
        eprintln!("SKIPPED {name} benches: scene files not found");
        return;
    }
    let f = || fixture().expect("scene loads");
    let mut g = c.benchmark_group(format!("traversal/{name}/primary"));
    g.sampling_mode(SamplingMode::Flat).sample_size(10);
    g.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
    g.bench_function("packet_8x1", |b| b.iter(|| trace_packets(&f().bvh, black_box(&f().primary_8x1), 2)));
    g.bench_function("packet_4x2", |b| b.iter(|| trace_packets(&f().bvh, black_box(&f().primary_4x2), 2)));
    g.bench_function("single", |b| b.iter(|| trace_single(&f().bvh, black_box(&f().primary))));
    g.bench_function("obvhs_single", |b| b.iter(|| obvhs_single(f(), black_box(&f().primary))));
    #[cfg(feature = "peer-embree")]
    {
        g.bench_function("embree_packet_8x1", |b| b.iter(|| f().embree.intersect8(black_box(&f().primary_8x1))));
        g.bench_function("embree_packet_4x2", |b| b.iter(|| f().embree.intersect8(black_box(&f().primary_4x2))));
        g.bench_function("embree_single", |b| b.iter(|| f().embree.intersect(black_box(&f().primary))));
    }
    g.finish();

    let mut g = c.benchmark_group(format!("traversal/{name}/shadow"));
    g.sampling_mode(SamplingMode::Flat).sample_size(10);
    g.throughput(Throughput::Elements(f().shadow.len() as u64));
    g.bench_function("packet_8x1", |b| b.iter(|| occlude_packets(&f().bvh, black_box(&f().shadow_8x1), 2)));
    g.bench_function("packet_4x2", |b| b.iter(|| occlude_packets(&f().bvh, black_box(&f().shadow_4x2), 2)));
    g.bench_function("single", |b| b.iter(|| occlude_single(&f().bvh, black_box(&f().shadow))));
    g.bench_function("single_stream_order", |b| b.iter(|| occlude_single(&f().bvh, black_box(&f().shadow_stream))));
    g.bench_function("packet_stream_order", |b| {
        b.iter(|| occlude_packets(&f().bvh, black_box(&f().shadow_stream_8), 2))
    });
    g.bench_function("obvhs_single", |b| b.iter(|| obvhs_occlude(f(), black_box(&f().shadow))));
    #[cfg(feature = "peer-embree")]
    {
        g.bench_function("embree_packet_8x1", |b| b.iter(|| f().embree.occluded8(black_box(&f().shadow_8x1))));
        g.bench_function("embree_packet_4x2", |b| b.iter(|| f().embree.occluded8(black_box(&f().shadow_4x2))));
        g.bench_function("embree_single", |b| b.iter(|| f().embree.occluded(black_box(&f().shadow))));
    }
    g.finish();

    let mut g = c.benchmark_group(format!("traversal/{name}/diffuse"));
    g.sampling_mode(SamplingMode::Flat).sample_size(10);
    g.throughput(Throughput::Elements(f().diffuse.len() as u64));
    g.bench_function("single", |b| b.iter(|| trace_single(&f().bvh, black_box(&f().diffuse))));
    g.bench_function("single_stream_order", |b| b.iter(|| trace_single(&f().bvh, black_box(&f().diffuse_stream))));
    g.bench_function("packet_stream_order", |b| {
        b.iter(|| trace_packets(&f().bvh, black_box(&f().diffuse_stream_8), 2))
    });
    // What the reordering itself costs per ray (keys and sort, as a renderer would pay it).
    g.bench_function("stream_order_sort", |b| b.iter(|| stream_order(black_box(&f().diffuse)).len()));
    g.bench_function("obvhs_single", |b| b.iter(|| obvhs_single(f(), black_box(&f().diffuse))));
    #[cfg(feature = "peer-embree")]
    g.bench_function("embree_single", |b| b.iter(|| f().embree.intersect(black_box(&f().diffuse))));
    g.finish();

    // Rays that miss everything: the fixed cost of a ray (setup and the root's test).
    let mut g = c.benchmark_group(format!("traversal/{name}/miss"));
    g.sampling_mode(SamplingMode::Flat).sample_size(10);
    g.throughput(Throughput::Elements(f().miss.len() as u64));
    g.bench_function("single", |b| b.iter(|| trace_single(&f().bvh, black_box(&f().miss))));
    #[cfg(feature = "peer-embree")]
    g.bench_function("embree_single", |b| b.iter(|| f().embree.intersect(black_box(&f().miss))));
    // The part of that before the root's test: validation, reciprocals, the triangle test's
    // shear and the slab origins.
    g.bench_function("setup", |b| b.iter(|| ray_setup(&f().bvh, black_box(&f().miss))));
    g.finish();

    // The same rays on two threads: each kind's best layout of ours (8×1 packets for primary
    // and shadow rays, single rays for diffuse ones) and Embree's, chunk by chunk.
    let fx = f();
    let mut g = c.benchmark_group(format!("traversal/{name}/two_threads"));
    g.sampling_mode(SamplingMode::Flat).sample_size(10);
    g.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
    g.bench_function("primary_packet_8x1", |b| {
        b.iter(|| on_two_threads(black_box(&fx.primary_8x1), |p| trace_packets(&fx.bvh, p, 2)))
    });
    g.bench_function("primary_single", |b| {
        b.iter(|| on_two_threads(black_box(&fx.primary), |r| trace_single(&fx.bvh, r)))
    });
    #[cfg(feature = "peer-embree")]
    {
        g.bench_function("embree_primary_packet_8x1", |b| {
            b.iter(|| on_two_threads(black_box(&fx.primary_8x1), |p| fx.embree.intersect8(p)))
        });
        g.bench_function("embree_primary_single", |b| {
            b.iter(|| on_two_threads(black_box(&fx.primary), |r| fx.embree.intersect(r)))
        });
    }
    g.throughput(Throughput::Elements(fx.shadow.len() as u64));
    g.bench_function("shadow_packet_8x1", |b| {
        b.iter(|| on_two_threads(black_box(&fx.shadow_8x1), |p| occlude_packets(&fx.bvh, p, 2)))
    });
    g.bench_function("shadow_single", |b| {
        b.iter(|| on_two_threads(black_box(&fx.shadow), |r| occlude_single(&fx.bvh, r)))
    });
    #[cfg(feature = "peer-embree")]
    {
        g.bench_function("embree_shadow_packet_8x1", |b| {
            b.iter(|| on_two_threads(black_box(&fx.shadow_8x1), |p| fx.embree.occluded8(p)))
        });
        g.bench_function("embree_shadow_single", |b| {
            b.iter(|| on_two_threads(black_box(&fx.shadow), |r| fx.embree.occluded(r)))
        });
    }
    g.throughput(Throughput::Elements(fx.diffuse.len() as u64));
    g.bench_function("diffuse_single", |b| {
        b.iter(|| on_two_threads(black_box(&fx.diffuse), |r| trace_single(&fx.bvh, r)))
    });
    #[cfg(feature = "peer-embree")]
    g.bench_function("embree_diffuse_single", |b| {
        b.iter(|| on_two_threads(black_box(&fx.diffuse), |r| fx.embree.intersect(r)))
    });
    g.finish();
}

fn traversal(c: &mut Criterion) {
    let have_sponza = have_sponza();
    bench_scene(c, "sponza", have_sponza, &sponza);
    bench_scene(c, "procedural700k", true, &|| Some(procedural()));
    for name in BUILTINS {
        bench_scene(c, name, true, &|| Some(builtin(name)));
    }

    // The single-ray fallback threshold of the packet traversal (lanes ≤ threshold continue
    // as single rays): primary and shadow rays in 8×1 tiles.
    if have_sponza {
        let f = || sponza().expect("checked");
        let mut g = c.benchmark_group("traversal/threshold");
        g.sampling_mode(SamplingMode::Flat).sample_size(10);
        for th in [0u32, 1, 2, 3, 4, 6] {
            g.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
            g.bench_function(format!("primary_8x1/{th}"), |b| b.iter(|| trace_packets(&f().bvh, &f().primary_8x1, th)));
            g.throughput(Throughput::Elements(f().shadow.len() as u64));
            g.bench_function(format!("shadow_8x1/{th}"), |b| b.iter(|| occlude_packets(&f().bvh, &f().shadow_8x1, th)));
        }
        g.finish();
    }
}

/// The obvhs parameter sets of the tree sweep: its presets, and the medium preset with one
/// setting changed at a time.
fn tree_settings() -> Vec<(&'static str, BvhBuildParams)> {
    use obvhs::ploc::PlocSearchDistance;
    let medium = BuildQuality::Medium.params();
    vec![
        ("fastest", BvhBuildParams::fastest_build()),
        ("fast", BuildQuality::Fast.params()),
        ("medium", medium),
        ("medium_leaf_1", BvhBuildParams { max_prims_per_leaf: 1, ..medium }),
        ("medium_leaf_2", BvhBuildParams { max_prims_per_leaf: 2, ..medium }),
        ("medium_reinsertion_0", BvhBuildParams { reinsertion_batch_ratio: 0.0, ..medium }),
        ("medium_reinsertion_0.2", BvhBuildParams { reinsertion_batch_ratio: 0.2, ..medium }),
        ("medium_reinsertion_1", BvhBuildParams { reinsertion_batch_ratio: 1.0, ..medium }),
        ("medium_search_32", BvhBuildParams { ploc_search_distance: PlocSearchDistance::VeryHigh, ..medium }),
        ("medium_presplit", BvhBuildParams { pre_split: true, ..medium }),
        ("high", BuildQuality::High.params()),
        ("very_slow", BvhBuildParams::very_slow_build()),
    ]
}

/// The tree sweep (see the module docs): build time and single-ray rates per parameter set.
fn trees(c: &mut Criterion) {
    if std::env::var_os("STEREOTRACE_BENCH_TREES").is_none_or(|v| v != "1") {
        eprintln!("SKIPPED tree sweep: set STEREOTRACE_BENCH_TREES=1");
        return;
    }
    let have_sponza = have_sponza();
    let scenes: Vec<(&str, &Fixture)> =
        [("sponza", if have_sponza { sponza() } else { None }), ("procedural700k", Some(procedural()))]
            .into_iter()
            .filter_map(|(name, f)| f.map(|f| (name, f)))
            .collect();
    for (scene, f) in scenes {
        for (setting, params) in tree_settings() {
            let mut builds: Vec<_> =
                (0..3).map(|_| TriangleBvh::build_with(&f.tris, &params).expect("valid scene")).collect();
            builds.sort_by_key(|(_, stats)| stats.total_time);
            let (bvh, stats) = builds.swap_remove(1);
            drop(builds);
            eprintln!(
                "[{scene}] tree {setting}: build median {:.1} ms (obvhs {:.1} ms), {} nodes, {} references, depth {}",
                stats.total_time.as_secs_f64() * 1e3,
                stats.obvhs_time.as_secs_f64() * 1e3,
                stats.nodes,
                stats.references,
                stats.depth
            );
            let mut g = c.benchmark_group(format!("traversal/{scene}/tree/{setting}"));
            g.sampling_mode(SamplingMode::Flat).sample_size(10);
            g.throughput(Throughput::Elements(f.primary.len() as u64));
            g.bench_function("primary", |b| b.iter(|| trace_single(&bvh, black_box(&f.primary))));
            g.throughput(Throughput::Elements(f.shadow.len() as u64));
            g.bench_function("shadow", |b| b.iter(|| occlude_single(&bvh, black_box(&f.shadow))));
            g.throughput(Throughput::Elements(f.diffuse.len() as u64));
            g.bench_function("diffuse", |b| b.iter(|| trace_single(&bvh, black_box(&f.diffuse))));
            g.finish();
        }
    }
}

/// The attribution table (see the module docs): per ray kind, what our single-ray traversal
/// does per ray on each scene (nodes read, child boxes tested, leaves entered, triangles
/// tested, waiting children skipped), and the tree's SAH cost beside the costs of other
/// builds of the same triangles: our fast and high obvhs presets and, with `peer-embree`,
/// Embree's builder (binned SAH, and SAH with spatial splits), all 8-wide, leaves of at most
/// 3 triangles, costs 1 per node read and 1 per triangle test.
fn attribution(_: &mut Criterion) {
    use stereotrace_kernels::traverse::TraversalCounts;
    if std::env::var_os("STEREOTRACE_BENCH_ATTRIBUTION").is_none_or(|v| v != "1") {
        eprintln!("SKIPPED attribution table: set STEREOTRACE_BENCH_ATTRIBUTION=1");
        return;
    }
    let mut scenes: Vec<(&str, &Fixture)> = BUILTINS.iter().map(|name| (*name, builtin(name))).collect();
    if let Some(f) = sponza() {
        scenes.push(("sponza", f));
    }
    println!("| scene | rays | per ray: nodes | boxes tested | leaves | triangles | skipped |");
    println!("|---|---|--:|--:|--:|--:|--:|");
    for (name, f) in &scenes {
        for (kind, rays, any_hit) in
            [("primary", &f.primary, false), ("shadow", &f.shadow, true), ("diffuse", &f.diffuse, false)]
        {
            let mut c = TraversalCounts::default();
            for r in rays.iter() {
                if any_hit {
                    f.bvh.occluded_counted(r, &mut c);
                } else {
                    f.bvh.intersect_counted(r, &mut c);
                }
            }
            let per = |v: u64| v as f64 / c.rays as f64;
            println!(
                "| {name} | {kind} | {:.1} | {:.1} | {:.2} | {:.1} | {:.2} |",
                per(c.nodes),
                per(c.box_tests),
                per(c.leaves),
                per(c.triangles),
                per(c.skipped)
            );
        }
    }
    println!();
    println!(
        "| scene | triangles | build ms, medium (PLOC) | build ms, sah (binned SAH) | sah ÷ medium | build ms, splits (SAH + spatial splits) | splits ÷ sah |"
    );
    println!("|---|--:|--:|--:|--:|--:|--:|");
    for (name, f) in &scenes {
        let median_ms = |q: BuildQuality| {
            let mut t: Vec<f64> = (0..3)
                .map(|_| TriangleBvh::build(&f.tris, q).expect("valid scene").1.total_time.as_secs_f64() * 1e3)
                .collect();
            t.sort_by(f64::total_cmp);
            t[1]
        };
        let (medium, sah, splits) =
            (median_ms(BuildQuality::Medium), median_ms(BuildQuality::Sah), median_ms(BuildQuality::SahSplits));
        println!(
            "| {name} | {} | {medium:.1} | {sah:.1} | {:.2} | {splits:.1} | {:.2} |",
            f.tris.len(),
            sah / medium,
            splits / sah
        );
    }
    println!();
    println!(
        "| scene | triangles | SAH ours (bench tree) | obvhs fast | obvhs high | our binned SAH | our SAH + spatial splits (refs) | Embree binned SAH (build) | Embree spatial splits (refs, build) |"
    );
    println!("|---|--:|--:|--:|--:|--:|--:|--:|--:|");
    for (name, f) in &scenes {
        let sah = |q: BuildQuality| TriangleBvh::build(&f.tris, q).expect("valid scene").0.sah_cost(1.0, 1.0);
        #[cfg(feature = "peer-embree")]
        let (binned, split) = {
            let binned = embree::embree_tree(&f.tris, embree::BUILD_QUALITY_MEDIUM, 0.0, 3);
            let split = embree::embree_tree(&f.tris, embree::BUILD_QUALITY_HIGH_SPLITS, 1.0, 3);
            let ms = |t: &embree::BuiltTree| t.build.as_secs_f64() * 1e3;
            (
                format!("{:.1} ({:.0} ms)", binned.sah, ms(&binned)),
                format!("{:.1} ({} refs, {:.0} ms)", split.sah, split.references, ms(&split)),
            )
        };
        #[cfg(not(feature = "peer-embree"))]
        let (binned, split) = ("-".to_string(), "-".to_string());
        let (ours_split, ours_split_stats) = TriangleBvh::build(&f.tris, BuildQuality::SahSplits).expect("valid scene");
        println!(
            "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} ({} refs) | {binned} | {split} |",
            f.tris.len(),
            f.bvh.sah_cost(1.0, 1.0),
            sah(BuildQuality::Fast),
            sah(BuildQuality::High),
            sah(BuildQuality::Sah),
            ours_split.sah_cost(1.0, 1.0),
            ours_split_stats.references
        );
    }
}

/// The request of [`embree_counts`]: `STEREOTRACE_BENCH_EMBREE_COUNTS=scene/kind/shape`, with
/// kind `primary`, `shadow` or `diffuse` and shape `single` or `packet_8x1`.
fn embree_count_request() -> Option<String> {
    std::env::var("STEREOTRACE_BENCH_EMBREE_COUNTS").ok()
}

/// Embree's side of the attribution table: Embree keeps no per-ray counts in its release
/// builds, but a build with its statistics counters (CMake `EMBREE_STAT_COUNTERS=ON`) adds up
/// nodes, leaves and triangle blocks tested in the whole process and prints them when the
/// process exits. With `STEREOTRACE_BENCH_EMBREE_COUNTS` set (and such a library on the
/// loader's path, in place of Debian's), this traces one ray set of one scene once, prints how
/// many rays it traced, and exits before anything else runs, so the printed totals divided by
/// that number are Embree's work per ray on exactly the rays of the timed rows
/// (`tools/bench/embree_counts.py` runs every row and prints the table).
#[cfg(feature = "peer-embree")]
fn embree_counts(_: &mut Criterion) {
    let Some(request) = embree_count_request() else { return };
    let parts: Vec<&str> = request.split('/').collect();
    let [scene, kind, shape] = parts[..] else {
        panic!("STEREOTRACE_BENCH_EMBREE_COUNTS: expected scene/kind/shape, got '{request}'")
    };
    let f = match scene {
        "sponza" => sponza().expect("STEREOTRACE_BENCH_EMBREE_COUNTS: ../shared/scenes/sponza not found"),
        "procedural700k" => procedural(),
        name => builtin(BUILTINS.iter().find(|b| **b == name).unwrap_or_else(|| panic!("unknown scene '{name}'"))),
    };
    // Calls: rays for single rays, packets for packets (Embree 3.13 counts neither itself).
    let (calls, hits) = match (kind, shape) {
        ("primary", "single") => (f.primary.len(), f.embree.intersect(&f.primary)),
        ("shadow", "single") => (f.shadow.len(), f.embree.occluded(&f.shadow)),
        ("diffuse", "single") => (f.diffuse.len(), f.embree.intersect(&f.diffuse)),
        ("primary", "packet_8x1") => (f.primary_8x1.len(), f.embree.intersect8(&f.primary_8x1)),
        ("shadow", "packet_8x1") => (f.shadow_8x1.len(), f.embree.occluded8(&f.shadow_8x1)),
        _ => panic!("STEREOTRACE_BENCH_EMBREE_COUNTS: no ray set '{kind}/{shape}'"),
    };
    // Our counts of the same rays, in the same process, for the table beside Embree's.
    let mut c = stereotrace_kernels::traverse::TraversalCounts::default();
    let ray_set = match kind {
        "primary" => &f.primary,
        "shadow" => &f.shadow,
        _ => &f.diffuse,
    };
    for r in ray_set {
        if kind == "shadow" {
            f.bvh.occluded_counted(r, &mut c);
        } else {
            f.bvh.intersect_counted(r, &mut c);
        }
    }
    println!(
        "EMBREE_COUNTS calls={calls} rays={} hits={hits} ours_nodes={} ours_leaves={} ours_triangles={} ours_blocks={}",
        c.rays, c.nodes, c.leaves, c.triangles, c.triangle_blocks
    );
    // Exit here: the library prints its totals from a static destructor at exit.
    std::process::exit(0);
}

#[cfg(not(feature = "peer-embree"))]
fn embree_counts(_: &mut Criterion) {
    if embree_count_request().is_some() {
        panic!("STEREOTRACE_BENCH_EMBREE_COUNTS needs --features peer-embree");
    }
}

criterion_group!(benches, embree_counts, traversal, trees, attribution);
criterion_main!(benches);

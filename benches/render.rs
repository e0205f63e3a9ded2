//! Rendering throughput at 1280×720 on the renderer's own scenes, cameras and lights, on 1
//! and 2 threads:
//!
//! * `render/rays/<scene>`: the three kinds of rays the path tracer casts, on the renderer's
//!   BVH: primary rays through the pixel centres as 8×1 packets, shadow rays from the primary
//!   hits toward a light sampled as next-event estimation samples it (8×1 packets), and
//!   cosine-distributed diffuse rays from the primary hits (single rays, as the tracer traces
//!   them); primary and shadow rays also as single rays on one thread. Rays are built
//!   outside the timed loop from fixed seeds.
//! * `render/trace/<scene>`: a whole 1-spp path-traced frame (one eye): the packet loop and
//!   the single-ray reference ([`Renderer::trace_single_rays`]); rays per second counts all
//!   four rays of every sample.
//! * `render/stereo_frame/<scene>`: both eyes' G-buffers and 1-spp path tracing, 2 threads:
//!   the time is the stereo frame time.
//! * `render/specialisation/<scene>`: the integrator specialised for the scene's effects
//!   against the general one (`trace(.., general: true)`) on all-diffuse static scenes, one
//!   thread, 1 spp.
//!
//! Throughput is in rays (criterion's "elem/s"). Scenes: the paper stand-ins among the
//! built-ins and `../shared/scenes/sponza` (skipped with a message if absent).
//!
//! Run: `cargo bench --bench render -- --warm-up-time 1 --measurement-time 3` (a filter such
//! as `render/rays` or `sponza` picks groups).

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::OnceLock;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use rayon::prelude::*;
use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::bvh::Ray;
use stereotrace::kernels::traverse::{PacketHits, RayPacket};
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::bsdf::cosine_hemisphere;
use stereotrace::render::rng::{Dim, SampleStream};
use stereotrace::render::{FrameView, GBufferBuf, Renderer, pixel_centre_ray};
use stereotrace::scene::resolve;
use stereotrace::source::PixelSelection;

const WIDTH: usize = 1280;
const HEIGHT: usize = 720;
const FRAME: u32 = 0;
/// Built-in scenes benchmarked (the paper stand-ins; the variants share their geometry).
const BUILTINS: [&str; 4] = ["atrium", "living-room", "classroom", "courtyard"];

type Packet = (RayPacket, u32);

struct Fixture {
    renderer: Renderer,
    /// Both eyes' cameras and the lights at [`FRAME`].
    view: FrameView,
    primary: Vec<Packet>,
    primary_rays: u64,
    shadow: Vec<Packet>,
    shadow_rays: u64,
    /// The active lanes of `primary` and `shadow` as single rays, in the same order.
    primary_single: Vec<Ray>,
    shadow_single: Vec<Ray>,
    diffuse: Vec<Ray>,
}

/// The tracer's offset of a ray origin off a surface (as `render::spawn`).
fn spawn(p: Vec3, n: Vec3, dir: Vec3) -> Vec3 {
    let eps = 1e-4 * p.abs().max_element().max(1.0);
    if n.dot(dir) >= 0.0 { p + n * eps } else { p - n * eps }
}

/// Eight-lane packets of the rays `at(x, y)` along rows (8×1 pixel tiles).
fn row_packets(at: &dyn Fn(usize, usize) -> Option<Ray>) -> Vec<Packet> {
    let mut out = Vec::with_capacity(WIDTH * HEIGHT / 8);
    for y in 0..HEIGHT {
        for x0 in (0..WIDTH).step_by(8) {
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::X); 8];
            let mut active = 0;
            for (i, ray) in rays.iter_mut().enumerate() {
                if let Some(r) = (x0 + i < WIDTH).then(|| at(x0 + i, y)).flatten() {
                    *ray = r;
                    active |= 1 << i;
                }
            }
            if active != 0 {
                out.push((RayPacket::from_rays(&rays), active));
            }
        }
    }
    out
}

impl Fixture {
    fn new(name: &str, renderer: Renderer) -> Self {
        let extent = Extent::new(WIDTH, HEIGHT).expect("extent");
        let view = FrameView::new(&renderer, &StereoRig::default(), extent, FRAME).expect("a valid frame");
        // The rays below are the right eye's (the path-traced one).
        let (camera, lights) = (view.camera(Eye::Right), &view.lights);
        let bvh = renderer.bvh();
        let mesh = &renderer.scene().mesh;
        // Primary hits: position and geometric normal facing the viewer.
        let hits: Vec<Option<(Vec3, Vec3)>> = (0..HEIGHT)
            .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
            .map(|(x, y)| {
                let ray = pixel_centre_ray(camera, x, y);
                bvh.intersect(&ray).map(|h| {
                    let n = mesh.geometric_normal(h.prim as usize);
                    (mesh.point(h.prim as usize, h.u, h.v), if n.dot(ray.dir) > 0.0 { -n } else { n })
                })
            })
            .collect();
        let stream = |x: usize, y: usize| SampleStream::new(1, 0, FRAME, (y * WIDTH + x) as u32, 0);
        let env = renderer.scene().lights.environment.as_ref();
        let shadow_at = |x: usize, y: usize| {
            let (p, n) = hits[y * WIDTH + x]?;
            let s = stream(x, y);
            let ls = lights.sample(env, p, s.get(Dim::LightPick1), s.get2(Dim::LightPoint1))?;
            (n.dot(ls.wi) > 0.0).then(|| {
                let tmax = if ls.distance.is_finite() { ls.distance * (1.0 - 1e-4) } else { f32::INFINITY };
                Ray::segment(spawn(p, n, ls.wi), ls.wi, 0.0, tmax)
            })
        };
        let primary = row_packets(&|x, y| Some(pixel_centre_ray(camera, x, y)));
        let shadow = row_packets(&shadow_at);
        let diffuse: Vec<Ray> = (0..HEIGHT)
            .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
            .filter_map(|(x, y)| {
                let (p, n) = hits[y * WIDTH + x]?;
                let wi = cosine_hemisphere(n, stream(x, y).get2(Dim::Bounce));
                Some(Ray::new(spawn(p, n, wi), wi))
            })
            .collect();
        let count = |p: &[Packet]| p.iter().map(|(_, m)| u64::from(m.count_ones())).sum::<u64>();
        let (primary_rays, shadow_rays) = (count(&primary), count(&shadow));
        eprintln!(
            "[{name}] {} triangles, effects {}: {primary_rays} primary, {shadow_rays} shadow, {} diffuse rays",
            renderer.scene().mesh.len(),
            stereotrace::render::effects::describe(renderer.effect_bits()),
            diffuse.len()
        );
        let unpack = |p: &[Packet]| -> Vec<Ray> {
            p.iter().flat_map(|(p, m)| (0..8).filter(move |&i| m & (1 << i) != 0).map(move |i| p.ray(i))).collect()
        };
        let (primary_single, shadow_single) = (unpack(&primary), unpack(&shadow));
        Fixture { view, renderer, primary, primary_rays, shadow, shadow_rays, primary_single, shadow_single, diffuse }
    }

    fn trace(&self, eye: Eye, out: &mut RgbBuf, general: bool, single_rays: bool) -> u64 {
        let request = self.view.request(eye, 1, 1, 0);
        let (r, l, c) = (&self.renderer, &self.view.lights, self.view.camera(eye));
        let stats = if single_rays {
            r.trace_single_rays(l, c, &request, PixelSelection::All, out, general)
        } else {
            r.trace(l, c, &request, PixelSelection::All, out, general)
        };
        stats.expect("trace").rays
    }
}

fn shared_dir() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    Some(root.join("../shared")).filter(|p| p.join("scenes").is_dir())
}

/// Fixtures built so far, by scene name (`None`: unavailable).
type FixtureCache = std::sync::Mutex<Vec<(&'static str, Option<&'static Fixture>)>>;

/// The fixture of `name` (a built-in or `sponza`), built once; `None` if unavailable.
fn fixture(name: &'static str) -> Option<&'static Fixture> {
    static CACHE: OnceLock<FixtureCache> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    let mut cache = cache.lock().expect("fixture cache");
    if let Some((_, f)) = cache.iter().find(|(n, _)| *n == name) {
        return *f;
    }
    let spec = if name == "sponza" {
        match shared_dir() {
            Some(d) => Some(d.join("scenes/sponza").to_string_lossy().into_owned()),
            None => {
                eprintln!("SKIPPED sponza benches: ../shared/scenes/sponza not found");
                None
            }
        }
    } else {
        Some(name.to_owned())
    };
    let f = spec.map(|s| {
        let scene = resolve(&s).unwrap_or_else(|e| panic!("{name}: {e}"));
        let renderer = Renderer::new(scene).expect("renderer");
        &*Box::leak(Box::new(Fixture::new(name, renderer)))
    });
    cache.push((name, f));
    f
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// Work split for the thread pools: chunks of this many packets or rays.
const CHUNK: usize = 64;

fn primary(f: &Fixture) -> u32 {
    f.primary
        .par_chunks(CHUNK)
        .map(|c| {
            let mut hits = PacketHits::NONE;
            c.iter().map(|(p, m)| f.renderer.bvh().intersect_packet(p, *m, &mut hits).count_ones()).sum::<u32>()
        })
        .sum()
}

fn shadow(f: &Fixture) -> u32 {
    f.shadow
        .par_chunks(CHUNK)
        .map(|c| c.iter().map(|(p, m)| f.renderer.bvh().occluded_packet(p, *m).count_ones()).sum::<u32>())
        .sum()
}

fn primary_single(f: &Fixture) -> u32 {
    f.primary_single.iter().map(|r| f.renderer.bvh().intersect(r).is_some() as u32).sum()
}

fn shadow_single(f: &Fixture) -> u32 {
    f.shadow_single.iter().map(|r| f.renderer.bvh().occluded(r) as u32).sum()
}

fn diffuse(f: &Fixture) -> u32 {
    f.diffuse
        .par_chunks(CHUNK * 8)
        .map(|c| c.iter().map(|r| f.renderer.bvh().intersect(r).is_some() as u32).sum::<u32>())
        .sum()
}

fn scenes() -> Vec<&'static str> {
    BUILTINS.into_iter().chain(["sponza"]).collect()
}

fn rays(c: &mut Criterion) {
    let pools = [(1, pool(1)), (2, pool(2))];
    for name in scenes() {
        let Some(f) = fixture(name) else { continue };
        let mut g = c.benchmark_group(format!("render/rays/{name}"));
        g.sampling_mode(SamplingMode::Flat).sample_size(10);
        // The same rays one at a time, for what packets buy.
        let one = &pools[0].1;
        g.throughput(Throughput::Elements(f.primary_rays));
        g.bench_function("primary_single/1t", |b| b.iter(|| one.install(|| primary_single(f))));
        g.throughput(Throughput::Elements(f.shadow_rays));
        g.bench_function("shadow_single/1t", |b| b.iter(|| one.install(|| shadow_single(f))));
        for (threads, pool) in &pools {
            g.throughput(Throughput::Elements(f.primary_rays));
            g.bench_function(format!("primary_packets/{threads}t"), |b| b.iter(|| pool.install(|| primary(f))));
            g.throughput(Throughput::Elements(f.shadow_rays));
            g.bench_function(format!("shadow_packets/{threads}t"), |b| b.iter(|| pool.install(|| shadow(f))));
            g.throughput(Throughput::Elements(f.diffuse.len() as u64));
            g.bench_function(format!("diffuse_single/{threads}t"), |b| b.iter(|| pool.install(|| diffuse(f))));
        }
        g.finish();
    }
}

fn trace(c: &mut Criterion) {
    let pools = [(1, pool(1)), (2, pool(2))];
    let extent = Extent::new(WIDTH, HEIGHT).expect("extent");
    for name in scenes() {
        let Some(f) = fixture(name) else { continue };
        let mut out = RgbBuf::new(extent, 0.0);
        let rays = f.trace(Eye::Right, &mut out, false, false);
        let mut g = c.benchmark_group(format!("render/trace/{name}"));
        g.sampling_mode(SamplingMode::Flat).sample_size(10).throughput(Throughput::Elements(rays));
        for (threads, pool) in &pools {
            g.bench_function(format!("packets/{threads}t"), |b| {
                b.iter(|| pool.install(|| f.trace(Eye::Right, black_box(&mut out), false, false)))
            });
        }
        g.bench_function("single_rays/1t", |b| {
            b.iter(|| pools[0].1.install(|| f.trace(Eye::Right, &mut out, false, true)))
        });
        g.finish();
    }
}

fn stereo_frame(c: &mut Criterion) {
    let two = pool(2);
    let extent = Extent::new(WIDTH, HEIGHT).expect("extent");
    for name in scenes() {
        let Some(f) = fixture(name) else { continue };
        let mut out = [RgbBuf::new(extent, 0.0), RgbBuf::new(extent, 0.0)];
        let mut gbuffers = f.view.cameras.map(GBufferBuf::new);
        let mut frame = || {
            let mut rays = 0;
            for eye in Eye::BOTH {
                f.renderer.render_gbuffer(&f.view.lights, &mut gbuffers[eye as usize]);
                rays += (WIDTH * HEIGHT) as u64 + f.trace(eye, &mut out[eye as usize], false, false);
            }
            rays
        };
        let rays = two.install(&mut frame);
        let mut g = c.benchmark_group(format!("render/stereo_frame/{name}"));
        g.sampling_mode(SamplingMode::Flat).sample_size(10).throughput(Throughput::Elements(rays));
        g.bench_function("1spp/2t", |b| b.iter(|| two.install(&mut frame)));
        g.finish();
    }
}

fn specialisation(c: &mut Criterion) {
    let one = pool(1);
    let extent = Extent::new(WIDTH, HEIGHT).expect("extent");
    for name in ["cornell", "living-room"] {
        let Some(f) = fixture(name) else { continue };
        let mut out = RgbBuf::new(extent, 0.0);
        let rays = one.install(|| f.trace(Eye::Right, &mut out, false, false));
        let mut g = c.benchmark_group(format!("render/specialisation/{name}"));
        g.sampling_mode(SamplingMode::Flat).sample_size(10).throughput(Throughput::Elements(rays));
        g.bench_function("specialised/1t", |b| b.iter(|| one.install(|| f.trace(Eye::Right, &mut out, false, false))));
        g.bench_function("general/1t", |b| b.iter(|| one.install(|| f.trace(Eye::Right, &mut out, true, false))));
        g.finish();
    }
}

criterion_group!(benches, rays, trace, stereo_frame, specialisation);
criterion_main!(benches);

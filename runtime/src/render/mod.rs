//! Rendering: the BVH, the G-buffer pass and the path tracer with the paper's estimator.
//!
//! # The estimator (one sample)
//! One primary ray, one secondary ray, two shadow rays:
//! 1. the primary ray through a jittered point of the pixel; emission it sees counts (and
//!    the environment and sun where it escapes);
//! 2. next-event estimation at the primary hit: one light record chosen by power, one point
//!    on it, shadow ray 1;
//! 3. one BSDF-sampled secondary ray;
//! 4. next-event estimation at the secondary hit: shadow ray 2.
//!
//! Emission reached by the secondary ray (an emitter, the sun, the environment) counts only
//! where next-event estimation could not have sampled it, i.e. after a delta (mirror) lobe;
//! otherwise it would be counted twice. The result is an unbiased estimate of transport over
//! paths with up to two bounces. A mirror at the primary hit gets no next-event estimate (a
//! delta lobe has zero value towards any sampled light).
//!
//! # Specialisation
//! Every per-sample function is generic over the effect bits `E` ([`effects`]); the public
//! entry points dispatch on the scene's bits, or on [`effects::ALL`] for the general
//! integrator, which must give the same image.
//!
//! # Tracing
//! [`Renderer::trace`] runs the estimator on groups of eight pixels stage by stage and traces
//! the coherent stages (primary rays, shadow rays from the primary hits) as 8-lane packets
//! (module `packets`); [`Renderer::trace_single_rays`] is the single-ray reference
//! (`Renderer::radiance`, one pixel and sample at a time). Both give the same image except
//! where a ray hits two triangles at exactly the same distance.
//!
//! # Determinism
//! Random numbers are a pure function of (seed, eye, frame, pixel, sample, purpose)
//! ([`rng`]); rows run in parallel but each pixel's value depends only on its own numbers,
//! so images are identical across runs and thread counts.

pub mod bsdf;
pub mod effects;
pub mod lights;
mod packets;
pub mod raster;
pub mod rng;
pub mod source;
pub mod spawn;

use std::time::Duration;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::kernels::bvh::{
    BuildQuality, BuildStats, BvhBuildParams, Hit, PreparedRay, Ray, TriHit, TriangleBvh, intersect_triangle,
};
pub use crate::kernels::gbuffer::GBufferBuf;
use crate::kernels::gbuffer::{NO_NORMAL, encode_normal};
use crate::kernels::simd::{F32s, LANES};
use crate::kernels::{CameraModel, FrameError, PlaneBuf, RgbBuf};
use crate::scene::{MaterialKind, Scene};
use crate::source::{PixelSelection, TraceRequest, TraceStats};
use bsdf::ShadingPoint;
use effects::{ALPHA_MASKS, MOVING_GEOMETRY, TEXTURES, has};
use lights::{FrameLights, MovingTriangle};
use rng::{Dim, SampleStream};
pub use source::{GBufferPass, RendererOptions, RendererSource};

/// Why rendering could not start.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("BVH build failed: {0}")]
    /// The scene's BVH could not be built.
    Bvh(#[from] crate::kernels::bvh::BvhError),
    #[error(transparent)]
    /// A buffer, extent or camera was refused.
    Frame(#[from] FrameError),
    #[error("{0}")]
    /// An input was refused (the message says which).
    Invalid(String),
}

/// A scene with its BVH, ready to render any frame and eye.
pub struct Renderer {
    scene: Scene,
    bvh: TriangleBvh,
    bvh_stats: BuildStats,
    bits: u16,
    /// 1: the paper's estimator; 0: direct lighting only (see [`Renderer::set_bounces`]).
    bounces: u32,
    /// The rasterised G-buffer's near plane: a millionth of the scene's size (the traced
    /// pass sees from depth 0; geometry nearer than this to the eye is not rasterised).
    raster_near: f32,
}

/// What the primary or secondary ray hit.
#[derive(Clone, Copy, Debug)]
enum Surface {
    /// A triangle of the static mesh.
    Mesh(Hit),
    /// A triangle placed for the frame (`index` into [`FrameLights::moving_triangles`]) at
    /// barycentrics `(u, v)`: of a moving area light (emits `radiance` on the side of the unit
    /// winding `normal`; `material` is [`MOVING_LIGHT_MATERIAL`]) or of a moving object
    /// (`radiance` zero, shaded flat with the scene material `material`).
    Moving { t: f32, u: f32, v: f32, normal: Vec3, radiance: Vec3, material: u32, index: u32 },
}

impl Surface {
    /// The hit at `t`, barycentrics `uv`, on the moving triangle `index` of `triangles`.
    #[inline]
    fn moving(triangles: &[MovingTriangle], index: u32, t: f32, (u, v): (f32, f32)) -> Self {
        let tri = &triangles[index as usize];
        let normal = (tri.v[1] - tri.v[0]).cross(tri.v[2] - tri.v[0]).normalize_or_zero();
        Surface::Moving { t, u, v, normal, radiance: tri.radiance, material: tri.material, index }
    }

    fn t(&self) -> f32 {
        match self {
            Surface::Mesh(h) => h.t,
            Surface::Moving { t, .. } => *t,
        }
    }
}

/// How a tracing call traces its rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kernel {
    /// Groups of up to eight pixels, each stage of the estimator traced as one packet
    /// ([`packets`]).
    Packets,
    /// The single-ray reference.
    SingleRays,
}

impl Renderer {
    /// Builds the BVH for `scene` (validated first) with the default [`BuildQuality`].
    pub fn new(scene: Scene) -> Result<Self, RenderError> {
        scene.validate().map_err(|e| RenderError::Invalid(e.to_string()))?;
        let built = TriangleBvh::build(&scene.mesh.positions, BuildQuality::default())?;
        Ok(Self::with_bvh(scene, built))
    }

    /// [`Renderer::new`] with the tree built from obvhs's parameters `params`: an engine that
    /// loads a scene once and traces it for many frames can pay a longer build for faster
    /// traversal (BENCHMARKS.md, "the tree's build parameters", measures the trade). Images
    /// are the same with any tree except which triangle wins an exact tie in `t`.
    ///
    /// # Errors
    /// Those of [`Renderer::new`], and `RenderError::Bvh` for parameters the builder refuses.
    pub fn with_bvh_params(scene: Scene, params: &BvhBuildParams) -> Result<Self, RenderError> {
        scene.validate().map_err(|e| RenderError::Invalid(e.to_string()))?;
        let built = TriangleBvh::build_with(&scene.mesh.positions, params)?;
        Ok(Self::with_bvh(scene, built))
    }

    /// The renderer of a validated `scene` over its built tree.
    fn with_bvh(scene: Scene, (bvh, bvh_stats): (TriangleBvh, BuildStats)) -> Self {
        let bits = effects::bits_for(scene.effects);
        let raster_near = (scene.bounds().extent().length() * 1e-6).max(1e-9);
        Self { scene, bvh, bvh_stats, bits, bounces: 1, raster_near }
    }

    /// Chooses the estimator: `1` (the default) is the paper's, one primary and one secondary
    /// bounce; `0` stops after next-event estimation at the primary hit (direct lighting
    /// only: what a renderer with a maximum path depth of 2 computes). A `0` estimate is the
    /// first part of the `1` estimate with the same random numbers.
    pub fn set_bounces(&mut self, bounces: u32) -> Result<(), RenderError> {
        if bounces > 1 {
            return Err(RenderError::Invalid(format!("bounces {bounces}: the estimator supports 0 or 1")));
        }
        self.bounces = bounces;
        Ok(())
    }

    /// The estimator's bounces (see [`Renderer::set_bounces`]).
    pub fn bounces(&self) -> u32 {
        self.bounces
    }

    /// The scene being rendered.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene's BVH.
    pub fn bvh(&self) -> &TriangleBvh {
        &self.bvh
    }

    /// How long the BVH build took.
    pub fn bvh_build_time(&self) -> Duration {
        self.bvh_stats.total_time
    }

    /// How the BVH was built (time, nodes, quality).
    pub fn bvh_stats(&self) -> &BuildStats {
        &self.bvh_stats
    }

    /// The integrator effect bits of the scene.
    pub fn effect_bits(&self) -> u16 {
        self.bits
    }

    /// The light table of `frame`.
    pub fn frame_lights(&self, frame: u32) -> FrameLights {
        FrameLights::new(&self.scene, frame)
    }

    /// Fills `out` with the G-buffer seen by `out.camera` (one ray per pixel centre, traced
    /// as 8-wide packets along rows).
    pub fn render_gbuffer(&self, lights: &FrameLights, out: &mut GBufferBuf) {
        macro_rules! call {
            ($e:literal) => {
                self.gbuffer_pass::<$e>(lights, out)
            };
        }
        crate::dispatch_effects!(self.bits, call)
    }

    /// Fills `out.motion`, if it has motion planes, with each pixel's world-space motion since
    /// the light table's previous frame: zero on the static mesh and background, and the
    /// motion of the moving light or object seen at the pixel (its centre ray's hit on the
    /// triangle now, less the same barycentric point of it then). A pixel sees moving geometry
    /// when its material is one that moving triangles carry and a moving triangle lies at its
    /// depth (not behind a static surface of the same material). Nothing is written for a
    /// scene without moving geometry: its planes stay as allocated, zero.
    pub fn write_motion(&self, lights: &FrameLights, out: &mut GBufferBuf) {
        let Some(motion) = &mut out.motion else { return };
        let triangles = lights.moving_triangles();
        if triangles.is_empty() {
            return;
        }
        for plane in motion.iter_mut() {
            plane.as_mut_slice().fill(0.0);
        }
        let camera = &out.camera;
        let width = out.material.extent().width();
        let depth = out.depth.as_slice();
        let moving = lights.moving_materials();
        for (i, _) in out.material.as_slice().iter().enumerate().filter(|(_, m)| moving.contains(m)) {
            let (x, y) = (i % width, i / width);
            let dir = Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5));
            let Some(ray) = PreparedRay::new(&Ray::new(Vec3::from(camera.centre), dir)) else { continue };
            // The ray has unit view depth, so the pixel's surface lies at t = depth; a moving
            // triangle up to a rounding margin beyond it is the one the pixel sees.
            let limit = depth[i] * (1.0 + 1e-5) + f32::MIN_POSITIVE;
            if let Some((index, hit)) = nearest_moving(triangles, &ray, limit) {
                let tri = &triangles[index as usize];
                let (u, v) = hit.uv();
                let moved = |k: usize| tri.v[k] - tri.previous[k];
                let m = (1.0 - u - v) * moved(0) + u * moved(1) + v * moved(2);
                for c in 0..3 {
                    motion[c].as_mut_slice()[i] = m[c];
                }
            }
        }
    }

    /// Path traces `request.spp` samples into `out` for the pixels `selection` names, with the
    /// integrator specialised for the scene's effects (`general = false`) or the general one.
    pub fn trace(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        self.trace_rows(lights, camera, request, selection, 0..camera.extent.height(), out, general)
    }

    /// [`Renderer::trace`] restricted to the rows `rows` (the budgeted runtime traces the
    /// frame in row tiles).
    #[allow(clippy::too_many_arguments)]
    pub fn trace_rows(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        self.trace_with(lights, camera, request, selection, rows, out, general, Kernel::Packets)
    }

    /// [`Renderer::trace`] by the single-ray reference loop: every ray traced alone, one
    /// pixel and sample at a time. It computes the same estimator with the same random
    /// numbers, so images equal [`Renderer::trace`]'s except where a ray hits two triangles at
    /// exactly the same distance (packet and single-ray traversal may pick different ones).
    /// The oracle for the packet loop's tests, and its bench baseline.
    pub fn trace_single_rays(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        let rows = 0..camera.extent.height();
        self.trace_with(lights, camera, request, selection, rows, out, general, Kernel::SingleRays)
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_with(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
        general: bool,
        kernel: Kernel,
    ) -> Result<TraceStats, RenderError> {
        crate::kernels::frame::same_extent("output image", camera.extent, out.extent())?;
        if rows.start > rows.end || rows.end > camera.extent.height() {
            return Err(RenderError::Invalid(format!(
                "rows {}..{} outside the image height {}",
                rows.start,
                rows.end,
                camera.extent.height()
            )));
        }
        if let PixelSelection::Mask(m) = selection {
            crate::kernels::frame::same_extent("pixel mask", camera.extent, m.extent())?;
        }
        if request.spp == 0 {
            return Err(RenderError::Invalid("samples per pixel must be at least 1".into()));
        }
        let bits = if general { effects::ALL } else { self.bits };
        macro_rules! call {
            ($e:literal) => {
                match kernel {
                    Kernel::Packets => self.trace_pass::<$e>(lights, camera, request, selection, rows, out),
                    Kernel::SingleRays => self.trace_pass_single::<$e>(lights, camera, request, selection, rows, out),
                }
            };
        }
        Ok(crate::dispatch_effects!(bits, call))
    }

    // ---- geometry queries ----------------------------------------------------------------

    /// Whether the triangle hit at `h` is cut away by its material's opacity (alpha test at
    /// 0.5: cut-outs are binary masks such as leaves).
    #[inline]
    fn cut_out(&self, h: &Hit) -> bool {
        let m = &self.scene.materials[self.scene.mesh.material[h.prim as usize] as usize];
        m.has_cutout() && m.coverage_at(&self.scene.textures, self.scene.mesh.uv(h.prim as usize, h.u, h.v)) < 0.5
    }

    /// Closest hit of the static mesh, skipping cut-out surfaces.
    #[inline]
    fn closest_mesh<const E: u16>(&self, mut ray: Ray) -> Option<Hit> {
        loop {
            let h = self.bvh.intersect(&ray)?;
            if !(has(E, ALPHA_MASKS) && self.cut_out(&h)) {
                return Some(h);
            }
            ray.tmin = h.t.next_up();
            if ray.tmin >= ray.tmax {
                return None;
            }
        }
    }

    /// Closest moving triangle (of a light or an object) nearer than `tmax`.
    #[inline]
    fn closest_moving(lights: &FrameLights, ray: &Ray, tmax: f32) -> Option<Surface> {
        if !lights.may_hit_moving(ray.origin, ray.dir.normalize_or_zero()) {
            return None;
        }
        let prepared = PreparedRay::new(&Ray { tmax, ..*ray })?;
        let triangles = lights.moving_triangles();
        let (index, hit) = nearest_moving(triangles, &prepared, tmax)?;
        Some(Surface::moving(triangles, index, hit.t, hit.uv()))
    }

    /// Shading information where a ray along `dir` meets `surface`, or `None` for a moving
    /// light (an emitter only: it reflects nothing).
    #[inline(always)]
    fn shade_surface<const E: u16>(&self, lights: &FrameLights, surface: &Surface, dir: Vec3) -> Option<ShadingPoint> {
        match *surface {
            Surface::Mesh(h) => Some(self.shade::<E>(&h, dir)),
            Surface::Moving { material: MOVING_LIGHT_MATERIAL, .. } => None,
            Surface::Moving { u, v, normal, material, index, .. } => {
                // A moving object: flat and untextured (see `scene::object`).
                let m = &self.scene.materials[material as usize];
                let n = if normal.dot(dir) > 0.0 { -normal } else { normal };
                let tri = &lights.moving_triangles()[index as usize];
                let (position, position_error) = spawn::barycentric_point(&tri.v, u, v);
                Some(ShadingPoint {
                    position,
                    position_error,
                    geometric_normal: n,
                    shading_normal: n,
                    kind: m.kind,
                    albedo: m.albedo,
                    specular: m.specular,
                    alpha: m.alpha(),
                })
            }
        }
    }

    /// Closest surface along `ray`.
    #[inline]
    fn closest<const E: u16>(&self, lights: &FrameLights, ray: Ray) -> Option<Surface> {
        let mesh = self.closest_mesh::<E>(ray).map(Surface::Mesh);
        if has(E, MOVING_GEOMETRY) {
            let tmax = mesh.map_or(ray.tmax, |s| s.t());
            if let Some(light) = Self::closest_moving(lights, &ray, tmax) {
                return Some(light);
            }
        }
        mesh
    }

    /// Whether anything blocks `ray` (in `[tmin, tmax)`).
    #[inline]
    fn occluded<const E: u16>(&self, lights: &FrameLights, ray: Ray) -> bool {
        let blocked = if has(E, ALPHA_MASKS) { self.closest_mesh::<E>(ray).is_some() } else { self.bvh.occluded(&ray) };
        blocked || (has(E, MOVING_GEOMETRY) && Self::closest_moving(lights, &ray, ray.tmax).is_some())
    }

    /// Shading information at a mesh hit seen along `dir`.
    #[inline(always)]
    fn shade<const E: u16>(&self, h: &Hit, dir: Vec3) -> ShadingPoint {
        let mesh = &self.scene.mesh;
        let tri = h.prim as usize;
        let material = &self.scene.materials[mesh.material[tri] as usize];
        let (ng, ns) = self.normals(h, dir);
        let albedo = if has(E, TEXTURES) && material.albedo_texture.is_some() {
            material.albedo_at(&self.scene.textures, mesh.uv(tri, h.u, h.v))
        } else {
            material.albedo
        };
        let (position, position_error) = spawn::barycentric_point(&mesh.positions[tri], h.u, h.v);
        ShadingPoint {
            position,
            position_error,
            geometric_normal: ng,
            shading_normal: ns,
            kind: material.kind,
            albedo,
            specular: material.specular,
            alpha: material.alpha(),
        }
    }

    /// The geometric and shading normals of a hit, both facing the incoming ray `dir` (the
    /// part of [`Renderer::shade`] the G-buffer needs: no material or texture lookups).
    #[inline]
    fn normals(&self, h: &Hit, dir: Vec3) -> (Vec3, Vec3) {
        let mesh = &self.scene.mesh;
        let tri = h.prim as usize;
        let mut ng = mesh.geometric_normal(tri);
        if ng.dot(dir) > 0.0 {
            ng = -ng;
        }
        let mut ns = mesh.shading_normal(tri, h.u, h.v);
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        (ng, ns)
    }

    /// Emitted radiance of a surface towards `-dir` (one-sided emitters).
    #[inline]
    fn emitted(&self, s: &Surface, dir: Vec3) -> Vec3 {
        match s {
            Surface::Mesh(h) => {
                let tri = h.prim as usize;
                let m = &self.scene.materials[self.scene.mesh.material[tri] as usize];
                if m.emission == Vec3::ZERO || self.scene.mesh.cross(tri).dot(dir) >= 0.0 {
                    Vec3::ZERO
                } else {
                    m.emission
                }
            }
            Surface::Moving { normal, radiance, .. } => {
                if normal.dot(dir) < 0.0 {
                    *radiance
                } else {
                    Vec3::ZERO
                }
            }
        }
    }

    /// Radiance arriving from infinity along `dir` (environment and sun disc).
    #[inline]
    fn escaped(&self, dir: Vec3) -> Vec3 {
        let lights = &self.scene.lights;
        let env = lights.environment.as_ref().map_or(Vec3::ZERO, |e| e.radiance(dir));
        let sun = lights.sun.map_or(Vec3::ZERO, |s| s.radiance_towards(dir));
        env + sun
    }

    // ---- the estimator ---------------------------------------------------------------------

    /// The ray-free half of next-event estimation at `sp` for outgoing direction `wo`: the
    /// shadow ray and the contribution it carries if nothing blocks it, or `None` where the
    /// estimate is zero without tracing (no light sample, zero BSDF value, the light below the
    /// surface).
    #[inline]
    fn light_sample<const E: u16>(
        &self,
        lights: &FrameLights,
        sp: &ShadingPoint,
        wo: Vec3,
        rng: &SampleStream,
        (pick, point): (Dim, Dim),
    ) -> Option<(Ray, Vec3)> {
        let ls = lights.sample(self.scene.lights.environment.as_ref(), sp.position, rng.get(pick), rng.get2(point))?;
        let f = bsdf::eval::<E>(sp, wo, ls.wi);
        let cos = sp.shading_normal.dot(ls.wi);
        if f == Vec3::ZERO || cos <= 0.0 || !(ls.pdf > 0.0) {
            return None;
        }
        let ray = spawn::shadow_ray(sp.position, sp.position_error, sp.geometric_normal, ls.wi, &ls.target);
        Some((ray, ls.radiance * f * (cos / ls.pdf)))
    }

    /// Next-event estimate at `sp` for outgoing direction `wo`, with one shadow ray.
    #[inline]
    fn next_event<const E: u16>(
        &self,
        lights: &FrameLights,
        sp: &ShadingPoint,
        wo: Vec3,
        rng: &SampleStream,
        dims: (Dim, Dim),
        rays: &mut u64,
    ) -> Vec3 {
        let Some((ray, contribution)) = self.light_sample::<E>(lights, sp, wo, rng, dims) else {
            return Vec3::ZERO;
        };
        *rays += 1;
        if self.occluded::<E>(lights, ray) { Vec3::ZERO } else { contribution }
    }

    /// One sample of the paper's estimator along the primary ray `ray`.
    #[inline]
    fn radiance<const E: u16>(&self, lights: &FrameLights, ray: Ray, rng: &SampleStream, rays: &mut u64) -> Vec3 {
        *rays += 1;
        let dir = ray.dir.normalize();
        let Some(first) = self.closest::<E>(lights, ray) else {
            return self.escaped(dir);
        };
        let mut radiance = self.emitted(&first, dir);
        let Some(sp) = self.shade_surface::<E>(lights, &first, dir) else {
            return radiance;
        };
        let wo = -dir;
        if !(sp.kind == MaterialKind::Mirror && has(E, effects::MIRROR)) {
            radiance += self.next_event::<E>(lights, &sp, wo, rng, (Dim::LightPick1, Dim::LightPoint1), rays);
        }
        if self.bounces == 0 {
            return radiance;
        }
        let Some(bounce) = bsdf::sample::<E>(&sp, wo, rng.get(Dim::Lobe), rng.get2(Dim::Bounce)) else {
            return radiance;
        };
        *rays += 1;
        let origin = spawn::offset_origin(sp.position, sp.position_error, sp.geometric_normal, bounce.wi);
        let Some(second) = self.closest::<E>(lights, Ray::new(origin, bounce.wi)) else {
            if bounce.delta {
                radiance += bounce.weight * self.escaped(bounce.wi);
            }
            return radiance;
        };
        if bounce.delta {
            radiance += bounce.weight * self.emitted(&second, bounce.wi);
        }
        let Some(sp2) = self.shade_surface::<E>(lights, &second, bounce.wi) else {
            return radiance;
        };
        if !(sp2.kind == MaterialKind::Mirror && has(E, effects::MIRROR)) {
            let nee = self.next_event::<E>(lights, &sp2, -bounce.wi, rng, (Dim::LightPick2, Dim::LightPoint2), rays);
            radiance += bounce.weight * nee;
        }
        radiance
    }

    /// The packet loop: each row's selected pixels in groups of eight, each stage of a
    /// sample traced as one packet ([`packets`]). Rows run in parallel.
    fn trace_pass<const E: u16>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
    ) -> TraceStats {
        let width = camera.extent.width();
        let pass = packets::Pass { lights, camera, request };
        for_each_row(selection, rows, out, |y, mask_row, [rr, gr, br]| {
            let mut stats = TraceStats::default();
            let mut next = 0;
            loop {
                // The next (up to) eight selected pixels of the row; unused lanes repeat
                // the last one but stay inactive.
                let mut xs = [0usize; LANES];
                let mut n = 0;
                while next < width && n < LANES {
                    if mask_row.is_none_or(|m| m[next] != 0) {
                        xs[n] = next;
                        n += 1;
                    }
                    next += 1;
                }
                if n == 0 {
                    break;
                }
                for k in n..LANES {
                    xs[k] = xs[n - 1];
                }
                let active = (1u32 << n) - 1;
                let mut sums = [PixelSum::default(); LANES];
                for s in 0..request.spp {
                    let l = self.sample_group::<E>(&pass, y, &xs, active, s, &mut stats.rays);
                    for k in 0..n {
                        sums[k].add(l[k], &mut stats);
                    }
                }
                for k in 0..n {
                    let x = xs[k];
                    [rr[x], gr[x], br[x]] = sums[k].mean(request.spp);
                }
            }
            stats
        })
    }

    /// The single-ray reference loop: one pixel and sample at a time through
    /// [`Renderer::radiance`].
    fn trace_pass_single<const E: u16>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
    ) -> TraceStats {
        let width = camera.extent.width();
        let origin = Vec3::from(camera.centre);
        for_each_row(selection, rows, out, |y, mask_row, [rr, gr, br]| {
            let mut stats = TraceStats::default();
            for x in 0..width {
                if mask_row.is_some_and(|m| m[x] == 0) {
                    continue;
                }
                let pixel = (y * width + x) as u32;
                let mut sum = PixelSum::default();
                for s in 0..request.spp {
                    let rng = SampleStream::new(
                        request.seed,
                        request.eye as u32,
                        request.frame,
                        pixel,
                        request.first_sample + s,
                    );
                    let j = rng.get2(Dim::PixelJitter);
                    let dir = Vec3::from(camera.ray(x as f32 + j.x, y as f32 + j.y));
                    let l = self.radiance::<E>(lights, Ray::new(origin, dir), &rng, &mut stats.rays);
                    sum.add(l, &mut stats);
                }
                [rr[x], gr[x], br[x]] = sum.mean(request.spp);
            }
            stats
        })
    }

    fn gbuffer_pass<const E: u16>(&self, lights: &FrameLights, out: &mut GBufferBuf) {
        let camera = out.camera;
        let width = camera.extent.width();
        let origin = Vec3::from(camera.centre);
        for_each_gbuffer_row(out, |y, mut row| {
            let mut x0 = 0;
            while x0 < width {
                let lanes = (width - x0).min(LANES);
                let rays: [Ray; LANES] = core::array::from_fn(|i| {
                    let x = (x0 + i.min(lanes - 1)) as f32 + 0.5;
                    Ray::new(origin, Vec3::from(camera.ray(x, y as f32 + 0.5)))
                });
                let active = (1u32 << lanes) - 1;
                let surfaces = self.closest_packet::<E>(lights, &rays, active, packets::PRIMARY);
                for i in 0..lanes {
                    row.set(x0 + i, &self.gbuffer_texel(surfaces[i], rays[i].dir, &camera));
                }
                x0 += LANES;
            }
        });
    }

    /// The traced visibility of `camera`: per pixel, the id of the triangle its centre ray
    /// hits (a mesh triangle's index, or the mesh's length plus a moving-light triangle's
    /// index; `u32::MAX` for none), by the same packets as the traced G-buffer pass. The
    /// reference the rasterised visibility is tested against.
    pub fn trace_visibility(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        out: &mut PlaneBuf<u32>,
    ) -> Result<(), RenderError> {
        crate::kernels::frame::same_extent("visibility plane", camera.extent, out.extent())?;
        macro_rules! call {
            ($e:literal) => {
                self.visibility_pass::<$e>(lights, camera, out)
            };
        }
        crate::dispatch_effects!(self.bits, call);
        Ok(())
    }

    fn visibility_pass<const E: u16>(&self, lights: &FrameLights, camera: &CameraModel, out: &mut PlaneBuf<u32>) {
        let width = camera.extent.width();
        let origin = Vec3::from(camera.centre);
        let mesh_len = self.scene.mesh.len() as u32;
        out.as_mut_slice().par_chunks_mut(width).enumerate().for_each(|(y, row)| {
            for x0 in (0..width).step_by(LANES) {
                let lanes = (width - x0).min(LANES);
                let rays: [Ray; LANES] = core::array::from_fn(|i| {
                    let x = (x0 + i.min(lanes - 1)) as f32 + 0.5;
                    Ray::new(origin, Vec3::from(camera.ray(x, y as f32 + 0.5)))
                });
                let surfaces = self.closest_packet::<E>(lights, &rays, (1u32 << lanes) - 1, packets::PRIMARY);
                for i in 0..lanes {
                    row[x0 + i] = match surfaces[i] {
                        None => u32::MAX,
                        Some(Surface::Mesh(h)) => h.prim,
                        Some(Surface::Moving { index, .. }) => mesh_len + index,
                    };
                }
            }
        });
    }

    /// What the G-buffer stores for a pixel whose centre ray (direction `dir`, unit view
    /// depth) sees `surface`: the one definition both the traced and the rasterised pass use.
    #[inline]
    fn gbuffer_texel(&self, surface: Option<Surface>, dir: Vec3, camera: &CameraModel) -> GTexel {
        let Some(s) = surface else { return GTexel::BACKGROUND };
        // The ray has unit view depth, so t is the depth; the position is formed exactly as
        // the compact layout rebuilds it.
        let t = s.t();
        let position = [0, 1, 2].map(|c| camera.centre[c] + t * dir[c]);
        let (n, material) = match s {
            Surface::Mesh(h) => {
                let (_, shading_normal) = self.normals(&h, dir);
                (shading_normal, self.scene.mesh.material[h.prim as usize])
            }
            Surface::Moving { normal, material, .. } => {
                (if normal.dot(dir) > 0.0 { -normal } else { normal }, material)
            }
        };
        GTexel { depth: t, position, normal: n.to_array(), oct: encode_normal(n.to_array()), material }
    }
}

/// The nearest of `triangles` along `ray` nearer than `limit`: its index and the hit. The
/// one loop behind moving geometry's ray hits and its motion vectors.
#[inline]
fn nearest_moving(triangles: &[MovingTriangle], ray: &PreparedRay, limit: f32) -> Option<(u32, TriHit)> {
    let mut nearest = None;
    let mut limit = limit;
    for (index, tri) in triangles.iter().enumerate() {
        let v = tri.v;
        let verts = [v[0].x, v[0].y, v[0].z, v[1].x, v[1].y, v[1].z, v[2].x, v[2].y, v[2].z];
        if let Some(hit) = intersect_triangle(ray, &verts, limit) {
            limit = hit.t;
            nearest = Some((index as u32, hit));
        }
    }
    nearest
}

/// One pixel of a [`GBufferBuf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct GTexel {
    pub depth: f32,
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub oct: u32,
    pub material: u32,
}

impl GTexel {
    /// No surface: infinite depth, NaN position and normal, no material.
    pub const BACKGROUND: GTexel = GTexel {
        depth: f32::INFINITY,
        position: [f32::NAN; 3],
        normal: [f32::NAN; 3],
        oct: NO_NORMAL,
        material: u32::MAX,
    };
}

/// Eight texels of a row, plane by plane (see [`GRow::set_lanes`]).
pub(crate) struct GLanes {
    pub depth: F32s,
    pub position: [F32s; 3],
    pub normal: [F32s; 3],
    pub oct: [u32; LANES],
    pub material: [u32; LANES],
}

/// One row of every plane of a [`GBufferBuf`].
pub(crate) struct GRow<'a> {
    depth: &'a mut [f32],
    position: [&'a mut [f32]; 3],
    normal: [&'a mut [f32]; 3],
    oct: &'a mut [u32],
    material: &'a mut [u32],
}

impl GRow<'_> {
    /// Eight texels from `x` on (lane `i` of each plane value is pixel `x + i`).
    #[inline(always)]
    pub(crate) fn set_lanes(&mut self, x: usize, lanes: &GLanes) {
        let f = |dst: &mut [f32], v: &F32s| dst[x..x + LANES].copy_from_slice(&v.to_array());
        f(self.depth, &lanes.depth);
        for c in 0..3 {
            f(self.position[c], &lanes.position[c]);
            f(self.normal[c], &lanes.normal[c]);
        }
        self.oct[x..x + LANES].copy_from_slice(&lanes.oct);
        self.material[x..x + LANES].copy_from_slice(&lanes.material);
    }

    /// [`GRow::set_lanes`] for the compact layout's planes only (depth, octahedral normal,
    /// material).
    #[inline(always)]
    pub(crate) fn set_compact_lanes(&mut self, x: usize, lanes: &GLanes) {
        self.depth[x..x + LANES].copy_from_slice(&lanes.depth.to_array());
        self.oct[x..x + LANES].copy_from_slice(&lanes.oct);
        self.material[x..x + LANES].copy_from_slice(&lanes.material);
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, x: usize, t: &GTexel) {
        self.depth[x] = t.depth;
        for c in 0..3 {
            self.position[c][x] = t.position[c];
            self.normal[c][x] = t.normal[c];
        }
        self.oct[x] = t.oct;
        self.material[x] = t.material;
    }
}

/// Runs `row` on every row of `out` in parallel, with that row of each plane.
pub(crate) fn for_each_gbuffer_row<F>(out: &mut GBufferBuf, row: F)
where
    F: Fn(usize, GRow<'_>) + Sync + Send,
{
    let width = out.extent().width();
    let GBufferBuf { depth, position: [px, py, pz], normal: [nx, ny, nz], normal_oct, material, .. } = out;
    let rows = (
        depth.as_mut_slice().par_chunks_mut(width),
        px.as_mut_slice().par_chunks_mut(width),
        py.as_mut_slice().par_chunks_mut(width),
        pz.as_mut_slice().par_chunks_mut(width),
        nx.as_mut_slice().par_chunks_mut(width),
        ny.as_mut_slice().par_chunks_mut(width),
        nz.as_mut_slice().par_chunks_mut(width),
        normal_oct.as_mut_slice().par_chunks_mut(width),
        material.as_mut_slice().par_chunks_mut(width),
    );
    rows.into_par_iter().enumerate().for_each(|(y, (d, px, py, pz, nx, ny, nz, oct, mat))| {
        row(y, GRow { depth: d, position: [px, py, pz], normal: [nx, ny, nz], oct, material: mat })
    });
}

/// The running sum of one pixel's samples, in f64: a mean of finite f32 samples is finite,
/// but their f32 sum is not (16 samples of 5e37 overflow), which wrote inf pixels.
#[derive(Clone, Copy, Default)]
struct PixelSum(DVec3);

impl PixelSum {
    /// Adds a sample; a non-finite one counts as zero and is counted in `stats`.
    #[inline]
    fn add(&mut self, sample: Vec3, stats: &mut TraceStats) {
        stats.samples += 1;
        if sample.is_finite() {
            self.0 += sample.as_dvec3();
        } else {
            stats.non_finite += 1;
        }
    }

    /// The mean over `spp` samples.
    #[inline]
    fn mean(&self, spp: u32) -> [f32; 3] {
        (self.0 / f64::from(spp)).as_vec3().to_array()
    }
}

/// The material id stored for pixels showing a moving light.
pub const MOVING_LIGHT_MATERIAL: u32 = u32::MAX - 1;

/// Jitter-free ray through a pixel centre (what the G-buffer uses), for tests.
pub fn pixel_centre_ray(camera: &CameraModel, x: usize, y: usize) -> Ray {
    Ray::new(Vec3::from(camera.centre), Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5)))
}

/// Runs `row` on each row of `rows` in parallel, with that row's selection mask (`None`:
/// every pixel) and its three colour rows of `out`, and sums the rows' statistics: the
/// schedule the packet loop and the single-ray reference share.
fn for_each_row<F>(selection: PixelSelection<'_>, rows: std::ops::Range<usize>, out: &mut RgbBuf, row: F) -> TraceStats
where
    F: Fn(usize, Option<&[u8]>, [&mut [f32]; 3]) -> TraceStats + Sync + Send,
{
    let width = out.extent().width();
    let span = rows.start * width..rows.end * width;
    let [r, g, b] = out.slices_mut();
    (r[span.clone()].par_chunks_mut(width), g[span.clone()].par_chunks_mut(width), b[span].par_chunks_mut(width))
        .into_par_iter()
        .enumerate()
        .map(|(i, (rr, gr, br))| {
            let y = rows.start + i;
            let mask_row = match selection {
                PixelSelection::All => None,
                PixelSelection::Mask(m) => Some(m.view().row(y)),
            };
            row(y, mask_row, [rr, gr, br])
        })
        .sum()
}

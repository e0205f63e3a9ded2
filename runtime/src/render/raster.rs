//! The rasterised G-buffer pass: both eyes' visibility from the kernel rasteriser
//! (`stereotrace_kernels::raster`), then a resolve that turns each pixel's triangle into
//! the G-buffer the traced pass writes.
//!
//! The resolve intersects the pixel's own centre ray (the ray the traced pass would trace)
//! with the plane of the one triangle the raster found: the tracer's watertight shear
//! without its edge tests (the raster decided coverage) and with one reciprocal of the
//! determinant for depth and both barycentrics, eight pixels at a time with a scalar
//! reference it equals bit for bit. Its texels agree with the traced pass's within rounding,
//! not bit for bit: `tests/raster_gbuffers.rs` holds depth to 1e-4 relative and normals to
//! 1e-3 where both see the same triangle, on every scene, and checks the few texels beyond
//! that against an f64 intersection (where the traced texel is the farther from it). Which
//! triangle is seen agrees with the traced pass everywhere except depth ties and, for the
//! fixed-point rasteriser, centres within its snap of an edge (the kernel's notes say why).
//! A centre the raster covers is never a hole: one just outside the triangle (within the
//! snap) takes the plane beyond the edge.
//!
//! Cut-outs are tested per fragment for the masked triangles only, moving-light triangles
//! (not in the BVH) are rasterised after the static mesh with ids following it, and
//! nothing is allocated once the buffers have grown to a frame's needs.

use std::ops::{Add, Div, Mul, Sub};

use glam::Vec3;

use super::effects::{ALPHA_MASKS, has};
use super::estimator::Surface;
use super::gbuffer::{GLanes, GRow, GTexel, for_each_gbuffer_row};
use super::lights::FrameLights;
use super::renderer::{RenderError, Renderer};
use crate::kernels::CameraModel;
use crate::kernels::bvh::{Hit, PreparedRay, Ray, TriVerts, intersect_triangle_line, tri_verts};
use crate::kernels::gbuffer::GBufferBuf;
use crate::kernels::gbuffer::{encode_normal, encode_normals};
use crate::kernels::isa::Isa;
use crate::kernels::raster::fixed::FixedRasterizer;
use crate::kernels::raster::{AlphaTest, Body, NO_PRIM, Rasterizer, Triangles, VisibilityBuffer};
use crate::kernels::simd::{F32s, LANES, lane_offsets, prefetch, u32x8};
use crate::kernels::{Extent, FrameError};
use crate::source::{Layout, RasterPassStats};

/// How many pixels ahead of its group the resolve prefetches triangle data.
const PREFETCH_AHEAD: usize = 2 * LANES;

/// The rasterised pass's own buffers (kept between frames).
#[derive(Clone, Debug)]
pub struct RasterGBuffers {
    rasterizer: Rasterizer,
    /// The fixed-point rasteriser, used instead of `rasterizer` with [`Visibility::Fixed`].
    fixed: FixedRasterizer,
    /// Which rasteriser decides visibility.
    pub visibility_by: Visibility,
    visibility: [VisibilityBuffer; 2],
    /// This frame's moving-light triangles (ids after the mesh's).
    extra: Vec<TriVerts>,
    /// The kernel body (the SIMD one, or its scalar reference for tests).
    pub body: Body,
    /// The instruction set of the resolve's SIMD body ([`Isa::active`] unless set; the
    /// 8-lane AVX2 build where the CPU lacks the one named). Every choice gives the same bits.
    pub isa: Isa,
    /// Which planes the resolve writes: with [`Layout::Full`] every plane, as the traced
    /// pass writes them; with [`Layout::Compact`] depth, octahedral normal and material only,
    /// what the compact layout's reprojection reads (it rebuilds positions from depth), which
    /// leaves the position and normal planes as they were and saves two thirds of the
    /// resolve's writes.
    pub planes: Layout,
}

/// What a pixel's visibility says its centre ray hits ([`Renderer::visible_surface`]).
pub(super) enum Visible {
    /// No triangle covers the pixel centre.
    Nothing,
    /// This surface.
    Surface(Surface),
    /// The raster's triangle fails the tracer's test at the centre (or is no triangle).
    Undecided,
}

/// Which rasteriser finds each pixel's triangle; the resolve is the same for both.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Visibility {
    /// [`Rasterizer`]: the tracer's own triangle test wherever rounding could decide, so the
    /// same triangle as the traced pass except at exact depth ties.
    #[default]
    Exact,
    /// [`FixedRasterizer`]: snapped vertices, integer edge functions and the top-left rule,
    /// as GPUs rasterise; the traced pass's triangle except within 1/256 px of an edge or at
    /// a depth tie.
    Fixed,
}

impl RasterGBuffers {
    /// Buffers for frames of `extent` (grown as frames need).
    pub fn new(extent: Extent) -> Self {
        Self {
            rasterizer: Rasterizer::new(),
            fixed: FixedRasterizer::new(),
            visibility_by: Visibility::Exact,
            visibility: [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)],
            extra: Vec::new(),
            body: Body::Simd,
            isa: Isa::active(),
            planes: Layout::Full,
        }
    }

    /// [`RasterGBuffers::new`] that reports an allocation failure of the per-pixel buffers
    /// instead of aborting. (The binning buffers grow with the first frames, by the scene's
    /// triangles: those allocations are not fallible.)
    pub fn try_new(extent: Extent) -> Result<Self, FrameError> {
        Ok(Self {
            rasterizer: Rasterizer::new(),
            fixed: FixedRasterizer::new(),
            visibility_by: Visibility::Exact,
            visibility: [VisibilityBuffer::try_new(extent)?, VisibilityBuffer::try_new(extent)?],
            extra: Vec::new(),
            body: Body::Simd,
            isa: Isa::active(),
            planes: Layout::Full,
        })
    }

    /// Each eye's visibility of the last frame (`[left, right]`).
    pub fn visibility(&self) -> &[VisibilityBuffer; 2] {
        &self.visibility
    }

    /// Rasterise in bands of `rows` rows (default [`crate::kernels::raster::BAND_ROWS`]): the
    /// same buffers, another partition of the work (for tests and tuning).
    pub fn set_band_rows(&mut self, rows: usize) {
        self.rasterizer = Rasterizer::with_band_rows(rows);
        self.fixed = FixedRasterizer::with_band_rows(rows);
    }
}

/// The scene's cut-outs as the kernel asks for them.
struct CutOuts<'a> {
    renderer: &'a Renderer,
    mesh_len: u32,
}

impl AlphaTest for CutOuts<'_> {
    fn has_mask(&self, prim: u32) -> bool {
        let scene = &self.renderer.scene;
        prim < self.mesh_len
            && has(self.renderer.bits, ALPHA_MASKS)
            && scene.materials[scene.mesh.material[prim as usize] as usize].has_cutout()
    }

    fn opaque(&self, prim: u32, u: f32, v: f32) -> bool {
        !self.renderer.cut_out(&Hit { t: 0.0, prim, u, v })
    }
}

impl Renderer {
    /// Fills both eyes' G-buffers (`out[0]` left, `out[1]` right; their cameras must be a
    /// parallel stereo pair of one extent) by rasterisation and resolve.
    pub fn render_gbuffers_raster(
        &self,
        lights: &FrameLights,
        out: [&mut GBufferBuf; 2],
        raster: &mut RasterGBuffers,
    ) -> Result<RasterPassStats, RenderError> {
        let [left, right] = out;
        crate::kernels::frame::same_extent("right G-buffer", left.extent(), right.extent())?;
        crate::kernels::frame::same_extent("raster buffers", left.extent(), raster.visibility[0].extent())?;
        raster.extra.clear();
        raster.extra.extend(lights.moving_triangles().iter().map(|t| tri_verts(&t.v)));
        let tris = Triangles { main: bytemuck::cast_slice(&self.scene.mesh.positions), extra: &raster.extra };
        let masks = CutOuts { renderer: self, mesh_len: self.scene.mesh.len() as u32 };
        let [vl, vr] = &mut raster.visibility;
        let cameras = [&left.camera, &right.camera];
        let stats = match raster.visibility_by {
            Visibility::Exact => {
                raster.rasterizer.rasterize(tris, cameras, &masks, self.raster_near, [vl, vr], raster.body)
            }
            Visibility::Fixed => raster.fixed.rasterize(tris, cameras, &masks, self.raster_near, [vl, vr], raster.body),
        }
        .map_err(|e: FrameError| RenderError::Frame(e))?;
        let start = std::time::Instant::now();
        let [vis_left, vis_right] = &raster.visibility;
        let isa = (raster.body == Body::Simd && raster.isa.is_supported()).then_some(raster.isa);
        if raster.planes == Layout::Full {
            self.resolve::<true>(lights, vis_left, left, raster.body, isa);
            self.resolve::<true>(lights, vis_right, right, raster.body, isa);
        } else {
            self.resolve::<false>(lights, vis_left, left, raster.body, isa);
            self.resolve::<false>(lights, vis_right, right, raster.body, isa);
        }
        Ok(RasterPassStats { raster: stats, resolve: start.elapsed() })
    }

    /// Writes `out` from one eye's visibility (see the module notes): with [`Body::Simd`],
    /// eight pixels at a time where the eight see mesh triangles or nothing
    /// ([`Renderer::resolve_lanes`]), one at a time ([`Renderer::resolve_pixel`]) for moving
    /// lights and the lanes the plane hit leaves undecided; with [`Body::Scalar`], every
    /// pixel one at a time, the reference the SIMD body equals bit for bit. `ALL_PLANES` is
    /// [`Layout::Full`]: a constant, so the compact layout's resolve neither computes nor
    /// writes the planes it does not need. `isa` is the SIMD body's instruction set, one
    /// the CPU has.
    fn resolve<const ALL_PLANES: bool>(
        &self,
        lights: &FrameLights,
        vis: &VisibilityBuffer,
        out: &mut GBufferBuf,
        body: Body,
        isa: Option<Isa>,
    ) {
        let camera = out.camera;
        let width = camera.extent.width();
        let prims = vis.prim.as_slice();
        let simd_width = if body == Body::Simd { width - width % LANES } else { 0 };
        for_each_gbuffer_row(out, |y, mut row| {
            let prims = &prims[y * width..(y + 1) * width];
            #[cfg(target_arch = "x86_64")]
            if isa == Some(Isa::Avx512) {
                // SAFETY: taken only where the CPU reports the features the function enables.
                unsafe { self.resolve_row_avx512::<ALL_PLANES>(lights, &camera, prims, y, &mut row, simd_width) };
                return;
            }
            self.resolve_row::<ALL_PLANES>(lights, &camera, prims, y, &mut row, simd_width);
        });
    }

    /// [`Renderer::resolve_row`] compiled with AVX-512 (F, BW, DQ, VL), taken at run time
    /// where the CPU has it: the same eight-lane source, so the same bits, but with 32 vector
    /// registers instead of AVX2's 16 (the body spills without them) and compares into mask
    /// registers. It is not a 16-lane body: that one measured slower on Zen 4 (BENCHMARKS.md).
    ///
    /// # Safety
    /// The CPU must have the features enabled here ([`Isa::Avx512`] supported).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
    unsafe fn resolve_row_avx512<const ALL_PLANES: bool>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        prims: &[u32],
        y: usize,
        row: &mut GRow<'_>,
        simd_width: usize,
    ) {
        self.resolve_row::<ALL_PLANES>(lights, camera, prims, y, row, simd_width);
    }

    /// Row `y` of [`Renderer::resolve`]: groups of eight from column 0 to `simd_width`, one
    /// pixel at a time after it.
    #[inline(always)]
    fn resolve_row<const ALL_PLANES: bool>(
        &self,
        lights: &FrameLights,
        camera: &CameraModel,
        prims: &[u32],
        y: usize,
        row: &mut GRow<'_>,
        simd_width: usize,
    ) {
        let camera = *camera;
        let width = prims.len();
        let mesh_len = self.scene.mesh.len() as u32;
        let set = |row: &mut GRow<'_>, x: usize, texel: &GTexel| {
            if ALL_PLANES { row.set(x, texel) } else { row.set_compact(x, texel) }
        };
        for x0 in (0..simd_width).step_by(LANES) {
            if let Some(ahead) = prims.get(x0 + PREFETCH_AHEAD..x0 + PREFETCH_AHEAD + LANES) {
                self.prefetch_triangles(ahead.try_into().expect("8 lanes"), mesh_len);
            }
            let group: &[u32; LANES] = prims[x0..x0 + LANES].try_into().expect("8 lanes");
            // Which lanes see the mesh, the sky or a moving light: two vector compares,
            // not a scalar loop (which cost a tenth of the resolve's instructions).
            let ids = u32x8::from(*group);
            let is_mesh = ids.simd_lt(u32x8::splat(mesh_len));
            let background = ids.simd_eq(u32x8::splat(NO_PRIM)).to_bitmask();
            let mesh_lanes = is_mesh.to_bitmask();
            let moving = !(background | mesh_lanes) & ((1 << LANES) - 1);
            let mut scalar = moving;
            if mesh_lanes != 0 {
                // Lanes without a mesh triangle compute on a neighbour's and are
                // overwritten below.
                let stand_in = u32x8::splat(group[mesh_lanes.trailing_zeros() as usize]);
                let lanes = is_mesh.select(ids, stand_in).to_array();
                let (texels, undecided) = self.resolve_lanes::<ALL_PLANES>(&camera, x0, y, &lanes);
                if ALL_PLANES {
                    row.set_lanes(x0, &texels);
                } else {
                    row.set_compact_lanes(x0, &texels);
                }
                scalar |= undecided & mesh_lanes;
            }
            let mut m = background;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                set(row, x0 + i, &GTexel::BACKGROUND);
            }
            let mut m = scalar;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                set(row, x0 + i, &self.resolve_pixel(lights, &camera, x0 + i, y, group[i]));
            }
        }
        for x in simd_width..width {
            set(row, x, &self.resolve_pixel(lights, &camera, x, y, prims[x]));
        }
    }

    /// Starts loading the mesh data of the triangles `ahead` names (each once where
    /// neighbours share one): the resolve's triangles are scattered over arrays larger than
    /// the L2 cache, and without this each group waits on its own loads.
    #[inline(always)]
    fn prefetch_triangles(&self, ahead: &[u32; LANES], mesh_len: u32) {
        let mesh = &self.scene.mesh;
        let ids = u32x8::from(*ahead);
        let previous =
            u32x8::from(core::array::from_fn::<u32, LANES, _>(|i| if i == 0 { NO_PRIM } else { ahead[i - 1] }));
        let mut m = (ids.simd_lt(u32x8::splat(mesh_len)) & !ids.simd_eq(previous)).to_bitmask();
        while m != 0 {
            let p = ahead[m.trailing_zeros() as usize] as usize;
            m &= m - 1;
            // A triangle's three vertices span 36 bytes, so they may straddle two lines.
            let lines = |s: *const u8| {
                prefetch(s);
                prefetch(s.wrapping_add(32));
            };
            lines(mesh.positions[p].as_ptr().cast());
            if let Some(normals) = &mesh.normals {
                lines(normals[p].as_ptr().cast());
            }
            prefetch(&mesh.material[p]);
        }
    }

    /// One pixel (the scalar body of the resolve, and the path of the lanes the SIMD body
    /// leaves undecided): a mesh triangle's plane hit ([`Renderer::plane_texel`]); for
    /// moving lights, and where the plane hit does not decide, the tracer's watertight test
    /// of the centre ray on the triangle the raster found, and no hit where that misses.
    fn resolve_pixel(&self, lights: &FrameLights, camera: &CameraModel, x: usize, y: usize, prim: u32) -> GTexel {
        if let Some(texel) = self.plane_texel(camera, x, y, prim) {
            return texel;
        }
        let dir = Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5));
        let surface = match self.visible_surface(lights, prim, &Ray::new(Vec3::from(camera.centre), dir)) {
            Visible::Surface(s) => Some(s),
            Visible::Nothing | Visible::Undecided => None,
        };
        self.gbuffer_texel(surface, dir, camera)
    }

    /// What the centre ray `ray` of a pixel whose visibility is `prim` hits: the triangle
    /// `prim` (the mesh's, then this frame's moving triangles, as rasterised) under the tracer's
    /// watertight test, so the same hit as tracing `ray` wherever the raster saw the traced
    /// triangle. [`Visible::Undecided`] where the test misses that triangle or `prim` names
    /// none: the caller traces, or treats the pixel as the traced pass would.
    #[inline]
    pub(super) fn visible_surface(&self, lights: &FrameLights, prim: u32, ray: &Ray) -> Visible {
        if prim == NO_PRIM {
            return Visible::Nothing;
        }
        let mesh = &self.scene.mesh;
        let mesh_len = mesh.len() as u32;
        let verts = match mesh.positions.get(prim as usize) {
            Some(tri) => tri_verts(tri),
            None => match lights.moving_triangles().get((prim - mesh_len) as usize) {
                Some(tri) => tri_verts(&tri.v),
                None => return Visible::Undecided,
            },
        };
        let Some(hit) = PreparedRay::new(ray).and_then(|r| intersect_triangle_line(&r, &verts)) else {
            return Visible::Undecided;
        };
        let (u, v) = hit.uv();
        Visible::Surface(if prim < mesh_len {
            Surface::Mesh(Hit { t: hit.t, prim, u, v })
        } else {
            Surface::moving(lights.moving_triangles(), prim - mesh_len, hit.t, (u, v))
        })
    }

    /// The scalar reference of [`Renderer::resolve_lanes`], one pixel whose visibility is the
    /// mesh triangle `prim`: its centre ray's hit on the triangle's plane ([`centre_hit`]) and
    /// the texel [`Renderer::gbuffer_texel`] writes for it, within rounding of the traced
    /// pass's (`tests/raster_gbuffers.rs` holds the two to a tolerance). `None` where the
    /// hit does not decide: behind the camera, a ray in the triangle's plane, or normals that
    /// do not normalise; [`Renderer::resolve_pixel`] then asks the tracer's test.
    fn plane_texel(&self, camera: &CameraModel, x: usize, y: usize, prim: u32) -> Option<GTexel> {
        let mesh = &self.scene.mesh;
        let verts = mesh.positions.get(prim as usize)?.map(|v| v.to_array());
        let dir = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
        let [kx, ky, kz] = PreparedRay::for_triangles(&Ray::new(Vec3::from(camera.centre), Vec3::from(dir)))?.k;
        let pick = |v: [f32; 3]| [v[kx], v[ky], v[kz]];
        let hit = centre_hit(pick(dir), pick(camera.centre), verts.map(pick));
        let cross = cross(sub(verts[1], verts[0]), sub(verts[2], verts[0]));
        if !(hit.t > 0.0 && hit.t < f32::INFINITY) {
            return None;
        }
        let (normal, oct) = match &mesh.normals {
            Some(normals) => {
                let interpolated = hit.interpolate(normals[prim as usize].map(|v| v.to_array()));
                let len2 = dot(interpolated, interpolated);
                // Where `1 / √len2` is finite and positive.
                if !(len2 > 0.0 && len2 < f32::INFINITY && dot(cross, cross) > 0.0) {
                    return None;
                }
                let facing = dot(cross, dir) > 0.0;
                let ng = if facing { cross.map(|c| -c) } else { cross };
                let turned = if dot(interpolated, ng) < 0.0 { interpolated.map(|c| -c) } else { interpolated };
                // The octahedral code divides by the L1 norm, so it needs no unit vector:
                // encoded before normalising, it keeps the square root and the division out
                // of the chain to the compact layout's only normal plane.
                let rcp = 1.0 / len2.sqrt();
                (turned.map(|c| c * rcp), encode_normal(turned))
            }
            None => {
                let ng0 = self.geometric_normals[prim as usize].to_array();
                let normal = if dot(ng0, dir) > 0.0 { ng0.map(|c| -c) } else { ng0 };
                (normal, encode_normal(normal))
            }
        };
        Some(GTexel {
            depth: hit.t,
            position: [0, 1, 2].map(|c| camera.centre[c] + hit.t * dir[c]),
            normal,
            oct,
            material: mesh.material[prim as usize],
        })
    }

    /// Eight neighbouring pixels of row `y` from `x0` that all see mesh triangles, as eight
    /// SIMD lanes: the pixel rays, their dominant-axis permutation (as the tracer's
    /// `PreparedRay::new`), then [`Renderer::resolve_lanes_permuted`].
    #[inline(always)]
    fn resolve_lanes<const ALL_PLANES: bool>(
        &self,
        camera: &CameraModel,
        x0: usize,
        y: usize,
        prims: &[u32; LANES],
    ) -> (GLanes, u32) {
        let (o, rdx, rdy) = (camera.ray_origin_corner, camera.ray_dx, camera.ray_dy);
        let px = F32s::splat(x0 as f32) + lane_offsets() + F32s::splat(0.5);
        let py = y as f32 + 0.5;
        let dir: [F32s; 3] = from3(|i| F32s::splat(o[i]) + px * F32s::splat(rdx[i]) + F32s::splat(py * rdy[i]));
        // Dominant axis and the winding-preserving permutation, as PreparedRay::new.
        let a = map3(dir, |d| d.abs());
        let k0 = a[0].simd_ge(a[1]) & a[0].simd_ge(a[2]);
        let k1 = !k0 & a[1].simd_ge(a[2]);
        let k2 = !(k0 | k1);
        let d_z = k0.select(dir[0], k1.select(dir[1], dir[2]));
        let neg = d_z.simd_lt(F32s::ZERO);
        // One permutation for the whole group where every lane has it (nearly every group
        // of a frame: only rays near a diagonal differ), which takes the 16 per-lane selects
        // out of the arithmetic. Both are exact, so the texels do not depend on the choice.
        let kz = [k0, k1, k2].iter().position(|k| k.all());
        match kz {
            // kx = kz + 1, ky = kz + 2 (mod 3), swapped when d[kz] < 0; as constants, so the
            // permutation is a choice of registers rather than an index into a stack array.
            Some(kz) if neg.all() || neg.none() => match (kz, neg.all()) {
                (0, false) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<1, 2, 0>, prims),
                (0, true) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<2, 1, 0>, prims),
                (1, false) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<2, 0, 1>, prims),
                (1, true) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<0, 2, 1>, prims),
                (_, false) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<0, 1, 2>, prims),
                (_, true) => self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, GroupAxes::<1, 0, 2>, prims),
            },
            _ => {
                let x = (neg.select(k1, k2), neg.select(k2, k0));
                let y = (neg.select(k2, k1), neg.select(k0, k2));
                self.resolve_lanes_permuted::<ALL_PLANES, _>(camera, dir, LaneAxes { x, y, z: (k0, k1) }, prims)
            }
        }
    }

    /// The body of [`Renderer::resolve_lanes`] once each lane's axis permutation is known:
    /// each centre ray's hit on its lane's triangle's plane ([`centre_hit`]), the
    /// interpolated shading normal turned to face the ray as [`Renderer::gbuffer_texel`]
    /// turns it, and the material. The same operations in the same order as
    /// [`Renderer::plane_texel`], so each lane equals it bit for bit. Returns the texels
    /// and the lanes that reference returns `None` for, which the scalar path redoes.
    #[inline(always)]
    fn resolve_lanes_permuted<const ALL_PLANES: bool, A: AxisPick>(
        &self,
        camera: &CameraModel,
        dir: [F32s; 3],
        axes: A,
        prims: &[u32; LANES],
    ) -> (GLanes, u32) {
        let mesh = &self.scene.mesh;
        let c = map3(camera.centre, F32s::splat);
        // The eight triangles, vertex by vertex (one triangle's, splat, when all eight lanes
        // see the same one: the common case inside a triangle).
        let uniform = u32x8::from(*prims).simd_eq(u32x8::splat(prims[0])).all();
        let verts = lane_triangles(&mesh.positions, prims, uniform);
        let hit = centre_hit(axes.pick(&dir), axes.pick(&c), verts.map(|v| axes.pick(&v)));
        let cross = cross(sub(verts[1], verts[0]), sub(verts[2], verts[0]));
        let zero = F32s::ZERO;
        let decided = hit.t.simd_gt(zero) & hit.t.simd_lt(F32s::splat(f32::INFINITY));
        let (normal, oct, decided) = match &mesh.normals {
            Some(normals) => {
                let n = lane_triangles(normals, prims, uniform);
                let interpolated = hit.interpolate(n);
                let len2 = dot(interpolated, interpolated);
                let ok = len2.simd_gt(zero) & len2.simd_lt(F32s::splat(f32::INFINITY));
                let facing = dot(cross, dir).simd_gt(zero);
                let ng = map3(cross, |g| facing.select(-g, g));
                let against = dot(interpolated, ng).simd_lt(zero);
                let has_area = dot(cross, cross).simd_gt(zero);
                let turned = map3(interpolated, |n| against.select(-n, n));
                // Dead in the compact layout's resolve, which writes the octahedral code only.
                let rcp = F32s::ONE / len2.sqrt();
                (map3(turned, |n| n * rcp), encode_normals(turned), decided & ok & has_area)
            }
            None => {
                let ng0 = lane_geometric_normals(&self.geometric_normals, prims, uniform, cross);
                let facing = dot(ng0, dir).simd_gt(zero);
                let normal = map3(ng0, |n| facing.select(-n, n));
                (normal, encode_normals(normal), decided)
            }
        };
        let lanes = GLanes {
            depth: hit.t,
            // Dead in the compact layout's resolve, which does not write positions.
            position: if ALL_PLANES { from3(|i| c[i] + hit.t * dir[i]) } else { [F32s::ZERO; 3] },
            normal,
            oct,
            material: lane_materials(&mesh.material, prims, uniform),
        };
        (lanes, !decided.to_bitmask() & ((1 << LANES) - 1))
    }
}

/// Which component of a vector each lane takes as its ray's x, y and z axis (the
/// watertight test's permutation: z the ray's dominant axis).
trait AxisPick: Copy {
    /// `v`'s components in the permuted order `[x, y, z]`.
    fn pick(&self, v: &[F32s; 3]) -> [F32s; 3];
}

/// One permutation for all eight lanes: component `KX` is the x axis, `KY` y and `KZ` z.
#[derive(Clone, Copy)]
struct GroupAxes<const KX: usize, const KY: usize, const KZ: usize>;

impl<const KX: usize, const KY: usize, const KZ: usize> AxisPick for GroupAxes<KX, KY, KZ> {
    #[inline(always)]
    fn pick(&self, v: &[F32s; 3]) -> [F32s; 3] {
        [v[KX], v[KY], v[KZ]]
    }
}

/// A permutation per lane: for each of x, y and z, the masks of the lanes taking component
/// 0 and component 1 (the others take component 2).
#[derive(Clone, Copy)]
struct LaneAxes {
    x: (F32s, F32s),
    y: (F32s, F32s),
    z: (F32s, F32s),
}

impl AxisPick for LaneAxes {
    #[inline(always)]
    fn pick(&self, v: &[F32s; 3]) -> [F32s; 3] {
        let one = |(is0, is1): (F32s, F32s)| is0.select(v[0], is1.select(v[1], v[2]));
        [one(self.x), one(self.y), one(self.z)]
    }
}

/// `f32` (one pixel, the scalar reference) or [`F32s`] (eight pixels): the arithmetic of
/// [`centre_hit`], written once for both so that both round the same operations in the same
/// order.
trait Real: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    const ONE: Self;
}

impl Real for f32 {
    const ONE: f32 = 1.0;
}

impl Real for F32s {
    const ONE: F32s = F32s::ONE;
}

/// A centre ray's hit on its triangle's plane.
#[derive(Clone, Copy)]
struct CentreHit<T> {
    /// Distance along the ray (the view depth: G-buffer rays have unit view depth).
    t: T,
    /// Barycentric weights of corners 1 and 2 (outside `[0, 1]` just outside the triangle).
    b1: T,
    b2: T,
}

impl<T: Real> CentreHit<T> {
    /// Per-corner values `[corner][axis]` interpolated at the hit, as
    /// `Mesh::interpolated_normal` weights them.
    #[inline(always)]
    fn interpolate(&self, v: [[T; 3]; 3]) -> [T; 3] {
        let b0 = (T::ONE - self.b1) - self.b2;
        from3(|i| v[0][i] * b0 + v[1][i] * self.b1 + v[2][i] * self.b2)
    }
}

/// Where the ray from `origin` along `dir` meets the plane of the triangle `v`, all three in
/// the ray's axis permutation (`[x, y, z]`, z dominant): the tracer's watertight test
/// (`intersect_triangle`) without its edge tests, and with one reciprocal of the
/// determinant for `t`, `b1` and `b2` instead of three divisions. The shear's `d_x / d_z`
/// and `d_y / d_z` stay divisions, as the tracer's: a reciprocal of `d_z` there moved the
/// barycentrics of small far triangles by up to 2e-3 (measured). The vertices are sheared into the
/// ray's frame, where they lie within the triangle's size of the axis, which keeps the
/// barycentrics as accurate as the tracer's (Möller–Trumbore's products of the far origin
/// with the edges lose up to 50× more on small far triangles, measured). The rasteriser
/// already decided that the triangle covers the pixel centre, so the hit is not tested
/// against the edges: a centre within the snap of an edge (1/256 px) takes the plane just
/// beyond it, as a GPU extrapolates its attributes, rather than a hole. A ray in the plane
/// gives an infinite or NaN `t`; the callers refuse it.
#[inline(always)]
fn centre_hit<T: Real>(dir: [T; 3], origin: [T; 3], v: [[T; 3]; 3]) -> CentreHit<T> {
    let rz = T::ONE / dir[2];
    let (sx, sy) = (dir[0] / dir[2], dir[1] / dir[2]);
    let sheared = |p: [T; 3]| {
        let z = p[2] - origin[2];
        [(p[0] - origin[0]) - sx * z, (p[1] - origin[1]) - sy * z, z]
    };
    let (a, b, c) = (sheared(v[0]), sheared(v[1]), sheared(v[2]));
    let u = c[0] * b[1] - c[1] * b[0];
    let v = a[0] * c[1] - a[1] * c[0];
    let w = b[0] * a[1] - b[1] * a[0];
    let inv_det = T::ONE / (u + v + w);
    CentreHit { t: (u * (rz * a[2]) + v * (rz * b[2]) + w * (rz * c[2])) * inv_det, b1: v * inv_det, b2: w * inv_det }
}

/// `a − b`.
#[inline(always)]
fn sub<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a × b` as glam computes it.
#[inline(always)]
fn cross<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[1] * b[2] - b[1] * a[2], a[2] * b[0] - b[2] * a[0], a[0] * b[1] - b[0] * a[1]]
}

/// `a · b` as glam computes it.
#[inline(always)]
fn dot<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The eight lanes' unit geometric normals (`Mesh::geometric_normal`, `Vec3::Y` for a
/// triangle without area): one table entry splat when `uniform`, else normalised from the
/// lanes' `cross` as the table's entries were (cheaper than gathering 24 floats).
#[inline(always)]
fn lane_geometric_normals(table: &[Vec3], prims: &[u32; LANES], uniform: bool, cross: [F32s; 3]) -> [F32s; 3] {
    if uniform {
        let n = table[prims[0] as usize];
        return [F32s::splat(n.x), F32s::splat(n.y), F32s::splat(n.z)];
    }
    let (n, ok) = try_normalize(cross);
    [ok.select(n[0], F32s::ZERO), ok.select(n[1], F32s::ONE), ok.select(n[2], F32s::ZERO)]
}

/// Per-vertex data of the eight lanes' triangles as `[vertex][axis]` lanes: splat when
/// `uniform` (every lane's triangle is `prims[0]`), else gathered: each lane's first eight
/// floats as one vector load, turned into eight `[vertex][axis]` vectors by one 8×8
/// transpose, and the ninth (`v2.z`) lane by lane. (Writing the 72 floats one by one into
/// arrays and loading those was the resolve's hottest line: every load waited on eight
/// narrower stores.)
#[inline(always)]
fn lane_triangles(data: &[[Vec3; 3]], prims: &[u32; LANES], uniform: bool) -> [[F32s; 3]; 3] {
    if uniform {
        let t = &data[prims[0] as usize];
        return from3(|v| [F32s::splat(t[v].x), F32s::splat(t[v].y), F32s::splat(t[v].z)]);
    }
    let floats = |lane: usize| -> &[f32; 9] { bytemuck::cast_ref(&data[prims[lane] as usize]) };
    let rows: [F32s; 8] = core::array::from_fn(|lane| {
        F32s::from(<[f32; 8]>::try_from(&floats(lane)[..8]).expect("eight of nine floats"))
    });
    let [x0, y0, z0, x1, y1, z1, x2, y2] = F32s::transpose(rows);
    let z2 = F32s::from(core::array::from_fn::<f32, LANES, _>(|lane| floats(lane)[8]));
    [[x0, y0, z0], [x1, y1, z1], [x2, y2, z2]]
}

/// The eight lanes' materials.
#[inline(always)]
fn lane_materials(material: &[u32], prims: &[u32; LANES], uniform: bool) -> [u32; LANES] {
    if uniform {
        return [material[prims[0] as usize]; LANES];
    }
    let mut out = [0; LANES];
    for (m, &p) in out.iter_mut().zip(prims) {
        *m = material[p as usize];
    }
    out
}

/// `[f(0), f(1), f(2)]`, inlined (`core::array::from_fn` and `map` are not always, and
/// here they sit in the resolve's innermost loop).
#[inline(always)]
fn from3<T>(f: impl Fn(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// `a.map(f)` for three elements, inlined (see [`from3`]).
#[inline(always)]
fn map3<T, U>(a: [T; 3], f: impl Fn(T) -> U) -> [U; 3] {
    let [x, y, z] = a;
    [f(x), f(y), f(z)]
}

/// glam's `try_normalize`, lane by lane: `v · (1 / √(v·v))` where that reciprocal is finite
/// and positive; the mask says where.
#[inline(always)]
fn try_normalize(v: [F32s; 3]) -> ([F32s; 3], F32s) {
    let rcp = F32s::ONE / dot(v, v).sqrt();
    let ok = rcp.simd_lt(F32s::splat(f32::INFINITY)) & rcp.simd_gt(F32s::ZERO);
    (map3(v, |c| c * rcp), ok)
}

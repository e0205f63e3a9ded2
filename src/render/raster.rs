//! The rasterised G-buffer pass: both eyes' visibility from the kernel rasteriser
//! (`stereotrace_kernels::raster`), then a resolve that turns each pixel's triangle into
//! the G-buffer the traced pass writes.
//!
//! The resolve intersects the pixel's own centre ray (the ray the traced pass would trace)
//! with the one triangle the raster found, with the same watertight test, and writes the
//! texel through the same function as the traced pass ([`Renderer::gbuffer_texel`]): where
//! both see the same triangle, depth, position, normals and material are identical bit for
//! bit. Which triangle is seen agrees with the traced pass everywhere except exact depth
//! ties (the kernel's notes say why); `tests/raster.rs` checks both on every scene.
//!
//! Cut-outs are tested per fragment for the masked triangles only, moving-light triangles
//! (not in the BVH) are rasterised after the static mesh with ids following it, and
//! nothing is allocated once the buffers have grown to a frame's needs.

use glam::Vec3;

use super::effects::{ALPHA_MASKS, has};
use super::lights::FrameLights;
use super::{GBufferBuf, RenderError, Renderer, Surface, for_each_gbuffer_row};
use crate::kernels::bvh::{Hit, PreparedRay, Ray, TriVerts, intersect_triangle};
use crate::kernels::raster::{AlphaTest, Body, NO_PRIM, RasterStats, Rasterizer, Triangles, VisibilityBuffer};
use crate::kernels::{Extent, FrameError};

/// The rasterised pass's own buffers (kept between frames).
#[derive(Clone, Debug)]
pub struct RasterGBuffers {
    rasterizer: Rasterizer,
    visibility: [VisibilityBuffer; 2],
    /// This frame's moving-light triangles (ids after the mesh's).
    extra: Vec<TriVerts>,
    /// The kernel body (the SIMD one, or its scalar reference for tests).
    pub body: Body,
}

impl RasterGBuffers {
    pub fn new(extent: Extent) -> Self {
        Self {
            rasterizer: Rasterizer::new(),
            visibility: [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)],
            extra: Vec::new(),
            body: Body::Simd,
        }
    }

    /// Each eye's visibility of the last frame (`[left, right]`).
    pub fn visibility(&self) -> &[VisibilityBuffer; 2] {
        &self.visibility
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
    ) -> Result<RasterStats, RenderError> {
        let [left, right] = out;
        crate::kernels::frame::same_extent("right G-buffer", left.extent(), right.extent())?;
        crate::kernels::frame::same_extent("raster buffers", left.extent(), raster.visibility[0].extent())?;
        raster.extra.clear();
        raster.extra.extend(lights.moving_triangles().iter().map(|t| {
            let [a, b, c] = t.v;
            [a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]
        }));
        let tris = Triangles { main: bytemuck::cast_slice(&self.scene.mesh.positions), extra: &raster.extra };
        let masks = CutOuts { renderer: self, mesh_len: self.scene.mesh.len() as u32 };
        let [vl, vr] = &mut raster.visibility;
        let stats = raster
            .rasterizer
            .rasterize(tris, [&left.camera, &right.camera], &masks, self.raster_near, [vl, vr], raster.body)
            .map_err(|e: FrameError| RenderError::Frame(e))?;
        self.resolve(lights, &raster.visibility[0], left, &tris);
        self.resolve(lights, &raster.visibility[1], right, &tris);
        Ok(stats)
    }

    /// Writes `out` from one eye's visibility (see the module notes).
    fn resolve(&self, lights: &FrameLights, vis: &VisibilityBuffer, out: &mut GBufferBuf, tris: &Triangles<'_>) {
        let camera = out.camera;
        let width = camera.extent.width();
        let origin = Vec3::from(camera.centre);
        let mesh_len = self.scene.mesh.len() as u32;
        let prims = vis.prim.as_slice();
        for_each_gbuffer_row(out, |y, mut row| {
            for x in 0..width {
                let prim = prims[y * width + x];
                let dir = Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5));
                let surface = (prim != NO_PRIM).then(|| {
                    let r = PreparedRay::new(&Ray::new(origin, dir))?;
                    let hit = intersect_triangle(&r, tris.get(prim), f32::INFINITY)?;
                    let (u, v) = hit.uv();
                    Some(if prim < mesh_len {
                        Surface::Mesh(Hit { t: hit.t, prim, u, v })
                    } else {
                        let tri = &lights.moving_triangles()[(prim - mesh_len) as usize];
                        let normal = (tri.v[1] - tri.v[0]).cross(tri.v[2] - tri.v[0]).normalize_or_zero();
                        Surface::MovingLight { t: hit.t, normal, radiance: tri.radiance, index: prim - mesh_len }
                    })
                });
                row.set(x, &self.gbuffer_texel(surface.flatten(), dir, &camera));
            }
        });
    }
}

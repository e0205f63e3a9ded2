//! The traced G-buffer pass, traced visibility (the rasteriser's reference), motion vectors,
//! and the one texel definition both G-buffer passes write through.

use glam::Vec3;
use rayon::prelude::*;

use crate::kernels::bvh::{PreparedRay, Ray};
use crate::kernels::gbuffer::{GBufferBuf, NO_NORMAL, encode_normal};
use crate::kernels::simd::{F32s, LANES};
use crate::kernels::{CameraModel, PlaneBuf};

use super::estimator::{Surface, nearest_moving};
use super::lights::FrameLights;
use super::packets;
use super::renderer::{RenderError, Renderer};

/// Pixels of a material row [`Renderer::write_motion`] tests for moving materials at once.
const MOTION_SCAN: usize = 32;

/// The barycentric coordinates `(u, v)` (the weights of `v[1]` and `v[2]`) of `point`
/// projected on the plane of the triangle `v`; `None` for a degenerate triangle.
fn barycentric(point: Vec3, v: &[Vec3; 3]) -> Option<(f32, f32)> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let n = e1.cross(e2);
    let inv = 1.0 / n.length_squared();
    if !inv.is_finite() {
        return None;
    }
    let p = point - v[0];
    Some((p.dot(e2.cross(n)) * inv, p.dot(n.cross(e1)) * inv))
}

impl Renderer {
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
    /// motion of the moving light or object seen at the pixel (the point of the triangle it
    /// sees now, less the same barycentric point of it then). A pixel sees moving geometry
    /// when its material is one that moving triangles carry and a moving triangle lies at its
    /// depth (not behind a static surface of the same material). Nothing is written for a
    /// scene without moving geometry: its planes stay as allocated, zero.
    ///
    /// `seen`, the rasteriser's visibility of `out` (triangle ids: the mesh's, then this
    /// frame's moving triangles), names the moving triangle a pixel sees, as a GPU's
    /// fragment knows its triangle: the pixel's surface point (rebuilt from its depth) is
    /// taken on that triangle's plane, with no ray. Elsewhere (no `seen`, or a static
    /// triangle of a moving material) the centre ray searches every moving triangle.
    pub fn write_motion(&self, lights: &FrameLights, out: &mut GBufferBuf, seen: Option<&[u32]>) {
        let Some([mx, my, mz]) = &mut out.motion else { return };
        let triangles = lights.moving_triangles();
        if triangles.is_empty() {
            return;
        }
        let camera = &out.camera;
        let width = out.material.extent().width();
        let moving = lights.moving_materials();
        let mesh_len = self.scene.mesh.len();
        // Rows in parallel: a moving object can cover a large share of the frame.
        let rows = (
            mx.as_mut_slice().par_chunks_mut(width),
            my.as_mut_slice().par_chunks_mut(width),
            mz.as_mut_slice().par_chunks_mut(width),
            out.material.as_slice().par_chunks(width),
            out.depth.as_slice().par_chunks(width),
        );
        rows.into_par_iter().enumerate().for_each(|(y, (mx, my, mz, material, depth))| {
            // Most rows show nothing that moves and were still last time too: reading them
            // to check costs less than writing three cold rows.
            for m in [&mut *mx, &mut *my, &mut *mz] {
                if m.iter().fold(0u32, |bits, v| bits | v.to_bits()) != 0 {
                    m.fill(0.0);
                }
            }
            let seen = seen.map(|s| &s[y * width..(y + 1) * width]);
            for (c, chunk) in material.chunks(MOTION_SCAN).enumerate() {
                // Whole chunks at a time (compares without a branch per pixel): the moving
                // materials are a few pixels of most rows.
                let shows_moving = moving.iter().any(|&id| chunk.iter().fold(false, |any, &m| any | (m == id)));
                if !shows_moving {
                    continue;
                }
                for (i, _) in chunk.iter().enumerate().filter(|(_, m)| moving.contains(m)) {
                    let x = c * MOTION_SCAN + i;
                    let raster_triangle = seen.and_then(|s| triangles.get((s[x] as usize).checked_sub(mesh_len)?));
                    let weights = match raster_triangle {
                        // The raster's triangle: the pixel's surface point lies on it.
                        Some(tri) => {
                            let point = Vec3::from(camera.unproject_pixel(x, y, depth[x]));
                            barycentric(point, &tri.v).map(|uv| (tri, uv))
                        }
                        None => {
                            let dir = Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5));
                            let Some(ray) = PreparedRay::new(&Ray::new(Vec3::from(camera.centre), dir)) else {
                                continue;
                            };
                            // The ray has unit view depth, so the pixel's surface lies at
                            // t = depth; a moving triangle up to a rounding margin beyond it is
                            // the one the pixel sees.
                            let limit = depth[x] * (1.0 + 1e-5) + f32::MIN_POSITIVE;
                            nearest_moving(lights, &ray, limit)
                                .map(|(index, hit)| (&triangles[index as usize], hit.uv()))
                        }
                    };
                    if let Some((tri, (u, v))) = weights {
                        let moved = |k: usize| tri.v[k] - tri.previous[k];
                        let m = (1.0 - u - v) * moved(0) + u * moved(1) + v * moved(2);
                        (mx[x], my[x], mz[x]) = (m[0], m[1], m[2]);
                    }
                }
            }
        });
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
    /// depth) sees `surface`: the traced pass's definition, and the rasterised pass's for moving
    /// lights and the pixels its plane hit leaves undecided (its mesh texels follow the same
    /// rules from the plane hit, `Renderer::plane_texel`).
    #[inline]
    pub(super) fn gbuffer_texel(&self, surface: Option<Surface>, dir: Vec3, camera: &CameraModel) -> GTexel {
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

    /// [`GRow::set`] for the compact layout's planes only (see [`GRow::set_compact_lanes`]).
    #[inline(always)]
    pub(crate) fn set_compact(&mut self, x: usize, t: &GTexel) {
        self.depth[x] = t.depth;
        self.oct[x] = t.oct;
        self.material[x] = t.material;
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

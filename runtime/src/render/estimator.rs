//! The paper's estimator (one sample: a primary ray, one secondary ray, two shadow rays) and
//! the geometry queries under it: what a ray hits (the static mesh, alpha cut-outs, the
//! frame's moving triangles), how a hit is shaded, and next-event estimation.

use glam::Vec3;

use crate::kernels::bvh::{Hit, PreparedRay, Ray, TriHit, intersect_triangles_lanes};
use crate::kernels::simd::LANES;
use crate::scene::MaterialKind;

use super::bsdf::{self, ShadingPoint};
use super::effects::{self, ALPHA_MASKS, MOVING_GEOMETRY, TEXTURES, has};
use super::lights::{FrameLights, MOVING_LIGHT_MATERIAL, MovingTriangle};
use super::renderer::Renderer;
use super::rng::{Dim, SampleStream};
use super::spawn;

/// What the primary or secondary ray hit.
#[derive(Clone, Copy, Debug)]
pub(super) enum Surface {
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
    pub(super) fn moving(triangles: &[MovingTriangle], index: u32, t: f32, (u, v): (f32, f32)) -> Self {
        let tri = &triangles[index as usize];
        let normal = (tri.v[1] - tri.v[0]).cross(tri.v[2] - tri.v[0]).normalize_or_zero();
        Surface::Moving { t, u, v, normal, radiance: tri.radiance, material: tri.material, index }
    }

    pub(super) fn t(&self) -> f32 {
        match self {
            Surface::Mesh(h) => h.t,
            Surface::Moving { t, .. } => *t,
        }
    }
}

impl Renderer {
    // ---- geometry queries ----------------------------------------------------------------

    /// Whether the triangle hit at `h` is cut away by its material's opacity (alpha test at
    /// 0.5: cut-outs are binary masks such as leaves).
    #[inline]
    pub(super) fn cut_out(&self, h: &Hit) -> bool {
        let m = &self.scene.materials[self.scene.mesh.material[h.prim as usize] as usize];
        m.has_cutout() && m.coverage_at(&self.scene.textures, self.scene.mesh.uv(h.prim as usize, h.u, h.v)) < 0.5
    }

    /// Closest hit of the static mesh, skipping cut-out surfaces.
    #[inline]
    pub(super) fn closest_mesh<const E: u16>(&self, mut ray: Ray) -> Option<Hit> {
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
    pub(super) fn closest_moving(lights: &FrameLights, ray: &Ray, tmax: f32) -> Option<Surface> {
        if !lights.may_hit_moving(ray.origin, ray.dir.normalize_or_zero()) {
            return None;
        }
        let prepared = PreparedRay::new(&Ray { tmax, ..*ray })?;
        let (index, hit) = nearest_moving(lights, &prepared, tmax)?;
        Some(Surface::moving(lights.moving_triangles(), index, hit.t, hit.uv()))
    }

    /// Shading information where a ray along `dir` meets `surface`, or `None` for a moving
    /// light (an emitter only: it reflects nothing).
    #[inline(always)]
    pub(super) fn shade_surface<const E: u16>(
        &self,
        lights: &FrameLights,
        surface: &Surface,
        dir: Vec3,
    ) -> Option<ShadingPoint> {
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
    pub(super) fn closest<const E: u16>(&self, lights: &FrameLights, ray: Ray) -> Option<Surface> {
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
    pub(super) fn occluded<const E: u16>(&self, lights: &FrameLights, ray: Ray) -> bool {
        // With cut-outs, an any-hit search that skips the holes: the closest non-hole hit
        // is found exactly when some non-hole hit is (but for a hole and a surface at the
        // very same distance), and the search can stop at the first one.
        let blocked = if has(E, ALPHA_MASKS) {
            self.bvh.occluded_where(&ray, |prim, u, v| !self.cut_out(&Hit { t: 0.0, prim, u, v }))
        } else {
            self.bvh.occluded(&ray)
        };
        blocked || (has(E, MOVING_GEOMETRY) && Self::closest_moving(lights, &ray, ray.tmax).is_some())
    }

    /// Shading information at a mesh hit seen along `dir`.
    #[inline(always)]
    pub(super) fn shade<const E: u16>(&self, h: &Hit, dir: Vec3) -> ShadingPoint {
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
    pub(super) fn normals(&self, h: &Hit, dir: Vec3) -> (Vec3, Vec3) {
        let tri = h.prim as usize;
        let geometric = self.geometric_normals[tri];
        let ng = if geometric.dot(dir) > 0.0 { -geometric } else { geometric };
        // Mesh::shading_normal, with the stored geometric normal.
        let mut ns = self.scene.mesh.interpolated_normal(tri, h.u, h.v).unwrap_or(geometric);
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        (ng, ns)
    }

    /// Emitted radiance of a surface towards `-dir` (one-sided emitters).
    #[inline]
    pub(super) fn emitted(&self, s: &Surface, dir: Vec3) -> Vec3 {
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
    pub(super) fn escaped(&self, dir: Vec3) -> Vec3 {
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
    pub(super) fn light_sample<const E: u16>(
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
    pub(super) fn next_event<const E: u16>(
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
    pub(super) fn radiance<const E: u16>(
        &self,
        lights: &FrameLights,
        ray: Ray,
        rng: &SampleStream,
        rays: &mut u64,
    ) -> Vec3 {
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
}

/// The nearest of the frame's moving triangles along `ray` nearer than `limit`: its index
/// and the hit. The one search behind moving geometry's ray hits and its motion vectors. It
/// tests eight triangles at a time ([`FrameLights::moving_blocks`]); each lane's test equals
/// the scalar one bit for bit, and a block keeps its lowest lane on equal `t`, so the
/// answer is [`nearest_moving_scalar`]'s, the reference one triangle at a time.
#[inline]
pub(super) fn nearest_moving(lights: &FrameLights, ray: &PreparedRay, limit: f32) -> Option<(u32, TriHit)> {
    let count = lights.moving_triangles().len();
    let mut nearest = None;
    let mut limit = limit;
    for (b, block) in lights.moving_blocks().iter().enumerate() {
        let lanes = (count - b * LANES).min(LANES);
        // A later block must be strictly nearer, as a later triangle must in the reference.
        if let Some((lane, hit)) = intersect_triangles_lanes(ray, block, (1 << lanes) - 1, limit) {
            limit = hit.t;
            nearest = Some(((b * LANES) as u32 + lane, hit));
        }
    }
    nearest
}

/// The scalar reference of [`nearest_moving`]: each triangle in turn, a hit replacing the
/// one kept only when strictly nearer.
#[cfg(test)]
fn nearest_moving_scalar(triangles: &[MovingTriangle], ray: &PreparedRay, limit: f32) -> Option<(u32, TriHit)> {
    let mut nearest = None;
    let mut limit = limit;
    for (index, tri) in triangles.iter().enumerate() {
        if let Some(hit) = crate::kernels::bvh::intersect_triangle(ray, &crate::kernels::bvh::tri_verts(&tri.v), limit)
        {
            limit = hit.t;
            nearest = Some((index as u32, hit));
        }
    }
    nearest
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::kernels::synth::Rng;
    use crate::scene::light::icosphere;

    /// A point of the cube `[−scale, scale]³`.
    fn point(rng: &mut Rng, scale: f32) -> Vec3 {
        Vec3::new(rng.range(-scale, scale), rng.range(-scale, scale), rng.range(-scale, scale))
    }

    /// The blocked search against the one-at-a-time reference, on an icosphere light (80
    /// triangles: ten full blocks) with duplicated triangles (equal `t`: the lower index must
    /// win), a partial last block, and rays from everywhere: through the sphere, grazing it,
    /// along its triangles' edges and vertices, with limits before and after the hits.
    #[test]
    fn blocked_moving_search_equals_the_scalar_reference() {
        let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
        let mut tris: Vec<[Vec3; 3]> = icosphere(1.0, 1);
        // Duplicates of earlier triangles, one in another block and one in the same block.
        tris.push(tris[3]);
        tris.insert(9, tris[12]);
        for _ in 0..5 {
            let c = point(&mut rng, 2.0);
            tris.push([c, c + point(&mut rng, 0.5), c + point(&mut rng, 0.5)]);
        }
        assert_ne!(tris.len() % LANES, 0, "a partial last block");
        let moving = |v: [Vec3; 3]| MovingTriangle { v, previous: v, radiance: Vec3::ONE, material: 0 };
        let lights = FrameLights::with_moving_triangles(tris.iter().copied().map(moving).collect());
        let (mut hits, mut rays) = (0, 0);
        for i in 0..20_000 {
            let origin = point(&mut rng, 4.0);
            // Aim at a random point near the sphere, or exactly at a vertex or an edge's middle.
            let t = &tris[i % tris.len()];
            let aim = match i % 4 {
                0 => t[0],
                1 => 0.5 * (t[0] + t[1]),
                _ => point(&mut rng, 1.3),
            };
            let Some(ray) = PreparedRay::new(&Ray::new(origin, aim - origin)) else { continue };
            let limit = if i % 3 == 0 { rng.range(0.2, 2.2) } else { f32::INFINITY };
            let blocked = nearest_moving(&lights, &ray, limit);
            let scalar = nearest_moving_scalar(lights.moving_triangles(), &ray, limit);
            let bits = |h: Option<(u32, TriHit)>| {
                h.map(|(index, hit)| (index, hit.t.to_bits(), hit.e.map(f32::to_bits), hit.det.to_bits()))
            };
            assert_eq!(bits(blocked), bits(scalar), "ray {i} from {origin} towards {aim}, limit {limit}");
            hits += usize::from(scalar.is_some());
            rays += 1;
        }
        assert!(hits > rays / 4 && hits < rays, "{hits} hits of {rays} rays: the rays must test both outcomes");
    }
}

//! The per-frame light table used by next-event estimation.
//!
//! Every light of the frame becomes one record: each emissive triangle (static, or of a
//! moving light placed at this frame), each point light, the sun, the environment. One
//! record is chosen per shadow ray with probability proportional to its approximate power
//! (distant lights as the power they deliver through a disc of the scene's radius), then a
//! point on it. Moving area lights and moving objects also keep their triangles for ray
//! hits, since they are not part of the static BVH.
//!
//! The table is rebuilt in place each frame: vectors are cleared and refilled, so after the
//! first frame no allocation happens (the real-time runtime relies on it).

use glam::{Vec2, Vec3};

use super::spawn::{ShadowTarget, barycentric_point};
use crate::kernels::bvh::{TriVerts, TriangleLanes, tri_verts};
use crate::kernels::simd::LANES;
use crate::scene::light::sample_triangle;
use crate::scene::sampling::luminance;
use crate::scene::{Environment, MovingShape, Scene, SpotCone, SunLight};

/// The material id stored for pixels showing a moving light.
pub const MOVING_LIGHT_MATERIAL: u32 = u32::MAX - 1;

/// One light of the frame.
#[derive(Clone, Copy, Debug)]
pub enum LightRecord {
    /// A one-sided emissive triangle (emits on the side of `(v1 − v0) × (v2 − v0)`).
    Triangle {
        /// The vertices.
        v: [Vec3; 3],
        /// Unit normal of the emitting side.
        normal: Vec3,
        /// Area in square metres.
        area: f32,
        /// Emitted radiance.
        radiance: Vec3,
    },
    /// A point light.
    Point {
        /// Its position.
        position: Vec3,
        /// Radiant intensity (W/sr per channel), on the axis for a spot light.
        intensity: Vec3,
        /// A spot light's cone.
        spot: Option<SpotCone>,
    },
    /// A sun: a distant disc of a given angular radius.
    Sun(SunLight),
    /// The scene's environment (constant, analytic sky or HDR map).
    Environment,
}

/// A sampled light direction seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (`inf` for the sun and the environment).
    pub distance: f32,
    /// Incident radiance (or intensity / d² for a point light).
    pub radiance: Vec3,
    /// Solid-angle density of the direction times the selection probability (for point
    /// lights: just the selection probability).
    pub pdf: f32,
    /// Where the shadow ray has to reach.
    pub target: ShadowTarget,
}

/// A triangle placed for this frame (of a moving area light or a moving object), for ray
/// hits.
#[derive(Clone, Copy, Debug)]
pub struct MovingTriangle {
    /// The vertices at this frame.
    pub v: [Vec3; 3],
    /// The vertices at the table's previous frame (the same as `v` on the first): where a
    /// point of the triangle was, for motion vectors.
    pub previous: [Vec3; 3],
    /// Emitted radiance (zero for an object's triangle).
    pub radiance: Vec3,
    /// The material a G-buffer records: [`MOVING_LIGHT_MATERIAL`] for a light's triangle, the
    /// scene material that shades it for an object's.
    pub material: u32,
}

/// The light table of one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameLights {
    records: Vec<LightRecord>,
    /// Cumulative selection probabilities (last = 1).
    cdf: Vec<f32>,
    pmf: Vec<f32>,
    moving_triangles: Vec<MovingTriangle>,
    /// `moving_triangles` eight at a time in SIMD lanes (the last block padded), for
    /// [`super::estimator::nearest_moving`]: an icosphere light is 80 triangles that every
    /// ray towards it tests.
    moving_blocks: Vec<TriangleLanes>,
    /// The distinct materials of `moving_triangles` (a handful), for finding the pixels that
    /// may see moving geometry without scanning every triangle per pixel.
    moving_materials: Vec<u32>,
    /// Bounding sphere (centre, radius²) of all moving triangles, for a cheap reject.
    moving_bound: (Vec3, f32),
    /// The frame of the last [`FrameLights::update`], from which moving lights' motion is
    /// measured.
    last_frame: Option<u32>,
}

impl FrameLights {
    /// The table of `scene` at `frame`.
    pub fn new(scene: &Scene, frame: u32) -> Self {
        let mut lights = Self::default();
        lights.update(scene, frame);
        lights
    }

    /// Rebuilds the table for `frame`, reusing the vectors' capacity. Moving lights' motion
    /// ([`MovingTriangle::previous`]) is measured from the frame of the previous call.
    pub fn update(&mut self, scene: &Scene, frame: u32) {
        self.records.clear();
        self.moving_triangles.clear();
        self.moving_materials.clear();
        let mesh = &scene.mesh;
        for &tri in &scene.lights.area.triangles {
            let emission = scene.materials[mesh.material[tri as usize] as usize].emission;
            self.push_triangle(mesh.positions[tri as usize], emission);
        }
        for p in &scene.lights.points {
            self.records.push(LightRecord::Point { position: p.position, intensity: p.intensity, spot: p.spot });
        }
        let previous_frame = self.last_frame.unwrap_or(frame);
        self.last_frame = Some(frame);
        for m in &scene.lights.moving {
            let transform = m.path.transform(frame as f32);
            let previous = m.path.transform(previous_frame as f32);
            match &m.shape {
                MovingShape::Point { intensity } => self.records.push(LightRecord::Point {
                    position: transform.translation.into(),
                    intensity: *intensity,
                    spot: None,
                }),
                MovingShape::Area { triangles, radiance } => {
                    for t in triangles {
                        let v = t.map(|p| transform.transform_point3(p));
                        self.push_triangle(v, *radiance);
                        let previous = t.map(|p| previous.transform_point3(p));
                        let material = MOVING_LIGHT_MATERIAL;
                        self.moving_triangles.push(MovingTriangle { v, previous, radiance: *radiance, material });
                    }
                }
            }
        }
        for o in &scene.moving_objects {
            let (transform, previous) = (o.path.transform(frame as f32), o.path.transform(previous_frame as f32));
            for t in &o.triangles {
                self.moving_triangles.push(MovingTriangle {
                    v: t.map(|p| transform.transform_point3(p)),
                    previous: t.map(|p| previous.transform_point3(p)),
                    radiance: Vec3::ZERO,
                    material: o.material,
                });
            }
        }
        if let Some(sun) = scene.lights.sun {
            self.records.push(LightRecord::Sun(sun));
        }
        if scene.lights.environment.is_some() {
            self.records.push(LightRecord::Environment);
        }
        self.fill_moving_blocks();
        for t in &self.moving_triangles {
            if !self.moving_materials.contains(&t.material) {
                self.moving_materials.push(t.material);
            }
        }
        self.moving_bound = bound(&self.moving_triangles);
        self.build_distribution(scene);
    }

    /// `moving_blocks` from `moving_triangles` (reusing the vector's capacity).
    fn fill_moving_blocks(&mut self) {
        self.moving_blocks.clear();
        for chunk in self.moving_triangles.chunks(LANES) {
            let mut verts: [TriVerts; LANES] = [[0.0; 9]; LANES];
            for (dst, t) in verts.iter_mut().zip(chunk) {
                *dst = tri_verts(&t.v);
            }
            self.moving_blocks.push(TriangleLanes::new(&verts[..chunk.len()]));
        }
    }

    /// A table holding only `triangles` as moving geometry (for tests of the searches).
    #[cfg(test)]
    pub(super) fn with_moving_triangles(triangles: Vec<MovingTriangle>) -> Self {
        let mut lights = Self { moving_triangles: triangles, ..Self::default() };
        lights.fill_moving_blocks();
        lights.moving_bound = bound(&lights.moving_triangles);
        lights
    }

    fn push_triangle(&mut self, v: [Vec3; 3], radiance: Vec3) {
        let cross = (v[1] - v[0]).cross(v[2] - v[0]);
        let area = 0.5 * cross.length();
        if area > 0.0 && area.is_finite() {
            self.records.push(LightRecord::Triangle { v, normal: cross / (2.0 * area), area, radiance });
        }
    }

    /// Selection probabilities proportional to power. Powers are formed and summed in f64:
    /// in f32, bright lights (an intensity of 3e37, a large emitter with `Ke` 1e36) overflow
    /// to inf and the probabilities become inf/inf = NaN, which picked no light at all.
    fn build_distribution(&mut self, scene: &Scene) {
        use std::f64::consts::PI;
        let lum = |v: Vec3| f64::from(luminance(v.max(Vec3::ZERO)));
        let radius = 0.5 * f64::from(scene.bounds().extent().length()).max(1e-3);
        let disc = PI * radius * radius;
        let env_power = scene.lights.environment.as_ref().map_or(0.0, |e| lum(e.mean_radiance()) * PI * disc);
        let power = |r: &LightRecord| match r {
            LightRecord::Triangle { area, radiance, .. } => PI * f64::from(*area) * lum(*radiance),
            LightRecord::Point { intensity, .. } => 4.0 * PI * lum(*intensity),
            LightRecord::Sun(s) => lum(s.irradiance) * disc,
            LightRecord::Environment => env_power,
        };
        let total: f64 = self.records.iter().map(power).sum();
        let n = self.records.len().max(1) as f64;
        self.pmf.clear();
        self.cdf.clear();
        let mut acc = 0.0f64;
        for r in &self.records {
            // Every light keeps some probability, so none is starved by a bright neighbour.
            let p = if total > 0.0 && total.is_finite() { 0.9 * (power(r) / total) + 0.1 / n } else { 1.0 / n };
            acc += p;
            self.pmf.push(p as f32);
            self.cdf.push(acc as f32);
        }
        if let Some(last) = self.cdf.last_mut() {
            *last = 1.0;
        }
    }

    /// Number of light records.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether the frame has no light at all.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Triangles of moving area lights and moving objects at this frame.
    pub fn moving_triangles(&self) -> &[MovingTriangle] {
        &self.moving_triangles
    }

    /// [`FrameLights::moving_triangles`] in blocks of eight (the last one padded).
    pub fn moving_blocks(&self) -> &[TriangleLanes] {
        &self.moving_blocks
    }

    /// The distinct materials the moving triangles carry ([`MovingTriangle::material`]).
    pub fn moving_materials(&self) -> &[u32] {
        &self.moving_materials
    }

    /// Whether a ray from `origin` along unit `dir` can reach the moving lights at all.
    #[inline]
    pub fn may_hit_moving(&self, origin: Vec3, dir: Vec3) -> bool {
        if self.moving_triangles.is_empty() {
            return false;
        }
        let (c, r2) = self.moving_bound;
        let oc = c - origin;
        let along = oc.dot(dir);
        let perp2 = oc.length_squared() - along * along;
        perp2 <= r2 && (along >= 0.0 || oc.length_squared() <= r2)
    }

    /// Samples a light as seen from `p`: `u_pick` chooses the record, `u` the point.
    pub fn sample(&self, environment: Option<&Environment>, p: Vec3, u_pick: f32, u: Vec2) -> Option<LightSample> {
        if self.records.is_empty() {
            return None;
        }
        let i = self.cdf.partition_point(|&c| c <= u_pick).min(self.records.len() - 1);
        let pick = self.pmf[i];
        match self.records[i] {
            LightRecord::Triangle { v, normal, area, radiance } => {
                let (b1, b2) = sample_triangle(u);
                let (q, error) = barycentric_point(&v, b1, b2);
                let d = q - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                if !(dist > 0.0) {
                    return None;
                }
                let wi = d / dist;
                // One-sided: the light emits only towards its front.
                let cos_light = -normal.dot(wi);
                if cos_light <= 0.0 {
                    return None;
                }
                let pdf = pick * dist2 / (cos_light * area);
                let target = ShadowTarget::Surface { point: q, error, normal };
                Some(LightSample { wi, distance: dist, radiance, pdf, target })
            }
            LightRecord::Point { position, intensity, spot } => {
                let d = position - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = d / dist;
                let radiance = match spot {
                    None => intensity / dist2,
                    Some(cone) => {
                        let falloff = cone.falloff(-wi);
                        if !(falloff > 0.0) {
                            return None;
                        }
                        intensity * falloff / dist2
                    }
                };
                let target = ShadowTarget::Point(position);
                Some(LightSample { wi, distance: dist, radiance, pdf: pick, target })
            }
            LightRecord::Sun(sun) => {
                let (wi, pdf) = sun.sample(u);
                let target = ShadowTarget::Distant;
                Some(LightSample { wi, distance: f32::INFINITY, radiance: sun.radiance(), pdf: pick * pdf, target })
            }
            LightRecord::Environment => {
                let (wi, pdf, radiance) = environment?.sample(u);
                let target = ShadowTarget::Distant;
                (pdf > 0.0).then_some(LightSample { wi, distance: f32::INFINITY, radiance, pdf: pick * pdf, target })
            }
        }
    }
}

fn bound(tris: &[MovingTriangle]) -> (Vec3, f32) {
    if tris.is_empty() {
        return (Vec3::ZERO, 0.0);
    }
    let n = (tris.len() * 3) as f32;
    let centre = tris.iter().flat_map(|t| t.v).fold(Vec3::ZERO, |a, v| a + v) / n;
    let r2 = tris.iter().flat_map(|t| t.v).map(|v| (v - centre).length_squared()).fold(0.0, f32::max);
    (centre, r2 * 1.0001 + 1e-12)
}

//! Lights: point, area (emissive triangles), directional sun, environment (constant,
//! analytic sky gradient or lat-long map) and moving point/area lights.
//!
//! Units: point intensity is radiant intensity (W/sr, irradiance `I cos θ / r²`); area and
//! environment values are radiance; the sun is given by its irradiance on a surface facing it,
//! spread uniformly over a disc of the given angular radius.
//!
//! Static area lights are ordinary mesh triangles whose material emits; [`AreaLights`] lists
//! them with their power for light selection. Moving lights are **not** in the mesh: a
//! [`MovingLight`] is placed per frame ([`MovingLight::at_frame`]) and the renderer traces its
//! few triangles (if any) on top of the static BVH, or refits.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::envmap::EnvMap;
use super::material::{Material, check_emission};
use super::mesh::Mesh;
use super::path::TransformPath;
use super::sampling::{Distribution1D, cone_solid_angle, luminance, uniform_cone, uniform_sphere};

/// A point light: isotropic, or a spot light when it has a [`SpotCone`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position (scene units).
    pub position: Vec3,
    /// Radiant intensity (W/sr) on the axis (everywhere for an isotropic light).
    pub intensity: Vec3,
    /// The cone of a spot light; `None` for an isotropic point light.
    pub spot: Option<SpotCone>,
}

impl PointLight {
    /// An isotropic point light.
    pub fn isotropic(position: Vec3, intensity: Vec3) -> Self {
        Self { position, intensity, spot: None }
    }

    /// Emitted power if it were isotropic, `4π I` (an upper bound for a spot light, which is
    /// what light selection needs).
    pub fn power(&self) -> Vec3 {
        self.intensity * (4.0 * PI)
    }
}

/// The cone of a spot light, as glTF's `KHR_lights_punctual` defines one: full intensity
/// within `inner` of the axis, none beyond `outer`, and between them the falloff the
/// extension recommends, the square of a linear ramp in the cosine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotCone {
    /// Unit direction the light points to.
    pub direction: Vec3,
    /// Cosine of the inner cone angle.
    pub cos_inner: f32,
    /// Cosine of the outer cone angle.
    pub cos_outer: f32,
}

impl SpotCone {
    /// A cone around `direction` with angles (radians) `0 <= inner < outer <= π/2`, the
    /// extension's rule.
    pub fn new(direction: Vec3, inner: f32, outer: f32) -> Result<Self, String> {
        let direction = direction.try_normalize().ok_or_else(|| format!("spot direction {direction} has no length"))?;
        if !(inner >= 0.0 && inner < outer && outer <= std::f32::consts::FRAC_PI_2 + 1e-6) {
            return Err(format!(
                "spot cone angles inner {inner} and outer {outer} rad need 0 <= inner < outer <= pi/2"
            ));
        }
        Ok(Self { direction, cos_inner: inner.cos(), cos_outer: outer.cos() })
    }

    /// The fraction of the axial intensity sent along unit direction `towards` (from the light).
    #[inline]
    pub fn falloff(&self, towards: Vec3) -> f32 {
        let scale = 1.0 / (self.cos_inner - self.cos_outer).max(1e-3);
        let ramp = ((self.direction.dot(towards) - self.cos_outer) * scale).clamp(0.0, 1.0);
        ramp * ramp
    }
}

/// Mitsuba's apparent sun radius in degrees (half its 0.5358° diameter): the real sun's.
pub const SUN_RADIUS_DEG: f32 = 0.5358 / 2.0;

/// A directional light with a finite angular radius (a sun disc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunLight {
    /// Unit direction from the scene **towards** the sun.
    pub direction: Vec3,
    /// Irradiance on a surface facing the sun (W/m²).
    pub irradiance: Vec3,
    /// Angular radius of the disc in degrees (> 0).
    pub angular_radius_deg: f32,
}

impl SunLight {
    /// Cosine of the angular radius.
    pub fn cos_max(&self) -> f32 {
        self.angular_radius_deg.to_radians().cos()
    }

    /// Solid angle of the disc.
    pub fn solid_angle(&self) -> f32 {
        cone_solid_angle(self.cos_max())
    }

    /// Radiance of the disc, `E / (π sin² θmax)` (uniform disc of that irradiance).
    pub fn radiance(&self) -> Vec3 {
        let s = self.angular_radius_deg.to_radians().sin();
        self.irradiance / (PI * s * s)
    }

    /// Uniform direction inside the disc and its solid-angle density.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec3, f32) {
        (uniform_cone(self.direction, self.cos_max(), u), 1.0 / self.solid_angle())
    }

    /// Density of [`sample`](Self::sample) at `dir` (0 outside the disc).
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        if dir.normalize_or_zero().dot(self.direction) >= self.cos_max() { 1.0 / self.solid_angle() } else { 0.0 }
    }

    /// Radiance seen along `dir` (the disc's radiance inside it, zero outside).
    #[inline]
    pub fn radiance_towards(&self, dir: Vec3) -> Vec3 {
        if dir.normalize_or_zero().dot(self.direction) >= self.cos_max() { self.radiance() } else { Vec3::ZERO }
    }
}

/// A simple analytic sky: `horizon → zenith` blend above the horizon (by `sqrt(y)`), a
/// constant `ground` below it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyGradient {
    /// Radiance straight up.
    pub zenith: Vec3,
    /// Radiance at the horizon.
    pub horizon: Vec3,
    /// Radiance from below the horizon.
    pub ground: Vec3,
}

impl SkyGradient {
    /// Radiance from world direction `dir` (+Y up).
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let y = dir.normalize_or_zero().y;
        if y < 0.0 { self.ground } else { self.horizon.lerp(self.zenith, y.sqrt()) }
    }

    /// Solid-angle mean radiance (exact: the upper hemisphere mean of `sqrt(y)` is 2/3).
    pub fn mean_radiance(&self) -> Vec3 {
        0.5 * self.horizon.lerp(self.zenith, 2.0 / 3.0) + 0.5 * self.ground
    }
}

/// Light arriving from infinitely far away, from every direction.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An analytic sky.
    Sky(SkyGradient),
    /// A lat-long HDR map.
    Map(Box<EnvMap>),
}

impl Environment {
    /// Radiance arriving from world direction `dir`.
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match self {
            Self::Constant(c) => *c,
            Self::Sky(s) => s.radiance(dir),
            Self::Map(m) => m.radiance(dir),
        }
    }

    /// Samples a direction: uniform over the sphere for the analytic kinds, importance
    /// sampled for maps. Returns `(direction, solid-angle pdf, radiance)`.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec3, f32, Vec3) {
        match self {
            Self::Map(m) => {
                let s = m.sample(u);
                (s.direction, s.pdf, s.radiance)
            }
            _ => {
                let d = uniform_sphere(u);
                (d, 1.0 / (4.0 * PI), self.radiance(d))
            }
        }
    }

    /// Density of [`sample`](Self::sample) at `dir`.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self {
            Self::Map(m) => m.pdf(dir),
            _ => 1.0 / (4.0 * PI),
        }
    }

    /// Solid-angle mean radiance.
    pub fn mean_radiance(&self) -> Vec3 {
        match self {
            Self::Constant(c) => *c,
            Self::Sky(s) => s.mean_radiance(),
            Self::Map(m) => m.mean_radiance,
        }
    }
}

/// The emissive triangles of the static mesh, with a power-proportional selection table.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct AreaLights {
    /// Emissive triangle indices, ascending. Zero-area emitters are left out (they can
    /// neither be sampled nor contribute).
    pub triangles: Vec<u32>,
    /// Power of each (`π · area · luminance(Ke)`, one-sided Lambertian emitter).
    pub power: Vec<f32>,
    /// Selection distribution over `triangles` (proportional to `power`); `None` when empty.
    pub distribution: Option<Distribution1D>,
}

impl AreaLights {
    /// Collects the emitters of `mesh` under `materials`.
    pub fn build(mesh: &Mesh, materials: &[Material]) -> Self {
        let mut triangles = Vec::new();
        let mut power = Vec::new();
        for (i, &m) in mesh.material.iter().enumerate() {
            let Some(mat) = materials.get(m as usize) else { continue };
            if !mat.is_emissive() {
                continue;
            }
            // In f64: a large emitter of a bright material overflows f32.
            let p = std::f64::consts::PI * f64::from(mesh.area(i)) * f64::from(luminance(mat.emission));
            if p > 0.0 && p.is_finite() {
                triangles.push(i as u32);
                power.push(p as f32);
            }
        }
        let distribution = (!power.is_empty()).then(|| Distribution1D::new(&power));
        Self { triangles, power, distribution }
    }

    /// Number of emissive triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Total power (luminance units).
    pub fn total_power(&self) -> f32 {
        self.distribution.as_ref().map_or(0.0, |d| d.total as f32)
    }

    /// Picks an emissive triangle proportionally to power: `(triangle index, probability)`.
    #[inline]
    pub fn sample(&self, u: f32) -> Option<(u32, f32)> {
        let d = self.distribution.as_ref()?;
        let (slot, p, _) = d.sample_discrete(u);
        Some((self.triangles[slot], p))
    }

    /// Probability that [`sample`](Self::sample) picks triangle `tri` (0 if not an emitter).
    #[inline]
    pub fn pmf(&self, tri: u32) -> f32 {
        match (self.triangles.binary_search(&tri), &self.distribution) {
            (Ok(slot), Some(d)) => d.pmf(slot),
            _ => 0.0,
        }
    }
}

/// Barycentrics `(b1, b2)` of a uniformly distributed point on a triangle.
#[inline]
pub fn sample_triangle(u: Vec2) -> (f32, f32) {
    let s = u.x.max(0.0).sqrt();
    (s * (1.0 - u.y), s * u.y)
}

/// What a moving light is.
#[derive(Clone, Debug, PartialEq)]
pub enum MovingShape {
    /// A point light at the path's origin.
    Point {
        /// Radiant intensity (W/sr).
        intensity: Vec3,
    },
    /// Emissive triangles in the light's local space (one-sided on their winding normals).
    Area {
        /// Local-space triangles.
        triangles: Vec<[Vec3; 3]>,
        /// Emitted radiance.
        radiance: Vec3,
    },
}

impl MovingShape {
    /// A closed, outward-wound icosphere of `radius` (`20 · 4^subdivisions` triangles).
    pub fn sphere(radius: f32, subdivisions: u32, radiance: Vec3) -> Self {
        Self::Area { triangles: icosphere(radius, subdivisions), radiance }
    }
}

/// A point or area light following a keyframed path over the frames.
#[derive(Clone, Debug, PartialEq)]
pub struct MovingLight {
    /// Name for diagnostics.
    pub name: String,
    /// The light in its local frame.
    pub shape: MovingShape,
    /// Local-to-world transform over frames.
    pub path: TransformPath,
}

/// A moving light placed at one frame.
#[derive(Clone, Debug, PartialEq)]
pub enum PlacedLight {
    /// A point light.
    Point(PointLight),
    /// World-space emissive triangles and their radiance.
    Area {
        /// World-space triangles.
        triangles: Vec<[Vec3; 3]>,
        /// Emitted radiance (one-sided, winding normal).
        radiance: Vec3,
    },
}

impl MovingLight {
    /// The light at (fractional) frame `frame`.
    pub fn at_frame(&self, frame: f32) -> PlacedLight {
        let m = self.path.transform(frame);
        match &self.shape {
            MovingShape::Point { intensity } => {
                PlacedLight::Point(PointLight::isotropic(m.translation.into(), *intensity))
            }
            MovingShape::Area { triangles, radiance } => PlacedLight::Area {
                triangles: triangles.iter().map(|t| t.map(|p| m.transform_point3(p))).collect(),
                radiance: *radiance,
            },
        }
    }

    /// Emitted power (rigid motion does not change it).
    pub fn power(&self) -> Vec3 {
        match &self.shape {
            MovingShape::Point { intensity } => *intensity * (4.0 * PI),
            MovingShape::Area { triangles, radiance } => {
                let area: f32 = triangles.iter().map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length()).sum();
                *radiance * (PI * area)
            }
        }
    }
}

/// Every light of a scene.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Lights {
    /// Static point lights.
    pub points: Vec<PointLight>,
    /// Static emissive triangles of the mesh (filled in from the materials).
    pub area: AreaLights,
    /// The sun, if any.
    pub sun: Option<SunLight>,
    /// The environment, if any.
    pub environment: Option<Environment>,
    /// Lights that move over the frames.
    pub moving: Vec<MovingLight>,
}

impl Lights {
    /// True when nothing emits.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
            && self.area.is_empty()
            && self.sun.is_none()
            && self.environment.is_none()
            && self.moving.is_empty()
    }

    /// Approximate luminous power of every light kind for a scene of bounding radius
    /// `radius` (distant lights as the power they deliver through a disc of that radius), for
    /// light-selection heuristics and sanity checks.
    pub fn approx_power(&self, radius: f32) -> f32 {
        let disc = PI * radius * radius;
        let points: f32 = self.points.iter().map(|p| luminance(p.power())).sum();
        let sun = self.sun.map_or(0.0, |s| luminance(s.irradiance) * disc);
        let env = self.environment.as_ref().map_or(0.0, |e| luminance(e.mean_radiance()) * PI * disc);
        let moving: f32 = self.moving.iter().map(|m| luminance(m.power())).sum();
        points + self.area.total_power() + sun + env + moving
    }

    /// Checks every light's values are finite and non-negative and that each light emits.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |v: Vec3| v.is_finite() && v.min_element() >= 0.0 && v.max_element() > 0.0;
        for p in &self.points {
            if !(p.position.is_finite() && ok(p.intensity)) {
                return Err(format!("point light at {} has intensity {}", p.position, p.intensity));
            }
            check_emission(&format!("point light at {}: intensity", p.position), p.intensity)?;
            if let Some(cone) = &p.spot {
                let unit = (cone.direction.length() - 1.0).abs() < 1e-3;
                let ordered = cone.cos_inner > cone.cos_outer && cone.cos_outer >= -1e-6 && cone.cos_inner <= 1.0;
                if !(unit && ordered) {
                    return Err(format!(
                        "spot light at {}: cone {cone:?} is not a unit axis with 0 <= inner < outer <= 90 deg",
                        p.position
                    ));
                }
            }
        }
        if let Some(s) = &self.sun {
            if !ok(s.irradiance) {
                return Err(format!("sun irradiance {} must be finite, non-negative and not all zero", s.irradiance));
            }
            if !((s.direction.length() - 1.0).abs() < 1e-3) {
                return Err(format!("sun direction {} is not a unit vector", s.direction));
            }
            if !(s.angular_radius_deg > 0.0 && s.angular_radius_deg < 90.0) {
                return Err(format!("sun angular radius {} deg is outside (0, 90)", s.angular_radius_deg));
            }
            check_emission("sun: radiance (irradiance / disc solid angle)", s.radiance())?;
        }
        match &self.environment {
            Some(Environment::Constant(c)) if !ok(*c) => return Err(format!("constant environment {c} emits nothing")),
            Some(Environment::Sky(s)) if !ok(s.mean_radiance()) => {
                return Err(format!(
                    "sky (zenith {}, horizon {}, ground {}) emits nothing",
                    s.zenith, s.horizon, s.ground
                ));
            }
            Some(Environment::Map(m)) if !ok(m.mean_radiance) => return Err("environment map is black".into()),
            Some(Environment::Constant(c)) => check_emission("constant environment: radiance", *c)?,
            Some(Environment::Sky(s)) => check_emission("sky: radiance", s.zenith.max(s.horizon).max(s.ground))?,
            Some(Environment::Map(m)) => {
                let brightest = m.texture.data.iter().copied().fold(0.0f32, f32::max);
                check_emission("environment map: scale x brightest texel", Vec3::splat(brightest * m.scale))?
            }
            None => {}
        }
        for m in &self.moving {
            m.path.validate().map_err(|e| format!("moving light {:?}: {e}", m.name))?;
            if !ok(m.power()) {
                return Err(format!("moving light {:?} emits nothing", m.name));
            }
            let value = match &m.shape {
                MovingShape::Point { intensity } => *intensity,
                MovingShape::Area { radiance, .. } => *radiance,
            };
            check_emission(&format!("moving light {:?}", m.name), value)?;
            if let MovingShape::Area { triangles, .. } = &m.shape
                && !triangles.iter().flatten().all(|p| p.is_finite())
            {
                return Err(format!("moving light {:?} has non-finite triangles", m.name));
            }
        }
        Ok(())
    }
}

/// Outward-wound icosphere triangles.
pub fn icosphere(radius: f32, subdivisions: u32) -> Vec<[Vec3; 3]> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v = [
        Vec3::new(-1.0, t, 0.0),
        Vec3::new(1.0, t, 0.0),
        Vec3::new(-1.0, -t, 0.0),
        Vec3::new(1.0, -t, 0.0),
        Vec3::new(0.0, -1.0, t),
        Vec3::new(0.0, 1.0, t),
        Vec3::new(0.0, -1.0, -t),
        Vec3::new(0.0, 1.0, -t),
        Vec3::new(t, 0.0, -1.0),
        Vec3::new(t, 0.0, 1.0),
        Vec3::new(-t, 0.0, -1.0),
        Vec3::new(-t, 0.0, 1.0),
    ]
    .map(|p| p.normalize());
    #[rustfmt::skip]
    let f: [[usize; 3]; 20] = [
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    let mut tris: Vec<[Vec3; 3]> = f.iter().map(|&[a, b, c]| [v[a], v[b], v[c]]).collect();
    for _ in 0..subdivisions {
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = ((a + b).normalize(), (b + c).normalize(), (c + a).normalize());
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    for t in &mut tris {
        // Orient outward explicitly (does not rely on the table's winding).
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        if n.dot(t[0] + t[1] + t[2]) < 0.0 {
            t.swap(1, 2);
        }
        *t = t.map(|p| p * radius);
    }
    tris
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::path::TransformKey;

    #[test]
    fn area_lights_are_power_weighted() {
        let mesh = Mesh {
            positions: vec![
                [Vec3::ZERO, Vec3::X, Vec3::Z],
                [Vec3::ZERO, Vec3::X * 2.0, Vec3::Z],
                [Vec3::ZERO, Vec3::X, Vec3::Y],
                [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
            ],
            normals: None,
            uvs: None,
            material: vec![1, 1, 0, 1],
        };
        let mats = [Material::diffuse("d", Vec3::splat(0.5)), Material::emitter("e", Vec3::ONE, Vec3::ZERO)];
        let a = AreaLights::build(&mesh, &mats);
        assert_eq!(a.triangles, vec![0, 1], "zero-area emitter left out");
        assert!((a.pmf(1) - 2.0 * a.pmf(0)).abs() < 1e-6);
        assert_eq!(a.pmf(2), 0.0);
        assert!((a.total_power() - PI * 1.5).abs() < 1e-5);
        assert_eq!(a.sample(0.9).unwrap().0, 1);
    }

    #[test]
    fn sun_radiance_times_projected_disc_is_irradiance() {
        let s = SunLight { direction: Vec3::Y, irradiance: Vec3::splat(10.0), angular_radius_deg: 5.0 };
        // ∫ L cos θ dω over the disc = L π sin² θmax = E.
        let n = 200_000;
        let mut e = 0.0;
        for i in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (i as f32 * 0.618034) % 1.0);
            let (d, pdf) = s.sample(u);
            e += s.radiance_towards(d).x * d.y / pdf;
        }
        assert!((e / n as f32 - 10.0).abs() < 0.01, "{}", e / n as f32);
        assert!(s.pdf(Vec3::X) == 0.0 && s.pdf(Vec3::Y) > 0.0);
    }

    #[test]
    fn moving_lights_follow_their_path() {
        let path = TransformPath::new(vec![
            TransformKey { frame: 0.0, translation: [0.0, 2.0, 0.0], yaw_deg: 0.0 },
            TransformKey { frame: 59.0, translation: [3.0, 2.0, 0.0], yaw_deg: 0.0 },
        ])
        .unwrap();
        let l = MovingLight { name: "m".into(), shape: MovingShape::sphere(0.1, 1, Vec3::splat(5.0)), path };
        let PlacedLight::Area { triangles, .. } = l.at_frame(59.0) else { panic!() };
        assert_eq!(triangles.len(), 80);
        let c: Vec3 = triangles.iter().flatten().copied().sum::<Vec3>() / 240.0;
        assert!((c - Vec3::new(3.0, 2.0, 0.0)).length() < 1e-3);
        for t in &triangles {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            assert!(n.dot(t[0] - Vec3::new(3.0, 2.0, 0.0)) > 0.0, "outward");
        }
        let lights = Lights { moving: vec![l], ..Default::default() };
        assert!(lights.validate().is_ok() && lights.approx_power(1.0) > 0.0);
    }

    #[test]
    fn sky_mean_is_the_integral() {
        let s = SkyGradient { zenith: Vec3::splat(1.0), horizon: Vec3::splat(3.0), ground: Vec3::splat(0.5) };
        let n = 100_000;
        let mut sum = Vec3::ZERO;
        for i in 0..n {
            let d = uniform_sphere(Vec2::new((i as f32 + 0.5) / n as f32, (i as f32 * 0.618034) % 1.0));
            sum += s.radiance(d);
        }
        assert!((sum / n as f32 - s.mean_radiance()).abs().max_element() < 5e-3);
    }
}

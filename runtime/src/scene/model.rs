//! The scene model itself: [`Scene`] (what the renderer reads), where it came from
//! ([`SceneSource`], [`Units`]) and its reprojection tolerances ([`SceneTolerances`]). The
//! loaders above build it; the parts below (mesh, materials, lights, paths) are its fields.

use std::path::PathBuf;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::effects::EffectSet;
use super::error::SceneError;
use super::light::{AreaLights, Environment, Lights, MovingShape};
use super::material::Material;
use super::mesh::{Aabb, Mesh};
use super::object::MovingObject;
use super::path::CameraPath;
use super::texture::Texture;

/// The frame height per-scene tolerances are set for (the paper's 1280×720).
pub const REFERENCE_HEIGHT: usize = 720;

/// Per-scene reprojection discard thresholds (the paper sets them "manually based on the
/// scale of each test scene"), for frames [`REFERENCE_HEIGHT`] pixels tall; see
/// [`SceneTolerances::at_height`] for other resolutions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneTolerances {
    /// Largest world-space distance between a source tap's surface point and the target's
    /// (scene units, metres).
    pub position: f32,
    /// Largest relative depth difference `|d_tap − d| / d`.
    pub depth_relative: f32,
    /// Largest angle between shading normals, in degrees.
    pub normal_degrees: f32,
}

impl SceneTolerances {
    /// Tolerances for a scene whose typical size is `size` metres (a loaded scene without
    /// hand-set values): position 0.4 % of the size, 2 % depth, 25°.
    pub fn for_size(size: f32) -> Self {
        Self { position: (0.004 * size).max(1e-4), depth_relative: 0.02, normal_degrees: 25.0 }
    }

    /// The kernel's form (normal threshold as a cosine), as set: for frames
    /// [`REFERENCE_HEIGHT`] pixels tall.
    pub fn to_kernel(&self) -> crate::kernels::reproject::Tolerances {
        crate::kernels::reproject::Tolerances::new(self.position, self.depth_relative, self.normal_degrees)
    }

    /// The kernel's form for frames `height` pixels tall.
    ///
    /// The values are set for the paper's 1280×720. The position and depth tests compare a
    /// tap's surface with the target's across up to a pixel's footprint, which grows as the
    /// resolution drops (a pixel at 360 rows spans twice the angle of one at 720), so both
    /// tolerances scale by `720 / height` and the discard tests keep meaning the same thing
    /// at any resolution. The normal angle does not depend on the resolution.
    pub fn at_height(&self, height: usize) -> crate::kernels::reproject::Tolerances {
        let scale = (REFERENCE_HEIGHT as f32 / height.max(1) as f32).max(1.0);
        crate::kernels::reproject::Tolerances::new(
            self.position * scale,
            self.depth_relative * scale,
            self.normal_degrees,
        )
    }

    /// All finite, position and depth > 0, angle in (0, 180].
    pub fn validate(&self) -> Result<(), String> {
        if !(self.position > 0.0 && self.position.is_finite()) {
            return Err(format!("position tolerance {} must be > 0", self.position));
        }
        if !(self.depth_relative > 0.0 && self.depth_relative.is_finite()) {
            return Err(format!("relative depth tolerance {} must be > 0", self.depth_relative));
        }
        if !(self.normal_degrees > 0.0 && self.normal_degrees <= 180.0) {
            return Err(format!("normal tolerance {} deg must be in (0, 180]", self.normal_degrees));
        }
        Ok(())
    }
}

/// The length unit of a scene's source files. Geometry is already scaled to metres; this
/// says what the files' numbers meant and who said so.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Units {
    /// One unit of the source files, in metres.
    pub meters_per_unit: f32,
    /// Who said so.
    pub from: UnitsFrom,
}

/// Who stated a scene's unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitsFrom {
    /// A built-in (generated in metres).
    Builtin,
    /// `meters_per_unit` in `camera.json`.
    CameraJson,
    /// A manifest's `meters_per_unit` (or `scale`), or a loader option.
    Manifest,
    /// The `Units:` line of `SOURCE.md`.
    SourceMd,
    /// Nothing conclusive: metres assumed (with a warning).
    Assumed,
    /// A glTF file: metres, by the specification.
    Gltf,
}

impl Units {
    /// Metres, for scenes made in code.
    pub const METRES: Units = Units { meters_per_unit: 1.0, from: UnitsFrom::Builtin };
}

impl std::fmt::Display for Units {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let from = match self.from {
            UnitsFrom::Builtin => "built-in",
            UnitsFrom::CameraJson => "camera.json meters_per_unit",
            UnitsFrom::Manifest => "manifest",
            UnitsFrom::SourceMd => "SOURCE.md Units line",
            UnitsFrom::Assumed => "assumed: nothing stated it",
            UnitsFrom::Gltf => "glTF: metres by specification",
        };
        write!(f, "1 unit = {} m ({from})", self.meters_per_unit)
    }
}

/// Where a scene came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// A procedural built-in, by name.
    Builtin(&'static str),
    /// A scene folder.
    Folder(PathBuf),
    /// A TOML manifest.
    Manifest(PathBuf),
    /// A scene file given directly (glTF), with any `camera.json` / `lights.json` beside it.
    File(PathBuf),
}

impl SceneSource {
    /// A path for error messages (`builtin:<name>` for built-ins).
    pub fn path(&self) -> PathBuf {
        match self {
            Self::Builtin(n) => PathBuf::from(format!("builtin:{n}")),
            Self::Folder(p) | Self::Manifest(p) | Self::File(p) => p.clone(),
        }
    }
}

/// A complete scene, ready to render.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Stable kebab-case id (`atrium-glossy`, `sponza`, a manifest's `name`).
    pub name: String,
    /// Human-readable name, naming the paper scene it stands for where it stands for one.
    pub display_name: String,
    /// The paper scene (Figure 2 label) this scene stands for, e.g. `Sponza (Glossy)`.
    pub paper_scene: Option<String>,
    /// Where it came from.
    pub source: SceneSource,
    /// World-space triangles.
    pub mesh: Mesh,
    /// Materials, indexed by `mesh.material`.
    pub materials: Vec<Material>,
    /// Textures, indexed by the materials.
    pub textures: Vec<Texture>,
    /// Lights (`lights.area` is derived from emissive materials by [`Scene::update`]).
    pub lights: Lights,
    /// Non-emissive objects that move over the frames (outside the static mesh).
    pub moving_objects: Vec<MovingObject>,
    /// The moving observer.
    pub camera: CameraPath,
    /// Reprojection tolerances.
    pub tolerances: SceneTolerances,
    /// Effects the renderer must simulate: derived from the content plus `forced_effects`.
    pub effects: EffectSet,
    /// Effects forced on by a manifest (kept across [`Scene::update`]).
    pub forced_effects: EffectSet,
    /// The unit of the source files (geometry is in metres already).
    pub units: Units,
    /// Non-fatal problems met while loading (missing textures, clamped values, ...).
    pub warnings: Vec<String>,
}

impl Scene {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.mesh.len()
    }

    /// Number of frames of the camera path.
    pub fn frame_count(&self) -> u32 {
        self.camera.frames
    }

    /// Bounds of the static geometry.
    pub fn bounds(&self) -> Aabb {
        self.mesh.bounds()
    }

    /// Re-derives the area-light table and the effect set from the content, then validates.
    /// Call after editing materials, geometry or lights.
    pub fn update(&mut self) -> Result<(), SceneError> {
        self.lights.area = AreaLights::build(&self.mesh, &self.materials);
        self.effects = EffectSet::derive(&self.mesh, &self.materials, &self.lights, &self.moving_objects)
            .union(self.forced_effects);
        self.validate()
    }

    /// Moves the whole scene to `scale · p + offset` (geometry, camera, lights, tolerances), so
    /// that it renders the same image: radiance and distant lights are scale-free, and point
    /// intensities grow by `scale²` so that their irradiance `I / r²` is kept. What the
    /// renderer's robustness is tested with: an image must not depend on where a scene sits
    /// or on its units. `scale` must be finite and positive.
    pub fn place(&mut self, scale: f32, offset: Vec3) -> Result<(), SceneError> {
        if !(scale.is_finite() && scale > 0.0 && offset.is_finite()) {
            return Err(SceneError::invalid(
                &self.source.path(),
                format!("placement scale {scale} and offset {offset} must be finite, with scale > 0"),
            ));
        }
        let at = |p: Vec3| p * scale + offset;
        for t in &mut self.mesh.positions {
            *t = t.map(at);
        }
        for p in &mut self.lights.points {
            p.position = at(p.position);
            p.intensity *= scale * scale;
        }
        for m in &mut self.lights.moving {
            for k in &mut m.path.keys {
                k.translation = at(Vec3::from(k.translation)).to_array();
            }
            match &mut m.shape {
                MovingShape::Point { intensity } => *intensity *= scale * scale,
                MovingShape::Area { triangles, .. } => {
                    triangles.iter_mut().for_each(|t| *t = t.map(|p| p * scale));
                }
            }
        }
        for o in &mut self.moving_objects {
            for k in &mut o.path.keys {
                k.translation = at(Vec3::from(k.translation)).to_array();
            }
            o.triangles.iter_mut().for_each(|t| *t = t.map(|p| p * scale));
        }
        for k in &mut self.camera.keys {
            k.eye = at(Vec3::from(k.eye)).to_array();
            k.target = at(Vec3::from(k.target)).to_array();
        }
        self.tolerances.position *= scale;
        self.update()
    }

    /// Checks every invariant the renderer relies on: a non-empty finite mesh, material and
    /// texture indices in range, sane materials, lights that emit, a valid camera path and
    /// tolerances, and effects that cover the content.
    pub fn validate(&self) -> Result<(), SceneError> {
        let path = self.source.path();
        let bad = |m: String| SceneError::invalid(&path, m);
        if self.mesh.is_empty() {
            return Err(bad("the scene has no triangles".into()));
        }
        self.mesh.validate(self.materials.len()).map_err(bad)?;
        for m in &self.materials {
            m.validate(self.textures.len()).map_err(bad)?;
        }
        if self.lights.is_empty() {
            return Err(bad(
                "the scene has no lights (no emissive material, lights.json entry or manifest light)".into()
            ));
        }
        self.lights.validate().map_err(bad)?;
        for o in &self.moving_objects {
            o.validate(&self.materials).map_err(bad)?;
        }
        self.camera.validate().map_err(|e| bad(format!("camera: {e}")))?;
        self.tolerances.validate().map_err(|e| bad(format!("tolerances: {e}")))?;
        let derived = EffectSet::derive(&self.mesh, &self.materials, &self.lights, &self.moving_objects);
        if !self.effects.contains(derived) {
            return Err(bad(format!("effects {} do not cover the content ({derived})", self.effects)));
        }
        Ok(())
    }

    /// A stable 64-bit hash of everything that affects an image (geometry, materials,
    /// textures, lights, camera, tolerances, effects), for cache keys. Names are included;
    /// warnings are not.
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fnv::new();
        h.str(&self.name);
        for t in &self.mesh.positions {
            t.iter().for_each(|v| h.vec3(*v));
        }
        if let Some(n) = &self.mesh.normals {
            n.iter().flatten().for_each(|v| h.vec3(*v));
        }
        if let Some(uv) = &self.mesh.uvs {
            uv.iter().flatten().for_each(|v| h.f32s(&v.to_array()));
        }
        self.mesh.material.iter().for_each(|&m| h.u32(m));
        for m in &self.materials {
            h.str(&m.name);
            h.u32(m.kind as u32);
            [m.albedo, m.specular, m.emission].into_iter().for_each(|v| h.vec3(v));
            h.f32s(&[m.roughness, m.opacity, m.texture_scale]);
            h.u32(m.metallic as u32);
            h.u32(m.albedo_texture.map_or(u32::MAX, |t| t));
            h.u32(m.opacity_texture.map_or(u32::MAX, |t| t));
        }
        for t in &self.textures {
            h.u32(t.width);
            h.u32(t.height);
            h.u32(t.channels as u32);
            h.f32s(&t.data);
        }
        let l = &self.lights;
        for p in &l.points {
            h.vec3(p.position);
            h.vec3(p.intensity);
            if let Some(cone) = &p.spot {
                h.vec3(cone.direction);
                h.f32s(&[cone.cos_inner, cone.cos_outer]);
            }
        }
        if let Some(s) = &l.sun {
            h.vec3(s.direction);
            h.vec3(s.irradiance);
            h.f32s(&[s.angular_radius_deg]);
        }
        match &l.environment {
            None => h.u32(0),
            Some(Environment::Constant(c)) => {
                h.u32(1);
                h.vec3(*c);
            }
            Some(Environment::Sky(s)) => {
                h.u32(2);
                [s.zenith, s.horizon, s.ground].into_iter().for_each(|v| h.vec3(v));
            }
            Some(Environment::Map(m)) => {
                h.u32(3);
                h.f32s(&m.texture.data);
                h.f32s(&[m.scale]);
                h.f32s(&m.to_world.to_cols_array());
            }
        }
        for m in &l.moving {
            h.str(&m.name);
            match &m.shape {
                MovingShape::Point { intensity } => h.vec3(*intensity),
                MovingShape::Area { triangles, radiance } => {
                    triangles.iter().flatten().for_each(|v| h.vec3(*v));
                    h.vec3(*radiance);
                }
            }
            for k in &m.path.keys {
                h.f32s(&[k.frame, k.yaw_deg]);
                h.f32s(&k.translation);
            }
        }
        for o in &self.moving_objects {
            h.str(&o.name);
            o.triangles.iter().flatten().for_each(|v| h.vec3(*v));
            h.u32(o.material);
            for k in &o.path.keys {
                h.f32s(&[k.frame, k.yaw_deg]);
                h.f32s(&k.translation);
            }
        }
        for k in &self.camera.keys {
            h.f32s(&[k.frame]);
            [k.eye, k.target, k.up].iter().for_each(|v| h.f32s(v));
        }
        h.u32(self.camera.frames);
        h.f32s(&[self.camera.vfov_deg]);
        let t = &self.tolerances;
        h.f32s(&[t.position, t.depth_relative, t.normal_degrees]);
        h.u32(self.effects.bits() as u32);
        h.0
    }

    /// A multi-line human-readable summary (for the CLI).
    pub fn summary(&self) -> String {
        let b = self.bounds();
        let l = &self.lights;
        let mut lights = Vec::new();
        if !l.area.is_empty() {
            lights.push(format!("{} emissive triangles", l.area.len()));
        }
        let spots = l.points.iter().filter(|p| p.spot.is_some()).count();
        if l.points.len() > spots {
            lights.push(format!("{} point", l.points.len() - spots));
        }
        if spots > 0 {
            lights.push(format!("{spots} spot"));
        }
        if let Some(s) = &l.sun {
            lights.push(format!("sun (radius {:.2} deg)", s.angular_radius_deg));
        }
        match &l.environment {
            Some(Environment::Constant(c)) => lights.push(format!("constant environment {c}")),
            Some(Environment::Sky(_)) => lights.push("sky gradient".into()),
            Some(Environment::Map(m)) => {
                lights.push(format!("environment map {} {}x{}", m.texture.name, m.texture.width, m.texture.height))
            }
            None => {}
        }
        if !l.moving.is_empty() {
            lights.push(format!("{} moving", l.moving.len()));
        }
        let t = &self.tolerances;
        format!(
            "{} ({})\n  paper scene: {}\n  triangles: {} ({} degenerate), materials: {}, textures: {}\n  bounds: {} .. {}\n  \
             lights: {}\n  moving objects: {}\n  camera: {} frames, vfov {:.2} deg, {} keys, travel {:.3}\n  tolerances: position {}, depth {}, normal {} deg\n  \
             effects: {}",
            self.display_name,
            self.name,
            self.paper_scene.as_deref().unwrap_or("-"),
            self.triangle_count(),
            self.mesh.degenerate_count(),
            self.materials.len(),
            self.textures.len(),
            b.min,
            b.max,
            lights.join(", "),
            self.moving_objects.len(),
            self.camera.frames,
            self.camera.vfov_deg,
            self.camera.keys.len(),
            self.camera.travel(),
            t.position,
            t.depth_relative,
            t.normal_degrees,
            self.effects,
        )
    }
}

/// FNV-1a over 32-bit words (platform independent: values are hashed by their bits).
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    fn u32(&mut self, w: u32) {
        self.0 = (self.0 ^ w as u64).wrapping_mul(0x0000_0100_0000_01b3);
    }
    fn f32s(&mut self, v: &[f32]) {
        for x in v {
            self.u32(x.to_bits());
        }
    }
    fn vec3(&mut self, v: Vec3) {
        self.f32s(&v.to_array());
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        for b in s.bytes() {
            self.u32(b as u32);
        }
    }
}

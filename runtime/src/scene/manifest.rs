//! TOML scene manifests: a mesh plus the variations the paper's scenes need.
//!
//! ```toml
//! name = "sponza-moving-light"          # stable id (default: the file stem)
//! display_name = "Sponza (Moving Light)"
//! paper_scene = "Sponza (Moving Light)"
//! mesh = "../../shared/scenes/sponza"   # an .obj, .gltf or .glb, or a scene folder (its
//!                                       # scene.obj, scene.glb or scene.gltf);
//!                                       # RELATIVE TO THIS MANIFEST FILE
//! meters_per_unit = 1.0                 # the mesh's unit in metres (alias: scale; default:
//!                                       # camera.json's meters_per_unit, SOURCE.md's Units line)
//! frames = 60
//! glass = "transparent"                 # or "skip"
//! folder_lights = true                  # use lights.json beside the mesh (default true)
//!
//! [camera]                              # optional: default = a path around camera.json
//! vfov_deg = 60.0
//! keys = [ { frame = 0, eye = [0, 1.6, 0], target = [0, 1.5, -5] },
//!          { frame = 59, eye = [0.6, 1.6, -0.2], target = [1, 1.5, -5], up = [0, 1, 0] } ]
//!
//! [[lights]]                            # added to the folder's lights
//! type = "moving-sphere"                # point | moving-point | moving-sphere | quad | sun | constant | sky | envmap
//! radius = 0.15
//! radiance = [3000, 2800, 2500]
//! keys = [ { frame = 0, translation = [-6, 5, 0] }, { frame = 59, translation = [8, 5, 0], yaw_deg = 0 } ]
//!
//! [[objects]]                           # moving objects (non-emissive, shaded flat)
//! type = "moving-box"                   # moving-box | moving-sphere
//! name = "crate"
//! size = [1, 1, 1]                      # moving-box: edge lengths (moving-sphere: radius,
//!                                       # subdivisions as for lights)
//! albedo = [0.7, 0.45, 0.25]            # a diffuse material of its own (kind, specular and
//!                                       # roughness as in [materials.all] may follow)
//! keys = [ { frame = 0, translation = [-1.5, 0.5, -2.5] }, { frame = 59, translation = [-1.5, 0.5, 2.5], yaw_deg = 60 } ]
//!
//! [materials.all]                       # applied to every material first
//! kind = "glossy"                       # diffuse | glossy | mirror
//! roughness = 0.3
//! specular = 0.5
//!
//! [[materials.set]]                     # then these, by name ('*' wildcards)
//! name = "sp_00_svod"
//! kind = "mirror"
//!
//! [effects]                             # true forces a flag on; false strips the content
//! textures = false
//!
//! [tolerances]
//! position = 0.1
//! depth_relative = 0.03
//! normal_degrees = 25
//! ```
//!
//! Coordinates in a manifest (camera keys, light positions) are in final scene units (metres,
//! after `meters_per_unit`). Unknown keys are errors (typos do not pass silently); syntax errors give the
//! manifest's line and column; semantic errors (a material pattern matching nothing, an
//! unknown effect) name the manifest and the key.
//!
//! Effect overrides set to `false` remove what needs the effect: `glossy` → glossy materials
//! become diffuse; `mirror` → mirrors become diffuse of their reflectance; `textures` → albedo
//! maps dropped (flat `Kd`); `alpha_masks` → cutouts made opaque; `moving_lights`,
//! `point_lights`, `sun`, `sky` → those lights dropped; `area_lights` → emission zeroed and
//! moving area lights dropped; `moving_objects` → the objects dropped; `env_map` → the map replaced by a constant environment of its
//! mean radiance. Set to `true`, a flag is forced on even without content (the integrator
//! then runs its general code, which must give the same image).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use serde::Deserialize;

use super::effects::{Effect, EffectSet};
use super::envmap::EnvMap;
use super::error::{Location, SceneError, line_column};
use super::folder::{load_parts, path_around, robust_size, scene_file};
use super::light::Lights;
use super::light::{Environment, MovingLight, MovingShape, PointLight, SkyGradient, SunLight};
use super::material::{Material, MaterialKind};
use super::mesh::Mesh;
use super::model::{Scene, SceneSource, SceneTolerances};
use super::obj::GlassMode;
use super::object::{MovingObject, box_triangles, sphere_triangles};
use super::path::{CameraKey, CameraPath, DEFAULT_FRAMES, MAX_FRAMES, TransformKey, TransformPath};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestToml {
    name: Option<String>,
    display_name: Option<String>,
    paper_scene: Option<String>,
    mesh: String,
    scale: Option<f32>,
    meters_per_unit: Option<f32>,
    frames: Option<u32>,
    glass: Option<GlassToml>,
    folder_lights: Option<bool>,
    camera: Option<CameraToml>,
    #[serde(default)]
    lights: Vec<LightToml>,
    #[serde(default)]
    objects: Vec<ObjectToml>,
    materials: Option<MaterialsToml>,
    effects: Option<BTreeMap<String, bool>>,
    tolerances: Option<SceneTolerances>,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum GlassToml {
    Transparent,
    Skip,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    vfov_deg: Option<f32>,
    #[serde(default)]
    keys: Vec<CameraKey>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
enum LightToml {
    Point {
        position: [f32; 3],
        intensity: [f32; 3],
    },
    MovingPoint {
        #[serde(default)]
        name: Option<String>,
        intensity: [f32; 3],
        keys: Vec<TransformKey>,
    },
    MovingSphere {
        #[serde(default)]
        name: Option<String>,
        radius: f32,
        radiance: [f32; 3],
        #[serde(default = "one_u32")]
        subdivisions: u32,
        keys: Vec<TransformKey>,
    },
    /// A static emissive quad: corners in order around the rim, emitting towards the side
    /// from which they run counter-clockwise.
    Quad {
        corners: [[f32; 3]; 4],
        radiance: [f32; 3],
    },
    Sun {
        direction: [f32; 3],
        irradiance: [f32; 3],
        #[serde(default = "sun_radius")]
        angular_radius_deg: f32,
    },
    Constant {
        radiance: [f32; 3],
    },
    Sky {
        zenith: [f32; 3],
        horizon: [f32; 3],
        ground: [f32; 3],
    },
    Envmap {
        file: String,
        #[serde(default = "one_f32")]
        scale: f32,
        /// Row-major 3×3 rotation (default identity).
        to_world: Option<[[f32; 3]; 3]>,
    },
}

/// A moving object: a shape, a material of its own (`albedo`, optionally `kind`, `specular`
/// and `roughness` as in a material override) and a path.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
enum ObjectToml {
    MovingBox {
        #[serde(default)]
        name: Option<String>,
        size: [f32; 3],
        albedo: [f32; 3],
        kind: Option<KindToml>,
        specular: Option<Scalar3>,
        roughness: Option<f32>,
        keys: Vec<TransformKey>,
    },
    MovingSphere {
        #[serde(default)]
        name: Option<String>,
        radius: f32,
        #[serde(default = "one_u32")]
        subdivisions: u32,
        albedo: [f32; 3],
        kind: Option<KindToml>,
        specular: Option<Scalar3>,
        roughness: Option<f32>,
        keys: Vec<TransformKey>,
    },
}

impl ObjectToml {
    /// The object's own material: diffuse of `albedo`, then `kind`, `specular` and
    /// `roughness` applied as a material override applies them.
    fn material(&self, name: String) -> Material {
        let (Self::MovingBox { albedo, kind, specular, roughness, .. }
        | Self::MovingSphere { albedo, kind, specular, roughness, .. }) = self;
        let mut m = Material::diffuse(name, Vec3::from(*albedo));
        let lobe = MaterialOverride {
            name: None,
            kind: *kind,
            albedo: None,
            specular: specular.clone(),
            roughness: *roughness,
            emission: None,
            emission_scale: None,
            texture: None,
            opacity: None,
        };
        apply_override(&mut m, &lobe);
        m
    }
}

fn one_u32() -> u32 {
    1
}
fn one_f32() -> f32 {
    1.0
}
fn sun_radius() -> f32 {
    super::light::SUN_RADIUS_DEG
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialsToml {
    all: Option<MaterialOverride>,
    #[serde(default)]
    set: Vec<MaterialOverride>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
enum Scalar3 {
    Scalar(f32),
    Rgb([f32; 3]),
}

impl Scalar3 {
    fn vec(&self) -> Vec3 {
        match self {
            Self::Scalar(s) => Vec3::splat(*s),
            Self::Rgb(c) => Vec3::from(*c),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialOverride {
    name: Option<String>,
    kind: Option<KindToml>,
    albedo: Option<[f32; 3]>,
    specular: Option<Scalar3>,
    roughness: Option<f32>,
    emission: Option<[f32; 3]>,
    emission_scale: Option<f32>,
    texture: Option<bool>,
    opacity: Option<f32>,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum KindToml {
    Diffuse,
    Glossy,
    Mirror,
}

/// Default glossy lobe of `kind = "glossy"` overrides: reflectance 0.5, roughness 0.3.
pub const DEFAULT_GLOSSY: (f32, f32) = (0.5, 0.3);

/// Matches `name` against a pattern with `*` wildcards.
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    if parts.len() == 1 {
        return pattern == name;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !name.starts_with(first) || !name[first.len()..].ends_with(last) || name.len() < first.len() + last.len() {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    for p in &parts[1..parts.len() - 1] {
        match rest.find(p) {
            Some(i) => rest = &rest[i + p.len()..],
            None => return false,
        }
    }
    true
}

fn apply_override(m: &mut Material, o: &MaterialOverride) {
    match o.kind {
        Some(KindToml::Glossy) => {
            let s = o.specular.as_ref().map_or(DEFAULT_GLOSSY.0, |s| s.vec().max_element());
            m.make_glossy(s, o.roughness.unwrap_or(DEFAULT_GLOSSY.1));
            if let Some(Scalar3::Rgb(c)) = &o.specular {
                m.specular = Vec3::from(*c);
            }
        }
        Some(KindToml::Mirror) => m.make_mirror(o.specular.as_ref().map_or(Vec3::splat(0.95), Scalar3::vec)),
        Some(KindToml::Diffuse) => m.make_diffuse(),
        None => {
            if let Some(s) = &o.specular {
                m.specular = s.vec();
            }
            if let Some(r) = o.roughness {
                m.roughness = r;
            }
        }
    }
    if let Some(a) = o.albedo {
        m.albedo = Vec3::from(a);
    }
    if let Some(e) = o.emission {
        m.emission = Vec3::from(e);
    }
    if let Some(s) = o.emission_scale {
        m.emission *= s;
    }
    if o.texture == Some(false) {
        m.albedo_texture = None;
    }
    if let Some(op) = o.opacity {
        m.opacity = op;
    }
}

fn read_manifest(path: &Path) -> Result<ManifestToml, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
    toml::from_str(&text).map_err(|e| {
        let (line, column) = e.span().map_or((1, 1), |s| line_column(&text, s.start));
        SceneError::Parse { location: Location::at(path, line, column), message: e.message().to_owned() }
    })
}

/// A manifest's scene name: its `name`, or the file stem.
fn name_of(path: &Path, name: Option<String>) -> String {
    name.unwrap_or_else(|| path.file_stem().map_or_else(|| "manifest".into(), |s| s.to_string_lossy().into_owned()))
}

/// The name the manifest at `path` gives its scene, read without loading the scene.
pub fn manifest_name(path: &Path) -> Result<String, SceneError> {
    Ok(name_of(path, read_manifest(path)?.name))
}

/// Loads a manifest (see the module documentation).
pub fn load_manifest(path: &Path) -> Result<Scene, SceneError> {
    let m = read_manifest(path)?;
    let bad = |key: &str, msg: String| SceneError::invalid(path, format!("{key}: {msg}"));
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut mesh_path: PathBuf = base.join(&m.mesh);
    if mesh_path.is_dir() {
        mesh_path = scene_file(&mesh_path).unwrap_or_else(|| mesh_path.join("scene.obj"));
    }
    if !mesh_path.is_file() {
        return Err(bad(
            "mesh",
            format!("{} does not exist (mesh paths are relative to the manifest)", mesh_path.display()),
        ));
    }
    let glass = match m.glass {
        Some(GlassToml::Skip) => GlassMode::Skip,
        _ => GlassMode::Transparent,
    };
    let unit = match (m.scale, m.meters_per_unit) {
        (Some(_), Some(_)) => {
            return Err(bad("meters_per_unit", "give meters_per_unit or its older name scale, not both".into()));
        }
        (Some(s), None) => Some(("scale", s)),
        (None, Some(s)) => Some(("meters_per_unit", s)),
        (None, None) => None,
    };
    if let Some((key, s)) = unit
        && !(s.is_finite() && s > 0.0)
    {
        return Err(bad(key, format!("{s} must be finite and > 0")));
    }
    let parts = load_parts(&mesh_path, unit.map(|u| u.1), glass, m.folder_lights.unwrap_or(true))?;
    let mut warnings = parts.warnings;
    let mut mesh = parts.geometry.mesh;
    let mut materials = parts.geometry.materials;
    let textures = parts.geometry.textures;
    let mut lights = parts.lights;
    let frames = m.frames.unwrap_or(DEFAULT_FRAMES);
    // Checked here so that the message names the manifest's field, not camera.json.
    if frames == 0 || frames > MAX_FRAMES {
        return Err(bad("frames", format!("must be in 1..={MAX_FRAMES}, not {frames}")));
    }
    let size = robust_size(&mesh);

    // Camera.
    let camera = match (&m.camera, &parts.camera) {
        (Some(c), folder) if !c.keys.is_empty() => {
            let vfov = c
                .vfov_deg
                .or(folder.as_ref().map(|f| f.1.vfov_deg))
                .ok_or_else(|| bad("camera.vfov_deg", "needed when there is no camera.json beside the mesh".into()))?;
            CameraPath::new(c.keys.clone(), frames, vfov).map_err(|e| bad("camera", e))?
        }
        (c, Some((cam_path, cam))) => {
            let mut cam = *cam;
            if let Some(v) = c.as_ref().and_then(|c| c.vfov_deg) {
                cam.vfov_deg = v;
            }
            path_around(&cam, parts.scale, size, frames).map_err(|e| SceneError::invalid(cam_path, e))?
        }
        (_, None) => {
            return Err(bad("camera", "no [camera] keys in the manifest and no camera.json beside the mesh".into()));
        }
    };

    // Materials.
    if let Some(mt) = &m.materials {
        if let Some(all) = &mt.all {
            if all.name.is_some() {
                return Err(bad(
                    "materials.all.name",
                    "materials.all applies to every material; use [[materials.set]]".into(),
                ));
            }
            materials.iter_mut().for_each(|mat| apply_override(mat, all));
        }
        for (i, o) in mt.set.iter().enumerate() {
            let key = format!("materials.set[{i}]");
            let Some(pattern) = &o.name else {
                return Err(bad(&key, "needs a name (or a '*' pattern)".into()));
            };
            let mut hit = false;
            for mat in materials.iter_mut().filter(|mat| glob_match(pattern, &mat.name)) {
                apply_override(mat, o);
                hit = true;
            }
            if !hit {
                let names: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
                return Err(bad(&key, format!("no material matches {pattern:?}; materials: {}", names.join(", "))));
            }
        }
    }

    // Lights.
    for (i, l) in m.lights.iter().enumerate() {
        let key = format!("lights[{i}]");
        match l {
            LightToml::Point { position, intensity } => {
                lights.points.push(PointLight::isotropic((*position).into(), (*intensity).into()))
            }
            LightToml::MovingPoint { name, intensity, keys } => lights.moving.push(MovingLight {
                name: name.clone().unwrap_or_else(|| key.clone()),
                shape: MovingShape::Point { intensity: (*intensity).into() },
                path: TransformPath::new(keys.clone()).map_err(|e| bad(&key, e))?,
            }),
            LightToml::MovingSphere { name, radius, radiance, subdivisions, keys } => {
                if !(radius.is_finite() && *radius > 0.0) || *subdivisions > 4 {
                    return Err(bad(&key, "radius must be > 0 and subdivisions <= 4".into()));
                }
                lights.moving.push(MovingLight {
                    name: name.clone().unwrap_or_else(|| key.clone()),
                    shape: MovingShape::sphere(*radius, *subdivisions, (*radiance).into()),
                    path: TransformPath::new(keys.clone()).map_err(|e| bad(&key, e))?,
                })
            }
            LightToml::Quad { corners, radiance } => {
                let c = corners.map(Vec3::from);
                let emitter = Material::emitter(format!("manifest_{key}"), (*radiance).into(), Vec3::splat(0.5));
                materials.push(emitter);
                let mid = materials.len() as u32 - 1;
                let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
                let extra = Mesh {
                    positions: vec![[c[0], c[1], c[2]], [c[0], c[2], c[3]]],
                    normals: Some(vec![[n; 3]; 2]),
                    uvs: None,
                    material: vec![0, 0],
                };
                mesh.append(&extra, mid);
            }
            LightToml::Sun { direction, irradiance, angular_radius_deg } => {
                lights.sun = Some(SunLight {
                    direction: Vec3::from(*direction).normalize_or_zero(),
                    irradiance: (*irradiance).into(),
                    angular_radius_deg: *angular_radius_deg,
                })
            }
            LightToml::Constant { radiance } => lights.environment = Some(Environment::Constant((*radiance).into())),
            LightToml::Sky { zenith, horizon, ground } => {
                lights.environment = Some(Environment::Sky(SkyGradient {
                    zenith: (*zenith).into(),
                    horizon: (*horizon).into(),
                    ground: (*ground).into(),
                }))
            }
            LightToml::Envmap { file, scale, to_world } => {
                let rows = to_world.unwrap_or([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
                let m3 = Mat3::from_cols_array_2d(&rows).transpose();
                let (map, bad_texels) = EnvMap::load_exr(&base.join(file), *scale, m3)?;
                if bad_texels > 0 {
                    warnings.push(format!("{file}: {bad_texels} negative or non-finite values set to 0"));
                }
                lights.environment = Some(Environment::Map(Box::new(map)));
            }
        }
    }

    // Moving objects, each with a material of its own appended to the materials.
    let mut objects = Vec::new();
    for (i, o) in m.objects.iter().enumerate() {
        let key = format!("objects[{i}]");
        let (name, triangles, keys) = match o {
            ObjectToml::MovingBox { name, size, keys, .. } => {
                if !size.iter().all(|s| s.is_finite() && *s > 0.0) {
                    return Err(bad(&key, format!("size {size:?} must be finite and > 0")));
                }
                (name, box_triangles((*size).into()), keys)
            }
            ObjectToml::MovingSphere { name, radius, subdivisions, keys, .. } => {
                if !(radius.is_finite() && *radius > 0.0) || *subdivisions > 4 {
                    return Err(bad(&key, "radius must be > 0 and subdivisions <= 4".into()));
                }
                (name, sphere_triangles(*radius, *subdivisions), keys)
            }
        };
        let name = name.clone().unwrap_or_else(|| key.clone());
        let object_material = o.material(format!("object_{name}"));
        object_material.validate(0).map_err(|e| bad(&key, e))?;
        materials.push(object_material);
        objects.push(MovingObject {
            name,
            triangles,
            material: materials.len() as u32 - 1,
            path: TransformPath::new(keys.clone()).map_err(|e| bad(&key, e))?,
        });
    }

    // Effects.
    let mut forced = EffectSet::EMPTY;
    for (name, on) in m.effects.iter().flatten() {
        let e = Effect::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Effect::ALL.iter().map(|e| e.name()).collect();
            bad(&format!("effects.{name}"), format!("unknown effect; effects: {}", names.join(", ")))
        })?;
        if *on {
            forced = forced.with(e);
        } else {
            strip(e, &mut materials, &mut lights);
            if e == Effect::MovingObjects {
                objects.clear();
            }
        }
    }

    let name = name_of(path, m.name);
    let mut scene = Scene {
        display_name: m.display_name.unwrap_or_else(|| name.clone()),
        name,
        paper_scene: m.paper_scene,
        source: SceneSource::Manifest(path.to_path_buf()),
        mesh,
        materials,
        textures,
        lights,
        moving_objects: objects,
        camera,
        tolerances: m.tolerances.unwrap_or_else(|| SceneTolerances::for_size(size)),
        effects: EffectSet::EMPTY,
        forced_effects: forced,
        units: parts.units,
        warnings,
    };
    scene.update()?;
    Ok(scene)
}

/// Removes the content that needs `effect` (see the module notes).
fn strip(effect: Effect, materials: &mut [Material], lights: &mut Lights) {
    match effect {
        Effect::Glossy => {
            materials.iter_mut().filter(|m| m.kind == MaterialKind::Glossy).for_each(Material::make_diffuse)
        }
        Effect::Mirror => {
            materials.iter_mut().filter(|m| m.kind == MaterialKind::Mirror).for_each(Material::make_diffuse)
        }
        Effect::Textures => materials.iter_mut().for_each(|m| m.albedo_texture = None),
        Effect::AlphaMasks => materials.iter_mut().for_each(|m| {
            m.opacity = 1.0;
            m.opacity_texture = None;
        }),
        Effect::MovingLights => lights.moving.clear(),
        // The objects are dropped by the caller (they are not lights or materials).
        Effect::MovingObjects => {}
        Effect::PointLights => {
            lights.points.clear();
            lights.moving.retain(|m| !matches!(m.shape, MovingShape::Point { .. }));
        }
        Effect::AreaLights => {
            materials.iter_mut().for_each(|m| m.emission = Vec3::ZERO);
            lights.moving.retain(|m| !matches!(m.shape, MovingShape::Area { .. }));
        }
        Effect::Sun => lights.sun = None,
        Effect::Sky => {
            if !matches!(lights.environment, Some(Environment::Map(_))) {
                lights.environment = None;
            }
        }
        Effect::EnvMap => {
            if let Some(Environment::Map(m)) = &lights.environment {
                lights.environment = Some(Environment::Constant(m.mean_radiance));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs() {
        assert!(glob_match("abc", "abc"));
        assert!(!glob_match("abc", "abd"));
        assert!(glob_match("*", "anything"));
        assert!(glob_match("sp_*", "sp_00_svod"));
        assert!(glob_match("*svod", "sp_00_svod"));
        assert!(glob_match("sp_*_svod", "sp_00_svod"));
        assert!(glob_match("s*0*d", "sp_00_svod"));
        assert!(!glob_match("sp_*x", "sp_00_svod"));
        assert!(!glob_match("ab*ba", "aba"));
    }
}

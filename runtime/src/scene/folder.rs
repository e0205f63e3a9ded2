//! Scene folders in the format of `../shared/scenes/*/`: `scene.obj`, `scene.mtl`,
//! `camera.json`, `lights.json`, `SOURCE.md` and textures.
//!
//! ## Units
//!
//! Scene units are metres. The scale comes from [`FolderOptions::scale`] when given, else from
//! `meters_per_unit` in `camera.json`, else from the `Units:` line of `SOURCE.md` (millimetres,
//! centimetres, metres, kilometres, inches and feet are recognised), else metres with a
//! warning; `camera.json` and `SOURCE.md` disagreeing is a warning too. So `cornell-box` (mm)
//! loads as a 0.556 m box. Camera and light positions are scaled with the geometry; radiance
//! is scale-free. [`Scene::units`] records the unit and where it came from.
//!
//! ## Camera
//!
//! `camera.json` gives one camera (`eye`, `target`, `up`, `vfov_deg`). A 60-frame smooth path
//! is synthesised around it: a forward dolly along the horizontal view direction of
//! `travel = clamp(0.05 × size, ·, 0.6 m)` (size = the robust scene extent below), a slight
//! lateral sway (±15 % of the travel) and a 5° pan to the right, all through four keys
//! (frames 0, 20, 40, 59) on the Catmull-Rom path. The first frame is exactly camera.json's view.
//!
//! ## Lights (`lights.json`)
//!
//! - `area`: already geometry (emissive material in the MTL); the entry is cross-checked
//!   against the material's `Ke` (mismatch: warning).
//! - `envmap`: a lat-long EXR with its `to_world` (row-major 4×4; its 3×3 part is used) and
//!   `scale`, in Mitsuba's convention (see [`EnvMap`]).
//! - `sunsky`: the sun becomes a [`SunLight`] along `sun_direction` with angular radius
//!   `0.2679° × sun_radius_scale` (Mitsuba's sun disc) and irradiance
//!   `sun_scale × (2.0, 1.85, 1.65)`; the sky becomes a [`SkyGradient`] with zenith
//!   `sky_scale × (0.06, 0.09, 0.16)`, horizon `sky_scale × (0.16, 0.17, 0.19)` and ground
//!   `albedo ×` the horizon. These absolute numbers are our choice (no Hosek–Wilkie model
//!   here): they give a clear-sky ratio of direct to diffuse irradiance of about 3:1 at the
//!   classroom's 25° sun elevation and a well-exposed interior at exposure 1.
//! - `constant`: a constant environment.
//! - Extensions (not in the shared scenes, accepted for hand-written folders): `point`
//!   (`position`, `intensity`), `spot` (`position`, `intensity`, `direction`,
//!   `inner_cone_deg` = 0, `outer_cone_deg` = 45: glTF's cone and falloff), `sun` (`direction`, `irradiance`, `angular_radius_deg`),
//!   `sky` (`zenith`, `horizon`, `ground`).
//!
//! A folder without `lights.json` is fine if its MTL has emitters; `camera.json` is required.

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use serde::Deserialize;

use super::effects::EffectSet;
use super::envmap::EnvMap;
use super::error::{Location, SceneError};
use super::gltf_file::load_gltf;
use super::light::{Environment, Lights, PointLight, SUN_RADIUS_DEG, SkyGradient, SpotCone, SunLight};
use super::mesh::Mesh;
use super::model::{Scene, SceneSource, SceneTolerances, Units, UnitsFrom};
use super::obj::{GlassMode, MeshData, ObjOptions, load_obj};
use super::path::{CameraKey, CameraPath, DEFAULT_FRAMES};

/// Options for [`load_folder`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FolderOptions {
    /// Scale to metres; `None` reads `SOURCE.md`.
    pub scale: Option<f32>,
    /// Glass handling.
    pub glass: GlassMode,
    /// Frames of the synthesised camera path.
    pub frames: u32,
}

impl Default for FolderOptions {
    fn default() -> Self {
        Self { scale: None, glass: GlassMode::Transparent, frames: DEFAULT_FRAMES }
    }
}

/// `camera.json`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct CameraJson {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up vector.
    #[serde(default = "up_y")]
    pub up: [f32; 3],
    /// Vertical field of view (degrees) for `width × height`.
    pub vfov_deg: f32,
    /// Film width the source was framed for.
    pub width: Option<u32>,
    /// Film height the source was framed for.
    pub height: Option<u32>,
    /// The file's length unit in metres (0.001 for millimetres).
    pub meters_per_unit: Option<f32>,
}

impl CameraJson {
    /// A camera at `eye` looking at `target`, with no film size or unit of its own (one that
    /// did not come from a `camera.json`).
    pub fn looking_at(eye: Vec3, target: Vec3, up: Vec3, vfov_deg: f32) -> Self {
        Self {
            eye: eye.into(),
            target: target.into(),
            up: up.into(),
            vfov_deg,
            width: None,
            height: None,
            meters_per_unit: None,
        }
    }

    /// Checks the fields a camera needs, naming the one at fault.
    pub fn validate(&self) -> Result<(), String> {
        let finite = |v: [f32; 3]| v.iter().all(|c| c.is_finite());
        for (name, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !finite(v) {
                return Err(format!("{name} {v:?} is not finite"));
            }
        }
        let view = Vec3::from(self.target) - Vec3::from(self.eye);
        if !(view.length() > 0.0) {
            return Err("eye == target: the view direction is undefined".into());
        }
        let up = Vec3::from(self.up);
        if !(up.length() > 0.0) {
            return Err(format!("up {:?} has zero length", self.up));
        }
        if view.normalize().cross(up.normalize()).length() < 1e-4 {
            return Err(format!("up {:?} is parallel to the view direction", self.up));
        }
        if !(self.vfov_deg > 1e-3 && self.vfov_deg < 179.0) {
            return Err(format!("vfov_deg {} must be in (0.001, 179) degrees", self.vfov_deg));
        }
        if let Some(m) = self.meters_per_unit
            && !(m.is_finite() && m > 0.0)
        {
            return Err(format!("meters_per_unit {m} must be finite and > 0"));
        }
        Ok(())
    }
}

fn up_y() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// One entry of `lights.json`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum LightJson {
    /// An emissive shape already in the mesh.
    Area {
        /// Emitting material name.
        material: Option<String>,
        /// Radiance (should equal the material's `Ke`).
        radiance: [f32; 3],
    },
    /// A lat-long EXR environment map.
    Envmap {
        /// File name relative to the folder. `null` or absent (what a converter writes when
        /// the scene's environment image was not exported) is refused with a message that
        /// says what to do, not a type error.
        #[serde(default)]
        filename: Option<String>,
        /// Radiance scale.
        #[serde(default = "one")]
        scale: f32,
        /// Row-major 4×4 (or 3×3) local-to-world matrix.
        to_world: Vec<Vec<f32>>,
    },
    /// Mitsuba sun + sky parameters.
    Sunsky {
        /// Unit vector towards the sun.
        sun_direction: [f32; 3],
        /// Sky brightness multiplier.
        #[serde(default = "one")]
        sky_scale: f32,
        /// Sun brightness multiplier.
        #[serde(default = "one")]
        sun_scale: f32,
        /// Sun disc radius multiplier.
        #[serde(default = "one")]
        sun_radius_scale: f32,
        /// Ground albedo.
        #[serde(default = "ground_albedo")]
        albedo: f32,
    },
    /// A constant environment.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
    },
    /// A point light (extension).
    Point {
        /// Position (scaled with the geometry).
        position: [f32; 3],
        /// Radiant intensity.
        intensity: [f32; 3],
    },
    /// A spot light (extension): a point light with glTF's cone and falloff.
    Spot {
        /// Position (scaled with the geometry).
        position: [f32; 3],
        /// Radiant intensity on the axis.
        intensity: [f32; 3],
        /// Direction the light points to.
        direction: [f32; 3],
        /// Inner cone angle in degrees (full intensity within it).
        #[serde(default)]
        inner_cone_deg: f32,
        /// Outer cone angle in degrees (no light beyond it).
        #[serde(default = "spot_outer")]
        outer_cone_deg: f32,
    },
    /// A directional sun (extension).
    Sun {
        /// Unit vector towards the sun.
        direction: [f32; 3],
        /// Irradiance facing the sun.
        irradiance: [f32; 3],
        /// Disc radius in degrees.
        #[serde(default = "sun_radius")]
        angular_radius_deg: f32,
    },
    /// A sky gradient (extension).
    Sky {
        /// Zenith radiance.
        zenith: [f32; 3],
        /// Horizon radiance.
        horizon: [f32; 3],
        /// Below-horizon radiance.
        ground: [f32; 3],
    },
}

fn one() -> f32 {
    1.0
}
fn ground_albedo() -> f32 {
    0.15
}
fn spot_outer() -> f32 {
    45.0
}
fn sun_radius() -> f32 {
    SUN_RADIUS_DEG
}

/// Reads and parses a JSON file; syntax errors carry line and column.
/// A `null` refused by serde is explained, naming the field when the object has one null.
pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| {
        let value: Option<serde_json::Value> = e.is_data().then(|| serde_json::from_str(&text).ok()).flatten();
        let mut nulls = value.iter().filter_map(|v| v.as_object()).flatten().filter(|(_, v)| v.is_null());
        let field = match (nulls.next(), nulls.next()) {
            (Some((key, _)), None) => Some(key.as_str()),
            _ => None,
        };
        SceneError::Parse {
            location: Location::at(path, e.line().max(1), e.column().max(1)),
            message: explain_null(field, &json_message(&e)),
        }
    })
}

/// serde_json's message without the " at line L column C" it appends: the error's location
/// says that once already.
fn json_message(e: &serde_json::Error) -> String {
    let full = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    full.strip_suffix(&suffix).map_or(full.clone(), str::to_owned)
}

/// serde's `invalid type: null, expected X` as a sentence a scene author can act on: the
/// field is null where a value is required (converters write null for what they could not
/// translate). Other messages pass unchanged.
fn explain_null(field: Option<&str>, message: &str) -> String {
    match (message.strip_prefix("invalid type: null, expected "), field) {
        (Some(expected), Some(f)) => format!("field {f:?} is null, but {expected} is required: give it a value"),
        (Some(expected), None) => format!("a field is null, but {expected} is required: give it a value"),
        (None, Some(f)) => format!("field {f:?}: {message}"),
        (None, None) => message.to_owned(),
    }
}

/// Reads `lights.json`. serde reports a wrong value inside an internally tagged entry
/// (`"filename": null`) without the field, at the entry's closing bracket; so when the typed
/// parse fails on valid JSON, the entries are parsed again one by one to name the entry, its
/// type and the field at fault (the position stays serde's).
fn read_lights(path: &Path) -> Result<Vec<LightJson>, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| {
        let detail =
            e.is_data().then(|| serde_json::from_str::<Vec<serde_json::Value>>(&text).ok()).flatten().and_then(
                |entries| {
                    entries.iter().enumerate().find_map(|(i, entry)| {
                        serde_json::from_value::<LightJson>(entry.clone())
                            .err()
                            .map(|refused| light_error(i, entry, &refused))
                    })
                },
            );
        SceneError::Parse {
            location: Location::at(path, e.line().max(1), e.column().max(1)),
            message: detail.unwrap_or_else(|| json_message(&e)),
        }
    })
}

/// The message for entry `index` of `lights.json` that serde refused with `e`. The field at
/// fault is the one that, alone in an entry of the same type, is refused the same way.
fn light_error(index: usize, entry: &serde_json::Value, e: &serde_json::Error) -> String {
    use serde_json::{Map, Value};
    let message = json_message(e);
    let kind = entry.get("type").and_then(Value::as_str).map_or(String::new(), |t| format!(" (type {t:?})"));
    let field = entry.as_object().and_then(|object| {
        object.iter().filter(|(k, _)| *k != "type").find_map(|(key, value)| {
            let mut alone = Map::new();
            if let Some(t) = object.get("type") {
                alone.insert("type".into(), t.clone());
            }
            alone.insert(key.clone(), value.clone());
            let refused = serde_json::from_value::<LightJson>(Value::Object(alone)).err()?;
            (json_message(&refused) == message).then(|| key.clone())
        })
    });
    let separator = if field.is_some() { "," } else { ":" };
    format!("light {index}{kind}{separator} {}", explain_null(field.as_deref(), &message))
}

/// The sun and sky of a Mitsuba `sunsky` entry (see the module notes for the numbers).
pub fn sunsky(
    direction: Vec3,
    sky_scale: f32,
    sun_scale: f32,
    sun_radius_scale: f32,
    albedo: f32,
) -> (SunLight, SkyGradient) {
    let horizon = Vec3::new(0.16, 0.17, 0.19) * sky_scale;
    let sky = SkyGradient { zenith: Vec3::new(0.06, 0.09, 0.16) * sky_scale, horizon, ground: horizon * albedo };
    let sun = SunLight {
        direction: direction.normalize_or(Vec3::Y),
        irradiance: Vec3::new(2.0, 1.85, 1.65) * sun_scale,
        angular_radius_deg: (SUN_RADIUS_DEG * sun_radius_scale).clamp(0.01, 45.0),
    };
    (sun, sky)
}

/// Applies `lights.json` entries to `lights` (environment and sun replace earlier ones).
/// `dir` resolves file names, `scale` scales positions, `materials` cross-checks area lights.
pub(crate) fn apply_light_json(
    entries: &[LightJson],
    json_path: &Path,
    dir: &Path,
    scale: f32,
    obj: &MeshData,
    lights: &mut Lights,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let bad = |i: usize, m: String| SceneError::invalid(json_path, format!("light {i}: {m}"));
    let finite3 = |v: [f32; 3]| Vec3::from(v).is_finite();
    for (i, e) in entries.iter().enumerate() {
        match e {
            LightJson::Area { material, radiance } => {
                let Some(name) = material else { continue };
                match obj.materials.iter().find(|m| &m.name == name) {
                    None => warnings
                        .push(format!("{}: light {i}: area material {name:?} is not in the MTL", json_path.display())),
                    Some(m)
                        if (m.emission - Vec3::from(*radiance)).abs().max_element()
                            > 1e-3 * m.emission.max_element().max(1.0) =>
                    {
                        warnings.push(format!(
                            "{}: light {i}: radiance {:?} differs from {name:?}'s Ke {}; Ke is used",
                            json_path.display(),
                            radiance,
                            m.emission
                        ))
                    }
                    Some(_) => {}
                }
            }
            LightJson::Envmap { filename, scale: s, to_world } => {
                let Some(filename) = filename else {
                    return Err(bad(
                        i,
                        "an \"envmap\" light has no image (\"filename\" is null or missing): name a \
                         lat-long EXR file in the scene folder, or drop this entry to render without \
                         the environment"
                            .into(),
                    ));
                };
                let rows: Vec<&[f32]> = to_world.iter().map(|r| &r[..]).collect();
                let ok = (rows.len() == 3 || rows.len() == 4) && rows.iter().all(|r| r.len() >= 3);
                if !ok {
                    return Err(bad(i, "to_world must be a 3x3 or 4x4 row-major matrix".into()));
                }
                let m = Mat3::from_cols(
                    Vec3::new(rows[0][0], rows[1][0], rows[2][0]),
                    Vec3::new(rows[0][1], rows[1][1], rows[2][1]),
                    Vec3::new(rows[0][2], rows[1][2], rows[2][2]),
                );
                let (map, bad_texels) = EnvMap::load_exr(&dir.join(filename), *s, m)?;
                if bad_texels > 0 {
                    warnings.push(format!("{filename}: {bad_texels} negative or non-finite values set to 0"));
                }
                lights.environment = Some(Environment::Map(Box::new(map)));
            }
            LightJson::Sunsky { sun_direction, sky_scale, sun_scale, sun_radius_scale, albedo } => {
                if !finite3(*sun_direction) || Vec3::from(*sun_direction).length() < 1e-6 {
                    return Err(bad(i, "sun_direction must be a finite non-zero vector".into()));
                }
                let (sun, sky) = sunsky(Vec3::from(*sun_direction), *sky_scale, *sun_scale, *sun_radius_scale, *albedo);
                lights.sun = Some(sun);
                lights.environment = Some(Environment::Sky(sky));
            }
            LightJson::Constant { radiance } => lights.environment = Some(Environment::Constant(Vec3::from(*radiance))),
            LightJson::Point { position, intensity } => {
                lights.points.push(PointLight::isotropic(Vec3::from(*position) * scale, Vec3::from(*intensity)))
            }
            LightJson::Spot { position, intensity, direction, inner_cone_deg, outer_cone_deg } => {
                let cone =
                    SpotCone::new(Vec3::from(*direction), inner_cone_deg.to_radians(), outer_cone_deg.to_radians())
                        .map_err(|m| bad(i, m))?;
                lights.points.push(PointLight {
                    position: Vec3::from(*position) * scale,
                    intensity: Vec3::from(*intensity),
                    spot: Some(cone),
                })
            }
            LightJson::Sun { direction, irradiance, angular_radius_deg } => {
                lights.sun = Some(SunLight {
                    direction: Vec3::from(*direction).normalize_or_zero(),
                    irradiance: Vec3::from(*irradiance),
                    angular_radius_deg: *angular_radius_deg,
                })
            }
            LightJson::Sky { zenith, horizon, ground } => {
                lights.environment = Some(Environment::Sky(SkyGradient {
                    zenith: (*zenith).into(),
                    horizon: (*horizon).into(),
                    ground: (*ground).into(),
                }))
            }
        }
    }
    Ok(())
}

/// The `Units:` scale stated in a `SOURCE.md`, if its words name a unit this recognises.
pub fn scale_from_source_md(text: &str) -> Option<f32> {
    let line = text.lines().find(|l| l.contains("Units:"))?;
    let after = line.split_once("Units:")?.1.trim_start().to_ascii_lowercase();
    let after = after.strip_prefix("about ").unwrap_or(&after);
    let word = |w: &str| after.starts_with(w);
    if word("millimet") || word("mm") {
        Some(0.001)
    } else if word("centimet") || word("cm") {
        Some(0.01)
    } else if word("kilomet") || word("km") {
        Some(1000.0)
    } else if word("metre") || word("meter") || word("m ") || word("m.") || after.contains("1 unit = 1 m") {
        Some(1.0)
    } else if word("inch") {
        Some(0.0254)
    } else if word("feet") || word("foot") || word("ft") {
        Some(0.3048)
    } else {
        None
    }
}

/// The unit of a folder's files: `explicit` (an option or a manifest key) first, then
/// `camera.json`'s `meters_per_unit`, then `SOURCE.md`'s `Units:` line, else metres with a
/// warning.
fn folder_units(explicit: Option<f32>, camera: Option<&CameraJson>, dir: &Path, warnings: &mut Vec<String>) -> Units {
    let source_md = std::fs::read_to_string(dir.join("SOURCE.md")).ok();
    let stated = source_md.as_deref().and_then(scale_from_source_md);
    let from_camera = camera.and_then(|c| c.meters_per_unit);
    if let (Some(c), Some(s)) = (from_camera, stated)
        && (c / s - 1.0).abs() > 1e-3
    {
        warnings.push(format!(
            "{}: camera.json says meters_per_unit = {c} but SOURCE.md's Units line says {s}; camera.json is used",
            dir.display()
        ));
    }
    match (explicit, from_camera, stated) {
        (Some(m), ..) => Units { meters_per_unit: m, from: UnitsFrom::Manifest },
        (None, Some(m), _) => Units { meters_per_unit: m, from: UnitsFrom::CameraJson },
        (None, None, Some(m)) => Units { meters_per_unit: m, from: UnitsFrom::SourceMd },
        (None, None, None) => {
            warnings.push(format!(
                "{}: the scene's unit is unknown (no meters_per_unit in camera.json, no recognised Units: line in \
                 SOURCE.md): loaded as metres",
                dir.display()
            ));
            Units { meters_per_unit: 1.0, from: UnitsFrom::Assumed }
        }
    }
}

/// Typical size of the geometry: the largest per-axis extent between the 2nd and 98th
/// percentiles of (a sample of) vertex coordinates. Robust to a few far-away vertices, such
/// as the classroom's 221 m ground quad.
pub fn robust_size(mesh: &Mesh) -> f32 {
    let n = mesh.len();
    if n == 0 {
        return 1.0;
    }
    let stride = (n / 50_000).max(1);
    let mut axes: [Vec<f32>; 3] = Default::default();
    for t in mesh.positions.iter().step_by(stride) {
        for p in t {
            for (a, v) in axes.iter_mut().zip(p.to_array()) {
                a.push(v);
            }
        }
    }
    axes.iter_mut()
        .map(|a| {
            let m = a.len();
            let (lo, hi) = ((m as f32 * 0.02) as usize, ((m as f32 * 0.98) as usize).min(m - 1));
            let l = *a.select_nth_unstable_by(lo, f32::total_cmp).1;
            let h = *a.select_nth_unstable_by(hi, f32::total_cmp).1;
            h - l
        })
        .fold(0.0f32, f32::max)
        .max(1e-3)
}

/// The synthesised camera path around one camera (see the module notes).
pub fn path_around(cam: &CameraJson, scale: f32, size: f32, frames: u32) -> Result<CameraPath, String> {
    let eye = Vec3::from(cam.eye) * scale;
    let target = Vec3::from(cam.target) * scale;
    let up = Vec3::from(cam.up).normalize_or(Vec3::Y);
    let view = target - eye;
    let dir = view.try_normalize().ok_or("camera eye == target")?;
    let flat = Vec3::new(dir.x, 0.0, dir.z);
    let forward = if flat.length() > 0.1 { flat.normalize() } else { dir };
    let right = forward.cross(Vec3::Y).try_normalize().unwrap_or_else(|| forward.any_orthonormal_vector());
    let travel = (0.05 * size).min(0.6);
    let last = frames.saturating_sub(1).max(1) as f32;
    let keys =
        [(0.0, 0.0, 0.0, 0.0), (20.0 / 59.0, 0.33, 0.15, 1.8), (40.0 / 59.0, 0.67, 0.10, 3.6), (1.0, 1.0, -0.05, 5.0)]
            .map(|(t, s, l, yaw): (f32, f32, f32, f32)| {
                // Pan right: rotate about +Y by −yaw (right-handed, +Y up).
                let rot = glam::Quat::from_rotation_y(-yaw.to_radians());
                let e = eye + forward * (s * travel) + right * (l * travel);
                CameraKey { frame: t * last, eye: e.into(), target: (e + rot * view).into(), up: (rot * up).into() }
            });
    let keys = if frames <= 1 { vec![keys[0]] } else { keys.to_vec() };
    CameraPath::new(keys, frames, cam.vfov_deg)
}

/// Paper scene names of the shared folders.
fn paper_scene(folder: &str) -> Option<&'static str> {
    match folder {
        "sponza" => Some("Sponza"),
        "living-room" => Some("Living Room"),
        "classroom" => Some("Classroom"),
        _ => None,
    }
}

/// The parts of a folder a manifest builds on.
pub(crate) struct FolderParts {
    /// Triangles, materials and textures, in metres.
    pub geometry: MeshData,
    /// What `path_around` multiplies the camera by: the mesh file's unit in metres.
    pub scale: f32,
    pub units: Units,
    /// The camera (glTF's own, else `camera.json`'s), in the mesh file's units.
    pub camera: Option<(PathBuf, CameraJson)>,
    pub lights: Lights,
    pub warnings: Vec<String>,
}

/// True for a `.gltf` or `.glb` path.
pub fn is_gltf(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// The scene file of a folder: `scene.obj`, else `scene.glb`, else `scene.gltf`.
pub fn scene_file(dir: &Path) -> Option<PathBuf> {
    ["scene.obj", "scene.glb", "scene.gltf"].into_iter().map(|name| dir.join(name)).find(|p| p.is_file())
}

/// Loads the mesh file at `mesh_path` (OBJ or glTF) plus `camera.json` / `lights.json` /
/// `SOURCE.md` beside it when present (`with_lights = false` ignores lights.json).
///
/// Beside a glTF file, which is in metres, `camera.json` and `lights.json` are in
/// `camera.json`'s own `meters_per_unit` (metres when absent), and a camera in the glTF file
/// wins over `camera.json`.
pub(crate) fn load_parts(
    mesh_path: &Path,
    scale: Option<f32>,
    glass: GlassMode,
    with_lights: bool,
) -> Result<FolderParts, SceneError> {
    let dir = mesh_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let camera_path = dir.join("camera.json");
    let camera = if camera_path.is_file() {
        let c: CameraJson = read_json(&camera_path)?;
        c.validate().map_err(|m| SceneError::invalid(&camera_path, m))?;
        Some((camera_path, c))
    } else {
        None
    };
    let lights_path = dir.join("lights.json");
    let light_entries = if with_lights && lights_path.is_file() { Some(read_lights(&lights_path)?) } else { None };
    let mut warnings = Vec::new();
    if is_gltf(mesh_path) {
        let units = match scale {
            Some(m) => Units { meters_per_unit: m, from: UnitsFrom::Manifest },
            None => Units { meters_per_unit: 1.0, from: UnitsFrom::Gltf },
        };
        let data = load_gltf(mesh_path, units.meters_per_unit)?;
        warnings.extend(data.geometry.warnings.iter().cloned());
        let sidecar_scale = camera.as_ref().and_then(|c| c.1.meters_per_unit).unwrap_or(1.0);
        let camera = match (data.camera, camera) {
            (Some(own), sidecar) => {
                if let Some((p, _)) = sidecar {
                    warnings.push(format!("{}: not used: {} has its own camera", p.display(), mesh_path.display()));
                }
                Some((mesh_path.to_path_buf(), CameraJson::looking_at(own.eye, own.target, own.up, own.vfov_deg)))
            }
            (None, Some((p, mut c))) => {
                // In the glTF file's units, which `path_around` scales to metres.
                let to_file_units = sidecar_scale / units.meters_per_unit;
                c.eye = (Vec3::from(c.eye) * to_file_units).into();
                c.target = (Vec3::from(c.target) * to_file_units).into();
                Some((p, c))
            }
            (None, None) => None,
        };
        let mut lights = data.lights;
        if let Some(entries) = &light_entries {
            apply_light_json(entries, &lights_path, &dir, sidecar_scale, &data.geometry, &mut lights, &mut warnings)?;
        }
        return Ok(FolderParts {
            geometry: data.geometry,
            scale: units.meters_per_unit,
            units,
            camera,
            lights,
            warnings,
        });
    }
    let units = folder_units(scale, camera.as_ref().map(|c| &c.1), &dir, &mut warnings);
    let scale = units.meters_per_unit;
    let geometry = load_obj(mesh_path, &ObjOptions { scale, glass })?;
    warnings.extend(geometry.warnings.iter().cloned());
    let mut lights = Lights::default();
    if let Some(entries) = &light_entries {
        apply_light_json(entries, &lights_path, &dir, scale, &geometry, &mut lights, &mut warnings)?;
    }
    Ok(FolderParts { geometry, scale, units, camera, lights, warnings })
}

/// The name a scene folder's scene gets: the folder's own name (after resolving `.` and `..`).
pub fn folder_name(dir: &Path) -> String {
    dir.canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .or_else(|| dir.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "scene".into())
}

/// The name a scene file's scene gets: its stem, or its folder's name for `scene.*`.
pub fn file_scene_name(file: &Path) -> String {
    match file.file_stem().map(|s| s.to_string_lossy().into_owned()) {
        Some(stem) if stem != "scene" => stem,
        _ => folder_name(file.parent().unwrap_or(Path::new("."))),
    }
}

/// A camera that frames the whole mesh (in file units: `mesh` is in metres, `scale` is
/// metres per file unit), for a glTF file with no camera of its own and no `camera.json`:
/// looking down -Z at the bounds' centre from slightly above, the bounding sphere filling a
/// 45° field of view.
fn framing_camera(mesh: &Mesh, scale: f32) -> CameraJson {
    let bounds = mesh.bounds();
    let centre = bounds.centre() / scale;
    let radius = (0.5 * bounds.extent().length() / scale).max(1e-3);
    let vfov_deg: f32 = 45.0;
    let distance = radius / (0.5 * vfov_deg).to_radians().sin();
    let eye = centre + Vec3::new(0.0, 0.25, 1.0).normalize() * distance;
    CameraJson::looking_at(eye, centre, Vec3::Y, vfov_deg)
}

/// Loads a scene folder (see the module notes): its `scene.obj`, `scene.glb` or `scene.gltf`.
pub fn load_folder(dir: &Path, options: &FolderOptions) -> Result<Scene, SceneError> {
    let Some(file) = scene_file(dir) else {
        return Err(SceneError::io(
            &dir.join("scene.obj"),
            std::io::Error::new(std::io::ErrorKind::NotFound, "no scene.obj, scene.glb or scene.gltf in the folder"),
        ));
    };
    load_scene_file(&file, options)
}

/// Loads a scene file (OBJ or glTF) with the `camera.json`, `lights.json` and `SOURCE.md`
/// beside it. An OBJ needs `camera.json`; a glTF file without a camera of either kind gets
/// one that frames it (looking down -Z at the bounds from slightly above), with a warning.
pub fn load_scene_file(file: &Path, options: &FolderOptions) -> Result<Scene, SceneError> {
    let dir = file.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut parts = load_parts(file, options.scale, options.glass, true)?;
    let (camera_path, cam) = match parts.camera.take() {
        Some(camera) => camera,
        None if is_gltf(file) => {
            parts.warnings.push(format!(
                "{}: no camera in the file and no camera.json beside it: a camera framing the scene is used",
                file.display()
            ));
            (file.to_path_buf(), framing_camera(&parts.geometry.mesh, parts.scale))
        }
        None => {
            return Err(SceneError::io(
                &dir.join("camera.json"),
                std::io::Error::new(std::io::ErrorKind::NotFound, "camera.json is required in a scene folder"),
            ));
        }
    };
    let size = robust_size(&parts.geometry.mesh);
    let camera =
        path_around(&cam, parts.scale, size, options.frames).map_err(|m| SceneError::invalid(&camera_path, m))?;
    let name = file_scene_name(file);
    let paper = paper_scene(&name);
    let title = std::fs::read_to_string(dir.join("SOURCE.md"))
        .ok()
        .and_then(|t| t.lines().next().and_then(|l| l.strip_prefix("# ")).map(str::to_owned));
    let display_name = match (paper, &title) {
        (Some(p), _) => format!("{p} ({name}, loaded)"),
        (None, Some(t)) => t.clone(),
        (None, None) => name.clone(),
    };
    let source = if is_gltf(file) { SceneSource::File(file.to_path_buf()) } else { SceneSource::Folder(dir) };
    let mut scene = Scene {
        name,
        display_name,
        paper_scene: paper.map(str::to_owned),
        source,
        mesh: parts.geometry.mesh,
        materials: parts.geometry.materials,
        textures: parts.geometry.textures,
        lights: parts.lights,
        moving_objects: Vec::new(),
        camera,
        tolerances: SceneTolerances::for_size(size),
        effects: EffectSet::EMPTY,
        forced_effects: EffectSet::EMPTY,
        units: parts.units,
        warnings: parts.warnings,
    };
    scene.update()?;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_lines_give_scales() {
        assert_eq!(scale_from_source_md("- Units: Millimetres. The box"), Some(0.001));
        assert_eq!(scale_from_source_md("- Units: 1 unit = 1 m."), Some(1.0));
        assert_eq!(scale_from_source_md("- Units: About 1 unit = 1 m."), Some(1.0));
        assert_eq!(scale_from_source_md("no units here"), None);
        assert_eq!(scale_from_source_md("- Units: Centimetres (the source's)"), Some(0.01));
        assert_eq!(scale_from_source_md("- Units: feet"), Some(0.3048));
        assert_eq!(scale_from_source_md("- Units: unknown, maybe cubits"), None);
    }

    #[test]
    fn synthesised_path_starts_at_the_camera_and_moves_gently() {
        let cam = CameraJson {
            eye: [5.1, 0.73, -2.3],
            target: [4.14, 0.8, -2.05],
            up: [0.07, 0.997, -0.02],
            vfov_deg: 58.7,
            meters_per_unit: None,
            width: None,
            height: None,
        };
        let p = path_around(&cam, 1.0, 5.6, 60).unwrap();
        let first = p.pose(0);
        assert!((first.eye - Vec3::from(cam.eye)).length() < 1e-5);
        let d = (Vec3::from(cam.target) - Vec3::from(cam.eye)).normalize();
        assert!(first.forward.dot(d) > 0.99999);
        let travel = (p.pose(59).eye - first.eye).length();
        assert!(travel > 0.2 && travel < 0.4, "{travel}");
        let yaw = p.pose(59).forward.dot(first.forward).acos().to_degrees();
        assert!((4.0..6.0).contains(&yaw), "{yaw}");
        assert!(p.poses().iter().all(|q| q.up.y > 0.99), "no roll");
    }

    #[test]
    fn sunsky_numbers() {
        let (sun, sky) = sunsky(Vec3::new(-0.866, 0.417, -0.277), 6.0, 10.0, 18.8131, 0.15);
        assert!((sun.angular_radius_deg - 5.04).abs() < 0.01);
        assert!((sun.direction.length() - 1.0).abs() < 1e-5);
        assert!(sky.zenith.z > sky.zenith.x, "blue zenith");
    }
}

//! Writing a scene as a folder in the shared format (`scene.obj`, `scene.mtl`, `camera.json`,
//! `lights.json`, textures), so that any scene — a built-in, a manifest's variant — can be
//! read by another renderer (the Mitsuba reference of `tools/reference/`) or edited by hand.
//!
//! The folder holds the scene **at frame 0**: the camera of frame 0 (`camera.json`), and moving
//! lights placed where they are at frame 0 as static lights (area lights become emissive
//! triangles, points point lights). Coordinates are the scene's own (metres:
//! `meters_per_unit = 1`). Positions, normals, UVs and colours are written in Rust's shortest
//! round-trip notation, so geometry and materials load back bit for bit; albedo textures
//! become 8-bit sRGB PNGs (what the format reads), masks 8-bit grey PNGs, an environment map
//! a float EXR.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;
use serde_json::json;

use super::error::SceneError;
use super::light::{Environment, MovingShape};
use super::material::MaterialKind;
use super::model::Scene;
use super::texture::Texture;
use super::texture::linear_to_srgb;
use crate::kernels::{Extent, RgbBuf};

/// What [`export_folder`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportSummary {
    /// Triangles written.
    pub triangles: usize,
    /// Materials written.
    pub materials: usize,
    /// Image files written (textures and the environment map).
    pub images: usize,
    /// Moving lights frozen at their frame-0 placement.
    pub frozen_lights: usize,
}

/// Writes `scene` at frame 0 into `dir` (created if needed; existing files of the same names
/// are replaced).
pub fn export_folder(scene: &Scene, dir: &Path) -> Result<ExportSummary, SceneError> {
    std::fs::create_dir_all(dir).map_err(|e| SceneError::io(dir, e))?;
    let write = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| SceneError::io(&path, e))
    };
    let names = material_names(scene);
    let mut images = 0;
    let mut mtl = String::from("# written by stereotrace export-scene: linear RGB, map_Kd sRGB\n");
    for (i, m) in scene.materials.iter().enumerate() {
        let v = |c: Vec3| format!("{} {} {}", c.x, c.y, c.z);
        let illum = match m.kind {
            MaterialKind::Diffuse => 1,
            MaterialKind::Glossy => 2,
            MaterialKind::Mirror => 3,
        };
        let roughness = if m.kind == MaterialKind::Mirror { 0.0 } else { m.roughness };
        let _ = write!(
            mtl,
            "\nnewmtl {}\nKd {}\nKs {}\nKe {}\nPr {roughness}\nd {}\nillum {illum}\n",
            names[i],
            v(m.albedo),
            v(m.specular),
            v(m.emission),
            m.opacity
        );
        if m.metallic {
            mtl.push_str("Pm 1\n");
        }
        if let Some(t) = m.albedo_texture {
            let file = format!("{}_albedo.png", names[i]);
            write_albedo_png(&scene.textures[t as usize], m.texture_scale, &dir.join(&file))?;
            let _ = writeln!(mtl, "map_Kd {file}");
            images += 1;
        }
        if let Some(t) = m.opacity_texture {
            let file = format!("{}_mask.png", names[i]);
            write_mask_png(&scene.textures[t as usize], &dir.join(&file))?;
            let _ = writeln!(mtl, "map_d {file}");
            images += 1;
        }
    }

    let mut obj = String::from("# written by stereotrace export-scene (frame 0)\nmtllib scene.mtl\n");
    let mut counts = ObjCounts::default();
    let mesh = &scene.mesh;
    for (mat, name) in names.iter().enumerate() {
        let tris: Vec<usize> = (0..mesh.len()).filter(|&t| mesh.material[t] as usize == mat).collect();
        if tris.is_empty() {
            continue;
        }
        let _ = write!(obj, "o {name}\nusemtl {name}\n");
        for t in tris {
            let uvs = mesh.uvs.as_ref().map(|u| u[t]);
            let normals = mesh.normals.as_ref().map(|n| n[t]);
            counts.triangle(&mut obj, mesh.positions[t], uvs.as_ref(), normals.as_ref());
        }
    }

    // Moving lights at frame 0, as static lights.
    let mut points: Vec<serde_json::Value> = scene
        .lights
        .points
        .iter()
        .map(|p| match &p.spot {
            None => json!({"type": "point", "position": p.position.to_array(), "intensity": p.intensity.to_array()}),
            Some(cone) => json!({
                "type": "spot",
                "position": p.position.to_array(),
                "intensity": p.intensity.to_array(),
                "direction": cone.direction.to_array(),
                "inner_cone_deg": cone.cos_inner.clamp(-1.0, 1.0).acos().to_degrees(),
                "outer_cone_deg": cone.cos_outer.clamp(-1.0, 1.0).acos().to_degrees(),
            }),
        })
        .collect();
    let mut mtl_frozen = String::new();
    for (k, light) in scene.lights.moving.iter().enumerate() {
        let transform = light.path.transform(0.0);
        match &light.shape {
            MovingShape::Point { intensity } => points.push(json!({
                "type": "point",
                "position": Vec3::from(transform.translation).to_array(),
                "intensity": intensity.to_array(),
                "note": format!("moving light {:?} at frame 0", light.name),
            })),
            MovingShape::Area { triangles, radiance } => {
                let name = format!("moving_light_{k}");
                let _ = write!(
                    mtl_frozen,
                    "\nnewmtl {name}\nKd 0 0 0\nKs 0 0 0\nKe {} {} {}\nillum 1\n",
                    radiance.x, radiance.y, radiance.z
                );
                let _ = write!(obj, "o {name}\nusemtl {name}\n");
                for tri in triangles {
                    counts.triangle(&mut obj, tri.map(|p| transform.transform_point3(p)), None, None);
                }
            }
        }
    }
    // Moving objects at frame 0, as static triangles of their own material.
    for (k, object) in scene.moving_objects.iter().enumerate() {
        let _ = write!(obj, "o moving_object_{k}\nusemtl {}\n", names[object.material as usize]);
        for tri in object.at_frame(0.0) {
            counts.triangle(&mut obj, tri, None, None);
        }
    }
    mtl.push_str(&mtl_frozen);

    let mut lights = points;
    for (m, name) in scene.materials.iter().zip(&names) {
        if m.emission != Vec3::ZERO {
            lights.push(json!({"type": "area", "material": name, "radiance": m.emission.to_array()}));
        }
    }
    if let Some(sun) = &scene.lights.sun {
        lights.push(json!({
            "type": "sun",
            "direction": sun.direction.to_array(),
            "irradiance": sun.irradiance.to_array(),
            "angular_radius_deg": sun.angular_radius_deg,
        }));
    }
    match &scene.lights.environment {
        None => {}
        Some(Environment::Constant(c)) => lights.push(json!({"type": "constant", "radiance": c.to_array()})),
        Some(Environment::Sky(s)) => lights.push(json!({
            "type": "sky",
            "zenith": s.zenith.to_array(),
            "horizon": s.horizon.to_array(),
            "ground": s.ground.to_array(),
        })),
        Some(Environment::Map(map)) => {
            let file = "environment.exr";
            write_environment_exr(&map.texture, &dir.join(file))?;
            images += 1;
            let m = map.to_world;
            let rows: Vec<[f32; 4]> = (0..3).map(|r| [m.x_axis[r], m.y_axis[r], m.z_axis[r], 0.0]).collect();
            let mut rows: Vec<Vec<f32>> = rows.into_iter().map(|r| r.to_vec()).collect();
            rows.push(vec![0.0, 0.0, 0.0, 1.0]);
            lights.push(json!({"type": "envmap", "filename": file, "scale": map.scale, "to_world": rows}));
        }
    }

    let pose = scene.camera.pose_at(0.0);
    let focus = scene.camera.keys.first().map_or(1.0, |k| (Vec3::from(k.target) - Vec3::from(k.eye)).length());
    let camera = json!({
        "eye": pose.eye.to_array(),
        "target": (pose.eye + pose.forward * focus.max(1e-3)).to_array(),
        "up": pose.up.to_array(),
        "vfov_deg": pose.vfov_deg,
        "width": 1280,
        "height": 720,
        "meters_per_unit": 1.0,
    });
    let pretty = |v: &serde_json::Value| serde_json::to_string_pretty(v).expect("JSON values serialise");
    write("scene.obj", &obj)?;
    write("scene.mtl", &mtl)?;
    write("camera.json", &pretty(&camera))?;
    write("lights.json", &pretty(&serde_json::Value::Array(lights)))?;
    write(
        "SOURCE.md",
        &format!(
            "# {} (exported)\n\nWritten by `stereotrace export-scene` from `{}` at frame 0.\n\n- Units: 1 unit = 1 m.\n",
            scene.display_name,
            scene.source.path().display()
        ),
    )?;
    Ok(ExportSummary {
        triangles: counts.triangles,
        materials: scene.materials.len(),
        images,
        frozen_lights: scene.lights.moving.len(),
    })
}

/// MTL-safe, unique material names (whitespace and `#` replaced).
fn material_names(scene: &Scene) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    scene
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let base: String =
                m.name.chars().map(|c| if c.is_whitespace() || c == '#' || c == '/' { '_' } else { c }).collect();
            let base = if base.is_empty() { format!("material_{i}") } else { base };
            if seen.insert(base.clone()) { base } else { format!("{base}_{i}") }
        })
        .collect()
}

/// Running vertex counts of the OBJ being written (indices are absolute and 1-based).
#[derive(Default)]
struct ObjCounts {
    v: usize,
    vt: usize,
    vn: usize,
    triangles: usize,
}

impl ObjCounts {
    fn triangle(&mut self, obj: &mut String, p: [Vec3; 3], uv: Option<&[glam::Vec2; 3]>, n: Option<&[Vec3; 3]>) {
        for q in p {
            let _ = writeln!(obj, "v {} {} {}", q.x, q.y, q.z);
        }
        if let Some(uv) = uv {
            for t in uv {
                let _ = writeln!(obj, "vt {} {}", t.x, t.y);
            }
        }
        if let Some(n) = n {
            for m in n {
                let _ = writeln!(obj, "vn {} {} {}", m.x, m.y, m.z);
            }
        }
        obj.push('f');
        for k in 1..=3 {
            let v = self.v + k;
            let _ = match (uv.is_some(), n.is_some()) {
                (false, false) => write!(obj, " {v}"),
                (true, false) => write!(obj, " {v}/{}", self.vt + k),
                (false, true) => write!(obj, " {v}//{}", self.vn + k),
                (true, true) => write!(obj, " {v}/{}/{}", self.vt + k, self.vn + k),
            };
        }
        obj.push('\n');
        self.v += 3;
        self.vt += if uv.is_some() { 3 } else { 0 };
        self.vn += if n.is_some() { 3 } else { 0 };
        self.triangles += 1;
    }
}

fn image_error(path: &Path, e: impl std::fmt::Display) -> SceneError {
    SceneError::Image { path: path.to_path_buf(), message: format!("cannot write: {e}") }
}

/// An albedo texture (times `scale`) as 8-bit sRGB RGB(A); alpha stays linear.
fn write_albedo_png(t: &Texture, scale: f32, path: &Path) -> Result<(), SceneError> {
    let c = t.channels as usize;
    let quantise = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let bytes: Vec<u8> = t
        .data
        .iter()
        .enumerate()
        .map(|(i, &v)| if c == 4 && i % 4 == 3 { quantise(v) } else { quantise(linear_to_srgb(v * scale)) })
        .collect();
    let colour = match c {
        4 => image::ExtendedColorType::Rgba8,
        3 => image::ExtendedColorType::Rgb8,
        _ => image::ExtendedColorType::L8,
    };
    image::save_buffer(path, &bytes, t.width, t.height, colour).map_err(|e| image_error(path, e))
}

/// A mask texture's first channel as 8-bit grey (linear coverage).
fn write_mask_png(t: &Texture, path: &Path) -> Result<(), SceneError> {
    let c = t.channels as usize;
    let bytes: Vec<u8> = t.data.chunks_exact(c).map(|px| (px[0].clamp(0.0, 1.0) * 255.0).round() as u8).collect();
    image::save_buffer(path, &bytes, t.width, t.height, image::ExtendedColorType::L8).map_err(|e| image_error(path, e))
}

/// An environment texture as a float RGB EXR (top row first, as it is stored).
fn write_environment_exr(t: &Texture, path: &Path) -> Result<(), SceneError> {
    let extent = Extent::new(t.width as usize, t.height as usize).map_err(|e| image_error(path, e))?;
    let mut img = RgbBuf::new(extent, 0.0);
    let c = t.channels as usize;
    for y in 0..t.height as usize {
        for x in 0..t.width as usize {
            let i = (y * t.width as usize + x) * c;
            img.set(x, y, [t.data[i], t.data[i + 1], t.data[i + 2]]);
        }
    }
    crate::image_io::write_exr(path, &img).map_err(|e| image_error(path, e))
}

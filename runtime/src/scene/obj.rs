//! Wavefront OBJ + MTL loading (through `tobj`), following the conventions of
//! `../shared/scenes/README.md`.
//!
//! ## How a file is read
//!
//! The OBJ is read into memory once and **pre-scanned** line by line before `tobj` sees it.
//! The pre-scan is cheap (one pass, no allocation per line) and does two jobs:
//!
//! 1. **Line numbers.** `tobj`'s errors carry no position; the pre-scan checks what `tobj`
//!    would reject (unparsable numbers, a `w` of zero, face indices of 0 or out of range,
//!    `usemtl`/`mtllib` without a name, invalid UTF-8) and reports `file:line: message`.
//! 2. **No panics.** It also rejects input on which `tobj` 4.0.5 would panic or misbehave
//!    (negative indices reaching before the first vertex overflow an index computation;
//!    an MTL colour with one or two numbers hits an `unwrap`), and what a renderer must not
//!    get: NaN/infinite coordinates, normals or UVs.
//!
//! The buffer then goes to `tobj::load_obj_buf` (the engine behind `tobj::load_obj`) with
//! `triangulate` and `single_index`, points and lines ignored; MTL files go through the same
//! pre-scan (`Kd 0.5` is expanded to `Kd 0.5 0.5 0.5`, as the MTL spec allows) and then
//! `tobj::load_mtl_buf`. A reader that counts lines is a second net: should `tobj` still fail,
//! the error names the line it stopped on.
//!
//! ## What is kept
//!
//! Every triangle, including near-zero-area ones (the shared scenes' counts include them:
//! 2 in classroom, 190 in living-room); polygons are fan-triangulated. Faces with fewer than
//! three vertices (points, lines) are skipped with a warning. Triangles without `vn` are flat
//! shaded; zero-length normals fall back to the geometric normal.
//!
//! ## Materials (`scene.mtl`)
//!
//! - `illum 0/1` (or no `illum` and `Ks` = 0): diffuse `Kd`.
//! - `illum 2` with `Ks` > 0: glossy, `Kd` + `Ks` lobe of roughness `Pr` (from `Ns` via
//!   `alpha = sqrt(2 / (Ns + 2))`, `Pr = sqrt(alpha)` when `Pr` is absent), at least
//!   [`MIN_GLOSSY_ROUGHNESS`](super::material::MIN_GLOSSY_ROUGHNESS).
//! - `illum 3/5/8`: conductor: a mirror of reflectance `Ks` when `Pr` ≤
//!   [`MIRROR_MAX_ROUGHNESS`], else glossy (`Kd` is 0
//!   for conductors in the shared scenes). `Pm 1` sets `metallic`.
//! - `illum 4/6/7/9` (glass): see [`GlassMode`].
//! - `Ke`: one-sided area-light radiance. `d` (or `1 − Tr`): constant opacity.
//! - `map_Kd`: sRGB albedo texture, which **replaces** `Kd` (the shared scenes set `Kd` to the
//!   texture's mean, so multiplying would darken twice). `map_d`: opacity mask (alpha channel).
//! - Colours outside [0, 1] are clamped with a warning.
//!
//! **Missing or undecodable textures** warn and continue: the material keeps its flat `Kd`
//! (the texture's mean colour in the shared scenes), a missing `map_d` leaves the material
//! opaque. A missing **MTL** file is an error: without it every material would be wrong.

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::{BufRead, Cursor};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::error::SceneError;
use super::material::{MIRROR_MAX_ROUGHNESS, Material, MaterialKind};
use super::mesh::Mesh;
use super::texture::{Texture, TextureUsage};

/// What to do with glass (`illum 4/6/7/9`): the paper's estimator has no refraction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GlassMode {
    /// Keep the triangles with a fully transparent cutout material (opacity 0): rays pass,
    /// triangle counts match the source. The default.
    #[default]
    Transparent,
    /// Drop glass triangles from the mesh.
    Skip,
}

/// Options for [`load_obj`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjOptions {
    /// Uniform scale applied to positions (0.001 for millimetres).
    pub scale: f32,
    /// Glass handling.
    pub glass: GlassMode,
}

impl Default for ObjOptions {
    fn default() -> Self {
        Self { scale: 1.0, glass: GlassMode::Transparent }
    }
}

/// A loaded OBJ: geometry, materials and textures, ready for a [`Scene`](super::model::Scene).
#[derive(Clone, Debug)]
pub struct MeshData {
    /// Triangles (scaled).
    pub mesh: Mesh,
    /// Materials in MTL order (plus `default` for faces without a known material).
    pub materials: Vec<Material>,
    /// Decoded textures.
    pub textures: Vec<Texture>,
    /// Non-fatal problems.
    pub warnings: Vec<String>,
    /// Number of near-zero-area triangles kept.
    pub degenerate: usize,
}

/// Loads `path` (an `.obj`) and its material libraries and textures.
pub fn load_obj(path: &Path, options: &ObjOptions) -> Result<MeshData, SceneError> {
    if !(options.scale.is_finite() && options.scale > 0.0) {
        return Err(SceneError::invalid(path, format!("scale {} must be finite and > 0", options.scale)));
    }
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let scan = prescan_obj(path, &bytes)?;
    let mut warnings = Vec::new();
    if scan.small_faces > 0 {
        warnings.push(format!(
            "{}: {} face(s) with fewer than 3 vertices skipped (first at line {})",
            path.display(),
            scan.small_faces,
            scan.first_small_face
        ));
    }
    if scan.triangles == 0 {
        return Err(SceneError::invalid(path, "no triangles (the file has no faces with 3 or more vertices)"));
    }

    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mtl_error: RefCell<Option<SceneError>> = RefCell::new(None);
    let mtl_files: RefCell<Vec<PathBuf>> = RefCell::new(Vec::new());
    // tobj's other option fields (merge_identical_points, reorder_data) exist only with its
    // `merging`/`reordering` features; the update keeps this compiling if they get enabled.
    #[allow(clippy::needless_update)]
    let load_options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = LineCounter::new(Cursor::new(&bytes[..]));
    let result = tobj::load_obj_buf(&mut reader, &load_options, |mtl: &Path| {
        let full = dir.join(mtl);
        let line = scan.mtllib_lines.iter().find(|(_, name)| Path::new(name) == mtl).map_or(0, |(l, _)| *l);
        match read_mtl(&full) {
            Ok(r) => {
                mtl_files.borrow_mut().push(full);
                r
            }
            Err(e) => {
                let e = match e {
                    SceneError::Io { source, .. } => {
                        SceneError::invalid_at(path, line, format!("material library {}: {source}", full.display()))
                    }
                    other => other,
                };
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    });
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, tobj_materials) = result.map_err(|e| SceneError::Parse {
        location: super::error::Location::line(path, reader.line.max(1)),
        message: format!("{e} (reported by tobj)"),
    })?;
    let tobj_materials = tobj_materials.map_err(|e| SceneError::invalid(path, format!("material libraries: {e}")))?;
    if scan.usemtl_lines > 0 && tobj_materials.is_empty() && !scan.mtllib_lines.is_empty() {
        warnings.push(format!("{}: the material libraries define no materials", path.display()));
    }

    // Materials and their textures (relative to the first MTL's folder, like tobj's loader).
    let mtl_dir = mtl_files.borrow().first().and_then(|p| p.parent().map(Path::to_path_buf)).unwrap_or(dir.clone());
    let mut textures = Vec::new();
    let mut cache: HashMap<(PathBuf, TextureUsage), Option<u32>> = HashMap::new();
    let mut materials = Vec::with_capacity(tobj_materials.len() + 1);
    let mut glass = Vec::with_capacity(tobj_materials.len());
    for m in &tobj_materials {
        let (mat, is_glass) = convert_material(m, options.glass, &mtl_dir, &mut textures, &mut cache, &mut warnings);
        materials.push(mat);
        glass.push(is_glass);
    }
    let mut default_material = None;

    // Geometry.
    let mut mesh = Mesh::default();
    let mut normals: Vec<[Vec3; 3]> = Vec::with_capacity(scan.triangles);
    let mut uvs: Vec<[Vec2; 3]> = Vec::with_capacity(scan.triangles);
    let (mut any_normals, mut any_uvs, mut skipped_glass, mut unknown_material) = (false, false, 0usize, 0usize);
    mesh.positions.reserve(scan.triangles);
    mesh.material.reserve(scan.triangles);
    for model in &models {
        let m = &model.mesh;
        let nv = m.positions.len() / 3;
        let has_n = !m.normals.is_empty() && m.normals.len() == m.positions.len();
        let has_t = !m.texcoords.is_empty() && m.texcoords.len() / 2 == nv;
        if !m.normals.is_empty() && !has_n {
            warnings.push(format!(
                "{}: object {:?} has normals on only some vertices; flat shaded",
                path.display(),
                model.name
            ));
        }
        if !m.texcoords.is_empty() && !has_t {
            warnings.push(format!(
                "{}: object {:?} has UVs on only some vertices; UVs dropped",
                path.display(),
                model.name
            ));
        }
        let mat = match m.material_id {
            Some(id) if id < materials.len() => {
                if glass[id] && options.glass == GlassMode::Skip {
                    skipped_glass += m.indices.len() / 3;
                    continue;
                }
                id as u32
            }
            _ => {
                unknown_material += m.indices.len() / 3;
                *default_material.get_or_insert_with(|| {
                    materials.push(Material::diffuse("default", Vec3::splat(0.8)));
                    materials.len() as u32 - 1
                })
            }
        };
        let pos = |i: u32| Vec3::from_slice(&m.positions[3 * i as usize..3 * i as usize + 3]) * options.scale;
        for t in m.indices.chunks_exact(3) {
            let p = [pos(t[0]), pos(t[1]), pos(t[2])];
            let g = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize().unwrap_or(Vec3::Y);
            mesh.positions.push(p);
            mesh.material.push(mat);
            normals.push(if has_n {
                any_normals = true;
                [0, 1, 2].map(|k| {
                    let i = 3 * t[k] as usize;
                    Vec3::from_slice(&m.normals[i..i + 3]).try_normalize().unwrap_or(g)
                })
            } else {
                [g; 3]
            });
            uvs.push(if has_t {
                any_uvs = true;
                [0, 1, 2].map(|k| Vec2::from_slice(&m.texcoords[2 * t[k] as usize..2 * t[k] as usize + 2]))
            } else {
                [Vec2::ZERO; 3]
            });
        }
    }
    if unknown_material > 0 {
        warnings.push(format!(
            "{}: {unknown_material} triangle(s) without a known material use a grey 'default'",
            path.display()
        ));
    }
    if skipped_glass > 0 {
        warnings.push(format!("{}: {skipped_glass} glass triangle(s) skipped", path.display()));
    }
    mesh.normals = any_normals.then_some(normals);
    mesh.uvs = any_uvs.then_some(uvs);
    if mesh.is_empty() {
        return Err(SceneError::invalid(path, "no triangles left after loading"));
    }
    let degenerate = mesh.degenerate_count();
    Ok(MeshData { mesh, materials, textures, warnings, degenerate })
}

/// A `BufRead` that counts the lines handed out (for tobj errors without positions).
struct LineCounter<R> {
    inner: R,
    line: usize,
}

impl<R: BufRead> LineCounter<R> {
    fn new(inner: R) -> Self {
        Self { inner, line: 0 }
    }
}

impl<R: BufRead> std::io::Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.line += buf[..n].iter().filter(|&&b| b == b'\n').count();
        Ok(n)
    }
}

impl<R: BufRead> BufRead for LineCounter<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }
    fn consume(&mut self, amt: usize) {
        if let Ok(b) = self.inner.fill_buf() {
            self.line += b[..amt.min(b.len())].iter().filter(|&&c| c == b'\n').count();
        }
        self.inner.consume(amt);
    }
}

/// What the OBJ pre-scan learnt.
struct ObjScan {
    triangles: usize,
    small_faces: usize,
    first_small_face: usize,
    mtllib_lines: Vec<(usize, String)>,
    usemtl_lines: usize,
}

/// Splits `bytes` into `(1-based line number, line)`, checking UTF-8.
fn lines<'a>(path: &'a Path, bytes: &'a [u8]) -> impl Iterator<Item = Result<(usize, &'a str), SceneError>> + 'a {
    bytes.split(|&b| b == b'\n').enumerate().map(move |(i, l)| {
        let l = l.strip_suffix(b"\r").unwrap_or(l);
        std::str::from_utf8(l).map(|s| (i + 1, s)).map_err(|_| SceneError::parse_at(path, i + 1, "not valid UTF-8"))
    })
}

fn parse_f32(tok: Option<&str>) -> Option<f32> {
    tok.and_then(|t| t.parse::<f32>().ok())
}

fn prescan_obj(path: &Path, bytes: &[u8]) -> Result<ObjScan, SceneError> {
    let (mut nv, mut nt, mut nn) = (0usize, 0usize, 0usize);
    // Largest positive index per kind and the first line it appeared on (forward references
    // are legal for tobj, so the range check against the totals happens at the end).
    let mut max_ref = [(0usize, 0usize); 3];
    let mut scan =
        ObjScan { triangles: 0, small_faces: 0, first_small_face: 0, mtllib_lines: Vec::new(), usemtl_lines: 0 };
    for item in lines(path, bytes) {
        let (ln, line) = item?;
        let err = |m: String| SceneError::parse_at(path, ln, m);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                // Up to 7 tokens without allocating: x y z [w | r g b].
                let mut v = [""; 7];
                let mut k = 0;
                for t in words {
                    if k < 7 {
                        v[k] = t;
                    }
                    k += 1;
                }
                let mut xyz = [0f32; 3];
                for (x, t) in xyz.iter_mut().zip(&v[..3]) {
                    *x = match t.parse::<f32>() {
                        Ok(x) if k >= 3 => x,
                        _ => return Err(err(format!("vertex position needs 3 numbers: {line:?}"))),
                    };
                }
                if !xyz.iter().all(|x| x.is_finite()) {
                    return Err(err(format!("vertex position is not finite (NaN or infinity): {line:?}")));
                }
                match k {
                    3 => {}
                    4 => match v[3].parse::<f32>() {
                        Ok(w) if w != 0.0 && w.is_finite() => {}
                        _ => return Err(err(format!("vertex weight w must be a finite non-zero number: {line:?}"))),
                    },
                    6 if v[3..6].iter().all(|t| t.parse::<f32>().is_ok()) => {}
                    _ => return Err(err(format!("vertex needs x y z [w] or x y z r g b: {line:?}"))),
                }
                nv += 1;
            }
            Some("vt") => {
                let (u, v) = (parse_f32(words.next()), parse_f32(words.next()));
                match (u, v) {
                    (Some(u), Some(v)) if u.is_finite() && v.is_finite() => nt += 1,
                    (Some(_), Some(_)) => return Err(err(format!("texture coordinate is not finite: {line:?}"))),
                    _ => return Err(err(format!("texture coordinate needs 2 numbers: {line:?}"))),
                }
            }
            Some("vn") => {
                let n: Vec<Option<f32>> = (0..3).map(|_| parse_f32(words.next())).collect();
                if n.iter().any(Option::is_none) {
                    return Err(err(format!("normal needs 3 numbers: {line:?}")));
                }
                if !n.iter().flatten().all(|x| x.is_finite()) {
                    return Err(err(format!("normal is not finite: {line:?}")));
                }
                nn += 1;
            }
            Some("f") => {
                let mut k = 0usize;
                for tok in words {
                    if tok.starts_with('/') || tok.split('/').count() > 3 {
                        return Err(err(format!("bad face vertex {tok:?}")));
                    }
                    for (kind, part) in tok.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let count = [nv, nt, nn][kind];
                        let what = ["vertex", "texture coordinate", "normal"][kind];
                        let i: i64 = part.parse().map_err(|_| err(format!("bad {what} index {part:?} in {tok:?}")))?;
                        if i == 0 {
                            return Err(err(format!("{what} index 0 in {tok:?} (OBJ indices start at 1)")));
                        }
                        if i < 0 {
                            if i.unsigned_abs() as usize > count {
                                return Err(err(format!(
                                    "relative {what} index {i} reaches before the first {what} ({count} defined so far)"
                                )));
                            }
                        } else if i as usize > max_ref[kind].0 {
                            max_ref[kind] = (i as usize, ln);
                        }
                    }
                    k += 1;
                }
                if k >= 3 {
                    scan.triangles += k - 2;
                } else {
                    if scan.small_faces == 0 {
                        scan.first_small_face = ln;
                    }
                    scan.small_faces += 1;
                }
            }
            Some("mtllib") => {
                let name = line.split_once(' ').map_or("", |x| x.1).trim();
                if name.is_empty() {
                    return Err(err("mtllib without a file name (separate it with a space)".into()));
                }
                scan.mtllib_lines.push((ln, name.to_owned()));
            }
            Some("usemtl") => {
                if line.split_once(' ').map_or("", |x| x.1).trim().is_empty() {
                    return Err(err("usemtl without a material name (separate it with a space)".into()));
                }
                scan.usemtl_lines += 1;
            }
            _ => {}
        }
    }
    for (kind, (i, ln)) in max_ref.iter().enumerate() {
        let count = [nv, nt, nn][kind];
        if *i > count {
            let (what, plural) =
                [("vertex", "vertices"), ("texture coordinate", "texture coordinates"), ("normal", "normals")][kind];
            let defined = if count == 1 { format!("1 {what}") } else { format!("{count} {plural}") };
            return Err(SceneError::parse_at(
                path,
                *ln,
                format!("{what} index {i} is out of range (the file defines {defined})"),
            ));
        }
    }
    Ok(scan)
}

/// Reads and pre-scans an MTL file, then hands it to tobj.
fn read_mtl(path: &Path) -> Result<tobj::MTLLoadResult, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let mut text = String::with_capacity(bytes.len() + 64);
    for item in lines(path, &bytes) {
        let (ln, line) = item?;
        let err = |m: String| SceneError::parse_at(path, ln, m);
        let mut words = line.split_whitespace();
        let key = words.next();
        let rest: Vec<&str> = words.collect();
        let numbers = || -> Result<Vec<f32>, SceneError> {
            rest.iter()
                .map(|t| match t.parse::<f32>() {
                    Ok(x) if x.is_finite() => Ok(x),
                    Ok(_) => Err(err(format!("{} value is not finite: {line:?}", key.unwrap_or_default()))),
                    Err(_) => Err(err(format!("{} expects numbers: {line:?}", key.unwrap_or_default()))),
                })
                .collect()
        };
        match key {
            Some("newmtl") if rest.is_empty() => return Err(err("newmtl without a name".into())),
            Some(k @ ("Ka" | "Kd" | "Ks" | "Ke" | "Tf")) => {
                let v = numbers()?;
                match v.len() {
                    3 => text.push_str(line),
                    // The MTL spec allows one value for grey; tobj would panic on it.
                    1 => text.push_str(&format!("{k} {0} {0} {0}", v[0])),
                    _ => return Err(err(format!("{k} expects 1 or 3 numbers, got {}: {line:?}", v.len()))),
                }
                text.push('\n');
                continue;
            }
            Some(k @ ("Ns" | "Ni" | "d" | "Tr" | "Pr" | "Pm")) => {
                let values = numbers()?;
                if values.is_empty() {
                    return Err(err(format!("{k} expects a number: {line:?}")));
                }
            }
            Some("illum") if rest.first().and_then(|t| t.parse::<u8>().ok()).is_none() => {
                return Err(err(format!("illum expects an integer model number: {line:?}")));
            }
            Some(k) if (k.starts_with("map_") || k == "bump" || k == "disp" || k == "refl") && rest.is_empty() => {
                return Err(err(format!("{k} without a file name")));
            }
            _ => {}
        }
        text.push_str(line);
        text.push('\n');
    }
    let mut reader = LineCounter::new(Cursor::new(text.as_bytes()));
    match tobj::load_mtl_buf(&mut reader) {
        Ok(r) => Ok(Ok(r)),
        Err(e) => Err(SceneError::parse_at(path, reader.line.max(1), format!("{e} (reported by tobj)"))),
    }
}

/// The file name of a texture statement, without options such as `-bm 1`.
fn texture_file(spec: &str) -> &str {
    let spec = spec.trim();
    if spec.starts_with('-') { spec.split_whitespace().last().unwrap_or(spec) } else { spec }
}

fn load_texture_cached(
    dir: &Path,
    spec: &str,
    usage: TextureUsage,
    material: &str,
    textures: &mut Vec<Texture>,
    cache: &mut HashMap<(PathBuf, TextureUsage), Option<u32>>,
    warnings: &mut Vec<String>,
) -> Option<u32> {
    let path = dir.join(texture_file(spec));
    if let Some(hit) = cache.get(&(path.clone(), usage)) {
        return *hit;
    }
    let index = match Texture::load(&path, usage) {
        Ok(t) => {
            textures.push(t);
            Some(textures.len() as u32 - 1)
        }
        Err(e) => {
            let what = match usage {
                TextureUsage::Albedo => "keeps its flat Kd",
                TextureUsage::Mask => "stays opaque",
                TextureUsage::Linear => "keeps its flat values",
            };
            warnings.push(format!("material {material:?}: {e}; the material {what}"));
            None
        }
    };
    cache.insert((path, usage), index);
    index
}

fn param(m: &tobj::Material, key: &str) -> Option<f32> {
    m.unknown_param.get(key).and_then(|v| v.split_whitespace().next()).and_then(|v| v.parse().ok())
}

fn convert_material(
    m: &tobj::Material,
    glass_mode: GlassMode,
    dir: &Path,
    textures: &mut Vec<Texture>,
    cache: &mut HashMap<(PathBuf, TextureUsage), Option<u32>>,
    warnings: &mut Vec<String>,
) -> (Material, bool) {
    let mut clamp_warned = false;
    let mut colour = |v: Option<[f32; 3]>, default: f32, what: &str| -> Vec3 {
        let c = v.map_or(Vec3::splat(default), Vec3::from);
        let k = c.clamp(Vec3::ZERO, Vec3::ONE);
        if k != c && !clamp_warned {
            warnings.push(format!("material {:?}: {what} {c} clamped to [0, 1]", m.name));
            clamp_warned = true;
        }
        k
    };
    let kd = colour(m.diffuse, 0.8, "Kd");
    let ks = colour(m.specular, 0.0, "Ks");
    let ke = m.emissive.map_or(Vec3::ZERO, |e| Vec3::from(e).max(Vec3::ZERO));
    let roughness = param(m, "Pr")
        .or_else(|| m.shininess.map(|ns| (2.0 / (ns.max(0.0) + 2.0)).sqrt().sqrt()))
        .unwrap_or(1.0)
        .clamp(0.0, 1.0);
    let metallic = param(m, "Pm").is_some_and(|p| p >= 0.5);
    let opacity = m.dissolve.or_else(|| param(m, "Tr").map(|t| 1.0 - t)).unwrap_or(1.0).clamp(0.0, 1.0);
    let illum = m.illumination_model.unwrap_or(if ks.max_element() > 0.0 { 2 } else { 1 });

    let mut mat = Material::diffuse(m.name.clone(), kd);
    mat.emission = ke;
    mat.metallic = metallic;
    mat.opacity = opacity;
    let mut is_glass = false;
    match illum {
        2 if ks.max_element() > 0.0 => {
            mat = Material { emission: ke, metallic, opacity, ..Material::glossy(m.name.clone(), kd, ks, roughness) }
        }
        3 | 5 | 8 if roughness <= MIRROR_MAX_ROUGHNESS => {
            mat = Material { emission: ke, metallic, opacity, ..Material::mirror(m.name.clone(), ks) }
        }
        3 | 5 | 8 => {
            mat = Material { emission: ke, metallic, opacity, ..Material::glossy(m.name.clone(), kd, ks, roughness) }
        }
        4 | 6 | 7 | 9 => {
            is_glass = true;
            mat = Material { opacity: 0.0, ..Material::diffuse(m.name.clone(), Vec3::ZERO) };
            if glass_mode == GlassMode::Transparent {
                warnings.push(format!("material {:?}: glass (illum {illum}) loaded as a transparent cutout", m.name));
            }
        }
        0..=2 => {}
        other => warnings.push(format!("material {:?}: illum {other} unsupported, loaded as diffuse", m.name)),
    }
    if !is_glass {
        if let Some(spec) = &m.diffuse_texture
            && mat.kind != MaterialKind::Mirror
        {
            mat.albedo_texture =
                load_texture_cached(dir, spec, TextureUsage::Albedo, &m.name, textures, cache, warnings);
        }
        if let Some(spec) = &m.dissolve_texture {
            mat.opacity_texture =
                load_texture_cached(dir, spec, TextureUsage::Mask, &m.name, textures, cache, warnings);
        }
    }
    (mat, is_glass)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_options_are_stripped() {
        assert_eq!(texture_file("wood.jpg"), "wood.jpg");
        assert_eq!(texture_file("-bm 0.5 -clamp on my wood.jpg"), "wood.jpg");
        assert_eq!(texture_file("  Sky 19.png "), "Sky 19.png");
    }

    #[test]
    fn line_counter_counts_consumed_lines() {
        let mut r = LineCounter::new(Cursor::new(&b"a\nb\nc"[..]));
        let mut s = String::new();
        r.read_line(&mut s).unwrap();
        assert_eq!(r.line, 1);
        r.read_line(&mut s).unwrap();
        r.read_line(&mut s).unwrap();
        assert_eq!(r.line, 2);
    }
}

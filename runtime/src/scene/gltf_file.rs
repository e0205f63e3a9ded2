//! glTF 2.0 scenes: `.gltf` (JSON, with buffers and images in files or `data:` URIs) and
//! `.glb` (binary), read with the `gltf` crate.
//!
//! ## What is read
//!
//! - **Geometry**: every mesh primitive of the default scene (else the first scene) in
//!   triangle, strip or fan mode, placed by its node's world transform. Normals go through
//!   the inverse transpose; a transform that mirrors (negative determinant) flips the
//!   winding, so fronts stay fronts. Without `NORMAL` a primitive is flat shaded (the glTF
//!   rule). UVs come from the set the base-colour texture names (`TEXCOORD_0` by default),
//!   with `v` flipped to this crate's convention (glTF's `v = 0` is the top row). Points and
//!   lines are skipped with a warning; skins and morph targets are read in their rest pose.
//!   Vertex colours are not read, and textures always wrap and filter bilinearly (samplers
//!   and `KHR_texture_transform` are not read).
//! - **Units**: metres, as the specification says. A manifest's `meters_per_unit` overrides
//!   it for files that are not.
//! - **Camera**: the first perspective camera met walking the scene's nodes in order. Its
//!   `yfov` is the vertical field of view; the aspect ratio is the render's. The camera path
//!   starts there (`folder::path_around` builds the path around it).
//! - **Lights**: emissive materials are area lights (one-sided, on the winding normal, like
//!   every emitter here). `KHR_lights_punctual` point and spot lights keep their intensity
//!   (candela) as radiant intensity and directional lights their illuminance (lux) as
//!   irradiance, one for one: radiance here has no photometric unit. A spot keeps its cone and
//!   the extension's falloff ([`SpotCone`]). A directional light becomes a sun of the real
//!   sun's angular radius (0.27°), since the renderer samples a disc; a second one is dropped
//!   with a warning. `range` is ignored (lights fall off as `1/r²`), with a warning.
//!
//! ## Materials: PBR metallic-roughness to the paper's set
//!
//! [`MATERIAL_RULES`] is the table `stereotrace scenes FILE` prints:
//!
//! 1. `metallic` and `roughness` are the factors times the mean of the metallic-roughness
//!    texture's blue and green channels (a material here has one roughness).
//! 2. `metallic >= 0.5` is a conductor of reflectance `baseColor` (factor × the texture's
//!    mean): a **mirror** when `roughness <= 0.02`, else **glossy** with no diffuse part.
//! 3. Otherwise a dielectric: a Lambert base of `baseColor` (its texture, the factor baked
//!    in) plus a microfacet lobe of reflectance `F0 = 0.04 × specularColorFactor ×
//!    specularFactor` (`KHR_materials_specular`; 0.04 is glTF's IOR 1.5) and that roughness
//!    (at least 0.1): **glossy**, or **diffuse** when `F0` is zero.
//! 4. Emission is `emissiveFactor × emissiveStrength` (`KHR_materials_emissive_strength`)
//!    times the emissive texture's mean.
//! 5. `alphaMode: MASK` is the alpha test at `alphaCutoff`; `BLEND` is the same test at 0.5,
//!    with a warning (the renderer has no blending); `OPAQUE` ignores alpha.
//! 6. Normal and occlusion textures are not used.
//!
//! ## Errors
//!
//! A file that is not glTF, JSON syntax (line and column), a schema or index error, a
//! required extension this loader does not support (named), a missing or short buffer, an
//! accessor reaching outside its buffer, an index past its vertices, NaN or infinite
//! coordinates, and a missing or undecodable image are all [`SceneError`]s naming the file.
//! Nothing here panics on bad input: the `gltf` fuzz target feeds it arbitrary files.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use base64::Engine as _;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::error::{Location, SceneError};
use super::light::{Lights, PointLight, SUN_RADIUS_DEG, SpotCone, SunLight};
use super::material::{MIN_GLOSSY_ROUGHNESS, MIRROR_MAX_ROUGHNESS, Material};
use super::mesh::Mesh;
use super::obj::MeshData;
use super::texture::{Texture, TextureUsage};

/// The extensions this loader reads; a file that *requires* any other is refused by name.
pub const SUPPORTED_EXTENSIONS: &[&str] =
    &["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_specular"];

/// How glTF's metallic-roughness materials become the paper's material set (printed by
/// `stereotrace scenes FILE`; the module notes explain each rule).
pub const MATERIAL_RULES: &str = "\
glTF material rules (PBR metallic-roughness -> diffuse / glossy / mirror):
  metallic, roughness = factor x mean of the metallic-roughness texture (blue, green)
  metallic >= 0.5     -> conductor of reflectance baseColor: mirror if roughness <= 0.02, else glossy (no diffuse)
  metallic <  0.5     -> Lambert baseColor (texture x factor) + lobe F0 = 0.04 x KHR_materials_specular
                         (glossy, roughness >= 0.1), or diffuse when F0 = 0
  emission            = emissiveFactor x KHR_materials_emissive_strength x mean emissive texture (one-sided area light)
  alphaMode MASK      -> alpha test at alphaCutoff; BLEND -> alpha test at 0.5 (warning); OPAQUE ignores alpha
  normal, occlusion textures: not used
  lights: KHR_lights_punctual point/spot (candela as W/sr), directional (lux as W/m2, a 0.27 deg sun disc)";

/// A camera of the file, in the file's units (not scaled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfCamera {
    /// Its position.
    pub eye: Vec3,
    /// A point straight ahead (one unit along its -Z).
    pub target: Vec3,
    /// Its +Y.
    pub up: Vec3,
    /// Its vertical field of view in degrees.
    pub vfov_deg: f32,
}

/// A loaded glTF file: what [`load_gltf`] returns.
#[derive(Clone, Debug)]
pub struct GltfData {
    /// Triangles (scaled), materials and textures.
    pub geometry: MeshData,
    /// The first perspective camera met walking the scene's nodes.
    pub camera: Option<GltfCamera>,
    /// `KHR_lights_punctual` lights (scaled).
    pub lights: Lights,
}

/// The largest file read (buffers included): 4 GiB.
const MAX_FILE_BYTES: u64 = 4 << 30;

/// Loads a `.gltf` or `.glb` file; positions are multiplied by `scale` (1 for metres).
pub fn load_gltf(path: &Path, scale: f32) -> Result<GltfData, SceneError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(SceneError::invalid(path, format!("scale {scale} must be finite and > 0")));
    }
    let size = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?.len();
    if size > MAX_FILE_BYTES {
        return Err(SceneError::invalid(path, format!("{size} bytes: files above {MAX_FILE_BYTES} are refused")));
    }
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let base = path.parent().map(Path::to_path_buf);
    load_gltf_bytes(path, &bytes, base.as_deref(), scale)
}

/// [`load_gltf`] on bytes in memory; `path` names the file in messages and `base` resolves
/// relative URIs (`None`: only `data:` URIs and the GLB chunk are allowed, as fuzzing wants).
pub fn load_gltf_bytes(path: &Path, bytes: &[u8], base: Option<&Path>, scale: f32) -> Result<GltfData, SceneError> {
    let (document, blob) = parse(path, bytes)?;
    let buffers = read_buffers(path, &document, blob, base)?;
    // The reader's own arithmetic is checked before it runs (`accessor_fits`), and the
    // document is validated, so nothing below should panic. This is a net for what the
    // `gltf` crate still unwraps on a malformed file; nothing is shared across it.
    let walked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let (decoded, placed) = (HashMap::new(), HashMap::new());
        Loader { path, document: &document, buffers: &buffers, base, scale, warnings: Vec::new(), decoded, placed }
            .load()
    }));
    walked.unwrap_or_else(|panic| {
        Err(SceneError::invalid(path, format!("the glTF reader failed on this file: {}", panic_text(panic.as_ref()))))
    })
}

fn panic_text(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// Parses the JSON or GLB container, refuses unsupported required extensions by name, then
/// validates the document (indices in range, enums known).
fn parse(path: &Path, bytes: &[u8]) -> Result<(gltf::Document, Option<Vec<u8>>), SceneError> {
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| match e {
        gltf::Error::Deserialize(e) => SceneError::Parse {
            location: Location::at(path, e.line().max(1), e.column().max(1)),
            message: format!("glTF JSON: {e}"),
        },
        gltf::Error::Binary(e) => SceneError::invalid(path, format!("not a valid GLB file: {e}")),
        other => SceneError::invalid(path, format!("not a glTF file: {other}")),
    })?;
    if let Some(unsupported) = document.extensions_required().find(|e| !SUPPORTED_EXTENSIONS.contains(e)) {
        return Err(SceneError::invalid(
            path,
            format!(
                "the file requires the extension {unsupported}, which this loader does not support (it reads {})",
                SUPPORTED_EXTENSIONS.join(", ")
            ),
        ));
    }
    // gltf-json 1.4.1's validation indexes the accessors by each POSITION attribute without a
    // bounds check (found by fuzzing): out-of-range attribute indices are refused here first.
    let root = document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.values().find(|i| i.value() >= root.accessors.len()) {
                return Err(SceneError::invalid(
                    path,
                    format!(
                        "mesh {m} primitive {p}: an attribute names accessor {}, but the file has {}",
                        index.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    // A net for any other unchecked index in the crate's validation.
    let json = document.into_json();
    let validated = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| gltf::Document::from_json(json)));
    let document = validated
        .unwrap_or_else(|panic| {
            Err(gltf::Error::Io(std::io::Error::other(format!("validation failed: {}", panic_text(panic.as_ref())))))
        })
        .map_err(|e| SceneError::invalid(path, e.to_string()))?;
    Ok((document, blob))
}

/// The bytes of a `data:` URI, or of a file relative to `base`.
fn read_uri(path: &Path, uri: &str, base: Option<&Path>, what: &str) -> Result<Vec<u8>, SceneError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| SceneError::invalid(path, format!("{what}: only base64 data URIs are supported")))?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| SceneError::invalid(path, format!("{what}: bad base64 in its data URI: {e}")));
    }
    if uri.contains("://") || (uri.contains(':') && !uri.starts_with("file:")) {
        return Err(SceneError::invalid(
            path,
            format!("{what}: URI {uri:?} is neither a data URI nor a relative file"),
        ));
    }
    let relative = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")).unwrap_or(uri);
    let decoded = urlencoding::decode(relative).map_err(|e| {
        SceneError::invalid(path, format!("{what}: URI {uri:?} is not valid percent-encoded UTF-8: {e}"))
    })?;
    let Some(base) = base else {
        return Err(SceneError::invalid(
            path,
            format!("{what}: external file {decoded:?} with no folder to read it from"),
        ));
    };
    let file = base.join(&*decoded);
    std::fs::read(&file).map_err(|e| SceneError::invalid(path, format!("{what}: cannot read {}: {e}", file.display())))
}

fn read_buffers(
    path: &Path,
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    base: Option<&Path>,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let what = format!("buffer {}", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                SceneError::invalid(path, format!("{what} is the GLB binary chunk, but the file has none"))
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(path, uri, base, &what)?,
        };
        if data.len() < buffer.length() {
            return Err(SceneError::invalid(
                path,
                format!("{what} holds {} bytes, but the file says {}", data.len(), buffer.length()),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The state of one load: the document, its buffers, and what has been built so far.
struct Loader<'a> {
    path: &'a Path,
    document: &'a gltf::Document,
    buffers: &'a [Vec<u8>],
    base: Option<&'a Path>,
    scale: f32,
    warnings: Vec<String>,
    /// Images decoded so far, by image index and usage: materials sharing an image (obj2gltf
    /// writes a copy of a material per OBJ group) decode it once.
    decoded: HashMap<(usize, TextureUsage), Rc<Texture>>,
    /// Scene textures made so far, by the image and what was baked into it: such copies
    /// share one texture too.
    placed: HashMap<(usize, Baked), u32>,
}

/// What a scene texture made from an image holds besides the image (the bits of the factors).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Baked {
    /// The colour times the base-colour factor's RGB.
    Albedo([u32; 3]),
    /// The alpha mask for the factor's alpha and the cutoff.
    Mask([u32; 2]),
}

/// The materials of a file, the textures they use, and where each glTF material went.
#[derive(Default)]
struct MaterialTable {
    materials: Vec<Material>,
    textures: Vec<Texture>,
    /// Per glTF material.
    slots: Vec<MaterialSlot>,
    /// For primitives without a material.
    default_slot: MaterialSlot,
}

/// A material's texture-coordinate set (for its base-colour texture) and its index here.
#[derive(Clone, Copy, Default)]
struct MaterialSlot {
    index: u32,
    uv_set: u32,
}

impl Loader<'_> {
    fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::invalid(self.path, message)
    }

    fn load(mut self) -> Result<GltfData, SceneError> {
        let MaterialTable { materials, textures, slots, default_slot } = self.materials()?;
        let mut geometry = MeshData { mesh: Mesh::default(), materials, textures, warnings: Vec::new(), degenerate: 0 };
        let mut camera = None;
        let mut lights = Lights::default();
        let roots: Vec<gltf::Node> = match self.document.default_scene().or_else(|| self.document.scenes().next()) {
            Some(scene) => scene.nodes().collect(),
            None => {
                self.warnings.push(format!("{}: no scene: every root node is drawn", self.path.display()));
                let mut child = vec![false; self.document.nodes().len()];
                self.document.nodes().flat_map(|n| n.children()).for_each(|c| child[c.index()] = true);
                self.document.nodes().filter(|n| !child[n.index()]).collect()
            }
        };
        // Depth-first, in document order, with an explicit stack: a cyclic or shared node graph
        // (glTF allows one parent per node) is an error, not endless recursion.
        let mut reached = vec![false; self.document.nodes().len()];
        let mut stack: Vec<(gltf::Node, Mat4)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            if std::mem::replace(&mut reached[node.index()], true) {
                return Err(
                    self.invalid(format!("node {} is reached twice (a glTF node has one parent)", node.index()))
                );
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            if !world.is_finite() {
                return Err(self.invalid(format!("node {}: its world transform is not finite", node.index())));
            }
            if let Some(mesh) = node.mesh() {
                for primitive in mesh.primitives() {
                    let slot = primitive.material().index().map_or(default_slot, |i| slots[i]);
                    let part = self.primitive(&mesh, &primitive, world, slot)?;
                    geometry.mesh.append(&part, 0);
                }
            }
            if let Some(cam) = node.camera()
                && camera.is_none()
            {
                camera = self.camera(&cam, world);
            }
            if let Some(light) = node.light() {
                self.light(&light, world, &mut lights);
            }
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((child, world));
            }
        }
        if geometry.mesh.is_empty() {
            return Err(self.invalid("no triangles (no mesh primitive in triangle, strip or fan mode is drawn)"));
        }
        geometry.mesh.validate(geometry.materials.len()).map_err(|m| self.invalid(m))?;
        geometry.degenerate = geometry.mesh.degenerate_count();
        geometry.warnings = self.warnings;
        Ok(GltfData { geometry, camera, lights })
    }

    /// The camera of `camera` at `world`, in file units; `None` (with a warning) for an
    /// orthographic one or a degenerate transform.
    fn camera(&mut self, camera: &gltf::Camera, world: Mat4) -> Option<GltfCamera> {
        let gltf::camera::Projection::Perspective(perspective) = camera.projection() else {
            self.warnings.push(format!("{}: orthographic camera {} skipped", self.path.display(), camera.index()));
            return None;
        };
        let eye = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(-Vec3::Z).try_normalize();
        let up = world.transform_vector3(Vec3::Y).try_normalize();
        let (Some(forward), Some(up)) = (forward, up) else {
            self.warnings.push(format!(
                "{}: camera {} has a degenerate transform",
                self.path.display(),
                camera.index()
            ));
            return None;
        };
        Some(GltfCamera { eye, target: eye + forward, up, vfov_deg: perspective.yfov().to_degrees() })
    }

    fn light(&mut self, light: &gltf::khr_lights_punctual::Light, world: Mat4, lights: &mut Lights) {
        use gltf::khr_lights_punctual::Kind;
        let radiant = Vec3::from(light.color()) * light.intensity();
        let position = world.transform_point3(Vec3::ZERO) * self.scale;
        let axis = world.transform_vector3(-Vec3::Z);
        let name = format!("{}: light {}", self.path.display(), light.index());
        if light.range().is_some() {
            self.warnings.push(format!("{name}: range ignored (lights fall off as 1/r^2 without a cutoff)"));
        }
        if !(radiant.is_finite() && radiant.min_element() >= 0.0 && radiant.max_element() > 0.0) {
            self.warnings.push(format!("{name}: colour x intensity {radiant} emits nothing; skipped"));
            return;
        }
        match light.kind() {
            Kind::Point => lights.points.push(PointLight::isotropic(position, radiant)),
            Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                match SpotCone::new(axis, inner_cone_angle, outer_cone_angle) {
                    Ok(cone) => lights.points.push(PointLight { position, intensity: radiant, spot: Some(cone) }),
                    Err(m) => self.warnings.push(format!("{name}: {m}; skipped")),
                }
            }
            Kind::Directional => match (lights.sun, (-axis).try_normalize()) {
                (Some(_), _) => {
                    self.warnings.push(format!("{name}: a second directional light; only the first is kept"))
                }
                (None, None) => self.warnings.push(format!("{name}: degenerate direction; skipped")),
                (None, Some(direction)) => {
                    lights.sun = Some(SunLight { direction, irradiance: radiant, angular_radius_deg: SUN_RADIUS_DEG })
                }
            },
        }
    }

    /// The triangles of one primitive, in world space and scene units.
    fn primitive(
        &mut self,
        mesh: &gltf::Mesh,
        primitive: &gltf::Primitive,
        world: Mat4,
        slot: MaterialSlot,
    ) -> Result<Mesh, SceneError> {
        let what = format!("mesh {} primitive {}", mesh.index(), primitive.index());
        let mode = primitive.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warnings.push(format!("{}: {what}: {mode:?} skipped (only triangles are drawn)", self.path.display()));
            return Ok(Mesh::default());
        }
        let positions_accessor =
            primitive.get(&gltf::Semantic::Positions).ok_or_else(|| self.invalid(format!("{what} has no POSITION")))?;
        self.accessor_fits(&positions_accessor, &what, "POSITION", &[(DataType::F32, Dimensions::Vec3)])?;
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| self.invalid(format!("{what}: POSITION could not be read")))?
            .map(Vec3::from)
            .collect();
        if let Some(bad) = positions.iter().position(|p| !p.is_finite()) {
            return Err(self.invalid(format!("{what}: POSITION {bad} is not finite")));
        }
        let normals: Option<Vec<Vec3>> = match primitive.get(&gltf::Semantic::Normals) {
            Some(a) => {
                self.accessor_fits(&a, &what, "NORMAL", &[(DataType::F32, Dimensions::Vec3)])?;
                Some(reader.read_normals().map(|n| n.map(Vec3::from).collect()).unwrap_or_default())
            }
            None => None,
        };
        let uvs: Option<Vec<Vec2>> = match primitive.get(&gltf::Semantic::TexCoords(slot.uv_set)) {
            Some(a) => {
                let kinds = [DataType::F32, DataType::U8, DataType::U16].map(|t| (t, Dimensions::Vec2));
                self.accessor_fits(&a, &what, "TEXCOORD", &kinds)?;
                reader.read_tex_coords(slot.uv_set).map(|t| t.into_f32().map(Vec2::from).collect())
            }
            None => None,
        };
        let vertex_count = positions.len();
        for (name, len) in [("NORMAL", normals.as_ref().map(Vec::len)), ("TEXCOORD", uvs.as_ref().map(Vec::len))] {
            if let Some(len) = len
                && len != vertex_count
            {
                return Err(self.invalid(format!("{what}: {name} has {len} entries for {vertex_count} positions")));
            }
        }
        let indices: Vec<u32> = match primitive.indices() {
            Some(a) => {
                let kinds = [DataType::U8, DataType::U16, DataType::U32].map(|t| (t, Dimensions::Scalar));
                self.accessor_fits(&a, &what, "indices", &kinds)?;
                let indices: Vec<u32> = reader.read_indices().map(|i| i.into_u32().collect()).unwrap_or_default();
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
                    return Err(self.invalid(format!("{what}: index {bad} is past its {vertex_count} vertices")));
                }
                indices
            }
            None => (0..vertex_count as u32).collect(),
        };
        let corners = triangle_corners(mode, &indices);
        let linear = Mat3::from_mat4(world);
        let mirrored = linear.determinant() < 0.0;
        let normal_matrix = (linear.determinant().abs() > f32::MIN_POSITIVE).then(|| linear.inverse().transpose());
        let mut part = Mesh {
            positions: Vec::with_capacity(corners.len()),
            normals: normals.as_ref().map(|_| Vec::with_capacity(corners.len())),
            uvs: uvs.as_ref().map(|_| Vec::with_capacity(corners.len())),
            material: vec![slot.index; corners.len()],
        };
        for c in corners {
            // A mirroring transform reverses the winding: swapping two corners restores it.
            let c = if mirrored { [c[0], c[2], c[1]] } else { c };
            let p = c.map(|i| world.transform_point3(positions[i as usize]) * self.scale);
            part.positions.push(p);
            if let (Some(out), Some(n)) = (&mut part.normals, &normals) {
                let geometric = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize().unwrap_or(Vec3::Y);
                out.push(
                    c.map(|i| normal_matrix.and_then(|m| (m * n[i as usize]).try_normalize()).unwrap_or(geometric)),
                );
            }
            if let (Some(out), Some(t)) = (&mut part.uvs, &uvs) {
                out.push(c.map(|i| {
                    let uv = t[i as usize];
                    Vec2::new(uv.x, 1.0 - uv.y)
                }));
            }
        }
        if let Some(uvs) = &part.uvs
            && uvs.iter().flatten().any(|uv| !uv.is_finite())
        {
            return Err(self.invalid(format!("{what}: a texture coordinate is not finite")));
        }
        Ok(part)
    }

    /// Checks that `accessor` is one of `kinds`, dense, non-empty and inside its buffer view
    /// and buffer: what the `gltf` reader assumes (its offsets are unchecked arithmetic).
    fn accessor_fits(
        &self,
        accessor: &gltf::Accessor,
        what: &str,
        name: &str,
        kinds: &[(DataType, Dimensions)],
    ) -> Result<(), SceneError> {
        let (data_type, dimensions) = (accessor.data_type(), accessor.dimensions());
        if !kinds.iter().any(|&(t, d)| t == data_type && d == dimensions) {
            return Err(
                self.invalid(format!("{what}: {name} is {data_type:?} {dimensions:?}, expected one of {kinds:?}"))
            );
        }
        if accessor.sparse().is_some() {
            return Err(self.invalid(format!("{what}: {name} is a sparse accessor, which this loader does not read")));
        }
        let Some(view) = accessor.view() else {
            return Err(self.invalid(format!("{what}: {name} has no buffer view")));
        };
        let element = accessor.size();
        let stride = view.stride().unwrap_or(element);
        let count = accessor.count();
        let end = (count.checked_sub(1))
            .and_then(|n| n.checked_mul(stride))
            .and_then(|n| n.checked_add(element))
            .and_then(|n| n.checked_add(accessor.offset()));
        let fits_view = end.is_some_and(|end| end <= view.length()) && stride >= element;
        let buffer_len = self.buffers.get(view.buffer().index()).map_or(0, Vec::len);
        let fits_buffer = view.offset().checked_add(view.length()).is_some_and(|end| end <= buffer_len);
        if !(fits_view && fits_buffer) {
            return Err(self.invalid(format!(
                "{what}: {name} ({count} elements of {element} bytes, stride {stride}, offset {}) reaches outside \
                 its buffer view or buffer",
                accessor.offset()
            )));
        }
        Ok(())
    }

    /// Every material (plus glTF's default material, last), the textures they use, and each
    /// one's slot.
    fn materials(&mut self) -> Result<MaterialTable, SceneError> {
        let mut table = MaterialTable::default();
        for m in self.document.materials() {
            let (material, uv_set) = self.material(&m, &mut table.textures)?;
            table.slots.push(MaterialSlot { index: table.materials.len() as u32, uv_set });
            table.materials.push(material);
        }
        // glTF's default material: white, metallic 1, roughness 1.
        table.default_slot = MaterialSlot { index: table.materials.len() as u32, uv_set: 0 };
        let fallback = Material { metallic: true, ..Material::glossy("gltf-default", Vec3::ZERO, Vec3::ONE, 1.0) };
        table.materials.push(fallback);
        Ok(table)
    }

    fn material(&mut self, m: &gltf::Material, textures: &mut Vec<Texture>) -> Result<(Material, u32), SceneError> {
        let name = m.name().map_or_else(|| format!("material{}", m.index().unwrap_or(0)), str::to_owned);
        let pbr = m.pbr_metallic_roughness();
        let factor = Vec4::from(pbr.base_color_factor());
        let (mut metallic, mut roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
        if let Some(info) = pbr.metallic_roughness_texture() {
            let mean = self.image(&info.texture(), TextureUsage::Linear)?.mean_rgb();
            roughness *= mean.y;
            metallic *= mean.z;
        }
        // (image index, decoded image, texture-coordinate set)
        let base_texture = match pbr.base_color_texture() {
            Some(info) => {
                let texture = info.texture();
                Some((texture.source().index(), self.image(&texture, TextureUsage::Albedo)?, info.tex_coord()))
            }
            None => None,
        };
        let base_mean = base_texture.as_ref().map_or(Vec3::ONE, |(_, t, _)| t.mean_rgb()) * factor.truncate();
        let mut material = if metallic >= 0.5 {
            let mut conductor = if roughness <= MIRROR_MAX_ROUGHNESS {
                Material::mirror(name.clone(), base_mean)
            } else {
                Material::glossy(name.clone(), Vec3::ZERO, base_mean, roughness)
            };
            conductor.metallic = true;
            conductor
        } else {
            let (specular_factor, specular_colour) =
                m.specular().map_or((1.0, Vec3::ONE), |s| (s.specular_factor(), Vec3::from(s.specular_color_factor())));
            let f0 = (0.04 * specular_colour * specular_factor).min(Vec3::ONE);
            let mut dielectric = if f0.max_element() > 0.0 {
                Material::glossy(name.clone(), factor.truncate(), f0, roughness.max(MIN_GLOSSY_ROUGHNESS))
            } else {
                Material::diffuse(name.clone(), factor.truncate())
            };
            if let Some((image, texture, _)) = &base_texture {
                let rgb = factor.truncate();
                dielectric.albedo_texture =
                    Some(self.place(textures, (*image, Baked::Albedo(rgb.to_array().map(f32::to_bits))), || {
                        let mut baked = Texture::clone(texture);
                        bake_factor(&mut baked, rgb);
                        Ok(baked)
                    })?);
                dielectric.albedo = base_mean;
            }
            dielectric
        };
        let strength = m.emissive_strength().unwrap_or(1.0);
        let mut emission = Vec3::from(m.emissive_factor()) * strength;
        if let Some(info) = m.emissive_texture()
            && emission.max_element() > 0.0
        {
            emission *= self.image(&info.texture(), TextureUsage::Albedo)?.mean_rgb();
        }
        material.emission = emission.max(Vec3::ZERO);
        let cutoff = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            gltf::material::AlphaMode::Mask => Some(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => {
                self.warnings.push(format!(
                    "{}: material {name:?}: alphaMode BLEND drawn as an alpha test at 0.5 (no blending here)",
                    self.path.display()
                ));
                Some(0.5)
            }
        };
        if let Some(cutoff) = cutoff {
            let image = base_texture.as_ref().map(|(image, texture, _)| (*image, texture.as_ref()));
            self.alpha_test(&mut material, factor.w, image, cutoff, textures)?;
        }
        let uv_set = base_texture.as_ref().map_or(0, |(_, _, set)| *set);
        Ok((material, uv_set))
    }

    /// Sets the material's cut-out so that the renderer's test (coverage below 0.5 is a hole)
    /// is glTF's (alpha below `cutoff` is a hole): the mask holds `0.5 × alpha / cutoff`, a
    /// linear map, so bilinear filtering crosses the threshold where alpha crosses the cutoff.
    /// `image` is the base-colour image (its index and its decoded texture), if any.
    fn alpha_test(
        &mut self,
        material: &mut Material,
        factor_alpha: f32,
        image: Option<(usize, &Texture)>,
        cutoff: f32,
        textures: &mut Vec<Texture>,
    ) -> Result<(), SceneError> {
        if !(cutoff > 0.0 && cutoff.is_finite()) {
            // A cutoff of 0 keeps every texel.
            return Ok(());
        }
        let scale = 0.5 / cutoff;
        match image.filter(|(_, t)| t.channels == 4) {
            Some((index, t)) => {
                let key = (index, Baked::Mask([factor_alpha.to_bits(), cutoff.to_bits()]));
                let path = self.path;
                let mask = self.place(textures, key, || {
                    let alpha = t.data.chunks_exact(4).map(|p| (p[3] * factor_alpha * scale).min(1e6)).collect();
                    Texture::new(format!("{}-alpha", t.name), t.width, t.height, 1, alpha)
                        .map_err(|m| SceneError::invalid(path, m))
                })?;
                material.opacity_texture = Some(mask);
            }
            None => material.opacity = (factor_alpha * scale).clamp(0.0, 1.0),
        }
        Ok(())
    }

    /// The scene texture `key` names: the one made before, or `make`'s, added to `textures`.
    fn place(
        &mut self,
        textures: &mut Vec<Texture>,
        key: (usize, Baked),
        make: impl FnOnce() -> Result<Texture, SceneError>,
    ) -> Result<u32, SceneError> {
        if let Some(&index) = self.placed.get(&key) {
            return Ok(index);
        }
        textures.push(make()?);
        let index = (textures.len() - 1) as u32;
        self.placed.insert(key, index);
        Ok(index)
    }

    /// The image of `texture` decoded for `usage` (once per image and usage).
    fn image(&mut self, texture: &gltf::Texture, usage: TextureUsage) -> Result<Rc<Texture>, SceneError> {
        let image = texture.source();
        if let Some(decoded) = self.decoded.get(&(image.index(), usage)) {
            return Ok(Rc::clone(decoded));
        }
        let origin = PathBuf::from(format!("{}#image{}", self.path.display(), image.index()));
        let bytes: Vec<u8> = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let buffer = self.buffers.get(view.buffer().index()).map_or(&[][..], Vec::as_slice);
                let range = view.offset()..view.offset().saturating_add(view.length());
                buffer.get(range).map(<[u8]>::to_vec).ok_or_else(|| {
                    self.invalid(format!("image {}: its buffer view reaches outside buffer", image.index()))
                })?
            }
            gltf::image::Source::Uri { uri, .. } => {
                read_uri(self.path, uri, self.base, &format!("image {}", image.index()))?
            }
        };
        let name = image.name().map_or_else(|| format!("image{}", image.index()), str::to_owned);
        let decoded = Rc::new(Texture::decode(&name, &bytes, usage, &origin)?);
        self.decoded.insert((image.index(), usage), Rc::clone(&decoded));
        Ok(decoded)
    }
}

/// The corner indices of each triangle of a primitive in `mode`.
fn triangle_corners(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        // Every other strip triangle is wound the other way round; glTF's rule restores it.
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                let (a, b, c) = (indices[i - 2], indices[i - 1], indices[i]);
                if i % 2 == 0 { [a, b, c] } else { [b, a, c] }
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len()).map(|i| [indices[i - 1], indices[i], indices[0]]).collect(),
        _ => Vec::new(),
    }
}

/// Multiplies a colour texture's RGB by `factor` (glTF's base-colour factor).
fn bake_factor(texture: &mut Texture, factor: Vec3) {
    if factor == Vec3::ONE {
        return;
    }
    let c = texture.channels as usize;
    for (i, v) in texture.data.iter_mut().enumerate() {
        if i % c < 3 {
            *v *= factor[i % c];
        }
    }
}

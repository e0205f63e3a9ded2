//! glTF 2.0 scenes: geometry and transforms, materials by the documented rules, cameras and
//! `KHR_lights_punctual` lights, and a clear error for each kind of bad file.
//!
//! The files are written here by a small builder (JSON with a base64 buffer, or a GLB), so
//! each test states exactly what the file holds. The shared scenes converted by independent
//! tools (obj2gltf, glTF-Transform) and checked by the Khronos validator are compared with
//! their OBJ renders in `tests/gltf_shared_scenes.rs`.

use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{Vec2, Vec3};
use serde_json::{Value, json};
use stereotrace_runtime::scene::gltf_file::{load_gltf, load_gltf_bytes};
use stereotrace_runtime::scene::{MaterialKind, SceneError, UnitsFrom, resolve};

/// A glTF file being written: one binary buffer and the JSON around it.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats(&mut self, values: &[f32], width: usize) -> usize {
        let view = self.view(bytemuck::cast_slice(values));
        let kind = match width {
            2 => "VEC2",
            3 => "VEC3",
            _ => "SCALAR",
        };
        let mut accessor =
            json!({"bufferView": view, "componentType": 5126, "count": values.len() / width, "type": kind});
        if width == 3 {
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for p in values.chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn indices(&mut self, values: &[u16]) -> usize {
        let view = self.view(bytemuck::cast_slice(values));
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5123, "count": values.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// The JSON document around `rest` (meshes, nodes, materials, ...), with the buffer as a
    /// data URI.
    fn gltf(&self, rest: Value) -> Value {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        let mut doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": self.bin.len(), "uri": uri}],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (k, v) in rest.as_object().expect("an object").iter() {
            doc[k] = v.clone();
        }
        doc
    }

    /// The same document as a GLB: the buffer in the binary chunk.
    fn glb(&self, rest: Value) -> Vec<u8> {
        let mut doc = self.gltf(rest);
        doc["buffers"] = json!([{"byteLength": self.bin.len()}]);
        let mut json_chunk = serde_json::to_vec(&doc).unwrap();
        while !json_chunk.len().is_multiple_of(4) {
            json_chunk.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json_chunk.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json_chunk);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// A unit quad in the z = 0 plane facing +z (two triangles), with normals and UVs.
fn quad(b: &mut Builder) -> Value {
    let positions = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
    let normals = [0.0, 0.0, 1.0].repeat(4);
    let uvs = [0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    let p = b.floats(&positions, 3);
    let n = b.floats(&normals, 3);
    let t = b.floats(&uvs, 2);
    let i = b.indices(&[0, 1, 2, 0, 2, 3]);
    json!({"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i, "material": 0})
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-gltf-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write_json(dir: &Path, name: &str, doc: &Value) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
    path
}

fn load_doc(doc: &Value) -> Result<stereotrace_runtime::scene::gltf_file::GltfData, SceneError> {
    load_gltf_bytes(Path::new("test.gltf"), &serde_json::to_vec(doc).unwrap(), None, 1.0)
}

fn error_of(doc: &Value) -> String {
    load_doc(doc).expect_err("the file must be refused").to_string()
}

/// A scene of one quad under `node` (which gets `"mesh": 0`) with `material`.
fn one_quad(node: Value, material: Value) -> (Builder, Value) {
    let mut b = Builder::default();
    let primitive = quad(&mut b);
    let mut node = node;
    node["mesh"] = json!(0);
    let rest = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{"primitives": [primitive]}],
        "materials": [material],
    });
    (b, rest)
}

#[test]
fn node_transforms_place_the_triangles_and_the_winding_survives_a_mirror() {
    let (b, rest) = one_quad(json!({"translation": [1, 2, 3], "scale": [2, 2, 2]}), json!({}));
    let data = load_doc(&b.gltf(rest)).unwrap();
    let mesh = &data.geometry.mesh;
    assert_eq!(mesh.len(), 2);
    assert_eq!(mesh.positions[0], [Vec3::new(1.0, 2.0, 3.0), Vec3::new(3.0, 2.0, 3.0), Vec3::new(3.0, 4.0, 3.0)]);
    assert!(mesh.geometric_normal(0).abs_diff_eq(Vec3::Z, 1e-6));

    // Mirrored in x: the quad still faces +z (the winding is flipped back) and so do its normals.
    let (b, rest) = one_quad(json!({"scale": [-1, 1, 1]}), json!({}));
    let mesh = load_doc(&b.gltf(rest)).unwrap().geometry.mesh;
    for t in 0..mesh.len() {
        assert!(mesh.geometric_normal(t).abs_diff_eq(Vec3::Z, 1e-6), "{}", mesh.geometric_normal(t));
        assert!(mesh.shading_normal(t, 0.3, 0.3).abs_diff_eq(Vec3::Z, 1e-6));
    }
    assert!(mesh.positions.iter().flatten().all(|p| p.x <= 0.0));

    // A rotation turns the normals with the geometry (inverse transpose of a rotation is itself).
    let quarter = std::f32::consts::FRAC_1_SQRT_2;
    let (b, rest) = one_quad(json!({"rotation": [quarter, 0, 0, quarter]}), json!({}));
    let mesh = load_doc(&b.gltf(rest)).unwrap().geometry.mesh;
    assert!(mesh.shading_normal(0, 0.2, 0.2).abs_diff_eq(-Vec3::Y, 1e-5), "{}", mesh.shading_normal(0, 0.2, 0.2));
    assert!(mesh.geometric_normal(0).abs_diff_eq(-Vec3::Y, 1e-5));
}

#[test]
fn texture_coordinates_flip_v_to_the_bottom_row_convention() {
    let (b, rest) = one_quad(json!({}), json!({}));
    let mesh = load_doc(&b.gltf(rest)).unwrap().geometry.mesh;
    // glTF's (0, 1) (bottom-left, v counted from the top) is (0, 0) here.
    assert_eq!(mesh.uvs.as_ref().unwrap()[0][0], Vec2::new(0.0, 0.0));
    assert_eq!(mesh.uvs.as_ref().unwrap()[0][2], Vec2::new(1.0, 1.0));
}

#[test]
fn strips_and_fans_give_front_facing_triangles() {
    for mode in [5, 6] {
        let mut b = Builder::default();
        // A strip 0-1-2-3 and a fan 0-1-2-3 over the same quad corners, both facing +z.
        let positions: &[f32] = if mode == 5 {
            &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0]
        } else {
            &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]
        };
        let p = b.floats(positions, 3);
        let rest = json!({
            "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p}, "mode": mode}]}],
        });
        let mesh = load_doc(&b.gltf(rest)).unwrap().geometry.mesh;
        assert_eq!(mesh.len(), 2, "mode {mode}");
        assert!(mesh.normals.is_none(), "no NORMAL: flat shaded");
        for t in 0..2 {
            assert!(mesh.geometric_normal(t).abs_diff_eq(Vec3::Z, 1e-6), "mode {mode} triangle {t}");
        }
    }
}

#[test]
fn materials_follow_the_documented_rules() {
    let materials = json!([
        {"name": "rough-plastic", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.4, 0.3, 1], "metallicFactor": 0, "roughnessFactor": 0.5}},
        {"name": "matte", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0}}},
        {"name": "chrome", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.8, 1], "metallicFactor": 1, "roughnessFactor": 0}},
        {"name": "brushed", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.3, 1], "metallicFactor": 1, "roughnessFactor": 0.4}},
        {"name": "lamp", "pbrMetallicRoughness": {"metallicFactor": 0}, "emissiveFactor": [1, 0.5, 0.25],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 40}, "KHR_materials_specular": {"specularFactor": 0}}},
        {"name": "tinted-specular", "pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.3},
         "extensions": {"KHR_materials_specular": {"specularColorFactor": [0.5, 1, 1]}}}
    ]);
    let mut b = Builder::default();
    let primitive = quad(&mut b);
    let primitives: Vec<Value> = (0..6)
        .map(|m| {
            let mut p = primitive.clone();
            p["material"] = json!(m);
            p
        })
        .collect();
    let rest = json!({
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}], "meshes": [{"primitives": primitives}],
        "materials": materials,
        "extensionsUsed": ["KHR_materials_specular", "KHR_materials_emissive_strength"],
    });
    let data = load_doc(&b.gltf(rest)).unwrap();
    let m = &data.geometry.materials;
    let by = |name: &str| m.iter().find(|x| x.name == name).unwrap();
    let plastic = by("rough-plastic");
    assert_eq!(plastic.kind, MaterialKind::Glossy);
    assert_eq!(plastic.albedo, Vec3::new(0.5, 0.4, 0.3));
    assert_eq!(plastic.specular, Vec3::splat(0.04));
    assert_eq!(plastic.roughness, 0.5);
    assert_eq!(by("matte").kind, MaterialKind::Diffuse);
    let chrome = by("chrome");
    assert_eq!((chrome.kind, chrome.specular), (MaterialKind::Mirror, Vec3::new(0.9, 0.9, 0.8)));
    let brushed = by("brushed");
    assert_eq!((brushed.kind, brushed.albedo, brushed.roughness), (MaterialKind::Glossy, Vec3::ZERO, 0.4));
    assert_eq!(brushed.specular, Vec3::new(0.9, 0.6, 0.3));
    assert!(brushed.metallic);
    let lamp = by("lamp");
    assert_eq!(lamp.emission, Vec3::new(40.0, 20.0, 10.0));
    assert_eq!(lamp.kind, MaterialKind::Diffuse);
    assert_eq!(by("tinted-specular").specular, Vec3::new(0.02, 0.04, 0.04));
    // glTF's default material (for primitives without one) is last: a rough white metal.
    let default = m.last().unwrap();
    assert!(default.metallic && default.kind == MaterialKind::Glossy && default.specular == Vec3::ONE);
}

/// A 2×1 RGBA PNG: an opaque red texel and a green one of alpha 0.2.
fn two_texel_png() -> Vec<u8> {
    let img = image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 255, 0, 51]).unwrap();
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
    bytes
}

#[test]
fn base_colour_textures_are_srgb_with_the_factor_baked_in_and_mask_tests_at_the_cutoff() {
    let png = base64::engine::general_purpose::STANDARD.encode(two_texel_png());
    let mut b = Builder::default();
    let primitive = quad(&mut b);
    let images = json!([{"uri": format!("data:image/png;base64,{png}")}]);
    let material = |cutoff: f32| {
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [0.5, 1, 1, 1], "metallicFactor": 0},
               "alphaMode": "MASK", "alphaCutoff": cutoff,
               "extensions": {"KHR_materials_specular": {"specularFactor": 0}}})
    };
    for cutoff in [0.1f32, 0.5] {
        let rest = json!({
            "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}], "meshes": [{"primitives": [primitive]}],
            "materials": [material(cutoff)], "textures": [{"source": 0}], "images": images,
        });
        let data = load_doc(&b.gltf(rest)).unwrap();
        let (m, textures) = (&data.geometry.materials[0], &data.geometry.textures);
        let albedo = &textures[m.albedo_texture.unwrap() as usize];
        // The red texel decoded from sRGB 255 is 1.0, times the factor's 0.5.
        assert_eq!(albedo.texel(0, 0).x, 0.5);
        assert_eq!(albedo.texel(1, 0).y, 1.0);
        // Texel centres: u = 0.25 is the opaque texel, u = 0.75 the one of alpha 0.2.
        let (opaque, faint) =
            (m.coverage_at(textures, Vec2::new(0.25, 0.5)), m.coverage_at(textures, Vec2::new(0.75, 0.5)));
        assert!(opaque >= 0.5, "cutoff {cutoff}: {opaque}");
        assert_eq!(faint >= 0.5, 0.2 >= cutoff, "cutoff {cutoff}: alpha 0.2 gives coverage {faint}");
    }
}

#[test]
fn cameras_and_punctual_lights_come_from_the_nodes() {
    let (b, mut rest) = one_quad(json!({}), json!({}));
    let quarter = std::f32::consts::FRAC_1_SQRT_2;
    rest["nodes"] = json!([
        {"mesh": 0},
        {"camera": 0, "translation": [0, 1, 5]},
        {"translation": [0, 3, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        // Rotated -90 deg about x: its -z axis points down.
        {"translation": [2, 3, 0], "rotation": [-quarter, 0, 0, quarter], "extensions": {"KHR_lights_punctual": {"light": 1}}},
        {"rotation": [-quarter, 0, 0, quarter], "extensions": {"KHR_lights_punctual": {"light": 2}}},
    ]);
    rest["scenes"] = json!([{"nodes": [0, 1, 2, 3, 4]}]);
    rest["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}]);
    rest["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    rest["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1, 0.5, 0.5], "intensity": 20},
        {"type": "spot", "intensity": 100, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.4}},
        {"type": "directional", "intensity": 3},
    ]}});
    let data = load_doc(&b.gltf(rest)).unwrap();
    let camera = data.camera.unwrap();
    assert_eq!(camera.eye, Vec3::new(0.0, 1.0, 5.0));
    assert_eq!(camera.target, Vec3::new(0.0, 1.0, 4.0));
    assert!((camera.vfov_deg - 0.8f32.to_degrees()).abs() < 1e-4);
    let points = &data.lights.points;
    assert_eq!(points.len(), 2);
    assert_eq!((points[0].position, points[0].intensity), (Vec3::new(0.0, 3.0, 0.0), Vec3::new(20.0, 10.0, 10.0)));
    assert!(points[0].spot.is_none());
    let cone = points[1].spot.unwrap();
    assert!(cone.direction.abs_diff_eq(-Vec3::Y, 1e-5), "{}", cone.direction);
    assert!((cone.cos_inner - 0.2f32.cos()).abs() < 1e-6 && (cone.cos_outer - 0.4f32.cos()).abs() < 1e-6);
    // Straight down is full intensity, 0.3 rad off the axis is between, 0.5 rad is dark.
    let off = |angle: f32| Vec3::new(angle.sin(), -angle.cos(), 0.0);
    assert_eq!(cone.falloff(off(0.0)), 1.0);
    let between = cone.falloff(off(0.3));
    assert!(between > 0.0 && between < 1.0, "{between}");
    assert_eq!(cone.falloff(off(0.5)), 0.0);
    let sun = data.lights.sun.unwrap();
    // A light shining down is a sun straight up.
    assert!(sun.direction.abs_diff_eq(Vec3::Y, 1e-5) && sun.irradiance == Vec3::splat(3.0));
}

#[test]
fn a_glb_loads_as_its_json_twin_and_a_file_spec_resolves_with_its_camera() {
    let (b, mut rest) = one_quad(json!({}), json!({"emissiveFactor": [1, 1, 1]}));
    rest["nodes"] = json!([{"mesh": 0}, {"camera": 0, "translation": [0.5, 0.5, 3]}]);
    rest["scenes"] = json!([{"nodes": [0, 1]}]);
    rest["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}}]);
    let dir = scratch("glb");
    let json_path = write_json(&dir, "quad.gltf", &b.gltf(rest.clone()));
    let glb_path = dir.join("quad.glb");
    std::fs::write(&glb_path, b.glb(rest)).unwrap();
    let (a, g) = (load_gltf(&json_path, 1.0).unwrap(), load_gltf(&glb_path, 1.0).unwrap());
    assert_eq!(a.geometry.mesh, g.geometry.mesh);
    assert_eq!(a.geometry.materials, g.geometry.materials);

    let scene = resolve(glb_path.to_str().unwrap()).unwrap();
    assert_eq!(scene.name, "quad");
    assert_eq!(scene.units.from, UnitsFrom::Gltf);
    let pose = scene.camera.pose(0);
    assert!(pose.eye.abs_diff_eq(Vec3::new(0.5, 0.5, 3.0), 1e-5), "{}", pose.eye);
    assert_eq!(scene.lights.area.len(), 2, "the emissive quad is an area light");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_file_without_a_camera_gets_one_that_frames_it_with_a_warning() {
    let (b, rest) = one_quad(json!({}), json!({"emissiveFactor": [1, 1, 1]}));
    let dir = scratch("nocam");
    let path = write_json(&dir, "bare.gltf", &b.gltf(rest));
    let scene = resolve(path.to_str().unwrap()).unwrap();
    assert!(scene.warnings.iter().any(|w| w.contains("framing")), "{:?}", scene.warnings);
    let pose = scene.camera.pose(0);
    assert!(pose.forward.dot((Vec3::new(0.5, 0.5, 0.0) - pose.eye).normalize()) > 0.999);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_files_are_refused_with_a_message_that_says_why() {
    // JSON syntax: line and column.
    let e = load_gltf_bytes(Path::new("bad.gltf"), b"{\n  \"asset\": {\"version\": \"2.0\"},\n  oops\n}", None, 1.0)
        .unwrap_err();
    assert!(matches!(&e, SceneError::Parse { location, .. } if location.line == Some(3)), "{e}");

    // A required extension this loader cannot read is named.
    let (b, mut rest) = one_quad(json!({}), json!({}));
    rest["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    rest["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let e = error_of(&b.gltf(rest));
    assert!(e.contains("KHR_draco_mesh_compression") && e.contains("does not support"), "{e}");

    // An index past the vertices.
    let mut b = Builder::default();
    let p = b.floats(&[0.0; 9], 3);
    let i = b.indices(&[0, 1, 7]);
    let rest = json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p}, "indices": i}]}]});
    let e = error_of(&b.gltf(rest));
    assert!(e.contains("index 7") && e.contains("3 vertices"), "{e}");

    // An accessor that claims more elements than its view holds.
    let (b, rest) = one_quad(json!({}), json!({}));
    let mut doc = b.gltf(rest);
    doc["accessors"][0]["count"] = json!(400);
    let e = error_of(&doc);
    assert!(e.contains("outside"), "{e}");

    // Positions of the wrong type.
    let (b, rest) = one_quad(json!({}), json!({}));
    let mut doc = b.gltf(rest);
    doc["accessors"][0]["componentType"] = json!(5123);
    let e = error_of(&doc);
    assert!(e.contains("POSITION") && e.contains("U16"), "{e}");

    // A cycle in the node graph.
    let (b, mut rest) = one_quad(json!({}), json!({}));
    rest["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
    let e = error_of(&b.gltf(rest));
    assert!(e.contains("reached twice"), "{e}");

    // NaN coordinates (written as a float the JSON cannot hold, so in the buffer).
    let mut b = Builder::default();
    let p = b.floats(&[0.0, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0, 0.0], 3);
    let rest = json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p}}]}]});
    let mut doc = b.gltf(rest);
    doc["accessors"][0]["min"] = json!([0, 0, 0]);
    doc["accessors"][0]["max"] = json!([1, 1, 0]);
    let e = error_of(&doc);
    assert!(e.contains("not finite"), "{e}");

    // Nothing to draw.
    let doc = json!({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}]});
    assert!(error_of(&doc).contains("no triangles"));

    // Not glTF at all.
    let e = load_gltf_bytes(Path::new("x.glb"), b"glTF\x02\0\0\0\x10\0\0\0garbage!", None, 1.0).unwrap_err();
    assert!(e.to_string().contains("GLB"), "{e}");
}

#[test]
fn missing_buffers_and_images_name_the_file() {
    let dir = scratch("missing");
    let (b, rest) = one_quad(json!({}), json!({}));
    let mut doc = b.gltf(rest);
    doc["buffers"][0]["uri"] = json!("gone%20away.bin");
    let path = write_json(&dir, "a.gltf", &doc);
    let e = load_gltf(&path, 1.0).unwrap_err().to_string();
    assert!(e.contains("buffer 0") && e.contains("gone away.bin") && e.contains("a.gltf"), "{e}");

    let (b, mut rest) = one_quad(json!({}), json!({}));
    rest["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    rest["textures"] = json!([{"source": 0}]);
    rest["images"] = json!([{"uri": "no-such.png"}]);
    let path = write_json(&dir, "b.gltf", &b.gltf(rest));
    let e = load_gltf(&path, 1.0).unwrap_err().to_string();
    assert!(e.contains("image 0") && e.contains("no-such.png"), "{e}");

    // A buffer shorter than it claims.
    let (b, rest) = one_quad(json!({}), json!({}));
    let mut doc = b.gltf(rest);
    doc["buffers"][0]["byteLength"] = json!(100_000);
    let e = error_of(&doc);
    assert!(e.contains("buffer 0 holds"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_manifest_takes_a_gltf_mesh_with_its_own_unit_and_lights() {
    let (b, mut rest) = one_quad(json!({}), json!({"emissiveFactor": [1, 1, 1]}));
    rest["nodes"] = json!([{"mesh": 0}, {"camera": 0, "translation": [500, 500, 3000]}]);
    rest["scenes"] = json!([{"nodes": [0, 1]}]);
    rest["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}}]);
    let dir = scratch("manifest");
    std::fs::write(dir.join("mm.glb"), b.glb(rest)).unwrap();
    // The quad is 1 unit wide; the manifest says a unit of this file is a kilometre.
    let manifest = dir.join("boxed.toml");
    std::fs::write(
        &manifest,
        "name = \"boxed\"\nmesh = \"mm.glb\"\nmeters_per_unit = 1000.0\n\n[[lights]]\ntype = \"point\"\nposition = [0.5, 0.5, 1.0]\nintensity = [1, 1, 1]\n",
    )
    .unwrap();
    let scene = resolve(manifest.to_str().unwrap()).unwrap();
    assert_eq!(scene.units.from, UnitsFrom::Manifest);
    assert_eq!(scene.mesh.positions[0][1], Vec3::new(1000.0, 0.0, 0.0), "scaled by meters_per_unit");
    // The file's camera is scaled with its geometry.
    assert!(scene.camera.pose(0).eye.abs_diff_eq(Vec3::new(500_000.0, 500_000.0, 3_000_000.0), 1.0));
    assert_eq!(scene.lights.points.len(), 1);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_attribute_naming_a_missing_accessor_is_refused_before_validation() {
    // gltf-json 1.4.1's validation would index past the accessors (the gltf fuzz target's
    // first find).
    let (b, rest) = one_quad(json!({}), json!({}));
    let mut doc = b.gltf(rest);
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(5);
    let e = error_of(&doc);
    assert!(e.contains("accessor 5") && e.contains("has 4"), "{e}");
}

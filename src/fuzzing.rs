//! Fuzz entry points above the kernels: the scene loaders (OBJ, MTL, `camera.json`, `lights.json`, TOML manifests, glTF), image decoding
//! (EXR, PNG, JPEG) and the evaluation cache's entry decoding. Each takes arbitrary bytes
//! and panics only when a property fails:
//!
//! * bad input is refused with an error value, never a panic, an abort or a huge allocation;
//! * what loads is valid (a scene passes `Scene::validate` and builds a renderer; an image
//!   has the extent its header claims);
//! * a cache payload decodes to what encodes back to the same bytes.
//!
//! The cargo-fuzz targets in `fuzz/` are one-line shims over these (the kernels' ones, the
//! rasterisers' among them, are in `stereotrace_kernels::fuzzing`), and `tests/fuzz_corpus_above_kernels.rs` replays the committed
//! corpora through them. Loaders read files, so the file-based entries write the input into
//! a per-process scratch folder first (under `/dev/shm` where it exists).

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};

use crate::eval::cache;
use crate::render::Renderer;
use crate::scene::folder::{FolderOptions, load_folder, load_scene_file};
use crate::scene::manifest::load_manifest;
use crate::scene::{EnvMap, Texture, TextureUsage};

/// This process's scratch folder (created once, emptied of nothing: every entry overwrites
/// the files it reads).
fn scratch() -> PathBuf {
    let base = if Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
    let dir = base.join(format!("stereotrace-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder for fuzz inputs");
    dir
}

/// Splits `data` at lines `#@@` into at most `n` parts (missing parts are empty).
fn parts(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut out = Vec::with_capacity(n);
    let mut rest = data;
    while out.len() + 1 < n {
        match rest.windows(4).position(|w| w == b"#@@\n") {
            Some(i) => {
                out.push(&rest[..i]);
                rest = &rest[i + 4..];
            }
            None => break,
        }
    }
    out.push(rest);
    out.resize(n, &[]);
    out
}

/// A loaded scene must be valid and build a renderer (its BVH, lights and textures).
fn check_scene(scene: crate::scene::Scene) {
    scene.validate().expect("a loaded scene is valid");
    if let Err(e) = Renderer::new(scene) {
        // Refusals are fine; they must explain themselves.
        assert!(!e.to_string().is_empty());
    }
}

/// Fuzzes a scene folder: the input is `scene.obj`, `scene.mtl`, `camera.json` and
/// `lights.json`, separated by lines `#@@`. Loading must succeed with a valid scene or fail
/// with a `SceneError`.
pub fn scene_folder(data: &[u8]) {
    let dir = scratch().join("folder");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let files = ["scene.obj", "scene.mtl", "camera.json", "lights.json"];
    for (name, part) in files.iter().zip(parts(data, files.len())) {
        std::fs::write(dir.join(name), part).expect("scratch file");
    }
    let options = FolderOptions { scale: Some(1.0), frames: 4, ..FolderOptions::default() };
    if let Ok(scene) = load_folder(&dir, &options) {
        check_scene(scene);
    }
}

/// A small valid folder that manifests fuzzed by [`manifest`] refer to (`mesh = "base"`).
const BASE_OBJ: &str = "mtllib scene.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv 0 1 0\n\
usemtl white\nf 1 2 3\nf 1 3 4\nusemtl lamp\nf 1 2 5\n";
const BASE_MTL: &str = "newmtl white\nKd 0.8 0.8 0.8\nnewmtl lamp\nKd 0 0 0\nKe 4 4 4\n";
const BASE_CAMERA: &str = r#"{"eye": [0, 0.5, 3], "target": [0, 0.3, 0], "up": [0, 1, 0], "vfov_deg": 60}"#;

/// Fuzzes TOML manifests over a small fixed folder (`base/`, beside the manifest). Loading
/// must succeed with a valid scene or fail with a `SceneError`.
pub fn manifest(data: &[u8]) {
    let dir = scratch().join("manifest");
    let base = dir.join("base");
    if !base.join("camera.json").is_file() {
        std::fs::create_dir_all(&base).expect("scratch folder");
        for (name, text) in [("scene.obj", BASE_OBJ), ("scene.mtl", BASE_MTL), ("camera.json", BASE_CAMERA)] {
            std::fs::write(base.join(name), text).expect("scratch file");
        }
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, data).expect("scratch file");
    if let Ok(scene) = load_manifest(&path) {
        check_scene(scene);
    }
}

/// Fuzzes the glTF loader with a whole file, GLB or JSON (buffers in the GLB chunk or in
/// `data:` URIs; a relative URI can only name the input itself, alone in its scratch folder).
/// Loading must succeed with a valid scene or fail with a `SceneError`. Run with
/// [`let_caught_panics_pass`]: the loader catches its image decoders' panics, and the `gltf`
/// crate's, and returns errors.
pub fn gltf(data: &[u8]) {
    let dir = scratch().join("gltf");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let path = dir.join("scene.glb");
    std::fs::write(&path, data).expect("scratch file");
    let options = FolderOptions { frames: 4, ..FolderOptions::default() };
    if let Ok(scene) = load_scene_file(&path, &options) {
        check_scene(scene);
    }
}

/// Lets panics that the code under test catches itself pass, for the `image` target.
///
/// `libfuzzer-sys` installs a panic hook that aborts at once, so that a panic counts as a
/// crash before anything can catch it. [`Texture::load`] catches its JPEG decoder's panics
/// and returns an error (its contract), which that hook would report as a crash. The hook
/// put in its place prints the panic's message and nothing else: the default hook captures
/// and symbolises a backtrace for each one under cargo-fuzz's `RUST_BACKTRACE=1`, and a
/// 40-minute run catches ~500 decoder panics. A panic that escapes the
/// entry point still aborts the process (`libfuzzer-sys` catches it at the top and aborts),
/// so no escaping panic is missed; `cargo test` replays the input with the full message.
pub fn let_caught_panics_pass() {
    std::panic::set_hook(Box::new(|info| eprintln!("{info}")));
}

/// Fuzzes image decoding: the first byte picks the format and one reader, EXR (its header,
/// then read whole; or as an environment map), PNG or JPEG (as an albedo or as a mask
/// texture); the rest is the file.
pub fn image(data: &[u8]) {
    let (kind, file) = data.split_first().map_or((0, &[][..]), |(k, rest)| (*k, rest));
    let ext = ["exr", "png", "jpg"][usize::from(kind % 3)];
    // The same byte picks one reader of the file (decoding dominates an execution, so one
    // decode per input fuzzes each reader as often in half the time).
    let second_reader = (kind / 3) % 2 == 1;
    let path = scratch().join(format!("image.{ext}"));
    std::fs::write(&path, file).expect("scratch file");
    if ext == "exr" {
        if second_reader {
            if let Ok((env, _)) = EnvMap::load_exr(&path, 1.0, Mat3::IDENTITY) {
                let radiance = env.radiance(Vec3::Y);
                assert!(radiance.is_finite() && radiance.min_element() >= 0.0, "environment radiance {radiance}");
            }
        } else {
            let header = crate::image_io::exr_extent(&path);
            if let Ok(img) = crate::image_io::read_exr(&path) {
                assert_eq!(Ok(img.extent()), header.map_err(|e| e.to_string()), "decoded extent vs header");
            }
        }
    } else {
        let usage = if second_reader { TextureUsage::Mask } else { TextureUsage::Albedo };
        if let Ok(t) = Texture::load(&path, usage) {
            let texel = t.sample(glam::Vec2::new(0.3, 0.7));
            assert!(texel.is_finite(), "texel {texel}");
        }
    }
}

/// Fuzzes the evaluation cache's decoding: the bytes as a whole entry file (must be refused
/// unless it is well formed), then as a payload in a well-formed entry, read by the image,
/// sample-sum and mask decoders; whatever decodes must encode back to the bytes it came from.
pub fn cache_entry(data: &[u8]) {
    let key = cache::CacheKey::new("fuzz", "scene", &[("field", "value".into())]);
    let _ = cache::decode_entry(data, key.text());
    let dir = scratch().join("cache");
    let store = cache::Cache::open(&dir).expect("scratch cache");
    store.put(&key, data).expect("scratch cache entry");
    let payload = match store.get(&key) {
        cache::Lookup::Hit(p) => p,
        other => panic!("a fresh entry does not read back: {other:?}"),
    };
    assert_eq!(payload, data, "payload round trip");
    let mut r = cache::Reader::new(data);
    if let Ok(img) = cache::decode_image(&mut r) {
        let mut out = Vec::new();
        cache::encode_image(&img, &mut out);
        assert_eq!(out, data[..out.len()], "image round trip");
    }
    let mut r = cache::Reader::new(data);
    if let Ok(sums) = cache::decode_sums(&mut r) {
        let mut out = Vec::new();
        cache::encode_sums(&sums, &mut out);
        assert_eq!(out, data[..out.len()], "sums round trip");
    }
    let mut r = cache::Reader::new(data);
    if let Ok(mask) = cache::decode_mask(&mut r) {
        let mut out = Vec::new();
        cache::encode_mask(&mask, &mut out);
        assert_eq!(out, data[..out.len()], "mask round trip");
    }
}

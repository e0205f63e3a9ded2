//! Helpers shared by the integration tests: hostile inputs, and a visible SKIP line.
#![allow(dead_code)]

use std::path::Path;

use stereotrace::kernels::{Extent, RgbBuf};

/// Writes a valid 4×4 EXR at `path`, then rewrites its data and display windows to claim
/// `side`×`side` pixels: a file of a few hundred bytes whose header asks a reader to allocate
/// `side²` pixels.
pub fn exr_claiming(path: &Path, side: i32) {
    stereotrace::image_io::write_exr(path, &RgbBuf::new(Extent::new(4, 4).unwrap(), 0.5)).unwrap();
    let mut bytes = std::fs::read(path).unwrap();
    for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = bytes.windows(name.len()).position(|w| w == name).expect("attribute in the header") + name.len();
        // The attribute's byte size (16), then xmin, ymin, xmax, ymax as little-endian i32.
        bytes[at + 12..at + 16].copy_from_slice(&(side - 1).to_le_bytes());
        bytes[at + 16..at + 20].copy_from_slice(&(side - 1).to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// Reports a test that skipped its work (`why`: what is missing) on the terminal even when
/// the harness captures output: `println!` of a passing test is swallowed, so a skipped
/// test would look like a passed one. Writing to the stderr handle directly bypasses the
/// capture, so `cargo test` shows a `SKIP <test>: <why>` line above its summary.
pub fn skip(why: &str) {
    use std::io::Write;
    let test = std::thread::current().name().unwrap_or("?").to_owned();
    let _ = writeln!(std::io::stderr().lock(), "SKIP {test}: {why}");
}

/// An OBJ of a closed box from −1 to 1 (material `white`; surfaces are two-sided, so the
/// winding does not matter) with a `lamp` quad under its ceiling.
pub const BOX_OBJ: &str = "mtllib scene.mtl
v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
v -0.3 0.99 -0.3
v 0.3 0.99 -0.3
v 0.3 0.99 0.3
v -0.3 0.99 0.3
usemtl white
f 1 2 3 4
f 5 8 7 6
f 1 5 6 2
f 4 3 7 8
f 1 4 8 5
f 2 6 7 3
usemtl lamp
f 9 10 11 12
";

/// Appended after [`BOX_OBJ`] (vertices 13..): a zero-area triangle (three equal vertices),
/// a collinear one, a needle 1e-6 wide, and one triangle twice with two materials.
pub const DEGENERATE_OBJ: &str = "v 0 0 0
v 0.2 0.2 0.2
v 0.4 0.4 0.4
v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0 -0.5 -0.499999
v -0.4 -0.2 0
v 0.4 -0.2 0
v 0 0.4 0
usemtl white
f 13 13 13
f 13 14 15
f 16 17 18
f 19 20 21
usemtl red
f 19 20 21
";

/// Writes a scene folder at `dir`: [`BOX_OBJ`] followed by `extra_obj`, materials `white`,
/// `lamp` (emitting `lamp_ke` in every channel) and `red`, and a camera inside the box.
pub fn write_box_scene(dir: &Path, extra_obj: &str, lamp_ke: f32) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("scene.obj"), format!("{BOX_OBJ}{extra_obj}")).unwrap();
    let mtl = format!(
        "newmtl white\nKd 0.9 0.9 0.9\nnewmtl lamp\nKd 0 0 0\nKe {lamp_ke:e} {lamp_ke:e} {lamp_ke:e}\nnewmtl red\nKd 0.9 0.1 0.1\n"
    );
    std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
    std::fs::write(dir.join("camera.json"), r#"{"eye": [0, 0, 0.9], "target": [0, 0, 0], "vfov_deg": 70}"#).unwrap();
}

pub mod eval;

/// The shared scenes converted to glTF by independent tools (`tools/gltf/convert.sh`:
/// obj2gltf and glTF-Transform, checked by the Khronos validator) in `target/gltf-scenes`,
/// converted once per test process. `None`, after a SKIP line, without `../shared/scenes` or
/// Node.js; a missing Node.js fails instead when `STEREOTRACE_REQUIRE_GLTF_TOOLS=1` (CI).
pub fn gltf_scenes() -> Option<&'static Path> {
    use std::path::PathBuf;
    use std::process::Command;
    static OUT: std::sync::OnceLock<Option<PathBuf>> = std::sync::OnceLock::new();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = OUT.get_or_init(|| {
        let shared = root.join("../shared/scenes");
        if !shared.is_dir() {
            return None;
        }
        if !Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success()) {
            if std::env::var("STEREOTRACE_REQUIRE_GLTF_TOOLS").is_ok_and(|v| v == "1") {
                panic!("STEREOTRACE_REQUIRE_GLTF_TOOLS=1 but node is not installed");
            }
            return None;
        }
        let out = root.join("target/gltf-scenes");
        let run = Command::new("bash").arg(root.join("tools/gltf/convert.sh")).arg(&shared).arg(&out).output();
        let run = run.expect("bash runs");
        assert!(
            run.status.success(),
            "converting the shared scenes to glTF failed\n{}\n{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        );
        Some(out)
    });
    if out.is_none() {
        skip("../shared/scenes or node not found");
    }
    out.as_deref()
}

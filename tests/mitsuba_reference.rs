//! The renderer against an independent implementation of the same estimator: Mitsuba 3
//! (`scalar_rgb`, the `path` integrator with max_depth 3, or 2 for `--bounces 0`), driven by
//! `tools/reference/mitsuba_ref.py`, which reads the scene files with its own parser. Each
//! case passes when every channel's mean is within 2 % of Mitsuba's and the relative RMSE of
//! 8×8-block means is within 5 %, at matched spp.
//!
//! Needs `python3` with the `mitsuba` and `numpy` packages (`.ci/run` installs them). Without
//! them the test prints SKIP and passes, unless `STEREOTRACE_REQUIRE_MITSUBA=1` is set (CI
//! sets it), which turns a missing Mitsuba into a failure. The shared-scene cases need
//! `../shared/scenes` (SKIP otherwise). The full table with larger images is in RESULTS.md.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn mitsuba_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import mitsuba, numpy; mitsuba.set_variant('scalar_rgb')"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok && std::env::var("STEREOTRACE_REQUIRE_MITSUBA").is_ok_and(|v| v == "1") {
        panic!("STEREOTRACE_REQUIRE_MITSUBA=1 but python3 cannot import mitsuba and numpy");
    }
    ok
}

/// Runs one comparison; panics with the script's output when it fails.
fn check(scene: &str, res: &str, spp: u32, extra: &[&str]) {
    let work = std::env::temp_dir().join(format!(
        "stereotrace-mitsuba-{}-{}",
        std::process::id(),
        scene.replace(['/', '.'], "_")
    ));
    let out = Command::new("python3")
        .arg(root().join("tools/reference/mitsuba_ref.py"))
        .args(["check", scene, "--stereotrace", env!("CARGO_BIN_EXE_stereotrace"), "--res", res])
        .args(["--spp", &spp.to_string(), "--work", work.to_str().unwrap()])
        .args(extra)
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{scene} {extra:?}: outside the tolerances or failed\n{stdout}\n{stderr}");
    println!("{stdout}");
    let _ = std::fs::remove_dir_all(&work);
}

fn shared(name: &str) -> Option<String> {
    let dir = root().join("../shared/scenes").join(name);
    if dir.is_dir() {
        Some(dir.to_str().unwrap().to_owned())
    } else {
        common::skip(&format!("{} not found", dir.display()));
        None
    }
}

#[test]
fn builtin_cornell_matches_mitsuba() {
    if !mitsuba_available() {
        common::skip("python3 with mitsuba and numpy not found");
        return;
    }
    check("cornell", "64x64", 512, &[]);
}

#[test]
fn shared_cornell_box_matches_mitsuba_with_one_bounce_and_direct_only() {
    if !mitsuba_available() {
        common::skip("python3 with mitsuba and numpy not found");
        return;
    }
    let Some(dir) = shared("cornell-box") else { return };
    check(&dir, "64x64", 1024, &["--bounces", "1"]);
    check(&dir, "64x64", 512, &["--bounces", "0"]);
}

#[test]
fn shared_sponza_diffuse_matches_mitsuba() {
    if !mitsuba_available() {
        common::skip("python3 with mitsuba and numpy not found");
        return;
    }
    let Some(dir) = shared("sponza") else { return };
    check(&dir, "96x54", 256, &["--diffuse", "--opaque", "--skip-glass"]);
}

#[test]
fn features_without_a_mitsuba_equivalent_are_refused_with_a_reason() {
    if !mitsuba_available() {
        common::skip("python3 with mitsuba and numpy not found");
        return;
    }
    let Some(dir) = shared("sponza") else { return };
    let out = Command::new("python3")
        .arg(root().join("tools/reference/mitsuba_ref.py"))
        .args(["render", &dir, "--res", "8x8", "--spp", "1", "--out"])
        .arg(Path::new(&std::env::temp_dir()).join("stereotrace-mitsuba-refused.exr"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "glossy / alpha / glass without overrides: exit 2");
    assert!(String::from_utf8_lossy(&out.stderr).contains("unsupported"));
}

/// The Cornell box converted to glTF by independent tools (`tools/gltf/convert.sh`:
/// obj2gltf and glTF-Transform, checked by the Khronos validator): stereotrace reads the
/// glTF, Mitsuba the OBJ. Needs Node.js as `tests/gltf_shared_scenes.rs` does (SKIP without
/// it unless `STEREOTRACE_REQUIRE_GLTF_TOOLS=1`).
#[test]
fn shared_cornell_box_as_gltf_matches_mitsuba_reading_the_obj() {
    if !mitsuba_available() {
        common::skip("python3 with mitsuba and numpy not found");
        return;
    }
    let Some(dir) = shared("cornell-box") else { return };
    let Some(out) = common::gltf_scenes() else { return };
    let gltf = out.join("cornell-box/scene.glb");
    check(&dir, "128x128", 1024, &["--ours", gltf.to_str().unwrap(), "--label", "cornell-box (glTF)"]);
}

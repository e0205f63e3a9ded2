//! Hard cases at render level, through the command-line tool as a user runs it: frames one
//! pixel wide or tall, the brightest lights the loader accepts, eye separations near the
//! bound, and scenes of degenerate and coincident triangles. Each run must succeed and write
//! images whose every sample is finite (a NaN or an overflow to infinity anywhere in the
//! estimator, the reprojection or the accumulation shows up there).
//! (The kernel-level hard cases are in `kernels/tests/hard_cases.rs`; raster against traced
//! visibility on degenerate and coincident triangles is in `tests/raster_gbuffers.rs`.)

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{DEGENERATE_OBJ, write_box_scene};

fn stereotrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace")).args(args).output().expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereotrace-hard-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn succeeded(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "the run failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Every sample of every EXR under `dir` (at least one) is finite; returns the largest.
fn all_finite(dir: &Path) -> f32 {
    fn walk(dir: &Path, images: &mut usize, largest: &mut f32) {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let p = entry.path();
            if p.is_dir() {
                walk(&p, images, largest);
            } else if p.extension().is_some_and(|e| e == "exr") {
                *images += 1;
                let img = stereotrace::image_io::read_exr(&p).unwrap();
                for plane in img.planes() {
                    for &v in plane.as_slice() {
                        assert!(v.is_finite(), "{}: sample {v}", p.display());
                        *largest = largest.max(v.abs());
                    }
                }
            }
        }
    }
    let (mut images, mut largest) = (0, 0.0f32);
    walk(dir, &mut images, &mut largest);
    assert!(images > 0, "no image written under {}", dir.display());
    largest
}

#[test]
fn frames_one_pixel_wide_or_tall_render_and_run_every_mode() {
    for res in ["1x9", "9x1", "1x1", "17x1"] {
        let dir = temp_dir(&format!("thin-{res}"));
        let out = dir.to_str().unwrap();
        succeeded(&stereotrace(&[
            "render", "--scene", "atrium", "--spp", "2", "--frames", "2", "--res", res, "--out", out,
        ]));
        all_finite(&dir);
        for mode in ["stereo", "temporal", "spatiotemporal", "stereo-blend", "spatiotemporal-blend"] {
            for gbuffer in ["raster", "traced"] {
                let run = stereotrace(&[
                    "throughput",
                    "--scene",
                    "cornell",
                    "--res",
                    res,
                    "--frames",
                    "3",
                    "--mode",
                    mode,
                    "--gbuffer",
                    gbuffer,
                    "--no-baseline",
                    "--json",
                ]);
                succeeded(&run);
                let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
                assert_eq!(report["frames_measured"], 3, "{res} {mode} {gbuffer}");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// A closed box lit by one area light of the largest emitted radiance the loader accepts
/// (`MAX_EMISSION`, 1e15): products in the estimator (radiance × BSDF × cosine / pdf) and the
/// EMA's sums must stay finite.
#[test]
fn the_brightest_accepted_light_renders_finite_images() {
    let dir = temp_dir("bright");
    let scene = dir.join("scene");
    write_box_scene(&scene, "", stereotrace::scene::material::MAX_EMISSION);
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    succeeded(&stereotrace(&[
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--spp",
        "4",
        "--res",
        "24x16",
        "--out",
        out,
    ]));
    let largest = all_finite(&dir.join("out"));
    assert!(largest > 1e13, "the light should show: largest sample {largest}");
    let run = stereotrace(&[
        "throughput",
        "--scene",
        scene.to_str().unwrap(),
        "--res",
        "24x16",
        "--frames",
        "4",
        "--mode",
        "spatiotemporal-blend",
        "--no-baseline",
    ]);
    succeeded(&run);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn eye_separations_up_to_the_bound_render_finite_images_with_a_warning() {
    let dir = temp_dir("separation");
    let out = dir.to_str().unwrap();
    for separation in ["0", "1e-7", "9999"] {
        let err = succeeded(&stereotrace(&[
            "render",
            "--scene",
            "courtyard",
            "--spp",
            "1",
            "--res",
            "16x9",
            "--eye-separation",
            separation,
            "--out",
            out,
        ]));
        assert_eq!(err.contains("wider than the scene"), separation == "9999", "{separation}: {err}");
        all_finite(&dir);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Degenerate (zero-area, collinear, needle) and coincident (the same triangle twice, with
/// different materials) triangles in a lit box: rendered by every pass, finite everywhere.
#[test]
fn degenerate_and_coincident_triangles_render_finite_images() {
    let dir = temp_dir("degenerate");
    let scene = dir.join("scene");
    write_box_scene(&scene, DEGENERATE_OBJ, 5.0);
    let out = dir.join("out");
    succeeded(&stereotrace(&[
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--spp",
        "4",
        "--res",
        "32x18",
        "--out",
        out.to_str().unwrap(),
    ]));
    all_finite(&out);
    for gbuffer in ["raster", "traced"] {
        succeeded(&stereotrace(&[
            "throughput",
            "--scene",
            scene.to_str().unwrap(),
            "--res",
            "32x18",
            "--frames",
            "3",
            "--gbuffer",
            gbuffer,
            "--no-baseline",
        ]));
    }
    std::fs::remove_dir_all(&dir).ok();
}

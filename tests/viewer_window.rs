//! `stereotrace view` in a real window (an X server in memory, `xvfb-run`): it runs a few
//! frames, writes what the window showed (every frame with `--record`, the last with
//! `--screenshot`), and the screenshot holds both eyes of the scene, lit, with the right
//! eye's image shifted by the stereo disparity the scene's depths give.
//!
//! Needs `xvfb-run` (Debian's `xvfb`; `.ci/run` installs it). Without it the test prints
//! SKIP and passes, unless `STEREOTRACE_REQUIRE_XVFB=1` is set (CI sets it).

mod common;

use std::process::Command;

use stereotrace::camera::DEFAULT_EYE_SEPARATION;
use stereotrace::kernels::bvh::{BuildQuality, Ray, TriangleBvh};
use stereotrace::scene::resolve;

const WIDTH: usize = 480;
const HEIGHT: usize = 270;
/// The heads-up lines cover the top of the image.
const HUD_ROWS: usize = 3 * 18;

/// The median disparity in pixels over a grid of the first frame's view: `separation · f / z`
/// for the depth `z` seen through each grid point (the rig is parallel).
fn expected_disparity() -> f32 {
    let scene = resolve("cornell").unwrap();
    let pose = scene.camera.pose(0);
    let (bvh, _) = TriangleBvh::build(&scene.mesh.positions, BuildQuality::Fast).unwrap();
    let tan = (0.5 * pose.vfov_deg.to_radians()).tan();
    let focal = 0.5 * HEIGHT as f32 / tan;
    let aspect = WIDTH as f32 / HEIGHT as f32;
    let mut disparities = Vec::new();
    for j in 0..9 {
        for i in 0..16 {
            let (x, y) = ((i as f32 + 0.5) / 16.0 * 2.0 - 1.0, 1.0 - (j as f32 + 0.5) / 9.0 * 2.0);
            // Below the heads-up band only.
            if (1.0 - y) * 0.5 * HEIGHT as f32 <= HUD_ROWS as f32 {
                continue;
            }
            let dir = (pose.forward + pose.right * (x * tan * aspect) + pose.up * (y * tan)).normalize();
            if let Some(hit) = bvh.intersect(&Ray::new(pose.eye, dir)) {
                let depth = hit.t * dir.dot(pose.forward);
                disparities.push(DEFAULT_EYE_SEPARATION * focal / depth);
            }
        }
    }
    disparities.sort_by(f32::total_cmp);
    disparities[disparities.len() / 2]
}

/// The shift `s` (pixels) that best lines up the left eye's columns `x + s` with the right
/// eye's columns `x`, by normalised correlation of luminance below the heads-up band.
fn best_shift(left: &[f32], right: &[f32], max_shift: usize) -> usize {
    let score = |s: usize| {
        let (mut sab, mut saa, mut sbb, mut sa, mut sb, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for y in HUD_ROWS..HEIGHT {
            for x in 0..WIDTH - s {
                let (a, b) = (f64::from(left[y * WIDTH + x + s]), f64::from(right[y * WIDTH + x]));
                sab += a * b;
                saa += a * a;
                sbb += b * b;
                sa += a;
                sb += b;
                n += 1.0;
            }
        }
        let cov = sab / n - sa / n * sb / n;
        cov / ((saa / n - (sa / n).powi(2)) * (sbb / n - (sb / n).powi(2))).sqrt()
    };
    (0..=max_shift).max_by(|&a, &b| score(a).total_cmp(&score(b))).unwrap()
}

#[test]
fn the_window_shows_both_eyes_apart_by_the_scenes_disparity() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        if std::env::var("STEREOTRACE_REQUIRE_XVFB").is_ok_and(|v| v == "1") {
            panic!("STEREOTRACE_REQUIRE_XVFB=1 but xvfb-run is not installed");
        }
        common::skip("xvfb-run not found");
        return;
    }
    let dir = std::env::temp_dir().join(format!("stereotrace-view-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("view.png");
    let recorded = dir.join("frames");
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x720x24", env!("CARGO_BIN_EXE_stereotrace"), "view", "--scene", "cornell"])
        .args(["--res", &format!("{WIDTH}x{HEIGHT}"), "--frames", "8", "--budget-ms", "200", "--screenshot"])
        .arg(&shot)
        .arg("--record")
        .arg(&recorded)
        .output()
        .expect("xvfb-run runs");
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "view failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains("fps"), "{stdout}");
    // --record wrote every frame; the last is the screenshot.
    let frames: Vec<_> = std::fs::read_dir(&recorded).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(frames.len(), 8, "{frames:?}");
    assert_eq!(std::fs::read(recorded.join("frame_00007.png")).unwrap(), std::fs::read(&shot).unwrap());
    let image = image::open(&shot).unwrap().to_rgb8();
    assert_eq!((image.width() as usize, image.height() as usize), (2 * WIDTH, HEIGHT), "side by side");
    let luminance = |x0: usize| -> Vec<f32> {
        (0..HEIGHT)
            .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
            .map(|(x, y)| {
                let p = image.get_pixel((x0 + x) as u32, y as u32).0;
                0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])
            })
            .collect()
    };
    let (left, right) = (luminance(0), luminance(WIDTH));
    for (name, eye) in [("left", &left), ("right", &right)] {
        let mean = eye.iter().sum::<f32>() / eye.len() as f32;
        assert!(mean > 20.0, "the {name} eye is lit (mean luminance {mean})");
    }
    assert_ne!(left, right, "the eyes differ");
    let expected = expected_disparity();
    let measured = best_shift(&left, &right, 60) as f32;
    println!("disparity: measured {measured} px, expected {expected:.1} px (median over the view)");
    assert!(
        (measured - expected).abs() <= (0.3 * expected).max(2.0),
        "the eyes are {measured} px apart, the scene's depths give {expected:.1} px"
    );
    std::fs::remove_dir_all(&dir).ok();
}

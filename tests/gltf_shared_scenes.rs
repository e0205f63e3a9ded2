//! The shared scenes, converted to glTF 2.0 by tools that are not ours, render as their OBJ
//! originals do: every channel's mean within 1 % and the relative RMSE of 8×8-block means
//! within 3 %, same view, same spp, same seed.
//!
//! `tools/gltf/convert.sh` converts them: obj2gltf (Cesium) writes the GLB, glTF-Transform
//! writes the MTL's PBR values, the unit and (for `cornell-box-punctual`) a camera and
//! `KHR_lights_punctual` point and spot lights into the file, and the Khronos glTF-Validator
//! checks each file (an error fails the conversion). The script installs the pinned npm
//! packages itself.
//!
//! Needs `../shared/scenes` (SKIP otherwise) and Node.js with npm. Without Node the tests
//! print SKIP and pass, unless `STEREOTRACE_REQUIRE_GLTF_TOOLS=1` is set (CI sets it).

mod common;

use std::path::{Path, PathBuf};

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::{FrameView, Renderer};
use stereotrace::scene::{Scene, UnitsFrom, resolve};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The left eye of frame 0 (a mono rig at the head pose) at `spp`, seed 7.
fn render(scene: &Scene, extent: Extent, spp: u32) -> RgbBuf {
    let renderer = Renderer::new(scene.clone()).unwrap();
    let view = FrameView::new(&renderer, &StereoRig::new(0.0).unwrap(), extent, 0).unwrap();
    let mut image = RgbBuf::new(extent, f32::NAN);
    let stats = view.trace(&renderer, &view.request(Eye::Left, spp, 7, 0), &mut image, false).unwrap();
    assert_eq!(stats.non_finite, 0);
    image
}

/// Per-channel relative differences of the means, and the relative RMSE of 8×8-block means
/// (over blocks and channels, divided by the reference's mean): `mitsuba_ref.py compare`'s
/// measures.
fn compare(ours: &RgbBuf, reference: &RgbBuf) -> ([f64; 3], f64) {
    let extent = reference.extent();
    let (w, h) = (extent.width(), extent.height());
    let (bw, bh) = (w / 8, h / 8);
    let mut mean_diff = [0.0; 3];
    let (mut squared, mut reference_sum, mut count) = (0.0, 0.0, 0usize);
    for (c, (a, b)) in ours.planes().iter().zip(reference.planes().iter()).enumerate() {
        let (a, b) = (a.as_slice(), b.as_slice());
        let mean = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
        mean_diff[c] = (mean(a) - mean(b)) / mean(b);
        for by in 0..bh {
            for bx in 0..bw {
                let block = |v: &[f32]| {
                    (0..8)
                        .flat_map(|y| (0..8).map(move |x| (by * 8 + y) * w + bx * 8 + x))
                        .map(|i| f64::from(v[i]))
                        .sum::<f64>()
                        / 64.0
                };
                let (ma, mb) = (block(a), block(b));
                squared += (ma - mb).powi(2);
                reference_sum += mb;
                count += 1;
            }
        }
    }
    let rmse = (squared / count as f64).sqrt() / (reference_sum / count as f64);
    (mean_diff, rmse)
}

/// Renders the OBJ folder and its glTF conversion and checks the tolerances.
fn obj_and_gltf_agree(obj: &Path, gltf: &Path, width: usize, height: usize, spp: u32) -> (Scene, Scene) {
    let obj_scene = resolve(obj.to_str().unwrap()).unwrap();
    let gltf_scene = resolve(gltf.to_str().unwrap()).unwrap();
    assert_eq!(gltf_scene.triangle_count(), obj_scene.triangle_count(), "{}", gltf.display());
    assert_eq!(gltf_scene.effects, obj_scene.effects, "{}: the same effects", gltf.display());
    let extent = Extent::new(width, height).unwrap();
    let (ours, reference) = (render(&gltf_scene, extent, spp), render(&obj_scene, extent, spp));
    let (means, rmse) = compare(&ours, &reference);
    let shown = means.map(|d| format!("{d:+.1e}")).join(" / ");
    println!("{}: means {shown}, 8x8-block rel. RMSE {rmse:.1e}", gltf.display());
    assert!(means.iter().all(|d| d.abs() <= 0.01), "{}: channel means differ by {means:?}", gltf.display());
    assert!(rmse <= 0.03, "{}: 8x8-block relative RMSE {rmse}", gltf.display());
    (obj_scene, gltf_scene)
}

fn shared_pair(name: &str, width: usize, height: usize, spp: u32) {
    let Some(out) = common::gltf_scenes() else { return };
    let (_, gltf) =
        obj_and_gltf_agree(&root().join("../shared/scenes").join(name), &out.join(name), width, height, spp);
    assert_eq!(gltf.units.from, UnitsFrom::Gltf);
}

#[test]
fn cornell_box_gltf_renders_as_the_obj() {
    shared_pair("cornell-box", 128, 128, 256);
}

#[test]
fn bunny_gltf_renders_as_the_obj() {
    shared_pair("bunny", 160, 96, 64);
}

#[test]
fn sponza_gltf_renders_as_the_obj() {
    shared_pair("sponza", 160, 96, 256);
}

#[test]
fn living_room_gltf_renders_as_the_obj() {
    shared_pair("living-room", 160, 96, 128);
}

#[test]
fn classroom_gltf_renders_as_the_obj() {
    shared_pair("classroom", 160, 96, 128);
}

/// The camera and the point and spot lights come from the glTF file itself (no
/// camera.json or lights.json beside it), written by glTF-Transform.
#[test]
fn camera_and_punctual_lights_from_the_file_render_as_the_obj_with_the_same_lights() {
    let Some(out) = common::gltf_scenes() else { return };
    let gltf = out.join("cornell-box-punctual");
    assert!(!gltf.join("camera.json").exists() && !gltf.join("lights.json").exists());
    let (obj, scene) = obj_and_gltf_agree(&out.join("cornell-box-punctual-obj"), &gltf, 128, 128, 256);
    let spots = scene.lights.points.iter().filter(|p| p.spot.is_some()).count();
    assert_eq!((scene.lights.points.len(), spots), (2, 1), "a point and a spot light from KHR_lights_punctual");
    assert_eq!(scene.lights.points.len(), obj.lights.points.len());
    let (a, b) = (scene.camera.pose(0), obj.camera.pose(0));
    assert!(
        a.eye.abs_diff_eq(b.eye, 1e-5) && a.forward.abs_diff_eq(b.forward, 1e-5),
        "the file's camera: {a:?} vs {b:?}"
    );
    assert!((a.vfov_deg - b.vfov_deg).abs() < 1e-3);
}

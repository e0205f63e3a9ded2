//! Every scene folder in `../shared/scenes` loads and renders: a small stereo frame (both
//! eyes' G-buffers and 2 spp of path tracing) with finite output and some light, with the
//! specialised integrator and the general one giving the same image.
//!
//! Prints `SKIP: ../shared/scenes not found` and passes when the folder is absent (CI has it).

mod common;

use std::path::{Path, PathBuf};

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::{GBufferBuf, Renderer, effects};
use stereotrace::scene::resolve;
use stereotrace::source::{PixelSelection, TraceRequest};

const SCENES: [&str; 5] = ["cornell-box", "sponza", "living-room", "classroom", "bunny"];

fn shared_scenes() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    p.is_dir().then_some(p)
}

#[test]
fn every_shared_scene_renders_a_small_stereo_frame() {
    let Some(root) = shared_scenes() else {
        common::skip("../shared/scenes not found");
        return;
    };
    let e = Extent::new(64, 36).unwrap();
    for name in SCENES {
        let dir = root.join(name);
        let scene = resolve(dir.to_str().unwrap()).unwrap_or_else(|err| panic!("{name}: {err}"));
        let renderer = Renderer::new(scene).unwrap_or_else(|err| panic!("{name}: {err}"));
        let frame = 3;
        let head = renderer.scene().camera.pose_at(frame as f32);
        let lights = renderer.frame_lights(frame);
        let mut summary = Vec::new();
        for eye in [Eye::Left, Eye::Right] {
            let camera = StereoRig::default().eye_camera(&head, eye, e).unwrap();
            let mut g = GBufferBuf::new(camera);
            renderer.render_gbuffer(&lights, &mut g);
            let surfaces = g.depth.as_slice().iter().filter(|d| d.is_finite()).count();
            assert!(surfaces > 0, "{name} {eye:?}: the camera sees no geometry");

            let request = TraceRequest { eye, frame, spp: 2, seed: 5, first_sample: 0 };
            let mut img = RgbBuf::new(e, f32::NAN);
            let stats = renderer.trace(&lights, &camera, &request, PixelSelection::All, &mut img, false).unwrap();
            assert_eq!(stats.samples, 2 * e.pixels() as u64, "{name}");
            assert_eq!(stats.non_finite, 0, "{name} {eye:?}: non-finite samples");
            let values = || img.planes().into_iter().flat_map(|p| p.as_slice().iter().copied());
            assert!(values().all(|v| v.is_finite() && v >= 0.0), "{name} {eye:?}: non-finite or negative radiance");
            let lit = (0..e.pixels())
                .filter(|&i| img.r().as_slice()[i] + img.g().as_slice()[i] + img.b().as_slice()[i] > 0.0);
            let lit = lit.count();
            assert!(lit > e.pixels() / 50, "{name} {eye:?}: only {lit} of {} pixels receive light", e.pixels());

            let mut general = RgbBuf::new(e, f32::NAN);
            renderer.trace(&lights, &camera, &request, PixelSelection::All, &mut general, true).unwrap();
            assert_eq!(img, general, "{name} {eye:?}: specialised and general integrators differ");
            let mean = values().map(f64::from).sum::<f64>() / (3 * e.pixels()) as f64;
            summary.push(format!("{eye:?}: {surfaces} surface pixels, {lit} lit, mean {mean:.4}"));
        }
        println!(
            "{name}: {} triangles, effects {}; {}",
            renderer.scene().mesh.len(),
            effects::describe(renderer.effect_bits()),
            summary.join("; ")
        );
    }
}

//! The packet loop of the path tracer against its single-ray reference
//! ([`Renderer::trace_single_rays`]): the same estimator on the same random numbers, so the
//! images are identical except where a ray hits two triangles at exactly the same distance
//! (packet and single-ray traversal may break such a tie differently). None of the scenes
//! here has such a pixel (and none of the built-ins and shared scenes had one at 1280×720,
//! 2 spp, when this was written), so the tests compare bit for bit.

use glam::Vec3;
use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::{Extent, PlaneBuf, RgbBuf};
use stereotrace::render::{FrameView, Renderer};
use stereotrace::scene::texture::Texture;
use stereotrace::scene::{Scene, resolve};
use stereotrace::source::{PixelSelection, TraceRequest};

fn view(renderer: &Renderer, frame: u32, e: Extent) -> FrameView {
    FrameView::new(renderer, &StereoRig::default(), e, frame).unwrap()
}

/// Renders with both loops (specialised or general) and checks they agree, pixel and counters.
fn assert_loops_agree(renderer: &Renderer, what: &str, e: Extent, selection: PixelSelection<'_>, general: bool) {
    let (eye, frame) = (Eye::Right, 7);
    let view = view(renderer, frame, e);
    let (lights, camera, request) = (&view.lights, view.camera(eye), view.request(eye, 3, 21, 2));
    let mut packets = RgbBuf::new(e, -1.0);
    let mut single = RgbBuf::new(e, -1.0);
    let a = renderer.trace(lights, camera, &request, selection, &mut packets, general).unwrap();
    let b = renderer.trace_single_rays(lights, camera, &request, selection, &mut single, general).unwrap();
    assert_eq!(a, b, "{what}: trace statistics differ");
    assert!(a.rays > a.samples, "{what}: {a:?}");
    assert_eq!(packets, single, "{what}: packet loop and single-ray reference differ");
}

#[test]
fn packet_loop_equals_the_single_ray_reference_on_every_builtin() {
    // 37 columns: four full groups of eight and a five-lane tail per row.
    let e = Extent::new(37, 11).unwrap();
    for name in stereotrace::scene::builtin_names() {
        let renderer = Renderer::new(resolve(name).unwrap()).unwrap();
        assert_loops_agree(&renderer, name, e, PixelSelection::All, false);
        assert_loops_agree(&renderer, &format!("{name} (general)"), e, PixelSelection::All, true);
    }
}

#[test]
fn packet_loop_with_masks_and_row_ranges() {
    let renderer = Renderer::new(resolve("atrium-moving-light").unwrap()).unwrap();
    let e = Extent::new(45, 13).unwrap();
    // Sparse, clustered and full rows: the loop packs each row's selected pixels into groups.
    let mask = PlaneBuf::from_vec(
        (0..e.pixels())
            .map(|i| {
                let (x, y) = (i % e.width(), i / e.width());
                u8::from(match y % 3 {
                    0 => (x * 7 + y) % 5 == 0,
                    1 => (10..22).contains(&x),
                    _ => true,
                })
            })
            .collect(),
        e,
    )
    .unwrap();
    assert_loops_agree(&renderer, "mask", e, PixelSelection::Mask(&mask), false);

    // Row tiles write only their rows and together give the whole image.
    let view = view(&renderer, 2, e);
    let (lights, camera, request) = (&view.lights, view.camera(Eye::Left), view.request(Eye::Left, 2, 3, 0));
    let mut whole = RgbBuf::new(e, -1.0);
    renderer.trace_single_rays(lights, camera, &request, PixelSelection::Mask(&mask), &mut whole, false).unwrap();
    let mut tiled = RgbBuf::new(e, -1.0);
    for rows in [0..4, 4..5, 5..5, 5..13] {
        let before = tiled.clone();
        renderer
            .trace_rows(lights, camera, &request, PixelSelection::Mask(&mask), rows.clone(), &mut tiled, false)
            .unwrap();
        for y in (0..e.height()).filter(|y| !rows.contains(y)) {
            let row = y * e.width()..(y + 1) * e.width();
            assert_eq!(
                tiled.r().as_slice()[row.clone()],
                before.r().as_slice()[row],
                "row {y} outside {rows:?} changed"
            );
        }
    }
    assert_eq!(tiled, whole);
}

/// Living room with cut-outs: one material fully transparent (opacity 0.3 < 0.5) and two more
/// masked by a checkerboard, so rays pass through some surfaces several times.
fn cut_out_scene() -> Scene {
    let mut scene = resolve("living-room").unwrap();
    let data: Vec<f32> = (0..64).map(|i| if (i % 8 + i / 8) % 2 == 0 { 1.0 } else { 0.0 }).collect();
    scene.textures.push(Texture::new("checker", 8, 8, 1, data).unwrap());
    let checker = (scene.textures.len() - 1) as u32;
    let n = scene.materials.len();
    let mut changed = 0;
    for (i, m) in scene.materials.iter_mut().enumerate() {
        if m.is_emissive() {
            continue;
        }
        match changed {
            0 => m.opacity = 0.3,
            1 | 2 => m.opacity_texture = Some(checker),
            _ => break,
        }
        changed += 1;
        assert!(i < n);
    }
    assert_eq!(changed, 3);
    scene.update().unwrap();
    scene
}

#[test]
fn packet_loop_with_cut_outs() {
    let renderer = Renderer::new(cut_out_scene()).unwrap();
    assert!(renderer.effect_bits() & stereotrace::render::effects::ALPHA_MASKS != 0);
    let e = Extent::new(40, 22).unwrap();
    assert_loops_agree(&renderer, "cut-outs", e, PixelSelection::All, false);
    // The cut-outs change what is seen (rays do pass through them).
    let opaque = Renderer::new(resolve("living-room").unwrap()).unwrap();
    let render = |r: &Renderer| {
        let view = view(r, 7, e);
        view.render(r, &view.request(Eye::Right, 1, 21, 0), false).unwrap().0
    };
    let (a, b) = (render(&renderer), render(&opaque));
    let changed = (0..e.pixels()).filter(|&i| a.g().as_slice()[i] != b.g().as_slice()[i]).count();
    assert!(changed > e.pixels() / 20, "only {changed} pixels changed");
    assert_loops_agree(&renderer, "cut-outs (general)", e, PixelSelection::All, true);
}

#[test]
fn rays_the_bvh_rejects_miss_in_both_loops() {
    // A camera beyond the BVH's largest accepted ray origin: every primary ray is invalid and
    // reports a miss, so each pixel sees the sky (classroom has a sky and a sun).
    let renderer = Renderer::new(resolve("classroom").unwrap()).unwrap();
    let e = Extent::new(19, 5).unwrap();
    let mut pose = renderer.scene().camera.pose_at(0.0);
    pose.eye += Vec3::new(1e9, 0.0, 0.0);
    let camera = stereotrace::kernels::CameraModel::from_pose(&pose, e).unwrap();
    let lights = renderer.frame_lights(0);
    let request = TraceRequest { eye: Eye::Left, frame: 0, spp: 1, seed: 1, first_sample: 0 };
    let mut packets = RgbBuf::new(e, -1.0);
    let mut single = RgbBuf::new(e, -1.0);
    let a = renderer.trace(&lights, &camera, &request, PixelSelection::All, &mut packets, false).unwrap();
    let b = renderer.trace_single_rays(&lights, &camera, &request, PixelSelection::All, &mut single, false).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.rays, e.pixels() as u64, "only the primary rays are cast");
    assert_eq!(packets, single);
    assert!(packets.r().as_slice().iter().all(|v| v.is_finite() && *v > 0.0), "the sky is seen everywhere");
}

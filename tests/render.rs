//! The path tracer and the G-buffer pass: a closed-form furnace, convergence, determinism,
//! specialised == general integrator, and the G-buffer's consistency with the kernels.

use glam::Vec3;
use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::gbuffer::SurfaceLayout;
use stereotrace::kernels::{Extent, PlaneBuf, RgbBuf};
use stereotrace::render::{GBufferBuf, Renderer};
use stereotrace::scene::light::icosphere;
use stereotrace::scene::{CameraPath, Material, Scene, resolve};
use stereotrace::source::{PixelSelection, TraceRequest};

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

fn render(renderer: &Renderer, eye: Eye, frame: u32, spp: u32, seed: u64, e: Extent, general: bool) -> RgbBuf {
    let head = renderer.scene().camera.pose_at(frame as f32);
    let camera = StereoRig::default().eye_camera(&head, eye, e).unwrap();
    let lights = renderer.frame_lights(frame);
    let mut img = RgbBuf::new(e, -1.0);
    let request = TraceRequest { eye, frame, spp, seed, first_sample: 0 };
    let stats = renderer.trace(&lights, &camera, &request, PixelSelection::All, &mut img, general).unwrap();
    assert_eq!(stats.non_finite, 0);
    img
}

fn mean(img: &RgbBuf) -> [f64; 3] {
    let n = img.extent().pixels() as f64;
    img.planes().map(|p| p.as_slice().iter().map(|&v| f64::from(v)).sum::<f64>() / n)
}

/// The inside of a closed polyhedron (an icosphere wound inwards) whose every triangle emits
/// `le` with albedo `rho`, seen from near its centre.
fn furnace(le: f32, rho: f32) -> Scene {
    let mut scene = resolve("cornell").unwrap();
    scene.materials = vec![Material::emitter("furnace", Vec3::splat(le), Vec3::splat(rho))];
    // Swapping two corners turns the outward winding inwards (emitters are one-sided).
    scene.mesh.positions = icosphere(1.0, 3).iter().map(|t| [t[0], t[2], t[1]]).collect();
    scene.mesh.normals = None;
    scene.mesh.uvs = None;
    scene.mesh.material = vec![0; scene.mesh.positions.len()];
    scene.camera = CameraPath::fixed(Vec3::new(0.1, 0.05, 0.0), Vec3::new(0.1, 0.05, -1.0), Vec3::Y, 60, 70.0);
    scene.update().unwrap();
    scene
}

const FURNACE: (f32, f32) = (1.0, 0.5);

/// Le (1 + ρ + ρ²): the two-bounce truncation of the furnace's Le / (1 − ρ).
fn furnace_answer() -> f64 {
    let (le, rho) = (f64::from(FURNACE.0), f64::from(FURNACE.1));
    le * (1.0 + rho + rho * rho)
}

#[test]
fn furnace_matches_the_two_bounce_closed_form() {
    // Inside any closed enclosure that emits Le everywhere with albedo ρ, irradiance is
    // exactly π·Le at every point, so each next-event estimate has mean ρ·Le and the paper's
    // estimator (emission + two bounces of next-event estimation) has mean Le (1 + ρ + ρ²).
    let renderer = Renderer::new(furnace(FURNACE.0, FURNACE.1)).unwrap();
    let e = extent(48, 27);
    let img = render(&renderer, Eye::Left, 0, 64, 7, e, false);
    let expected = furnace_answer();
    // Per-sample standard deviation is about 0.065 (inside a sphere the next-event estimate
    // is nearly constant), so the mean of 83k samples is within 0.001 of the answer.
    for c in mean(&img) {
        assert!((c - expected).abs() < 0.004, "mean {c}, expected {expected}");
    }
    // Each 64-sample pixel is close too. The per-sample distribution has a tail (next-event
    // estimates near the polyhedron's edges, up to ~3.5), so allow a few of those per pixel.
    for &v in img.r().as_slice() {
        assert!((f64::from(v) - expected).abs() < 0.25, "pixel {v}, expected {expected}");
    }
}

#[test]
fn error_falls_as_one_over_sqrt_spp() {
    // In the furnace the exact answer is known, so the error is pure Monte Carlo noise.
    let renderer = Renderer::new(furnace(FURNACE.0, FURNACE.1)).unwrap();
    let e = extent(32, 18);
    let expected = furnace_answer();
    let rmse = |spp: u32| {
        let img = render(&renderer, Eye::Left, 0, spp, 3, e, false);
        let d: f64 = img.r().as_slice().iter().map(|&v| (f64::from(v) - expected).powi(2)).sum();
        (d / e.pixels() as f64).sqrt()
    };
    let errors: Vec<f64> = [1, 4, 16, 64].into_iter().map(rmse).collect();
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!((1.8..2.2).contains(&ratio), "error ratio {ratio} for 4x the samples ({errors:?})");
    }
    // A scene with real light transport: the Cornell box, against a 1024-spp reference, over
    // pixels that do not see the light directly (their error is dominated by a handful of
    // light-edge pixels, too few to average). Mean squared error over four seeds.
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let e = extent(40, 24);
    let reference = render(&renderer, Eye::Right, 3, 1024, 99, e, false);
    let keep: Vec<bool> = reference.g().as_slice().iter().map(|&v| v < 2.0).collect();
    let mse = |spp: u32| {
        (1..=4)
            .map(|seed| {
                let img = render(&renderer, Eye::Right, 3, spp, seed, e, false);
                let d: f64 = (0..e.pixels())
                    .filter(|&i| keep[i])
                    .map(|i| f64::from(img.g().as_slice()[i] - reference.g().as_slice()[i]).powi(2))
                    .sum();
                d / keep.iter().filter(|&&k| k).count() as f64
            })
            .sum::<f64>()
            / 4.0
    };
    // MSE(n) = σ²/n + σ²/1024 (the reference's own noise): 4 → 64 spp divides it by ~14.
    let ratio = mse(4) / mse(64);
    assert!((9.0..20.0).contains(&ratio), "MSE ratio {ratio} from 4 to 64 spp");
}

#[test]
fn renders_are_deterministic_across_runs_and_thread_counts() {
    let renderer = Renderer::new(resolve("atrium-glossy").unwrap()).unwrap();
    let e = extent(33, 17);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let a = one.install(|| render(&renderer, Eye::Left, 5, 2, 3, e, false));
    let b = two.install(|| render(&renderer, Eye::Left, 5, 2, 3, e, false));
    let c = two.install(|| render(&renderer, Eye::Left, 5, 2, 3, e, false));
    assert_eq!(a, b);
    assert_eq!(b, c);
    let other_seed = render(&renderer, Eye::Left, 5, 2, 4, e, false);
    assert_ne!(a, other_seed);
}

/// A tree built with other parameters changes the order in which nodes are visited, not the
/// closest hits: every primary hit's depth is the same bit for bit, and so is the image where
/// no ray meets two triangles at exactly the same `t` (cornell, atrium). Classroom has
/// coplanar overlapping triangles, where the tree decides which of the tied two is returned;
/// there only the depths are compared. Parameters the builder refuses are a `RenderError::Bvh`.
#[test]
fn another_tree_gives_the_same_hits() {
    use stereotrace::kernels::bvh::{BuildQuality, BvhBuildParams};
    let e = extent(37, 21);
    for name in ["cornell", "atrium", "classroom"] {
        let scene = resolve(name).unwrap();
        let default = Renderer::new(scene.clone()).unwrap();
        for params in [
            BvhBuildParams { reinsertion_batch_ratio: 0.2, ..BuildQuality::Medium.params() },
            BuildQuality::Fast.params(),
        ] {
            let other = Renderer::with_bvh_params(scene.clone(), &params).unwrap();
            assert!(other.bvh_stats().quality.is_none(), "{name}: built from parameters, not a preset");
            let frame = 4;
            let camera = StereoRig::default()
                .eye_camera(&scene.camera.pose_at(frame as f32), Eye::Right, extent(320, 180))
                .unwrap();
            let lights = default.frame_lights(frame);
            let (mut a, mut b) = (GBufferBuf::new(camera), GBufferBuf::new(camera));
            default.render_gbuffer(&lights, &mut a);
            other.render_gbuffer(&lights, &mut b);
            let bits = |g: &GBufferBuf| g.depth.as_slice().iter().map(|d| d.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&b), "{name}: primary depths with {params:?}");
            if name != "classroom" {
                assert_eq!(
                    render(&default, Eye::Right, frame, 1, 7, e, false),
                    render(&other, Eye::Right, frame, 1, 7, e, false),
                    "{name}: {params:?}"
                );
            }
        }
    }
    let refused = BvhBuildParams { max_prims_per_leaf: 0, ..BuildQuality::Medium.params() };
    let err = Renderer::with_bvh_params(resolve("cornell").unwrap(), &refused).err().expect("refused");
    assert!(matches!(err, stereotrace::render::RenderError::Bvh(_)), "{err}");
}

#[test]
fn specialised_and_general_integrators_give_identical_images() {
    for name in stereotrace::scene::builtin_names() {
        let renderer = Renderer::new(resolve(name).unwrap()).unwrap();
        let e = extent(24, 14);
        let special = render(&renderer, Eye::Right, 10, 2, 11, e, false);
        let general = render(&renderer, Eye::Right, 10, 2, 11, e, true);
        assert_eq!(special, general, "{name}");
    }
}

#[test]
fn samples_can_be_added_in_batches() {
    // first_sample lets a caller add samples later with exactly the numbers of one long render.
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let e = extent(16, 9);
    let head = renderer.scene().camera.pose_at(0.0);
    let camera = StereoRig::default().eye_camera(&head, Eye::Left, e).unwrap();
    let lights = renderer.frame_lights(0);
    let run = |first_sample, spp| {
        let mut img = RgbBuf::new(e, 0.0);
        let req = TraceRequest { eye: Eye::Left, frame: 0, spp, seed: 5, first_sample };
        renderer.trace(&lights, &camera, &req, PixelSelection::All, &mut img, false).unwrap();
        img
    };
    let all = run(0, 8);
    let (a, b) = (run(0, 4), run(4, 4));
    for (x, (p, q)) in all.r().as_slice().iter().zip(a.r().as_slice().iter().zip(b.r().as_slice())) {
        assert!((x - 0.5 * (p + q)).abs() <= 1e-5 * x.abs().max(1.0));
    }
}

#[test]
fn pixel_masks_trace_only_the_selected_pixels() {
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let e = extent(16, 9);
    let camera = StereoRig::default().eye_camera(&renderer.scene().camera.pose_at(0.0), Eye::Left, e).unwrap();
    let lights = renderer.frame_lights(0);
    let mask = PlaneBuf::from_vec((0..e.pixels()).map(|i| u8::from(i % 3 == 0)).collect(), e).unwrap();
    let mut img = RgbBuf::new(e, -5.0);
    let req = TraceRequest { eye: Eye::Left, frame: 0, spp: 2, seed: 1, first_sample: 0 };
    let stats = renderer.trace(&lights, &camera, &req, PixelSelection::Mask(&mask), &mut img, false).unwrap();
    assert_eq!(stats.samples, 2 * mask.as_slice().iter().filter(|&&m| m != 0).count() as u64);
    let full = render(&renderer, Eye::Left, 0, 2, 1, e, false);
    for i in 0..e.pixels() {
        if i % 3 == 0 {
            assert_eq!(img.r().as_slice()[i], full.r().as_slice()[i]);
        } else {
            assert_eq!(img.r().as_slice()[i], -5.0);
        }
    }
}

#[test]
fn gbuffer_layouts_agree_and_depth_is_view_depth() {
    let renderer = Renderer::new(resolve("living-room").unwrap()).unwrap();
    let e = extent(64, 36);
    let head = renderer.scene().camera.pose_at(20.0);
    let camera = StereoRig::default().eye_camera(&head, Eye::Left, e).unwrap();
    let mut g = GBufferBuf::new(camera);
    renderer.render_gbuffer(&renderer.frame_lights(20), &mut g);
    let (full, compact) = (g.view(), g.compact());
    let (mut surfaces, mut facing) = (0, 0);
    for y in 0..e.height() {
        for x in 0..e.width() {
            let (a, b) = (full.surfel(x, y), compact.surfel(x, y));
            if a.depth.is_infinite() {
                continue;
            }
            surfaces += 1;
            // The compact layout rebuilds the stored position bit for bit.
            assert_eq!(a.position, b.position, "({x}, {y})");
            // Depth is the distance along the view axis.
            let p = Vec3::from(a.position);
            let view_depth = (p - Vec3::from(camera.centre)).dot(head.forward);
            assert!((view_depth - a.depth).abs() <= 1e-4 * a.depth, "{view_depth} vs {}", a.depth);
            // Octahedral normals are within a hundredth of a degree (not normalised: compare angles).
            let (na, nb) = (Vec3::from(a.normal), Vec3::from(b.normal).normalize());
            assert!(na.dot(nb) > 0.999_99, "({x}, {y}): {na} vs {nb}");
            // Shading normals are flipped to the camera's side of the surface; interpolated
            // normals may still lean away from the view ray near silhouettes.
            if na.dot(p - Vec3::from(camera.centre)) <= 0.0 {
                facing += 1;
            }
        }
    }
    assert!(surfaces > e.pixels() / 2);
    assert!(facing as f64 >= 0.95 * surfaces as f64, "{facing} of {surfaces} normals face the camera");
}

#[test]
fn a_zero_separation_rig_gives_identical_gbuffers() {
    let renderer = Renderer::new(resolve("classroom").unwrap()).unwrap();
    let e = extent(32, 18);
    let head = renderer.scene().camera.pose_at(0.0);
    let rig = StereoRig::new(0.0).unwrap();
    let lights = renderer.frame_lights(0);
    let mut a = GBufferBuf::new(rig.eye_camera(&head, Eye::Left, e).unwrap());
    let mut b = GBufferBuf::new(rig.eye_camera(&head, Eye::Right, e).unwrap());
    renderer.render_gbuffer(&lights, &mut a);
    renderer.render_gbuffer(&lights, &mut b);
    assert_eq!(a.depth, b.depth);
    assert_eq!(a.normal_oct, b.normal_oct);
}

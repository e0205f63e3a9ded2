//! `--first-sample centre`: each pixel's first sample of a frame goes through the pixel centre,
//! and with a rasterised G-buffer pass its hit is read from the pass's visibility buffer
//! instead of traced. The oracle is independent of the visibility buffer: the same packet
//! loop tracing every centre ray through the BVH ([`PrimaryRays::Centre`]), itself checked
//! against the single-ray reference ([`Renderer::trace_single_rays_centred`]). Where the
//! raster saw the traced triangle the images must be identical bit for bit (the rest of the
//! sample uses the same random numbers); where it did not (depth ties, centres on an edge:
//! ≤ 0.1 % of the pixels, see `tests/raster_gbuffers.rs`) the pixel is left out and counted.

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::raster::NO_PRIM;
use stereotrace::kernels::{CameraModel, Extent, PlaneBuf, RgbBuf};
use stereotrace::pipeline::Layout;
use stereotrace::render::lights::FrameLights;
use stereotrace::render::raster::RasterGBuffers;
use stereotrace::render::{
    FirstSample, FrameView, GBufferBuf, GBufferPass, PrimaryRays, RenderError, Renderer, RendererOptions,
    RendererSource,
};
use stereotrace::scene::{builtin_names, resolve};
use stereotrace::source::{FrameSource, PixelSelection, TraceRequest, TraceStats};

/// Pixels whose values differ between `a` and `b`, and how many of them lie where the
/// raster's triangle is not the traced one (`differs` true there).
fn compare(a: &RgbBuf, b: &RgbBuf, differs: &[bool]) -> (usize, usize) {
    let (mut outside, mut inside) = (0, 0);
    for (c, (pa, pb)) in a.view().channels().iter().zip(b.view().channels()).enumerate() {
        let _ = c;
        for (i, (x, y)) in pa.as_slice().iter().zip(pb.as_slice()).enumerate() {
            if x.to_bits() != y.to_bits() {
                if differs[i] {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
    }
    (outside, inside)
}

/// The packet loop over every pixel of `out` with the first sample as `primary` says.
fn trace_packets(
    renderer: &Renderer,
    lights: &FrameLights,
    camera: &CameraModel,
    request: &TraceRequest,
    out: &mut RgbBuf,
    primary: PrimaryRays<'_>,
) -> Result<TraceStats, RenderError> {
    let rows = 0..camera.extent.height();
    renderer.trace_rows_from(lights, camera, request, PixelSelection::All, rows, out, false, primary)
}

/// Where the raster's triangle (`raster`) is not the one the traced pass finds for `camera`.
fn disagreements(renderer: &Renderer, view: &FrameView, eye: Eye, raster: &PlaneBuf<u32>) -> Vec<bool> {
    let mut traced = PlaneBuf::new(raster.extent(), NO_PRIM);
    renderer.trace_visibility(&view.lights, view.camera(eye), &mut traced).unwrap();
    raster.as_slice().iter().zip(traced.as_slice()).map(|(r, t)| r != t).collect()
}

/// The packet loop reading centre hits from the raster's visibility against the single-ray
/// reference tracing them, for both eyes, 2 spp (sample 0 centred, sample 1 jittered).
fn check_scene(name: &str, extent: Extent, frame: u32) {
    let renderer = Renderer::new(resolve(name).unwrap()).unwrap();
    let view = FrameView::new(&renderer, &StereoRig::default(), extent, frame).unwrap();
    let mut raster = RasterGBuffers::new(extent);
    let [mut gl, mut gr] = view.cameras.map(GBufferBuf::new);
    renderer.render_gbuffers_raster(&view.lights, [&mut gl, &mut gr], &mut raster).unwrap();
    for eye in [Eye::Left, Eye::Right] {
        let (camera, request) = (view.camera(eye), view.request(eye, 2, 5, 0));
        let vis = &raster.visibility()[eye as usize];
        let mut from_vis = RgbBuf::new(extent, -1.0);
        let a =
            trace_packets(&renderer, &view.lights, camera, &request, &mut from_vis, PrimaryRays::CentreVisible(vis))
                .unwrap();
        let mut traced = RgbBuf::new(extent, -1.0);
        let b = trace_packets(&renderer, &view.lights, camera, &request, &mut traced, PrimaryRays::Centre).unwrap();
        let differs = disagreements(&renderer, &view, eye, &vis.prim);
        let (outside, inside) = compare(&from_vis, &traced, &differs);
        let disagreeing = differs.iter().filter(|&&d| d).count();
        println!("{name} {eye:?} {extent:?}: {disagreeing} pixels see another triangle, {inside} values differ there");
        assert_eq!(outside, 0, "{name} {eye:?}: values differ where the raster saw the traced triangle");
        assert!(disagreeing * 1000 <= extent.pixels(), "{name} {eye:?}: {disagreeing} disagreeing pixels");
        // The same samples; the centre rays the visibility decided are not traced.
        assert_eq!(a.samples, b.samples);
        // Every centre ray the visibility decided is one ray fewer (a few undecided ones are
        // traced after all).
        assert!(a.rays < b.rays && b.rays - a.rays <= extent.pixels() as u64, "{name}: {a:?} against {b:?}");
    }
}

#[test]
fn centre_hits_from_the_visibility_buffer_equal_traced_centre_rays_on_every_builtin() {
    // 45 columns: five groups of eight and a five-lane tail per row.
    for name in builtin_names() {
        check_scene(name, Extent::new(45, 27).unwrap(), 3);
    }
}

#[test]
fn centre_hits_from_the_visibility_buffer_equal_traced_centre_rays_at_a_real_size() {
    // Moving lights (their triangles follow the mesh's ids) and a sun-lit courtyard.
    for name in ["atrium-moving-light", "courtyard", "cornell"] {
        check_scene(name, Extent::new(320, 180).unwrap(), 5);
    }
}

/// The packet loop's centred first sample against the single-ray reference's, as
/// `tests/render_packets.rs` checks the jittered one: identical images and counters.
#[test]
fn the_packet_loop_centres_the_first_sample_as_the_single_ray_reference_does() {
    let extent = Extent::new(37, 11).unwrap();
    for name in builtin_names() {
        let renderer = Renderer::new(resolve(name).unwrap()).unwrap();
        let view = FrameView::new(&renderer, &StereoRig::default(), extent, 7).unwrap();
        let (camera, request) = (view.camera(Eye::Right), view.request(Eye::Right, 2, 21, 0));
        let mut packets = RgbBuf::new(extent, -1.0);
        let a = trace_packets(&renderer, &view.lights, camera, &request, &mut packets, PrimaryRays::Centre).unwrap();
        let mut single = RgbBuf::new(extent, -1.0);
        let b = renderer
            .trace_single_rays_centred(&view.lights, camera, &request, PixelSelection::All, &mut single)
            .unwrap();
        assert_eq!(a, b, "{name}");
        assert_eq!(packets, single, "{name}");
    }
}

#[test]
fn the_jittered_default_is_the_papers_estimator() {
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let extent = Extent::new(37, 21).unwrap();
    let view = FrameView::new(&renderer, &StereoRig::default(), extent, 1).unwrap();
    let request = view.request(Eye::Right, 1, 9, 0);
    let camera = view.camera(Eye::Right);
    let mut plain = RgbBuf::new(extent, 0.0);
    renderer.trace(&view.lights, camera, &request, PixelSelection::All, &mut plain, false).unwrap();
    let mut explicit = RgbBuf::new(extent, 0.0);
    trace_packets(&renderer, &view.lights, camera, &request, &mut explicit, PrimaryRays::Jittered).unwrap();
    assert_eq!(plain, explicit);
    // Centring changes the image (the first sample moves), and only sample 0 is centred: a
    // request that starts at sample 1 is the jittered one.
    let mut centred = RgbBuf::new(extent, 0.0);
    renderer.trace_single_rays_centred(&view.lights, camera, &request, PixelSelection::All, &mut centred).unwrap();
    assert_ne!(plain, centred);
    let later = view.request(Eye::Right, 1, 9, 1);
    let (mut a, mut b) = (RgbBuf::new(extent, 0.0), RgbBuf::new(extent, 0.0));
    renderer.trace_single_rays(&view.lights, camera, &later, PixelSelection::All, &mut a, false).unwrap();
    renderer.trace_single_rays_centred(&view.lights, camera, &later, PixelSelection::All, &mut b).unwrap();
    assert_eq!(a, b);
}

/// Through the pipeline's seam: each eye's trace reads its own eye's visibility, and a frame
/// begun without new G-buffers (a stale visibility) traces its centre rays.
#[test]
fn the_renderer_source_reads_each_eyes_own_visibility_and_never_a_stale_one() {
    let extent = Extent::new(64, 40).unwrap();
    let renderer = Renderer::new(resolve("atrium-moving-light").unwrap()).unwrap();
    for pass in [GBufferPass::Raster, GBufferPass::Exact] {
        each_eye_reads_its_own_visibility(&renderer, pass, extent);
    }
}

fn each_eye_reads_its_own_visibility(renderer: &Renderer, pass: GBufferPass, extent: Extent) {
    let options = RendererOptions::with_first_sample(pass, FirstSample::Centre);
    let mut source = RendererSource::new(renderer, options, extent).unwrap();
    let frame = 4;
    let view = FrameView::new(renderer, &StereoRig::default(), extent, frame).unwrap();
    source.begin_frame(frame);
    let [mut gl, mut gr] = view.cameras.map(GBufferBuf::new);
    source.fill_gbuffers([&mut gl, &mut gr], Layout::Compact).unwrap();
    let trace = |source: &RendererSource<&Renderer>, eye: Eye| -> (RgbBuf, TraceStats) {
        let mut out = RgbBuf::new(extent, -1.0);
        let request = view.request(eye, 1, 11, 0);
        let stats =
            source.trace(view.camera(eye), &request, PixelSelection::All, 0..extent.height(), &mut out).unwrap();
        (out, stats)
    };
    // The same pass again, outside the source, for the visibility it read.
    let mut raster = RasterGBuffers::new(extent);
    raster.visibility_by = pass.visibility().expect("a rasterised pass");
    let [mut hl, mut hr] = view.cameras.map(GBufferBuf::new);
    renderer.render_gbuffers_raster(&view.lights, [&mut hl, &mut hr], &mut raster).unwrap();
    for eye in [Eye::Left, Eye::Right] {
        let (image, stats) = trace(&source, eye);
        let mut reference = RgbBuf::new(extent, -1.0);
        let request = view.request(eye, 1, 11, 0);
        let traced =
            trace_packets(renderer, &view.lights, view.camera(eye), &request, &mut reference, PrimaryRays::Centre)
                .unwrap();
        let differs = disagreements(renderer, &view, eye, &raster.visibility()[eye as usize].prim);
        assert_eq!(compare(&image, &reference, &differs).0, 0, "{pass:?} {eye:?}");
        assert!(stats.rays < traced.rays, "{eye:?}: the visibility was not read");
    }
    // The next frame begun, its G-buffers not yet filled: every centre ray is traced, so the
    // packet loop equals the reference everywhere, ties included.
    source.begin_frame(frame + 1);
    let next = FrameView::new(renderer, &StereoRig::default(), extent, frame + 1).unwrap();
    let request = next.request(Eye::Right, 1, 11, 0);
    let mut image = RgbBuf::new(extent, -1.0);
    let stats =
        source.trace(next.camera(Eye::Right), &request, PixelSelection::All, 0..extent.height(), &mut image).unwrap();
    let mut reference = RgbBuf::new(extent, -1.0);
    let traced =
        trace_packets(renderer, &next.lights, next.camera(Eye::Right), &request, &mut reference, PrimaryRays::Centre)
            .unwrap();
    assert_eq!(image, reference);
    assert_eq!(stats, traced);
}

#[test]
fn a_visibility_buffer_of_another_extent_is_refused() {
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let extent = Extent::new(32, 16).unwrap();
    let view = FrameView::new(&renderer, &StereoRig::default(), extent, 0).unwrap();
    let raster = RasterGBuffers::new(Extent::new(16, 16).unwrap());
    let mut out = RgbBuf::new(extent, 0.0);
    let (camera, request) = (view.camera(Eye::Left), view.request(Eye::Left, 1, 1, 0));
    let visibility = PrimaryRays::CentreVisible(&raster.visibility()[0]);
    let err = trace_packets(&renderer, &view.lights, camera, &request, &mut out, visibility).unwrap_err();
    assert!(err.to_string().contains("visibility buffer"), "{err}");
}

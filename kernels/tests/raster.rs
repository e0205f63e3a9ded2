//! The rasteriser on the cases that break rasterisers, against a brute-force oracle: for every
//! pixel, the tracer's own pixel-centre ray tested against every triangle with the tracer's
//! watertight test, the closest hit winning (equal `t`: the smaller id, the rule the
//! rasteriser's exact path uses). No BVH, no binning, no edge functions: nothing the
//! rasteriser shares except the triangle test that defines what the tracer sees.
//!
//! Cases: a camera inside a closed box (every direction hits), triangles behind the camera
//! and crossing the near plane (clipped to quads whose vertices land far off screen), a
//! million tiny triangles inside one pixel, and NaN or infinite vertices (the scene loader
//! refuses them, the root crate's `tests/scenes.rs`; the kernel must still not let one reach a pixel). Scalar
//! reference and SIMD body must give the same buffers on each, and so must bands of any height.
//! The fixed-point rasteriser runs every case too, against the same oracle within its
//! tolerance (`check_fixed`).

use glam::Vec3;
use stereotrace_kernels::bvh::{PreparedRay, Ray, TriVerts, intersect_triangle};
use stereotrace_kernels::camera::CameraPose;
use stereotrace_kernels::fuzzing::{plane_depth, screen_boundary};
use stereotrace_kernels::raster::fixed::FixedRasterizer;
use stereotrace_kernels::raster::{Body, NO_PRIM, NoMasks, Rasterizer, Triangles, VisibilityBuffer};
use stereotrace_kernels::{CameraModel, Extent};

/// The runtime's default eye separation (a parallel rig: the eyes at ±half of it along the
/// head's right vector).
const SEPARATION: f32 = 0.065;

/// The left and right eyes' cameras of a parallel rig `separation` wide on `head`.
fn eye_cameras(head: &CameraPose, separation: f32, extent: Extent) -> [CameraModel; 2] {
    CameraModel::stereo_pair(head, separation, extent).unwrap()
}

fn pose(eye: Vec3, target: Vec3) -> CameraPose {
    let forward = (target - eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    CameraPose { eye, forward, up: right.cross(forward), right, vfov_deg: 60.0 }
}

fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> TriVerts {
    [a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]]
}

/// The oracle's answer at pixel `(x, y)`.
fn brute_force(camera: &CameraModel, tris: &[TriVerts], x: usize, y: usize) -> u32 {
    brute_force_at(camera, tris, x as f32 + 0.5, y as f32 + 0.5).1
}

/// The oracle's closest hit `(t, id)` along the ray through screen point `(px, py)`.
fn brute_force_at(camera: &CameraModel, tris: &[TriVerts], px: f32, py: f32) -> (f32, u32) {
    let d = camera.ray(px, py);
    let Some(r) = PreparedRay::new(&Ray::new(camera.centre.into(), d.into())) else { return (f32::INFINITY, NO_PRIM) };
    let mut best = (f32::INFINITY, NO_PRIM);
    for (i, t) in tris.iter().enumerate() {
        if let Some(hit) = intersect_triangle(&r, t, f32::INFINITY)
            && (hit.t < best.0 || (hit.t == best.0 && (i as u32) < best.1))
        {
            best = (hit.t, i as u32);
        }
    }
    best
}

/// The pixel-centre ray's hit depth on triangle `prim` alone.
fn depth_on(camera: &CameraModel, tri: &TriVerts, x: usize, y: usize) -> Option<f32> {
    let d = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
    let r = PreparedRay::new(&Ray::new(camera.centre.into(), d.into()))?;
    intersect_triangle(&r, tri, f32::INFINITY).map(|h| h.t)
}

/// The fixed-point rasteriser on the same case: both bodies and every band height give the
/// same buffers, and every pixel shows the oracle's triangle, or one within the snap (1/256
/// px) of the centre (the oracle's view from a point that far off the centre, or the
/// triangle's exact f64 image with its plane nearer than the oracle's hit), or one at a depth
/// tie (1e-3 relative).
fn check_fixed(name: &str, tris: &[TriVerts], cams: &[CameraModel; 2], only: Option<(usize, usize)>) {
    let extent = cams[0].extent;
    let run = |body, mut rasterizer: FixedRasterizer| {
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        let [l, r] = &mut out;
        let tris = Triangles { main: tris, extra: &[] };
        rasterizer.rasterize(tris, [&cams[0], &cams[1]], &NoMasks, 1e-6, [l, r], body).unwrap();
        out
    };
    let simd = run(Body::Simd, FixedRasterizer::new());
    assert_eq!(simd, run(Body::Scalar, FixedRasterizer::new()), "{name}: fixed: SIMD and scalar differ");
    for rows in [1, 3, 8] {
        assert_eq!(simd, run(Body::Simd, FixedRasterizer::with_band_rows(rows)), "{name}: fixed: bands of {rows}");
    }
    for (eye, vis) in simd.iter().enumerate() {
        let cam = &cams[eye];
        for y in 0..extent.height() {
            for x in 0..extent.width() {
                if only.is_some_and(|p| p != (x, y)) {
                    continue;
                }
                let got = vis.prim.as_slice()[y * extent.width() + x];
                let (t, want) = brute_force_at(cam, tris, x as f32 + 0.5, y as f32 + 0.5);
                if got == want {
                    continue;
                }
                let snap = (0..16).any(|k| {
                    let a = k as f32 * std::f32::consts::TAU / 16.0;
                    let (ox, oy) = (a.cos() / 256.0, a.sin() / 256.0);
                    brute_force_at(cam, tris, x as f32 + 0.5 + ox, y as f32 + 0.5 + oy).1 == got
                });
                let tie = got != NO_PRIM
                    && want != NO_PRIM
                    && depth_on(cam, &tris[got as usize], x, y).is_some_and(|d| (d - t).abs() <= 1e-3 * t);
                // A sliver thinner than the samples' spacing on that circle slips between them:
                // its exact image decides, if its plane is the nearer one at the centre.
                let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
                let snap = snap
                    || got != NO_PRIM
                        && screen_boundary(cam, &tris[got as usize], cx, cy)
                            .is_some_and(|(inside, dist)| inside || dist <= 1.0 / 256.0)
                        && (want == NO_PRIM
                            || plane_depth(cam, &tris[got as usize], cx, cy)
                                .is_some_and(|p| p > 0.0 && p <= f64::from(t) * (1.0 + 1e-3)));
                if !(snap || tie) {
                    // How far the oracle has to look for the raster's triangle, for the message.
                    let reach = [64.0f32, 32.0, 16.0, 8.0, 4.0, 2.0].into_iter().find(|&r| {
                        (0..64).any(|k| {
                            let a = k as f32 * std::f32::consts::TAU / 64.0;
                            let (px, py) = (x as f32 + 0.5 + a.cos() / r, y as f32 + 0.5 + a.sin() / r);
                            brute_force_at(cam, tris, px, py).1 == got
                        })
                    });
                    panic!(
                        "{name}: fixed: eye {eye} pixel ({x}, {y}): raster {got}, oracle {want}, seen within 1/{reach:?} px"
                    );
                }
            }
        }
    }
}

/// Rasterises `tris` for both eyes of `head` at `extent` with both bodies; checks them equal
/// to each other and to the oracle on every pixel (or on `only` when given). Returns the
/// left eye's ids.
fn check(name: &str, tris: &[TriVerts], head: &CameraPose, extent: Extent, only: Option<(usize, usize)>) -> Vec<u32> {
    check_rig(name, tris, head, SEPARATION, extent, only)
}

/// [`check`] with the eyes `separation` apart.
fn check_rig(
    name: &str,
    tris: &[TriVerts],
    head: &CameraPose,
    separation: f32,
    extent: Extent,
    only: Option<(usize, usize)>,
) -> Vec<u32> {
    let cams = eye_cameras(head, separation, extent);
    let run = |body, mut rasterizer: Rasterizer| {
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        let [l, r] = &mut out;
        let tris = Triangles { main: tris, extra: &[] };
        rasterizer.rasterize(tris, [&cams[0], &cams[1]], &NoMasks, 1e-6, [l, r], body).unwrap();
        out
    };
    let (simd, scalar) = (run(Body::Simd, Rasterizer::new()), run(Body::Scalar, Rasterizer::new()));
    assert_eq!(simd, scalar, "{name}: the SIMD body and the scalar reference differ");
    // The band height changes the work's partition, never a pixel.
    for rows in [1, 3, 8] {
        assert_eq!(simd, run(Body::Simd, Rasterizer::with_band_rows(rows)), "{name}: bands of {rows} rows differ");
    }
    for (eye, vis) in simd.iter().enumerate() {
        let ids = vis.prim.as_slice();
        for y in 0..extent.height() {
            for x in 0..extent.width() {
                if only.is_some_and(|p| p != (x, y)) {
                    continue;
                }
                let expected = brute_force(&cams[eye], tris, x, y);
                let got = ids[y * extent.width() + x];
                assert_eq!(got, expected, "{name}: eye {eye} pixel ({x}, {y}): raster {got}, oracle {expected}");
            }
        }
    }
    check_fixed(name, tris, &cams, only);
    simd[0].prim.as_slice().to_vec()
}

/// The twelve triangles of an axis-aligned box from `lo` to `hi`.
fn cube(lo: [f32; 3], hi: [f32; 3]) -> Vec<TriVerts> {
    let p = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    quads.iter().flat_map(|q| [tri(p(q[0]), p(q[1]), p(q[2])), tri(p(q[0]), p(q[2]), p(q[3]))]).collect()
}

#[test]
fn a_camera_inside_a_closed_box_sees_a_wall_at_every_pixel() {
    let mut tris = cube([-1.0, -1.0, -1.0], [1.0, 1.5, 2.0]);
    // A panel inside the box, in front of the camera, and one exactly on a wall (a depth tie).
    tris.push(tri([-0.3, -0.3, -0.5], [0.4, -0.2, -0.5], [0.0, 0.5, -0.6]));
    tris.push(tri([-0.5, -0.5, -1.0], [0.5, -0.5, -1.0], [0.0, 0.5, -1.0]));
    let extent = Extent::new(67, 41).unwrap();
    let ids = check("inside a box", &tris, &pose(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.0, -1.0)), extent, None);
    assert!(ids.iter().all(|&p| p != NO_PRIM), "a closed box leaves no pixel empty");
}

#[test]
fn triangles_behind_the_camera_and_across_the_near_plane() {
    let eye = Vec3::new(0.0, 1.0, 0.0);
    let tris = vec![
        // A ground plane running from far in front to far behind the camera (clipped).
        tri([-50.0, 0.0, -50.0], [50.0, 0.0, -50.0], [0.0, 0.0, 50.0]),
        // Entirely behind the camera.
        tri([-1.0, 0.5, 3.0], [1.0, 0.5, 3.0], [0.0, 2.0, 3.0]),
        // One vertex behind the eye plane, passing right beside the eye (huge clipped quad).
        tri([0.02, 1.0, 0.5], [0.3, 0.8, -2.0], [-0.3, 1.3, -2.0]),
        // Crossing the eye plane through the eye point itself.
        tri([0.0, 1.0, 0.0], [1.0, 1.5, -3.0], [0.5, 0.4, -3.0]),
        // A wall in front.
        tri([-3.0, 0.0, -4.0], [3.0, 0.0, -4.0], [0.0, 3.0, -4.0]),
    ];
    for extent in [Extent::new(64, 36).unwrap(), Extent::new(7, 3).unwrap(), Extent::new(1, 1).unwrap()] {
        let ids = check("near plane", &tris, &pose(eye, Vec3::new(0.0, 0.9, -1.0)), extent, None);
        assert!(!ids.contains(&1), "a triangle behind the camera was drawn");
    }
}

/// Two slivers folded along one shared edge 2000 units long that runs past the eye end-on
/// (one end 1000 units ahead, the other 1000 units behind, so both are clipped), a wall behind
/// them. At pixel (1, 14) of the right eye the pixel ray passes 7e-5 px outside both slivers,
/// but the tracer's f32 test hits both (its rounding on an edge seen end-on with vertices 10³
/// units away, ~10⁻² px here). The raster once called that pixel certainly outside the first
/// sliver and uncertain for the second, so its exact path showed the second where the tracer
/// sees the first: its band now includes the tracer's own edge rounding (found by fuzzing).
#[test]
fn a_far_clipped_sliver_pair_seen_end_on_matches_the_tracer() {
    let tris = vec![
        tri([-4.0, -4.0, -4.0], [-4.0, 2.0, 2.0], [2.0, -1.0, -1.5]),
        tri([-1000.0, -1.5, -4.0], [-1000.0, 4.0, 0.0], [1000.0, -4.0, -1.5]),
        tri([-4.0, -2.0, -1000.0], [4.0, 0.0, 1000.0], [-4.0, -1.5, -3.0]),
        tri([1000.0, -4.0, -1.5], [-3.0, 2.5, -1000.0], [-3.0, -1.5, 2.3686275]),
        tri([-4.0, -4.0, -4.0], [-4.0, -2.0, -1000.0], [4.0, 0.0, 1000.0]),
    ];
    let head = CameraPose {
        eye: Vec3::new(0.4372549, -0.08823529, 0.5),
        forward: Vec3::new(0.5171012, 0.27067998, -0.81199664),
        up: Vec3::new(-0.14539671, 0.9626694, 0.22831437),
        right: Vec3::new(0.8434845, -0.0, 0.53715354),
        vfov_deg: 120.0,
    };
    check_rig("far clipped slivers", &tris, &head, 0.064, Extent::new(17, 16).unwrap(), Some((1, 14)));
}

/// Long thin triangles across the whole screen at every angle, over a backdrop: their boxes
/// are mostly empty, so the SIMD body walks only each row's span of them (edges nearly
/// parallel to the rows, nearly vertical, and slivers thinner than a pixel included). Both
/// bodies and every band height give the oracle's triangle at every pixel.
#[test]
fn long_thin_triangles_at_every_angle_walk_only_their_rows_spans() {
    let extent = Extent::new(160, 90).unwrap();
    let head = pose(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0));
    let mut tris = vec![tri([-50.0, -50.0, -6.0], [50.0, -50.0, -6.0], [0.0, 50.0, -6.0])];
    for i in 0..48 {
        // Angles from 0 to 180° (0°, 90° and 180° exactly among them), widths from a hundredth
        // of a pixel to a few pixels at this depth (a pixel is ~0.01 units).
        let angle = i as f32 * std::f32::consts::PI / 47.0 + if i % 3 == 1 { 1e-4 } else { 0.0 };
        let (dir, across) = (Vec3::new(angle.cos(), angle.sin(), 0.0), Vec3::new(-angle.sin(), angle.cos(), 0.0));
        let width = 1e-4 * 3f32.powi(i % 6);
        let centre = Vec3::new(0.3 * (i as f32 / 47.0 - 0.5), 0.2 * ((i * 7 % 11) as f32 / 10.0 - 0.5), -3.0);
        let (a, b) = (centre - dir * 4.0, centre + dir * 4.0);
        tris.push(tri(a.into(), b.into(), (centre + across * width).into()));
    }
    check("long thin triangles", &tris, &head, extent, None);
}

#[test]
fn a_million_tiny_triangles_in_one_pixel() {
    let extent = Extent::new(16, 9).unwrap();
    let head = pose(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0));
    let [camera, _] = eye_cameras(&head, SEPARATION, extent);
    // The left eye's pixel (8, 4): its centre direction at depth 1, and one pixel's size there.
    let origin = Vec3::from(camera.centre);
    let centre = Vec3::from(camera.ray(8.5, 4.5));
    let pixel = Vec3::from(camera.ray(9.5, 4.5)) - centre;
    let size = pixel.length();
    let mut tris = vec![tri([-50.0, -50.0, -3.0], [50.0, -50.0, -3.0], [0.0, 50.0, -3.0])];
    // 10⁶ triangles of 1e-3 px on a jittered grid across the pixel, at depths 1 to 2: a few
    // contain the pixel centre's ray, most fall between pixel centres.
    let mut rng = stereotrace_kernels::synth::Rng::new(0x9E37_79B9_7F4A_7C15);
    let mut next = || rng.next_f32();
    let (u, v) = (pixel.normalize(), Vec3::Y * size);
    for i in 0..1_000_000 {
        let depth = 1.0 + next();
        let offset = (next() - 0.5) * u * size + (next() - 0.5) * v;
        // Every 1000th triangle sits on the centre ray itself.
        let e = 1e-3 * size * depth;
        let along =
            if i % 1000 == 0 { centre * depth - (u * 0.2 + Vec3::Y * 0.3) * e } else { (centre + offset) * depth };
        let base = origin + along;
        tris.push(tri(base.into(), (base + u * e).into(), (base + Vec3::Y * e - u * e * 0.3).into()));
    }
    let ids = check("tiny triangles", &tris, &head, extent, Some((8, 4)));
    assert_ne!(ids[4 * 16 + 8], 0, "the pixel sees one of the tiny triangles on its centre ray");
    let elsewhere = check("tiny triangles", &tris[..1], &head, extent, None);
    assert!(elsewhere.iter().all(|&p| p == 0));
}

#[test]
fn non_finite_vertices_never_reach_a_pixel() {
    let n = f32::NAN;
    let inf = f32::INFINITY;
    let tris = vec![
        tri([-3.0, -2.0, -4.0], [3.0, -2.0, -4.0], [0.0, 3.0, -4.0]),
        tri([n, 0.0, -2.0], [1.0, 0.0, -2.0], [0.0, 1.0, -2.0]),
        tri([-1.0, -1.0, -2.0], [inf, 0.0, -2.0], [0.0, 1.0, -2.0]),
        tri([-1.0, -1.0, -2.0], [1.0, -1.0, -2.0], [0.0, 1.0, -inf]),
        tri([n; 3], [n; 3], [n; 3]),
    ];
    let ids =
        check("non-finite", &tris, &pose(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0)), Extent::new(40, 30).unwrap(), None);
    assert!(ids.iter().all(|&p| p == 0 || p == NO_PRIM), "a non-finite triangle was drawn");
}

//! The fixed-point rasteriser (`raster::fixed`) on its own:
//!
//! - the SIMD body equals the scalar reference bit for bit, whatever the band height;
//! - against an independent oracle, every pixel shows the triangle whose exact (unsnapped,
//!   f64) surface is nearest along the pixel-centre ray, or one that a sample point within
//!   the fixed-point snap (1/256 px) of the centre sees, or one at a depth tie (1e-4
//!   relative): snapping and the f32 depth key are the only differences, and each pixel's
//!   cause is named;
//! - shared edges through pixel centres give each centre to exactly one of the two triangles
//!   (the top-left rule), so a mesh has neither cracks nor double coverage;
//! - triangles through the eye plane and far past the frame (near and guard-band clipping)
//!   and non-finite vertices are handled, and the refusals are clear.

use glam::{DVec3, Vec3};
use stereotrace_kernels::bvh::TriVerts;
use stereotrace_kernels::raster::fixed::FixedRasterizer;
use stereotrace_kernels::raster::{Body, NO_PRIM, NoMasks, Triangles, VisibilityBuffer};
use stereotrace_kernels::synth::{Rng, camera_at};
use stereotrace_kernels::{CameraModel, Extent};

const NEAR: f32 = 1e-3;

fn tri(v: [Vec3; 3]) -> TriVerts {
    [v[0].x, v[0].y, v[0].z, v[1].x, v[1].y, v[1].z, v[2].x, v[2].y, v[2].z]
}

/// A stereo pair 6.5 cm apart at `x`, looking down −z.
fn rig(x: f32, extent: Extent, vfov: f32) -> [CameraModel; 2] {
    [-0.0325, 0.0325].map(|dx| camera_at(Vec3::new(x + dx, 0.0, 0.0), extent, vfov))
}

/// A random soup in front of the cameras: mostly small triangles at 1–20 m, some large, some
/// through the eye plane, some far off to the side.
fn soup(rng: &mut Rng, n: usize) -> Vec<TriVerts> {
    let mut v = |lo: f32, hi: f32| rng.range(lo, hi);
    (0..n)
        .map(|i| {
            let (centre, size) = match i % 10 {
                0 => (Vec3::new(v(-3.0, 3.0), v(-2.0, 2.0), v(-2.0, 2.0)), v(1.0, 5.0)),
                1 => (Vec3::new(v(-400.0, 400.0), v(-50.0, 50.0), v(-30.0, -1.0)), v(1.0, 100.0)),
                _ => (Vec3::new(v(-6.0, 6.0), v(-4.0, 4.0), v(-20.0, -1.0)), v(0.01, 1.5)),
            };
            let mut p = || centre + Vec3::new(v(-size, size), v(-size, size), v(-size, size));
            tri([p(), p(), p()])
        })
        .collect()
}

fn run(tris: &[TriVerts], cameras: &[CameraModel; 2], body: Body, band_rows: usize) -> [VisibilityBuffer; 2] {
    run_near(tris, cameras, body, band_rows, NEAR)
}

fn run_near(
    tris: &[TriVerts],
    cameras: &[CameraModel; 2],
    body: Body,
    band_rows: usize,
    near: f32,
) -> [VisibilityBuffer; 2] {
    let extent = cameras[0].extent;
    let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
    let [l, r] = &mut out;
    let mut raster = FixedRasterizer::with_band_rows(band_rows);
    raster
        .rasterize(Triangles { main: tris, extra: &[] }, [&cameras[0], &cameras[1]], &NoMasks, near, [l, r], body)
        .expect("valid input");
    out
}

fn bits(v: &VisibilityBuffer) -> (Vec<u32>, Vec<u32>) {
    (v.prim.as_slice().to_vec(), v.q.as_slice().iter().map(|q| q.to_bits()).collect())
}

#[test]
fn simd_equals_scalar_bit_for_bit_at_any_band_height() {
    let mut rng = Rng::new(11);
    for (case, (w, h)) in [(1, 1), (7, 5), (33, 17), (64, 36), (130, 41), (200, 9)].into_iter().enumerate() {
        let extent = Extent::new(w, h).unwrap();
        let tris = soup(&mut rng, 300);
        let cameras = rig(0.1 * case as f32, extent, 60.0);
        let reference = run(&tris, &cameras, Body::Scalar, 32);
        assert!(reference[0].prim.as_slice().iter().any(|&p| p != NO_PRIM) || w * h < 10, "{w}x{h}: nothing drawn");
        for band_rows in [1, 3, 32] {
            let simd = run(&tris, &cameras, Body::Simd, band_rows);
            for eye in 0..2 {
                assert!(bits(&simd[eye]) == bits(&reference[eye]), "{w}x{h}, bands of {band_rows}, eye {eye}");
            }
        }
    }
}

/// The SIMD setup skips clusters of 64 consecutive triangles whose bounding box lies beyond
/// one side plane of each eye's frustum. Skipping must change nothing: a cluster far off to
/// the side is skipped; a cluster with one visible triangle is not; a cluster that only the
/// right eye sees (a sliver beside the left eye's frustum) is not, and the right eye shows it.
#[test]
fn off_screen_clusters_are_skipped_and_nothing_else_changes() {
    const CLUSTER: usize = 64;
    let extent = Extent::new(64, 36).unwrap();
    let cameras = rig(0.0, extent, 60.0);
    // The half-width of the view at unit depth, from the camera's own ray corner.
    let half_width = (cameras[0].ray_origin_corner[0] / cameras[0].ray_origin_corner[2]).abs();
    let mut rng = Rng::new(5);
    let mut cluster = |x: (f32, f32), y: (f32, f32), z: f32, size: f32| -> Vec<TriVerts> {
        (0..CLUSTER)
            .map(|_| {
                let c = Vec3::new(rng.range(x.0, x.1), rng.range(y.0, y.1), z);
                let d = size;
                tri([c + Vec3::new(-d, -d, 0.0), c + Vec3::new(d, -d, 0.0), c + Vec3::new(0.0, d, 0.0)])
            })
            .collect()
    };
    let far_left = cluster((-40.0, -30.0), (-1.0, 1.0), -5.0, 0.2);
    let far_above = cluster((-1.0, 1.0), (30.0, 40.0), -5.0, 0.2);
    let mut one_visible = cluster((30.0, 40.0), (-1.0, 1.0), -5.0, 0.2);
    one_visible[17] = tri([Vec3::new(-0.5, -0.5, -5.0), Vec3::new(0.5, -0.5, -5.0), Vec3::new(0.0, 0.5, -5.0)]);
    // At depth 1 the left eye sees x up to −0.0325 + half_width, the right eye 6.5 cm more.
    let edge = -0.0325 + half_width;
    let right_only = cluster((edge + 0.02, edge + 0.045), (-0.2, 0.2), -1.0, 0.005);
    let tris: Vec<TriVerts> = [far_left, one_visible, right_only, far_above].concat();
    let run = |body: Body| {
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        let [l, r] = &mut out;
        let stats = FixedRasterizer::new()
            .rasterize(Triangles { main: &tris, extra: &[] }, [&cameras[0], &cameras[1]], &NoMasks, NEAR, [l, r], body)
            .expect("valid input");
        (out, stats)
    };
    let ((simd, simd_stats), (scalar, scalar_stats)) = (run(Body::Simd), run(Body::Scalar));
    assert_eq!(simd_stats.cluster_culled, 2 * CLUSTER as u64, "the far-left and far-above clusters");
    assert_eq!(scalar_stats.cluster_culled, 0, "the scalar reference sets up every triangle");
    assert_eq!(simd_stats.visible, scalar_stats.visible);
    for eye in 0..2 {
        assert!(bits(&simd[eye]) == bits(&scalar[eye]), "eye {eye}: skipping changed the output");
    }
    let shows = |eye: usize, ids: std::ops::Range<usize>| {
        simd[eye].prim.as_slice().iter().any(|&p| p != NO_PRIM && ids.contains(&(p as usize)))
    };
    assert!(shows(0, CLUSTER..2 * CLUSTER) && shows(1, CLUSTER..2 * CLUSTER), "the one visible triangle");
    assert!(!shows(0, 2 * CLUSTER..3 * CLUSTER), "the sliver is outside the left eye");
    assert!(shows(1, 2 * CLUSTER..3 * CLUSTER), "the right eye shows the sliver");
}

/// The oracle: the exact f64 ray through the centre of `(x, y)` (offset by `(ox, oy)` px)
/// against every triangle; the nearest hit past the near plane (view depth), the smaller id
/// on equal depth.
fn nearest(tris: &[TriVerts], camera: &CameraModel, x: f64, y: f64) -> Option<(u32, f64)> {
    let o = DVec3::from(camera.centre.map(f64::from));
    let [c, dx, dy] = [camera.ray_origin_corner, camera.ray_dx, camera.ray_dy].map(|v| DVec3::from(v.map(f64::from)));
    let d = c + x * dx + y * dy;
    let mut best: Option<(u32, f64)> = None;
    for (i, t) in tris.iter().enumerate() {
        let Some(depth) = hit(t, o, d) else { continue };
        if depth > f64::from(NEAR) && best.is_none_or(|(_, b)| depth < b) {
            best = Some((i as u32, depth));
        }
    }
    best
}

/// Möller–Trumbore in f64: the ray parameter (view depth, for the camera's unit-depth rays).
fn hit(t: &TriVerts, o: DVec3, d: DVec3) -> Option<f64> {
    let v = |k: usize| DVec3::new(f64::from(t[3 * k]), f64::from(t[3 * k + 1]), f64::from(t[3 * k + 2]));
    let (e1, e2) = (v(1) - v(0), v(2) - v(0));
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = o - v(0);
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let w = d.dot(q) / det;
    if !(u >= 0.0 && w >= 0.0 && u + w <= 1.0) {
        return None;
    }
    Some(e2.dot(q) / det)
}

#[derive(Default, Debug)]
struct Tally {
    pixels: usize,
    agree: usize,
    snap: usize,
    ties: usize,
    unexplained: Vec<String>,
}

/// Compares one eye's buffer with the oracle and names each difference's cause.
fn explain(tris: &[TriVerts], camera: &CameraModel, vis: &VisibilityBuffer, tally: &mut Tally) {
    let (w, h) = (camera.extent.width(), camera.extent.height());
    let o = DVec3::from(camera.centre.map(f64::from));
    let [c, dx, dy] = [camera.ray_origin_corner, camera.ray_dx, camera.ray_dy].map(|v| DVec3::from(v.map(f64::from)));
    for y in 0..h {
        for x in 0..w {
            tally.pixels += 1;
            let got = vis.prim.as_slice()[y * w + x];
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let want = nearest(tris, camera, px, py);
            if want.map(|(p, _)| p) == Some(got).filter(|&p| p != NO_PRIM) || (want.is_none() && got == NO_PRIM) {
                tally.agree += 1;
                continue;
            }
            // Seen from a point within the snap of the centre?
            let radius = 1.0 / 256.0;
            let seen_nearby = (0..16).any(|k| {
                let a = k as f64 * std::f64::consts::TAU / 16.0;
                let seen = nearest(tris, camera, px + radius * a.cos(), py + radius * a.sin()).map(|(p, _)| p);
                seen.unwrap_or(NO_PRIM) == got
            });
            if seen_nearby {
                tally.snap += 1;
                continue;
            }
            // A depth tie: the raster's triangle is hit at the centre within 1e-4 of the
            // nearest depth.
            let d = c + px * dx + py * dy;
            let tie = match (want, got) {
                (Some((_, best)), g) if g != NO_PRIM => {
                    hit(&tris[g as usize], o, d).is_some_and(|t| (t - best).abs() <= 1e-4 * best)
                }
                _ => false,
            };
            if tie {
                tally.ties += 1;
                continue;
            }
            tally.unexplained.push(format!("({x}, {y}): raster {got}, oracle {want:?}"));
        }
    }
}

#[test]
fn every_pixel_is_the_nearest_exact_surface_or_within_the_snap_or_a_depth_tie() {
    let mut rng = Rng::new(5);
    let mut tally = Tally::default();
    for (case, (w, h, vfov)) in
        [(96, 54, 60.0), (61, 37, 90.0), (40, 40, 20.0), (128, 72, 75.0)].into_iter().enumerate()
    {
        let extent = Extent::new(w, h).unwrap();
        let tris = soup(&mut rng, 150);
        let cameras = rig(0.05 * case as f32, extent, vfov);
        let out = run(&tris, &cameras, Body::Simd, 32);
        for eye in 0..2 {
            explain(&tris, &cameras[eye], &out[eye], &mut tally);
        }
    }
    println!("{tally:?}");
    assert!(
        tally.unexplained.is_empty(),
        "{} unexplained: {:?}",
        tally.unexplained.len(),
        &tally.unexplained[..10.min(tally.unexplained.len())]
    );
    assert!(tally.agree as f64 >= 0.99 * tally.pixels as f64, "{tally:?}");
}

/// World points that project to the given pixel positions of `camera` at view depth `depth`.
fn at_pixels(camera: &CameraModel, pts: [(f32, f32); 3], depth: f32) -> TriVerts {
    let o = Vec3::from(camera.centre);
    tri(pts.map(|(x, y)| o + Vec3::from(camera.ray(x, y)) * depth))
}

#[test]
fn shared_edges_through_pixel_centres_give_each_centre_to_one_triangle() {
    let extent = Extent::new(48, 40).unwrap();
    let cameras = rig(0.0, extent, 60.0);
    let cam = &cameras[0];
    // Pairs sharing an edge that runs exactly through pixel centres: vertical (x = 20.5),
    // horizontal (y = 10.5) and diagonal (through (8.5, 4.5), (12.5, 12.5), ...).
    let pairs: [[(f32, f32); 4]; 3] = [
        [(20.5, 4.5), (20.5, 30.5), (6.0, 17.0), (35.0, 17.0)],
        [(5.5, 10.5), (40.5, 10.5), (22.0, 2.0), (22.0, 25.0)],
        [(8.5, 4.5), (20.5, 28.5), (2.0, 27.0), (30.0, 3.0)],
    ];
    for (i, [a, b, l, r]) in pairs.into_iter().enumerate() {
        let coverage = |t: TriVerts| {
            let out = run(&[t], &cameras, Body::Simd, 32);
            out[0].prim.as_slice().iter().map(|&p| p != NO_PRIM).collect::<Vec<bool>>()
        };
        let (one, two) = (coverage(at_pixels(cam, [a, b, l], 3.0)), coverage(at_pixels(cam, [b, a, r], 3.0)));
        let both = one.iter().zip(&two).filter(|(p, q)| **p && **q).count();
        assert_eq!(both, 0, "pair {i}: {both} pixel centres covered by both triangles");
        // Every centre on the shared edge (strictly between its ends) is covered by one.
        let (ax, ay, bx, by) = (a.0 as f64, a.1 as f64, b.0 as f64, b.1 as f64);
        let steps = ((bx - ax).abs().max((by - ay).abs())) as usize;
        let mut on_edge = 0;
        for s in 1..steps {
            let f = s as f64 / steps as f64;
            let (x, y) = (ax + f * (bx - ax), ay + f * (by - ay));
            if (x - 0.5).fract() == 0.0 && (y - 0.5).fract() == 0.0 {
                let at = y as usize * 48 + x as usize;
                assert!(
                    one[at] ^ two[at],
                    "pair {i}: centre ({x}, {y}) on the shared edge covered {} times",
                    u8::from(one[at]) + u8::from(two[at])
                );
                on_edge += 1;
            }
        }
        assert!(on_edge >= 4, "pair {i}: only {on_edge} centres on the edge");
    }
}

#[test]
fn a_tessellated_wall_has_no_cracks() {
    let extent = Extent::new(97, 61).unwrap();
    let cameras = rig(0.0, extent, 70.0);
    // A 30 × 20 grid of quads on the plane z = −4, seen whole by both eyes.
    let (nx, ny) = (30, 20);
    let p = |i: usize, j: usize| Vec3::new(-2.0 + 4.0 * i as f32 / nx as f32, -1.5 + 3.0 * j as f32 / ny as f32, -4.0);
    let mut tris = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            tris.push(tri([p(i, j), p(i + 1, j), p(i + 1, j + 1)]));
            tris.push(tri([p(i, j), p(i + 1, j + 1), p(i, j + 1)]));
        }
    }
    let out = run(&tris, &cameras, Body::Simd, 32);
    for (eye, cam) in cameras.iter().enumerate() {
        // Every pixel whose centre ray hits the wall (the oracle, a pixel away from its
        // outline) shows a triangle.
        for y in 1..60 {
            for x in 1..96 {
                let inside = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (0.0, 0.0)]
                    .iter()
                    .all(|(ox, oy)| nearest(&tris, cam, x as f64 + 0.5 + ox, y as f64 + 0.5 + oy).is_some());
                if inside {
                    assert_ne!(out[eye].prim.as_slice()[y * 97 + x], NO_PRIM, "eye {eye}: a crack at ({x}, {y})");
                }
            }
        }
    }
}

#[test]
fn triangles_through_the_eye_plane_and_far_past_the_frame_are_clipped() {
    let extent = Extent::new(64, 48).unwrap();
    let cameras = rig(0.0, extent, 60.0);
    let tris = vec![
        // A floor from behind the eye to far ahead, and a wall 10⁶ m wide.
        tri([Vec3::new(-50.0, -1.0, 30.0), Vec3::new(50.0, -1.0, 30.0), Vec3::new(0.0, -1.0, -500.0)]),
        tri([Vec3::new(-1e6, -1e3, -50.0), Vec3::new(1e6, -1e3, -50.0), Vec3::new(0.0, 1e6, -50.0)]),
        // Entirely behind the eye.
        tri([Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 2.0)]),
    ];
    let out = run(&tris, &cameras, Body::Scalar, 32);
    let simd = run(&tris, &cameras, Body::Simd, 7);
    let mut tally = Tally::default();
    for eye in 0..2 {
        assert!(bits(&out[eye]) == bits(&simd[eye]));
        explain(&tris, &cameras[eye], &out[eye], &mut tally);
    }
    assert!(tally.unexplained.is_empty(), "{:?}", tally.unexplained);
    let seen = |p: u32| out[0].prim.as_slice().iter().filter(|&&q| q == p).count();
    assert!(seen(0) > 500 && seen(1) > 500 && seen(2) == 0, "floor {}, wall {}, behind {}", seen(0), seen(1), seen(2));
}

/// Found by fuzzing (the `raster_fixed` corpus holds the inputs): with a near plane at 10⁻⁶
/// and eyes 18–19 cm apart, a triangle whose plane passes within a centimetre of one eye and
/// behind it is cut by the near plane beside that eye's axis, where the other eye sees the
/// cut 0.19 m / 10⁻⁶ m off to the side. First the triangle was dropped from both eyes (past
/// the coordinate limit in one); then, clipped to both eyes' guard bands at once, the left
/// eye's band cut away most of what the right eye sees. Each eye is clipped to its own band
/// now.
#[test]
fn a_triangle_behind_the_eye_clips_to_each_eyes_own_guard_band() {
    let extent = Extent::new(10, 6).unwrap();
    let (eye, forward) =
        (Vec3::new(0.24509805, -0.39411765, 1.382353), Vec3::new(-0.19511418, -0.18833314, -0.9625285));
    let right = forward.cross(Vec3::Y).normalize();
    let cameras = [-0.5f32, 0.5].map(|s| {
        let at = eye + right * (s * 0.18745098);
        let vp = stereotrace_kernels::camera::look_at_perspective(
            at,
            at + forward,
            Vec3::Y,
            13.019608f32.to_radians(),
            extent,
        );
        CameraModel::new(vp, extent).unwrap()
    });
    let tris =
        vec![[0.18988705, 0.9311765, -3.2591176, -2.3279412, -3.2591176, 3.724706, 2.3279412, 1.3967648, 1.3967648]];
    let out = run_near(&tris, &cameras, Body::Simd, 32, 1e-6);
    let mut tally = Tally::default();
    for eye in 0..2 {
        explain(&tris, &cameras[eye], &out[eye], &mut tally);
    }
    assert!(tally.unexplained.is_empty(), "{:?}", tally.unexplained);
    assert!(out[0].prim.as_slice().contains(&0), "the left eye sees it");
}

#[test]
fn non_finite_vertices_draw_nothing_and_bad_input_is_refused() {
    let extent = Extent::new(16, 9).unwrap();
    let cameras = rig(0.0, extent, 60.0);
    let good = tri([Vec3::new(-1.0, -1.0, -3.0), Vec3::new(1.0, -1.0, -3.0), Vec3::new(0.0, 1.0, -3.0)]);
    let mut nan = good;
    nan[4] = f32::NAN;
    let mut inf = good;
    inf[0] = f32::INFINITY;
    let out = run(&[nan, inf, good], &cameras, Body::Simd, 32);
    assert!(out[0].prim.as_slice().iter().all(|&p| p == NO_PRIM || p == 2));
    assert!(out[0].prim.as_slice().contains(&2));

    let mut raster = FixedRasterizer::new();
    let mut bufs = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
    let [l, r] = &mut bufs;
    let tris = Triangles { main: &[good], extra: &[] };
    let err = raster.rasterize(tris, [&cameras[0], &cameras[1]], &NoMasks, 0.0, [l, r], Body::Simd).unwrap_err();
    assert!(err.to_string().contains("near plane"), "{err}");
    let tilted = camera_at(Vec3::ZERO, extent, 50.0);
    let err = raster.rasterize(tris, [&cameras[0], &tilted], &NoMasks, NEAR, [l, r], Body::Simd).unwrap_err();
    assert!(err.to_string().contains("parallel stereo pair"), "{err}");
}

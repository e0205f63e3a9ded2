//! The rasterisers against a brute-force oracle: the SIMD body must equal its scalar
//! reference bit for bit, and both must equal the tracer's closest hit (smaller id on equal
//! `t`) at every pixel, unless the near plane, the tracer's self-intersection guard or its
//! f32 rounding explains the difference in exact (f64) geometry.

use glam::{DVec3, Vec3};

use crate::bvh::{PreparedRay, Ray, TriVerts, intersect_triangle, intersect_triangle_line};
use crate::camera::{CameraModel, CameraPose};
use crate::frame::Extent;
use crate::raster::fixed::FixedRasterizer;
use crate::raster::{Body, NO_PRIM, NoMasks, Rasterizer, Triangles, VisibilityBuffer};

use super::input::Bytes;

/// How far from the origin a fuzzed raster vertex may lie (the camera is within 2 units of it):
/// a scene 10³ times the viewing distance. Farther, the f32 tracer stops being an oracle at
/// all (at ±2²⁴ its hits land behind the eye and near ties are ordered by rounding; see
/// `RELIABILITY.md`).
pub const RASTER_FUZZ_EXTENT: f32 = 1e3;

/// A coordinate: mostly on a coarse grid (shared edges, coincident and degenerate triangles,
/// triangles through the eye), sometimes anywhere, rarely any f32 (NaN and ±∞ included, which
/// must never reach a pixel; finite values clamped to ±`extent`).
fn coordinate(bytes: &mut Bytes<'_>, scale: f32, extent: f32) -> f32 {
    let b = bytes.u8();
    match b {
        0..=223 => (f32::from(b % 17) / 8.0 - 1.0) * scale,
        224..=251 => bytes.unit(-scale, scale),
        _ => {
            let v = bytes.f32();
            if v.is_finite() { v.clamp(-extent, extent) } else { v }
        }
    }
}

/// The tracer's pixel-centre ray of `(x, y)`.
fn pixel_ray(camera: &CameraModel, x: usize, y: usize) -> Option<PreparedRay> {
    let d = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
    PreparedRay::new(&Ray::new(camera.centre.into(), d.into()))
}

/// The tracer's closest hit at pixel `(x, y)` (smaller id on equal `t`): the oracle.
fn closest(camera: &CameraModel, tris: &[TriVerts], x: usize, y: usize) -> (u32, f32) {
    let mut best = (NO_PRIM, f32::INFINITY);
    let Some(r) = pixel_ray(camera, x, y) else { return best };
    for (i, t) in tris.iter().enumerate() {
        if let Some(hit) = intersect_triangle(&r, t, f32::INFINITY)
            && (hit.t < best.1 || (hit.t == best.1 && (i as u32) < best.0))
        {
            best = (i as u32, hit.t);
        }
    }
    best
}

/// The tracer's hit `t` on triangle `prim` at `(x, y)` (for failure messages).
fn tracer_hit(camera: &CameraModel, tris: &[TriVerts], prim: u32, x: usize, y: usize) -> Option<f32> {
    let r = pixel_ray(camera, x, y)?;
    intersect_triangle(&r, tris.get(prim as usize)?, f32::INFINITY).map(|h| h.t)
}

/// Whether the tracer's self-intersection guard explains why it does not see `prim` at
/// `(x, y)` where the raster does: the pixel ray's line meets `prim` in front of the eye and
/// nearer than the tracer's own hit, but the watertight test rejects that hit because `t` is
/// within its rounding bound of 0 (pbrt-v4's conservative test; it happens for slivers
/// whose vertices lie far away relative to their area). The raster decides visibility by
/// geometry and has no such guard.
fn guard_rejected(camera: &CameraModel, tris: &[TriVerts], prim: u32, x: usize, y: usize, tracer_t: f32) -> bool {
    let Some(r) = pixel_ray(camera, x, y) else { return false };
    let tri = &tris[prim as usize];
    intersect_triangle(&r, tri, f32::INFINITY).is_none()
        && intersect_triangle_line(&r, tri).is_some_and(|h| h.t > 0.0 && h.t <= tracer_t)
}

/// Vertex `k` of a triangle, in f64.
fn vertex(tri: &TriVerts, k: usize) -> DVec3 {
    DVec3::new(tri[3 * k].into(), tri[3 * k + 1].into(), tri[3 * k + 2].into())
}

/// A triangle's doubled area vector `(v₁ − v₀) × (v₂ − v₀)`, in f64.
fn area_vector(tri: &TriVerts) -> DVec3 {
    (vertex(tri, 1) - vertex(tri, 0)).cross(vertex(tri, 2) - vertex(tri, 0))
}

/// The distance from `eye` to the farthest vertex of `tri`.
fn reach(eye: DVec3, tri: &TriVerts) -> f64 {
    (0..3).map(|k| (vertex(tri, k) - eye).length()).fold(0.0, f64::max)
}

/// The f32 tracer's error scale on `tri`: its watertight test works on coordinates relative
/// to the eye, so `t` is known to about `8·2⁻²⁴·max|v − eye|`. Below that the tracer cannot
/// order two hits or place one on a side of the raster's near plane.
fn tracer_error(eye: DVec3, tri: &TriVerts) -> f64 {
    8.0 * f64::from(f32::EPSILON) * 0.5 * reach(eye, tri)
}

/// The raster's near plane in the fuzz target: the smallest view depth it rasterises.
const RASTER_NEAR: f32 = 1e-6;

/// The view depths at which a hit on `tri` may fall on either side of the raster's near
/// plane: within the tracer's error of it (`[RASTER_NEAR − e, RASTER_NEAR + e)`).
fn near_plane_band(eye: DVec3, tri: &TriVerts) -> (f64, f64) {
    let (near, e) = (f64::from(RASTER_NEAR), tracer_error(eye, tri));
    (near - e, near + e)
}

/// Whether the raster's near plane explains a disagreement at `(x, y)`: the tracer's closest
/// hit, on `tracer` at `tracer_t`, lies at or in front of the near plane, which the raster by
/// design does not draw (pixel rays have unit view depth, so `t` is the view depth). A hit
/// within the tracer's f32 error of the plane ([`tracer_error`], ~1e-6 for vertices a
/// few units away) may fall on either side of it, so the raster may show any such triangle,
/// or the nearest hit beyond them all (none: no triangle).
fn near_plane_explains(
    camera: &CameraModel,
    tris: &[TriVerts],
    got: u32,
    tracer: u32,
    tracer_t: f32,
    x: usize,
    y: usize,
) -> bool {
    let eye = DVec3::from(Vec3::from(camera.centre));
    let (Some(r), Some(tracer_tri)) = (pixel_ray(camera, x, y), tris.get(tracer as usize)) else { return false };
    if f64::from(tracer_t) >= near_plane_band(eye, tracer_tri).1 {
        return false;
    }
    let mut beyond = (NO_PRIM, f32::INFINITY);
    for (i, t) in tris.iter().enumerate() {
        let Some(hit) = intersect_triangle(&r, t, f32::INFINITY) else { continue };
        let (id, (low, high), hit_t) = (i as u32, near_plane_band(eye, t), f64::from(hit.t));
        if hit_t < high {
            if id == got && hit_t >= low {
                return true;
            }
        } else if hit.t < beyond.1 || (hit.t == beyond.1 && id < beyond.0) {
            beyond = (id, hit.t);
        }
    }
    got == beyond.0
}

/// How far from the eye a vertex must lie for the f32 tracer's rounding to be a possible cause
/// of a disagreement: its watertight test works on coordinates relative to the ray origin, so
/// its error grows as `2⁻²⁴·|v − eye|` (and more in the products of slivers). Fuzzed vertices
/// lie up to [`RASTER_FUZZ_EXTENT`] from the origin, the camera within 2 units of it.
const FAR_VERTEX: f64 = 50.0;

/// The exact answer at `(x, y)` where the tracer's rounding may be wrong. For an empty raster
/// pixel (`prim` is [`NO_PRIM`]): whether the tracer's triangle has a far vertex and, in f64
/// on the tracer's own f32 pixel ray, no triangle is hit beyond the near plane. Otherwise: whether, in f64 on
/// the tracer's own f32 pixel ray, `prim` is hit in front of the eye and no triangle nearer
/// by more than the two triangles' f32 error scales ([`tracer_error`] each: below that
/// the tracer cannot order them) unless the tracer misses that far triangle there or it lies
/// at or in front of the raster's near plane; and a
/// vertex of `prim` or of the tracer's triangle lies beyond [`FAR_VERTEX`], or the tracer's
/// triangle is hit within those error scales of `prim` (a near tie the f32 test orders by
/// rounding), or `prim` is hit so near the eye that the f32 test's `t`, whose error grows as
/// the incidence grazes, may lie behind it.
fn exact_explains(camera: &CameraModel, tris: &[TriVerts], prim: u32, tracer: u32, x: usize, y: usize) -> bool {
    let o = DVec3::from(Vec3::from(camera.centre));
    let d = DVec3::from(Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5)));
    let reach = |t: &TriVerts| reach(o, t);
    // The f32 test's `t` errs by about `u·reach³/|det|` (its edge functions by `u·reach²`,
    // weighted by the vertices' depths over the determinant), which is the error scale for
    // a well-shaped triangle and `reach²/|n·d̂|` times it for a needle whose determinant
    // nearly vanishes (`n` the doubled area vector): such a needle's `t` was off by 2.6
    // error scales in a fuzz input.
    let unit_d = d.normalize();
    let error = |t: &TriVerts| {
        let conditioning = (reach(t).powi(2) / area_vector(t).dot(unit_d).abs()).max(1.0);
        tracer_error(o, t) * if conditioning.is_finite() { conditioning } else { 1.0 }
    };

    // Möller–Trumbore in f64, edges inclusive (to 1e-12 of the barycentrics).
    let hit = |t: &TriVerts| -> Option<f64> {
        let (e1, e2) = (vertex(t, 1) - vertex(t, 0), vertex(t, 2) - vertex(t, 0));
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let s = o - vertex(t, 0);
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let w = d.dot(q) / det;
        let t = e2.dot(q) / det;
        (u >= -1e-12 && w >= -1e-12 && u + w <= 1.0 + 1e-12 && t > 0.0).then_some(t)
    };
    // A nearer triangle at or in front of the near plane is one the raster does not draw.
    let clipped = |t: &TriVerts, ti: f64| ti < f64::from(RASTER_NEAR) + tracer_error(o, t);
    if prim == NO_PRIM {
        // The raster shows nothing where the tracer hits a far triangle: explained when the
        // exact ray hits nothing the raster could draw (a tracer hit just outside an edge of
        // a triangle whose vertices lie 10³ units away).
        let far = tris.get(tracer as usize).is_some_and(|t| reach(t) > FAR_VERTEX);
        return far && tris.iter().all(|t| hit(t).is_none_or(|ti| clipped(t, ti)));
    }
    let mine = &tris[prim as usize];
    let Some(t_prim) = hit(mine) else { return false };
    // The tracer's rounding is a possible cause only with a far vertex, or where its triangle
    // is hit within the two triangles' error scales of the raster's (a near tie it orders by
    // rounding: two hits 1e-8 apart at t = 0.0028 with vertices 3.5 units away).
    let far = reach(mine) > FAR_VERTEX || tris.get(tracer as usize).is_some_and(|t| reach(t) > FAR_VERTEX);
    let near_tie = tris
        .get(tracer as usize)
        .is_some_and(|t| hit(t).is_some_and(|ti| (ti - t_prim).abs() <= error(mine) + error(t)));
    // Or where `prim`'s plane passes so near the eye that the f32 test's `t` may fall behind
    // it: the eye's distance to the plane errs by the error scale, and `t` by that over the
    // cosine of the incidence (`|Δt| ≈ error·|n|/|n·d|` for `t` in units of `d`), so a grazing
    // ray through a plane 10⁻⁶ from the eye is placed behind it.
    let at_eye = {
        let n = area_vector(mine);
        t_prim * n.dot(d).abs() <= tracer_error(o, mine) * n.length()
    };
    if !(far || near_tie || at_eye) {
        return false;
    }
    // The raster's uncertain pixels take the tracer's answer, so a nearer far sliver that
    // the f32 test misses there is one the raster cannot see either.
    let ray = pixel_ray(camera, x, y);
    let tracer_misses = |t: &TriVerts| {
        reach(t) > FAR_VERTEX && ray.as_ref().is_none_or(|r| intersect_triangle(r, t, f32::INFINITY).is_none())
    };
    tris.iter().enumerate().all(|(i, t)| {
        i as u32 == prim
            || hit(t).is_none_or(|ti| ti >= t_prim - (error(mine) + error(t)) || clipped(t, ti))
            || tracer_misses(t)
    })
}

/// One rasteriser fuzz case: a frame size, a head pose, an eye separation and up to 24
/// triangles, decoded from the bytes (shared by both rasterisers' targets, so a corpus input
/// means the same scene to both).
struct RasterCase {
    extent: Extent,
    head: CameraPose,
    separation: f32,
    tris: Vec<TriVerts>,
    left: CameraModel,
    right: CameraModel,
}

/// Frames up to this wide: past the 24 columns from which the exact rasteriser's SIMD body
/// walks row spans instead of whole boxes.
const MAX_WIDTH: u8 = 64;

/// The case the bytes describe.
fn raster_case(data: &[u8]) -> Option<RasterCase> {
    let mut bytes = Bytes(data);
    let extent = Extent::new(1 + usize::from(bytes.u8() % MAX_WIDTH), 1 + usize::from(bytes.u8() % 16)).expect("small");
    let eye = Vec3::new(bytes.unit(-0.5, 0.5), bytes.unit(-0.5, 0.5), bytes.unit(0.5, 2.0));
    let yaw = bytes.unit(-0.6, 0.6);
    let forward = Vec3::new(yaw.sin(), bytes.unit(-0.3, 0.3), -yaw.cos()).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let head = CameraPose { eye, forward, up: right.cross(forward), right, vfov_deg: bytes.unit(10.0, 120.0) };
    let separation = match bytes.u8() % 4 {
        0 => 0.0,
        1 => bytes.unit(0.0, 0.2),
        2 => bytes.unit(0.0, 20.0),
        _ => 0.064,
    };
    let scale = bytes.unit(0.1, 4.0);
    let n = usize::from(bytes.u8() % 25);
    let tris: Vec<TriVerts> =
        (0..n).map(|_| core::array::from_fn(|_| coordinate(&mut bytes, scale, RASTER_FUZZ_EXTENT))).collect();
    let [left, right] = CameraModel::stereo_pair(&head, separation, extent).ok()?;
    Some(RasterCase { extent, head, separation, tris, left, right })
}

/// Fuzzes the stereo rasteriser: up to 24 triangles around a camera (the grid puts many
/// through the eye, behind it, coincident or degenerate), an extent from 1×1 to 64×16, any
/// eye separation from the bytes. Both bodies (in bands of different heights) must give the
/// same buffers, and every pixel of
/// both eyes the tracer's closest hit, unless one of these explains the difference:
/// - the raster's near plane: the tracer's hit lies nearer than `RASTER_NEAR` (10⁻⁶), which the
///   raster does not draw by design;
/// - the tracer's self-intersection guard refused the raster's triangle there (a hit the
///   watertight test takes for one within its rounding bound of the eye);
/// - the tracer's rounding: a vertex lies far from the eye (beyond `FAR_VERTEX`, 50 units), two
///   hits are a near tie, or the raster's triangle passes within the f32 test's `t` error of
///   the eye (grazing), and the exact f64 answer is the raster's.
pub fn raster(data: &[u8]) {
    let Some(RasterCase { extent, head, separation, tris, left, right }) = raster_case(data) else {
        return;
    };
    let run = |body, mut rasterizer: Rasterizer| {
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        let [l, r] = &mut out;
        let result = rasterizer.rasterize(
            Triangles { main: &tris, extra: &[] },
            [&left, &right],
            &NoMasks,
            RASTER_NEAR,
            [l, r],
            body,
        );
        result.map(|_| out)
    };
    // The SIMD body in bands of 1–8 rows (from the extent, so the corpus keeps its meaning),
    // the scalar one in the default bands: every frame here crosses band boundaries in one of
    // them, and the buffers must not depend on where they lie.
    let small_bands = Rasterizer::with_band_rows(1 + (extent.width() + extent.height()) % 8);
    let (simd, scalar) = match (run(Body::Simd, small_bands), run(Body::Scalar, Rasterizer::new())) {
        (Ok(simd), Ok(scalar)) => (simd, scalar),
        (Err(a), Err(b)) => {
            assert_eq!(a, b, "the bodies refuse differently");
            return;
        }
        (a, b) => panic!("one body refuses: {:?} vs {:?}", a.err(), b.err()),
    };
    assert_eq!(simd, scalar, "the SIMD body and the scalar reference differ");
    for (vis, cam) in simd.iter().zip([&left, &right]) {
        for y in 0..extent.height() {
            for x in 0..extent.width() {
                let got = vis.prim.as_slice()[y * extent.width() + x];
                let (want, tracer_t) = closest(cam, &tris, x, y);
                assert!(
                    got == want
                        || near_plane_explains(cam, &tris, got, want, tracer_t, x, y)
                        || (got != NO_PRIM && guard_rejected(cam, &tris, got, x, y, tracer_t))
                        || exact_explains(cam, &tris, got, want, x, y),
                    "pixel ({x}, {y}) of {extent:?}: raster {got}, tracer {want} (the tracer's t: {:?} and {:?}); \
                     camera {head:?}, separation {separation}, triangles {tris:?}",
                    tracer_hit(cam, &tris, got, x, y),
                    tracer_hit(cam, &tris, want, x, y),
                );
            }
        }
    }
}

/// The fixed-point rasteriser's snap: vertices land on a 1/256-pixel grid.
const SNAP_PX: f64 = 1.0 / 256.0;

/// Fuzzes the fixed-point rasteriser on the cases of [`raster`]: both bodies (in bands of
/// different heights) must give the same buffers, and every pixel of both eyes the tracer's
/// closest hit, unless one of these explains the difference:
/// - the near plane or the tracer's self-intersection guard, as in [`raster`];
/// - **the snap**: exact (f64) geometry shows the raster's answer from some point within
///   1/256 px of the pixel centre (sampled on three circles), or every triangle it shows in
///   front of the raster's at the centre has an edge within 1/256 px of the centre (its
///   snapped image may leave the centre out), is a depth tie with it, or lies within the
///   tracer's error of the near plane (so the two explanations may meet at one pixel);
/// - **a depth tie within the snap**: both triangles' planes pass the centre ray at depth keys
///   `q = 1/depth` closer than what moving their vertices by the snap can change
///   (`|∇q|₁/256` each, in pixels), plus the tracer's own rounding.
pub fn raster_fixed(data: &[u8]) {
    let Some(RasterCase { extent, head, separation, tris, left, right }) = raster_case(data) else {
        return;
    };
    let run = |body, mut rasterizer: FixedRasterizer| {
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        let [l, r] = &mut out;
        let cams = [&left, &right];
        let result =
            rasterizer.rasterize(Triangles { main: &tris, extra: &[] }, cams, &NoMasks, RASTER_NEAR, [l, r], body);
        result.map(|_| out)
    };
    let small_bands = FixedRasterizer::with_band_rows(1 + (extent.width() + extent.height()) % 8);
    let (simd, scalar) = match (run(Body::Simd, small_bands), run(Body::Scalar, FixedRasterizer::new())) {
        (Ok(simd), Ok(scalar)) => (simd, scalar),
        (Err(a), Err(b)) => {
            assert_eq!(a, b, "the bodies refuse differently");
            return;
        }
        (a, b) => panic!("one body refuses: {:?} vs {:?}", a.err(), b.err()),
    };
    assert_eq!(simd, scalar, "the SIMD body and the scalar reference differ");
    for (vis, cam) in simd.iter().zip([&left, &right]) {
        for y in 0..extent.height() {
            for x in 0..extent.width() {
                let got = vis.prim.as_slice()[y * extent.width() + x];
                let (want, tracer_t) = closest(cam, &tris, x, y);
                assert!(
                    got == want
                        || near_plane_explains(cam, &tris, got, want, tracer_t, x, y)
                        || (got != NO_PRIM && guard_rejected(cam, &tris, got, x, y, tracer_t))
                        || snap_explains(cam, &tris, got, x, y)
                        || depth_tie_within_snap(cam, &tris, got, want, x, y),
                    "pixel ({x}, {y}) of {extent:?}: fixed raster {got}, tracer {want} (the tracer's t: {:?} and \
                     {:?}); camera {head:?}, separation {separation}, triangles {tris:?}",
                    tracer_hit(cam, &tris, got, x, y),
                    tracer_hit(cam, &tris, want, x, y),
                );
            }
        }
    }
}

/// The pixel ray through screen point `(px, py)` in f64: origin and unit-view-depth direction.
fn ray_f64(camera: &CameraModel, px: f64, py: f64) -> (DVec3, DVec3) {
    let v = |a: [f32; 3]| DVec3::from(Vec3::from(a));
    (v(camera.centre), v(camera.ray_origin_corner) + px * v(camera.ray_dx) + py * v(camera.ray_dy))
}

/// Exact geometry's answer at screen point `(px, py)`: the nearest triangle hit beyond the
/// near plane (Möller–Trumbore in f64, edges inclusive), the smaller id on equal depth.
fn exact_nearest_at(camera: &CameraModel, tris: &[TriVerts], px: f64, py: f64) -> u32 {
    let (o, d) = ray_f64(camera, px, py);
    let mut best = (f64::INFINITY, NO_PRIM);
    for (i, t) in tris.iter().enumerate() {
        if let Some(depth) = exact_hit(t, o, d)
            && depth < best.0
        {
            best = (depth, i as u32);
        }
    }
    best.1
}

/// Whether snapping explains the fixed raster's `got` at pixel `(x, y)`:
/// - exact geometry shows `got` from a point within the snap of the centre (sampled on
///   circles of 1/4, 1/2 and 1 snap), or
/// - every triangle exact geometry shows in front of `got` at the centre (all it shows there,
///   when `got` is none) has an edge within the snap of the centre, so its snapped image may
///   leave the centre out, or lies within the tracer's error of the near plane, and `got`
///   itself covers the centre or has an edge within the snap (two triangles meeting there
///   without sharing an edge may both be snapped off it).
fn snap_explains(camera: &CameraModel, tris: &[TriVerts], got: u32, x: usize, y: usize) -> bool {
    let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
    let sees = |px: f64, py: f64| exact_nearest_at(camera, tris, px, py) == got;
    let circles = [0.25, 0.5, 1.0].iter().any(|&r| {
        (0..16).any(|k| {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            sees(cx + r * SNAP_PX * a.cos(), cy + r * SNAP_PX * a.sin())
        })
    });
    if circles {
        return true;
    }
    let boundary = |t: &TriVerts| screen_boundary(camera, t, cx, cy);
    let got_depth = match tris.get(got as usize) {
        None => f64::INFINITY,
        Some(t) => match boundary(t) {
            // Covering the centre, or within the snap of doing so: its plane's depth there.
            Some((inside, dist)) if inside || dist <= SNAP_PX => match plane_depth(camera, t, cx, cy) {
                Some(depth) => depth,
                None => return false,
            },
            _ => return false,
        },
    };
    let (o, d) = ray_f64(camera, cx, cy);
    // A hit within the tracer's f32 error of the near plane may lie on its far side in exact
    // geometry and its near side in the raster's (as in [`near_plane_explains`]).
    let at_near_plane = |t: &TriVerts, depth: f64| depth < near_plane_band(o, t).1;
    tris.iter().enumerate().all(|(i, t)| {
        i as u32 == got
            || exact_hit(t, o, d).is_none_or(|depth| depth >= got_depth || at_near_plane(t, depth))
            || boundary(t).is_some_and(|(_, dist)| dist <= SNAP_PX)
            || tris.get(got as usize).is_some_and(|g| keys_tie(camera, g, t, cx, cy))
    })
}

/// Where the pixel ray through screen point `(cx, cy)` meets `tri`'s plane, in f64 and in the
/// units of the tracer's `t` (unit view depth; behind the eye when negative); `None` when not
/// finite (a degenerate triangle, or a ray parallel to the plane).
pub fn plane_depth(camera: &CameraModel, tri: &TriVerts, cx: f64, cy: f64) -> Option<f64> {
    let (o, d) = ray_f64(camera, cx, cy);
    let n = area_vector(tri);
    let depth = n.dot(vertex(tri, 0) - o) / n.dot(d);
    depth.is_finite().then_some(depth)
}

/// Möller–Trumbore in f64 (edges inclusive): the depth of `tri` along `o + t·d` beyond the
/// near plane, if hit.
fn exact_hit(t: &TriVerts, o: DVec3, d: DVec3) -> Option<f64> {
    let (e1, e2) = (vertex(t, 1) - vertex(t, 0), vertex(t, 2) - vertex(t, 0));
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = o - vertex(t, 0);
    let (u, q) = (s.dot(p) / det, s.cross(e1));
    let v = d.dot(q) / det;
    let depth = e2.dot(q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && depth > f64::from(RASTER_NEAR)).then_some(depth)
}

/// Whether `(cx, cy)` lies in `tri`'s screen image (its part in front of the near plane), and
/// its distance to the image's boundary. `None` when nothing of it is in front.
pub fn screen_boundary(camera: &CameraModel, tri: &TriVerts, cx: f64, cy: f64) -> Option<(bool, f64)> {
    let rows = camera.rows.map(|r| r.map(f64::from));
    let (hw, hh) = (camera.extent.width() as f64 * 0.5, camera.extent.height() as f64 * 0.5);
    let clip: Vec<[f64; 3]> = (0..3)
        .map(|k| {
            let p = vertex(tri, k);
            let dot = |r: &[f64; 4]| r[0] * p.x + r[1] * p.y + r[2] * p.z + r[3];
            [dot(&rows[0]), dot(&rows[1]), dot(&rows[3])]
        })
        .collect();
    let near = f64::from(RASTER_NEAR);
    let mut poly = Vec::new();
    for k in 0..3 {
        let (a, b) = (clip[k], clip[(k + 1) % 3]);
        if a[2] > near {
            poly.push(a);
        }
        if (a[2] > near) != (b[2] > near) {
            let s = (near - a[2]) / (b[2] - a[2]);
            poly.push([a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s, near]);
        }
    }
    if poly.len() < 3 || !poly.iter().flatten().all(|v| v.is_finite()) {
        return None;
    }
    let pts: Vec<[f64; 2]> = poly.iter().map(|c| [c[0] / c[2] * hw + hw, -c[1] / c[2] * hh + hh]).collect();
    let n = pts.len();
    let cross = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (cy - a[1]) - (b[1] - a[1]) * (cx - a[0]);
    let signs: Vec<f64> = (0..n).map(|k| cross(pts[k], pts[(k + 1) % n])).collect();
    let inside = signs.iter().all(|&s| s >= 0.0) || signs.iter().all(|&s| s <= 0.0);
    let dist = (0..n)
        .map(|k| {
            let (a, b) = (pts[k], pts[(k + 1) % n]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len2 = dx * dx + dy * dy;
            let s = if len2 > 0.0 { (((cx - a[0]) * dx + (cy - a[1]) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
            ((a[0] + s * dx - cx).powi(2) + (a[1] + s * dy - cy).powi(2)).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    Some((inside, dist))
}

/// `tri`'s plane as a depth key along the pixel rays: `q(px, py) = 1/depth`, linear in screen
/// space, and `|∂q/∂x| + |∂q/∂y|` (per pixel). `None` for a degenerate triangle or a plane
/// through the eye.
fn depth_key(camera: &CameraModel, tri: &TriVerts, px: f64, py: f64) -> Option<(f64, f64)> {
    let v = |a: [f32; 3]| DVec3::from(Vec3::from(a));
    let n = area_vector(tri);
    let c = n.dot(vertex(tri, 0) - v(camera.centre));
    if c == 0.0 || !c.is_finite() || n == DVec3::ZERO {
        return None;
    }
    let (_, d) = ray_f64(camera, px, py);
    let grad = (n.dot(v(camera.ray_dx)) / c).abs() + (n.dot(v(camera.ray_dy)) / c).abs();
    Some((n.dot(d) / c, grad))
}

/// Whether `got` and `want` are a depth tie at pixel `(x, y)` for the fixed rasteriser: their
/// planes' depth keys at the centre are closer than the snap can move them, plus the tracer's
/// rounding (relative `tracer_error / reach` of each).
fn depth_tie_within_snap(camera: &CameraModel, tris: &[TriVerts], got: u32, want: u32, x: usize, y: usize) -> bool {
    let (Some(a), Some(b)) = (tris.get(got as usize), tris.get(want as usize)) else { return false };
    keys_tie(camera, a, b, x as f64 + 0.5, y as f64 + 0.5)
}

/// Whether triangles `a` and `b` are a depth tie at screen point `(cx, cy)` for the fixed
/// rasteriser (see [`depth_tie_within_snap`]).
fn keys_tie(camera: &CameraModel, a: &TriVerts, b: &TriVerts, cx: f64, cy: f64) -> bool {
    let (Some((qa, ga)), Some((qb, gb))) = (depth_key(camera, a, cx, cy), depth_key(camera, b, cx, cy)) else {
        return false;
    };
    let eye = DVec3::from(Vec3::from(camera.centre));
    let rounding = |t: &TriVerts, q: f64| q * q * tracer_error(eye, t) + 1e-6 * q.abs();
    (qa - qb).abs() <= (ga + gb) * SNAP_PX + rounding(a, qa) + rounding(b, qb)
}

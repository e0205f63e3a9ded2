//! Reprojection on the geometry that breaks reprojection, against the analytic scene's own
//! ground truth (each target pixel's colour as the target camera sees it, ray-cast), with
//! the SIMD body and the scalar reference compared on each:
//!
//! * **grazing angles**: a floor seen at 89.9° and flatter from its normal, where one pixel
//!   row spans metres of depth: every sample the kernel accepts is the right colour;
//! * **points at and beyond the far plane** of the cameras' projection (1000 m): the kernel
//!   reprojects positions, not clip depths, so a wall at 999.99, 1000 and 5000 m moved by a
//!   whole number of pixels is copied exactly;
//! * **points behind the source camera** (the source moved past them): their projection
//!   lands mirrored inside the frame, and not one of them may be used.

use glam::Vec3;
use stereotrace_kernels::check::same_bits;
use stereotrace_kernels::frame::{Extent, RgbBuf};
use stereotrace_kernels::gbuffer::SurfaceLayout;
use stereotrace_kernels::reproject::{
    self, Reason, ReasonCounts, ReprojectInput, ReprojectOutput, ReprojectParams, TapPolicy, Tolerances,
};
use stereotrace_kernels::synth::{AnalyticScene, Rect, SynthFrame, Texture, camera_at, focal_pixels};

/// Reprojects `source` into `target` with both bodies; checks them equal bit for bit and
/// returns the colour, the reasons and the counts.
fn reproject_both<L: SurfaceLayout>(
    target: &L,
    source: &L,
    source_frame: &SynthFrame,
    policy: TapPolicy,
) -> (RgbBuf, Vec<u8>, ReasonCounts) {
    let e = target.extent();
    let params = ReprojectParams { tolerances: Tolerances::new(0.5, 0.03, 25.0), policy, band_rows: 3 };
    let input = ReprojectInput {
        target,
        source,
        source_camera: &source_frame.surfaces.camera,
        colour: source_frame.colour.view(),
        extra: None,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    };
    let run = |simd: bool| {
        let (mut colour, mut reason) = (RgbBuf::new(e, -7.0), stereotrace_kernels::PlaneBuf::new(e, 99u8));
        let out = ReprojectOutput { colour: colour.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
        let counts = if simd {
            reproject::reproject(&input, out, &params)
        } else {
            reproject::reproject_scalar(&input, out, &params)
        }
        .expect("valid input");
        (colour, reason, counts)
    };
    let (colour, reason, counts) = run(true);
    let (colour_ref, reason_ref, counts_ref) = run(false);
    assert_eq!((counts, &reason), (counts_ref, &reason_ref), "SIMD and scalar reasons differ");
    for (a, b) in colour.planes().into_iter().zip(colour_ref.planes()) {
        for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
            assert!(same_bits(*x, *y), "SIMD {x} vs scalar {y}");
        }
    }
    (colour, reason.as_slice().to_vec(), counts)
}

/// The floor's colour gradient per metre along x.
const SLOPE: [f32; 3] = [0.02, 0.01, -0.01];

#[test]
fn a_floor_at_grazing_angles_reprojects_to_the_right_colour_or_not_at_all() {
    // A horizontal camera 1 m above an endless floor, 2° field of view over 48 rows: the
    // rows just below the horizon meet the floor 0.02°..1° from grazing (89.98°..89°
    // from its normal), 57 m to 2.7 km away. The floor's colour is a ramp along x (the
    // stereo baseline's axis), so how far a sample's colour is from the target's own says
    // how far along the floor it came from.
    let e = Extent::new(64, 48).unwrap();
    let vfov = 2.0;
    let floor = AnalyticScene {
        rects: vec![Rect {
            centre: Vec3::new(0.0, -1.0, 0.0),
            axis_u: Vec3::X,
            axis_v: Vec3::Z,
            half: (1e5, 1e5),
            texture: Texture::ramp([0.5, 0.4, 0.3], SLOPE),
        }],
    };
    let baseline = 0.065;
    let left = floor.render(&camera_at(Vec3::new(-baseline / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let right = floor.render(&camera_at(Vec3::new(baseline / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    // The steepest visible row is 1° from grazing; the flattest within 0.03°.
    let angle = |y: usize| {
        let depth = left.surfaces.depth.as_slice()[y * e.width()];
        (1.0 / depth).atan().to_degrees()
    };
    assert!(angle(e.height() - 1) < 1.1 && angle(e.height() / 2) < 0.05, "{} {}", angle(e.height() - 1), angle(24));
    for policy in [TapPolicy::Strict, TapPolicy::Renormalize] {
        for (target, source, source_frame) in
            [(left.compact(), right.compact(), &right), (right.compact(), left.compact(), &left)]
        {
            let (colour, reason, counts) = reproject_both(&target, &source, source_frame, policy);
            let truth = if std::ptr::eq(source_frame, &right) { &left } else { &right };
            let mut grazing_accepted = 0;
            for y in 0..e.height() {
                for x in 0..e.width() {
                    let i = y * e.width() + x;
                    if reason[i] != Reason::Reprojected as u8 {
                        continue;
                    }
                    // A pixel spans `footprint` metres of floor across; the taps the position
                    // tolerance accepts lie within it, so a right sample's colour is within
                    // the ramp's change over one footprint (a tap from the next row, metres
                    // or kilometres away along the floor, is far outside it).
                    let depth = truth.surfaces.depth.as_slice()[i];
                    let footprint = 1.5 * depth * vfov.to_radians() / e.height() as f32;
                    let (got, want) = (colour.get(x, y), truth.colour.get(x, y));
                    for (c, slope) in SLOPE.iter().enumerate() {
                        assert!(
                            (got[c] - want[c]).abs() <= slope.abs() * footprint + 1e-4,
                            "{policy:?} ({x}, {y}) at {:.3}° from grazing, {depth} m away: {got:?} vs {want:?}",
                            angle(y)
                        );
                    }
                    grazing_accepted += usize::from(angle(y) <= 0.1);
                }
            }
            // Under the strict policy a tap from the next row (metres away at grazing angles)
            // fails the depth test and discards the pixel; renormalising keeps the taps of
            // the pixel's own row, so grazing samples must be accepted there, and right.
            if policy == TapPolicy::Renormalize {
                assert!(grazing_accepted > 64, "{policy:?}: {grazing_accepted} grazing samples accepted, {counts:?}");
            }
        }
    }
}

#[test]
fn walls_at_and_beyond_the_far_plane_move_by_whole_pixels_exactly() {
    let e = Extent::new(48, 20).unwrap();
    let vfov = 50.0;
    let f = focal_pixels(e, vfov);
    for z in [999.99f32, 1000.0, 1000.01, 5000.0] {
        let shift = 3;
        let b = (shift as f64 * f64::from(z) / f) as f32;
        let wall = AnalyticScene {
            rects: vec![Rect {
                centre: Vec3::new(0.0, 0.0, -z),
                axis_u: Vec3::X,
                axis_v: Vec3::Y,
                half: (1e6, 1e6),
                texture: Texture::pattern([0.5, 0.4, 0.3], 0.3, 0.01),
            }],
        };
        let left = wall.render(&camera_at(Vec3::new(-b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
        let right = wall.render(&camera_at(Vec3::new(b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
        let (colour, reason, _) = reproject_both(&left.compact(), &right.compact(), &right, TapPolicy::Strict);
        for y in 0..e.height() {
            for x in shift..e.width() {
                let i = y * e.width() + x;
                assert_eq!(reason[i], Reason::Reprojected as u8, "wall at {z} m: ({x}, {y})");
                assert_eq!(colour.get(x, y), right.colour.get(x - shift, y), "wall at {z} m: ({x}, {y})");
            }
        }
    }
}

#[test]
fn points_behind_the_source_camera_are_never_used() {
    // The target camera at the origin sees a wall 4 m ahead; the source camera stands 6 m
    // ahead (past the wall, looking the same way), so every target point is 2 m behind it.
    // Projected through the source camera they land mirrored, many of them inside the frame.
    let e = Extent::new(40, 24).unwrap();
    let wall = AnalyticScene {
        rects: vec![Rect {
            centre: Vec3::new(0.0, 0.0, -4.0),
            axis_u: Vec3::X,
            axis_v: Vec3::Y,
            half: (50.0, 50.0),
            texture: Texture::pattern([0.5, 0.4, 0.3], 0.3, 3.0),
        }],
    };
    let target = wall.render(&camera_at(Vec3::ZERO, e, 60.0), [0.0; 3]);
    // The source's G-buffer: another wall 3 m in front of it, so its depths are plausible.
    let ahead = AnalyticScene { rects: vec![Rect { centre: Vec3::new(0.0, 0.0, -9.0), ..wall.rects[0] }] };
    let source_camera = camera_at(Vec3::new(0.0, 0.0, -6.0), e, 60.0);
    let source = ahead.render(&source_camera, [0.0; 3]);
    let mirrored_inside = (0..e.pixels())
        .filter(|&i| {
            let p = Vec3::new(
                target.surfaces.position[0].as_slice()[i],
                target.surfaces.position[1].as_slice()[i],
                target.surfaces.position[2].as_slice()[i],
            );
            // The projection without the sign check: divide by w < 0 anyway.
            let [cx, cy, _, cw] = source_camera.clip(p.to_array());
            let (hw, hh) = source_camera.half_extent();
            let (sx, sy) = (cx / cw * hw + hw, -(cy / cw) * hh + hh);
            cw < 0.0 && (0.0..e.width() as f32).contains(&sx) && (0.0..e.height() as f32).contains(&sy)
        })
        .count();
    for policy in [TapPolicy::Strict, TapPolicy::Renormalize] {
        for layout in ["full", "compact"] {
            let (_, reason, counts) = if layout == "full" {
                reproject_both(&target.gbuffer(), &source.gbuffer(), &source, policy)
            } else {
                reproject_both(&target.compact(), &source.compact(), &source, policy)
            };
            assert_eq!(counts.get(Reason::Reprojected), 0, "{policy:?} {layout}: {counts:?}");
            assert!(reason.iter().all(|&r| r == Reason::OutOfFrame as u8), "{policy:?} {layout}: {counts:?}");
        }
    }
    // The case is real: a quarter of the points' mirrored projections land inside the frame.
    assert!(mirrored_inside > e.pixels() / 5, "{mirrored_inside} of {} mirrored into the frame", e.pixels());
}

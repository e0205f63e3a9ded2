//! BVH build and traversal against brute force.

use glam::Vec3;

use crate::simd::LANES;

use super::input::Bytes;

/// A coordinate: mostly on a coarse grid in [−1, 1] (so shared edges, coincident and
/// degenerate triangles and axis-aligned rays come up often), sometimes any f32.
fn coordinate(bytes: &mut Bytes<'_>) -> f32 {
    let b = bytes.u8();
    match b {
        0..=239 => f32::from(b % 17) / 8.0 - 1.0,
        240..=247 => bytes.unit(-1.0, 1.0),
        _ => bytes.f32(),
    }
}

/// Fuzzes BVH build and traversal: up to 48 triangles and 16 rays from the bytes. Checks the
/// single-ray closest hit against brute force (`t` bit for bit, the same triangle unless both
/// are hit at exactly that `t`), occlusion against the closest hit, and every lane of a
/// packet (at single-ray thresholds 0, 2 and 8) against its single ray. Builds that refuse
/// (non-finite or huge vertices) must say so with a `BvhError`.
pub fn traverse(data: &[u8]) {
    use crate::bvh::{BuildQuality, Hit, Ray, TriangleBvh};
    use crate::traverse::{PacketHits, RayPacket, intersect_brute_force};

    let mut bytes = Bytes(data);
    let quality = match bytes.u8() % 5 {
        0 => BuildQuality::Fast,
        1 => BuildQuality::Medium,
        2 => BuildQuality::High,
        3 => BuildQuality::Sah,
        _ => BuildQuality::SahSplits,
    };
    let n_tris = usize::from(bytes.u8() % 49);
    let n_rays = 1 + usize::from(bytes.u8() % 16);
    let vec = |bytes: &mut Bytes<'_>| Vec3::new(coordinate(bytes), coordinate(bytes), coordinate(bytes));
    let tris: Vec<[Vec3; 3]> = (0..n_tris).map(|_| [vec(&mut bytes), vec(&mut bytes), vec(&mut bytes)]).collect();
    let rays: Vec<Ray> = (0..n_rays)
        .map(|_| {
            let origin = vec(&mut bytes) * 2.0;
            let dir = vec(&mut bytes);
            let (tmin, tmax) = match bytes.u8() % 4 {
                0 => (0.0, f32::INFINITY),
                1 => (bytes.unit(0.0, 1.0), bytes.unit(0.0, 4.0)),
                2 => (bytes.f32(), bytes.f32()),
                _ => (1e-4, f32::INFINITY),
            };
            Ray { origin, dir, tmin, tmax }
        })
        .collect();
    let bvh = match TriangleBvh::build(&tris, quality) {
        Ok((bvh, _)) => bvh,
        Err(e) => {
            // Refused: only for vertices a build cannot take (NaN included: compared lane by
            // lane, as the build does; `max_element` would skip a NaN).
            let bound = Vec3::splat(crate::bvh::MAX_COORD);
            assert!(tris.iter().flatten().any(|v| !v.abs().cmple(bound).all()), "refused: {e}");
            return;
        }
    };
    let t_of = |prim: u32, ray: &Ray| intersect_brute_force(&tris[prim as usize..prim as usize + 1], ray).map(|h| h.t);
    let same = |a: Option<Hit>, b: Option<Hit>, ray: &Ray, what: &str| match (a, b) {
        (None, None) => {}
        (Some(x), Some(y)) => {
            assert_eq!(x.t.to_bits(), y.t.to_bits(), "{what}: t {} vs {} for {ray:?}", x.t, y.t);
            if x.prim == y.prim {
                assert_eq!((x.u.to_bits(), x.v.to_bits()), (y.u.to_bits(), y.v.to_bits()), "{what}: uv for {ray:?}");
            } else {
                assert_eq!(t_of(x.prim, ray), Some(x.t), "{what}: {} vs {} is not a tie", x.prim, y.prim);
                assert_eq!(t_of(y.prim, ray), Some(x.t), "{what}: {} vs {} is not a tie", x.prim, y.prim);
            }
        }
        _ => panic!("{what}: {a:?} vs {b:?} for {ray:?}"),
    };
    let singles: Vec<Option<Hit>> = rays.iter().map(|r| bvh.intersect(r)).collect();
    for (r, s) in rays.iter().zip(&singles) {
        same(*s, intersect_brute_force(&tris, r), r, "single ray vs brute force");
        assert_eq!(bvh.occluded(r), s.is_some(), "occlusion vs closest hit for {r:?}");
        // Occlusion with holes (every other triangle a hole where u < 0.5) against brute force:
        // any solid hit in the ray's interval.
        let solid = |prim: u32, u: f32, _: f32| prim % 2 == 1 || u >= 0.5;
        let want = (0..tris.len())
            .any(|i| intersect_brute_force(&tris[i..i + 1], r).is_some_and(|h| solid(i as u32, h.u, h.v)));
        assert_eq!(bvh.occluded_where(r, solid), want, "occlusion with holes for {r:?}");
        if let Some(h) = s {
            assert!(h.t.is_finite() && h.t >= r.tmin && h.t < r.tmax, "hit outside the ray's interval: {h:?} {r:?}");
        }
    }
    for (chunk, singles) in rays.chunks(LANES).zip(singles.chunks(LANES)) {
        let mut lanes = [Ray::new(Vec3::ZERO, Vec3::X); LANES];
        lanes[..chunk.len()].copy_from_slice(chunk);
        let active = (1u32 << chunk.len()) - 1;
        let packet = RayPacket::from_rays(&lanes);
        for threshold in [0, 2, 8] {
            let mut hits = PacketHits::NONE;
            let hit_mask = bvh.intersect_packet_with(&packet, active, &mut hits, threshold);
            let occluded = bvh.occluded_packet_with(&packet, active, threshold);
            for (i, s) in singles.iter().enumerate() {
                same(hits.get(i), *s, &chunk[i], "packet lane vs single ray");
                assert_eq!(hit_mask & (1 << i) != 0, s.is_some(), "packet hit mask lane {i}");
                assert_eq!(occluded & (1 << i) != 0, s.is_some(), "packet occlusion lane {i}");
            }
        }
    }
}

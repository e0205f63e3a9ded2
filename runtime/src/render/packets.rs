//! The path tracer's main loop: the estimator run on groups of up to eight pixels, stage
//! by stage, so that the coherent rays of a stage can be traced as one 8-lane packet.
//!
//! # Stages of one sample of a group
//! The selected pixels of a row are taken eight at a time (a sparse mask packs the selected
//! pixels of the row together, so packets stay full). For each sample index:
//!
//! 1. the eight jittered primary rays: one closest-hit packet (or, for a frame's first sample
//!    with [`PrimaryRays::CentreVisible`], the eight centre rays' hits read from the
//!    visibility buffer, and only the lanes it leaves undecided traced);
//! 2. per lane: emission seen, shading, the light sample of next-event estimation (shadow
//!    ray 1) and the BSDF sample (the secondary ray);
//! 3. shadow rays 1: one occlusion packet;
//! 4. the secondary rays: single rays;
//! 5. per lane: emission reached after a delta lobe, shading, shadow ray 2;
//! 6. shadow rays 2: single rays.
//!
//! Which stages use packets was measured (see [`PRIMARY`] and the constants after it): rays
//! that start at scattered points or leave in scattered directions fall into many direction
//! classes, and packets of them cost more than single rays.
//!
//! Every lane performs exactly the operations of [`Renderer::radiance`] (the single-ray
//! reference) in the same order, on the same random numbers; packets return the same hits
//! as single rays bit for bit except which triangle wins an exact tie in `t`. So the image
//! equals the reference's except at such ties (tested).
//!
//! Cut-outs (alpha masks) are skipped as in the reference, by re-tracing the lanes that hit
//! one from just past the hit (`t.next_up()`), as a packet of those lanes. Moving lights
//! (not in the BVH) are tested per lane after the packet, as in the reference. Invalid rays
//! (NaN, zero direction) drop out of the packet's active mask and report a miss, as single
//! rays do.

use glam::Vec3;

use super::bsdf::{self, BsdfSample};
use super::effects::{self, ALPHA_MASKS, MIRROR, MOVING_GEOMETRY, has};
use super::estimator::Surface;
use super::lights::FrameLights;
use super::raster::Visible;
use super::renderer::Renderer;
use super::rng::{Dim, SampleStream};
use super::spawn;
use super::trace::PrimaryRays;
use crate::kernels::CameraModel;
use crate::kernels::bvh::{Hit, Ray};
use crate::kernels::simd::{F32s, LANES};
use crate::kernels::traverse::{PacketHits, RayPacket};
use crate::scene::MaterialKind;
use crate::source::TraceRequest;

/// What a group's samples share: the frame's lights, the camera and the request.
pub(super) struct Pass<'a> {
    pub lights: &'a FrameLights,
    pub camera: &'a CameraModel,
    pub request: &'a TraceRequest,
    pub primary: PrimaryRays<'a>,
}

/// The single-ray threshold of each stage's packets: a class of lanes (same direction
/// octant and dominant axis) with at most this many lanes is traced as single rays;
/// [`SINGLE_RAYS`] skips the packet kernel and traces every lane alone.
///
/// Chosen by instruction counts of whole renders (callgrind, deterministic: 320×180, 1 spp,
/// atrium, living-room, classroom, courtyard and Sponza), each stage varied alone, and
/// checked with thread CPU time (best of 7–9 interleaved runs at 640×360; the machine is
/// shared, so times vary ±10 % and only confirmed the direction). Primary rays of eight
/// neighbouring pixels are coherent: packets save 8–11 % of all instructions of a render.
pub(super) const PRIMARY: u32 = crate::kernels::traverse::SINGLE_RAY_THRESHOLD;
/// Shadow rays from the primary hits: coherent toward a sun, much less toward several area
/// lights (each lane picks its own light). Threshold 4 is the compromise: against 2 it saves
/// 0–4 % of the instructions (atrium 4.1 %); against single rays it saves 0.8 % on the
/// sun-lit scenes and costs 0.5–1.5 % on the area-lit ones.
pub(super) const SHADOW_1: u32 = 4;
/// Secondary (BSDF-sampled) rays scatter over the hemisphere, so a group's lanes fall into
/// many classes: packets with threshold 4 / 2 cost 1 % / 3 % more instructions than single
/// rays.
pub(super) const SECONDARY: u32 = SINGLE_RAYS;
/// Shadow rays from the secondary hits start anywhere: packets with threshold 4 / 2 cost
/// 0.5–1 % / 1–3 % more.
pub(super) const SHADOW_2: u32 = SINGLE_RAYS;
/// A threshold that traces every lane as a single ray.
pub(super) const SINGLE_RAYS: u32 = LANES as u32;

/// A placeholder for lanes that carry no ray (never traced: they are outside the mask).
const NO_RAY: Ray = Ray { origin: Vec3::ZERO, dir: Vec3::Z, tmin: 0.0, tmax: f32::INFINITY };
const NO_BOUNCE: BsdfSample = BsdfSample { wi: Vec3::Z, weight: Vec3::ZERO, delta: false };

/// Indices of the set bits of `mask`, lowest first.
#[inline(always)]
pub(super) fn lanes(mask: u32) -> impl Iterator<Item = usize> {
    let mut m = mask;
    core::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

impl Renderer {
    /// [`Renderer::closest`] for the lanes `active` of `rays`: one packet whose classes of at
    /// most `threshold` lanes continue as single rays (see [`PRIMARY`]); [`SINGLE_RAYS`] traces
    /// every lane alone.
    #[inline]
    pub(super) fn closest_packet<const E: u16>(
        &self,
        lights: &FrameLights,
        rays: &[Ray; LANES],
        active: u32,
        threshold: u32,
    ) -> [Option<Surface>; LANES] {
        if threshold >= SINGLE_RAYS {
            let mut out = [None; LANES];
            for i in lanes(active) {
                out[i] = self.closest::<E>(lights, rays[i]);
            }
            return out;
        }
        let mut packet = RayPacket::from_rays(rays);
        let mut hits = PacketHits::NONE;
        let hit = self.bvh.intersect_packet_with(&packet, active, &mut hits, threshold);
        if has(E, ALPHA_MASKS) {
            self.skip_cut_outs(&mut packet, hit, &mut hits, threshold);
        }
        let mut out = [None; LANES];
        for i in lanes(active) {
            let mesh = hits.get(i).map(Surface::Mesh);
            out[i] = mesh;
            if has(E, MOVING_GEOMETRY) {
                let tmax = mesh.map_or(rays[i].tmax, |s| s.t());
                if let Some(light) = Self::closest_moving(lights, &rays[i], tmax) {
                    out[i] = Some(light);
                }
            }
        }
        out
    }

    /// [`Renderer::occluded`] for the lanes `active` of `rays` (the mask of blocked lanes),
    /// traced like [`Renderer::closest_packet`].
    #[inline]
    pub(super) fn occluded_packet<const E: u16>(
        &self,
        lights: &FrameLights,
        rays: &[Ray; LANES],
        active: u32,
        threshold: u32,
    ) -> u32 {
        // With cut-outs, each lane's any-hit search that skips the holes (the reference's):
        // a packet would have to find each lane's closest hit and restart past every hole.
        if threshold >= SINGLE_RAYS || has(E, ALPHA_MASKS) {
            return lanes(active).filter(|&i| self.occluded::<E>(lights, rays[i])).fold(0, |m, i| m | 1 << i);
        }
        if active == 0 {
            return 0;
        }
        let packet = RayPacket::from_rays(rays);
        let mut blocked = self.bvh.occluded_packet_with(&packet, active, threshold);
        if has(E, MOVING_GEOMETRY) {
            for i in lanes(active & !blocked) {
                if Self::closest_moving(lights, &rays[i], rays[i].tmax).is_some() {
                    blocked |= 1 << i;
                }
            }
        }
        blocked
    }

    /// Continues the lanes `hit` of `packet` whose closest hit is cut away, from just past
    /// it, until each lane has an opaque hit or none ([`Renderer::closest_mesh`] per lane).
    pub(super) fn skip_cut_outs(&self, packet: &mut RayPacket, hit: u32, hits: &mut PacketHits, threshold: u32) {
        let tmax = packet.tmax.to_array();
        let mut tmin = packet.tmin.to_array();
        let mut pending = hit;
        loop {
            let mut again = 0;
            for i in lanes(pending) {
                let Some(h) = hits.get(i) else { continue };
                if !self.cut_out(&h) {
                    continue;
                }
                tmin[i] = h.t.next_up();
                if tmin[i] < tmax[i] {
                    again |= 1 << i;
                } else {
                    let none = Hit::NONE;
                    (hits.t[i], hits.prim[i], hits.u[i], hits.v[i]) = (none.t, none.prim, none.u, none.v);
                }
            }
            if again == 0 {
                return;
            }
            packet.tmin = F32s::from(tmin);
            pending = self.bvh.intersect_packet_with(packet, again, hits, threshold);
        }
    }

    /// One sample (index `sample` of the request) of the estimator for the pixels
    /// `(xs[i], y)` of the lanes `active`; inactive lanes return zero. Adds the rays traced
    /// to `rays`.
    #[inline]
    pub(super) fn sample_group<const E: u16>(
        &self,
        pass: &Pass<'_>,
        y: usize,
        xs: &[usize; LANES],
        active: u32,
        sample: u32,
        rays: &mut u64,
    ) -> [Vec3; LANES] {
        let Pass { lights, camera, request, primary: first_sample } = *pass;
        let width = camera.extent.width();
        let count = |m: u32| u64::from(m.count_ones());
        let mut radiance = [Vec3::ZERO; LANES];

        // 1. Primary rays.
        let rng: [SampleStream; LANES] = core::array::from_fn(|i| {
            let pixel = (y * width + xs[i]) as u32;
            SampleStream::new(request.seed, request.eye as u32, request.frame, pixel, request.first_sample + sample)
        });
        let origin = Vec3::from(camera.centre);
        let centred = first_sample.centred(request.first_sample + sample);
        let primary: [Ray; LANES] = core::array::from_fn(|i| {
            let j = first_sample.pixel_offset(request.first_sample + sample, &rng[i]);
            Ray::new(origin, Vec3::from(camera.ray(xs[i] as f32 + j.x, y as f32 + j.y)))
        });
        let first = match first_sample {
            PrimaryRays::CentreVisible(vis) if centred => {
                let prims = vis.prim.view();
                let mut first = [None; LANES];
                let mut undecided = 0u32;
                for i in lanes(active) {
                    match self.visible_surface(lights, prims.get(xs[i], y), &primary[i]) {
                        Visible::Surface(s) => first[i] = Some(s),
                        Visible::Nothing => {}
                        Visible::Undecided => undecided |= 1 << i,
                    }
                }
                if undecided != 0 {
                    *rays += count(undecided);
                    let traced = self.closest_packet::<E>(lights, &primary, undecided, PRIMARY);
                    for i in lanes(undecided) {
                        first[i] = traced[i];
                    }
                }
                first
            }
            _ => {
                *rays += count(active);
                self.closest_packet::<E>(lights, &primary, active, PRIMARY)
            }
        };

        // 2. Shading at the primary hits: shadow rays 1 and the secondary rays.
        let mut shadow = [NO_RAY; LANES];
        let mut carried = [Vec3::ZERO; LANES];
        // Lanes that add a next-event estimate (possibly zero), and those that trace its ray.
        let (mut nee, mut traced) = (0u32, 0u32);
        let mut bounce = [NO_BOUNCE; LANES];
        let mut secondary = [NO_RAY; LANES];
        let mut bounced = 0u32;
        for i in lanes(active) {
            let dir = primary[i].dir.normalize();
            let Some(surface) = first[i] else {
                radiance[i] = self.escaped(dir);
                continue;
            };
            radiance[i] = self.emitted(&surface, dir);
            let Some(sp) = self.shade_surface::<E>(lights, &surface, dir) else { continue };
            let wo = -dir;
            if !(sp.kind == MaterialKind::Mirror && has(E, MIRROR)) {
                nee |= 1 << i;
                let dims = (Dim::LightPick1, Dim::LightPoint1);
                if let Some((ray, c)) = self.light_sample::<E>(lights, &sp, wo, &rng[i], dims) {
                    (shadow[i], carried[i]) = (ray, c);
                    traced |= 1 << i;
                }
            }
            if self.bounces == 0 {
                continue;
            }
            if let Some(b) = bsdf::sample::<E>(&sp, wo, rng[i].get(Dim::Lobe), rng[i].get2(Dim::Bounce)) {
                bounce[i] = b;
                let origin = spawn::offset_origin(sp.position, sp.position_error, sp.geometric_normal, b.wi);
                secondary[i] = Ray::new(origin, b.wi);
                bounced |= 1 << i;
            }
        }

        // 3. Shadow rays 1.
        *rays += count(traced);
        let visible = traced & !self.occluded_packet::<E>(lights, &shadow, traced, SHADOW_1);
        for i in lanes(nee) {
            radiance[i] += if visible & (1 << i) != 0 { carried[i] } else { Vec3::ZERO };
        }

        // 4. Secondary rays.
        *rays += count(bounced);
        let second = self.closest_packet::<E>(lights, &secondary, bounced, SECONDARY);

        // 5. Shading at the secondary hits: shadow rays 2.
        (nee, traced) = (0, 0);
        for i in lanes(bounced) {
            let b = &bounce[i];
            let Some(surface) = second[i] else {
                if b.delta {
                    radiance[i] += b.weight * self.escaped(b.wi);
                }
                continue;
            };
            if b.delta {
                radiance[i] += b.weight * self.emitted(&surface, b.wi);
            }
            let Some(sp) = self.shade_surface::<E>(lights, &surface, b.wi) else { continue };
            if !(sp.kind == MaterialKind::Mirror && has(E, effects::MIRROR)) {
                nee |= 1 << i;
                let dims = (Dim::LightPick2, Dim::LightPoint2);
                if let Some((ray, c)) = self.light_sample::<E>(lights, &sp, -b.wi, &rng[i], dims) {
                    (shadow[i], carried[i]) = (ray, c);
                    traced |= 1 << i;
                }
            }
        }

        // 6. Shadow rays 2.
        *rays += count(traced);
        let visible = traced & !self.occluded_packet::<E>(lights, &shadow, traced, SHADOW_2);
        for i in lanes(nee) {
            let estimate = if visible & (1 << i) != 0 { carried[i] } else { Vec3::ZERO };
            radiance[i] += bounce[i].weight * estimate;
        }
        radiance
    }
}

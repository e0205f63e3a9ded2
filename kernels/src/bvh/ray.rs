//! Rays: the caller's [`Ray`], its closest [`Hit`], and the per-ray constants
//! ([`PreparedRay`]) that the node tests and the watertight triangle test share. The limits
//! on coordinates and directions that keep every quantity of those tests finite are here
//! (see the notes of [`crate::bvh`]).

use glam::{Vec3, Vec3A};

/// Largest accepted `|coordinate|` of a triangle vertex (2²⁴ m ≈ 16 800 km).
pub const MAX_COORD: f32 = 16_777_216.0;
/// Largest accepted `|coordinate|` of a ray origin (2²⁶ m); rays starting farther away miss.
pub const MAX_ORIGIN: f32 = 67_108_864.0;
/// Smallest accepted largest-direction-component magnitude (2⁻³²).
pub const MIN_DIR: f32 = 1.0 / 4_294_967_296.0;
/// Largest accepted direction component magnitude (2³²).
pub const MAX_DIR: f32 = 4_294_967_296.0;

/// Components of a direction below this magnitude use `±1/RCP_CLAMP` as their reciprocal.
pub(crate) const RCP_CLAMP: f32 = f32::from_bits((127 - 80) << 23); // 2^-80

/// Relative widening of every slab interval (see "Robust node test" in [`crate::bvh`]).
pub(crate) const NODE_PAD: f32 = f32::from_bits((127 - 20) << 23); // 2^-20

/// A triangle as three vertices (counter-clockwise winding gives the front face, though both
/// faces are hit).
pub type Tri = [Vec3; 3];

/// A ray `origin + t·dir` for `t ∈ [tmin, tmax)`. `dir` need not be normalised; `t` is in
/// units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction (any non-zero length).
    pub dir: Vec3,
    /// Nearest accepted `t`.
    pub tmin: f32,
    /// Farthest `t` (exclusive): a hit must be nearer.
    pub tmax: f32,
}

impl Ray {
    /// An infinite ray (`tmin = 0`, `tmax = inf`).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir, tmin: 0.0, tmax: f32::INFINITY }
    }

    /// A ray restricted to `[tmin, tmax)`.
    #[inline]
    pub fn segment(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Self { origin, dir, tmin, tmax }
    }

    /// Whether queries trace this ray; an invalid ray is reported as a miss. Valid: every
    /// origin coordinate finite with magnitude ≤ [`MAX_ORIGIN`]; every direction component
    /// finite, at least one of magnitude ≥ [`MIN_DIR`] and none above [`MAX_DIR`];
    /// `0 ≤ tmin < tmax` with `tmin` finite (`tmax` may be `+inf`). NaN anywhere is invalid.
    #[inline]
    pub fn is_valid(&self) -> bool {
        let o = self.origin.abs();
        let d = self.dir.abs();
        // Written so that NaN fails every comparison.
        let origin_ok = o.x <= MAX_ORIGIN && o.y <= MAX_ORIGIN && o.z <= MAX_ORIGIN;
        let dir_ok = d.x <= MAX_DIR && d.y <= MAX_DIR && d.z <= MAX_DIR && d.max_element() >= MIN_DIR;
        let t_ok = self.tmin >= 0.0 && self.tmin < f32::INFINITY && self.tmin < self.tmax;
        origin_ok && dir_ok && t_ok
    }
}

/// A closest hit: distance, the caller's triangle index and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit (in units of the ray's direction).
    pub t: f32,
    /// Index into the triangle list the BVH was built from.
    pub prim: u32,
    /// Weight of `v1`.
    pub u: f32,
    /// Weight of `v2`.
    pub v: f32,
}

impl Hit {
    /// The "no hit" record (`prim == u32::MAX`, `t = inf`).
    pub const NONE: Hit = Hit { t: f32::INFINITY, prim: u32::MAX, u: 0.0, v: 0.0 };

    /// Whether this is a hit (not [`Hit::NONE`]).
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.prim != u32::MAX
    }
}

/// Per-ray constants shared by the node test and the watertight triangle test. One lane of a
/// packet holds exactly these values, so packet and single-ray arithmetic are identical.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedRay {
    /// The ray's origin.
    pub origin: Vec3A,
    /// Safe reciprocal of the direction (never 0, inf or NaN).
    pub inv: Vec3A,
    /// `NODE_PAD · |inv|` per axis: the slab widening per unit of `|p − o| + 255·e`.
    pub pad: Vec3A,
    /// obvhs's inverted octant: bit 2/1/0 set when `inv.x/y/z` is positive. Children are
    /// visited in descending `slot ^ oct_inv` order (front to back for this octant).
    pub oct_inv: u32,
    /// Axis permutation of the watertight test: `kz` is the dominant direction axis.
    pub k: [usize; 3],
    /// Shear constants `(d[kx]/d[kz], d[ky]/d[kz], 1/d[kz])`.
    pub shear: [f32; 3],
    /// The origin permuted: `(o[kx], o[ky], o[kz])`.
    pub origin_k: [f32; 3],
    /// Nearest accepted `t`.
    pub tmin: f32,
    /// Farthest `t` (exclusive); closest-hit traversal shrinks it.
    pub tmax: f32,
}

/// Reciprocal that is never 0, infinite or NaN for finite input (see the module notes).
#[inline(always)]
pub fn safe_rcp(d: f32) -> f32 {
    if d.abs() < RCP_CLAMP { (1.0 / RCP_CLAMP).copysign(d) } else { 1.0 / d }
}

impl PreparedRay {
    /// `None` for an invalid ray (see [`Ray::is_valid`]).
    #[inline]
    pub fn new(ray: &Ray) -> Option<Self> {
        let mut r = Self::for_triangles(ray)?;
        // `safe_rcp` on all three components with one vector division (the same bits: both
        // divisions round correctly, and the clamped lanes take the same signed constant).
        let d = Vec3A::from(ray.dir);
        let clamped = d.abs().cmplt(Vec3A::splat(RCP_CLAMP));
        r.inv = Vec3A::select(clamped, Vec3A::splat(1.0 / RCP_CLAMP).copysign(d), Vec3A::ONE / d);
        r.pad = NODE_PAD * r.inv.abs();
        let inv = r.inv.to_array();
        r.oct_inv = (if inv[0] < 0.0 { 0 } else { 4 })
            | (if inv[1] < 0.0 { 0 } else { 2 })
            | (if inv[2] < 0.0 { 0 } else { 1 });
        Some(r)
    }

    /// The fields [`intersect_triangle`](crate::bvh::intersect_triangle) reads (axis permutation, shear, origin, `t` range)
    /// without the node test's reciprocals ([`PreparedRay::new`] adds them): for callers
    /// that test single triangles (the rasteriser's exact path). `None` for an invalid ray.
    #[inline]
    pub fn for_triangles(ray: &Ray) -> Option<Self> {
        if !ray.is_valid() {
            return None;
        }
        let o = ray.origin.to_array();
        let d = ray.dir.to_array();
        let a = d.map(f32::abs);
        let kz = if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding (and so the sign convention of the edge functions) per ray.
        if d[kz] < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        Some(Self {
            origin: Vec3A::from_array(o),
            inv: Vec3A::ZERO,
            pad: Vec3A::ZERO,
            oct_inv: 0,
            k: [kx, ky, kz],
            // One vector division, the same bits as three scalar ones.
            shear: (Vec3A::new(d[kx], d[ky], 1.0) / Vec3A::splat(d[kz])).to_array(),
            origin_k: [o[kx], o[ky], o[kz]],
            tmin: ray.tmin,
            tmax: ray.tmax,
        })
    }

    /// Dominant-axis class used to group packet lanes: `oct_inv | kz << 3` (0..24). Lanes
    /// of one class share the node-test plane choice and the triangle-test permutation.
    #[inline]
    pub fn class(&self) -> u32 {
        self.oct_inv | ((self.k[2] as u32) << 3)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use proptest::prelude::*;

    use super::super::wide::SlabOrigins;
    use super::*;

    /// A direction component: ordinary values, and the edges of the reciprocal's clamp
    /// (signed zeros, values just either side of `RCP_CLAMP`, the largest allowed).
    fn component() -> impl Strategy<Value = f32> {
        prop_oneof![
            -1.0e3f32..1.0e3,
            Just(0.0),
            Just(-0.0),
            Just(RCP_CLAMP),
            Just(-RCP_CLAMP),
            Just(f32::from_bits(RCP_CLAMP.to_bits() - 1)),
            Just(-f32::from_bits(RCP_CLAMP.to_bits() + 1)),
            Just(MAX_DIR),
            Just(-1.0e-30),
        ]
    }

    proptest! {
        /// The ray setup's vector arithmetic against the scalar formulas it replaced, bit for
        /// bit: the reciprocals, their pads, the octant, the shear, and the slab origins.
        #[test]
        fn ray_setup_equals_the_scalar_formulas(
            d in (component(), component(), component()),
            o in (-1.0e4f32..1.0e4, -1.0e4f32..1.0e4, -1.0e4f32..1.0e4),
            lo in (-1.0e4f32..0.0, -1.0e4f32..0.0, -1.0e4f32..0.0),
            size in (0.0f32..1.0e4, 0.0f32..1.0e4, 0.0f32..1.0e4),
        ) {
            let ray = Ray::segment(Vec3::new(o.0, o.1, o.2), Vec3::new(d.0, d.1, d.2), 0.0, f32::INFINITY);
            let Some(r) = PreparedRay::new(&ray) else {
                prop_assert!(!ray.is_valid());
                return Ok(());
            };
            let (d, o) = (ray.dir.to_array(), ray.origin.to_array());
            let inv = d.map(safe_rcp);
            prop_assert_eq!(r.inv.to_array().map(f32::to_bits), inv.map(f32::to_bits));
            prop_assert_eq!(r.pad.to_array().map(f32::to_bits), inv.map(|i| (NODE_PAD * i.abs()).to_bits()));
            let oct = (if inv[0] < 0.0 { 0 } else { 4 }) | (if inv[1] < 0.0 { 0 } else { 2 }) | (if inv[2] < 0.0 { 0 } else { 1 });
            prop_assert_eq!(r.oct_inv, oct);
            let [kx, ky, kz] = r.k;
            let shear = [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]];
            prop_assert_eq!(r.shear.map(f32::to_bits), shear.map(f32::to_bits));

            let bounds = [[lo.0, lo.1, lo.2], [lo.0 + size.0, lo.1 + size.1, lo.2 + size.2]];
            let reach = (0..3).fold(0.0f32, |m, k| {
                m.max((bounds[0][k] - o[k]).abs()).max((bounds[1][k] - o[k]).abs()).max(o[k].abs())
            });
            let shift = reach * crate::bvh::wide::POSITION_PAD;
            let slab = SlabOrigins::new(&r, &bounds);
            prop_assert_eq!(slab.near.map(f32::to_bits), [0, 1, 2].map(|k| (o[k] + shift.copysign(inv[k])).to_bits()));
            prop_assert_eq!(slab.far.map(f32::to_bits), [0, 1, 2].map(|k| (o[k] - shift.copysign(inv[k])).to_bits()));
        }
    }
}

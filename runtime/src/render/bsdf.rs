//! Materials as the integrator sees them: evaluation and sampling of the three lobes.
//!
//! * **Diffuse**: Lambert, `f = albedo / π`, sampled by the cosine-weighted hemisphere.
//! * **Glossy**: Lambert plus a GGX microfacet lobe with Schlick Fresnel (`F0 = Ks`,
//!   `α = roughness²`) and the separable Smith shadowing term. Sampled by picking a lobe with
//!   probability proportional to its reflectance (clamped to [0.1, 0.9]) and weighting by the
//!   mixture pdf, so the estimate stays unbiased whichever lobe produced the direction.
//! * **Mirror**: a delta reflection of reflectance `Ks`. Next-event estimation cannot sample
//!   it, so its contribution comes from what the reflected ray hits (see the integrator).
//!
//! Whether the glossy and mirror code exists at all is decided by the effect bits `E` of the
//! integrator (see [`super::effects`]): with the bit clear the branch is compiled out and a
//! material of that kind cannot occur (the scene's effect set covers its content).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::effects::{GLOSSY, MIRROR, has};
use crate::scene::MaterialKind;

/// Everything shading needs about a surface point. Normals face the side the ray came from.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    /// World position of the point.
    pub position: Vec3,
    /// Per-axis bound on the rounding error of `position` (see [`super::spawn`]).
    pub position_error: Vec3,
    /// Unit geometric normal, on the incoming side.
    pub geometric_normal: Vec3,
    /// Unit shading normal (interpolated), on the same side as `geometric_normal`.
    pub shading_normal: Vec3,
    /// Which BSDF.
    pub kind: MaterialKind,
    /// Diffuse albedo after texturing.
    pub albedo: Vec3,
    /// Specular reflectance at normal incidence.
    pub specular: Vec3,
    /// GGX width `α`.
    pub alpha: f32,
}

/// A sampled direction and its weight `f · |cos θ| / pdf`.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Unit direction of the sampled incoming light.
    pub wi: Vec3,
    /// `f · |cos θ| / pdf` per colour channel.
    pub weight: Vec3,
    /// True for a delta lobe (mirror): next-event estimation could not have sampled it.
    pub delta: bool,
}

/// An orthonormal basis around `n` (Duff et al. 2017, branchless).
#[inline]
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Cosine-weighted direction around `n` (pdf `cos θ / π`).
#[inline]
pub fn cosine_hemisphere(n: Vec3, u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let (t, b) = basis(n);
    let z = (1.0 - u.x).max(0.0).sqrt();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalize()
}

/// The mirror direction of `wo` about `n`.
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    2.0 * wo.dot(n) * n - wo
}

fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (Vec3::ONE - f0) * (m2 * m2 * m)
}

fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

fn smith_g1(alpha: f32, cos: f32) -> f32 {
    let a2 = alpha * alpha;
    2.0 * cos / (cos + (a2 + (1.0 - a2) * cos * cos).sqrt())
}

/// Probability of sampling the glossy lobe of a glossy material.
fn glossy_probability(sp: &ShadingPoint) -> f32 {
    let s = sp.specular.max_element();
    let d = sp.albedo.max_element();
    if s + d <= 0.0 { 0.5 } else { (s / (s + d)).clamp(0.1, 0.9) }
}

/// The GGX lobe's value and its sampling pdf (solid angle) for `wo → wi`.
fn ggx(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    let n = sp.shading_normal;
    let (cos_o, cos_i) = (n.dot(wo), n.dot(wi));
    if cos_o <= 0.0 || cos_i <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let h = (wo + wi).normalize();
    let cos_h = n.dot(h).max(0.0);
    let d = ggx_d(sp.alpha, cos_h);
    let g = smith_g1(sp.alpha, cos_o) * smith_g1(sp.alpha, cos_i);
    let f = schlick(sp.specular, wo.dot(h));
    let value = f * (d * g / (4.0 * cos_o * cos_i));
    let pdf = d * cos_h / (4.0 * wo.dot(h).abs().max(1e-8));
    (value, pdf)
}

/// `f(wo, wi)` for the non-delta lobes (zero for mirrors and for `wi` below the surface).
#[inline]
pub fn eval<const E: u16>(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Vec3 {
    if sp.geometric_normal.dot(wi) <= 0.0 || sp.shading_normal.dot(wi) <= 0.0 {
        return Vec3::ZERO;
    }
    match sp.kind {
        MaterialKind::Glossy if has(E, GLOSSY) => sp.albedo * (1.0 / PI) + ggx(sp, wo, wi).0,
        MaterialKind::Mirror if has(E, MIRROR) => Vec3::ZERO,
        _ => sp.albedo * (1.0 / PI),
    }
}

/// Samples the secondary direction. `u_lobe` picks the lobe, `u` the direction.
#[inline]
pub fn sample<const E: u16>(sp: &ShadingPoint, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
    let n = sp.shading_normal;
    match sp.kind {
        MaterialKind::Mirror if has(E, MIRROR) => {
            let wi = reflect(wo, n);
            (sp.geometric_normal.dot(wi) > 0.0).then_some(BsdfSample { wi, weight: sp.specular, delta: true })
        }
        MaterialKind::Glossy if has(E, GLOSSY) => {
            let p_glossy = glossy_probability(sp);
            let wi = if u_lobe < p_glossy {
                // GGX half-vector: tan²θ = α²·u/(1 − u).
                let a2 = sp.alpha * sp.alpha;
                let cos2 = (1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x);
                let cos_h = cos2.max(0.0).sqrt();
                let sin_h = (1.0 - cos2).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let (t, b) = basis(n);
                let h = (t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + n * cos_h).normalize();
                reflect(wo, h)
            } else {
                cosine_hemisphere(n, u)
            };
            let cos_i = n.dot(wi);
            if cos_i <= 0.0 || sp.geometric_normal.dot(wi) <= 0.0 {
                return None;
            }
            let (spec, spec_pdf) = ggx(sp, wo, wi);
            let pdf = p_glossy * spec_pdf + (1.0 - p_glossy) * cos_i / PI;
            if !(pdf > 0.0) {
                return None;
            }
            let f = sp.albedo * (1.0 / PI) + spec;
            Some(BsdfSample { wi, weight: f * (cos_i / pdf), delta: false })
        }
        _ => {
            let wi = cosine_hemisphere(n, u);
            // f·cos/pdf = (albedo/π)·cos/(cos/π) = albedo.
            (sp.geometric_normal.dot(wi) > 0.0).then_some(BsdfSample { wi, weight: sp.albedo, delta: false })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::effects::ALL;

    fn point(kind: MaterialKind) -> ShadingPoint {
        ShadingPoint {
            position_error: Vec3::ZERO,
            position: Vec3::ZERO,
            geometric_normal: Vec3::Z,
            shading_normal: Vec3::Z,
            kind,
            albedo: Vec3::splat(0.5),
            specular: Vec3::splat(0.04),
            alpha: 0.3,
        }
    }

    /// Monte Carlo estimate of ∫ f cos dω by the sampler, against a stratified quadrature.
    #[test]
    fn sampling_weights_are_unbiased_for_each_lobe() {
        for kind in [MaterialKind::Diffuse, MaterialKind::Glossy] {
            let sp = point(kind);
            let wo = Vec3::new(0.3, 0.1, 0.95).normalize();
            let n = 200_000;
            let mut mc = Vec3::ZERO;
            for i in 0..n {
                let s = crate::render::rng::SampleStream::new(3, 0, 0, i, 0);
                if let Some(b) = sample::<ALL>(
                    &sp,
                    wo,
                    s.get(crate::render::rng::Dim::Lobe),
                    s.get2(crate::render::rng::Dim::Bounce),
                ) {
                    mc += b.weight;
                }
            }
            mc /= n as f32;
            // Quadrature over the hemisphere in (cos θ, φ).
            let (nt, np) = (400, 400);
            let mut quad = Vec3::ZERO;
            for a in 0..nt {
                for b in 0..np {
                    let cos_t = (a as f32 + 0.5) / nt as f32;
                    let phi = 2.0 * PI * (b as f32 + 0.5) / np as f32;
                    let sin_t = (1.0 - cos_t * cos_t).sqrt();
                    let wi = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
                    quad += eval::<ALL>(&sp, wo, wi) * cos_t * (2.0 * PI / (nt * np) as f32);
                }
            }
            assert!((mc - quad).abs().max_element() < 0.01 * quad.max_element().max(0.1), "{kind:?}: {mc} vs {quad}");
        }
    }

    #[test]
    fn mirror_reflects_and_is_not_evaluated() {
        let sp = point(MaterialKind::Mirror);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let s = sample::<ALL>(&sp, wo, 0.5, Vec2::splat(0.5)).unwrap();
        assert!(s.delta);
        assert!((s.wi - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
        assert_eq!(eval::<ALL>(&sp, wo, s.wi), Vec3::ZERO);
    }

    #[test]
    fn nothing_below_the_surface() {
        let sp = point(MaterialKind::Diffuse);
        assert_eq!(eval::<ALL>(&sp, Vec3::Z, -Vec3::Z), Vec3::ZERO);
    }
}

//! Materials: the three lobes the paper's scenes need, emission and opacity.
//!
//! One flat struct for every material, with a [`MaterialKind`] saying which lobes are live:
//!
//! | kind | diffuse lobe | specular lobe |
//! |---|---|---|
//! | `Diffuse` | Lambert, `albedo` (or the albedo texture) | none |
//! | `Glossy` | Lambert, `albedo` (zero for conductors) | microfacet, `specular` = reflectance at normal incidence, `alpha = roughness²` |
//! | `Mirror` | none | perfect (delta) reflection scaled by `specular` |
//!
//! Emission (`Ke`) is radiance leaving the front (winding-normal) side only. Opacity is
//! `opacity × mask(uv)`; the renderer treats coverage below 0.5 as a hole (a cutout, so the
//! G-buffer stays deterministic). Glass (`illum 7`) is loaded as a fully transparent cutout by
//! default (see `obj::GlassMode`): the paper's estimator has no refraction, and a clear thin
//! pane transmits almost everything.

use glam::{Vec2, Vec3};

use super::texture::Texture;

/// The largest emitted radiance a scene may contain, and likewise the largest point-light
/// intensity and sun radiance. Far above anything physical (the sun's radiance is ~2e7
/// W m⁻² sr⁻¹), and low enough that nothing downstream overflows f32: the estimator multiplies
/// it by BSDF values and inverse densities (up to ~1e8 for a light almost touching a surface),
/// and SSIM squares pixel values (f32 holds squares only up to ~1.8e19). Brighter lights are
/// refused with a message naming the light, instead of rendering black or writing inf.
pub const MAX_EMISSION: f32 = 1e15;

/// `Err` naming `what` when `v` exceeds [`MAX_EMISSION`] in some channel.
pub fn check_emission(what: &str, v: Vec3) -> Result<(), String> {
    if v.max_element() > MAX_EMISSION {
        Err(format!("{what} {v} exceeds the largest supported value {MAX_EMISSION:e}"))
    } else {
        Ok(())
    }
}

/// Smallest roughness a glossy lobe keeps (`alpha = 0.01`): smoother lobes (smooth plastic,
/// `Pr 0` with `illum 2`) would be delta lobes mixed with a diffuse base.
pub const MIN_GLOSSY_ROUGHNESS: f32 = 0.1;

/// Conductors (`illum 3`) with roughness at or below this are perfect mirrors.
pub const MIRROR_MAX_ROUGHNESS: f32 = 0.02;

/// Which lobes a material has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MaterialKind {
    /// Lambert only.
    Diffuse,
    /// Lambert (possibly black) plus a rough microfacet lobe.
    Glossy,
    /// Perfect specular reflection.
    Mirror,
}

/// A material (see the module table for what each field means per kind).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the MTL file or the generator.
    pub name: String,
    /// Which lobes are live.
    pub kind: MaterialKind,
    /// Diffuse albedo (linear RGB); ignored where `albedo_texture` is set.
    pub albedo: Vec3,
    /// Specular reflectance at normal incidence (`Ks`) for `Glossy` and `Mirror`.
    pub specular: Vec3,
    /// Perceptual roughness `Pr`; the microfacet `alpha` is `roughness²`.
    pub roughness: f32,
    /// Conductor (`Pm 1`): informational; its diffuse albedo is already zero.
    pub metallic: bool,
    /// Emitted radiance (`Ke`), one-sided on the winding normal. Zero for non-emitters.
    pub emission: Vec3,
    /// Albedo texture (index into `Scene::textures`, linear RGB(A)); replaces `albedo`.
    pub albedo_texture: Option<u32>,
    /// Multiplier on the albedo texture (1 unless an all-glossy conversion lowered the
    /// diffuse part, so that diffuse + specular stays below 1). Use [`Material::albedo_at`].
    pub texture_scale: f32,
    /// Constant opacity (`d`), 1 = opaque.
    pub opacity: f32,
    /// Opacity mask (index into `Scene::textures`, one channel): coverage = opacity × mask.
    pub opacity_texture: Option<u32>,
}

impl Material {
    /// A Lambertian material.
    pub fn diffuse(name: impl Into<String>, albedo: Vec3) -> Self {
        Self {
            name: name.into(),
            kind: MaterialKind::Diffuse,
            albedo,
            specular: Vec3::ZERO,
            roughness: 1.0,
            metallic: false,
            emission: Vec3::ZERO,
            albedo_texture: None,
            texture_scale: 1.0,
            opacity: 1.0,
            opacity_texture: None,
        }
    }

    /// Diffuse base plus a glossy lobe of reflectance `specular` and roughness `roughness`.
    pub fn glossy(name: impl Into<String>, albedo: Vec3, specular: Vec3, roughness: f32) -> Self {
        Self {
            kind: MaterialKind::Glossy,
            specular,
            roughness: roughness.max(MIN_GLOSSY_ROUGHNESS),
            ..Self::diffuse(name, albedo)
        }
    }

    /// A perfect mirror of reflectance `specular`.
    pub fn mirror(name: impl Into<String>, specular: Vec3) -> Self {
        Self {
            kind: MaterialKind::Mirror,
            albedo: Vec3::ZERO,
            specular,
            roughness: 0.0,
            ..Self::diffuse(name, Vec3::ZERO)
        }
    }

    /// A one-sided emitter with a diffuse base.
    pub fn emitter(name: impl Into<String>, radiance: Vec3, albedo: Vec3) -> Self {
        Self { emission: radiance, ..Self::diffuse(name, albedo) }
    }

    /// Microfacet `alpha = roughness²` (GGX/Beckmann width).
    pub fn alpha(&self) -> f32 {
        self.roughness * self.roughness
    }

    /// True when the material emits.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// True when some point of the material can be (partly) transparent.
    pub fn has_cutout(&self) -> bool {
        self.opacity < 1.0 || self.opacity_texture.is_some()
    }

    /// Diffuse albedo at `uv`: the texture (times `texture_scale`) when there is one, else
    /// `albedo`. The renderer must use this rather than reading the fields.
    #[inline]
    pub fn albedo_at(&self, textures: &[Texture], uv: Vec2) -> Vec3 {
        match self.albedo_texture {
            Some(t) => textures[t as usize].sample_rgb(uv) * self.texture_scale,
            None => self.albedo,
        }
    }

    /// Coverage in [0, 1] at `uv`: `opacity × mask`. Rays pass where it is below 0.5.
    #[inline]
    pub fn coverage_at(&self, textures: &[Texture], uv: Vec2) -> f32 {
        match self.opacity_texture {
            Some(t) => self.opacity * textures[t as usize].sample(uv).x,
            None => self.opacity,
        }
    }

    /// Turns the material into an all-glossy one, keeping its colour: the diffuse part is
    /// scaled by `1 - specular` (energy stays below 1) and the glossy lobe gets reflectance
    /// `specular` (grey) and roughness `roughness`. Mirrors and emitters are left alone.
    pub fn make_glossy(&mut self, specular: f32, roughness: f32) {
        if self.kind == MaterialKind::Mirror || self.is_emissive() {
            return;
        }
        let s = specular.clamp(0.0, 1.0);
        if !self.metallic {
            self.albedo *= 1.0 - s;
            self.texture_scale *= 1.0 - s;
            self.specular = Vec3::splat(s);
        }
        self.kind = MaterialKind::Glossy;
        self.roughness = roughness.max(MIN_GLOSSY_ROUGHNESS);
    }

    /// Turns the material into a mirror of reflectance `specular` (no texture, no diffuse).
    pub fn make_mirror(&mut self, specular: Vec3) {
        self.kind = MaterialKind::Mirror;
        self.albedo = Vec3::ZERO;
        self.albedo_texture = None;
        self.specular = specular;
        self.roughness = 0.0;
    }

    /// Turns the material into a Lambertian one of its current albedo.
    pub fn make_diffuse(&mut self) {
        if self.kind == MaterialKind::Mirror {
            self.albedo = self.specular;
        }
        self.kind = MaterialKind::Diffuse;
        self.specular = Vec3::ZERO;
        self.roughness = 1.0;
    }

    /// Checks ranges: finite colours, albedo and specular in [0, 1], non-negative emission,
    /// roughness and opacity in [0, 1], texture indices below `texture_count`.
    pub fn validate(&self, texture_count: usize) -> Result<(), String> {
        let unit = |v: Vec3| v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0;
        if !unit(self.albedo) {
            return Err(format!("material {:?}: albedo {} outside [0, 1]", self.name, self.albedo));
        }
        if !unit(self.specular) {
            return Err(format!("material {:?}: specular {} outside [0, 1]", self.name, self.specular));
        }
        if !(self.emission.is_finite() && self.emission.min_element() >= 0.0) {
            return Err(format!("material {:?}: emission {} is negative or not finite", self.name, self.emission));
        }
        check_emission(&format!("material {:?}: emission (Ke)", self.name), self.emission)?;
        if !(0.0..=1.0).contains(&self.roughness)
            || !(0.0..=1.0).contains(&self.opacity)
            || !(0.0..=1.0).contains(&self.texture_scale)
        {
            return Err(format!("material {:?}: roughness, opacity or texture scale outside [0, 1]", self.name));
        }
        for t in [self.albedo_texture, self.opacity_texture].into_iter().flatten() {
            if t as usize >= texture_count {
                return Err(format!("material {:?}: texture {t} of {texture_count}", self.name));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glossy_conversion_keeps_energy_below_one() {
        let mut m = Material::diffuse("d", Vec3::new(0.8, 0.5, 0.2));
        m.make_glossy(0.5, 0.3);
        assert_eq!(m.kind, MaterialKind::Glossy);
        assert!((m.albedo + m.specular).max_element() <= 1.0 + 1e-6);
        assert!((m.alpha() - 0.09).abs() < 1e-6);
        let mut e = Material::emitter("e", Vec3::ONE, Vec3::splat(0.5));
        e.make_glossy(0.5, 0.3);
        assert_eq!(e.kind, MaterialKind::Diffuse, "emitters are left alone");
        let mut g = Material::glossy("g", Vec3::ZERO, Vec3::ONE, 0.0);
        assert_eq!(g.roughness, MIN_GLOSSY_ROUGHNESS);
        g.make_mirror(Vec3::splat(0.9));
        assert_eq!(g.kind, MaterialKind::Mirror);
        assert!(g.validate(0).is_ok());
        let bad = Material::diffuse("b", Vec3::splat(1.5));
        assert!(bad.validate(0).is_err());
    }
}

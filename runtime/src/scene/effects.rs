//! The effect set: which rendering features a scene needs, so the integrator can be
//! specialised (monomorphised) for it and an all-diffuse, static-light scene runs no glossy,
//! mirror, light-motion or object-motion code.
//!
//! The set is derived from the content ([`EffectSet::derive`]); a manifest may force flags on
//! (the general code then runs and must give the same image) or strip content so that a flag
//! goes away. The flags are plain bits so they fit a const generic (`const E: u16`).

use std::fmt;

use super::light::{Environment, Lights, MovingShape};
use super::material::{Material, MaterialKind};
use super::mesh::Mesh;
use super::object::MovingObject;

/// A set of [`Effect`]s, as bits.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct EffectSet(u16);

/// One rendering feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum Effect {
    /// A used material has a glossy (microfacet) lobe.
    Glossy = 1 << 0,
    /// A used material is a perfect mirror.
    Mirror = 1 << 1,
    /// Some light moves over the frames.
    MovingLights = 1 << 2,
    /// A used material has an albedo texture.
    Textures = 1 << 3,
    /// The environment is a lat-long HDR map (importance sampled).
    EnvMap = 1 << 4,
    /// There is a directional sun.
    Sun = 1 << 5,
    /// There are emissive triangles (static or moving).
    AreaLights = 1 << 6,
    /// There are point lights (static or moving).
    PointLights = 1 << 7,
    /// A used material has an opacity below 1 or an opacity mask (cutouts).
    AlphaMasks = 1 << 8,
    /// The environment is analytic: constant or a sky gradient.
    Sky = 1 << 9,
    /// Some non-emissive object moves over the frames.
    MovingObjects = 1 << 10,
}

impl Effect {
    /// Every effect, in bit order.
    pub const ALL: [Effect; 11] = [
        Effect::Glossy,
        Effect::Mirror,
        Effect::MovingLights,
        Effect::Textures,
        Effect::EnvMap,
        Effect::Sun,
        Effect::AreaLights,
        Effect::PointLights,
        Effect::AlphaMasks,
        Effect::Sky,
        Effect::MovingObjects,
    ];

    /// Short kebab-case name (used in listings and manifests, `effects.<name>` with `-` → `_`).
    pub fn name(self) -> &'static str {
        match self {
            Effect::Glossy => "glossy",
            Effect::Mirror => "mirror",
            Effect::MovingLights => "moving-lights",
            Effect::Textures => "textures",
            Effect::EnvMap => "env-map",
            Effect::Sun => "sun",
            Effect::AreaLights => "area-lights",
            Effect::PointLights => "point-lights",
            Effect::AlphaMasks => "alpha-masks",
            Effect::Sky => "sky",
            Effect::MovingObjects => "moving-objects",
        }
    }

    /// The effect of a name (`-` and `_` are interchangeable).
    pub fn from_name(name: &str) -> Option<Self> {
        let n = name.replace('_', "-");
        Self::ALL.into_iter().find(|e| e.name() == n)
    }
}

impl EffectSet {
    /// No effects.
    pub const EMPTY: Self = Self(0);

    /// The raw bits (for a const generic parameter).
    pub const fn bits(self) -> u16 {
        self.0
    }

    /// A set from raw bits (unknown bits are dropped).
    pub const fn from_bits(bits: u16) -> Self {
        Self(bits & ((1 << Effect::ALL.len()) - 1))
    }

    /// True when `effect` is in the set (usable in const contexts: `EffectSet::from_bits(E).has(..)`).
    pub const fn has(self, effect: Effect) -> bool {
        self.0 & effect as u16 != 0
    }

    /// The set with `effect` added.
    pub const fn with(self, effect: Effect) -> Self {
        Self(self.0 | effect as u16)
    }

    /// The set without `effect`.
    pub const fn without(self, effect: Effect) -> Self {
        Self(self.0 & !(effect as u16))
    }

    /// Union.
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    /// True when every effect of `other` is in `self`.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// The effects in the set, in bit order.
    pub fn iter(self) -> impl Iterator<Item = Effect> {
        Effect::ALL.into_iter().filter(move |e| self.has(*e))
    }

    /// Derives the set from what the scene contains. Only materials used by at least one
    /// triangle (of the mesh or of a moving object) count.
    pub fn derive(mesh: &Mesh, materials: &[Material], lights: &Lights, objects: &[MovingObject]) -> Self {
        let mut used = vec![false; materials.len()];
        for &m in mesh.material.iter().chain(objects.iter().map(|o| &o.material)) {
            if let Some(u) = used.get_mut(m as usize) {
                *u = true;
            }
        }
        let mut set = Self::EMPTY;
        for (m, _) in materials.iter().zip(&used).filter(|(_, u)| **u) {
            match m.kind {
                MaterialKind::Glossy => set = set.with(Effect::Glossy),
                MaterialKind::Mirror => set = set.with(Effect::Mirror),
                MaterialKind::Diffuse => {}
            }
            if m.albedo_texture.is_some() && m.kind != MaterialKind::Mirror {
                set = set.with(Effect::Textures);
            }
            if m.has_cutout() {
                set = set.with(Effect::AlphaMasks);
            }
        }
        if !lights.area.is_empty() {
            set = set.with(Effect::AreaLights);
        }
        if !lights.points.is_empty() {
            set = set.with(Effect::PointLights);
        }
        if lights.sun.is_some() {
            set = set.with(Effect::Sun);
        }
        match lights.environment {
            Some(Environment::Map(_)) => set = set.with(Effect::EnvMap),
            Some(_) => set = set.with(Effect::Sky),
            None => {}
        }
        if !objects.is_empty() {
            set = set.with(Effect::MovingObjects);
        }
        for m in &lights.moving {
            set = set.with(Effect::MovingLights);
            set = set.with(match m.shape {
                MovingShape::Point { .. } => Effect::PointLights,
                MovingShape::Area { .. } => Effect::AreaLights,
            });
        }
        set
    }
}

impl fmt::Display for EffectSet {
    /// Comma-separated names, or `none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0 == 0 {
            return f.write_str("none");
        }
        let names: Vec<&str> = self.iter().map(Effect::name).collect();
        f.write_str(&names.join(","))
    }
}

impl fmt::Debug for EffectSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EffectSet({self})")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_names_and_sets() {
        let s = EffectSet::EMPTY.with(Effect::Glossy).with(Effect::Sky);
        assert!(s.has(Effect::Glossy) && !s.has(Effect::Mirror));
        assert_eq!(s.to_string(), "glossy,sky");
        assert_eq!(EffectSet::from_bits(s.bits()), s);
        assert_eq!(EffectSet::from_bits(u16::MAX).iter().count(), Effect::ALL.len());
        assert_eq!(EffectSet::EMPTY.to_string(), "none");
        for e in Effect::ALL {
            assert_eq!(Effect::from_name(e.name()), Some(e));
            assert_eq!(Effect::from_name(&e.name().replace('-', "_")), Some(e));
        }
        assert!(s.contains(EffectSet::EMPTY.with(Effect::Sky)));
        assert!(!s.without(Effect::Sky).has(Effect::Sky));
        // Distinct bits.
        let all = Effect::ALL.iter().fold(0u16, |a, e| {
            assert_eq!(a & *e as u16, 0);
            a | *e as u16
        });
        assert_eq!(all.count_ones() as usize, Effect::ALL.len());
    }
}

//! Effect bits the integrator is specialised on.
//!
//! The integrator is generic over `const E: u16`. Each bit switches on one piece of code:
//! glossy lobes, mirrors, moving geometry (lights or objects), texture lookups and cut-out
//! (alpha-masked) geometry. With a bit clear the compiler removes that code, so an
//! all-diffuse, static, untextured scene runs no glossy, mirror or motion code at all. Light *types* (area,
//! point, sun, environment) need no bits: they are records in the per-frame light table,
//! and a scene without a type simply has no such record.
//!
//! [`ALL`] is the general integrator: every branch is compiled in and decided per material
//! at run time. It gives bit-identical images to the specialised one on the same seed
//! (tested), because every random number has a fixed dimension (see [`super::rng::Dim`]).

use crate::scene::{Effect, EffectSet};

/// Glossy (GGX) materials.
pub const GLOSSY: u16 = 1 << 0;
/// Mirror materials.
pub const MIRROR: u16 = 1 << 1;
/// Triangles placed per frame outside the static BVH: moving area lights and moving objects
/// (one bit: both are hit, occlude and move by the same code).
pub const MOVING_GEOMETRY: u16 = 1 << 2;
/// Texture lookups.
pub const TEXTURES: u16 = 1 << 3;
/// Alpha-masked (cut-out) materials.
pub const ALPHA_MASKS: u16 = 1 << 4;
/// The general integrator.
pub const ALL: u16 = GLOSSY | MIRROR | MOVING_GEOMETRY | TEXTURES | ALPHA_MASKS;

/// Whether effect bits `e` include `bit` (usable in `if` on a const generic: folded away).
#[inline(always)]
pub const fn has(e: u16, bit: u16) -> bool {
    e & bit != 0
}

/// The integrator bits a scene's effect set needs.
pub fn bits_for(effects: EffectSet) -> u16 {
    let mut bits = 0;
    for (effect, bit) in [
        (Effect::Glossy, GLOSSY),
        (Effect::Mirror, MIRROR),
        (Effect::MovingLights, MOVING_GEOMETRY),
        (Effect::MovingObjects, MOVING_GEOMETRY),
        (Effect::Textures, TEXTURES),
        (Effect::AlphaMasks, ALPHA_MASKS),
    ] {
        if effects.has(effect) {
            bits |= bit;
        }
    }
    bits
}

/// Names of the bits set in `e`, for reports.
pub fn describe(e: u16) -> String {
    let names: Vec<&str> = [
        (GLOSSY, "glossy"),
        (MIRROR, "mirror"),
        (MOVING_GEOMETRY, "moving-geometry"),
        (TEXTURES, "textures"),
        (ALPHA_MASKS, "alpha-masks"),
    ]
    .iter()
    .filter(|(b, _)| has(e, *b))
    .map(|(_, n)| *n)
    .collect();
    if names.is_empty() { "diffuse-only".into() } else { names.join("+") }
}

/// Calls `$call!(E)` with `E` the compile-time constant equal to the run-time `$bits`
/// (0..=31): one monomorphised copy per effect combination.
#[macro_export]
#[doc(hidden)]
macro_rules! dispatch_effects {
    ($bits:expr, $call:ident) => {
        match $bits & $crate::render::effects::ALL {
            0 => $call!(0),
            1 => $call!(1),
            2 => $call!(2),
            3 => $call!(3),
            4 => $call!(4),
            5 => $call!(5),
            6 => $call!(6),
            7 => $call!(7),
            8 => $call!(8),
            9 => $call!(9),
            10 => $call!(10),
            11 => $call!(11),
            12 => $call!(12),
            13 => $call!(13),
            14 => $call!(14),
            15 => $call!(15),
            16 => $call!(16),
            17 => $call!(17),
            18 => $call!(18),
            19 => $call!(19),
            20 => $call!(20),
            21 => $call!(21),
            22 => $call!(22),
            23 => $call!(23),
            24 => $call!(24),
            25 => $call!(25),
            26 => $call!(26),
            27 => $call!(27),
            28 => $call!(28),
            29 => $call!(29),
            30 => $call!(30),
            31 => $call!(31),
            _ => unreachable!("effect bits are masked to 5 bits"),
        }
    };
}

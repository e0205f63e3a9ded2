//! Built-in procedural scenes: stand-ins for the paper's test scenes (Figure 2) that need no
//! files, plus a tiny Cornell box for quick runs and tests.
//!
//! | name | stands for | content |
//! |---|---|---|
//! | `cornell` | (estimator checks) | closed box, two blocks, ceiling light; a few dozen triangles |
//! | `atrium` | Sponza | two-storey colonnaded atrium with arches, vaults, balustrades, banners; skylight over the open courtyard |
//! | `atrium-glossy` | Sponza (Glossy) | every material glossy |
//! | `atrium-moving-light` | Sponza (Moving Light) | dimmed skylight, a glowing sphere crossing the courtyard |
//! | `atrium-moving-object` | (beyond the paper) | a turning crate sliding across the courtyard, for motion vectors |
//! | `living-room` | Living Room | sofa, armchairs, table, shelves, lamp, curtains; daylight through two windows |
//! | `living-room-glossy` | Living Room (Glossy) | every material glossy |
//! | `living-room-moving-light` | Living Room (Moving Light) | dimmed windows, a carried lantern (point light) |
//! | `classroom` | Classroom | rows of desks and tube-frame chairs, blackboard, notice board; sun + sky through windows, ceiling panels |
//! | `classroom-glossy` | Classroom (Glossy) | every material glossy |
//! | `classroom-mirror` | Classroom (Mirror) | the notice board is a mirror |
//! | `courtyard` | San Miguel | dense courtyard: arcades, fountain, trees with tens of thousands of leaves, potted plants, tables; sun + sky |
//!
//! All-glossy variants convert every non-emissive material with
//! [`Material::make_glossy`](crate::scene::material::Material::make_glossy) at reflectance 0.5 and
//! roughness 0.3 (α = 0.09). Generation is seeded and uses no floating-point reductions whose
//! order could vary, so a built-in is bit-identical across runs and machines of one target.

mod atrium;
mod classroom;
mod cornell;
mod courtyard;
pub mod geom;
mod living_room;
pub mod textures;

use super::effects::EffectSet;
use super::error::SceneError;
use super::light::Lights;
use super::material::Material;
use super::mesh::Mesh;
use super::model::{Scene, SceneSource, SceneTolerances, Units};
use super::object::MovingObject;
use super::path::CameraPath;
use super::texture::Texture;

/// Glossy lobe of the all-glossy variants: (reflectance, roughness).
pub const GLOSSY_VARIANT: (f32, f32) = (0.5, 0.3);

/// Which variant of a base scene to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// As designed (diffuse-dominated, static lights).
    Base,
    /// Every material glossy.
    Glossy,
    /// Static lights dimmed, a moving light added.
    MovingLight,
    /// One designated surface turned into a mirror.
    Mirror,
    /// A non-emissive object added that moves (the paper has no such scene).
    MovingObject,
}

/// What a generator returns.
pub(crate) struct Parts {
    pub mesh: Mesh,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Lights,
    pub moving_objects: Vec<MovingObject>,
    pub camera: CameraPath,
    pub tolerances: SceneTolerances,
}

/// A built-in scene's identity.
#[derive(Clone, Copy, Debug)]
pub struct BuiltinSpec {
    /// Stable kebab-case id.
    pub name: &'static str,
    /// Human-readable name.
    pub display_name: &'static str,
    /// The paper scene it stands for (Figure 2 label).
    pub paper_scene: Option<&'static str>,
    /// The base scene.
    base: fn(Variant) -> Parts,
    /// The variant.
    pub variant: Variant,
}

/// Every built-in, in listing order.
pub const BUILTINS: &[BuiltinSpec] = &[
    BuiltinSpec {
        name: "cornell",
        display_name: "Cornell box (quick checks)",
        paper_scene: None,
        base: cornell::build,
        variant: Variant::Base,
    },
    BuiltinSpec {
        name: "atrium",
        display_name: "Atrium (stand-in for Sponza)",
        paper_scene: Some("Sponza"),
        base: atrium::build,
        variant: Variant::Base,
    },
    BuiltinSpec {
        name: "atrium-glossy",
        display_name: "Atrium, glossy (stand-in for Sponza (Glossy))",
        paper_scene: Some("Sponza (Glossy)"),
        base: atrium::build,
        variant: Variant::Glossy,
    },
    BuiltinSpec {
        name: "atrium-moving-light",
        display_name: "Atrium, moving light (stand-in for Sponza (Moving Light))",
        paper_scene: Some("Sponza (Moving Light)"),
        base: atrium::build,
        variant: Variant::MovingLight,
    },
    BuiltinSpec {
        name: "atrium-moving-object",
        display_name: "Atrium, moving object (beyond the paper: a crate crossing the courtyard)",
        paper_scene: None,
        base: atrium::build,
        variant: Variant::MovingObject,
    },
    BuiltinSpec {
        name: "living-room",
        display_name: "Living room (stand-in for Living Room)",
        paper_scene: Some("Living Room"),
        base: living_room::build,
        variant: Variant::Base,
    },
    BuiltinSpec {
        name: "living-room-glossy",
        display_name: "Living room, glossy (stand-in for Living Room (Glossy))",
        paper_scene: Some("Living Room (Glossy)"),
        base: living_room::build,
        variant: Variant::Glossy,
    },
    BuiltinSpec {
        name: "living-room-moving-light",
        display_name: "Living room, moving light (stand-in for Living Room (Moving Light))",
        paper_scene: Some("Living Room (Moving Light)"),
        base: living_room::build,
        variant: Variant::MovingLight,
    },
    BuiltinSpec {
        name: "classroom",
        display_name: "Classroom (stand-in for Classroom)",
        paper_scene: Some("Classroom"),
        base: classroom::build,
        variant: Variant::Base,
    },
    BuiltinSpec {
        name: "classroom-glossy",
        display_name: "Classroom, glossy (stand-in for Classroom (Glossy))",
        paper_scene: Some("Classroom (Glossy)"),
        base: classroom::build,
        variant: Variant::Glossy,
    },
    BuiltinSpec {
        name: "classroom-mirror",
        display_name: "Classroom, mirror notice board (stand-in for Classroom (Mirror))",
        paper_scene: Some("Classroom (Mirror)"),
        base: classroom::build,
        variant: Variant::Mirror,
    },
    BuiltinSpec {
        name: "courtyard",
        display_name: "Courtyard (stand-in for San Miguel)",
        paper_scene: Some("San Miguel"),
        base: courtyard::build,
        variant: Variant::Base,
    },
];

/// The built-in names, in listing order.
pub fn builtin_names() -> Vec<&'static str> {
    BUILTINS.iter().map(|b| b.name).collect()
}

/// Builds the built-in `name`; `None` when there is no such built-in.
pub fn build(name: &str) -> Option<Result<Scene, SceneError>> {
    let spec = BUILTINS.iter().find(|b| b.name == name)?;
    Some(build_spec(spec))
}

fn build_spec(spec: &BuiltinSpec) -> Result<Scene, SceneError> {
    let mut parts = (spec.base)(spec.variant);
    if spec.variant == Variant::Glossy {
        for m in &mut parts.materials {
            m.make_glossy(GLOSSY_VARIANT.0, GLOSSY_VARIANT.1);
        }
    }
    let mut scene = Scene {
        name: spec.name.to_owned(),
        display_name: spec.display_name.to_owned(),
        paper_scene: spec.paper_scene.map(str::to_owned),
        source: SceneSource::Builtin(spec.name),
        mesh: parts.mesh,
        materials: parts.materials,
        textures: parts.textures,
        lights: parts.lights,
        moving_objects: parts.moving_objects,
        camera: parts.camera,
        tolerances: parts.tolerances,
        effects: EffectSet::EMPTY,
        forced_effects: EffectSet::EMPTY,
        units: Units::METRES,
        warnings: Vec::new(),
    };
    scene.update()?;
    Ok(scene)
}

/// One line of [`list_builtin`].
#[derive(Clone, Debug, PartialEq)]
pub struct BuiltinInfo {
    /// Stable id.
    pub name: &'static str,
    /// Human-readable name.
    pub display_name: &'static str,
    /// Paper scene it stands for.
    pub paper_scene: Option<&'static str>,
    /// Triangle count.
    pub triangles: usize,
    /// Effect set.
    pub effects: EffectSet,
}

/// Builds every built-in (in parallel) and reports name, display name, paper scene, triangle
/// count and effects.
pub fn list_builtin() -> Vec<BuiltinInfo> {
    use rayon::prelude::*;
    BUILTINS
        .par_iter()
        .map(|spec| {
            let (triangles, effects) = match build_spec(spec) {
                Ok(s) => (s.triangle_count(), s.effects),
                Err(_) => (0, EffectSet::EMPTY),
            };
            BuiltinInfo {
                name: spec.name,
                display_name: spec.display_name,
                paper_scene: spec.paper_scene,
                triangles,
                effects,
            }
        })
        .collect()
}

/// Helpers shared by the generators.
pub(crate) mod util {
    use glam::Vec3;

    use crate::scene::path::{CameraKey, CameraPath, DEFAULT_FRAMES};

    /// A camera path through `(frame, eye, target)` keys with +Y up.
    pub fn path(vfov_deg: f32, keys: &[(f32, [f32; 3], [f32; 3])]) -> CameraPath {
        let keys =
            keys.iter().map(|&(frame, eye, target)| CameraKey { frame, eye, target, up: [0.0, 1.0, 0.0] }).collect();
        CameraPath::new(keys, DEFAULT_FRAMES, vfov_deg).expect("built-in camera keys are valid")
    }

    /// sRGB-ish colour literal to linear.
    pub fn rgb(r: f32, g: f32, b: f32) -> Vec3 {
        Vec3::new(r, g, b).map(crate::scene::texture::srgb_to_linear)
    }
}

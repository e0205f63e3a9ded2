//! # Scenes
//!
//! Everything the renderer needs to know about a scene, in one flat, renderer-friendly
//! [`Scene`]: world-space triangles ([`Mesh`]), [`Material`]s, decoded [`Texture`]s,
//! [`Lights`], a smooth 60-frame [`CameraPath`] (the moving observer), the per-scene
//! reprojection [`SceneTolerances`] and the [`EffectSet`] the integrator is specialised for.
//!
//! Scenes come from three places, all reached through [`resolve()`]:
//!
//! - **Built-ins** ([`builtin`]): procedural stand-ins for the paper's four scenes and their
//!   variants (Figure 2) plus a tiny `cornell` box. No files, deterministic, fast.
//! - **Scene folders** ([`folder`]): `scene.obj` + `scene.mtl` + `camera.json` +
//!   `lights.json` + textures, the format of `../shared/scenes/*/`.
//! - **Manifests** ([`manifest`]): a small TOML file naming a mesh and expressing variants
//!   over it (all-glossy, a mirror, moving lights, effect overrides, tolerances).
//!
//! Conventions: scene units are metres (loaders scale); +Y is up; triangles are wound
//! counter-clockwise seen from their front, and emitters emit to the front only (one-sided
//! `Ke`); reflection is two-sided (the renderer faces the shading normal towards the incoming
//! ray); colours are linear RGB; UV `v = 0` is the bottom image row.
//!
//! ## Error policy
//!
//! One error type, [`SceneError`]; every message names the file and, for syntax errors, the
//! line (and column for JSON/TOML). Nothing here panics on bad input.
//!
//! | input | behaviour |
//! |---|---|
//! | missing or unreadable OBJ, MTL, camera.json, lights.json, manifest, EXR | error naming the file (a missing MTL also names the `mtllib` line) |
//! | OBJ/MTL syntax: bad numbers, `w` = 0, index 0 or out of range, truncated lines, invalid UTF-8 | error `file:line: ...` |
//! | NaN or infinite coordinates, normals, UVs, colours | error `file:line: ...` |
//! | no triangles, no lights, a degenerate camera | error naming the file |
//! | JSON/TOML syntax or schema (unknown keys, wrong types) | error `file:line:column: ...` |
//! | missing or undecodable texture (`map_Kd`, `map_d`) | **warning** in `Scene::warnings`; the material keeps its flat `Kd` (the texture mean in the shared scenes) / stays opaque |
//! | faces with < 3 vertices, glass, colours > 1, Ke/lights.json mismatch | warning |

pub mod builtin;
pub mod command;
pub mod effects;
pub mod envmap;
pub mod error;
pub mod export;
pub mod folder;
pub mod gltf_file;
pub mod light;
pub mod manifest;
pub mod material;
pub mod mesh;
pub mod model;
pub mod obj;
pub mod object;
pub mod path;
pub mod resolve;
pub mod sampling;
pub mod texture;

pub use builtin::{BuiltinInfo, builtin_names, list_builtin};
pub use effects::{Effect, EffectSet};
pub use envmap::{EnvMap, EnvSample};
pub use error::{Location, SceneError};
pub use light::{
    AreaLights, Environment, Lights, MovingLight, MovingShape, PlacedLight, PointLight, SkyGradient, SpotCone, SunLight,
};
pub use material::{Material, MaterialKind};
pub use mesh::{Aabb, Mesh};
pub use model::{REFERENCE_HEIGHT, Scene, SceneSource, SceneTolerances, Units, UnitsFrom};
pub use object::MovingObject;
pub use path::{CameraKey, CameraPath, CameraPose, DEFAULT_FRAMES, TransformKey, TransformPath};
pub use resolve::{resolve, scene_name};
pub use texture::{Texture, TextureUsage};

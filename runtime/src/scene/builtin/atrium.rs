//! `atrium`: the Sponza stand-in. A closed 27 × 15 m atrium, 15 m high: two storeys of
//! colonnades with round arches along both long sides (turned columns, segmental vaults over
//! the galleries, a balustrade upstairs), an attic storey with windows, stone-flag and ashlar
//! textures, hanging banners in the ground-floor galleries and four urns in the courtyard.
//! The open roof over the courtyard is a downward-facing emissive skylight, so the scene is
//! closed and lit the way Sponza's open courtyard is (light from above, the galleries lit
//! indirectly). About 1.7·10⁵ triangles.
//!
//! Axes: x along the atrium (±13.5), z across (±7.5), y up. The moving-light variant dims the
//! skylight to a quarter and sends a glowing sphere across the courtyard; the moving-object
//! variant keeps the lighting and slides a turning crate across the courtyard in front of the
//! camera.

use glam::{Vec2, Vec3};

use super::geom::{Builder, Rng};
use super::textures;
use super::util::{path, rgb};
use super::{Parts, Variant};
use crate::scene::light::{Lights, MovingLight, MovingShape};
use crate::scene::material::Material;
use crate::scene::model::SceneTolerances;
use crate::scene::object::{MovingObject, box_triangles};
use crate::scene::path::{TransformKey, TransformPath};

const HALF_X: f32 = 13.5;
const ARCADE_Z: f32 = 4.5;
const ARCADE_HALF_THICK: f32 = 0.35;
const OUTER_Z: f32 = 7.5;
const BAY: f32 = 3.0;
const ROOF_Y: f32 = 15.3;
const SKY_RADIANCE: Vec3 = Vec3::new(5.0, 4.8, 4.5);

/// Profile of a turned column (radius, height) from 0 to `h`, with base mouldings, a shaft with
/// entasis and a flared capital.
fn column_profile(h: f32) -> Vec<(f32, f32)> {
    let mut p = vec![(0.0, 0.0), (0.42, 0.0), (0.42, 0.08), (0.45, 0.12), (0.44, 0.18), (0.38, 0.22), (0.36, 0.28)];
    let (s0, s1) = (0.3, h - 0.55);
    for k in 0..=10 {
        let t = k as f32 / 10.0;
        let entasis = 0.34 - 0.05 * t + 0.02 * (std::f32::consts::PI * t).sin();
        p.push((entasis, s0 + (s1 - s0) * t));
    }
    p.extend([
        (0.31, h - 0.5),
        (0.34, h - 0.45),
        (0.33, h - 0.4),
        (0.36, h - 0.32),
        (0.42, h - 0.22),
        (0.5, h - 0.12),
        (0.5, h),
        (0.0, h),
    ]);
    p
}

fn baluster_profile() -> Vec<(f32, f32)> {
    vec![
        (0.0, 0.0),
        (0.07, 0.0),
        (0.07, 0.06),
        (0.05, 0.1),
        (0.06, 0.2),
        (0.085, 0.32),
        (0.08, 0.42),
        (0.05, 0.52),
        (0.035, 0.6),
        (0.045, 0.66),
        (0.04, 0.7),
        (0.07, 0.72),
        (0.07, 0.75),
        (0.0, 0.75),
    ]
}

fn urn_profile() -> Vec<(f32, f32)> {
    let mut p = vec![(0.0, 0.0), (0.35, 0.0), (0.35, 0.12), (0.22, 0.2), (0.18, 0.3)];
    for k in 0..=14 {
        let t = k as f32 / 14.0;
        p.push((0.25 + 0.33 * (std::f32::consts::PI * t).sin(), 0.35 + 0.9 * t));
    }
    p.extend([(0.33, 1.3), (0.42, 1.38), (0.42, 1.42), (0.3, 1.42)]);
    p
}

/// Segmental vault under a gallery slab: spans `z0..z1`, springs at `y_spring`, rises `rise`.
fn segmental_vault(b: &mut Builder, z0: f32, z1: f32, y_spring: f32, rise: f32) {
    let c = (z1 - z0).abs();
    let r = (c * c / 4.0 + rise * rise) / (2.0 * rise);
    let (zc, yc) = (0.5 * (z0 + z1), y_spring + rise - r);
    let tm = (0.5 * c / r).asin();
    b.grid(54, 10, Vec2::new(13.5, 1.3), |u, v| {
        let phi = -tm + 2.0 * tm * v;
        let p = Vec3::new(-HALF_X + 2.0 * HALF_X * u, yc + r * phi.cos(), zc + r * phi.sin());
        (p, -Vec3::new(0.0, phi.cos(), phi.sin()))
    });
}

pub(crate) fn build(variant: Variant) -> Parts {
    let mut rng = Rng::new(0xA791_0001);
    let mut b = Builder::new();
    let flags = b.texture(textures::stone_flags(11));
    let ashlar = b.texture(textures::ashlar(12));
    let floor =
        b.material(Material { albedo_texture: Some(flags), ..Material::diffuse("floor", rgb(0.78, 0.73, 0.63)) });
    let wall = b.material(Material { albedo_texture: Some(ashlar), ..Material::diffuse("wall", rgb(0.8, 0.75, 0.65)) });
    let stone = b.material(Material::diffuse("column-stone", rgb(0.82, 0.78, 0.7)));
    let vault = b.material(Material::diffuse("vault-plaster", rgb(0.88, 0.84, 0.76)));
    let trim = b.material(Material::diffuse("trim", rgb(0.7, 0.66, 0.58)));
    let urn = b.material(Material::diffuse("urn", rgb(0.7, 0.42, 0.28)));
    let banners = [
        b.material(Material::diffuse("banner-red", rgb(0.62, 0.12, 0.1))),
        b.material(Material::diffuse("banner-green", rgb(0.15, 0.4, 0.18))),
        b.material(Material::diffuse("banner-blue", rgb(0.14, 0.22, 0.5))),
    ];
    let sky_scale = if variant == Variant::MovingLight { 0.25 } else { 1.0 };
    let sky = b.material(Material::emitter("skylight", SKY_RADIANCE * sky_scale, Vec3::ZERO));
    // Last, so that the mesh's material indices are those of the base scene.
    let crate_material =
        (variant == Variant::MovingObject).then(|| b.material(Material::diffuse("crate", rgb(0.7, 0.45, 0.25))));

    // Ground floor and outer shell.
    b.use_material(floor);
    b.plane(
        Vec3::new(-HALF_X, 0.0, OUTER_Z),
        Vec3::X * 2.0 * HALF_X,
        Vec3::NEG_Z * 2.0 * OUTER_Z,
        27,
        15,
        Vec2::new(13.5, 7.5),
    );
    b.use_material(wall);
    for s in [1.0f32, -1.0] {
        // Long outer walls, facing the atrium.
        // (`plane` faces `eu x ev`; every wall faces into the atrium.)
        let (o, eu) = if s > 0.0 {
            (Vec3::new(HALF_X, 0.0, OUTER_Z), Vec3::NEG_X * 2.0 * HALF_X)
        } else {
            (Vec3::new(-HALF_X, 0.0, -OUTER_Z), Vec3::X * 2.0 * HALF_X)
        };
        b.plane(o, eu, Vec3::Y * ROOF_Y, 27, 15, Vec2::new(13.5, 7.65));
        // End walls.
        let (o, eu) = if s > 0.0 {
            (Vec3::new(HALF_X, 0.0, -OUTER_Z), Vec3::Z * 2.0 * OUTER_Z)
        } else {
            (Vec3::new(-HALF_X, 0.0, OUTER_Z), Vec3::NEG_Z * 2.0 * OUTER_Z)
        };
        b.plane(o, eu, Vec3::Y * ROOF_Y, 15, 15, Vec2::new(7.5, 7.65));
    }

    // Both colonnaded sides: build the +z side in local space, mirror by rotating 180° about Y.
    for side in [0.0f32, 180.0] {
        b.at(Vec3::ZERO, side, |b| {
            let (za, zb) = (ARCADE_Z - ARCADE_HALF_THICK, ARCADE_Z + ARCADE_HALF_THICK);
            for (level, y0, col_h) in [(0, 0.0f32, 4.5f32), (1, 6.8, 3.7)] {
                let spring = y0 + col_h;
                let top = spring + 2.0;
                // Columns (interior supports) and pilasters at the end walls.
                b.use_material(stone);
                for k in 0..=9 {
                    let x = -HALF_X + BAY * k as f32;
                    if k == 0 || k == 9 {
                        let x0 = if k == 0 { x } else { x - 0.45 };
                        b.cuboid(Vec3::new(x0, y0, za - 0.1), Vec3::new(x0 + 0.45, spring, zb + 0.1));
                        continue;
                    }
                    b.lathe(Vec3::new(x, y0, ARCADE_Z), &column_profile(col_h - 0.12), 32, false);
                    b.cuboid(
                        Vec3::new(x - 0.48, spring - 0.12, ARCADE_Z - 0.48),
                        Vec3::new(x + 0.48, spring, ARCADE_Z + 0.48),
                    );
                }
                // Arches and the wall above them.
                b.use_material(wall);
                for k in 0..9 {
                    let x0 = -HALF_X + BAY * k as f32;
                    b.arch((x0, x0 + BAY), (za, zb), (spring, top), 32);
                }
                // Gallery slab above, and a segmental vault under it.
                let slab_top = top + 0.3;
                b.use_material(if level == 0 { floor } else { trim });
                b.cuboid(Vec3::new(-HALF_X, top, za), Vec3::new(HALF_X, slab_top, OUTER_Z));
                b.use_material(vault);
                segmental_vault(b, zb, OUTER_Z, spring + 1.5, top - 0.05 - (spring + 1.5));
                if level == 1 {
                    // Balustrade between the upper columns.
                    b.use_material(trim);
                    for k in 0..9 {
                        let x0 = -HALF_X + BAY * k as f32;
                        let (a, e) = (x0 + 0.55, x0 + BAY - 0.55);
                        b.cuboid(Vec3::new(a, y0, ARCADE_Z - 0.16), Vec3::new(e, y0 + 0.1, ARCADE_Z + 0.16));
                        b.cuboid(Vec3::new(a, y0 + 0.85, ARCADE_Z - 0.14), Vec3::new(e, y0 + 0.97, ARCADE_Z + 0.14));
                        let n = 8;
                        for i in 0..n {
                            let x = a + (e - a) * (i as f32 + 0.5) / n as f32;
                            b.lathe(Vec3::new(x, y0 + 0.1, ARCADE_Z), &baluster_profile(), 16, false);
                        }
                    }
                }
            }
            // Attic storey: piers between windows, sills and lintels, roof slab and cornice.
            let (ya, yb) = (12.8f32, 15.0f32);
            b.use_material(wall);
            for k in 0..=9 {
                let x = -HALF_X + BAY * k as f32;
                let (x0, x1) = ((x - 0.6).max(-HALF_X), (x + 0.6).min(HALF_X));
                b.cuboid(Vec3::new(x0, ya, za), Vec3::new(x1, yb, zb));
                if k < 9 {
                    b.cuboid(Vec3::new(x1, ya, za), Vec3::new(x + BAY - 0.6, ya + 0.5, zb));
                    b.cuboid(Vec3::new(x1, yb - 0.5, za), Vec3::new(x + BAY - 0.6, yb, zb));
                }
            }
            b.use_material(trim);
            b.cuboid(Vec3::new(-HALF_X, yb, za), Vec3::new(HALF_X, ROOF_Y, OUTER_Z));
            b.cuboid(Vec3::new(-HALF_X, 12.5, za - 0.12), Vec3::new(HALF_X, 12.62, za));
            // Banners on the outer wall of the ground gallery, one per bay.
            for k in 0..9 {
                let x0 = -HALF_X + BAY * k as f32 + 0.7;
                b.use_material(banners[k % 3]);
                // Turned to face the atrium (the cloth faces its local +Z).
                b.at(Vec3::new(x0 + 1.6, 5.7, OUTER_Z - 0.12), 180.0, |b| {
                    b.cloth(Vec3::ZERO, Vec2::new(1.6, 3.6), (2.5, 0.05), (24, 48))
                });
            }
        });
    }

    // Urns at the courtyard corners.
    b.use_material(urn);
    for (x, z) in [(-10.0f32, -3.0f32), (-10.0, 3.0), (10.0, -3.0), (10.0, 3.0)] {
        b.lathe(Vec3::new(x, 0.0, z), &urn_profile(), 48, false);
    }
    // Stone benches along the arcades.
    b.use_material(trim);
    for k in 0..6 {
        let x = -7.5 + 3.0 * k as f32;
        for s in [1.0f32, -1.0] {
            let z = s * (ARCADE_Z - 1.0);
            let jitter = rng.range(-0.2, 0.2);
            b.cuboid(Vec3::new(x - 0.8 + jitter, 0.0, z - 0.25), Vec3::new(x + 0.8 + jitter, 0.45, z + 0.25));
        }
    }

    // The skylight closing the courtyard, facing down.
    b.use_material(sky);
    let (zx, zz) = (HALF_X, ARCADE_Z - ARCADE_HALF_THICK);
    b.quad(
        [
            Vec3::new(-zx, ROOF_Y, -zz),
            Vec3::new(zx, ROOF_Y, -zz),
            Vec3::new(zx, ROOF_Y, zz),
            Vec3::new(-zx, ROOF_Y, zz),
        ],
        Vec3::NEG_Y,
        [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
    );

    let (mesh, materials, textures) = b.finish();
    let mut lights = Lights::default();
    if variant == Variant::MovingLight {
        let keys = [(0.0, [-5.0, 3.2, -2.0]), (30.0, [0.0, 3.6, 0.5]), (59.0, [5.0, 3.2, 2.5])]
            .map(|(frame, translation)| TransformKey { frame, translation, yaw_deg: 0.0 });
        lights.moving.push(MovingLight {
            name: "glowing sphere".into(),
            shape: MovingShape::sphere(0.25, 1, Vec3::new(150.0, 142.0, 128.0)),
            path: TransformPath::new(keys.to_vec()).expect("valid keys"),
        });
    }
    // A 1.2 m crate sliding 4.4 m across the courtyard, about 4 m in front of the camera
    // (about 12 pixels a frame at 1280×720), turning 60° on the way, clear of the benches; it
    // clears the floor by 1 mm so that no face is coplanar with it.
    let mut moving_objects = Vec::new();
    if let Some(material) = crate_material {
        let keys =
            [(0.0, [-3.0, 0.601, -2.2], 0.0), (30.0, [-2.8, 0.601, 0.0], 30.0), (59.0, [-3.0, 0.601, 2.2], 60.0)]
                .map(|(frame, translation, yaw_deg)| TransformKey { frame, translation, yaw_deg });
        moving_objects.push(MovingObject {
            name: "crate".into(),
            triangles: box_triangles(Vec3::splat(1.2)),
            material,
            path: TransformPath::new(keys.to_vec()).expect("valid keys"),
        });
    }
    // Walking slowly down the courtyard (0.76 m), panning ~7° to the left.
    let camera = path(
        60.0,
        &[
            (0.0, [-7.0, 1.6, 1.2], [6.0, 4.0, -2.0]),
            (30.0, [-6.65, 1.6, 1.08], [6.0, 4.1, -1.2]),
            (59.0, [-6.3, 1.6, 0.9], [6.0, 4.2, -0.5]),
        ],
    );
    Parts {
        mesh,
        materials,
        textures,
        lights,
        moving_objects,
        camera,
        tolerances: SceneTolerances { position: 0.08, depth_relative: 0.03, normal_degrees: 25.0 },
    }
}

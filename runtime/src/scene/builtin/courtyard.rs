//! `courtyard`: the San Miguel stand-in. A 20 × 20 m hacienda courtyard: arcaded galleries on
//! all four sides (turned columns, round arches, a closed upper storey with shuttered
//! windows and balconies), a terracotta floor, a three-tier fountain, five trees whose
//! canopies are tens of thousands of small leaves, potted bushes, hanging baskets with
//! trailing vines in every arch, and café tables under the arcades. Thin, dense, heavily
//! occluding geometry (about 3.4·10⁵ triangles), lit by the sun (0.5° disc) and a sky
//! gradient, like San Miguel's open courtyard.
//!
//! Axes: x and z across the courtyard (±10, arcade line at ±7), y up. The camera stands in
//! the west gallery and looks out through an arch.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use super::geom::{Builder, Rng};
use super::textures;
use super::util::{path, rgb};
use super::{Parts, Variant};
use crate::scene::folder::sunsky;
use crate::scene::light::{Environment, Lights};
use crate::scene::material::Material;
use crate::scene::model::SceneTolerances;

const HALF: f32 = 10.0;
const ARCADE: f32 = 7.0;
const BAY: f32 = 2.8;
const SPRING: f32 = 3.4;
const WALL_TOP: f32 = 5.2;
const SLAB_TOP: f32 = 5.5;
const EAVES: f32 = 8.5;

struct Mats {
    plaster: u32,
    stone: u32,
    wood: u32,
    pane: u32,
    iron: u32,
    terracotta: u32,
    leaves: [u32; 3],
    bark: u32,
    cloth: u32,
    water: u32,
    roof: u32,
}

fn column(h: f32) -> Vec<(f32, f32)> {
    let mut p = vec![(0.0, 0.0), (0.32, 0.0), (0.32, 0.12), (0.3, 0.16), (0.27, 0.2)];
    for k in 0..=12 {
        let t = k as f32 / 12.0;
        p.push((0.24 - 0.03 * t, 0.25 + (h - 0.7) * t));
    }
    p.extend([(0.24, h - 0.42), (0.23, h - 0.38), (0.27, h - 0.3), (0.33, h - 0.18), (0.36, h), (0.0, h)]);
    p
}

/// One side of the courtyard in local space: the arcade along x at z = +ARCADE, the gallery
/// behind it to z = +HALF. Covers local x in [−HALF, ARCADE] for the shared corner pieces, so
/// four copies rotated by 90° tile the square without overlaps.
fn side(b: &mut Builder, m: &Mats, rng: &mut Rng) {
    let (za, zb) = (ARCADE - 0.25, ARCADE + 0.25);
    // Columns (the k = 0 one is this side's corner column) and arches.
    for k in 0..5 {
        let x = -ARCADE + BAY * k as f32;
        b.use_material(m.stone);
        b.lathe(Vec3::new(x, 0.0, ARCADE), &column(SPRING - 0.1), 28, false);
        b.cuboid(Vec3::new(x - 0.34, SPRING - 0.1, ARCADE - 0.34), Vec3::new(x + 0.34, SPRING, ARCADE + 0.34));
        b.use_material(m.plaster);
        b.arch((x, x + BAY), (za, zb), (SPRING, WALL_TOP), 28);
        // A hanging basket in the middle of the arch with trailing vines.
        let c = Vec3::new(x + BAY / 2.0, 3.75, ARCADE);
        b.use_material(m.iron);
        b.cylinder(c + Vec3::Y * 0.3, Vec3::new(c.x, SPRING + BAY / 2.0, ARCADE), 0.006, 0.006, 6, false);
        b.use_material(m.terracotta);
        b.lathe(c, &[(0.0, 0.0), (0.1, 0.0), (0.17, 0.12), (0.18, 0.2), (0.15, 0.2), (0.0, 0.19)], 24, false);
        b.use_material(m.leaves[k % 3]);
        for _ in 0..7 {
            let a = rng.range(0.0, TAU);
            let out = Vec3::new(a.cos(), 0.0, a.sin());
            let len = rng.range(0.4, 1.0);
            let strand: Vec<Vec3> = (0..=10)
                .map(|i| {
                    c + Vec3::Y * 0.18 + out * (0.17 + 0.12 * (i as f32 / 10.0).sqrt())
                        - Vec3::Y * (len * i as f32 / 10.0)
                })
                .collect();
            b.use_material(m.bark);
            b.tube(&strand, 5, |_| 0.004);
            b.use_material(m.leaves[k % 3]);
            for i in 1..=10 {
                let p = strand[i];
                let d = Vec3::new(rng.range(-1.0, 1.0), rng.range(-0.5, 0.3), rng.range(-1.0, 1.0));
                b.leaf(p, d, Vec3::Y, rng.range(0.05, 0.09), rng.range(0.025, 0.04), 0.25);
                b.leaf(p, -d, Vec3::Y, rng.range(0.05, 0.09), rng.range(0.025, 0.04), 0.25);
            }
        }
    }
    // Gallery: slab, outer wall, floor tiles are the courtyard floor.
    b.use_material(m.plaster);
    b.cuboid(Vec3::new(-HALF, WALL_TOP, za), Vec3::new(ARCADE - 0.25, SLAB_TOP, HALF));
    b.plane(Vec3::new(ARCADE, 0.0, HALF), Vec3::NEG_X * (HALF + ARCADE), Vec3::Y * WALL_TOP, 17, 5, Vec2::ONE);
    // Doors in the gallery's back wall.
    b.use_material(m.wood);
    for x in [-4.2f32, 1.4] {
        b.cuboid(Vec3::new(x - 0.6, 0.0, HALF - 0.06), Vec3::new(x + 0.6, 2.4, HALF));
        b.use_material(m.iron);
        b.cylinder(Vec3::new(x + 0.4, 1.0, HALF - 0.07), Vec3::new(x + 0.4, 1.1, HALF - 0.07), 0.015, 0.015, 8, true);
        b.use_material(m.wood);
    }
    // Upper storey: facade, shuttered windows with balconies, roof.
    b.use_material(m.plaster);
    b.cuboid(Vec3::new(-ARCADE - 0.25, SLAB_TOP, za), Vec3::new(ARCADE - 0.25, EAVES, zb));
    for k in 0..5 {
        let x = -ARCADE + BAY * (k as f32 + 0.5);
        b.use_material(m.pane);
        b.cuboid(Vec3::new(x - 0.45, 6.1, za - 0.02), Vec3::new(x + 0.45, 7.7, za));
        b.use_material(m.wood);
        for s in [-1.0f32, 1.0] {
            let open = rng.range(60.0, 110.0);
            let hinge = Vec3::new(x + s * 0.47, 6.1, za - 0.03);
            b.at(hinge, s * open, |b| {
                b.cuboid(
                    Vec3::new(if s < 0.0 { -0.45 } else { 0.0 }, 0.0, -0.03),
                    Vec3::new(if s < 0.0 { 0.0 } else { 0.45 }, 1.6, 0.0),
                )
            });
        }
        b.use_material(m.stone);
        b.cuboid(Vec3::new(x - 0.65, 5.95, za - 0.45), Vec3::new(x + 0.65, 6.05, za));
        b.use_material(m.iron);
        b.cylinder(Vec3::new(x - 0.63, 6.95, za - 0.43), Vec3::new(x + 0.63, 6.95, za - 0.43), 0.012, 0.012, 8, false);
        for i in 0..=10 {
            let xb = x - 0.6 + 1.2 * i as f32 / 10.0;
            b.cylinder(Vec3::new(xb, 6.05, za - 0.43), Vec3::new(xb, 6.95, za - 0.43), 0.008, 0.008, 6, false);
        }
    }
    b.use_material(m.roof);
    b.cuboid(Vec3::new(-HALF, EAVES, za), Vec3::new(ARCADE - 0.25, EAVES + 0.2, HALF));
    b.use_material(m.stone);
    b.cuboid(Vec3::new(-ARCADE + 0.25, EAVES - 0.15, za - 0.35), Vec3::new(ARCADE - 0.25, EAVES + 0.25, za));

    // Café tables in the gallery (away from the camera's bay).
    for x in [-5.6f32, 2.8] {
        let t = Vec3::new(x, 0.0, 8.6);
        b.use_material(m.iron);
        b.lathe(
            t,
            &[(0.0, 0.0), (0.25, 0.0), (0.25, 0.02), (0.04, 0.06), (0.03, 0.7), (0.06, 0.72), (0.0, 0.72)],
            32,
            false,
        );
        b.use_material(m.wood);
        b.lathe(t + Vec3::Y * 0.72, &[(0.0, 0.0), (0.5, 0.0), (0.52, 0.015), (0.5, 0.03), (0.0, 0.03)], 48, false);
        b.use_material(m.cloth);
        b.lathe(t + Vec3::Y * 0.751, &[(0.0, 0.0), (0.3, 0.0), (0.3, 0.003), (0.0, 0.003)], 32, false);
        for j in 0..4 {
            let a = TAU * (j as f32 + 0.3 * rng.f32()) / 4.0;
            let d = Vec3::new(a.cos(), 0.0, a.sin());
            let c = t + d * 0.72;
            let yaw = (-d.x).atan2(-d.z).to_degrees() + 180.0;
            b.at(c, yaw, |b| {
                b.use_material(m.iron);
                for (lx, lz) in [(-0.17f32, -0.17f32), (0.17, -0.17), (-0.17, 0.17), (0.17, 0.17)] {
                    b.cylinder(Vec3::new(lx, 0.0, lz), Vec3::new(lx, 0.45, lz), 0.01, 0.01, 8, false);
                }
                b.use_material(m.wood);
                b.rounded_box(Vec3::new(0.0, 0.46, 0.0), Vec3::new(0.2, 0.015, 0.2), 0.01, 4);
                b.rounded_box(Vec3::new(0.0, 0.7, 0.19), Vec3::new(0.2, 0.12, 0.012), 0.008, 4);
            });
        }
    }

    // Potted bushes along the arcade, courtyard side.
    for k in 0..4 {
        let x = -ARCADE + BAY * (k as f32 + 1.0);
        let p = Vec3::new(x + rng.range(-0.3, 0.3), 0.0, ARCADE - 0.85);
        bush(b, m, rng, p, 0.28, 0.55, 260);
    }
}

/// A pot with a round bush of `n` leaves.
fn bush(b: &mut Builder, m: &Mats, rng: &mut Rng, p: Vec3, r: f32, size: f32, n: usize) {
    b.use_material(m.terracotta);
    b.lathe(
        p,
        &[
            (0.0, 0.0),
            (r * 0.7, 0.0),
            (r, r * 1.4),
            (r * 1.08, r * 1.5),
            (r * 0.95, r * 1.5),
            (r * 0.95, r * 1.35),
            (0.0, r * 1.35),
        ],
        32,
        false,
    );
    let centre = p + Vec3::Y * (r * 1.4 + size * 0.8);
    b.use_material(m.bark);
    for _ in 0..5 {
        let tip = centre + rng.unit() * size * 0.6;
        b.tube(&[p + Vec3::Y * r * 1.3, (p + Vec3::Y * r * 1.3 + tip) * 0.5, tip], 5, |t| 0.012 * (1.0 - 0.7 * t));
    }
    b.use_material(m.leaves[(rng.next_u64() % 3) as usize]);
    for _ in 0..n {
        let d = rng.unit();
        let q = centre + d * size * rng.f32().cbrt() * Vec3::new(1.0, 0.8, 1.0);
        b.leaf(q, d + rng.unit() * 0.8, Vec3::Y, rng.range(0.06, 0.11), rng.range(0.03, 0.05), 0.3);
    }
}

/// A tree: a curved trunk, two levels of branches and a leaf cluster at every tip.
fn tree(b: &mut Builder, m: &Mats, rng: &mut Rng, base: Vec3, leaves_per_tip: usize) {
    let lean = Vec3::new(rng.range(-0.3, 0.3), 0.0, rng.range(-0.3, 0.3));
    let trunk: Vec<Vec3> = (0..=12)
        .map(|i| {
            let t = i as f32 / 12.0;
            base + Vec3::Y * (2.6 * t) + lean * (t * t) + Vec3::new(0.08 * (PI * 2.0 * t).sin(), 0.0, 0.0)
        })
        .collect();
    b.use_material(m.bark);
    b.tube(&trunk, 14, |t| 0.17 - 0.07 * t);
    let top = trunk[12];
    let first = rng.range(0.0, TAU);
    for i in 0..4 {
        let a = first + TAU * i as f32 / 4.0 + rng.range(-0.3, 0.3);
        let dir = Vec3::new(a.cos(), rng.range(0.9, 1.4), a.sin()).normalize();
        let end = top + dir * rng.range(1.0, 1.4);
        let mid = (top + end) * 0.5 + Vec3::Y * 0.1;
        b.use_material(m.bark);
        b.tube(&[top - dir * 0.1, mid, end], 9, |t| 0.09 - 0.04 * t);
        for _ in 0..3 {
            let d2 = (dir + rng.unit() * 0.8 + Vec3::Y * 0.3).normalize();
            let tip = end + d2 * rng.range(0.55, 0.85);
            b.use_material(m.bark);
            b.tube(&[end - dir * 0.05, (end + tip) * 0.5, tip], 6, |t| 0.045 - 0.03 * t);
            // Leaves on twigs around the tip: a cluster, denser near the centre.
            b.use_material(m.leaves[(rng.next_u64() % 3) as usize]);
            for _ in 0..leaves_per_tip {
                let d = rng.unit();
                let q = tip + d * 0.75 * rng.f32().sqrt() * Vec3::new(1.0, 0.7, 1.0);
                let facing = (d + Vec3::Y * 0.8 + rng.unit() * 0.6).normalize();
                let along = facing.cross(rng.unit()).normalize_or(Vec3::X);
                b.leaf(q, along, facing, rng.range(0.07, 0.12), rng.range(0.035, 0.055), 0.25);
            }
        }
    }
}

fn fountain(b: &mut Builder, m: &Mats) {
    b.use_material(m.stone);
    let mut basin = vec![
        (0.0, 0.0),
        (1.7, 0.0),
        (1.75, 0.05),
        (1.75, 0.45),
        (1.8, 0.5),
        (1.8, 0.56),
        (1.6, 0.56),
        (1.58, 0.5),
        (1.58, 0.4),
    ];
    basin.push((0.0, 0.4));
    b.lathe(Vec3::ZERO, &basin, 96, false);
    b.use_material(m.water);
    b.disc(Vec3::new(0.0, 0.42, 0.0), Vec3::Y, 1.58, 96);
    b.use_material(m.stone);
    let mut col = vec![(0.0, 0.4), (0.35, 0.4), (0.3, 0.5)];
    for k in 0..=10 {
        let t = k as f32 / 10.0;
        col.push((0.18 + 0.05 * (PI * 3.0 * t).cos(), 0.55 + 0.9 * t));
    }
    col.extend([
        (0.3, 1.5),
        (0.75, 1.62),
        (0.8, 1.7),
        (0.72, 1.72),
        (0.2, 1.66),
        (0.15, 1.9),
        (0.1, 2.3),
        (0.35, 2.38),
        (0.38, 2.44),
        (0.3, 2.45),
        (0.08, 2.5),
        (0.1, 2.7),
        (0.0, 2.78),
    ]);
    b.lathe(Vec3::ZERO, &col, 64, false);
}

pub(crate) fn build(_variant: Variant) -> Parts {
    let mut rng = Rng::new(0x5A11_0004);
    let mut b = Builder::new();
    let tiles = b.texture(textures::terracotta(41));
    let m = Mats {
        plaster: b.material(Material::diffuse("plaster", rgb(0.86, 0.78, 0.62))),
        stone: b.material(Material::diffuse("stone", rgb(0.7, 0.66, 0.58))),
        wood: b.material(Material::diffuse("wood", rgb(0.42, 0.26, 0.14))),
        pane: b.material(Material::diffuse("window-pane", rgb(0.08, 0.1, 0.13))),
        iron: b.material(Material::diffuse("wrought-iron", rgb(0.12, 0.12, 0.12))),
        terracotta: b.material(Material::diffuse("terracotta", rgb(0.7, 0.38, 0.24))),
        leaves: [
            b.material(Material::diffuse("leaves-a", rgb(0.18, 0.38, 0.12))),
            b.material(Material::diffuse("leaves-b", rgb(0.26, 0.45, 0.14))),
            b.material(Material::diffuse("leaves-c", rgb(0.34, 0.42, 0.16))),
        ],
        bark: b.material(Material::diffuse("bark", rgb(0.3, 0.24, 0.18))),
        cloth: b.material(Material::diffuse("table-cloth", rgb(0.85, 0.82, 0.75))),
        water: b.material(Material::diffuse("water", rgb(0.12, 0.2, 0.22))),
        roof: b.material(Material::diffuse("roof-tiles", rgb(0.55, 0.28, 0.18))),
    };
    let floor =
        b.material(Material { albedo_texture: Some(tiles), ..Material::diffuse("floor", rgb(0.6, 0.35, 0.25)) });

    b.use_material(floor);
    b.plane(Vec3::new(-HALF, 0.0, HALF), Vec3::X * 2.0 * HALF, Vec3::NEG_Z * 2.0 * HALF, 20, 20, Vec2::splat(10.0));
    for k in 0..4 {
        b.at(Vec3::ZERO, 90.0 * k as f32, |b| side(b, &m, &mut rng));
    }
    fountain(&mut b, &m);
    for base in [
        Vec3::new(-4.0, 0.0, -4.0),
        Vec3::new(4.2, 0.0, -3.8),
        Vec3::new(-3.8, 0.0, 4.2),
        Vec3::new(4.5, 0.0, 4.4),
        Vec3::new(0.6, 0.0, -5.3),
    ] {
        tree(&mut b, &m, &mut rng, base, 900);
    }

    let (mesh, materials, textures) = b.finish();
    let (sun, sky) = sunsky(Vec3::new(0.35, 0.8, 0.45), 2.5, 4.5, 2.0, 0.15);
    let lights = Lights { sun: Some(sun), environment: Some(Environment::Sky(sky)), ..Lights::default() };
    // Stepping out of the west gallery towards the arch (0.86 m), panning right.
    let camera = path(
        60.0,
        &[
            (0.0, [-8.3, 1.6, 0.4], [2.0, 2.0, -1.0]),
            (30.0, [-7.95, 1.6, 0.15], [2.0, 2.0, -1.8]),
            (59.0, [-7.6, 1.6, -0.1], [2.0, 2.0, -2.6]),
        ],
    );
    Parts {
        mesh,
        materials,
        textures,
        lights,
        moving_objects: Vec::new(),
        camera,
        tolerances: SceneTolerances { position: 0.03, depth_relative: 0.02, normal_degrees: 25.0 },
    }
}

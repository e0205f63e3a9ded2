//! `living-room`: the Living Room stand-in. A 6 × 4.5 m room, 2.8 m high, lit by daylight
//! through two tall windows in the left wall (emissive panels just outside the openings, the
//! way the original's sky enters through its windows) and a floor lamp. Furnished with a sofa
//! and two armchairs of rounded cushions, a coffee table on turned legs, a rug, a bookcase
//! full of books, a sideboard with vases, curtains, a chandelier, a potted plant and two
//! pictures. About 1.1·10⁵ triangles.
//!
//! Axes: x across (0 = window wall, 6 = right wall), z from the front wall (0) to the back
//! wall (4.5), y up. The moving-light variant dims the windows to 30 % and adds a lantern
//! (point light) carried across the room.

use glam::{Vec2, Vec3};

use super::geom::{Builder, Rng};
use super::textures;
use super::util::{path, rgb};
use super::{Parts, Variant};
use crate::scene::light::{Lights, MovingLight, MovingShape};
use crate::scene::material::Material;
use crate::scene::model::SceneTolerances;
use crate::scene::path::{TransformKey, TransformPath};

const W: f32 = 6.0;
const D: f32 = 4.5;
const H: f32 = 2.8;
const WINDOWS: [(f32, f32); 2] = [(0.8, 2.0), (2.6, 3.8)];
const WIN_Y: (f32, f32) = (0.7, 2.5);
const REVEAL: f32 = 0.25;
const DAYLIGHT: Vec3 = Vec3::new(5.5, 6.0, 6.8);

fn turned_leg(h: f32) -> Vec<(f32, f32)> {
    let mut p = vec![(0.0, 0.0), (0.025, 0.0)];
    for k in 0..=10 {
        let t = k as f32 / 10.0;
        p.push((0.022 + 0.012 * (std::f32::consts::TAU * 1.5 * t).sin().abs(), 0.02 + (h - 0.06) * t));
    }
    p.extend([(0.035, h - 0.02), (0.035, h), (0.0, h)]);
    p
}

fn vase(h: f32, r: f32) -> Vec<(f32, f32)> {
    let mut p = vec![(0.0, 0.0)];
    for k in 0..=18 {
        let t = k as f32 / 18.0;
        let bulge = (std::f32::consts::PI * t * 0.9).sin();
        p.push((r * (0.45 + 0.55 * bulge) + 0.3 * r * (t - 0.8).max(0.0) * 5.0, h * t));
    }
    p
}

/// A cushioned seat: base, seat cushions, back cushions and arms, in local space with the
/// seat facing −z (the back at +z), centred on x = 0, `width` wide.
fn seat(b: &mut Builder, width: f32, cushions: usize, fabric: u32, legs: u32, n: usize) {
    b.use_material(legs);
    for (x, z) in [(-1.0f32, -1.0f32), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        b.cylinder(
            Vec3::new(x * (width / 2.0 - 0.1), 0.0, z * 0.35),
            Vec3::new(x * (width / 2.0 - 0.1), 0.1, z * 0.35),
            0.025,
            0.02,
            12,
            true,
        );
    }
    b.use_material(fabric);
    b.rounded_box(Vec3::new(0.0, 0.26, 0.0), Vec3::new(width / 2.0, 0.16, 0.43), 0.05, n);
    let arm = 0.16;
    let inner = width - 2.0 * arm;
    let cw = inner / cushions as f32;
    for i in 0..cushions {
        let x = -inner / 2.0 + cw * (i as f32 + 0.5);
        b.rounded_box(Vec3::new(x, 0.5, -0.06), Vec3::new(cw / 2.0 - 0.005, 0.08, 0.34), 0.06, n);
        b.rounded_box(Vec3::new(x, 0.76, 0.3), Vec3::new(cw / 2.0 - 0.005, 0.24, 0.11), 0.08, n);
    }
    for s in [-1.0f32, 1.0] {
        b.rounded_box(Vec3::new(s * (width / 2.0 - arm / 2.0), 0.5, 0.0), Vec3::new(arm / 2.0, 0.22, 0.43), 0.06, n);
    }
}

pub(crate) fn build(variant: Variant) -> Parts {
    let mut rng = Rng::new(0x11F1_0002);
    let mut b = Builder::new();
    let planks = b.texture(textures::planks(21, Vec3::new(0.55, 0.36, 0.2)));
    let painting = b.texture(textures::painting(22));
    let floor =
        b.material(Material { albedo_texture: Some(planks), ..Material::diffuse("floor", rgb(0.5, 0.33, 0.2)) });
    let wall = b.material(Material::diffuse("wall", rgb(0.86, 0.85, 0.82)));
    let ceiling = b.material(Material::diffuse("ceiling", rgb(0.92, 0.92, 0.9)));
    let trim = b.material(Material::diffuse("trim", rgb(0.95, 0.95, 0.93)));
    let fabric = b.material(Material::diffuse("sofa-fabric", rgb(0.72, 0.7, 0.66)));
    let fabric2 = b.material(Material::diffuse("armchair-fabric", rgb(0.42, 0.46, 0.55)));
    let wood = b.material(Material::diffuse("dark-wood", rgb(0.3, 0.18, 0.1)));
    let rug = b.material(Material::diffuse("rug", rgb(0.55, 0.25, 0.2)));
    let curtain = b.material(Material::diffuse("curtain", rgb(0.9, 0.88, 0.8)));
    let ceramic = b.material(Material::diffuse("ceramic", rgb(0.8, 0.82, 0.85)));
    let brass = b.material(Material::diffuse("brass", rgb(0.7, 0.55, 0.3)));
    let leaf = b.material(Material::diffuse("leaf", rgb(0.2, 0.42, 0.15)));
    let picture =
        b.material(Material { albedo_texture: Some(painting), ..Material::diffuse("picture", rgb(0.45, 0.5, 0.45)) });
    let books: Vec<u32> =
        [(0.6, 0.15, 0.12), (0.15, 0.3, 0.5), (0.2, 0.45, 0.25), (0.75, 0.65, 0.4), (0.4, 0.2, 0.35), (0.85, 0.8, 0.7)]
            .iter()
            .enumerate()
            .map(|(i, &(r, g, bl))| b.material(Material::diffuse(format!("book-{i}"), rgb(r, g, bl))))
            .collect();
    let dim = if variant == Variant::MovingLight { 0.3 } else { 1.0 };
    let daylight = b.material(Material::emitter("daylight", DAYLIGHT * dim, Vec3::ZERO));
    let bulb = b.material(Material::emitter("lamp-bulb", Vec3::new(40.0, 30.0, 18.0), Vec3::splat(0.8)));

    // Shell: floor, ceiling, three plain walls, the window wall in pieces with reveals.
    b.use_material(floor);
    b.plane(Vec3::new(0.0, 0.0, D), Vec3::X * W, Vec3::NEG_Z * D, 12, 9, Vec2::new(3.0, 2.25));
    b.use_material(ceiling);
    b.plane(Vec3::new(0.0, H, 0.0), Vec3::X * W, Vec3::Z * D, 12, 9, Vec2::ONE);
    b.use_material(wall);
    b.plane(Vec3::new(W, 0.0, 0.0), Vec3::Z * D, Vec3::Y * H, 9, 6, Vec2::ONE); // right, faces −x
    b.plane(Vec3::new(W, 0.0, D), Vec3::NEG_X * W, Vec3::Y * H, 12, 6, Vec2::ONE); // back, faces −z
    b.plane(Vec3::new(0.0, 0.0, 0.0), Vec3::X * W, Vec3::Y * H, 12, 6, Vec2::ONE); // front, faces +z
    let x_wall = |b: &mut Builder, z0: f32, z1: f32, y0: f32, y1: f32| {
        b.quad(
            [Vec3::new(0.0, y0, z0), Vec3::new(0.0, y0, z1), Vec3::new(0.0, y1, z1), Vec3::new(0.0, y1, z0)],
            Vec3::X,
            [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        );
    };
    x_wall(&mut b, 0.0, D, 0.0, WIN_Y.0);
    x_wall(&mut b, 0.0, D, WIN_Y.1, H);
    let mut z = 0.0;
    for (z0, z1) in WINDOWS {
        x_wall(&mut b, z, z0, WIN_Y.0, WIN_Y.1);
        z = z1;
    }
    x_wall(&mut b, z, D, WIN_Y.0, WIN_Y.1);
    for (z0, z1) in WINDOWS {
        let (y0, y1) = WIN_Y;
        b.use_material(trim);
        // Reveals (sill, head, jambs), facing into the opening.
        b.quad(
            [Vec3::new(-REVEAL, y0, z0), Vec3::new(0.0, y0, z0), Vec3::new(0.0, y0, z1), Vec3::new(-REVEAL, y0, z1)],
            Vec3::Y,
            [Vec2::ZERO; 4],
        );
        b.quad(
            [Vec3::new(-REVEAL, y1, z0), Vec3::new(-REVEAL, y1, z1), Vec3::new(0.0, y1, z1), Vec3::new(0.0, y1, z0)],
            Vec3::NEG_Y,
            [Vec2::ZERO; 4],
        );
        b.quad(
            [Vec3::new(-REVEAL, y0, z0), Vec3::new(-REVEAL, y1, z0), Vec3::new(0.0, y1, z0), Vec3::new(0.0, y0, z0)],
            Vec3::Z,
            [Vec2::ZERO; 4],
        );
        b.quad(
            [Vec3::new(-REVEAL, y0, z1), Vec3::new(0.0, y0, z1), Vec3::new(0.0, y1, z1), Vec3::new(-REVEAL, y1, z1)],
            Vec3::NEG_Z,
            [Vec2::ZERO; 4],
        );
        // Mullion and transom.
        let zm = 0.5 * (z0 + z1);
        b.cuboid(Vec3::new(-0.15, y0, zm - 0.03), Vec3::new(-0.09, y1, zm + 0.03));
        b.cuboid(Vec3::new(-0.15, 1.95, z0), Vec3::new(-0.09, 2.01, z1));
        // Sill board.
        b.cuboid(Vec3::new(-0.02, y0 - 0.04, z0 - 0.08), Vec3::new(0.08, y0, z1 + 0.08));
        // Daylight panel closing the opening, facing the room.
        b.use_material(daylight);
        b.quad(
            [
                Vec3::new(-REVEAL, y0, z0),
                Vec3::new(-REVEAL, y1, z0),
                Vec3::new(-REVEAL, y1, z1),
                Vec3::new(-REVEAL, y0, z1),
            ],
            Vec3::X,
            [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        );
        // Curtains either side, turned to hang along the wall (local +z → +x).
        b.use_material(curtain);
        for (zc, wdt) in [(z0 - 0.05, 0.45f32), (z1 + 0.5, 0.45)] {
            b.at(Vec3::new(0.1, H - 0.15, zc), 90.0, |b| {
                b.cloth(Vec3::ZERO, Vec2::new(wdt, H - 0.17), (4.0, 0.04), (40, 80))
            });
        }
        b.use_material(brass);
        b.cylinder(Vec3::new(0.1, H - 0.12, z0 - 0.6), Vec3::new(0.1, H - 0.12, z1 + 0.6), 0.015, 0.015, 12, true);
    }
    // Skirting and cornice.
    b.use_material(trim);
    b.cuboid(Vec3::new(W - 0.015, 0.0, 0.0), Vec3::new(W, 0.1, D));
    b.cuboid(Vec3::new(0.0, 0.0, D - 0.015), Vec3::new(W, 0.1, D));
    b.cuboid(Vec3::new(0.0, 0.0, 0.0), Vec3::new(W, 0.1, 0.015));
    b.cuboid(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.015, 0.1, D));
    b.cuboid(Vec3::new(0.0, H - 0.08, D - 0.06), Vec3::new(W, H, D));
    b.cuboid(Vec3::new(W - 0.06, H - 0.08, 0.0), Vec3::new(W, H, D));

    // Sofa against the back wall, armchairs facing it.
    b.at(Vec3::new(3.2, 0.0, D - 0.5), 0.0, |b| seat(b, 2.3, 3, fabric, wood, 16));
    b.at(Vec3::new(1.7, 0.0, 1.75), 200.0, |b| seat(b, 1.0, 1, fabric2, wood, 16));
    b.at(Vec3::new(4.7, 0.0, 1.75), 160.0, |b| seat(b, 1.0, 1, fabric2, wood, 16));

    // Coffee table and rug.
    b.use_material(rug);
    b.cuboid(Vec3::new(1.9, 0.0, 1.9), Vec3::new(4.5, 0.012, 3.6));
    b.use_material(wood);
    b.rounded_box(Vec3::new(3.2, 0.43, 2.75), Vec3::new(0.6, 0.025, 0.32), 0.012, 10);
    b.cuboid(Vec3::new(2.7, 0.14, 2.5), Vec3::new(3.7, 0.16, 3.0));
    for (x, z) in [(2.68f32, 2.5f32), (3.72, 2.5), (2.68, 3.0), (3.72, 3.0)] {
        b.lathe(Vec3::new(x, 0.012, z), &turned_leg(0.395), 24, false);
    }
    b.use_material(ceramic);
    b.lathe(Vec3::new(3.0, 0.455, 2.7), &vase(0.28, 0.07), 48, false);
    b.use_material(brass);
    b.lathe(
        Vec3::new(3.45, 0.455, 2.85),
        &[(0.0, 0.0), (0.12, 0.0), (0.13, 0.01), (0.14, 0.05), (0.13, 0.05), (0.11, 0.012), (0.0, 0.012)],
        48,
        false,
    );

    // Bookcase on the back wall, right of the sofa.
    b.use_material(wood);
    let (bx0, bx1, bz0, bz1) = (4.65f32, 5.9f32, D - 0.34, D - 0.015);
    b.cuboid(Vec3::new(bx0, 0.0, bz0), Vec3::new(bx0 + 0.03, 2.1, bz1));
    b.cuboid(Vec3::new(bx1 - 0.03, 0.0, bz0), Vec3::new(bx1, 2.1, bz1));
    b.cuboid(Vec3::new(bx0, 0.0, bz1 - 0.01), Vec3::new(bx1, 2.1, bz1));
    for k in 0..6 {
        let y = 0.05 + 0.4 * k as f32;
        b.cuboid(Vec3::new(bx0, y, bz0), Vec3::new(bx1, y + 0.025, bz1));
        if k == 5 {
            break;
        }
        let mut x = bx0 + 0.035;
        while x < bx1 - 0.09 {
            let t = rng.range(0.02, 0.05);
            let h = rng.range(0.2, 0.34);
            let d = rng.range(0.18, 0.26);
            b.use_material(books[(rng.next_u64() % books.len() as u64) as usize]);
            if rng.f32() < 0.08 {
                // A leaning book.
                let lean = rng.range(8.0, 18.0);
                b.with(
                    glam::Affine3A::from_rotation_translation(
                        glam::Quat::from_rotation_z(-lean.to_radians()),
                        Vec3::new(x, y + 0.025, bz0 + 0.02),
                    ),
                    |b| {
                        b.cuboid(Vec3::ZERO, Vec3::new(t, h, d));
                    },
                );
                x += t + h * lean.to_radians().sin() + 0.01;
            } else {
                b.cuboid(Vec3::new(x, y + 0.025, bz0 + 0.02), Vec3::new(x + t, y + 0.025 + h, bz0 + 0.02 + d));
                x += t + 0.002;
            }
            b.use_material(wood);
        }
    }

    // Sideboard on the right wall with vases and a picture above.
    b.use_material(wood);
    b.rounded_box(Vec3::new(W - 0.23, 0.42, 2.6), Vec3::new(0.22, 0.38, 0.8), 0.015, 8);
    b.use_material(ceramic);
    for (k, (h, r)) in [(0.45f32, 0.09f32), (0.32, 0.07), (0.25, 0.1)].into_iter().enumerate() {
        b.lathe(Vec3::new(W - 0.24, 0.8, 2.1 + 0.45 * k as f32), &vase(h, r), 48, false);
    }
    b.use_material(picture);
    b.quad(
        [
            Vec3::new(W - 0.02, 1.3, 2.05),
            Vec3::new(W - 0.02, 1.3, 3.15),
            Vec3::new(W - 0.02, 2.1, 3.15),
            Vec3::new(W - 0.02, 2.1, 2.05),
        ],
        Vec3::NEG_X,
        [Vec2::ONE - Vec2::X, Vec2::ZERO, Vec2::Y, Vec2::ONE],
    );
    b.quad(
        [
            Vec3::new(2.6, 1.2, D - 0.02),
            Vec3::new(3.8, 1.2, D - 0.02),
            Vec3::new(3.8, 2.0, D - 0.02),
            Vec3::new(2.6, 2.0, D - 0.02),
        ],
        Vec3::NEG_Z,
        [Vec2::X, Vec2::ZERO, Vec2::Y, Vec2::ONE],
    );
    b.use_material(brass);
    b.cuboid(Vec3::new(2.55, 1.15, D - 0.03), Vec3::new(3.85, 1.2, D - 0.015));
    b.cuboid(Vec3::new(2.55, 2.0, D - 0.03), Vec3::new(3.85, 2.05, D - 0.015));

    // Floor lamp in the back-left corner: base, pole, open shade, bulb facing down.
    let lamp = Vec3::new(0.55, 0.0, D - 0.55);
    b.use_material(brass);
    b.lathe(lamp, &[(0.0, 0.0), (0.16, 0.0), (0.16, 0.02), (0.05, 0.05), (0.015, 0.07)], 32, false);
    b.cylinder(lamp + Vec3::Y * 0.06, lamp + Vec3::Y * 1.55, 0.012, 0.012, 12, false);
    b.use_material(curtain);
    b.lathe(lamp + Vec3::Y * 1.4, &[(0.22, 0.0), (0.13, 0.28)], 48, false);
    b.use_material(bulb);
    b.disc(lamp + Vec3::Y * 1.5, Vec3::NEG_Y, 0.05, 16);

    // Chandelier: a ring of arms with hanging drops.
    let ch = Vec3::new(3.0, H, 2.4);
    b.use_material(brass);
    b.cylinder(ch, ch - Vec3::Y * 0.5, 0.01, 0.01, 12, false);
    b.lathe(ch - Vec3::Y * 0.56, &[(0.0, 0.0), (0.06, 0.01), (0.07, 0.05), (0.02, 0.07)], 32, false);
    b.use_material(ceramic);
    for k in 0..12 {
        let a = std::f32::consts::TAU * k as f32 / 12.0;
        let d = Vec3::new(a.cos(), 0.0, a.sin());
        b.use_material(brass);
        let arm: Vec<Vec3> = (0..=12)
            .map(|i| {
                let t = i as f32 / 12.0;
                ch - Vec3::Y * 0.52 + d * (0.35 * t) + Vec3::Y * (0.12 * (std::f32::consts::PI * t).sin())
            })
            .collect();
        b.tube(&arm, 8, |_| 0.008);
        b.use_material(ceramic);
        for j in 0..4 {
            let p = ch - Vec3::Y * (0.58 + 0.06 * j as f32) + d * (0.12 + 0.07 * j as f32);
            b.lathe(p, &[(0.0, 0.0), (0.015, 0.02), (0.012, 0.045), (0.0, 0.055)], 12, false);
        }
        b.lathe(
            ch - Vec3::Y * 0.52 + d * 0.35,
            &[(0.0, 0.0), (0.025, 0.0), (0.02, 0.05), (0.012, 0.09), (0.0, 0.1)],
            16,
            false,
        );
    }

    // Potted plant by the right wall, between the sideboard and the bookcase.
    let pot = Vec3::new(W - 0.4, 0.0, 3.82);
    b.use_material(ceramic);
    b.lathe(
        pot,
        &[(0.0, 0.0), (0.16, 0.0), (0.2, 0.35), (0.22, 0.38), (0.19, 0.38), (0.19, 0.33), (0.0, 0.33)],
        40,
        false,
    );
    b.use_material(leaf);
    for _ in 0..28 {
        let dir = Vec3::new(rng.range(-1.0, 1.0), rng.range(1.2, 2.5), rng.range(-1.0, 1.0)).normalize();
        let len = rng.range(0.5, 1.1);
        let stem: Vec<Vec3> = (0..=8)
            .map(|i| pot + Vec3::Y * 0.33 + dir * (len * i as f32 / 8.0) - Vec3::Y * (0.15 * (i as f32 / 8.0).powi(2)))
            .collect();
        b.tube(&stem, 6, |t| 0.008 * (1.0 - 0.6 * t));
        for i in 2..=8 {
            let p = stem[i];
            let out = Vec3::new(rng.range(-1.0, 1.0), rng.range(-0.3, 0.6), rng.range(-1.0, 1.0));
            b.leaf(p, out + dir * 0.5, Vec3::Y, rng.range(0.1, 0.18), rng.range(0.04, 0.07), 0.3);
            b.leaf(p, -out + dir * 0.5, Vec3::Y, rng.range(0.1, 0.18), rng.range(0.04, 0.07), 0.3);
        }
    }

    let (mesh, materials, textures) = b.finish();
    let mut lights = Lights::default();
    if variant == Variant::MovingLight {
        let keys = [(0.0, [1.0, 1.4, 2.3]), (30.0, [2.7, 1.5, 2.0]), (59.0, [4.4, 1.4, 2.4])]
            .map(|(frame, translation)| TransformKey { frame, translation, yaw_deg: 0.0 });
        lights.moving.push(MovingLight {
            name: "carried lantern".into(),
            shape: MovingShape::Point { intensity: Vec3::new(5.0, 4.2, 3.0) },
            path: TransformPath::new(keys.to_vec()).expect("valid keys"),
        });
    }
    // Stepping in from the front-right (0.68 m), panning from the windows towards the sofa.
    let camera = path(
        60.0,
        &[
            (0.0, [4.9, 1.6, 0.55], [1.6, 1.0, 4.0]),
            (30.0, [4.62, 1.6, 0.7], [1.8, 1.0, 4.2]),
            (59.0, [4.3, 1.6, 0.88], [2.0, 1.0, 4.4]),
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

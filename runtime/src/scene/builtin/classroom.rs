//! `classroom`: the Classroom stand-in. An 8 × 10 m classroom, 3.2 m high: five rows of six
//! desks with tube-frame chairs, a blackboard and a cork notice board on the front wall, a
//! teacher's desk, lockers and a bookshelf at the back, curtains. Three windows in the left
//! wall let in the sun (a directional light with a 2° disc, so desks get sun patches) and the
//! sky (an analytic gradient); six ceiling panels are area lights. About 1.1·10⁵ triangles.
//!
//! Axes: x across (0 = window wall), z from the front wall (0) to the back wall (10), y up.
//! The mirror variant turns the notice board into a mirror (the paper's Figure 2 (h)).

use glam::{Affine3A, Quat, Vec2, Vec3};

use super::geom::{Builder, Rng};
use super::textures;
use super::util::{path, rgb};
use super::{Parts, Variant};
use crate::scene::folder::sunsky;
use crate::scene::light::{Environment, Lights};
use crate::scene::material::Material;
use crate::scene::model::SceneTolerances;

const W: f32 = 8.0;
const D: f32 = 10.0;
const H: f32 = 3.2;
const WINDOWS: [(f32, f32); 3] = [(2.0, 3.8), (4.6, 6.4), (7.2, 9.0)];
const WIN_Y: (f32, f32) = (0.9, 2.7);
const REVEAL: f32 = 0.3;

/// A polyline with its interior corners rounded by `k`-point quadratic arcs of size `r`.
fn bend_path(pts: &[Vec3], r: f32, k: usize) -> Vec<Vec3> {
    let mut out = vec![pts[0]];
    for i in 1..pts.len() - 1 {
        let (a, c, e) = (pts[i - 1], pts[i], pts[i + 1]);
        let r = r.min(0.45 * (c - a).length()).min(0.45 * (e - c).length());
        let (p0, p2) = (c + (a - c).normalize() * r, c + (e - c).normalize() * r);
        for j in 0..=k {
            let t = j as f32 / k as f32;
            out.push(p0 * (1.0 - t) * (1.0 - t) + c * 2.0 * t * (1.0 - t) + p2 * t * t);
        }
    }
    out.push(pts[pts.len() - 1]);
    out
}

/// A school chair in local space: seat facing −z, centred on x = 0.
fn chair(b: &mut Builder, frame: u32, wood: u32) {
    b.use_material(frame);
    for s in [-1.0f32, 1.0] {
        let x = s * 0.19;
        let base =
            [Vec3::new(x, 0.0, -0.19), Vec3::new(x, 0.43, -0.19), Vec3::new(x, 0.43, 0.17), Vec3::new(x, 0.0, 0.21)];
        b.tube(&bend_path(&base, 0.05, 6), 14, |_| 0.011);
        let post = [Vec3::new(x, 0.43, 0.17), Vec3::new(x, 0.62, 0.19), Vec3::new(x, 0.84, 0.23)];
        b.tube(&bend_path(&post, 0.06, 6), 14, |_| 0.011);
    }
    b.cylinder(Vec3::new(-0.19, 0.1, 0.2), Vec3::new(0.19, 0.1, 0.2), 0.009, 0.009, 12, false);
    b.cylinder(Vec3::new(-0.19, 0.1, -0.19), Vec3::new(0.19, 0.1, -0.19), 0.009, 0.009, 12, false);
    b.use_material(wood);
    b.rounded_box(Vec3::new(0.0, 0.45, -0.01), Vec3::new(0.21, 0.012, 0.2), 0.01, 6);
    b.with(Affine3A::from_rotation_translation(Quat::from_rotation_x(-0.12), Vec3::new(0.0, 0.73, 0.22)), |b| {
        b.rounded_box(Vec3::ZERO, Vec3::new(0.2, 0.1, 0.012), 0.01, 6);
    });
}

/// A pupil's desk in local space: top at 0.72 m, front edge at −z.
fn desk(b: &mut Builder, frame: u32, top: u32) {
    b.use_material(frame);
    for (x, z) in [(-0.3f32, -0.19f32), (0.3, -0.19), (-0.3, 0.19), (0.3, 0.19)] {
        b.cylinder(Vec3::new(x, 0.0, z), Vec3::new(x, 0.7, z), 0.013, 0.013, 16, false);
    }
    for z in [-0.19f32, 0.19] {
        b.cylinder(Vec3::new(-0.3, 0.15, z), Vec3::new(0.3, 0.15, z), 0.01, 0.01, 12, false);
    }
    b.cuboid(Vec3::new(-0.3, 0.56, -0.18), Vec3::new(0.3, 0.58, 0.16));
    b.use_material(top);
    b.rounded_box(Vec3::new(0.0, 0.71, 0.0), Vec3::new(0.33, 0.015, 0.23), 0.008, 4);
}

pub(crate) fn build(variant: Variant) -> Parts {
    let mut rng = Rng::new(0xC1A5_0003);
    let mut b = Builder::new();
    let planks = b.texture(textures::planks(31, Vec3::new(0.72, 0.55, 0.36)));
    let board_tex = b.texture(textures::blackboard(32));
    let cork_tex = b.texture(textures::cork(33));
    let floor =
        b.material(Material { albedo_texture: Some(planks), ..Material::diffuse("floor", rgb(0.66, 0.5, 0.33)) });
    let wall = b.material(Material::diffuse("wall", rgb(0.82, 0.84, 0.86)));
    let ceiling = b.material(Material::diffuse("ceiling", rgb(0.93, 0.93, 0.92)));
    let trim = b.material(Material::diffuse("window-frame", rgb(0.75, 0.76, 0.78)));
    let metal = b.material(Material::diffuse("chair-frame", rgb(0.55, 0.56, 0.58)));
    let wood = b.material(Material::diffuse("desk-wood", rgb(0.8, 0.62, 0.4)));
    let dark = b.material(Material::diffuse("dark-wood", rgb(0.35, 0.22, 0.13)));
    let board = b.material(Material {
        albedo_texture: Some(board_tex),
        ..Material::diffuse("blackboard", rgb(0.16, 0.24, 0.19))
    });
    let notice = if variant == Variant::Mirror {
        b.material(Material::mirror("notice-board", Vec3::splat(0.95)))
    } else {
        b.material(Material {
            albedo_texture: Some(cork_tex),
            ..Material::diffuse("notice-board", rgb(0.62, 0.45, 0.3))
        })
    };
    let locker = b.material(Material::diffuse("lockers", rgb(0.45, 0.55, 0.62)));
    let curtain = b.material(Material::diffuse("curtain", rgb(0.85, 0.83, 0.72)));
    let books: Vec<u32> = [(0.6, 0.15, 0.12), (0.15, 0.3, 0.5), (0.2, 0.45, 0.25), (0.75, 0.65, 0.4)]
        .iter()
        .enumerate()
        .map(|(i, &(r, g, bl))| b.material(Material::diffuse(format!("book-{i}"), rgb(r, g, bl))))
        .collect();
    let panel = b.material(Material::emitter("ceiling-panel", Vec3::new(8.0, 8.0, 7.7), Vec3::splat(0.8)));

    // Shell.
    b.use_material(floor);
    b.plane(Vec3::new(0.0, 0.0, D), Vec3::X * W, Vec3::NEG_Z * D, 16, 20, Vec2::new(4.0, 5.0));
    b.use_material(ceiling);
    b.plane(Vec3::new(0.0, H, 0.0), Vec3::X * W, Vec3::Z * D, 16, 20, Vec2::ONE);
    b.use_material(wall);
    b.plane(Vec3::new(W, 0.0, 0.0), Vec3::Z * D, Vec3::Y * H, 20, 6, Vec2::ONE);
    b.plane(Vec3::new(W, 0.0, D), Vec3::NEG_X * W, Vec3::Y * H, 16, 6, Vec2::ONE);
    b.plane(Vec3::new(0.0, 0.0, 0.0), Vec3::X * W, Vec3::Y * H, 16, 6, Vec2::ONE);
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
        b.use_material(wall);
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
        // Mullions, transom and sill.
        b.use_material(trim);
        for k in 1..3 {
            let zm = z0 + (z1 - z0) * k as f32 / 3.0;
            b.cuboid(Vec3::new(-0.2, y0, zm - 0.025), Vec3::new(-0.14, y1, zm + 0.025));
        }
        b.cuboid(Vec3::new(-0.2, 1.95, z0), Vec3::new(-0.14, 2.0, z1));
        b.cuboid(Vec3::new(-0.02, y0 - 0.04, z0 - 0.05), Vec3::new(0.12, y0, z1 + 0.05));
        b.use_material(curtain);
        for zc in [z0 - 0.02, z1 + 0.38] {
            b.at(Vec3::new(0.12, H - 0.2, zc), 90.0, |b| {
                b.cloth(Vec3::ZERO, Vec2::new(0.36, 2.3), (3.0, 0.035), (24, 64))
            });
        }
    }
    // Skirting.
    b.use_material(dark);
    b.cuboid(Vec3::new(W - 0.02, 0.0, 0.0), Vec3::new(W, 0.12, D));
    b.cuboid(Vec3::new(0.0, 0.0, D - 0.02), Vec3::new(W, 0.12, D));
    b.cuboid(Vec3::new(0.0, 0.0, 0.0), Vec3::new(W, 0.12, 0.02));

    // Front wall: blackboard (with chalk tray and frame) and the notice board.
    b.use_material(board);
    b.cuboid(Vec3::new(1.8, 0.9, 0.0), Vec3::new(5.8, 2.1, 0.03));
    b.use_material(dark);
    b.cuboid(Vec3::new(1.75, 0.86, 0.0), Vec3::new(5.85, 0.9, 0.09));
    b.cuboid(Vec3::new(1.75, 2.1, 0.0), Vec3::new(5.85, 2.15, 0.04));
    b.cuboid(Vec3::new(1.75, 0.9, 0.0), Vec3::new(1.8, 2.1, 0.04));
    b.cuboid(Vec3::new(5.8, 0.9, 0.0), Vec3::new(5.85, 2.1, 0.04));
    b.use_material(notice);
    b.cuboid(Vec3::new(6.3, 1.0, 0.0), Vec3::new(7.5, 2.0, 0.025));
    b.use_material(dark);
    b.cuboid(Vec3::new(6.26, 0.96, 0.0), Vec3::new(7.54, 1.0, 0.04));
    b.cuboid(Vec3::new(6.26, 2.0, 0.0), Vec3::new(7.54, 2.04, 0.04));
    b.cuboid(Vec3::new(6.26, 1.0, 0.0), Vec3::new(6.3, 2.0, 0.04));
    b.cuboid(Vec3::new(7.5, 1.0, 0.0), Vec3::new(7.54, 2.0, 0.04));

    // Teacher's desk and lectern.
    b.use_material(wood);
    b.rounded_box(Vec3::new(4.0, 0.75, 1.3), Vec3::new(0.75, 0.02, 0.35), 0.008, 6);
    b.use_material(dark);
    b.cuboid(Vec3::new(3.28, 0.0, 1.0), Vec3::new(3.32, 0.73, 1.6));
    b.cuboid(Vec3::new(4.68, 0.0, 1.0), Vec3::new(4.72, 0.73, 1.6));
    b.cuboid(Vec3::new(3.32, 0.25, 1.55), Vec3::new(4.68, 0.73, 1.58));
    b.cuboid(Vec3::new(1.0, 0.0, 1.2), Vec3::new(1.5, 1.1, 1.6));

    // Desks and chairs: six columns with a central aisle, five rows.
    for (r, zd) in [3.0f32, 4.2, 5.4, 6.6, 7.8].into_iter().enumerate() {
        for (c, xd) in [1.3f32, 2.3, 3.3, 5.3, 6.3, 7.3].into_iter().enumerate() {
            let jx = rng.range(-0.04, 0.04);
            let yaw = rng.range(-3.0, 3.0);
            b.at(Vec3::new(xd + jx, 0.0, zd), yaw, |b| desk(b, metal, wood));
            let chair_yaw = rng.range(-8.0, 8.0);
            let pull = rng.range(0.0, 0.12) + if (r + c) % 5 == 0 { 0.1 } else { 0.0 };
            b.at(Vec3::new(xd + jx * 2.0, 0.0, zd + 0.5 + pull), chair_yaw, |b| chair(b, metal, wood));
        }
    }

    // Back wall: lockers and a bookshelf.
    b.use_material(locker);
    for k in 0..8 {
        let x0 = 5.5 + 0.3 * k as f32;
        b.cuboid(Vec3::new(x0 + 0.005, 0.0, D - 0.45), Vec3::new(x0 + 0.295, 1.8, D - 0.02));
    }
    b.use_material(dark);
    b.cuboid(Vec3::new(0.5, 0.0, D - 0.32), Vec3::new(3.5, 0.04, D - 0.02));
    for k in 0..4 {
        let y = 0.05 + 0.42 * k as f32;
        b.use_material(dark);
        b.cuboid(Vec3::new(0.5, y, D - 0.32), Vec3::new(3.5, y + 0.025, D - 0.02));
        let mut x = 0.52;
        while x < 3.4 {
            let t = rng.range(0.02, 0.05);
            let h = rng.range(0.18, 0.32);
            b.use_material(books[(rng.next_u64() % books.len() as u64) as usize]);
            b.cuboid(Vec3::new(x, y + 0.025, D - 0.3), Vec3::new(x + t, y + 0.025 + h, D - 0.06));
            x += t + 0.003;
        }
    }
    b.use_material(dark);
    b.cuboid(Vec3::new(0.5, 0.0, D - 0.32), Vec3::new(0.52, 1.72, D - 0.02));
    b.cuboid(Vec3::new(3.48, 0.0, D - 0.32), Vec3::new(3.5, 1.72, D - 0.02));
    // Door in the right wall.
    b.cuboid(Vec3::new(W - 0.03, 0.0, 1.0), Vec3::new(W, 2.1, 2.0));

    // Ceiling panels: housings and downward-facing emitters.
    for x in [2.5f32, 5.5] {
        for zc in [2.5f32, 5.5, 8.5] {
            b.use_material(trim);
            b.cuboid(Vec3::new(x - 0.7, H - 0.06, zc - 0.2), Vec3::new(x + 0.7, H, zc + 0.2));
            b.use_material(panel);
            let y = H - 0.061;
            b.quad(
                [
                    Vec3::new(x - 0.6, y, zc - 0.15),
                    Vec3::new(x + 0.6, y, zc - 0.15),
                    Vec3::new(x + 0.6, y, zc + 0.15),
                    Vec3::new(x - 0.6, y, zc + 0.15),
                ],
                Vec3::NEG_Y,
                [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            );
        }
    }

    let (mesh, materials, textures) = b.finish();
    // Sun from the window side, ~28° up, through the windows onto the desks.
    let (sun, sky) = sunsky(Vec3::new(-0.8, 0.45, 0.3), 6.0, 10.0, 7.5, 0.15);
    let lights = Lights { sun: Some(sun), environment: Some(Environment::Sky(sky)), ..Lights::default() };
    // From the back of the room down the aisle (0.7 m), panning right towards the notice board.
    let camera = path(
        55.0,
        &[
            (0.0, [4.3, 1.6, 9.3], [3.9, 1.2, 0.0]),
            (30.0, [4.28, 1.6, 8.95], [4.4, 1.22, 0.0]),
            (59.0, [4.25, 1.6, 8.6], [4.9, 1.25, 0.0]),
        ],
    );
    Parts {
        mesh,
        materials,
        textures,
        lights,
        moving_objects: Vec::new(),
        camera,
        tolerances: SceneTolerances { position: 0.04, depth_relative: 0.02, normal_degrees: 25.0 },
    }
}

//! `cornell`: a closed 2 × 2 × 4 m box (red left wall, green right wall), two white blocks and
//! a square ceiling light. 34 triangles. The box is closed so no ray escapes; the camera
//! stands inside near the front wall.

use glam::{Vec2, Vec3};

use super::geom::Builder;
use super::util::{path, rgb};
use super::{Parts, Variant};
use crate::scene::light::Lights;
use crate::scene::material::Material;
use crate::scene::model::SceneTolerances;

pub(crate) fn build(_variant: Variant) -> Parts {
    let mut b = Builder::new();
    let white = b.material(Material::diffuse("white", rgb(0.74, 0.74, 0.74)));
    let red = b.material(Material::diffuse("red", rgb(0.63, 0.07, 0.06)));
    let green = b.material(Material::diffuse("green", rgb(0.15, 0.48, 0.09)));
    let light = b.material(Material::emitter("light", Vec3::new(17.0, 12.5, 6.0), Vec3::splat(0.78)));

    let (x0, x1, y0, y1, z0, z1) = (-1.0f32, 1.0f32, 0.0f32, 2.0f32, -2.0f32, 2.0f32);
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let t = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
    b.use_material(white);
    b.quad([v(x0, y0, z0), v(x1, y0, z0), v(x1, y0, z1), v(x0, y0, z1)], Vec3::Y, t); // floor
    b.quad([v(x0, y1, z0), v(x0, y1, z1), v(x1, y1, z1), v(x1, y1, z0)], Vec3::NEG_Y, t); // ceiling
    b.quad([v(x0, y0, z0), v(x0, y1, z0), v(x1, y1, z0), v(x1, y0, z0)], Vec3::Z, t); // back
    b.quad([v(x0, y0, z1), v(x1, y0, z1), v(x1, y1, z1), v(x0, y1, z1)], Vec3::NEG_Z, t); // front
    b.use_material(red);
    b.quad([v(x0, y0, z0), v(x0, y0, z1), v(x0, y1, z1), v(x0, y1, z0)], Vec3::X, t);
    b.use_material(green);
    b.quad([v(x1, y0, z0), v(x1, y1, z0), v(x1, y1, z1), v(x1, y0, z1)], Vec3::NEG_X, t);
    // Blocks without bottoms (10 triangles each).
    b.use_material(white);
    for (centre, half, yaw) in
        [(v(-0.35, 0.6, -1.1), v(0.3, 0.6, 0.3), 17.0f32), (v(0.4, 0.3, -0.5), v(0.3, 0.3, 0.3), -18.0)]
    {
        b.at(centre, yaw, |b| {
            let (lo, hi) = (-half, half);
            let c = |x: f32, y: f32, z: f32| v(x, y, z);
            b.quad([c(lo.x, hi.y, lo.z), c(lo.x, hi.y, hi.z), c(hi.x, hi.y, hi.z), c(hi.x, hi.y, lo.z)], Vec3::Y, t);
            b.quad([c(hi.x, lo.y, lo.z), c(hi.x, hi.y, lo.z), c(hi.x, hi.y, hi.z), c(hi.x, lo.y, hi.z)], Vec3::X, t);
            b.quad(
                [c(lo.x, lo.y, lo.z), c(lo.x, lo.y, hi.z), c(lo.x, hi.y, hi.z), c(lo.x, hi.y, lo.z)],
                Vec3::NEG_X,
                t,
            );
            b.quad([c(lo.x, lo.y, hi.z), c(hi.x, lo.y, hi.z), c(hi.x, hi.y, hi.z), c(lo.x, hi.y, hi.z)], Vec3::Z, t);
            b.quad(
                [c(lo.x, lo.y, lo.z), c(lo.x, hi.y, lo.z), c(hi.x, hi.y, lo.z), c(hi.x, lo.y, lo.z)],
                Vec3::NEG_Z,
                t,
            );
        });
    }
    // The light, 1 cm below the ceiling, facing down.
    b.use_material(light);
    let (h, yl, zc) = (0.25, y1 - 0.01, -0.8);
    b.quad([v(-h, yl, zc - h), v(h, yl, zc - h), v(h, yl, zc + h), v(-h, yl, zc + h)], Vec3::NEG_Y, t);

    let (mesh, materials, textures) = b.finish();
    // A slow 12 cm dolly towards the blocks with a slight pan.
    let camera = path(50.0, &[(0.0, [0.0, 1.0, 1.7], [0.0, 0.9, -1.0]), (59.0, [0.06, 1.02, 1.58], [0.12, 0.9, -1.0])]);
    Parts {
        mesh,
        materials,
        textures,
        lights: Lights::default(),
        moving_objects: Vec::new(),
        camera,
        tolerances: SceneTolerances { position: 0.01, depth_relative: 0.02, normal_degrees: 25.0 },
    }
}

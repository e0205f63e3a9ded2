//! Moving objects against an independent path through the renderer: an object placed at a
//! frame must render exactly as the same triangles made part of the static mesh (the BVH,
//! the mesh's shading and the static integrator), both in the path-traced image (shading,
//! shadows it casts, light it bounces) and in the G-buffer.

use glam::Vec3;
use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::Extent;
use stereotrace::render::{FrameView, Renderer};
use stereotrace::scene::object::{MovingObject, box_triangles};
use stereotrace::scene::{Effect, Material, Mesh, Scene, TransformKey, TransformPath, resolve};

const FRAME: u32 = 5;

/// Cornell with a turning glossy box flying through it, and the same box frozen at
/// [`FRAME`] into the static mesh.
fn moving_and_frozen() -> (Scene, Scene) {
    let mut moving = resolve("cornell").unwrap();
    moving.materials.push(Material::glossy("box", Vec3::new(0.6, 0.5, 0.3), Vec3::splat(0.3), 0.4));
    let material = moving.materials.len() as u32 - 1;
    let keys = vec![
        TransformKey { frame: 0.0, translation: [-0.5, 1.4, 0.4], yaw_deg: 0.0 },
        TransformKey { frame: 10.0, translation: [0.5, 1.5, 0.3], yaw_deg: 50.0 },
    ];
    moving.moving_objects.push(MovingObject {
        name: "box".into(),
        triangles: box_triangles(Vec3::splat(0.35)),
        material,
        path: TransformPath::new(keys).unwrap(),
    });
    moving.update().unwrap();

    let mut frozen = moving.clone();
    let object = frozen.moving_objects.pop().unwrap();
    let positions: Vec<[Vec3; 3]> = object.at_frame(FRAME as f32).collect();
    let n = positions.len();
    let extra = Mesh { positions, normals: None, uvs: None, material: vec![0; n] };
    frozen.mesh.append(&extra, object.material);
    frozen.update().unwrap();
    assert!(moving.effects.has(Effect::MovingObjects) && !frozen.effects.has(Effect::MovingObjects));
    (moving, frozen)
}

fn view(r: &Renderer, e: Extent) -> FrameView {
    FrameView::new(r, &StereoRig::default(), e, FRAME).unwrap()
}

#[test]
fn a_moving_object_renders_as_the_same_triangles_made_static() {
    let (moving, frozen) = moving_and_frozen();
    let (moving, frozen) = (Renderer::new(moving).unwrap(), Renderer::new(frozen).unwrap());
    let e = Extent::new(96, 64).unwrap();
    let render = |r: &Renderer, general: bool| {
        let view = view(r, e);
        view.render(r, &view.request(Eye::Left, 4, 9, 0), general).unwrap().0
    };
    let reference = render(&frozen, false);
    for general in [false, true] {
        let image = render(&moving, general);
        // The same estimator on the same random numbers: equal but for float noise in hits
        // found by two triangle loops (the BVH's and the moving triangles').
        let (mut close, mut sum_a, mut sum_b) = (0usize, 0.0f64, 0.0f64);
        for (ia, ib) in image.planes().into_iter().zip(reference.planes()) {
            for (a, b) in ia.as_slice().iter().zip(ib.as_slice()) {
                close += usize::from((a - b).abs() <= 1e-4 * b.abs().max(1.0));
                (sum_a, sum_b) = (sum_a + f64::from(*a), sum_b + f64::from(*b));
            }
        }
        let total = 3 * e.pixels();
        assert!(close * 1000 >= total * 998, "general {general}: {close} of {total} channel values agree");
        assert!((sum_a - sum_b).abs() <= 1e-4 * sum_b, "general {general}: image sums {sum_a} vs {sum_b}");
    }
    // The box is in view (and so the comparison tests it): the frozen mesh's extra triangles
    // are seen by some pixels.
    let g = view(&frozen, e).gbuffer(&frozen, Eye::Left);
    let object_material = frozen.scene().materials.len() as u32 - 1;
    let seen = g.material.as_slice().iter().filter(|&&m| m == object_material).count();
    assert!(seen > 100, "the box covers {seen} pixels");
}

#[test]
fn a_moving_object_gives_the_static_g_buffer() {
    let (moving, frozen) = moving_and_frozen();
    let (moving, frozen) = (Renderer::new(moving).unwrap(), Renderer::new(frozen).unwrap());
    let e = Extent::new(96, 64).unwrap();
    let gbuffer = |r: &Renderer| view(r, e).gbuffer(r, Eye::Left);
    let (a, b) = (gbuffer(&moving), gbuffer(&frozen));
    assert_eq!(a.material, b.material);
    for (i, (da, db)) in a.depth.as_slice().iter().zip(b.depth.as_slice()).enumerate() {
        assert!(da == db || (da - db).abs() <= 1e-5 * db, "pixel {i}: depth {da} vs {db}");
    }
    for c in 0..3 {
        for (na, nb) in a.normal[c].as_slice().iter().zip(b.normal[c].as_slice()) {
            assert!(na.is_nan() && nb.is_nan() || (na - nb).abs() <= 1e-5, "normal {na} vs {nb}");
        }
    }
}

//! Moving objects: rigid, non-emissive triangle sets that follow a keyframed path, as
//! moving lights do.
//!
//! An object is not part of the static mesh (the BVH is built once). The renderer places
//! it per frame beside the moving lights' triangles ([`crate::render::lights::FrameLights`]): rays
//! hit it, it casts shadows, it is shaded with its material, and the G-buffer's motion
//! planes carry its motion. A scene without objects runs none of that code (the
//! [`Effect::MovingObjects`](super::effects::Effect::MovingObjects) effect).
//!
//! Shading is flat (the face normal) and untextured: an object's material gives the BSDF
//! and a constant albedo. Objects come from manifests (`[[objects]]`) and the
//! `atrium-moving-object` built-in.

use glam::Vec3;

use super::light::icosphere;
use super::material::Material;
use super::path::TransformPath;

/// A rigid object following a path over the frames.
#[derive(Clone, Debug, PartialEq)]
pub struct MovingObject {
    /// Name for diagnostics.
    pub name: String,
    /// Triangles in the object's local frame (outward winding).
    pub triangles: Vec<[Vec3; 3]>,
    /// Index into the scene's materials (non-emissive, untextured, opaque).
    pub material: u32,
    /// Local-to-world transform over frames.
    pub path: TransformPath,
}

impl MovingObject {
    /// The object's triangles at (fractional) frame `frame`, in world space.
    pub fn at_frame(&self, frame: f32) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        let m = self.path.transform(frame);
        self.triangles.iter().map(move |t| t.map(|p| m.transform_point3(p)))
    }

    /// Checks what the renderer relies on: finite triangles, a path, and a material that
    /// exists and that flat untextured shading can render exactly (no emission, which is a
    /// moving light's job; no texture or cut-out, which need UVs the object does not have).
    pub fn validate(&self, materials: &[Material]) -> Result<(), String> {
        let name = &self.name;
        if self.triangles.is_empty() {
            return Err(format!("moving object {name:?} has no triangles"));
        }
        if !self.triangles.iter().flatten().all(|p| p.is_finite()) {
            return Err(format!("moving object {name:?} has non-finite triangles"));
        }
        self.path.validate().map_err(|e| format!("moving object {name:?}: {e}"))?;
        let Some(m) = materials.get(self.material as usize) else {
            return Err(format!("moving object {name:?}: material {} of {}", self.material, materials.len()));
        };
        if m.is_emissive() {
            return Err(format!("moving object {name:?}: material {:?} emits (use a moving light)", m.name));
        }
        if m.albedo_texture.is_some() || m.has_cutout() {
            return Err(format!(
                "moving object {name:?}: material {:?} is textured or cut out; objects are shaded flat and untextured",
                m.name
            ));
        }
        Ok(())
    }
}

/// The 12 outward-wound triangles of an axis-aligned box of `size` centred on the origin.
pub fn box_triangles(size: Vec3) -> Vec<[Vec3; 3]> {
    let h = 0.5 * size;
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 != 0 { h.x } else { -h.x },
            if i & 2 != 0 { h.y } else { -h.y },
            if i & 4 != 0 { h.z } else { -h.z },
        )
    };
    // Faces as corner quads; the winding is fixed below from the face's outward direction.
    let faces: [[usize; 4]; 6] = [[0, 2, 6, 4], [1, 5, 7, 3], [0, 4, 5, 1], [2, 3, 7, 6], [0, 1, 3, 2], [4, 6, 7, 5]];
    let mut tris = Vec::with_capacity(12);
    for f in faces {
        let q = f.map(corner);
        let centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
        for mut t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            if (t[1] - t[0]).cross(t[2] - t[0]).dot(centre) < 0.0 {
                t.swap(1, 2);
            }
            tris.push(t);
        }
    }
    tris
}

/// An outward-wound icosphere of `radius` (`20 · 4^subdivisions` triangles).
pub fn sphere_triangles(radius: f32, subdivisions: u32) -> Vec<[Vec3; 3]> {
    icosphere(radius, subdivisions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::path::TransformKey;

    #[test]
    fn a_box_is_closed_and_outward() {
        let tris = box_triangles(Vec3::new(2.0, 1.0, 4.0));
        assert_eq!(tris.len(), 12);
        // Outward winding everywhere, and the divergence theorem gives the volume 2·1·4.
        let mut volume = 0.0;
        for t in &tris {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            assert!(n.dot(t[0] + t[1] + t[2]) > 0.0, "{t:?}");
            volume += t[0].dot(t[1].cross(t[2])) / 6.0;
        }
        assert!((volume - 8.0).abs() < 1e-5, "{volume}");
    }

    #[test]
    fn objects_follow_their_path_and_refuse_emitting_materials() {
        let path = TransformPath::new(vec![
            TransformKey { frame: 0.0, translation: [0.0, 0.0, 0.0], yaw_deg: 0.0 },
            TransformKey { frame: 10.0, translation: [5.0, 0.0, 0.0], yaw_deg: 0.0 },
        ])
        .unwrap();
        let object = MovingObject { name: "crate".into(), triangles: box_triangles(Vec3::ONE), material: 0, path };
        let at = |f: f32| object.at_frame(f).flatten().fold(Vec3::ZERO, |s, p| s + p) / 36.0;
        assert!((at(10.0) - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5);
        let diffuse = [Material::diffuse("grey", Vec3::splat(0.5))];
        assert!(object.validate(&diffuse).is_ok());
        let glowing = [Material::emitter("lamp", Vec3::ONE, Vec3::splat(0.5))];
        assert!(object.validate(&glowing).unwrap_err().contains("emits"));
        assert!(object.validate(&[]).unwrap_err().contains("material 0 of 0"));
    }
}

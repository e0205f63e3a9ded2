//! Triangle soup in world space: the renderer's geometry.
//!
//! Flat, per-triangle arrays (structure of arrays): positions always, shading normals and UVs
//! when any triangle has them, a material index per triangle. Triangles are never indexed:
//! the BVH builder and the intersector want the three corners of a primitive next to each
//! other, and the shared scenes have few shared vertices once UV seams and flat shading are
//! unwelded. Near-zero-area triangles are kept (the shared scenes' counts include them); they
//! get a fallback geometric normal and zero area, so they are never sampled as lights.

use std::fmt;

use glam::{Vec2, Vec3};

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (grows from nothing).
    pub const EMPTY: Self = Self { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// True when no point was ever added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    /// `max - min` (zero for an empty box).
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() { Vec3::ZERO } else { self.max - self.min }
    }

    /// The centre.
    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// True when `p` lies inside or on the box.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The box grown by `margin` on every side (shrunk for negative margins).
    pub fn expanded(&self, margin: f32) -> Self {
        Self { min: self.min - Vec3::splat(margin), max: self.max + Vec3::splat(margin) }
    }
}

/// World-space triangles with optional per-vertex shading normals and UVs.
///
/// Invariants (checked by [`Mesh::validate`]): every array has one entry per triangle, all
/// positions are finite, normals are unit length and UVs finite.
#[derive(Clone, Default, PartialEq)]
pub struct Mesh {
    /// Corner positions, counter-clockwise seen from the front (the geometric normal is
    /// `(p1 - p0) x (p2 - p0)`; one-sided emitters emit on that side).
    pub positions: Vec<[Vec3; 3]>,
    /// Per-corner shading normals, or `None` when the whole mesh is flat shaded. Triangles
    /// that had no normals in the source carry their geometric normal here.
    pub normals: Option<Vec<[Vec3; 3]>>,
    /// Per-corner texture coordinates (v = 0 at the bottom image row), or `None` when no
    /// triangle has any. Triangles without UVs in the source carry zeros.
    pub uvs: Option<Vec<[Vec2; 3]>>,
    /// Index into `Scene::materials` per triangle.
    pub material: Vec<u32>,
}

impl fmt::Debug for Mesh {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Mesh")
            .field("triangles", &self.len())
            .field("normals", &self.normals.is_some())
            .field("uvs", &self.uvs.is_some())
            .finish()
    }
}

impl Mesh {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Twice the area vector, `(p1 - p0) x (p2 - p0)`.
    #[inline]
    pub fn cross(&self, tri: usize) -> Vec3 {
        let [a, b, c] = self.positions[tri];
        (b - a).cross(c - a)
    }

    /// Area of a triangle (zero for degenerate ones).
    #[inline]
    pub fn area(&self, tri: usize) -> f32 {
        0.5 * self.cross(tri).length()
    }

    /// Unit geometric normal on the winding side; `+Y` for degenerate triangles (which
    /// cannot be hit in a way that matters, but must not produce NaN).
    #[inline]
    pub fn geometric_normal(&self, tri: usize) -> Vec3 {
        self.cross(tri).try_normalize().unwrap_or(Vec3::Y)
    }

    /// Interpolated unit shading normal at barycentrics `(b1, b2)` (weights of corners 1
    /// and 2); the geometric normal for flat-shaded meshes.
    #[inline]
    pub fn shading_normal(&self, tri: usize, b1: f32, b2: f32) -> Vec3 {
        self.interpolated_normal(tri, b1, b2).unwrap_or_else(|| self.geometric_normal(tri))
    }

    /// The interpolated unit normal at barycentrics `(b1, b2)`, or `None` for a flat-shaded
    /// mesh or normals that do not normalise (where [`Mesh::shading_normal`] takes the
    /// geometric normal).
    #[inline]
    pub fn interpolated_normal(&self, tri: usize, b1: f32, b2: f32) -> Option<Vec3> {
        let [n0, n1, n2] = self.normals.as_ref()?[tri];
        (n0 * (1.0 - b1 - b2) + n1 * b1 + n2 * b2).try_normalize()
    }

    /// Interpolated UV at barycentrics `(b1, b2)`; zero when the mesh has none.
    #[inline]
    pub fn uv(&self, tri: usize, b1: f32, b2: f32) -> Vec2 {
        match &self.uvs {
            Some(t) => {
                let [t0, t1, t2] = t[tri];
                t0 * (1.0 - b1 - b2) + t1 * b1 + t2 * b2
            }
            None => Vec2::ZERO,
        }
    }

    /// Point at barycentrics `(b1, b2)`.
    #[inline]
    pub fn point(&self, tri: usize, b1: f32, b2: f32) -> Vec3 {
        let [a, b, c] = self.positions[tri];
        a * (1.0 - b1 - b2) + b * b1 + c * b2
    }

    /// Bounds of all positions.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.positions {
            for &p in t {
                b.grow(p);
            }
        }
        b
    }

    /// Number of triangles with (near) zero area: `|(p1 - p0) x (p2 - p0)| <= 1e-6 * longest
    /// edge²` (this includes exactly zero areas).
    pub fn degenerate_count(&self) -> usize {
        (0..self.len())
            .filter(|&i| {
                let [a, b, c] = self.positions[i];
                let e = (b - a).length_squared().max((c - a).length_squared()).max((c - b).length_squared());
                self.cross(i).length() <= 1e-6 * e
            })
            .count()
    }

    /// Appends `other`, offsetting its material indices by `material_offset`. The optional
    /// attribute arrays are filled in (geometric normals, zero UVs) where one side lacks them.
    pub fn append(&mut self, other: &Mesh, material_offset: u32) {
        let (old, add) = (self.len(), other.len());
        match (&mut self.normals, &other.normals) {
            (Some(a), Some(b)) => a.extend_from_slice(b),
            (Some(a), None) => a.extend((0..add).map(|i| [other.geometric_normal(i); 3])),
            (None, Some(b)) => {
                let mut a: Vec<[Vec3; 3]> = (0..old).map(|i| [self.geometric_normal(i); 3]).collect();
                a.extend_from_slice(b);
                self.normals = Some(a);
            }
            (None, None) => {}
        }
        match (&mut self.uvs, &other.uvs) {
            (Some(a), Some(b)) => a.extend_from_slice(b),
            (Some(a), None) => a.extend(std::iter::repeat_n([Vec2::ZERO; 3], add)),
            (None, Some(b)) => {
                let mut a = vec![[Vec2::ZERO; 3]; old];
                a.extend_from_slice(b);
                self.uvs = Some(a);
            }
            (None, None) => {}
        }
        self.positions.extend_from_slice(&other.positions);
        self.material.extend(other.material.iter().map(|m| m + material_offset));
    }

    /// Checks the invariants; the message names the first offending triangle.
    pub fn validate(&self, material_count: usize) -> Result<(), String> {
        let n = self.len();
        if self.material.len() != n {
            return Err(format!("{} material indices for {n} triangles", self.material.len()));
        }
        if let Some(v) = &self.normals
            && v.len() != n
        {
            return Err(format!("{} normal triples for {n} triangles", v.len()));
        }
        if let Some(v) = &self.uvs
            && v.len() != n
        {
            return Err(format!("{} UV triples for {n} triangles", v.len()));
        }
        for (i, t) in self.positions.iter().enumerate() {
            if !t.iter().all(|p| p.is_finite()) {
                return Err(format!("triangle {i} has a non-finite position {t:?}"));
            }
        }
        if let Some(v) = &self.normals {
            for (i, t) in v.iter().enumerate() {
                if !t.iter().all(|p| p.is_finite() && (p.length() - 1.0).abs() < 1e-3) {
                    return Err(format!("triangle {i} has a non-unit shading normal {t:?}"));
                }
            }
        }
        if let Some(v) = &self.uvs {
            for (i, t) in v.iter().enumerate() {
                if !t.iter().all(|p| p.is_finite()) {
                    return Err(format!("triangle {i} has a non-finite UV {t:?}"));
                }
            }
        }
        if let Some((i, m)) = self.material.iter().enumerate().find(|(_, m)| **m as usize >= material_count) {
            return Err(format!("triangle {i} uses material {m} of {material_count}"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(p: [Vec3; 3]) -> Mesh {
        Mesh { positions: vec![p], normals: None, uvs: None, material: vec![0] }
    }

    #[test]
    fn geometric_normal_follows_winding_and_survives_degenerates() {
        let m = one([Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(m.geometric_normal(0), Vec3::Z);
        assert!((m.area(0) - 0.5).abs() < 1e-6);
        let d = one([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        assert_eq!(d.geometric_normal(0), Vec3::Y);
        assert_eq!(d.area(0), 0.0);
        assert_eq!(d.degenerate_count(), 1);
        assert_eq!(m.degenerate_count(), 0);
    }

    #[test]
    fn append_fills_missing_attributes() {
        let mut a = one([Vec3::ZERO, Vec3::X, Vec3::Y]);
        let mut b = one([Vec3::ZERO, Vec3::Y, Vec3::X]);
        b.uvs = Some(vec![[Vec2::ONE; 3]]);
        b.normals = Some(vec![[Vec3::X; 3]]);
        a.append(&b, 3);
        assert_eq!(a.len(), 2);
        assert_eq!(a.material, vec![0, 3]);
        assert_eq!(a.normals.as_ref().unwrap()[0], [Vec3::Z; 3]);
        assert_eq!(a.uvs.as_ref().unwrap()[0], [Vec2::ZERO; 3]);
        assert!(a.validate(4).is_ok());
        assert!(a.validate(3).is_err());
    }
}

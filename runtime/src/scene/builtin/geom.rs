//! A small mesh builder for the procedural scenes: boxes, rounded boxes, surfaces of
//! revolution, swept tubes, arches, vaults, cloth and leaves, under a transform stack.
//!
//! Every emitted triangle gets smooth (or flat) shading normals and UVs, and is wound so its
//! geometric normal agrees with the shading normals: the builder checks and flips, so callers
//! never think about winding (one-sided emitters included). Degenerate triangles are dropped
//! (the built-ins have none by construction; the test suite checks).

use std::f32::consts::{PI, TAU};

use glam::{Affine3A, Mat3, Quat, Vec2, Vec3};

use crate::scene::material::Material;
use crate::scene::mesh::Mesh;
use crate::scene::texture::Texture;

/// SplitMix64: tiny, seedable, and identical on every platform (the built-ins must be
/// deterministic, so no thread-local or OS entropy anywhere).
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// The next 64 random bits (splitmix64).
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f32()
    }

    /// Uniform unit vector.
    pub fn unit(&mut self) -> Vec3 {
        crate::scene::sampling::uniform_sphere(Vec2::new(self.f32(), self.f32()))
    }
}

/// Collects triangles, materials and textures.
#[derive(Default)]
pub struct Builder {
    pos: Vec<[Vec3; 3]>,
    nrm: Vec<[Vec3; 3]>,
    uv: Vec<[Vec2; 3]>,
    mat: Vec<u32>,
    /// The materials added so far.
    pub materials: Vec<Material>,
    /// The textures added so far.
    pub textures: Vec<Texture>,
    xf: Affine3A,
    nmat: Mat3,
    cur: u32,
}

impl Builder {
    /// An empty builder with the identity transform.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a material and makes it current.
    pub fn material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        self.cur = self.materials.len() as u32 - 1;
        self.cur
    }

    /// Makes material `m` current.
    pub fn use_material(&mut self, m: u32) {
        self.cur = m;
    }

    /// Adds a texture and returns its index.
    pub fn texture(&mut self, t: Texture) -> u32 {
        self.textures.push(t);
        self.textures.len() as u32 - 1
    }

    /// Triangles emitted so far.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// True before the first triangle.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// Runs `f` with `xf` applied after (inside) the current transform.
    pub fn with(&mut self, xf: Affine3A, f: impl FnOnce(&mut Self)) {
        let (saved, saved_n) = (self.xf, self.nmat);
        self.xf = saved * xf;
        self.nmat = Mat3::from(self.xf.matrix3).inverse().transpose();
        f(self);
        self.xf = saved;
        self.nmat = saved_n;
    }

    /// Translation + rotation about Y (degrees) shorthand for [`with`](Self::with).
    pub fn at(&mut self, t: Vec3, yaw_deg: f32, f: impl FnOnce(&mut Self)) {
        self.with(Affine3A::from_rotation_translation(Quat::from_rotation_y(yaw_deg.to_radians()), t), f);
    }

    /// One triangle (local space), oriented to agree with the shading normals.
    pub fn tri(&mut self, p: [Vec3; 3], n: [Vec3; 3], t: [Vec2; 3]) {
        let mut p = p.map(|v| self.xf.transform_point3(v));
        let mut n = n.map(|v| (self.nmat * v).normalize_or(Vec3::Y));
        let mut t = t;
        let g = (p[1] - p[0]).cross(p[2] - p[0]);
        let e = (p[1] - p[0]).length_squared().max((p[2] - p[0]).length_squared());
        if !(g.length() > 1e-6 * e) || !p.iter().all(|v| v.is_finite()) {
            return;
        }
        if g.dot(n[0] + n[1] + n[2]) < 0.0 {
            p.swap(1, 2);
            n.swap(1, 2);
            t.swap(1, 2);
        }
        self.pos.push(p);
        self.nrm.push(n);
        self.uv.push(t);
        self.mat.push(self.cur);
    }

    /// A flat quad `a b c d` (in order around the rim) facing `n`.
    pub fn quad(&mut self, [a, b, c, d]: [Vec3; 4], n: Vec3, t: [Vec2; 4]) {
        self.tri([a, b, c], [n; 3], [t[0], t[1], t[2]]);
        self.tri([a, c, d], [n; 3], [t[0], t[2], t[3]]);
    }

    /// A smooth quad with per-corner normals.
    pub fn quad_smooth(&mut self, p: [Vec3; 4], n: [Vec3; 4], t: [Vec2; 4]) {
        self.tri([p[0], p[1], p[2]], [n[0], n[1], n[2]], [t[0], t[1], t[2]]);
        self.tri([p[0], p[2], p[3]], [n[0], n[2], n[3]], [t[0], t[2], t[3]]);
    }

    /// A parametric surface sampled on an `nu × nv` grid: `f(u, v) -> (position, normal)`,
    /// `u, v` in [0, 1]; UVs are `(u, v) * uv_scale`.
    pub fn grid(&mut self, nu: usize, nv: usize, uv_scale: Vec2, f: impl Fn(f32, f32) -> (Vec3, Vec3)) {
        let pts: Vec<(Vec3, Vec3)> = (0..=nv)
            .flat_map(|j| (0..=nu).map(move |i| (i, j)))
            .map(|(i, j)| f(i as f32 / nu as f32, j as f32 / nv as f32))
            .collect();
        let at = |i: usize, j: usize| pts[j * (nu + 1) + i];
        let tc = |i: usize, j: usize| Vec2::new(i as f32 / nu as f32, j as f32 / nv as f32) * uv_scale;
        for j in 0..nv {
            for i in 0..nu {
                let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                self.quad_smooth(
                    c.map(|x| x.0),
                    c.map(|x| x.1),
                    [tc(i, j), tc(i + 1, j), tc(i + 1, j + 1), tc(i, j + 1)],
                );
            }
        }
    }

    /// A flat rectangle subdivided `nu × nv`: origin, two edge vectors, facing `eu × ev`.
    pub fn plane(&mut self, origin: Vec3, eu: Vec3, ev: Vec3, nu: usize, nv: usize, uv_scale: Vec2) {
        let n = eu.cross(ev).normalize();
        self.grid(nu, nv, uv_scale, |u, v| (origin + eu * u + ev * v, n));
    }

    /// An axis-aligned box (local space), faces outward; UVs in metres per face.
    pub fn cuboid(&mut self, min: Vec3, max: Vec3) {
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(if x { max.x } else { min.x }, if y { max.y } else { min.y }, if z { max.z } else { min.z })
        };
        let faces: [([Vec3; 4], Vec3); 6] = [
            ([c(true, false, false), c(true, true, false), c(true, true, true), c(true, false, true)], Vec3::X),
            ([c(false, false, false), c(false, false, true), c(false, true, true), c(false, true, false)], Vec3::NEG_X),
            ([c(false, true, false), c(false, true, true), c(true, true, true), c(true, true, false)], Vec3::Y),
            ([c(false, false, false), c(true, false, false), c(true, false, true), c(false, false, true)], Vec3::NEG_Y),
            ([c(false, false, true), c(true, false, true), c(true, true, true), c(false, true, true)], Vec3::Z),
            ([c(false, false, false), c(false, true, false), c(true, true, false), c(true, false, false)], Vec3::NEG_Z),
        ];
        for (p, n) in faces {
            // Planar UVs along the face's two in-plane axes, in metres.
            let (a, b) = if n.x != 0.0 {
                (Vec3::Z, Vec3::Y)
            } else if n.y != 0.0 {
                (Vec3::X, Vec3::Z)
            } else {
                (Vec3::X, Vec3::Y)
            };
            let t = p.map(|q| Vec2::new(q.dot(a), q.dot(b)));
            self.quad(p, n, t);
        }
    }

    /// A box with rounded edges: half extents `half`, edge radius `r`, `n × n` cells per face.
    pub fn rounded_box(&mut self, centre: Vec3, half: Vec3, r: f32, n: usize) {
        let r = r.min(half.min_element() * 0.999);
        let inner = half - Vec3::splat(r);
        let axes = [(Vec3::X, Vec3::Y, Vec3::Z), (Vec3::Y, Vec3::Z, Vec3::X), (Vec3::Z, Vec3::X, Vec3::Y)];
        for (a, b, c) in axes {
            for s in [1.0f32, -1.0] {
                self.grid(n, n, Vec2::ONE, |u, v| {
                    // A point on the unit cube's face, mapped onto the rounded box.
                    let q = (a * s + b * (2.0 * u - 1.0) + c * (2.0 * v - 1.0) * s) * half;
                    let core = q.clamp(-inner, inner);
                    let d = (q - core).normalize_or(a * s);
                    (centre + core + d * r, d)
                });
            }
        }
    }

    /// A surface of revolution about local +Y through `base`: `profile` is `(radius, height)`
    /// pairs from bottom to top. Optional flat caps at the ends (when the radius is > 0).
    pub fn lathe(&mut self, base: Vec3, profile: &[(f32, f32)], segs: usize, caps: bool) {
        let m = profile.len();
        if m < 2 {
            return;
        }
        let normal2 = |k: usize| -> Vec2 {
            let (a, b) = (profile[k.saturating_sub(1)], profile[(k + 1).min(m - 1)]);
            let t = Vec2::new(b.0 - a.0, b.1 - a.1);
            Vec2::new(t.y, -t.x).normalize_or(Vec2::X)
        };
        let ring = |k: usize, j: usize| -> (Vec3, Vec3) {
            let phi = TAU * j as f32 / segs as f32;
            let dir = Vec3::new(phi.cos(), 0.0, -phi.sin());
            let (r, h) = profile[k];
            let n2 = normal2(k);
            (base + dir * r + Vec3::Y * h, (dir * n2.x + Vec3::Y * n2.y).normalize_or(Vec3::Y))
        };
        for k in 0..m - 1 {
            for j in 0..segs {
                let c = [ring(k, j), ring(k, j + 1), ring(k + 1, j + 1), ring(k + 1, j)];
                let t = [
                    Vec2::new(j as f32 / segs as f32, k as f32 / (m - 1) as f32),
                    Vec2::new((j + 1) as f32 / segs as f32, k as f32 / (m - 1) as f32),
                    Vec2::new((j + 1) as f32 / segs as f32, (k + 1) as f32 / (m - 1) as f32),
                    Vec2::new(j as f32 / segs as f32, (k + 1) as f32 / (m - 1) as f32),
                ];
                self.quad_smooth(c.map(|x| x.0), c.map(|x| x.1), t);
            }
        }
        if caps {
            for (k, up) in [(0, -1.0f32), (m - 1, 1.0)] {
                let (r, h) = profile[k];
                if r > 0.0 {
                    self.disc(base + Vec3::Y * h, Vec3::Y * up, r, segs);
                }
            }
        }
    }

    /// A flat disc (triangle fan) facing `n`.
    pub fn disc(&mut self, centre: Vec3, n: Vec3, r: f32, segs: usize) {
        let (t, b) = n.normalize().any_orthonormal_pair();
        for j in 0..segs {
            let (a0, a1) = (TAU * j as f32 / segs as f32, TAU * (j + 1) as f32 / segs as f32);
            let p0 = centre + (t * a0.cos() + b * a0.sin()) * r;
            let p1 = centre + (t * a1.cos() + b * a1.sin()) * r;
            self.tri([centre, p0, p1], [n; 3], [Vec2::splat(0.5), Vec2::ZERO, Vec2::X]);
        }
    }

    /// A straight cylinder (or cone frustum) from `a` to `b` with radii `ra`, `rb`.
    pub fn cylinder(&mut self, a: Vec3, b: Vec3, ra: f32, rb: f32, segs: usize, caps: bool) {
        let axis = b - a;
        let len = axis.length();
        if len <= 0.0 {
            return;
        }
        let rot = Quat::from_rotation_arc(Vec3::Y, axis / len);
        self.with(Affine3A::from_rotation_translation(rot, a), |s| {
            s.lathe(Vec3::ZERO, &[(ra, 0.0), (rb, len)], segs, caps);
        });
    }

    /// A tube of radius `radius(t)` (t in [0, 1] along the path) swept along a polyline with
    /// rotation-minimising frames; open ends.
    pub fn tube(&mut self, path: &[Vec3], segs: usize, radius: impl Fn(f32) -> f32) {
        let m = path.len();
        if m < 2 {
            return;
        }
        let tangent = |k: usize| (path[(k + 1).min(m - 1)] - path[k.saturating_sub(1)]).normalize_or(Vec3::Y);
        let mut frames = Vec::with_capacity(m);
        let t0 = tangent(0);
        let mut nrm = t0.any_orthonormal_vector();
        for k in 0..m {
            let t = tangent(k);
            // Parallel transport: remove the tangential part and renormalise.
            nrm = (nrm - t * nrm.dot(t)).normalize_or(t.any_orthonormal_vector());
            frames.push((t, nrm, t.cross(nrm)));
        }
        let ring = |k: usize, j: usize| -> (Vec3, Vec3) {
            let phi = TAU * j as f32 / segs as f32;
            let (_, n, b) = frames[k];
            let d = n * phi.cos() + b * phi.sin();
            (path[k] + d * radius(k as f32 / (m - 1) as f32), d)
        };
        for k in 0..m - 1 {
            for j in 0..segs {
                let c = [ring(k, j), ring(k, j + 1), ring(k + 1, j + 1), ring(k + 1, j)];
                let v = |k: usize| k as f32 / (m - 1) as f32;
                let u = |j: usize| j as f32 / segs as f32;
                let t = [
                    Vec2::new(u(j), v(k)),
                    Vec2::new(u(j + 1), v(k)),
                    Vec2::new(u(j + 1), v(k + 1)),
                    Vec2::new(u(j), v(k + 1)),
                ];
                self.quad_smooth(c.map(|x| x.0), c.map(|x| x.1), t);
            }
        }
    }

    /// An arch bay in local space: a wall slab of thickness `z0..z1` filling the rectangle
    /// `x0..x1 × y_spring..y_top` minus a semicircular opening of radius `(x1 - x0) / 2`
    /// springing at `y_spring`. Emits the intrados (underside) and both faces.
    pub fn arch(&mut self, (x0, x1): (f32, f32), (z0, z1): (f32, f32), (y_spring, y_top): (f32, f32), segs: usize) {
        let xc = 0.5 * (x0 + x1);
        let r = 0.5 * (x1 - x0);
        let arc = |k: usize| {
            let phi = PI * k as f32 / segs as f32;
            Vec2::new(xc + r * phi.cos(), y_spring + r * phi.sin())
        };
        // Radial projection of the arc point onto the bounding rectangle.
        let rim = |k: usize| {
            let phi = PI * k as f32 / segs as f32;
            let d = Vec2::new(phi.cos(), phi.sin());
            let mut s = f32::INFINITY;
            if d.x > 1e-6 {
                s = s.min((x1 - xc) / d.x);
            }
            if d.x < -1e-6 {
                s = s.min((x0 - xc) / d.x);
            }
            if d.y > 1e-6 {
                s = s.min((y_top - y_spring) / d.y);
            }
            Vec2::new(xc, y_spring) + d * s
        };
        for k in 0..segs {
            let (a0, a1, r0, r1) = (arc(k), arc(k + 1), rim(k), rim(k + 1));
            for (z, nz) in [(z0, -1.0f32), (z1, 1.0)] {
                let p = [a0, a1, r1, r0].map(|q| Vec3::new(q.x, q.y, z));
                let t = [a0, a1, r1, r0];
                self.tri([p[0], p[1], p[2]], [Vec3::Z * nz; 3], [t[0], t[1], t[2]]);
                self.tri([p[0], p[2], p[3]], [Vec3::Z * nz; 3], [t[0], t[2], t[3]]);
                // Where the rim turns a corner of the rectangle, fill the corner triangle.
                let on_top = |q: Vec2| (q.y - y_top).abs() < 1e-5;
                if on_top(r0) != on_top(r1) {
                    let corner = Vec2::new(if r0.x.min(r1.x) <= x0 + 1e-5 { x0 } else { x1 }, y_top);
                    let q = [r0, corner, r1].map(|q| Vec3::new(q.x, q.y, z));
                    self.tri(q, [Vec3::Z * nz; 3], [r0, corner, r1]);
                }
            }
            // Intrados, facing the opening's centre.
            let n = |q: Vec2| Vec3::new(xc - q.x, y_spring - q.y, 0.0).normalize_or(Vec3::NEG_Y);
            self.quad_smooth(
                [
                    Vec3::new(a0.x, a0.y, z0),
                    Vec3::new(a1.x, a1.y, z0),
                    Vec3::new(a1.x, a1.y, z1),
                    Vec3::new(a0.x, a0.y, z1),
                ],
                [n(a0), n(a1), n(a1), n(a0)],
                [
                    Vec2::new(k as f32 / segs as f32, 0.0),
                    Vec2::new((k + 1) as f32 / segs as f32, 0.0),
                    Vec2::new((k + 1) as f32 / segs as f32, 1.0),
                    Vec2::new(k as f32 / segs as f32, 1.0),
                ],
            );
        }
        // Top of the wall.
        self.quad(
            [Vec3::new(x0, y_top, z0), Vec3::new(x1, y_top, z0), Vec3::new(x1, y_top, z1), Vec3::new(x0, y_top, z1)],
            Vec3::Y,
            [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        );
    }

    /// A leaf: a bent diamond of length `len` from `base` along `dir`, with `up` giving its
    /// face orientation (4 triangles).
    pub fn leaf(&mut self, base: Vec3, dir: Vec3, up: Vec3, len: f32, width: f32, bend: f32) {
        let d = dir.normalize_or(Vec3::X);
        let side = d.cross(up).normalize_or(d.any_orthonormal_vector());
        let n = side.cross(d).normalize();
        let mid = base + d * (0.45 * len) + n * (0.5 * bend * len);
        let tip = base + d * len - n * (bend * len * 0.3);
        let l = mid + side * (0.5 * width);
        let r = mid - side * (0.5 * width);
        let nm = n;
        let (nl, nr) = ((n + side * bend).normalize(), (n - side * bend).normalize());
        self.tri([base, r, mid], [nm, nr, nm], [Vec2::new(0.5, 0.0), Vec2::new(1.0, 0.45), Vec2::new(0.5, 0.45)]);
        self.tri([base, mid, l], [nm, nm, nl], [Vec2::new(0.5, 0.0), Vec2::new(0.5, 0.45), Vec2::new(0.0, 0.45)]);
        self.tri([mid, r, tip], [nm, nr, nm], [Vec2::new(0.5, 0.45), Vec2::new(1.0, 0.45), Vec2::new(0.5, 1.0)]);
        self.tri([mid, tip, l], [nm, nm, nl], [Vec2::new(0.5, 0.45), Vec2::new(0.5, 1.0), Vec2::new(0.0, 0.45)]);
    }

    /// A hanging cloth (curtain, banner): a `size.x × size.y` sheet in the local XY plane
    /// hanging down from `top_left`, facing +Z, with `folds` sinusoidal folds of depth `depth`
    /// along Z, on an `nu × nv` grid.
    pub fn cloth(&mut self, top_left: Vec3, size: Vec2, (folds, depth): (f32, f32), (nu, nv): (usize, usize)) {
        let (w, h) = (size.x, size.y);
        self.grid(nu, nv, size, |u, v| {
            let a = TAU * folds * u;
            let sway = 1.0 - 0.3 * v;
            let p = top_left + Vec3::new(w * u, -h * v, depth * a.sin() * sway);
            let dz_du = depth * TAU * folds * a.cos() * sway / w;
            (p, Vec3::new(-dz_du, 0.0, 1.0).normalize())
        });
    }

    /// The mesh and everything collected.
    pub fn finish(self) -> (Mesh, Vec<Material>, Vec<Texture>) {
        let mesh = Mesh { positions: self.pos, normals: Some(self.nrm), uvs: Some(self.uv), material: self.mat };
        (mesh, self.materials, self.textures)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normals_agree(b: &Builder) -> bool {
        (0..b.len()).all(|i| {
            let p = b.pos[i];
            let g = (p[1] - p[0]).cross(p[2] - p[0]);
            g.dot(b.nrm[i][0] + b.nrm[i][1] + b.nrm[i][2]) > 0.0
        })
    }

    #[test]
    fn closed_shapes_face_outward() {
        let mut b = Builder::new();
        b.material(Material::diffuse("m", Vec3::ONE));
        b.cuboid(Vec3::ZERO, Vec3::ONE);
        let c = Vec3::splat(0.5);
        for i in 0..b.len() {
            let p = b.pos[i];
            let g = (p[1] - p[0]).cross(p[2] - p[0]);
            assert!(g.dot((p[0] + p[1] + p[2]) / 3.0 - c) > 0.0, "box face {i} inward");
        }
        assert_eq!(b.len(), 12);
        b.rounded_box(Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.5, 0.3, 0.2), 0.05, 4);
        b.lathe(Vec3::new(0.0, 0.0, 3.0), &[(0.2, 0.0), (0.3, 0.5), (0.1, 1.0)], 12, true);
        b.tube(&[Vec3::ZERO, Vec3::Y, Vec3::new(1.0, 2.0, 0.0)], 8, |_| 0.05);
        b.arch((0.0, 3.0), (0.0, 0.5), (4.0, 6.0), 16);
        b.leaf(Vec3::ZERO, Vec3::X, Vec3::Y, 0.1, 0.05, 0.2);
        b.cloth(Vec3::ZERO, Vec2::new(1.0, 2.0), (3.0, 0.05), (8, 8));
        assert!(normals_agree(&b));
        let (mesh, mats, _) = b.finish();
        assert!(mesh.validate(mats.len()).is_ok());
        assert_eq!(mesh.degenerate_count(), 0);
    }

    #[test]
    fn transforms_apply_to_normals() {
        let mut b = Builder::new();
        b.material(Material::diffuse("m", Vec3::ONE));
        b.at(Vec3::new(5.0, 0.0, 0.0), 90.0, |b| {
            b.quad([Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y], Vec3::Z, [Vec2::ZERO; 4])
        });
        let (mesh, _, _) = b.finish();
        assert!((mesh.geometric_normal(0) - Vec3::X).length() < 1e-5);
        assert!((mesh.positions[0][0] - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5);
    }

    #[test]
    fn rng_is_deterministic() {
        let (mut a, mut b) = (Rng::new(7), Rng::new(7));
        for _ in 0..100 {
            assert_eq!(a.next_u64(), b.next_u64());
        }
        let x = Rng::new(1).f32();
        assert!((0.0..1.0).contains(&x));
    }
}

//! Lat-long HDR environment maps with importance sampling.
//!
//! Convention (Mitsuba's equirectangular map, as documented in the living room's
//! `lights.json`): image coordinates `(u, v)` in `[0, 1)²` with `v = 0` the **top** row map
//! to the local direction
//!
//! ```text
//! d = (sin(2πu) sin(πv), cos(πv), −cos(2πu) sin(πv))        (+Y up in local space)
//! ```
//!
//! and the world direction is `to_world · d`. Radiance is `texel × scale`, piecewise
//! constant over texels (nearest lookup): the sampling density is proportional to texel
//! luminance × `sin θ` of the texel row, so within a texel radiance / pdf is constant (up to
//! `sin θ` varying inside the texel), which is the lowest-variance choice for a
//! piecewise-constant map.
//!
//! Sampling is a 2-D piecewise-constant distribution over `(u, v)` (marginal over rows,
//! conditional over columns); the solid-angle density is `pdf_uv / (2π² sin θ)` with θ the
//! exact polar angle of the direction, so it integrates to exactly 1 over the sphere.

use std::f32::consts::PI;
use std::path::Path;

use glam::{Mat3, Vec2, Vec3};

use super::error::SceneError;
use super::sampling::{Distribution2D, luminance};
use super::texture::Texture;

/// A sampled environment direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit world direction (pointing away from the scene, towards the sky).
    pub direction: Vec3,
    /// Solid-angle density of `direction`.
    pub pdf: f32,
    /// Radiance arriving from `direction`.
    pub radiance: Vec3,
}

/// A lat-long environment map with its sampling tables.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    /// Linear RGB texels, top row (v = 0, local +Y) first.
    pub texture: Texture,
    /// Radiance scale.
    pub scale: f32,
    /// Local-to-world rotation.
    pub to_world: Mat3,
    /// World-to-local rotation (the transpose).
    pub to_local: Mat3,
    /// Sampling tables over `(u, v)`.
    pub distribution: Distribution2D,
    /// Solid-angle-weighted mean radiance (a constant-environment stand-in).
    pub mean_radiance: Vec3,
}

impl EnvMap {
    /// Builds the map and its sampling tables. `texture` must have 3 or 4 channels (alpha
    /// ignored); `to_world` must be orthonormal (a rotation, possibly mirrored), since any
    /// other matrix would change solid angles.
    pub fn new(texture: Texture, scale: f32, to_world: Mat3) -> Result<Self, String> {
        if texture.channels < 3 {
            return Err(format!("environment map {:?} has {} channel(s), need RGB", texture.name, texture.channels));
        }
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(format!("environment scale {scale} must be finite and >= 0"));
        }
        let gram = to_world.transpose() * to_world;
        if !to_world.is_finite() || !gram.abs_diff_eq(Mat3::IDENTITY, 1e-3) {
            return Err(format!("environment to_world {to_world} is not a rotation"));
        }
        let (w, h) = (texture.width as usize, texture.height as usize);
        let mut weights = Vec::with_capacity(w * h);
        let mut sum = glam::DVec3::ZERO;
        let mut solid = 0.0f64;
        for y in 0..h {
            let sin_t = (PI * (y as f32 + 0.5) / h as f32).sin();
            for x in 0..w {
                let c = texture.texel(x as u32, y as u32).truncate().max(Vec3::ZERO);
                weights.push(luminance(c) * sin_t);
                sum += c.as_dvec3() * sin_t as f64;
                solid += sin_t as f64;
            }
        }
        let mean_radiance = (sum / solid.max(1e-30)).as_vec3() * scale;
        let distribution = Distribution2D::new(&weights, w, h);
        Ok(Self { texture, scale, to_world, to_local: to_world.transpose(), distribution, mean_radiance })
    }

    /// Loads an OpenEXR lat-long map (first RGBA layer; alpha ignored). Negative and
    /// non-finite texels are set to zero; their count is returned for a warning.
    pub fn load_exr(path: &Path, scale: f32, to_world: Mat3) -> Result<(Self, usize), SceneError> {
        use exr::prelude::*;
        let img_err = |m: String| SceneError::Image { path: path.to_path_buf(), message: m };
        if !path.is_file() {
            return Err(SceneError::io(path, std::io::Error::new(std::io::ErrorKind::NotFound, "file not found")));
        }
        // The size first, so that a header claiming billions of pixels is refused before the
        // decoder allocates them.
        crate::image_io::exr_extent(path).map_err(|e| img_err(e.message))?;
        let image = read_first_rgba_layer_from_file(
            path,
            |res: exr::math::Vec2<usize>, _| (res.width(), vec![0f32; res.width() * res.height() * 3]),
            |(w, px): &mut (usize, Vec<f32>), pos: exr::math::Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = (pos.y() * *w + pos.x()) * 3;
                px[i] = r;
                px[i + 1] = g;
                px[i + 2] = b;
            },
        )
        .map_err(|e| img_err(e.to_string()))?;
        let size = image.layer_data.size;
        let (_, mut data) = image.layer_data.channel_data.pixels;
        let mut bad = 0;
        for v in &mut data {
            if !(v.is_finite() && *v >= 0.0) {
                *v = 0.0;
                bad += 1;
            }
        }
        let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let tex = Texture::new(name, size.width() as u32, size.height() as u32, 3, data).map_err(img_err)?;
        let map = Self::new(tex, scale, to_world).map_err(|m| SceneError::invalid(path, m))?;
        Ok((map, bad))
    }

    /// Local direction of image coordinates `uv` (v = 0 top row).
    #[inline]
    pub fn uv_to_local(uv: Vec2) -> Vec3 {
        let (sp, cp) = (2.0 * PI * uv.x).sin_cos();
        let (st, ct) = (PI * uv.y).sin_cos();
        Vec3::new(sp * st, ct, -cp * st)
    }

    /// Image coordinates of a unit local direction, `u` in `[0, 1)`, `v` in `[0, 1]`.
    #[inline]
    pub fn local_to_uv(d: Vec3) -> Vec2 {
        let v = d.y.clamp(-1.0, 1.0).acos() / PI;
        let mut u = d.x.atan2(-d.z) / (2.0 * PI);
        if u < 0.0 {
            u += 1.0;
        }
        if u >= 1.0 || !u.is_finite() {
            u = 0.0;
        }
        Vec2::new(u, v)
    }

    /// World direction of image coordinates `uv`.
    #[inline]
    pub fn uv_to_direction(&self, uv: Vec2) -> Vec3 {
        (self.to_world * Self::uv_to_local(uv)).normalize()
    }

    /// Image coordinates of world direction `dir` (any length).
    #[inline]
    pub fn direction_to_uv(&self, dir: Vec3) -> Vec2 {
        Self::local_to_uv((self.to_local * dir).normalize_or(Vec3::Y))
    }

    /// Radiance arriving from world direction `dir` (nearest texel × scale).
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let uv = self.direction_to_uv(dir);
        let (w, h) = (self.texture.width, self.texture.height);
        let x = ((uv.x * w as f32) as u32).min(w - 1);
        let y = ((uv.y * h as f32) as u32).min(h - 1);
        self.texture.texel(x, y).truncate().max(Vec3::ZERO) * self.scale
    }

    /// Samples a direction proportionally to luminance (see the module notes).
    #[inline]
    pub fn sample(&self, u: Vec2) -> EnvSample {
        let (uv, pdf_uv) = self.distribution.sample(u);
        let sin_t = (PI * uv.y).sin();
        let direction = self.uv_to_direction(uv);
        let pdf = if sin_t > 0.0 { pdf_uv / (2.0 * PI * PI * sin_t) } else { 0.0 };
        EnvSample { direction, pdf, radiance: self.radiance(direction) }
    }

    /// Solid-angle density with which [`sample`](Self::sample) returns `dir`.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let local = (self.to_local * dir).normalize_or(Vec3::Y);
        // From x and z, not sqrt(1 − y²): accurate near the poles, where the density is large.
        let sin_t = Vec2::new(local.x, local.z).length();
        if sin_t <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(Self::local_to_uv(local)) / (2.0 * PI * PI * sin_t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_map() -> EnvMap {
        let (w, h) = (16, 8);
        let mut data = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let sun = if x == 5 && y == 2 { 200.0 } else { 0.0 };
                data.extend([0.2 + sun + y as f32 * 0.1, 0.3 + x as f32 * 0.05, 0.5 + sun]);
            }
        }
        EnvMap::new(Texture::new("t", w, h, 3, data).unwrap(), 2.0, Mat3::from_rotation_y(1.0)).unwrap()
    }

    #[test]
    fn uv_and_direction_round_trip() {
        let m = test_map();
        for &(u, v) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.95), (0.01, 0.6)] {
            let d = m.uv_to_direction(Vec2::new(u, v));
            let back = m.direction_to_uv(d);
            assert!((back - Vec2::new(u, v)).length() < 1e-4, "{u} {v} -> {back}");
        }
        // v = 0 is local +Y (up); u = 0 at v = 0.5 is local −Z.
        assert!((EnvMap::uv_to_local(Vec2::new(0.0, 0.0)) - Vec3::Y).length() < 1e-6);
        assert!((EnvMap::uv_to_local(Vec2::new(0.0, 0.5)) - Vec3::NEG_Z).length() < 1e-6);
        assert!((EnvMap::uv_to_local(Vec2::new(0.25, 0.5)) - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn samples_report_their_own_pdf_and_radiance() {
        let m = test_map();
        for i in 0..200 {
            let u = Vec2::new((i as f32 * 0.618034) % 1.0, (i as f32 + 0.5) / 200.0);
            let s = m.sample(u);
            assert!(s.pdf > 0.0);
            let p = m.pdf(s.direction);
            assert!((p - s.pdf).abs() <= 2e-3 * s.pdf, "{p} vs {}", s.pdf);
            assert_eq!(s.radiance, m.radiance(s.direction));
        }
    }

    #[test]
    fn refuses_non_rotations() {
        let t = Texture::new("t", 2, 1, 3, vec![1.0; 6]).unwrap();
        assert!(EnvMap::new(t.clone(), 1.0, Mat3::from_diagonal(Vec3::new(2.0, 1.0, 1.0))).is_err());
        assert!(EnvMap::new(t.clone(), f32::NAN, Mat3::IDENTITY).is_err());
        assert!(EnvMap::new(t, 1.0, Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0))).is_ok(), "mirrored is fine");
    }
}

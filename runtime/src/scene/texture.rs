//! Decoded textures: linear `f32`, 1, 3 or 4 channels, bilinear lookup with wrapping.
//!
//! Conventions (those of the shared scenes' `scene.mtl` headers):
//!
//! - Storage is row-major with the **top** image row first, as images are decoded.
//! - Lookups take OBJ texture coordinates: `v = 0` is the **bottom** row, so texel row
//!   `(1 - v) * height` is read. `u` and `v` wrap (repeat); NaN coordinates read as 0.
//! - Albedo maps (`map_Kd`) are sRGB-encoded: colour channels are decoded to linear on load,
//!   alpha stays linear. Opacity masks (`map_d`) are loaded as one linear channel: the alpha
//!   channel when the image has one, else its (undecoded) grey level.
//! - Texel centres sit at `(i + 0.5) / width`; a lookup exactly at a texel centre returns
//!   that texel.

use std::fmt;
use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

use super::error::SceneError;

/// The most texels a texture file may have (8192×8192): textures are stored as f32, so this
/// is up to 1 GiB for RGBA. Checked from the file's header before anything is decoded: a
/// JPEG of a few hundred bytes can claim 20036×18757 texels, whose decoding and conversion
/// would allocate gigabytes (found by fuzzing).
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 26;

/// What a texture file is used for; decides how it is decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TextureUsage {
    /// sRGB colour (+ linear alpha when present): 3 or 4 channels.
    Albedo,
    /// Coverage in [0, 1]: 1 channel (alpha, or grey level without alpha).
    Mask,
    /// Linear data (a glTF metallic-roughness map): 3 or 4 channels as stored, no sRGB curve.
    Linear,
}

/// A decoded texture.
#[derive(Clone, PartialEq)]
pub struct Texture {
    /// File name or procedural name (diagnostics only).
    pub name: String,
    /// Width in texels (> 0).
    pub width: u32,
    /// Height in texels (> 0).
    pub height: u32,
    /// 1 (mask), 3 (RGB) or 4 (RGBA).
    pub channels: u8,
    /// `width * height * channels` linear values, top row first.
    pub data: Vec<f32>,
}

impl fmt::Debug for Texture {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Texture({:?}, {}x{}x{})", self.name, self.width, self.height, self.channels)
    }
}

/// The message of a caught panic (`&str` or `String` payloads; others are not printable).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("panicked")
}

/// sRGB transfer function, decoded to linear (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear to sRGB-encoded (the inverse of [`srgb_to_linear`]).
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.0031308 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

impl Texture {
    /// A texture from linear values (top row first). Refuses zero sizes, channel counts
    /// other than 1, 3, 4, a data length that does not match, and non-finite values.
    pub fn new(name: impl Into<String>, width: u32, height: u32, channels: u8, data: Vec<f32>) -> Result<Self, String> {
        let name = name.into();
        if width == 0 || height == 0 {
            return Err(format!("texture {name:?} has zero size {width}x{height}"));
        }
        if !matches!(channels, 1 | 3 | 4) {
            return Err(format!("texture {name:?} has {channels} channels (1, 3 or 4 supported)"));
        }
        let expected = width as usize * height as usize * channels as usize;
        if data.len() != expected {
            return Err(format!("texture {name:?} has {} values, expected {expected}", data.len()));
        }
        if data.iter().any(|v| !v.is_finite()) {
            return Err(format!("texture {name:?} has non-finite values"));
        }
        Ok(Self { name, width, height, channels, data })
    }

    /// A texture from 8-bit sRGB-encoded colour (alpha, if any, linear), top row first.
    pub fn from_srgb8(
        name: impl Into<String>,
        width: u32,
        height: u32,
        channels: u8,
        bytes: &[u8],
    ) -> Result<Self, String> {
        let lut: Vec<f32> = (0..256).map(|i| srgb_to_linear(i as f32 / 255.0)).collect();
        let c = channels as usize;
        let data = bytes
            .iter()
            .enumerate()
            .map(|(i, &b)| if c == 4 && i % 4 == 3 { b as f32 / 255.0 } else { lut[b as usize] })
            .collect();
        Self::new(name, width, height, channels, data)
    }

    /// A single-colour 1x1 texture.
    pub fn constant(name: impl Into<String>, rgb: Vec3) -> Self {
        Self { name: name.into(), width: 1, height: 1, channels: 3, data: rgb.to_array().to_vec() }
    }

    /// Loads an image file (PNG or JPEG) for `usage`; see the module conventions. Files of
    /// more than [`MAX_TEXTURE_TEXELS`] texels are refused from their header. A decoder that
    /// panics on a corrupt file gives [`SceneError::Image`] too (the process's panic hook
    /// still prints the decoder's message first).
    pub fn load(path: &Path, usage: TextureUsage) -> Result<Self, SceneError> {
        let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        Self::decode(&name, &bytes, usage, path)
    }

    /// Decodes an encoded image (PNG or JPEG) held in memory, as [`load`](Self::load) does a
    /// file: what a glTF file's embedded images need. `origin` names the image in errors (the
    /// file, or `file.glb#image3`).
    pub fn decode(name: &str, bytes: &[u8], usage: TextureUsage, origin: &Path) -> Result<Self, SceneError> {
        let img_err = |m: String| SceneError::Image { path: origin.to_path_buf(), message: m };
        let reader = || {
            image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| img_err(e.to_string()))
        };
        let (w, h) = reader()?.into_dimensions().map_err(|e| img_err(e.to_string()))?;
        if u64::from(w) * u64::from(h) > MAX_TEXTURE_TEXELS {
            return Err(img_err(format!(
                "texture of {w}x{h} texels refused before decoding: at most {MAX_TEXTURE_TEXELS} (8192x8192) are supported"
            )));
        }
        // The JPEG decoder can panic on a corrupt stream (zune-jpeg 0.5.15 unwraps an
        // out-of-range block slice in its AVX2 IDCT; found by fuzzing). A scene load must
        // fail with an error instead, so a panic while decoding becomes one. The decoder
        // only touches its own buffers, so nothing is left half-updated.
        let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            reader()?.decode().map_err(|e| img_err(e.to_string()))
        }));
        let img = decoded
            .unwrap_or_else(|panic| Err(img_err(format!("the decoder failed: {}", panic_message(panic.as_ref())))))?;
        let name = name.to_owned();
        let (w, h) = (img.width(), img.height());
        let has_alpha = img.color().has_alpha();
        let eight_bit = img.color().bytes_per_pixel() / img.color().channel_count() == 1;
        let tex = match usage {
            TextureUsage::Albedo if eight_bit && has_alpha => Self::from_srgb8(name, w, h, 4, img.to_rgba8().as_raw()),
            TextureUsage::Albedo if eight_bit => Self::from_srgb8(name, w, h, 3, img.to_rgb8().as_raw()),
            TextureUsage::Albedo => {
                let c = if has_alpha { 4 } else { 3 };
                let raw: Vec<f32> = if has_alpha { img.to_rgba32f().into_raw() } else { img.to_rgb32f().into_raw() };
                let data = raw
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| if c == 4 && i % 4 == 3 { v } else { srgb_to_linear(v) })
                    .collect();
                Self::new(name, w, h, c as u8, data)
            }
            TextureUsage::Linear => {
                let c = if has_alpha { 4 } else { 3 };
                let data = if has_alpha { img.to_rgba32f().into_raw() } else { img.to_rgb32f().into_raw() };
                Self::new(name, w, h, c, data)
            }
            TextureUsage::Mask => {
                let data: Vec<f32> = if has_alpha {
                    img.to_rgba32f().into_raw().chunks_exact(4).map(|p| p[3]).collect()
                } else {
                    img.to_luma32f().into_raw()
                };
                Self::new(name, w, h, 1, data)
            }
        };
        tex.map_err(img_err)
    }

    /// Texel `(x, y)` with `y` counted from the **top** row, padded to RGBA (1 channel →
    /// `(c, c, c, 1)`, 3 channels → alpha 1).
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> Vec4 {
        let c = self.channels as usize;
        let i = (y as usize * self.width as usize + x as usize) * c;
        let d = &self.data[i..i + c];
        match c {
            1 => Vec4::new(d[0], d[0], d[0], 1.0),
            3 => Vec4::new(d[0], d[1], d[2], 1.0),
            _ => Vec4::new(d[0], d[1], d[2], d[3]),
        }
    }

    /// Bilinear lookup at OBJ coordinates `uv` (v = 0 at the bottom row), wrapping.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
        let x = finite(uv.x) * w as f32 - 0.5;
        let y = (1.0 - finite(uv.y)) * h as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // `as i64` saturates for huge coordinates; rem_euclid then wraps into range.
        let xi = (x0 as i64).rem_euclid(w);
        let yi = (y0 as i64).rem_euclid(h);
        let (xj, yj) = ((xi + 1) % w, (yi + 1) % h);
        let t = |x: i64, y: i64| self.texel(x as u32, y as u32);
        t(xi, yi) * ((1.0 - fx) * (1.0 - fy))
            + t(xj, yi) * (fx * (1.0 - fy))
            + t(xi, yj) * ((1.0 - fx) * fy)
            + t(xj, yj) * (fx * fy)
    }

    /// Bilinear colour at `uv`.
    #[inline]
    pub fn sample_rgb(&self, uv: Vec2) -> Vec3 {
        self.sample(uv).truncate()
    }

    /// Mean colour over all texels.
    pub fn mean_rgb(&self) -> Vec3 {
        let n = self.width as usize * self.height as usize;
        let mut sum = glam::DVec3::ZERO;
        for y in 0..self.height {
            for x in 0..self.width {
                sum += self.texel(x, y).truncate().as_dvec3();
            }
        }
        (sum / n as f64).as_vec3()
    }

    /// True when some texel has coverage below 1 (alpha for RGBA, the value for masks).
    pub fn has_transparency(&self) -> bool {
        match self.channels {
            1 => self.data.iter().any(|&v| v < 1.0),
            4 => self.data.chunks_exact(4).any(|p| p[3] < 1.0),
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_hits_known_values() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // 188/255 encodes ~0.5 linear.
        assert!((srgb_to_linear(188.0 / 255.0) - 0.5029).abs() < 1e-3);
        for i in 0..=100 {
            let c = i as f32 / 100.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
    }

    #[test]
    fn v_zero_is_the_bottom_row() {
        // 2x2, top row red/green, bottom row blue/white.
        #[rustfmt::skip]
        let data = vec![
            1.0, 0.0, 0.0,   0.0, 1.0, 0.0,
            0.0, 0.0, 1.0,   1.0, 1.0, 1.0,
        ];
        let t = Texture::new("t", 2, 2, 3, data).unwrap();
        assert_eq!(t.sample_rgb(Vec2::new(0.25, 0.25)), Vec3::Z, "bottom-left texel centre");
        assert_eq!(t.sample_rgb(Vec2::new(0.75, 0.25)), Vec3::ONE, "bottom-right");
        assert_eq!(t.sample_rgb(Vec2::new(0.25, 0.75)), Vec3::X, "top-left");
        assert_eq!(t.sample_rgb(Vec2::new(0.75, 0.75)), Vec3::Y, "top-right");
        // Half way between the two left texels: the mean of red and blue.
        let mid = t.sample_rgb(Vec2::new(0.25, 0.5));
        assert!((mid - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-6, "{mid}");
        // Wrapping: u + 1 and v - 3 give the same value.
        assert_eq!(t.sample(Vec2::new(1.25, -2.75)), t.sample(Vec2::new(0.25, 0.25)));
        // At u = 0 the left and right columns blend (wrap); NaN and huge values do not panic.
        let edge = t.sample_rgb(Vec2::new(0.0, 0.25));
        assert!((edge - Vec3::new(0.5, 0.5, 1.0)).length() < 1e-6, "{edge}");
        assert!(t.sample(Vec2::new(f32::NAN, f32::INFINITY)).is_finite());
        assert!(t.sample(Vec2::new(1e30, -1e30)).is_finite());
    }

    #[test]
    fn srgb8_decodes_colour_but_not_alpha() {
        let t = Texture::from_srgb8("p", 1, 1, 4, &[188, 0, 255, 128]).unwrap();
        let v = t.texel(0, 0);
        assert!((v.x - 0.5029).abs() < 1e-3 && v.y == 0.0 && (v.z - 1.0).abs() < 1e-6);
        assert!((v.w - 128.0 / 255.0).abs() < 1e-6);
        assert!(t.has_transparency());
    }

    #[test]
    fn bad_shapes_are_refused() {
        assert!(Texture::new("z", 0, 1, 3, vec![]).is_err());
        assert!(Texture::new("c", 1, 1, 2, vec![0.0; 2]).is_err());
        assert!(Texture::new("n", 1, 1, 1, vec![0.0; 2]).is_err());
        assert!(Texture::new("nan", 1, 1, 1, vec![f32::NAN]).is_err());
    }
}

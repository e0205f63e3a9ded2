//! Analytic test scenes for the kernels' tests, benches and fuzz targets.
//!
//! A handful of textured rectangles ray-cast exactly through pixel centres gives G-buffers
//! and images whose reprojection can be predicted in closed form (disparity `f·b/z` for a
//! fronto-parallel plane, occlusion bands behind a foreground strip), without the path
//! tracer. Everything here is deterministic; [`Rng`] is a small xorshift generator so tests
//! need no extra crates.

use glam::Vec3;

use crate::camera::CameraModel;
use crate::frame::{Extent, RgbBuf};
use crate::gbuffer::{CompactGBuffer, GBuffer, GBufferBuf, encode_normal};

/// xorshift64* — small, fast, deterministic; not for cryptography.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next_f32()
    }

    /// Uniform integer in `0..n` (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// The values SIMD/scalar agreement tests feed in first.
pub const EDGE_VALUES: [f32; 16] = [
    0.0,
    -0.0,
    1.0e-40,  // subnormal
    -1.0e-40, // negative subnormal
    f32::MIN_POSITIVE,
    1.0,
    -1.0,
    0.5,
    f32::MAX,
    -f32::MAX,
    3.0e38,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    1.0e6,
    1.0e-7,
];

/// How a rectangle is coloured: `base + amplitude · sin(frequency · (u, v) + phase)` per
/// channel, with `(u, v)` the hit point's coordinates along the rectangle's axes in scene
/// units. Zero amplitude gives a flat colour; `linear` adds `slope · u` so that bilinear
/// interpolation reproduces the texture exactly.
#[derive(Clone, Copy, Debug)]
pub struct Texture {
    /// Colour at `u = 0` without the wave.
    pub base: [f32; 3],
    /// Amplitude of the wave per channel.
    pub amplitude: [f32; 3],
    /// Frequency of the wave (0: none).
    pub frequency: f32,
    /// Change of colour per unit of `u`.
    pub slope: [f32; 3],
}

impl Texture {
    /// One colour everywhere.
    pub fn flat(rgb: [f32; 3]) -> Self {
        Self { base: rgb, amplitude: [0.0; 3], frequency: 0.0, slope: [0.0; 3] }
    }

    /// A smooth two-frequency pattern.
    pub fn pattern(base: [f32; 3], amplitude: f32, frequency: f32) -> Self {
        Self { base, amplitude: [amplitude; 3], frequency, slope: [0.0; 3] }
    }

    /// `base + slope · u`: linear along the rectangle's first axis.
    pub fn ramp(base: [f32; 3], slope: [f32; 3]) -> Self {
        Self { base, amplitude: [0.0; 3], frequency: 0.0, slope }
    }

    /// The colour at texture coordinates `(u, v)`.
    pub fn eval(&self, u: f32, v: f32) -> [f32; 3] {
        let wave = (self.frequency * u).sin() * (self.frequency * 0.7 * v + 0.3).cos();
        [0, 1, 2].map(|c| self.base[c] + self.amplitude[c] * wave + self.slope[c] * u)
    }
}

/// A textured rectangle: `centre + s·axis_u + t·axis_v` for `|s| ≤ half.0`, `|t| ≤ half.1`.
/// Its normal is `axis_u × axis_v` (normalised); both sides are visible.
#[derive(Clone, Copy, Debug)]
pub struct Rect {
    /// Centre of the rectangle.
    pub centre: Vec3,
    /// First half-axis direction (and texture `u` unit).
    pub axis_u: Vec3,
    /// Second half-axis direction (and texture `v` unit).
    pub axis_v: Vec3,
    /// Half extents along the two axes, in axis units.
    pub half: (f32, f32),
    /// Its texture.
    pub texture: Texture,
}

impl Rect {
    fn normal(&self) -> Vec3 {
        self.axis_u.cross(self.axis_v).normalize()
    }

    /// Ray parameter and texture coordinates of the hit, if any.
    fn hit(&self, origin: Vec3, dir: Vec3) -> Option<(f32, f32, f32)> {
        let n = self.normal();
        let denom = n.dot(dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = n.dot(self.centre - origin) / denom;
        if !(t > 0.0) {
            return None;
        }
        let p = origin + t * dir - self.centre;
        let (s, r) =
            (p.dot(self.axis_u) / self.axis_u.length_squared(), p.dot(self.axis_v) / self.axis_v.length_squared());
        (s.abs() <= self.half.0 && r.abs() <= self.half.1).then_some((t, s, r))
    }
}

/// A set of rectangles; pixels that hit none are background.
#[derive(Clone, Debug, Default)]
pub struct AnalyticScene {
    /// The rectangles.
    pub rects: Vec<Rect>,
}

/// Everything a frame of an analytic scene provides.
#[derive(Clone, Debug)]
pub struct SynthFrame {
    /// The frame's G-buffer (material 0 on every rectangle).
    pub surfaces: GBufferBuf,
    /// The surfaces' texture colour (the background colour where there is none).
    pub colour: RgbBuf,
}

impl SynthFrame {
    /// The full-precision G-buffer view.
    pub fn gbuffer(&self) -> GBuffer<'_> {
        self.surfaces.view()
    }

    /// The compact G-buffer view (depth + octahedral normals + camera).
    pub fn compact(&self) -> CompactGBuffer<'_> {
        self.surfaces.compact()
    }

    /// The frame's width and height.
    pub fn extent(&self) -> Extent {
        self.surfaces.extent()
    }
}

impl AnalyticScene {
    /// Ray-casts one primary ray through every pixel centre of `camera`. Background pixels
    /// get depth `+inf`, NaN positions and normals, and colour `background`.
    pub fn render(&self, camera: &CameraModel, background: [f32; 3]) -> SynthFrame {
        let extent = camera.extent;
        let mut g = GBufferBuf::new(*camera);
        let mut colour = RgbBuf::new(extent, 0.0);
        let origin = Vec3::from(camera.centre);
        for y in 0..extent.height() {
            for x in 0..extent.width() {
                let i = y * extent.width() + x;
                // A ray with unit view depth: the hit parameter is the view depth.
                let dir = Vec3::from(camera.ray(x as f32 + 0.5, y as f32 + 0.5));
                let nearest = self
                    .rects
                    .iter()
                    .filter_map(|r| r.hit(origin, dir).map(|h| (h, r)))
                    .min_by(|a, b| a.0.0.total_cmp(&b.0.0));
                let Some(((t, s, r), rect)) = nearest else {
                    colour.set(x, y, background);
                    continue;
                };
                let p = camera.unproject_pixel(x, y, t);
                let n = rect.normal();
                // Shading normals face the camera, as a renderer's would.
                let n = if n.dot(dir) > 0.0 { -n } else { n };
                g.depth.as_mut_slice()[i] = t;
                for c in 0..3 {
                    g.position[c].as_mut_slice()[i] = p[c];
                    g.normal[c].as_mut_slice()[i] = n[c];
                }
                g.normal_oct.as_mut_slice()[i] = encode_normal(n.to_array());
                g.material.as_mut_slice()[i] = 0;
                colour.set(x, y, rect.texture.eval(s, r));
            }
        }
        SynthFrame { surfaces: g, colour }
    }

    /// A textured back wall at depth `wall_z` with a few boxes' fronts in front of it and a
    /// floor: the standard bench and test scene (depth discontinuities, slanted floor).
    pub fn room(wall_z: f32) -> Self {
        let wall = Rect {
            centre: Vec3::new(0.0, 0.0, -wall_z),
            axis_u: Vec3::X,
            axis_v: Vec3::Y,
            half: (50.0, 50.0),
            texture: Texture::pattern([0.6, 0.5, 0.4], 0.3, 4.0),
        };
        let floor = Rect {
            centre: Vec3::new(0.0, -1.5, -wall_z * 0.5),
            axis_u: Vec3::X,
            axis_v: Vec3::Z,
            half: (50.0, wall_z * 0.5),
            texture: Texture::pattern([0.3, 0.35, 0.3], 0.2, 6.0),
        };
        let mut rects = vec![wall, floor];
        for i in 0..4 {
            let x = -1.8 + 1.2 * i as f32;
            let z = 2.5 + 0.9 * i as f32;
            rects.push(Rect {
                centre: Vec3::new(x, -0.8, -z),
                axis_u: Vec3::X,
                axis_v: Vec3::Y,
                half: (0.35, 0.7),
                texture: Texture::pattern([0.2 + 0.15 * i as f32, 0.4, 0.7 - 0.1 * i as f32], 0.15, 9.0),
            });
        }
        Self { rects }
    }
}

/// Parallel stereo pair (or any camera) for analytic scenes: looking down −z from `eye`,
/// with vertical field of view `vfov_deg`.
pub fn camera_at(eye: Vec3, extent: Extent, vfov_deg: f32) -> CameraModel {
    let vp = crate::camera::look_at_perspective(eye, eye - Vec3::Z, Vec3::Y, vfov_deg.to_radians(), extent);
    CameraModel::new(vp, extent).expect("a finite perspective camera")
}

/// Focal length in pixels of [`camera_at`]'s cameras.
pub fn focal_pixels(extent: Extent, vfov_deg: f32) -> f64 {
    extent.height() as f64 * 0.5 / (f64::from(vfov_deg).to_radians() * 0.5).tan()
}

/// An RGB image of values in [0, 4), with a share `edge_share` of [`EDGE_VALUES`].
pub fn random_rgb(e: Extent, rng: &mut Rng, edge_share: f32) -> RgbBuf {
    random_rgb_in(e, rng, edge_share, (0.0, 4.0))
}

/// An RGB image of values in `range`, with a share `edge_share` of [`EDGE_VALUES`].
pub fn random_rgb_in(e: Extent, rng: &mut Rng, edge_share: f32, (lo, hi): (f32, f32)) -> RgbBuf {
    let mut img = RgbBuf::new(e, 0.0);
    for p in img.slices_mut() {
        for v in p {
            *v =
                if rng.next_f32() < edge_share { EDGE_VALUES[rng.below(EDGE_VALUES.len())] } else { rng.range(lo, hi) };
        }
    }
    img
}

//! Small procedural albedo textures (stone, planks, tiles, boards, a painting), generated
//! deterministically from integer hashes. Colours are designed in sRGB and stored linear,
//! like a decoded `map_Kd`.

use glam::Vec3;

use crate::scene::texture::{Texture, srgb_to_linear};

fn hash(x: i32, y: i32, seed: u32) -> f32 {
    let mut h =
        (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841) ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h & 0x00ff_ffff) as f32 / 0x0100_0000 as f32
}

/// Smooth value noise with period `period` cells (tiles seamlessly).
fn noise(x: f32, y: f32, period: i32, seed: u32) -> f32 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let w = |i: i32| i.rem_euclid(period);
    let (x0, y0) = (xi as i32, yi as i32);
    let h = |i: i32, j: i32| hash(w(x0 + i), w(y0 + j), seed);
    let a = h(0, 0) + (h(1, 0) - h(0, 0)) * sx;
    let b = h(0, 1) + (h(1, 1) - h(0, 1)) * sx;
    a + (b - a) * sy
}

/// Fractal noise in [0, 1), tiling over the unit square at base frequency `f`.
fn fbm(u: f32, v: f32, f: i32, seed: u32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut freq = f;
    for o in 0..4 {
        sum += amp * noise(u * freq as f32, v * freq as f32, freq, seed + o);
        amp *= 0.5;
        freq *= 2;
    }
    sum / 0.9375
}

fn make(name: &str, size: u32, f: impl Fn(f32, f32) -> Vec3) -> Texture {
    let mut data = Vec::with_capacity((size * size * 3) as usize);
    for y in 0..size {
        for x in 0..size {
            // Row 0 is the top row: v = 1 there.
            let (u, v) = ((x as f32 + 0.5) / size as f32, 1.0 - (y as f32 + 0.5) / size as f32);
            let c = f(u, v).clamp(Vec3::ZERO, Vec3::ONE);
            data.extend(c.to_array().map(srgb_to_linear));
        }
    }
    Texture::new(name, size, size, 3, data).expect("procedural texture is well formed")
}

fn srgb(r: u8, g: u8, b: u8) -> Vec3 {
    Vec3::new(r as f32, g as f32, b as f32) / 255.0
}

/// Square stone flags (2 × 2 per texture) with grout lines and mottling.
pub fn stone_flags(seed: u32) -> Texture {
    make("stone-flags", 256, |u, v| {
        let (cu, cv) = ((u * 2.0).floor() as i32, (v * 2.0).floor() as i32);
        let (fu, fv) = ((u * 2.0).fract(), (v * 2.0).fract());
        let grout = fu.min(1.0 - fu).min(fv.min(1.0 - fv)) < 0.015;
        let tint = 0.85 + 0.15 * hash(cu, cv, seed);
        let m = 0.8 + 0.2 * fbm(u, v, 8, seed);
        if grout { srgb(120, 112, 100) } else { srgb(200, 186, 160) * tint * m }
    })
}

/// Ashlar wall blocks (running bond).
pub fn ashlar(seed: u32) -> Texture {
    make("ashlar", 256, |u, v| {
        let rows = 4.0;
        let r = (v * rows).floor();
        let off = if (r as i32) % 2 == 0 { 0.0 } else { 0.25 };
        let cu = ((u + off) * 2.0).rem_euclid(2.0);
        let (fu, fv) = (cu.fract(), (v * rows).fract());
        let joint = fu.min(1.0 - fu) < 0.012 || fv.min(1.0 - fv) < 0.025;
        let m = 0.8 + 0.2 * fbm(u, v, 8, seed);
        let tint = 0.9 + 0.1 * hash(cu.floor() as i32, r as i32, seed);
        if joint { srgb(140, 128, 110) } else { srgb(214, 196, 168) * m * tint }
    })
}

/// Wooden floor planks (along u), with grain.
pub fn planks(seed: u32, base: Vec3) -> Texture {
    make("planks", 256, move |u, v| {
        let n = 8.0;
        let row = (v * n).floor();
        let fv = (v * n).fract();
        let seam = fv.min(1.0 - fv) < 0.03;
        let grain = fbm(u * 0.25 + row * 0.37, v * 4.0, 4, seed);
        let streak = 0.5 + 0.5 * (60.0 * (v + 0.05 * grain)).sin();
        let tint = 0.8 + 0.3 * hash(row as i32, 0, seed);
        if seam { base * 0.35 } else { base * tint * (0.8 + 0.2 * streak) * (0.85 + 0.3 * grain) }
    })
}

/// Terracotta tiles with a diagonal pattern.
pub fn terracotta(seed: u32) -> Texture {
    make("terracotta", 256, |u, v| {
        let (cu, cv) = ((u * 4.0).floor() as i32, (v * 4.0).floor() as i32);
        let (fu, fv) = ((u * 4.0).fract(), (v * 4.0).fract());
        let grout = fu.min(1.0 - fu).min(fv.min(1.0 - fv)) < 0.03;
        let tint = 0.8 + 0.2 * hash(cu, cv, seed);
        let m = 0.85 + 0.15 * fbm(u, v, 16, seed);
        if grout { srgb(170, 160, 140) } else { srgb(184, 96, 60) * tint * m }
    })
}

/// A chalk board: dark green with faint chalk strokes.
pub fn blackboard(seed: u32) -> Texture {
    make("blackboard", 256, |u, v| {
        let smudge = fbm(u, v, 4, seed);
        let line = ((v * 9.0).fract() - 0.5).abs() < 0.04
            && (u * 7.0 + 3.0 * v).fract() < 0.6
            && hash((u * 7.0) as i32, (v * 9.0) as i32, seed) < 0.5;
        let base = srgb(38, 62, 48) * (0.8 + 0.4 * smudge);
        if line { base.lerp(srgb(220, 225, 215), 0.6) } else { base }
    })
}

/// Cork for a notice board, with a few pinned sheets of paper.
pub fn cork(seed: u32) -> Texture {
    make("cork", 128, |u, v| {
        let speck = hash((u * 128.0) as i32, (v * 128.0) as i32, seed);
        let paper = [(0.1, 0.55, 0.35, 0.9), (0.45, 0.2, 0.75, 0.6), (0.6, 0.7, 0.9, 0.95)]
            .iter()
            .any(|&(u0, v0, u1, v1)| u > u0 && u < u1 && v > v0 && v < v1);
        if paper { srgb(235, 232, 220) } else { srgb(170, 120, 80) * (0.75 + 0.35 * speck) }
    })
}

/// An abstract painting (soft colour fields), for a picture frame.
pub fn painting(seed: u32) -> Texture {
    make("painting", 256, |u, v| {
        let a = fbm(u, v, 2, seed);
        let b = fbm(u + 0.3, v, 3, seed + 9);
        let sky = srgb(90, 130, 180).lerp(srgb(230, 200, 150), v);
        let land = srgb(70, 110, 60).lerp(srgb(150, 120, 70), a);
        let horizon = 0.35 + 0.15 * b;
        if v > horizon { sky * (0.9 + 0.2 * a) } else { land }
    })
}

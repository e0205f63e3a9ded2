//! The heads-up lines over the image, drawn with Noto Sans Mono (pre-rasterised by the
//! `noto-sans-mono-bitmap` crate: anti-aliased glyphs, no font files, no allocation).

use noto_sans_mono_bitmap::{FontWeight, RasterHeight, get_raster, get_raster_width};

const WEIGHT: FontWeight = FontWeight::Regular;
const SIZE: RasterHeight = RasterHeight::Size16;

/// Height of one text line in pixels.
pub const LINE_HEIGHT: usize = 18;

/// Draws `text` (one line per `\n`) at the top-left of a `width`-wide `0RGB` image `out`,
/// white on a darkened band, clipped to the image. Characters outside the font show as `?`.
pub fn draw(out: &mut [u32], width: usize, text: &str) {
    let height = out.len() / width.max(1);
    let glyph_width = get_raster_width(WEIGHT, SIZE);
    for (line_index, line) in text.lines().enumerate() {
        let top = line_index * LINE_HEIGHT;
        if top + LINE_HEIGHT > height {
            return;
        }
        let text_width = (line.chars().count() * glyph_width + 8).min(width);
        for row in &mut out[top * width..(top + LINE_HEIGHT) * width].chunks_exact_mut(width) {
            // Halve the brightness under the text, so it reads over any image.
            row[..text_width].iter_mut().for_each(|p| *p = (*p >> 1) & 0x007f_7f7f);
        }
        for (k, c) in line.chars().enumerate() {
            let x0 = 4 + k * glyph_width;
            if x0 + glyph_width > width {
                break;
            }
            let Some(glyph) = get_raster(c, WEIGHT, SIZE).or_else(|| get_raster('?', WEIGHT, SIZE)) else { continue };
            for (dy, coverage_row) in glyph.rows().enumerate() {
                let y = top + 1 + dy;
                if y >= height {
                    break;
                }
                for (dx, &coverage) in coverage_row.iter().enumerate() {
                    if coverage > 0 {
                        let p = &mut out[y * width + x0 + dx];
                        *p = blend_white(*p, coverage);
                    }
                }
            }
        }
    }
}

/// `pixel` moved towards white by `coverage / 255`.
fn blend_white(pixel: u32, coverage: u8) -> u32 {
    let a = u32::from(coverage);
    let mix = |shift: u32| {
        let c = (pixel >> shift) & 0xff;
        ((c * (255 - a) + 255 * a + 127) / 255) << shift
    };
    mix(16) | mix(8) | mix(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_lights_pixels_inside_its_band_only_and_clips() {
        let (w, h) = (200, 40);
        let mut image = vec![0x0040_4040u32; w * h];
        draw(&mut image, w, "fps 30.0\nbudget 50 ms\nthis third line does not fit");
        let lit = |y0: usize, y1: usize| image[y0 * w..y1 * w].iter().filter(|&&p| p & 0xff > 0x80).count();
        assert!(lit(0, LINE_HEIGHT) > 20 && lit(LINE_HEIGHT, 2 * LINE_HEIGHT) > 20, "two lines drawn");
        assert_eq!(lit(2 * LINE_HEIGHT, h), 0, "the third line would not fit and is not drawn");
        // Past the text's width the image is untouched.
        assert_eq!(image[5 * w + 199], 0x0040_4040);
        // A line wider than the image is clipped, not a panic.
        draw(&mut image, w, &"x".repeat(100));
        draw(&mut [0u32; 10], 10, "tiny");
    }
}

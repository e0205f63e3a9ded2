//! Reading and writing images: linear HDR EXR (the data) and tonemapped PNG (a preview).
//! Every error names the file.

use std::path::{Path, PathBuf};

use crate::kernels::{Extent, RgbBuf};

/// An image file could not be read or written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ImageError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub message: String,
}

impl ImageError {
    fn new(path: &Path, message: impl Into<String>) -> Self {
        Self { path: path.to_path_buf(), message: message.into() }
    }
}

/// Writes `img` as a 32-bit float RGB EXR (linear radiance, nothing clamped). An image with a
/// NaN or infinite value is refused (naming the first such pixel): the renderer and the
/// pipeline make finite images from finite inputs, so one that is not is a fault to report,
/// not data to pass on.
pub fn write_exr(path: &Path, img: &RgbBuf) -> Result<(), ImageError> {
    let e = img.extent();
    let view = img.view();
    let bad = (0..e.height()).flat_map(|y| (0..e.width()).map(move |x| (x, y))).find(|&(x, y)| {
        let [r, g, b] = view.get(x, y);
        !(r.is_finite() && g.is_finite() && b.is_finite())
    });
    if let Some((x, y)) = bad {
        return Err(ImageError::new(
            path,
            format!("pixel ({x}, {y}) is {:?}: not writing a non-finite image", view.get(x, y)),
        ));
    }
    use exr::prelude::{Encoding, Image, LineOrder, SpecificChannels, Vec2, WritableImage};
    // The encoder's default (RLE, 64×64 tiles), with the tiles in increasing order: in the
    // default `Unspecified` order the parallel encoder writes them as they finish, and the
    // same image gives different files.
    let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let channels = SpecificChannels::rgb(|Vec2(x, y)| {
        let [r, g, b] = view.get(x, y);
        (r, g, b)
    });
    Image::from_encoded_channels((e.width(), e.height()), encoding, channels)
        .write()
        .to_file(path)
        .map_err(|err| ImageError::new(path, format!("cannot write EXR: {err}")))
}

/// The largest EXR tile accepted beyond the layer's own size, in pixels (a 256×256 tile;
/// writers use 16–256 pixels a side, ours 64).
pub const MAX_EXR_TILE_PIXELS: usize = 256 * 256;

/// The extent of an EXR's first layer, read from its header alone, after checking every
/// layer's size against the frame bounds. Readers call this before the decoder allocates: a
/// 28 KB file can claim 65536×65536 pixels, and the decoder would try to allocate them all.
pub fn exr_extent(path: &Path) -> Result<Extent, ImageError> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|err| ImageError::new(path, format!("cannot read EXR header: {err}")))?;
    let mut first = None;
    for header in meta.headers.iter() {
        let size = header.layer_size;
        let extent = Extent::new(size.width(), size.height())
            .map_err(|err| ImageError::new(path, format!("EXR layer refused before reading its pixels: {err}")))?;
        // The decoder allocates a whole tile per block, whatever the layer's size: a 4×3
        // image whose header claims 64×4,194,304-pixel tiles took 2 GB (a fuzz finding).
        if let exr::meta::BlockDescription::Tiles(tiles) = &header.blocks {
            let tile = tiles.tile_size;
            if tile.width().saturating_mul(tile.height()) > extent.pixels().max(MAX_EXR_TILE_PIXELS) {
                return Err(ImageError::new(
                    path,
                    format!(
                        "EXR tiles of {}x{} pixels refused for a {}x{} layer (tiles may exceed the layer only up to {MAX_EXR_TILE_PIXELS} pixels)",
                        tile.width(),
                        tile.height(),
                        size.width(),
                        size.height()
                    ),
                ));
            }
        }
        first.get_or_insert(extent);
    }
    first.ok_or_else(|| ImageError::new(path, "EXR file has no layer"))
}

/// Reads the first RGB(A) layer of an EXR as linear f32 RGB (its size checked first, see
/// [`exr_extent`]).
pub fn read_exr(path: &Path) -> Result<RgbBuf, ImageError> {
    exr_extent(path)?;
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (resolution.width(), resolution.height(), vec![[0.0f32; 3]; resolution.width() * resolution.height()])
        },
        |(w, _, px): &mut (usize, usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .map_err(|err| ImageError::new(path, format!("cannot read EXR: {err}")))?;
    let (w, h, px) = image.layer_data.channel_data.pixels;
    let extent = Extent::new(w, h).map_err(|err| ImageError::new(path, err.to_string()))?;
    let mut out = RgbBuf::new(extent, 0.0);
    for y in 0..h {
        for x in 0..w {
            out.set(x, y, px[y * w + x]);
        }
    }
    Ok(out)
}

/// The preview tonemap: exposure, Reinhard `x / (1 + x)`, then the sRGB transfer curve.
/// Non-finite values show as magenta so they cannot hide.
pub fn tonemap(rgb: [f32; 3], exposure: f32) -> [u8; 3] {
    if !rgb.iter().all(|v| v.is_finite()) {
        return [255, 0, 255];
    }
    rgb.map(|v| {
        let x = (v * exposure).max(0.0);
        let mapped = x / (1.0 + x);
        let srgb = if mapped <= 0.003_130_8 { 12.92 * mapped } else { 1.055 * mapped.powf(1.0 / 2.4) - 0.055 };
        (srgb * 255.0 + 0.5).clamp(0.0, 255.0) as u8
    })
}

/// Writes a tonemapped 8-bit PNG preview of `img`.
pub fn write_png_preview(path: &Path, img: &RgbBuf, exposure: f32) -> Result<(), ImageError> {
    let e = img.extent();
    let view = img.view();
    let mut out = image::RgbImage::new(e.width() as u32, e.height() as u32);
    for (x, y, p) in out.enumerate_pixels_mut() {
        *p = image::Rgb(tonemap(view.get(x as usize, y as usize), exposure));
    }
    out.save(path).map_err(|err| ImageError::new(path, format!("cannot write PNG: {err}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_hdr_values_exactly() {
        let dir = std::env::temp_dir().join(format!("stereotrace-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.exr");
        let e = Extent::new(5, 3).unwrap();
        let mut img = RgbBuf::new(e, 0.0);
        img.set(1, 2, [1e6, 0.5, 3.25e-3]);
        img.set(4, 0, [0.0, 65504.5, 7.0]);
        write_exr(&path, &img).unwrap();
        assert_eq!(read_exr(&path).unwrap(), img);
        let err = read_exr(&dir.join("missing.exr")).unwrap_err();
        assert!(err.to_string().contains("missing.exr"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A header claiming tiles far larger than its layer is refused before the decoder
    /// allocates them (the fuzz input took 2 GB before the check).
    #[test]
    fn huge_tiles_are_refused_from_the_header() {
        // The fuzz input's first byte picks the reader; the file is the rest.
        let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus/image/oom-huge-tiles-on-a-4x3-layer");
        let path = std::env::temp_dir().join(format!("stereotrace-huge-tiles-{}.exr", std::process::id()));
        std::fs::write(&path, &std::fs::read(&input).unwrap()[1..]).unwrap();
        let err = read_exr(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(err.message.contains("EXR tiles of 64x4194304 pixels refused for a 4x3 layer"), "{}", err.message);
    }

    /// The same image always gives the same bytes (the encoder compresses tiles in parallel;
    /// without a fixed line order it wrote them in whatever order they finished, so two
    /// renders with identical pixels gave different files).
    #[test]
    fn exr_files_of_the_same_image_are_identical() {
        let dir = std::env::temp_dir().join(format!("stereotrace-exr-bytes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = Extent::new(640, 360).unwrap();
        let mut img = RgbBuf::new(e, 0.0);
        for y in 0..e.height() {
            for x in 0..e.width() {
                img.set(x, y, [(x * y % 97) as f32 * 0.37, (x + y) as f32 * 1e-3, ((x ^ y) % 13) as f32]);
            }
        }
        let bytes = |i: usize| {
            let path = dir.join(format!("{i}.exr"));
            write_exr(&path, &img).unwrap();
            std::fs::read(&path).unwrap()
        };
        let first = bytes(0);
        for i in 1..12 {
            assert!(bytes(i) == first, "write {i} differs from the first");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn tonemap_is_monotone_and_flags_nan() {
        assert_eq!(tonemap([0.0; 3], 1.0), [0, 0, 0]);
        assert!(tonemap([1.0; 3], 1.0)[0] < tonemap([2.0; 3], 1.0)[0]);
        assert_eq!(tonemap([f32::NAN, 0.0, 0.0], 1.0), [255, 0, 255]);
    }
}

//! RIB's `MakeTexture`: converting an image into a texture file.
//!
//! The input is any file [`load_texture_image`] reads (8-bit inputs decoded from sRGB unless
//! `raw`). The output's extension picks its form:
//!
//! - `.png`, `.tga`, `.ppm`, `.tif`: 8-bit, colour re-encoded with the sRGB curve (unless `raw`) so that
//!   loading it again gives the same linear values up to 8-bit rounding. These formats have no
//!   place for wrap modes: lookups of such a texture wrap periodically unless they say otherwise.
//! - anything else (`.exr`, and RenderMan's usual `.tex`/`.tx`): a 32-bit float OpenEXR file in
//!   linear values, with the standard `wrapmodes` attribute (`"swrap,twrap"`), which
//!   [`TextureCache`](super::TextureCache) lookups honour when they set no wrap mode of their own.
//!
//! Mip levels are not stored: they are rebuilt at load, which costs less than reading them.
//! RIB's filter arguments (`filterfunc`, `swidth`, `twidth`) do not apply for that reason.

use std::path::Path;

use super::image::load_texture_image;
use super::Wrap;
use crate::image_io::{self, ExrLayer, ImageError, ImageFormat, Transfer, WriteOptions};

/// What `MakeTexture` says besides the file names.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MakeTextureOptions {
    pub swrap: Wrap,
    pub twrap: Wrap,
    /// Keep 8-bit values as stored, for data textures (no sRGB decoding or encoding).
    pub raw: bool,
}

/// Converts `src` into the texture file `dst` (see the module doc).
pub fn make_texture(src: impl AsRef<Path>, dst: impl AsRef<Path>, opts: &MakeTextureOptions) -> Result<(), ImageError> {
    let (src, dst) = (src.as_ref(), dst.as_ref());
    let image = load_texture_image(src, opts.raw)?.image;
    let (width, height, channels) = (image.width(), image.height(), image.channels());
    match ImageFormat::from_path(dst) {
        Some(ImageFormat::Png | ImageFormat::Tga | ImageFormat::Ppm | ImageFormat::Tiff) => {
            let rgba: Vec<f32> = image.data().chunks_exact(channels).flat_map(expand_to_rgba).collect();
            let transfer = if opts.raw { Transfer::Linear } else { Transfer::Srgb };
            let write = WriteOptions { transfer, ..WriteOptions::default() };
            image_io::write_image(dst, width, height, &rgba, &write)
        }
        _ => {
            let names = channel_names(channels);
            let layer = ExrLayer {
                width,
                height,
                channels: names
                    .into_iter()
                    .enumerate()
                    .map(|(c, name)| (name, image.data().iter().skip(c).step_by(channels).copied().collect()))
                    .collect(),
                wrap_modes: Some(format!("{},{}", opts.swrap.name(), opts.twrap.name())),
                ..ExrLayer::default()
            };
            image_io::write_exr(dst, &layer, false)
        }
    }
}

/// A pixel of 1-4 channels as RGBA: grey fills R, G, B; a missing alpha is opaque.
fn expand_to_rgba(p: &[f32]) -> [f32; 4] {
    match *p {
        [y] => [y, y, y, 1.0],
        [y, a] => [y, y, y, a],
        [r, g, b] => [r, g, b, 1.0],
        [r, g, b, a, ..] => [r, g, b, a],
        [] => [0.0, 0.0, 0.0, 1.0],
    }
}

/// EXR channel names that load back in the same order (see `exr_channel_rank` in `image.rs`).
fn channel_names(channels: usize) -> Vec<String> {
    let base: &[&str] = match channels {
        1 => &["Y"],
        2 => &["Y", "A"],
        _ => &["R", "G", "B", "A"],
    };
    (0..channels).map(|c| base.get(c).map_or_else(|| format!("C{c:02}"), |n| n.to_string())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{Footprint, LookupOptions, TextureCache};

    #[test]
    fn png_to_exr_keeps_linear_values_and_wrap_modes() {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("src.png");
        ::image::save_buffer(&src, &[255, 0, 0, 255, 0, 0, 128, 255], 2, 1, ::image::ExtendedColorType::Rgba8).unwrap();
        let dst = dir.path().join("out.tex");
        let opts = MakeTextureOptions { swrap: Wrap::Clamp, twrap: Wrap::Black, raw: false };
        make_texture(&src, &dst, &opts).unwrap();
        let loaded = load_texture_image(&dst, false).unwrap();
        assert_eq!(loaded.wrap, Some([Wrap::Clamp, Wrap::Black]));
        let blue = loaded.image.texel(1, 0)[2];
        assert!((blue - crate::texture::srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);

        // The cache honours the file's clamp in s: far right stays blue.
        let cache = TextureCache::new();
        let mut rgb = [0.0; 3];
        assert!(cache.texture(
            dst.to_str().unwrap(),
            5.0,
            0.5,
            Footprint::POINT,
            0,
            &mut rgb,
            &LookupOptions::default()
        ));
        assert!((rgb[2] - blue).abs() < 1e-6 && rgb[0] == 0.0, "{rgb:?}");
    }

    #[test]
    fn png_to_png_round_trips_the_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("src.png");
        let bytes: Vec<u8> = (0..4 * 4 * 3).map(|i| (i * 5) as u8).collect();
        ::image::save_buffer(&src, &bytes, 4, 4, ::image::ExtendedColorType::Rgb8).unwrap();
        let dst = dir.path().join("dst.png");
        make_texture(&src, &dst, &MakeTextureOptions::default()).unwrap();
        let back = ::image::open(&dst).unwrap().to_rgb8().into_raw();
        assert_eq!(back, bytes);
    }

    #[test]
    fn grey_and_many_channel_names() {
        assert_eq!(channel_names(1), ["Y"]);
        assert_eq!(channel_names(6), ["R", "G", "B", "A", "C04", "C05"]);
        assert_eq!(expand_to_rgba(&[0.5, 0.25]), [0.5, 0.5, 0.5, 0.25]);
    }

    #[test]
    fn a_missing_source_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let err = make_texture(dir.path().join("absent.png"), dir.path().join("x.exr"), &MakeTextureOptions::default())
            .unwrap_err();
        assert!(err.to_string().contains("absent.png"), "{err}");
    }
}

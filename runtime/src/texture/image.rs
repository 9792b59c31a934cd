//! A texture's pixels as linear floats, and loading them from a file.
//!
//! Invariant: a [`TexImage`] has `width >= 1`, `height >= 1`, `channels >= 1` and exactly
//! `width * height * channels` values, row-major, top row (t = 0) first, followed in memory by
//! [`TEXEL_PADDING`] zeros (see [`TexImage::padded_data`]).

use std::path::Path;

use super::{parse_wrap_modes, srgb_to_linear, Wrap};
use crate::image_io::{self, ImageError};

/// How many zeros follow an image's values: enough for a four-value load from any value.
pub(crate) const TEXEL_PADDING: usize = 4;

/// An N-channel float image, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct TexImage {
    width: usize,
    height: usize,
    channels: usize,
    /// The values, then [`TEXEL_PADDING`] zeros.
    data: Vec<f32>,
}

impl TexImage {
    /// An image from its values; `None` when a dimension is zero or the length does not match.
    pub fn new(width: usize, height: usize, channels: usize, mut data: Vec<f32>) -> Option<TexImage> {
        let ok =
            width > 0 && height > 0 && channels > 0 && width.checked_mul(height)?.checked_mul(channels)? == data.len();
        if !ok {
            return None;
        }
        data.extend_from_slice(&[0.0; TEXEL_PADDING]);
        Some(TexImage { width, height, channels, data })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn channels(&self) -> usize {
        self.channels
    }

    pub fn data(&self) -> &[f32] {
        &self.data[..self.data.len() - TEXEL_PADDING]
    }

    /// The values followed by [`TEXEL_PADDING`] zeros: the four values from the offset of any
    /// value (a texel's channels and what follows) are inside it, so a filter loads them at once
    /// without a shorter way for the last texel of an image of fewer than four channels.
    pub(crate) fn padded_data(&self) -> &[f32] {
        &self.data
    }

    /// The values of texel (x, y), y = 0 the top row. Panics when out of range.
    pub fn texel(&self, x: usize, y: usize) -> &[f32] {
        let start = (y * self.width + x) * self.channels;
        &self.data()[start..start + self.channels]
    }
}

/// A texture file's pixels and what its header says about wrapping.
#[derive(Clone, Debug)]
pub struct LoadedImage {
    pub image: TexImage,
    /// The file's `wrapmodes` attribute (EXR files written by `make_texture`), s then t.
    pub wrap: Option<[Wrap; 2]>,
    /// Whether the file held integer values (8/16-bit), as opposed to floats.
    pub integer_source: bool,
    /// The file's `worldToCamera` and `worldToNDC` attributes, when it has both (a shadow map
    /// or a rendered frame), for `textureinfo`.
    pub projection: Option<[[f32; 16]; 2]>,
}

/// Loads a texture file: EXR as stored (channels in R, G, B, A order, then the others by name);
/// everything else through the `image` crate, integer values taken as sRGB unless `raw` (alpha
/// is always linear). Never panics on a corrupt file.
pub fn load_texture_image(path: &Path, raw: bool) -> Result<LoadedImage, ImageError> {
    if image_io::is_exr(path) {
        return load_exr(path);
    }
    texture_from_decoded(path, image_io::decode_with_image_crate(path)?, raw)
}

/// Decodes a texture file's bytes held in memory (PNG, JPEG, TGA, PPM: what the `image` crate
/// reads; not EXR) as [`load_texture_image`] would decode the file; `name` is what errors call it.
pub fn decode_texture_image(name: &Path, bytes: &[u8], raw: bool) -> Result<LoadedImage, ImageError> {
    texture_from_decoded(name, image_io::decode_memory_with_image_crate(name, bytes)?, raw)
}

fn texture_from_decoded(path: &Path, decoded: ::image::DynamicImage, raw: bool) -> Result<LoadedImage, ImageError> {
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    let color = decoded.color();
    // Every layout the decoders produce has 1-4 channels; each becomes f32 in [0, 1] (integers
    // divided by their maximum), keeping its channel count.
    let channels = (color.channel_count() as usize).clamp(1, 4);
    let has_alpha = color.has_alpha();
    let is_float = matches!(color, ::image::ColorType::Rgb32F | ::image::ColorType::Rgba32F);
    let mut values: Vec<f32> = match channels {
        1 => decoded.to_luma32f().into_raw(),
        2 => decoded.to_luma_alpha32f().into_raw(),
        3 => decoded.to_rgb32f().into_raw(),
        _ => decoded.to_rgba32f().into_raw(),
    };
    if !is_float && !raw {
        let eight_bit = color.bytes_per_pixel() as usize == channels;
        let lut = eight_bit.then(srgb_lut_8bit);
        for (i, v) in values.iter_mut().enumerate() {
            let is_alpha = has_alpha && i % channels == channels - 1;
            if !is_alpha {
                *v = match &lut {
                    // Exact for 8-bit values, and a table lookup instead of a `powf`.
                    Some(lut) => lut[(*v * 255.0).round() as usize & 255],
                    None => srgb_to_linear(*v),
                };
            }
        }
    }
    let image = TexImage::new(width, height, channels, values)
        .ok_or_else(|| ImageError::Decode { path: path.into(), message: "the image has no pixels".into() })?;
    Ok(LoadedImage { image, wrap: None, integer_source: !is_float, projection: None })
}

fn srgb_lut_8bit() -> [f32; 256] {
    std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0))
}

/// The order of an EXR file's channels in a texture: colour first, so that channel 0..3 of a
/// lookup mean R, G, B, A as in any other file; then depth, then the rest by name.
fn exr_channel_rank(name: &str) -> (usize, &str) {
    let rank = match name {
        "R" | "r" | "Y" | "y" => 0,
        "G" | "g" => 1,
        "B" | "b" => 2,
        "A" | "a" => 3,
        "Z" | "z" => 4,
        _ => 5,
    };
    (rank, name)
}

/// Decodes a texture file's bytes held in memory, whatever its format (EXR included), as
/// [`load_texture_image`] would decode the file; `name` is what errors call it.
pub fn decode_texture_file(name: &Path, bytes: &[u8], raw: bool) -> Result<LoadedImage, ImageError> {
    if image_io::is_exr_bytes(bytes) {
        return exr_texture(name, image_io::read_exr_bytes(name, bytes)?);
    }
    decode_texture_image(name, bytes, raw)
}

fn load_exr(path: &Path) -> Result<LoadedImage, ImageError> {
    exr_texture(path, image_io::read_exr(path)?)
}

fn exr_texture(path: &Path, layer: image_io::ExrLayer) -> Result<LoadedImage, ImageError> {
    let mut channels: Vec<&(String, Vec<f32>)> = layer.channels.iter().collect();
    channels.sort_by(|a, b| exr_channel_rank(&a.0).cmp(&exr_channel_rank(&b.0)));
    let count = channels.len();
    let pixels = layer.width * layer.height;
    let mut data = Vec::with_capacity(pixels * count);
    for i in 0..pixels {
        data.extend(channels.iter().map(|(_, values)| values[i]));
    }
    let image = TexImage::new(layer.width, layer.height, count, data).ok_or_else(|| ImageError::Decode {
        path: path.into(),
        message: "the image has no pixels or no channels".into(),
    })?;
    let wrap = layer.wrap_modes.as_deref().and_then(parse_wrap_modes);
    let projection = layer.world_to_camera.zip(layer.world_to_ndc).map(|(camera, ndc)| [camera, ndc]);
    Ok(LoadedImage { image, wrap, integer_source: false, projection })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image_io::{write_exr, ExrLayer};

    fn save_rgba8(path: &Path, w: u32, h: u32, bytes: &[u8]) {
        ::image::save_buffer(path, bytes, w, h, ::image::ExtendedColorType::Rgba8).unwrap();
    }

    /// The values are exactly the image's; the padding after them is zeros that no texel reads.
    #[test]
    fn values_are_followed_by_zeros_that_are_not_texels() {
        let img = TexImage::new(2, 1, 3, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        assert_eq!(img.data(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(img.padded_data(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(img.texel(1, 0), &[4.0, 5.0, 6.0]);
        assert!(std::panic::catch_unwind(|| img.texel(2, 0).to_vec()).is_err(), "past the last texel");
        assert_eq!(img.clone(), img);
        assert!(TexImage::new(2, 1, 3, vec![0.0; 7]).is_none());
    }

    #[test]
    fn eight_bit_colour_is_decoded_from_srgb_but_alpha_is_not() {
        let dir = tempfile::tempdir().unwrap();
        for ext in ["png", "tga"] {
            let path = dir.path().join(format!("c.{ext}"));
            save_rgba8(&path, 1, 1, &[128, 255, 0, 128]);
            let img = load_texture_image(&path, false).unwrap().image;
            assert_eq!(img.channels(), 4);
            let t = img.texel(0, 0);
            assert!((t[0] - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6, "{ext}");
            assert!((t[1] - 1.0).abs() < 1e-6 && t[2] == 0.0);
            assert!((t[3] - 128.0 / 255.0).abs() < 1e-6, "alpha stays linear");

            let raw = load_texture_image(&path, true).unwrap().image;
            assert!((raw.texel(0, 0)[0] - 128.0 / 255.0).abs() < 1e-6, "raw keeps the stored value");
        }
    }

    #[test]
    fn ppm_and_jpeg_load_as_rgb() {
        let dir = tempfile::tempdir().unwrap();
        let ppm = dir.path().join("c.ppm");
        ::image::save_buffer(&ppm, &[255, 0, 0, 0, 0, 255], 2, 1, ::image::ExtendedColorType::Rgb8).unwrap();
        let img = load_texture_image(&ppm, false).unwrap().image;
        assert_eq!((img.width(), img.height(), img.channels()), (2, 1, 3));
        assert_eq!(img.texel(1, 0), &[0.0, 0.0, 1.0]);

        let jpg = dir.path().join("c.jpg");
        ::image::save_buffer(&jpg, &[200u8; 8 * 8 * 3], 8, 8, ::image::ExtendedColorType::Rgb8).unwrap();
        let img = load_texture_image(&jpg, false).unwrap().image;
        assert!((img.texel(3, 3)[1] - srgb_to_linear(200.0 / 255.0)).abs() < 0.02);
    }

    #[test]
    fn sixteen_bit_and_grey_alpha_pngs() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grey16.png");
        ::image::ImageBuffer::<::image::Luma<u16>, _>::from_raw(2, 1, vec![0u16, 30000]).unwrap().save(&path).unwrap();
        let img = load_texture_image(&path, false).unwrap().image;
        assert_eq!(img.channels(), 1);
        assert!((img.texel(1, 0)[0] - srgb_to_linear(30000.0 / 65535.0)).abs() < 1e-5);

        let path = dir.path().join("grey_alpha.png");
        ::image::save_buffer(&path, &[64, 64], 1, 1, ::image::ExtendedColorType::La8).unwrap();
        let img = load_texture_image(&path, false).unwrap().image;
        assert_eq!(img.channels(), 2);
        assert!((img.texel(0, 0)[0] - srgb_to_linear(64.0 / 255.0)).abs() < 1e-6);
        assert!((img.texel(0, 0)[1] - 64.0 / 255.0).abs() < 1e-6, "alpha stays linear");
    }

    #[test]
    fn exr_channels_come_in_rgba_order_with_wrap_modes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.exr");
        let layer = ExrLayer {
            width: 1,
            height: 1,
            channels: vec![
                ("A".into(), vec![0.25]),
                ("B".into(), vec![3.0]),
                ("G".into(), vec![2.0]),
                ("R".into(), vec![-1.0]),
            ],
            wrap_modes: Some("black,clamp".into()),
            ..ExrLayer::default()
        };
        write_exr(&path, &layer, false).unwrap();
        let loaded = load_texture_image(&path, false).unwrap();
        assert_eq!(loaded.image.texel(0, 0), &[-1.0, 2.0, 3.0, 0.25], "floats are not decoded");
        assert_eq!(loaded.wrap, Some([Wrap::Black, Wrap::Clamp]));
    }

    #[test]
    fn corrupt_files_are_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.png");
        save_rgba8(&good, 16, 16, &[77u8; 16 * 16 * 4]);
        let bytes = std::fs::read(&good).unwrap();
        let truncated = dir.path().join("truncated.png");
        std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
        assert!(load_texture_image(&truncated, false).is_err());

        // Random bytes under every extension we read (a fixed xorshift, so the test is stable).
        let mut state = 0x9e3779b97f4a7c15u64;
        for (i, ext) in ["png", "jpg", "tga", "ppm", "exr", "tex"].iter().enumerate() {
            let noise: Vec<u8> = (0..300 + i * 97)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    state as u8
                })
                .collect();
            let path = dir.path().join(format!("noise.{ext}"));
            std::fs::write(&path, noise).unwrap();
            assert!(load_texture_image(&path, false).is_err(), "{ext}");
        }
    }

    /// A file in no format rtsl reads says so, and PRMan's own texture files (before `txmake`
    /// wrote TIFF) are named, in either byte order; a TIFF file named `.tx` reads.
    #[test]
    fn files_in_formats_rtsl_cannot_read_say_which() {
        let dir = tempfile::tempdir().unwrap();
        let message = |name: &str, bytes: &[u8]| {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            let from_file = load_texture_image(&path, false).unwrap_err().to_string();
            let from_memory = decode_texture_file(&path, bytes, false).unwrap_err().to_string();
            assert!(from_file.ends_with(from_memory.rsplit(": ").next().unwrap()), "{from_file} / {from_memory}");
            from_file
        };
        for magic in [[0xce, 0xfa, 0x03, 0x00], [0xfa, 0xce, 0x00, 0x03], [0xce, 0xfa, 0x02, 0x00]] {
            let bytes: Vec<u8> = magic.iter().copied().chain([0x10, 0x04, 0x01, 0x08].repeat(40)).collect();
            let m = message("old.tx", &bytes);
            assert!(m.contains("PRMan's own texture format"), "{m}");
        }
        let m = message("text.tx", b"hello, not an image at all");
        assert!(m.contains("not an image format rtsl reads"), "{m}");

        let tiff = dir.path().join("grey.tif");
        ::image::GrayImage::from_raw(2, 2, vec![10, 20, 30, 40]).unwrap().save(&tiff).unwrap();
        let tx = dir.path().join("grey.tx");
        std::fs::copy(&tiff, &tx).unwrap();
        assert_eq!(load_texture_image(&tx, true).unwrap().image.texel(1, 1), &[40.0 / 255.0]);
    }
}

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
//!
//! RIB's `MakeCubeFaceEnvironment` ([`make_cube_face_environment`]): the texture system has one
//! kind of environment map, the latitude-longitude one `environment()` reads
//! (`super::environment`), so the six faces are resampled into one when the map is made.

use std::path::Path;

use super::environment::latlong_to_direction;
use super::image::{load_texture_image, TexImage};
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
    write_texture(&image, dst, opts)
}

/// The widest latitude-longitude map [`make_cube_face_environment`] makes (its height is half
/// that): four faces across, each at most a quarter of it.
pub const MAX_CUBE_LATLONG_WIDTH: usize = 4096;

/// Makes the latitude-longitude environment map `dst` of six cube faces (RISpec's
/// `MakeCubeFaceEnvironment`: `faces` seen from the cube's centre along +x, -x, +y, -y, +z, -z, in
/// RenderMan's left-handed space, each `fov_degrees` across, oriented as Aqsis's cube sampler
/// reads them: up is +y for the four side faces (right -z, +z, +x, -x for +x, -x, +z, -z), -z
/// for +y and +z for -y (right +x for both)). Each texel of the map, `4 n` by `2 n` for a +x face
/// of `n` texels across (at most [`MAX_CUBE_LATLONG_WIDTH`] wide), takes the bilinear value of
/// its direction on the face it points to. Faces may differ in size; their channels are made
/// RGBA. The faces are read one at a time. With `raw`, 8-bit values are kept as stored, as
/// [`MakeTextureOptions::raw`].
pub fn make_cube_face_environment(
    faces: [&Path; 6],
    dst: &Path,
    fov_degrees: f32,
    raw: bool,
) -> Result<(), ImageError> {
    if !(fov_degrees > 0.0 && fov_degrees < 180.0) {
        let message = format!("a cube face's field of view is between 0 and 180 degrees, not {fov_degrees}");
        return Err(ImageError::Encode { path: dst.to_path_buf(), message });
    }
    // One face in memory at a time: each fills the texels that look at it.
    let cot = 1.0 / (0.5 * fov_degrees.to_radians()).tan();
    let (mut rgba, mut width, mut height) = (Vec::new(), 0, 0);
    for (k, face) in faces.into_iter().enumerate() {
        let image = load_texture_image(face, raw)?.image;
        if k == 0 {
            width = (4 * image.width()).clamp(4, MAX_CUBE_LATLONG_WIDTH);
            height = width / 2;
            rgba = vec![0.0; width * height * 4];
        }
        for (j, row) in rgba.chunks_exact_mut(width * 4).enumerate() {
            for (i, texel) in row.chunks_exact_mut(4).enumerate() {
                let d = latlong_to_direction((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32);
                let (on, u, v) = cube_face_at(d, cot);
                if on == k {
                    texel.copy_from_slice(&bilinear_rgba(&image, u, v));
                }
            }
        }
    }
    let image = TexImage::new(width, height, 4, rgba)
        .ok_or_else(|| ImageError::Encode { path: dst.to_path_buf(), message: "an empty map".into() })?;
    write_texture(&image, dst, &MakeTextureOptions { swrap: Wrap::Periodic, twrap: Wrap::Clamp, raw })
}

/// The face (0 to 5: +x, -x, +y, -y, +z, -z) direction `d` points to and where on it, `(u, v)`
/// with u to the right and v down, 0 to 1 across a face of the field of view whose half-angle's
/// cotangent is `cot`.
fn cube_face_at([x, y, z]: [f32; 3], cot: f32) -> (usize, f32, f32) {
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    // (face, right, up) over the major axis' length.
    let (face, right, up, major) = if ax >= ay && ax >= az {
        if x > 0.0 {
            (0, -z, y, ax)
        } else {
            (1, z, y, ax)
        }
    } else if ay >= az {
        if y > 0.0 {
            (2, x, -z, ay)
        } else {
            (3, x, z, ay)
        }
    } else if z > 0.0 {
        (4, x, y, az)
    } else {
        (5, -x, y, az)
    };
    let major = major.max(f32::MIN_POSITIVE);
    (face, 0.5 + 0.5 * cot * right / major, 0.5 - 0.5 * cot * up / major)
}

/// The bilinear RGBA value of `image` at `(u, v)` (0 to 1 across, texel centres at half steps),
/// clamped to its edges.
fn bilinear_rgba(image: &TexImage, u: f32, v: f32) -> [f32; 4] {
    let (w, h) = (image.width(), image.height());
    let fx = (u * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
    let fy = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
    let at = |x, y| expand_to_rgba(image.texel(x, y));
    let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
    std::array::from_fn(|k| {
        let top = a[k] + (b[k] - a[k]) * tx;
        let bottom = c[k] + (d[k] - c[k]) * tx;
        top + (bottom - top) * ty
    })
}

/// Writes `image` as the texture file `dst` (see the module doc).
fn write_texture(image: &TexImage, dst: &Path, opts: &MakeTextureOptions) -> Result<(), ImageError> {
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

    /// Six 2x2 faces: red marks the face (`40 k` for face k), green the column, blue the row.
    fn write_faces(dir: &Path, across: u32) -> Vec<std::path::PathBuf> {
        (0..6u8)
            .map(|k| {
                let path = dir.join(format!("face{k}.png"));
                let mut bytes = Vec::new();
                for y in 0..across {
                    for x in 0..across {
                        let (g, b) = (if 2 * x >= across { 255 } else { 0 }, if 2 * y >= across { 255 } else { 0 });
                        bytes.extend([40 * k, g, b]);
                    }
                }
                ::image::save_buffer(&path, &bytes, across, across, ::image::ExtendedColorType::Rgb8).unwrap();
                path
            })
            .collect()
    }

    #[test]
    fn cube_faces_become_a_latlong_map_oriented_as_aqsis_reads_them() {
        let dir = tempfile::tempdir().unwrap();
        let faces = write_faces(dir.path(), 2);
        let dst = dir.path().join("env.tex");
        let f: Vec<&Path> = faces.iter().map(|p| p.as_path()).collect();
        make_cube_face_environment([f[0], f[1], f[2], f[3], f[4], f[5]], &dst, 90.0, false).unwrap();
        let loaded = load_texture_image(&dst, false).unwrap();
        let image = &loaded.image;
        assert_eq!((image.width(), image.height(), image.channels()), (8, 4, 4));
        assert_eq!(loaded.wrap, Some([Wrap::Periodic, Wrap::Clamp]));
        // Each face seen up and to the right of its centre, then one down and to the left.
        let cases: [([f32; 3], usize, [f32; 2]); 7] = [
            ([1.0, 0.5, -0.5], 0, [1.0, 0.0]),
            ([-1.0, 0.5, 0.5], 1, [1.0, 0.0]),
            ([0.5, 1.0, -0.5], 2, [1.0, 0.0]),
            ([0.5, -1.0, 0.5], 3, [1.0, 0.0]),
            ([0.5, 0.5, 1.0], 4, [1.0, 0.0]),
            ([-0.5, 0.5, -1.0], 5, [1.0, 0.0]),
            ([-0.5, -0.5, 1.0], 4, [0.0, 1.0]),
        ];
        // A finer map, so the texel a direction lands in is near it.
        let faces = write_faces(dir.path(), 16);
        let f: Vec<&Path> = faces.iter().map(|p| p.as_path()).collect();
        make_cube_face_environment([f[0], f[1], f[2], f[3], f[4], f[5]], &dst, 90.0, false).unwrap();
        let image = load_texture_image(&dst, false).unwrap().image;
        for (d, face, [column, row]) in cases {
            let (s, t) = crate::texture::environment::direction_to_latlong(d).unwrap();
            let x = ((s * image.width() as f32) as usize).min(image.width() - 1);
            let y = ((t * image.height() as f32) as usize).min(image.height() - 1);
            let texel = image.texel(x, y);
            let marker = crate::texture::srgb_to_linear(40.0 * face as f32 / 255.0);
            assert!((texel[0] - marker).abs() < 1e-3, "{d:?}: face {face}, got {texel:?}");
            assert!((texel[1] - column).abs() < 1e-3 && (texel[2] - row).abs() < 1e-3, "{d:?}: got {texel:?}");
        }
    }

    #[test]
    fn cube_faces_refuse_a_bad_field_of_view_and_missing_faces() {
        let dir = tempfile::tempdir().unwrap();
        let faces = write_faces(dir.path(), 2);
        let f: Vec<&Path> = faces.iter().map(|p| p.as_path()).collect();
        let dst = dir.path().join("env.tex");
        for fov in [0.0, 180.0, f32::NAN, -5.0] {
            assert!(make_cube_face_environment([f[0], f[1], f[2], f[3], f[4], f[5]], &dst, fov, false).is_err());
        }
        let absent = dir.path().join("absent.png");
        let err = make_cube_face_environment([f[0], f[1], f[2], f[3], f[4], &absent], &dst, 95.0, false).unwrap_err();
        assert!(err.to_string().contains("absent.png"), "{err}");
        assert!(!dst.exists());
    }
}

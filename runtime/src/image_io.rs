//! Reading and writing whole images: rendered frames, golden images, and the EXR files behind
//! textures and shadow maps.
//!
//! Conventions, for every function here:
//! - Pixels are `f32`, row-major, **top row first**, `channels` values per pixel (RGBA frames:
//!   4, straight from the framebuffer, linear and not premultiplied by this module).
//! - The format follows the file extension (case-insensitive): `.png`, `.tga`, `.ppm`, `.tif`
//!   (`.tiff`) and `.exr`. Integer files are 8-bit unless a [`Quantize`] asks for 16 bits (PNG,
//!   TIFF) or for floats (TIFF); EXR is always float (32-bit or half).
//! - Integer files are display-encoded: colour (not alpha, not depth) goes through the sRGB curve
//!   unless [`WriteOptions::transfer`] says [`Transfer::Linear`], then is quantised as RenderMan's
//!   `Quantize "rgba" one min max ditheramplitude` says: value times `one`, plus 0.5 (or plus a
//!   dither of the amplitude around it), truncated and clamped to `min..=max`. Without a
//!   `Quantize` that is `255 0 255` and no dither (RenderMan's default dithers by 0.5;
//!   [`WriteOptions::dither`] asks for it). Float files hold the linear values.
//!   `.ppm` has no alpha channel: alpha is dropped.
//! - [`read_image`] gives back exactly what was stored: 8-bit values divided by 255 (no sRGB
//!   decoding: that is a texture's business, see `crate::texture`), EXR values as they are.
//!   Missing channels read as 0, a missing alpha as 1; a luminance-only file (`Y`/grey, or an EXR
//!   of one channel such as depth `Z`) fills R, G, B.
//!
//! Every error names the file it is about.

use std::path::{Path, PathBuf};

use exr::prelude::{self as exrp, ReadChannels, ReadLayers, WritableImage};

/// An error reading, writing or comparing images. Each names the path it concerns.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: cannot decode: {message}")]
    Decode { path: PathBuf, message: String },
    #[error("{path}: cannot encode: {message}")]
    Encode { path: PathBuf, message: String },
    #[error("{path}: unsupported image format (known: .png .tga .ppm .tif .exr, and .jpg for reading)")]
    UnsupportedFormat { path: PathBuf },
    #[error("{path}: this format cannot store {what}")]
    UnsupportedSamples { path: PathBuf, what: String },
    #[error("{path}: {width}x{height} pixels with {channels} channels need {expected} values, got {got}")]
    BufferSize { path: PathBuf, width: usize, height: usize, channels: usize, expected: usize, got: usize },
    #[error("images differ in size: {a_width}x{a_height} and {b_width}x{b_height}")]
    SizeMismatch { a_width: usize, a_height: usize, b_width: usize, b_height: usize },
}

/// A file format this module writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Tga,
    Ppm,
    Tiff,
    Exr,
}

impl ImageFormat {
    /// The format named by a path's extension, if it is one we write.
    pub fn from_path(path: &Path) -> Option<ImageFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(ImageFormat::Png),
            "tga" => Some(ImageFormat::Tga),
            "ppm" => Some(ImageFormat::Ppm),
            "tif" | "tiff" => Some(ImageFormat::Tiff),
            "exr" => Some(ImageFormat::Exr),
            _ => None,
        }
    }
}

/// How [`write_image`] encodes pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WriteOptions {
    /// EXR only: store half floats (16-bit) instead of 32-bit floats.
    pub exr_half: bool,
    /// 8-bit only: add an ordered dither (a 4x4 Bayer matrix, deterministic) instead of rounding,
    /// RenderMan's `Quantize ... 0.5` dither amplitude. Breaks up banding in smooth gradients.
    pub dither: bool,
    /// Integer files only: the curve colour (not alpha) goes through before quantising.
    pub transfer: Transfer,
    /// How values become what the file stores; `None` for 8 bits, rounded (or dithered by
    /// [`WriteOptions::dither`]).
    pub quantize: Option<Quantize>,
}

/// RenderMan's `Quantize`: a value becomes `floor(one * value + 0.5 + dither * d)` clamped to
/// `[min, max]`, `d` in [-1, 1) from an ordered (4x4 Bayer) dither, deterministic. `one` of 0 asks
/// for floats.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Quantize {
    pub one: f32,
    pub min: f32,
    pub max: f32,
    pub dither: f32,
}

/// What a file's samples are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleType {
    U8,
    U16,
    F32,
}

impl Quantize {
    /// 8 bits, rounded.
    pub const EIGHT_BIT: Quantize = Quantize { one: 255.0, min: 0.0, max: 255.0, dither: 0.0 };

    /// The samples it asks for: floats for `one` of 0 (or less), 8 bits up to a `max` of 255, 16
    /// bits above.
    pub fn samples(&self) -> SampleType {
        if self.one <= 0.0 || !self.one.is_finite() {
            SampleType::F32
        } else if self.max <= 255.0 {
            SampleType::U8
        } else {
            SampleType::U16
        }
    }

    /// The integer `v` (already display-encoded) becomes at pixel `(x, y)`.
    fn apply(&self, v: f32, x: usize, y: usize) -> f32 {
        let d = if self.dither > 0.0 { self.dither * (2.0 * BAYER4[y % 4][x % 4] - 1.0) } else { 0.0 };
        let top = if self.samples() == SampleType::U8 { 255.0 } else { 65535.0 };
        // NaN becomes 0 (the casts after), infinities clamp.
        (v * self.one + 0.5 + d).floor().clamp(self.min.max(0.0), self.max.min(top))
    }
}

/// How the linear values of a frame become the values an 8-bit file stores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Transfer {
    /// The sRGB curve (IEC 61966-2-1), what displays and image viewers expect of an 8-bit file.
    /// 8-bit textures are decoded with its inverse (`crate::texture`), so a written image read back
    /// as a texture gives the values rendered.
    #[default]
    Srgb,
    /// None: the values as rendered (RenderMan's convention, for RIB scenes and data, or when the
    /// scene applied its own gamma with RIB `Exposure`).
    Linear,
}

impl Transfer {
    /// `srgb` or `linear` (case-insensitive), for flags.
    pub fn parse(name: &str) -> Result<Transfer, String> {
        match name.to_ascii_lowercase().as_str() {
            "srgb" => Ok(Transfer::Srgb),
            "linear" => Ok(Transfer::Linear),
            _ => Err(format!("`{name}` is not a transfer: srgb or linear")),
        }
    }

    /// A linear value encoded.
    pub fn encode(self, v: f32) -> f32 {
        match self {
            Transfer::Srgb => crate::texture::linear_to_srgb(v),
            Transfer::Linear => v,
        }
    }

    /// A table for encoding whole frames to 8 bits fast (a viewer's every frame):
    /// [`ByteTable::byte`] of a linear value is within one code of what [`write_image`] stores.
    pub fn byte_table(self) -> ByteTable {
        let last = (ByteTable::LEN - 1) as f32;
        ByteTable(
            (0..ByteTable::LEN)
                .map(|i| (self.encode(i as f32 / last) * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8)
                .collect(),
        )
    }
}

/// Linear values in [0, 1] to 8-bit codes by table ([`Transfer::byte_table`]).
#[derive(Clone, Debug)]
pub struct ByteTable(Vec<u8>);

impl ByteTable {
    /// Entries over [0, 1]: fine enough that the sRGB curve's steepest part (slope 12.92 near 0)
    /// moves less than one code between neighbours.
    const LEN: usize = 8192;

    /// The 8-bit code of linear `v` (clamped to [0, 1]; NaN is 0).
    pub fn byte(&self, v: f32) -> u8 {
        let i = (v.clamp(0.0, 1.0) * (Self::LEN - 1) as f32 + 0.5) as usize;
        self.0[i.min(Self::LEN - 1)]
    }
}

/// A decoded image: `channels` floats per pixel, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbaImage {
    pub width: usize,
    pub height: usize,
    /// 4 values (R, G, B, A) per pixel.
    pub pixels: Vec<f32>,
}

impl RgbaImage {
    /// The RGBA value of pixel (x, y), y = 0 the top row.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 4] {
        let i = (y * self.width + x) * 4;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2], self.pixels[i + 3]]
    }
}

/// Writes a linear RGBA frame (4 floats per pixel, top row first), choosing the format by the
/// path's extension.
pub fn write_image(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgba: &[f32],
    opts: &WriteOptions,
) -> Result<(), ImageError> {
    write_channels(path, width, height, &["R", "G", "B", "A"], rgba, opts)
}

/// Writes an image of the named channels (`values` interleaved, `names.len()` a pixel, top row
/// first): one (a grey image: alpha `A`, depth `Z` or any other), three (`R G B`) or four
/// (`R G B A`); any number in EXR. Colour channels are display-encoded in integer files; the others are stored as
/// they are. Depth (`Z`) is refused in integer files: it is not a value in [0, 1].
pub fn write_channels(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    names: &[&str],
    values: &[f32],
    opts: &WriteOptions,
) -> Result<(), ImageError> {
    let path = path.as_ref();
    let format = ImageFormat::from_path(path).ok_or_else(|| ImageError::UnsupportedFormat { path: path.into() })?;
    write_channels_as(path, format, width, height, names, values, opts)
}

/// [`write_channels`] in `format`, whatever the path's extension (a RenderMan display driver
/// names the format, as `Display "ri.pic" "tiff" "rgb"` does).
pub fn write_channels_as(
    path: impl AsRef<Path>,
    format: ImageFormat,
    width: usize,
    height: usize,
    names: &[&str],
    values: &[f32],
    opts: &WriteOptions,
) -> Result<(), ImageError> {
    use ::image::ExtendedColorType as C;
    let path = path.as_ref();
    let channels = names.len();
    check_buffer(path, width, height, channels, values.len())?;
    let unsupported = |what: &str| ImageError::UnsupportedSamples { path: path.into(), what: what.into() };
    if format == ImageFormat::Exr {
        let channel = |c: usize| -> Vec<f32> { values.iter().skip(c).step_by(channels).copied().collect() };
        let layer = ExrLayer {
            width,
            height,
            channels: names.iter().enumerate().map(|(c, name)| (name.to_string(), channel(c))).collect(),
            ..ExrLayer::default()
        };
        return write_exr(path, &layer, opts.exr_half);
    }
    if !matches!(channels, 1 | 3 | 4) {
        return Err(unsupported(&format!("{channels} channels (use .exr)")));
    }
    let samples = opts.quantize.map_or(SampleType::U8, |q| q.samples());
    if names.contains(&"Z") && samples != SampleType::F32 {
        return Err(unsupported("depth as integers (write it to .exr or .tif with floats)"));
    }
    // PPM stores RGB: alpha is dropped, grey is repeated.
    let (names, values): (Vec<&str>, std::borrow::Cow<[f32]>) = match (format, channels) {
        (ImageFormat::Ppm, 4) => {
            (vec!["R", "G", "B"], values.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>().into())
        }
        (ImageFormat::Ppm, 1) => {
            (vec!["R", "G", "B"], values.iter().flat_map(|&v| [v, v, v]).collect::<Vec<_>>().into())
        }
        _ => (names.to_vec(), values.into()),
    };
    let channels = names.len();
    let color = |bytes: u8| match (channels, bytes) {
        (1, 1) => C::L8,
        (3, 1) => C::Rgb8,
        (4, 1) => C::Rgba8,
        (1, 2) => C::L16,
        (3, 2) => C::Rgb16,
        (4, 2) => C::Rgba16,
        (1 | 3, _) => C::Rgb32F,
        _ => C::Rgba32F,
    };
    match (samples, format) {
        (SampleType::F32, ImageFormat::Tiff) => {
            // The encoder has no one-channel float layout: grey is stored as RGB.
            let rgb: std::borrow::Cow<[f32]> =
                if channels == 1 { values.iter().flat_map(|&v| [v, v, v]).collect::<Vec<_>>().into() } else { values };
            save_encoded(path, format, bytemuck::cast_slice(&rgb[..]), width, height, color(4))
        }
        (SampleType::U16, ImageFormat::Png | ImageFormat::Tiff) => {
            let q = opts.quantize.unwrap_or(Quantize::EIGHT_BIT);
            let words: Vec<u16> =
                encode_integers(width, &names, &values, opts, |v, x, y| q.apply(v, x, y)).map(|v| v as u16).collect();
            save_encoded(path, format, bytemuck::cast_slice(&words), width, height, color(2))
        }
        (SampleType::U8, _) => {
            let bytes: Vec<u8> = match opts.quantize {
                Some(q) => {
                    encode_integers(width, &names, &values, opts, |v, x, y| q.apply(v, x, y)).map(|v| v as u8).collect()
                }
                None => quantize(width, &values, &names, opts),
            };
            save_encoded(path, format, &bytes, width, height, color(1))
        }
        (SampleType::F32, _) => Err(unsupported("floats (use .tif or .exr)")),
        (SampleType::U16, _) => Err(unsupported("16-bit samples (use .png or .tif)")),
    }
}

/// The values of an integer file before the cast: colour display-encoded, then quantised by
/// `apply(value, x, y)`.
fn encode_integers<'a>(
    width: usize,
    names: &'a [&str],
    values: &'a [f32],
    opts: &'a WriteOptions,
    apply: impl Fn(f32, usize, usize) -> f32 + 'a,
) -> impl Iterator<Item = f32> + 'a {
    let channels = names.len();
    values.iter().enumerate().map(move |(i, &v)| {
        let pixel = i / channels;
        let v = if is_colour(names[i % channels]) { opts.transfer.encode(v) } else { v };
        apply(v, pixel % width, pixel / width)
    })
}

/// Whether a channel holds colour, which integer files display-encode.
fn is_colour(name: &str) -> bool {
    matches!(name, "R" | "G" | "B")
}

/// Reads an image as RGBA floats (see the module doc for what the values mean).
pub fn read_image(path: impl AsRef<Path>) -> Result<RgbaImage, ImageError> {
    let path = path.as_ref();
    if is_exr(path) {
        let layer = read_exr(path)?;
        let (width, height) = (layer.width, layer.height);
        let get = |names: &[&str]| names.iter().find_map(|n| layer.channel(n));
        // Grey: `Y`, or a file's only channel (depth `Z`, say).
        let only = (layer.channels.len() == 1).then(|| layer.channels[0].1.as_slice());
        let luminance = get(&["Y", "y"]).or(only);
        let red = get(&["R", "r"]).or(luminance);
        let green = get(&["G", "g"]).or(luminance);
        let blue = get(&["B", "b"]).or(luminance);
        let alpha = get(&["A", "a"]);
        let mut pixels = Vec::with_capacity(width * height * 4);
        for i in 0..width * height {
            let at = |c: Option<&[f32]>, missing: f32| c.map_or(missing, |c| c[i]);
            pixels.extend([at(red, 0.0), at(green, 0.0), at(blue, 0.0), at(alpha, 1.0)]);
        }
        return Ok(RgbaImage { width, height, pixels });
    }
    let decoded = decode_with_image_crate(path)?;
    let rgba = decoded.to_rgba32f();
    Ok(RgbaImage { width: rgba.width() as usize, height: rgba.height() as usize, pixels: rgba.into_raw() })
}

/// Whether a file is OpenEXR: by its magic number, so that a `.tex` or `.shad` made by
/// `MakeTexture` is recognised; by its extension when it cannot be read (for the error).
pub fn is_exr(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 4];
    match std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)) {
        Ok(()) => magic == [0x76, 0x2f, 0x31, 0x01],
        Err(_) => ImageFormat::from_path(path) == Some(ImageFormat::Exr),
    }
}

/// Opens and decodes a non-EXR image with the `image` crate, guessing the format from the
/// content when the extension does not say. A panic inside a decoder becomes an error: a corrupt
/// file must never take the renderer down.
pub(crate) fn decode_with_image_crate(path: &Path) -> Result<::image::DynamicImage, ImageError> {
    let decode = || -> Result<::image::DynamicImage, ImageError> {
        let reader = ::image::ImageReader::open(path).map_err(|source| ImageError::Io { path: path.into(), source })?;
        let reader = reader.with_guessed_format().map_err(|source| ImageError::Io { path: path.into(), source })?;
        reader.decode().map_err(|e| ImageError::Decode { path: path.into(), message: decode_failure(path, &e) })
    };
    std::panic::catch_unwind(decode)
        .unwrap_or_else(|_| Err(ImageError::Decode { path: path.into(), message: "the decoder panicked".into() }))
}

/// Decodes an image file's bytes held in memory with the `image` crate (format from the content);
/// `name` is what errors call it. Never panics on corrupt bytes.
pub(crate) fn decode_memory_with_image_crate(name: &Path, bytes: &[u8]) -> Result<::image::DynamicImage, ImageError> {
    let decode = || {
        ::image::load_from_memory(bytes)
            .map_err(|e| ImageError::Decode { path: name.into(), message: unreadable_format(bytes, &e) })
    };
    std::panic::catch_unwind(decode)
        .unwrap_or_else(|_| Err(ImageError::Decode { path: name.into(), message: "the decoder panicked".into() }))
}

/// What a decoder's error says, with the format named when the file is in none that rtsl reads.
fn decode_failure(path: &Path, error: &::image::ImageError) -> String {
    use std::io::Read;
    let mut head = [0u8; 4];
    let read = std::fs::File::open(path).and_then(|mut f| f.read(&mut head)).unwrap_or(0);
    unreadable_format(&head[..read], error)
}

/// [`decode_failure`] of a file beginning with `head`.
fn unreadable_format(head: &[u8], error: &::image::ImageError) -> String {
    if !matches!(error, ::image::ImageError::Unsupported(_)) {
        return error.to_string();
    }
    // PRMan's own texture files before it wrote TIFF (`txmake`'s `.tx`), in either byte order.
    if head.starts_with(&[0xce, 0xfa]) || head.starts_with(&[0xfa, 0xce]) {
        return "PRMan's own texture format, which is not documented and which rtsl cannot read: make the \
                texture again from its source image (RIB `MakeTexture`, or any TIFF, PNG or EXR file)"
            .into();
    }
    "not an image format rtsl reads (OpenEXR, TIFF, PNG, JPEG, TGA, PPM/PGM)".into()
}

fn check_buffer(path: &Path, width: usize, height: usize, channels: usize, got: usize) -> Result<(), ImageError> {
    let expected = width * height * channels;
    if got != expected || width == 0 || height == 0 {
        return Err(ImageError::BufferSize { path: path.into(), width, height, channels, expected, got });
    }
    Ok(())
}

/// The 4x4 Bayer matrix, as thresholds in [0, 1): the dither added before truncation.
const BAYER4: [[f32; 4]; 4] = [
    [0.0 / 16.0, 8.0 / 16.0, 2.0 / 16.0, 10.0 / 16.0],
    [12.0 / 16.0, 4.0 / 16.0, 14.0 / 16.0, 6.0 / 16.0],
    [3.0 / 16.0, 11.0 / 16.0, 1.0 / 16.0, 9.0 / 16.0],
    [15.0 / 16.0, 7.0 / 16.0, 13.0 / 16.0, 5.0 / 16.0],
];

/// Quantises `channels`-wide pixels to bytes (see the module doc). The last channel of a
/// 4-channel pixel is alpha, never sRGB-encoded.
fn quantize(width: usize, values: &[f32], names: &[&str], opts: &WriteOptions) -> Vec<u8> {
    let channels = names.len();
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let pixel = i / channels;
            let v = if is_colour(names[i % channels]) { opts.transfer.encode(v) } else { v };
            let offset = if opts.dither { BAYER4[(pixel / width) % 4][(pixel % width) % 4] } else { 0.5 };
            // NaN becomes 0 (the `as` cast), infinities clamp.
            (v * 255.0 + offset).floor().clamp(0.0, 255.0) as u8
        })
        .collect()
}

fn save_encoded(
    path: &Path,
    format: ImageFormat,
    bytes: &[u8],
    width: usize,
    height: usize,
    color: ::image::ExtendedColorType,
) -> Result<(), ImageError> {
    let format = match format {
        ImageFormat::Png => ::image::ImageFormat::Png,
        ImageFormat::Tga => ::image::ImageFormat::Tga,
        ImageFormat::Ppm => ::image::ImageFormat::Pnm,
        ImageFormat::Tiff => ::image::ImageFormat::Tiff,
        ImageFormat::Exr => ::image::ImageFormat::OpenExr,
    };
    let mut encoded = std::io::Cursor::new(Vec::new());
    ::image::write_buffer_with_format(&mut encoded, bytes, width as u32, height as u32, color, format)
        .map_err(|e| ImageError::Encode { path: path.into(), message: e.to_string() })?;
    write_file(path, encoded.get_ref())
}

/// Writes a whole encoded file, every failure (a full disk included) an error. A regular file, or
/// a new one, is written to a temporary file beside it and renamed over it, so a failed write
/// leaves the old file as it was and a reader never sees half an image. A symbolic link is
/// followed and its target replaced, so the link stays. What cannot be renamed over (a device such
/// as `/dev/stdout`, a named pipe) is written in place.
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    use std::io::Write;
    let io = |source| ImageError::Io { path: path.into(), source };
    let target = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    if let Ok(meta) = std::fs::metadata(&target) {
        if !meta.is_file() && !meta.is_dir() {
            let mut file = std::fs::OpenOptions::new().write(true).open(&target).map_err(io)?;
            return file.write_all(bytes).and_then(|()| file.flush()).map_err(io);
        }
    }
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.{}.{n}.tmp", std::process::id()));
    let written = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp).and_then(|mut file| {
        file.write_all(bytes)?;
        // Some file systems report a full disk only when the data reaches it.
        file.sync_all()
    });
    if let Err(e) = written.and_then(|()| std::fs::rename(&tmp, &target)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    Ok(())
}

/// One layer of an EXR file as plain floats, with the header attributes rtsl uses.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExrLayer {
    pub width: usize,
    pub height: usize,
    /// Channels by name, each `width * height` values, top row first. EXR stores channels
    /// sorted by name; [`write_exr`] sorts them.
    pub channels: Vec<(String, Vec<f32>)>,
    /// The standard `worldToCamera` attribute: row-vector convention (`p' = p M`, OpenEXR's
    /// and Imath's), so elements 12..15 are the translation.
    pub world_to_camera: Option<[f32; 16]>,
    /// The standard `worldToNDC` attribute, same convention.
    pub world_to_ndc: Option<[f32; 16]>,
    /// The standard `wrapmodes` attribute, e.g. `"periodic,clamp"` (s then t).
    pub wrap_modes: Option<String>,
}

impl ExrLayer {
    /// The values of the channel called `name`, if there is one.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_slice())
    }
}

/// The most channel values (pixels times channels) [`read_exr`] accepts: 1 GiB of floats. A
/// corrupt header can claim any size; refusing it beats aborting on a failed allocation.
pub const MAX_EXR_VALUES: usize = 1 << 28;

/// Reads the first layer of an EXR file, every channel converted to `f32`.
pub fn read_exr(path: &Path) -> Result<ExrLayer, ImageError> {
    read_exr_from(path, || std::fs::File::open(path).map(std::io::BufReader::new))
}

/// Reads the first layer of an EXR file's bytes held in memory, as [`read_exr`] reads the file;
/// `name` is what errors call it.
pub fn read_exr_bytes(name: &Path, bytes: &[u8]) -> Result<ExrLayer, ImageError> {
    read_exr_from(name, || Ok(std::io::Cursor::new(bytes)))
}

/// Whether bytes held in memory are an OpenEXR file (its magic number).
pub fn is_exr_bytes(bytes: &[u8]) -> bool {
    bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01])
}

/// [`read_exr`] over whatever `open` reads (opened twice: the header is checked first).
fn read_exr_from<R: std::io::Read + std::io::Seek + Send>(
    path: &Path,
    open: impl Fn() -> std::io::Result<R> + std::panic::RefUnwindSafe,
) -> Result<ExrLayer, ImageError> {
    let failed = |e: exr::error::Error| match e {
        exr::error::Error::Io(source) => ImageError::Io { path: path.into(), source },
        e => ImageError::Decode { path: path.into(), message: e.to_string() },
    };
    let panicked = || ImageError::Decode { path: path.into(), message: "the decoder panicked".into() };
    let meta = std::panic::catch_unwind(|| exr::meta::MetaData::read_from_buffered(open()?, false))
        .map_err(|_| panicked())?
        .map_err(failed)?;
    for header in meta.headers.iter() {
        let values = header
            .layer_size
            .0
            .checked_mul(header.layer_size.1)
            .and_then(|p| p.checked_mul(header.channels.list.len()));
        if values.is_none_or(|v| v > MAX_EXR_VALUES) {
            let (w, h) = (header.layer_size.0, header.layer_size.1);
            let message =
                format!("{w}x{h} pixels with {} channels is larger than rtsl reads", header.channels.list.len());
            return Err(ImageError::Decode { path: path.into(), message });
        }
    }
    let read = || {
        exrp::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(open()?)
    };
    let image = std::panic::catch_unwind(read).map_err(|_| panicked())?.map_err(failed)?;
    let layer = image.layer_data;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect::<Vec<f32>>()))
        .collect();
    let attrs = &layer.attributes;
    Ok(ExrLayer {
        width: layer.size.0,
        height: layer.size.1,
        channels,
        world_to_camera: attrs.world_to_camera,
        world_to_ndc: attrs.world_to_normalized_device,
        wrap_modes: attrs.wrap_mode_name.as_ref().map(|t| t.to_string()),
    })
}

/// Writes one EXR layer (ZIP-compressed, lossless), 32-bit floats or halves.
pub fn write_exr(path: &Path, layer: &ExrLayer, half: bool) -> Result<(), ImageError> {
    let (width, height) = (layer.width, layer.height);
    for (_, values) in &layer.channels {
        check_buffer(path, width, height, 1, values.len())?;
    }
    let list: exrp::SmallVec<[exrp::AnyChannel<exrp::FlatSamples>; 4]> = layer
        .channels
        .iter()
        .map(|(name, values)| {
            let samples = if half {
                exrp::FlatSamples::F16(values.iter().map(|&v| exrp::f16::from_f32(v)).collect())
            } else {
                exrp::FlatSamples::F32(values.clone())
            };
            exrp::AnyChannel::new(name.as_str(), samples)
        })
        .collect();
    let attributes = exrp::LayerAttributes {
        world_to_camera: layer.world_to_camera,
        world_to_normalized_device: layer.world_to_ndc,
        wrap_mode_name: layer.wrap_modes.as_deref().map(exrp::Text::from),
        ..exrp::LayerAttributes::default()
    };
    let exr_layer =
        exrp::Layer::new((width, height), attributes, exrp::Encoding::SMALL_LOSSLESS, exrp::AnyChannels::sort(list));
    let mut encoded = std::io::Cursor::new(Vec::new());
    exrp::Image::from_layer(exr_layer)
        .write()
        .to_buffered(&mut encoded)
        .map_err(|e| ImageError::Encode { path: path.into(), message: e.to_string() })?;
    write_file(path, encoded.get_ref())
}

/// How two images differ, pixel by pixel: for golden-image tests.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDiff {
    pub width: usize,
    pub height: usize,
    /// The largest absolute difference of any channel of any pixel.
    pub max_abs: f32,
    /// The mean absolute difference over all channels of all pixels.
    pub mean_abs: f32,
    /// The root mean square difference over all channels of all pixels.
    pub rmse: f32,
    /// Per pixel, the largest absolute difference of its four channels.
    pub per_pixel: Vec<f32>,
}

impl ImageDiff {
    /// How many pixels have a channel that differs by more than `threshold`.
    pub fn differing_pixels(&self, threshold: f32) -> usize {
        self.per_pixel.iter().filter(|&&d| d > threshold).count()
    }

    /// A picture of the difference: each pixel's largest channel difference times `scale`, as
    /// grey, opaque. Write it with [`write_image`].
    pub fn difference_image(&self, scale: f32) -> RgbaImage {
        let pixels = self.per_pixel.iter().flat_map(|&d| [d * scale, d * scale, d * scale, 1.0]).collect();
        RgbaImage { width: self.width, height: self.height, pixels }
    }
}

/// Compares two RGBA images of the same size. NaN differences count as infinite, so a NaN
/// in either image never passes a threshold.
pub fn diff_image(a: &RgbaImage, b: &RgbaImage) -> Result<ImageDiff, ImageError> {
    if a.width != b.width || a.height != b.height {
        return Err(ImageError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    let (mut sum, mut sum_sq, mut max_abs) = (0.0f64, 0.0f64, 0.0f32);
    let per_pixel: Vec<f32> = a
        .pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .map(|(pa, pb)| {
            let mut pixel_max = 0.0f32;
            for (x, y) in pa.iter().zip(pb) {
                let d = (x - y).abs();
                let d = if d.is_nan() { f32::INFINITY } else { d };
                pixel_max = pixel_max.max(d);
                sum += d as f64;
                sum_sq += (d as f64) * (d as f64);
            }
            max_abs = max_abs.max(pixel_max);
            pixel_max
        })
        .collect();
    let n = (a.pixels.len().max(1)) as f64;
    Ok(ImageDiff {
        width: a.width,
        height: a.height,
        max_abs,
        mean_abs: (sum / n) as f32,
        rmse: (sum_sq / n).sqrt() as f32,
        per_pixel,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3x2 frame with distinct values in every channel, exactly representable in 8 bits.
    fn frame() -> Vec<f32> {
        (0..3 * 2 * 4).map(|i| (i * 10) as f32 / 255.0).collect()
    }

    /// Written as rendered, no transfer curve: what the quantisation tests look at.
    const LINEAR: WriteOptions =
        WriteOptions { exr_half: false, dither: false, transfer: Transfer::Linear, quantize: None };

    #[test]
    fn tiff_stores_8_bit_16_bit_and_float_samples() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.tif");
        let values: Vec<f32> = vec![0.0, 0.25, 0.5, 1.0, 2.5, -1.0, 0.125, 0.75];
        let write = |q: Option<Quantize>| {
            write_image(&path, 2, 1, &values, &WriteOptions { quantize: q, ..LINEAR }).unwrap();
            read_image(&path).unwrap().pixels
        };
        // 8 bits: rounded, clamped.
        let eight = write(None);
        assert_eq!(
            eight.iter().map(|v| (v * 255.0).round() as i32).collect::<Vec<_>>(),
            [0, 64, 128, 255, 255, 0, 32, 191]
        );
        // 16 bits: `Quantize "rgba" 65535 0 65535 0`.
        let sixteen = write(Some(Quantize { one: 65535.0, min: 0.0, max: 65535.0, dither: 0.0 }));
        assert!((sixteen[1] - 0.25).abs() < 1.0 / 65535.0 && sixteen[4] == 1.0, "{sixteen:?}");
        // Floats: `Quantize "rgba" 0 0 0 0` keeps every value, out of [0, 1] too.
        let float = write(Some(Quantize { one: 0.0, min: 0.0, max: 0.0, dither: 0.0 }));
        assert_eq!(float, values);
    }

    #[test]
    fn quantize_follows_renderman() {
        let q = Quantize { one: 100.0, min: 10.0, max: 90.0, dither: 0.0 };
        assert_eq!((q.apply(0.5, 0, 0), q.apply(0.0, 0, 0), q.apply(1.0, 0, 0)), (50.0, 10.0, 90.0));
        // A dither of amplitude 0.5 spreads one value over neighbouring codes, averaging it.
        let dithered = Quantize { one: 255.0, min: 0.0, max: 255.0, dither: 0.5 };
        let v = 100.3 / 255.0;
        let codes: Vec<f32> = (0..16).map(|i| dithered.apply(v, i % 4, i / 4)).collect();
        assert!(codes.iter().all(|&c| c == 100.0 || c == 101.0), "{codes:?}");
        assert!((codes.iter().sum::<f32>() / 16.0 - 100.3).abs() < 0.07, "{codes:?}");
        assert_eq!(Quantize::EIGHT_BIT.samples(), SampleType::U8);
    }

    #[test]
    fn one_channel_images_and_depth() {
        let dir = tempfile::tempdir().unwrap();
        let alpha = dir.path().join("a.png");
        write_channels(&alpha, 2, 1, &["A"], &[0.5, 1.0], &WriteOptions::default()).unwrap();
        // Alpha is not display-encoded.
        assert_eq!(read_image(&alpha).unwrap().pixel(0, 0)[0], 128.0 / 255.0);
        let float = WriteOptions { quantize: Some(Quantize { one: 0.0, min: 0.0, max: 0.0, dither: 0.0 }), ..LINEAR };
        for name in ["z.exr", "z.tif"] {
            let path = dir.path().join(name);
            write_channels(&path, 2, 1, &["Z"], &[3.5, 7.0], &float).unwrap();
            assert_eq!(read_image(&path).unwrap().pixel(1, 0)[0], 7.0, "{name}");
        }
        let err = write_channels(dir.path().join("z.png"), 2, 1, &["Z"], &[3.5, 7.0], &WriteOptions::default());
        assert!(err.unwrap_err().to_string().contains("cannot store depth as integers"));
        let err = write_image(dir.path().join("f.png"), 1, 1, &[0.0; 4], &float);
        assert!(err.unwrap_err().to_string().contains("cannot store floats"));
    }

    #[test]
    fn eight_bit_formats_round_trip_to_the_nearest_level() {
        let dir = tempfile::tempdir().unwrap();
        for ext in ["png", "tga"] {
            let path = dir.path().join(format!("frame.{ext}"));
            write_image(&path, 3, 2, &frame(), &LINEAR).unwrap();
            let back = read_image(&path).unwrap();
            assert_eq!((back.width, back.height), (3, 2));
            for (a, b) in back.pixels.iter().zip(frame()) {
                assert!((a - b).abs() < 1e-6, "{ext}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn ppm_drops_alpha() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.PPM");
        write_image(&path, 3, 2, &frame(), &LINEAR).unwrap();
        let back = read_image(&path).unwrap();
        let want = frame();
        for p in 0..6 {
            for c in 0..3 {
                assert!((back.pixels[p * 4 + c] - want[p * 4 + c]).abs() < 1e-6);
            }
            assert_eq!(back.pixels[p * 4 + 3], 1.0);
        }
    }

    #[test]
    fn png_quantises_like_renderman_and_clamps() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.png");
        // 0.5/255 rounds up to 1; below it to 0; out of range and NaN clamp.
        let values = [0.49 / 255.0, 0.5 / 255.0, 2.0, -1.0, f32::NAN, f32::INFINITY, 1.0, 0.0];
        write_image(&path, 2, 1, &values, &LINEAR).unwrap();
        let back = read_image(&path).unwrap();
        let bytes: Vec<u8> = back.pixels.iter().map(|v| (v * 255.0).round() as u8).collect();
        assert_eq!(bytes, [0, 1, 255, 0, 0, 255, 255, 0]);
    }

    #[test]
    fn eight_bit_colour_is_srgb_encoded_by_default_and_alpha_and_exr_are_not() {
        let dir = tempfile::tempdir().unwrap();
        // Linear 0.22 is sRGB 0.506 (code 129, where linear would be 56); 0.0031308 is where the
        // curve's linear part ends (12.92 times it).
        let values = [0.22, 0.0031308, 1.0, 0.22];
        let path = dir.path().join("s.png");
        write_image(&path, 1, 1, &values, &WriteOptions::default()).unwrap();
        let back = read_image(&path).unwrap();
        let bytes: Vec<u8> = back.pixels.iter().map(|v| (v * 255.0).round() as u8).collect();
        assert_eq!(bytes, [129, 10, 255, 56], "colour encoded, alpha as it is");
        let path = dir.path().join("s.exr");
        write_image(&path, 1, 1, &values, &WriteOptions::default()).unwrap();
        assert_eq!(read_image(&path).unwrap().pixels, values, "EXR stays linear");
        // The viewer's table agrees with the file to within one code.
        let table = Transfer::Srgb.byte_table();
        for v in (0..=1000).map(|i| i as f32 / 1000.0) {
            let file = (Transfer::Srgb.encode(v) * 255.0 + 0.5).floor();
            assert!((f32::from(table.byte(v)) - file).abs() <= 1.0, "{v}: {} vs {file}", table.byte(v));
        }
        assert_eq!((table.byte(f32::NAN), table.byte(-1.0), table.byte(7.0)), (0, 0, 255));
    }

    #[test]
    fn dithering_keeps_the_mean_of_a_flat_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let level = 100.3 / 255.0;
        let values = vec![level; 8 * 8 * 4];
        write_image(&path, 8, 8, &values, &WriteOptions { dither: true, ..LINEAR }).unwrap();
        let back = read_image(&path).unwrap();
        let mean = back.pixels.iter().map(|v| v * 255.0).sum::<f32>() / back.pixels.len() as f32;
        assert!((mean - 100.3).abs() < 0.1, "mean {mean}");
        assert!(back.pixels.iter().any(|&v| (v * 255.0).round() == 101.0));
    }

    #[test]
    fn exr_round_trips_floats_exactly_and_halves_closely() {
        let dir = tempfile::tempdir().unwrap();
        let values: Vec<f32> = (0..4 * 3 * 4).map(|i| i as f32 * 0.37 - 3.0).collect();
        let path = dir.path().join("f.exr");
        write_image(&path, 4, 3, &values, &WriteOptions::default()).unwrap();
        assert_eq!(read_image(&path).unwrap().pixels, values);

        let path = dir.path().join("h.exr");
        write_image(&path, 4, 3, &values, &WriteOptions { exr_half: true, ..WriteOptions::default() }).unwrap();
        let back = read_image(&path).unwrap();
        for (a, b) in back.pixels.iter().zip(&values) {
            assert!((a - b).abs() <= b.abs() * 1e-3 + 1e-3, "{a} vs {b}");
        }
    }

    #[test]
    fn exr_attributes_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("z.exr");
        let m: [f32; 16] = std::array::from_fn(|i| i as f32);
        let layer = ExrLayer {
            width: 2,
            height: 1,
            channels: vec![("Z".into(), vec![1.0, 2.0])],
            world_to_camera: Some(m),
            world_to_ndc: Some(m.map(|v| -v)),
            wrap_modes: Some("clamp,periodic".into()),
        };
        write_exr(&path, &layer, false).unwrap();
        assert_eq!(read_exr(&path).unwrap(), layer);
    }

    #[test]
    fn errors_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.png");
        let err = read_image(&missing).unwrap_err();
        assert!(matches!(err, ImageError::Io { .. }));
        assert!(err.to_string().contains("missing.png"));
        let err = write_image(dir.path().join("x.bmp"), 1, 1, &[0.0; 4], &WriteOptions::default()).unwrap_err();
        assert!(matches!(err, ImageError::UnsupportedFormat { .. }), "{err}");
        let err = write_image(dir.path().join("x.png"), 2, 2, &[0.0; 4], &WriteOptions::default()).unwrap_err();
        assert!(matches!(err, ImageError::BufferSize { expected: 16, got: 4, .. }), "{err}");
        let garbage = dir.path().join("garbage.exr");
        std::fs::write(&garbage, b"not an exr at all").unwrap();
        let err = read_image(&garbage).unwrap_err();
        assert!(err.to_string().contains("garbage.exr"), "{err}");
    }

    #[test]
    fn an_exr_header_claiming_a_huge_image_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.exr");
        write_image(&path, 1, 1, &[0.0; 4], &WriteOptions::default()).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        // dataWindow is a box2i: xMin yMin xMax yMax after the name, type and a 4-byte size.
        let key = b"dataWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
        bytes[at + 8..at + 16].copy_from_slice(&[0, 0, 0, 0x10, 0, 0, 0, 0x10]);
        std::fs::write(&path, bytes).unwrap();
        let err = read_image(&path).unwrap_err();
        assert!(err.to_string().contains("larger than rtsl reads"), "{err}");
    }

    #[test]
    fn diff_statistics() {
        let a = RgbaImage { width: 2, height: 1, pixels: vec![0.0, 0.0, 0.0, 1.0, 0.5, 0.5, 0.5, 1.0] };
        let mut b = a.clone();
        b.pixels[4] = 0.7; // one channel of the second pixel differs by 0.2
        let d = diff_image(&a, &b).unwrap();
        assert!((d.max_abs - 0.2).abs() < 1e-6);
        assert!((d.mean_abs - 0.2 / 8.0).abs() < 1e-6);
        assert!((d.rmse - (0.04f32 / 8.0).sqrt()).abs() < 1e-6);
        assert_eq!(d.differing_pixels(0.1), 1);
        assert_eq!(d.differing_pixels(0.3), 0);
        assert_eq!(d.difference_image(5.0).pixel(1, 0)[0], d.per_pixel[1] * 5.0);
        assert_eq!(diff_image(&a, &a).unwrap().max_abs, 0.0);

        let mut nan = a.clone();
        nan.pixels[0] = f32::NAN;
        assert_eq!(diff_image(&a, &nan).unwrap().differing_pixels(1e9), 1);
        let small = RgbaImage { width: 1, height: 1, pixels: vec![0.0; 4] };
        assert!(matches!(diff_image(&a, &small), Err(ImageError::SizeMismatch { .. })));
    }

    #[test]
    fn difference_image_can_be_written() {
        let dir = tempfile::tempdir().unwrap();
        let a = RgbaImage { width: 1, height: 1, pixels: vec![0.0, 0.0, 0.0, 1.0] };
        let b = RgbaImage { width: 1, height: 1, pixels: vec![0.1, 0.0, 0.0, 1.0] };
        let img = diff_image(&a, &b).unwrap().difference_image(10.0);
        let path = dir.path().join("diff.png");
        write_image(&path, img.width, img.height, &img.pixels, &WriteOptions::default()).unwrap();
        assert_eq!(read_image(&path).unwrap().pixel(0, 0), [1.0, 1.0, 1.0, 1.0]);
    }
}

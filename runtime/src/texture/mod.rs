//! Textures for the shading language's `texture()`, `environment()` and `shadow()`, and the 3-D
//! grids of `texture3d()` (`grid.rs`, `docs/volumes.md`).
//!
//! `docs/textures.md` is the user-facing description; the conventions every part keeps are:
//!
//! - **Coordinates.** RenderMan's: `s` runs left to right, `t` runs **down**, so `(0, 0)` is the
//!   top-left corner of the image and `t = 0` its top row. Texel `(i, j)` covers
//!   `[i/w, (i+1)/w] x [j/h, (j+1)/h]`; its centre is exact under bilinear filtering.
//! - **Colour.** Texels are linear `f32`. 8-bit and 16-bit files (PNG, JPEG, TGA, PPM) are taken
//!   as sRGB-encoded and decoded to linear at load, except alpha (always linear) and except when
//!   the lookup asks for raw data ([`LookupOptions::raw`], for bump or normal maps). Float files
//!   (EXR) are read as they are.
//! - **Wrap modes** ([`Wrap`]): RenderMan's `periodic`, `clamp` and `black`, per axis. A lookup's
//!   [`LookupOptions::swrap`]/`twrap` override the file's own `wrapmodes` attribute (written by
//!   [`make_texture`]); with neither, `periodic`.
//! - **Filtering.** The footprint is the screen-space derivatives of `(s, t)`, widened by
//!   `swidth`/`twidth` (multipliers) and `sblur`/`tblur` (added, in texture coordinates). It
//!   becomes an ellipse in texel space; its minor axis picks the mip level (trilinear between two),
//!   and up to [`MAX_ANISOTROPY`] trilinear probes along the major axis cover its length.
//! - **Failure.** A texture that cannot be loaded gives one warning (see
//!   [`TextureCache::take_warnings`]) and then every lookup answers `false`/`None` at once; the caller
//!   applies RenderMan's `fill` value. Nothing here panics on a bad file.
//! - **Threads.** [`TextureCache`] is `Send + Sync`: lookups take `&self`, each file loads once
//!   however many threads ask for it at the same moment, and loaded data is shared as `Arc`.

mod cache;
mod environment;
pub mod grid;
pub mod grid_data;
pub(crate) mod image;
mod level_tiles;
mod make;
mod mip;
mod remote;
mod shadow;
mod source;

pub use cache::{TextureCache, TextureInfo, TextureQuery, TextureWarning};
pub use environment::{direction_to_latlong, latlong_to_direction};
pub use grid::{Grid, GridError, GridType};
pub use image::{load_texture_image, LoadedImage, TexImage};
pub use make::{make_cube_face_environment, make_texture, MakeTextureOptions, MAX_CUBE_LATLONG_WIDTH};
pub use mip::{level_sizes, LookupLanes, MipMap, MAX_ANISOTROPY};
pub use remote::{DecodedTexture, TextureDecoder, TextureServer, MAX_SERVED_BYTES, TILED_FROM_BYTES};
pub use shadow::{make_shadow, write_shadow_map, ShadowMap};
pub use source::{
    decode_answer, encode_answer, Delivered, LevelValues, PyramidHeader, TextureAnswer, TextureKind, TexturePart,
    TextureSource,
};

/// What a lookup outside `[0, 1]` sees, per axis (RenderMan's `swrap`/`twrap` names).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// The texture repeats.
    #[default]
    Periodic,
    /// The edge texels extend forever.
    Clamp,
    /// Outside is zero in every channel (alpha too).
    Black,
}

impl Wrap {
    /// The mode for a RenderMan name (`"periodic"`, `"clamp"`, `"black"`; OpenEXR's `"repeat"`
    /// is taken as periodic), case-insensitive.
    pub fn from_name(name: &str) -> Option<Wrap> {
        match name.trim().to_ascii_lowercase().as_str() {
            "periodic" | "repeat" => Some(Wrap::Periodic),
            "clamp" => Some(Wrap::Clamp),
            "black" => Some(Wrap::Black),
            _ => None,
        }
    }

    /// RenderMan's name for the mode.
    pub fn name(self) -> &'static str {
        match self {
            Wrap::Periodic => "periodic",
            Wrap::Clamp => "clamp",
            Wrap::Black => "black",
        }
    }
}

/// Parses an EXR `wrapmodes` attribute, `"s"` or `"s,t"`.
pub(crate) fn parse_wrap_modes(text: &str) -> Option<[Wrap; 2]> {
    let mut parts = text.split(',');
    let s = Wrap::from_name(parts.next()?)?;
    let t = match parts.next() {
        Some(t) => Wrap::from_name(t)?,
        None => s,
    };
    Some([s, t])
}

/// The screen-space derivatives of a lookup's coordinates: how far `(s, t)` moves for one pixel
/// step in x and in y. All zero means a point sample (bilinear on the finest level).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Footprint {
    pub dsdx: f32,
    pub dtdx: f32,
    pub dsdy: f32,
    pub dtdy: f32,
}

impl Footprint {
    /// No extent: a point sample.
    pub const POINT: Footprint = Footprint { dsdx: 0.0, dtdx: 0.0, dsdy: 0.0, dtdy: 0.0 };
}

impl From<[f32; 4]> for Footprint {
    /// `[dsdx, dtdx, dsdy, dtdy]`.
    fn from([dsdx, dtdx, dsdy, dtdy]: [f32; 4]) -> Self {
        Footprint { dsdx, dtdx, dsdy, dtdy }
    }
}

/// The optional parameters of a lookup, named after RenderMan's texture-call parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct LookupOptions {
    /// Wrap mode across s; `None` uses the file's own (or periodic).
    pub swrap: Option<Wrap>,
    /// Wrap mode across t; `None` uses the file's own (or periodic).
    pub twrap: Option<Wrap>,
    /// Multiplies the footprint's extent in s (RenderMan's `swidth`, or `width` for both).
    pub swidth: f32,
    /// Multiplies the footprint's extent in t.
    pub twidth: f32,
    /// Added filter width in s, in texture coordinates (RenderMan's `sblur`, or `blur`).
    pub sblur: f32,
    /// Added filter width in t, in texture coordinates.
    pub tblur: f32,
    /// The value of channels the texture does not have (RenderMan's `fill`).
    pub fill: f32,
    /// Keep 8-bit values as stored instead of decoding sRGB: for data textures. Part of the
    /// cache key, so one file can be used both ways.
    pub raw: bool,
    /// Shadow maps: subtracted from a point's depth before comparing, against self-shadowing.
    pub bias: f32,
    /// Shadow maps: the width of a ramp above `bias` (Aqsis's `bias0` to `bias1`): a point
    /// `bias + bias_ramp` or more behind the stored depth is in shadow, one `bias` or less behind
    /// it lit, and in between in shadow by the fraction of the way; 0 (or less) is a step at
    /// `bias`.
    pub bias_ramp: f32,
    /// Shadow maps: the number of percentage-closer samples (rounded up to a square).
    pub samples: u32,
}

impl Default for LookupOptions {
    fn default() -> Self {
        LookupOptions {
            swrap: None,
            twrap: None,
            swidth: 1.0,
            twidth: 1.0,
            sblur: 0.0,
            tblur: 0.0,
            fill: 0.0,
            raw: false,
            bias: 0.0,
            bias_ramp: 0.0,
            samples: 16,
        }
    }
}

/// sRGB-encoded value in [0, 1] to linear (the exact piecewise curve of IEC 61966-2-1).
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value to sRGB encoding (the inverse of [`srgb_to_linear`]); negative values give 0.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v.is_nan() || v <= 0.0 {
        0.0
    } else if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_round_trips_and_hits_known_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 128/255 is about 21.6% linear.
        assert!((srgb_to_linear(128.0 / 255.0) - 0.2158).abs() < 1e-3);
        for i in 0..=255 {
            let v = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
    }

    #[test]
    fn wrap_names() {
        assert_eq!(Wrap::from_name("Periodic"), Some(Wrap::Periodic));
        assert_eq!(Wrap::from_name("black"), Some(Wrap::Black));
        assert_eq!(Wrap::from_name("mirror"), None);
        assert_eq!(parse_wrap_modes("clamp,black"), Some([Wrap::Clamp, Wrap::Black]));
        assert_eq!(parse_wrap_modes("clamp"), Some([Wrap::Clamp, Wrap::Clamp]));
        assert_eq!(parse_wrap_modes("bogus,clamp"), None);
        for w in [Wrap::Periodic, Wrap::Clamp, Wrap::Black] {
            assert_eq!(Wrap::from_name(w.name()), Some(w));
        }
    }
}

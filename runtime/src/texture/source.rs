//! What a texture cache's source delivers for a name (`cache.rs`): the whole of what it stands
//! for, or, for a texture, the parts a distributed worker fetches a mip level at a time
//! (`remote.rs`); and how those travel.

use std::any::Any;
use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

use super::image::{decode_texture_file, LoadedImage, TexImage};

/// What a name is looked up as: each has a cache of its own, and is decoded its own way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TextureKind {
    /// `texture()` and `environment()`: an image, mip-mapped.
    Texture,
    /// `shadow()`: a depth map with its matrices.
    Shadow,
    /// `texture3d()`: a 3-D grid.
    Grid,
}

/// What a [`TextureSource`] delivers for a name.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Delivered {
    /// A file's bytes, decoded here as the file would be; `path` is what warnings call it.
    File { path: PathBuf, bytes: Vec<u8> },
    /// An image built in memory (`Context::tex_image_2d`): its texels, rows top to bottom. It
    /// repeats (periodic wrap).
    Image { width: u32, height: u32, channels: u32, texels: Vec<f32> },
    /// The same, when every texel value is a multiple of 1/255 (an 8-bit image taken as stored):
    /// each value times 255, a quarter of the bytes.
    Image8 { width: u32, height: u32, channels: u32, values: Vec<u8> },
    /// Nothing: why, and the file when one was found (the warning a cache reading files itself
    /// would give).
    Missing { path: Option<PathBuf>, reason: String },
}

impl Delivered {
    /// An image built in memory, as [`Delivered::Image8`] where that holds every value exactly.
    pub fn image(image: &TexImage) -> Delivered {
        let [width, height, channels] = [image.width(), image.height(), image.channels()].map(|n| n as u32);
        match eight_bit_values(image.data()) {
            Some(values) => Delivered::Image8 { width, height, channels, values },
            None => Delivered::Image { width, height, channels, texels: image.data().to_vec() },
        }
    }
}

/// Where a cache gets what names stand for instead of reading files (see the module doc).
pub trait TextureSource: Send + Sync + fmt::Debug {
    /// `part` of what `name` stands for; blocks until it is here. A source that cannot deliver
    /// says why with [`Delivered::Missing`]. A source may answer a request for a pyramid or a
    /// level with the whole texture.
    fn fetch(&self, part: TexturePart, name: &str) -> TextureAnswer;

    /// Records that something it delivered could not be used (a damaged answer): a distributed
    /// frame then fails. A source that does nothing leaves it to the texture's warning.
    fn failed(&self, _message: String) {}

    /// What a cache made before of `part` of `name` (a texture's map, a shadow map, a grid),
    /// where the source keeps what caches make (a distributed worker keeps what its last scene
    /// made) and has answered [`TextureAnswer::Unchanged`]: the cache takes it rather than
    /// making another. A texture map's further levels come from the source it was made with,
    /// under the same name.
    fn kept(&self, _part: TexturePart, _name: &str) -> Option<Arc<dyn Any + Send + Sync>> {
        None
    }

    /// Offers what a cache made of the source's last answer to `part` of `name`, to keep.
    fn keep(&self, _part: TexturePart, _name: &str, _made: Arc<dyn Any + Send + Sync>) {}

    /// Asks for `part` of `name` without waiting, for a render thread that renders
    /// [`crate::accel::ask_ahead::without_waiting`]: a later [`TextureSource::fetch`] of it takes
    /// the answer. Returns whether the answer is still to come (`false`: fetch it now; a source
    /// that cannot ask ahead always says so).
    fn ask_ahead(&self, _part: TexturePart, _name: &str) -> bool {
        false
    }
}

/// What `delivered` stands for as a texture decoded `raw` or not: its image, with the file's
/// wrap modes and projection; or the path and reason of the warning a cache gives.
pub(crate) fn image_from_delivered(delivered: Delivered, raw: bool) -> Result<LoadedImage, (Option<PathBuf>, String)> {
    let in_memory = |image: Option<TexImage>| {
        let image = image.ok_or((None, "its size and its texels differ".to_string()))?;
        Ok(LoadedImage { image, wrap: None, integer_source: false, projection: None })
    };
    match delivered {
        Delivered::File { path, bytes } => {
            decode_texture_file(&path, &bytes, raw).map_err(|e| (Some(path.clone()), error_chain(&e)))
        }
        Delivered::Image { width, height, channels, texels } => {
            let [w, h, c] = [width, height, channels].map(|n| n as usize);
            in_memory(TexImage::new(w, h, c, texels))
        }
        Delivered::Image8 { width, height, channels, values } => {
            let [w, h, c] = [width, height, channels].map(|n| n as usize);
            in_memory(TexImage::new(w, h, c, values.iter().map(|&v| f32::from(v) / 255.0).collect()))
        }
        Delivered::Missing { path, reason } => Err((path, reason)),
    }
}

/// What a worker asks for of what a name stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TexturePart {
    /// All of it, looked up as this kind: shadow maps and grids.
    Whole(TextureKind),
    /// A texture's pyramid: its description and coarsest levels (or the whole texture, when that
    /// is no larger), its texels decoded `raw` or not.
    Pyramid { raw: bool },
    /// One level of the pyramid (or the whole texture, when that is no larger).
    Level { raw: bool, level: u32 },
    /// One tile of a level of the pyramid that comes in tiles (`level_tiles.rs`), numbered row
    /// after row (or the whole texture, when the master has no such tile).
    Tile { raw: bool, level: u32, tile: u32 },
}

/// The master's answer to a [`TexturePart`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum TextureAnswer {
    /// What the name stands for, whole, as a cache reading it would get it (or why nothing).
    Whole(Delivered),
    /// A texture's pyramid, described.
    Pyramid(PyramidHeader),
    /// One level's values (or one tile's).
    Level(LevelValues),
    /// What the asker holds of the name, by the digest it sent, is what the name stands for
    /// ([`TextureSource::kept`]).
    Unchanged,
}

/// A texture's pyramid as a worker first gets it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PyramidHeader {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    /// The file's wrap modes (s, t), from the `Wrap` names.
    pub wrap: [u8; 2],
    pub projection: Option<[[f32; 16]; 2]>,
    /// No level has an infinite or NaN value.
    pub finite: bool,
    /// The coarsest levels, finest of them first, down to 1x1.
    pub coarsest: Vec<LevelValues>,
    /// The side of the tiles in which the master sends large levels (`level_tiles.rs`); 0 when
    /// it sends whole levels only.
    pub tile_side: u32,
    /// The bytes of the texture as given, encoded (what a request for the image costs): a
    /// worker that has fetched half as many bytes of tiles asks for the image rather than more
    /// tiles.
    pub whole_bytes: u64,
    /// blake3 of the texture as given (its whole answer): a worker that made a map from a
    /// pyramid of this digest under the same name takes it again (a new scene's texture that did
    /// not change keeps the levels the worker fetched).
    pub digest: [u8; 32],
}

/// A level's values, row after row.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum LevelValues {
    Floats(Vec<f32>),
    /// Every value times 255, when each is a multiple of 1/255 that this gives back exactly.
    Bytes(Vec<u8>),
}

impl LevelValues {
    /// The bytes the values take: one a value, or four.
    pub fn bytes(&self) -> usize {
        match self {
            LevelValues::Floats(v) => 4 * v.len(),
            LevelValues::Bytes(v) => v.len(),
        }
    }

    pub fn of(image: &TexImage) -> LevelValues {
        match eight_bit_values(image.data()) {
            Some(bytes) => LevelValues::Bytes(bytes),
            None => LevelValues::Floats(image.data().to_vec()),
        }
    }

    /// The level as an image of `width x height x channels`; `None` when the values are not that
    /// many.
    pub fn into_image(self, width: usize, height: usize, channels: usize) -> Option<TexImage> {
        let values = match self {
            LevelValues::Floats(values) => values,
            LevelValues::Bytes(bytes) => bytes.iter().map(|&b| f32::from(b) / 255.0).collect(),
        };
        TexImage::new(width, height, channels, values)
    }
}

/// Each value times 255 as a byte, when every value is a multiple of 1/255 that dividing the byte
/// by 255 gives back bit for bit.
pub(crate) fn eight_bit_values(values: &[f32]) -> Option<Vec<u8>> {
    let eight_bit = |v: f32| {
        let b = (v * 255.0).round();
        ((0.0..=255.0).contains(&b) && (b / 255.0).to_bits() == v.to_bits()).then_some(b as u8)
    };
    values.iter().map(|&v| eight_bit(v)).collect()
}

/// The most bytes an answer inflates to on a worker: the largest file a worker fetches
/// (`MAX_DELIVERED_FILE_BYTES`, 1 GiB) with room for its path and the encoding's own bytes.
pub const MAX_INFLATED_ANSWER: u64 = (1 << 30) + (1 << 20);

/// How answers travel: postcard, in a payload deflated or plain ([`crate::deflate::pack`]).
/// Deflated, texture files that are not compressed themselves (PPM, TGA, EXR without
/// compression) and the floats of mip levels shrink by a third to nineteen twentieths: bytes a
/// slow link does not carry. The fastest level: the master compresses each answer once, but
/// while a worker waits.
pub fn encode_answer(answer: &TextureAnswer, deflated: bool) -> Vec<u8> {
    // Plain data of vectors and strings: encoding it cannot fail.
    crate::deflate::pack(&[&postcard::to_allocvec(answer).unwrap_or_default()], deflated)
}

/// An answer [`encode_answer`] wrote; an error for anything else, or one that would inflate past
/// [`MAX_INFLATED_ANSWER`].
pub fn decode_answer(bytes: &[u8]) -> Result<TextureAnswer, String> {
    let plain =
        crate::deflate::unpack_at_most(bytes, MAX_INFLATED_ANSWER).map_err(|e| format!("the master's answer {e}"))?;
    postcard::from_bytes(&plain).map_err(|e| format!("the master's answer cannot be decoded: {e}"))
}

/// An error's message followed by its causes', as anyhow's `{:#}` writes them.
pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text = format!("{text}: {c}");
        cause = c.source();
    }
    text
}

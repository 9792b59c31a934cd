//! Textures a distributed worker fetches a mip level at a time (the paper's section 5.4 at a
//! finer grain than the texture).
//!
//! The master decodes a texture and builds its pyramid once ([`TextureServer`]). A worker's
//! first lookup of the name gets a description of the pyramid (sizes, wrap modes, projection)
//! with its coarsest levels, a few kilobytes ([`TextureAnswer::Pyramid`]); each finer level comes
//! the first time a lookup reads it ([`MipMap::level`]): computed from a finer level the worker
//! holds, else fetched. So a surface that is only ever seen far away never pulls the image
//! itself.
//!
//! A level travels as its values (bytes when every value is an 8-bit one exactly, else floats),
//! unless the texture as it was given (the file's bytes, or the image given in memory) is less
//! than twice as large: then that comes instead, and the worker decodes the image from it and
//! computes the levels it needs (the whole gives every level, for little more). So a worker
//! fetches at most about twice the whole texture, even when its lookups ask for the coarse levels
//! first and the fine ones later. Computed or fetched, a level is bit for bit the master's: the
//! same code makes it from the same image.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use rayon::prelude::*;

use super::image::TexImage;
use super::level_tiles::{cut_tile, tile_grid, valid_side, MAX_TILES_A_MAP, TILE_SIDE};
use super::mip::{level_sizes, FetchedLevel, LevelFetch, MipMap, RemotePyramid};
use super::source::{
    encode_answer, image_from_delivered, Delivered, LevelValues, PyramidHeader, TextureAnswer, TextureKind,
    TexturePart, TextureSource,
};
use super::Wrap;

/// At most this many bytes of a texture's coarsest levels travel with its description (the
/// 1x1 level always does).
const COARSEST_BYTES: usize = 16 << 10;

/// Textures whose whole (the texture as given, encoded) is at least this many bytes send their
/// large levels in tiles, unless the master is told otherwise. Tiles trade the bytes a worker
/// fetches for the speed of its lookups: a level held in tiles is read tap by tap, not in the
/// faster ways, so below this a worker fetches the whole once rather than render every frame
/// slower. (A worker handed image tiles from all over the image also reads most of a texture it
/// sees close: the tiles of a small texture cost it more than the whole.)
pub const TILED_FROM_BYTES: usize = 64 << 20;

/// The most bytes of decoded pyramids and encoded answers the master keeps for the workers; past
/// it, the textures asked for least recently are dropped, and decoded again when asked for again.
pub const MAX_SERVED_BYTES: usize = 2 << 30;

/// The most values of a level the master sends as a level (a quarter of a GiB, 1 GiB of floats:
/// MPI counts a message's bytes in 32 bits, and a worker inflates an answer to at most
/// `MAX_INFLATED_ANSWER`); the whole texture comes instead of a larger one.
const MAX_LEVEL_VALUES: usize = 1 << 28;

fn wrap_code(wrap: Wrap) -> u8 {
    match wrap {
        Wrap::Periodic => 0,
        Wrap::Clamp => 1,
        Wrap::Black => 2,
    }
}

fn wrap_of(code: u8) -> Option<Wrap> {
    [Wrap::Periodic, Wrap::Clamp, Wrap::Black].get(usize::from(code)).copied()
}

/// The remote map `header` describes, its levels fetched from `source` as texture `name`
/// (decoded `raw` or not). `None` when the header does not hold.
pub(crate) fn remote_map(
    header: PyramidHeader,
    source: Arc<dyn TextureSource>,
    name: &str,
    raw: bool,
) -> Option<MipMap> {
    let [width, height, channels] = [header.width, header.height, header.channels].map(|n| n as usize);
    let tile_side = header.tile_side as usize;
    if !valid_side(tile_side) {
        return None;
    }
    let sizes = level_sizes(width, height);
    let first = sizes.len().checked_sub(header.coarsest.len())?;
    let coarsest = header
        .coarsest
        .into_iter()
        .zip(&sizes[first..])
        .map(|(values, &[w, h])| values.into_image(w, h, channels))
        .collect::<Option<Vec<TexImage>>>()?;
    let pyramid = RemotePyramid {
        width,
        height,
        channels,
        wrap: [wrap_of(header.wrap[0])?, wrap_of(header.wrap[1])?],
        projection: header.projection,
        finite: header.finite,
        coarsest,
        tile_side,
    };
    let whole_bytes = usize::try_from(header.whole_bytes).unwrap_or(usize::MAX);
    let levels = SourceLevels { source, name: name.to_string(), raw, whole_bytes, tile_bytes: AtomicUsize::new(0) };
    MipMap::remote(pyramid, Arc::new(levels))
}

/// The levels of texture `name` from a cache's source.
struct SourceLevels {
    source: Arc<dyn TextureSource>,
    name: String,
    raw: bool,
    /// What the image costs (the texture as given, encoded), and the bytes of the tiles' values
    /// fetched so far: once those are half as many, the image comes rather than another tile.
    whole_bytes: usize,
    tile_bytes: AtomicUsize,
}

impl SourceLevels {
    /// `part` of the texture, `w x h` texels: its values, or the image (of `size`) when that came.
    fn fetch_part(&self, part: TexturePart, what: &str, [w, h]: [usize; 2], size: [usize; 3]) -> Option<FetchedLevel> {
        let failed = |why: String| {
            self.source.failed(format!("texture \"{}\", {what}: {why}", self.name));
            None
        };
        let channels = size[2];
        match self.source.fetch(part, &self.name) {
            TextureAnswer::Level(values) => {
                let bytes = values.bytes();
                match values.into_image(w, h, channels) {
                    Some(image) => {
                        if matches!(part, TexturePart::Tile { .. }) {
                            self.tile_bytes.fetch_add(bytes, Ordering::Relaxed);
                        }
                        Some(FetchedLevel::Level(image))
                    }
                    None => failed(format!("its values are not {w}x{h}x{channels}")),
                }
            }
            TextureAnswer::Whole(delivered) => match image_from_delivered(delivered, self.raw) {
                Ok(loaded) if [loaded.image.width(), loaded.image.height(), loaded.image.channels()] == size => {
                    Some(FetchedLevel::Image(loaded.image))
                }
                Ok(_) => failed("the image is not the size its pyramid was".into()),
                Err((_, reason)) => failed(reason),
            },
            TextureAnswer::Pyramid(_) => failed("the answer is a pyramid, not a level".into()),
            TextureAnswer::Unchanged => failed("a level was answered as unchanged".into()),
        }
    }
}

impl LevelFetch for SourceLevels {
    fn fetch_level(&self, level: usize, size: [usize; 3]) -> Option<FetchedLevel> {
        let level_size = *level_sizes(size[0], size[1]).get(level)?;
        let part = TexturePart::Level { raw: self.raw, level: u32::try_from(level).ok()? };
        self.fetch_part(part, &format!("mip level {level}"), level_size, size)
    }

    fn fetch_tile(&self, level: usize, tile: usize, tile_size: [usize; 2], size: [usize; 3]) -> Option<FetchedLevel> {
        if self.tile_bytes.load(Ordering::Relaxed) >= self.whole_bytes / 2 {
            // Tiles of half the image's bytes: the image (or level 0, where it is smaller).
            return match self.fetch_level(0, size)? {
                FetchedLevel::Level(image) | FetchedLevel::Image(image) => Some(FetchedLevel::Image(image)),
            };
        }
        let [level, tile] = [level, tile].map(|n| u32::try_from(n).ok());
        let part = TexturePart::Tile { raw: self.raw, level: level?, tile: tile? };
        self.fetch_part(part, &format!("tile {} of mip level {}", tile?, level?), tile_size, size)
    }

    fn failed(&self, message: String) {
        self.source.failed(format!("texture \"{}\", {message}", self.name));
    }

    fn ask_ahead_level(&self, level: usize) -> bool {
        let Ok(level) = u32::try_from(level) else { return false };
        self.source.ask_ahead(TexturePart::Level { raw: self.raw, level }, &self.name)
    }
}

/// The master's side: each texture a worker asked for, decoded and mip-mapped once, and its
/// answers encoded once.
pub struct TextureServer {
    /// The generation of the texture cache the textures below were read under: when the
    /// master's cache is renewed, so are the workers', and what names stand for is read again.
    generation: u64,
    served: HashMap<(String, bool), Served>,
    /// Batches of requests answered: when each texture was last asked for.
    batches: u64,
    /// Textures whose whole takes at least this many bytes send their large levels in tiles.
    tiled_from: usize,
    /// Whether answers travel deflated ([`encode_answer`]).
    deflated: bool,
}

struct Served {
    /// The [`TextureServer`]'s count of batches answered when this texture was last asked for.
    last_used: u64,
    /// The texture as given, encoded as a [`TextureAnswer::Whole`], and its blake3 digest.
    whole: Arc<Vec<u8>>,
    digest: [u8; 32],
    /// Its pyramid, kept while levels may be asked for (`None` when it is no texture, and the
    /// worker decodes the whole and warns as the master would, or when the whole goes instead of
    /// any level).
    map: Option<MipMap>,
    /// The description with the coarsest levels, when less than half the whole.
    pyramid: Option<Arc<Vec<u8>>>,
    /// Each level's answer, encoded when first asked for (`None`: the whole is less than twice as
    /// large).
    levels: Vec<OnceLock<Option<Arc<Vec<u8>>>>>,
    /// Each level's tiles' answers, encoded when first asked for (none for a level not cut).
    tiles: Vec<Box<[EncodedOnce]>>,
    /// Whether its answers travel deflated.
    deflated: bool,
}

/// An answer, encoded the first time it is asked for.
type EncodedOnce = OnceLock<Arc<Vec<u8>>>;

impl std::fmt::Debug for TextureServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TextureServer").field("textures", &self.served.len()).finish_non_exhaustive()
    }
}

impl Default for TextureServer {
    fn default() -> TextureServer {
        TextureServer {
            generation: 0,
            served: HashMap::new(),
            batches: 0,
            tiled_from: TILED_FROM_BYTES,
            deflated: true,
        }
    }
}

impl TextureServer {
    pub fn new() -> TextureServer {
        TextureServer::default()
    }

    /// The server, sending the large levels of textures whose whole takes at least `bytes` in
    /// tiles ([`TILED_FROM_BYTES`] unless told otherwise).
    pub fn with_tiles_from(self, bytes: usize) -> TextureServer {
        TextureServer { tiled_from: bytes, ..self }
    }

    /// The server, its answers deflated (the default) or plain ([`encode_answer`]).
    pub fn with_deflate(self, deflated: bool) -> TextureServer {
        TextureServer { deflated, ..self }
    }

    /// The encoded answers to `requests` (parts of names), in order, where `generation` is the
    /// master's texture cache's and `deliver` gives what a name stands for as a kind
    /// (`Context::deliver_texture`). The textures not served yet are decoded and mip-mapped, and
    /// the answers encoded, on the caller's thread pool: a worker's first frame asks for many at
    /// once, and waits for them. A request that comes with the digest of what the asker holds of
    /// the name is answered [`TextureAnswer::Unchanged`] when the texture (or the shadow map or
    /// grid) is the one of that digest.
    pub fn answer_all(
        &mut self,
        generation: u64,
        requests: &[(TexturePart, String, Option<[u8; 32]>)],
        deliver: impl Fn(TextureKind, &str) -> Delivered + Sync,
    ) -> Vec<Arc<Vec<u8>>> {
        let new = self.undecoded(generation, requests);
        let (tiled_from, deflated) = (self.tiled_from, self.deflated);
        let built: Vec<((String, bool), Served)> = new
            .into_par_iter()
            .map(|(name, raw)| {
                let served = Served::of(deliver(TextureKind::Texture, &name), raw, tiled_from, deflated);
                ((name, raw), served)
            })
            .collect();
        self.served.extend(built);
        self.batches += 1;
        for (part, name, _) in requests {
            if let TexturePart::Pyramid { raw } | TexturePart::Level { raw, .. } | TexturePart::Tile { raw, .. } = *part
            {
                if let Some(served) = self.served.get_mut(&(name.clone(), raw)) {
                    served.last_used = self.batches;
                }
            }
        }
        let served = &self.served;
        let answers = requests
            .par_iter()
            .map(|(part, name, held)| {
                let unchanged = || Arc::new(encode_answer(&TextureAnswer::Unchanged, deflated));
                let raw = match *part {
                    TexturePart::Whole(kind) => {
                        let whole = encode_answer(&TextureAnswer::Whole(deliver(kind, name)), deflated);
                        if held.is_some_and(|d| d == <[u8; 32]>::from(blake3::hash(&whole))) {
                            return unchanged();
                        }
                        return Arc::new(whole);
                    }
                    TexturePart::Pyramid { raw } | TexturePart::Level { raw, .. } | TexturePart::Tile { raw, .. } => {
                        raw
                    }
                };
                // Every texture asked for was served above.
                let Some(served) = served.get(&(name.clone(), raw)) else {
                    return Arc::new(encode_answer(
                        &TextureAnswer::Whole(deliver(TextureKind::Texture, name)),
                        deflated,
                    ));
                };
                match *part {
                    TexturePart::Level { level, .. } => served.level(level as usize),
                    TexturePart::Tile { level, tile, .. } => served.tile(level as usize, tile as usize),
                    // What the asker holds was made of the texture it is now (a whole answer or
                    // a pyramid: both made of this, whose digest a pyramid carries).
                    _ if *held == Some(served.digest) => unchanged(),
                    _ => served.pyramid.clone().unwrap_or_else(|| served.whole.clone()),
                }
            })
            .collect();
        self.evict(MAX_SERVED_BYTES);
        answers
    }

    /// Drops the textures asked for least recently until those held take at most `limit` bytes
    /// (they are decoded again if asked for again).
    fn evict(&mut self, limit: usize) {
        let mut held: Vec<(u64, usize, (String, bool))> =
            self.served.iter().map(|(key, s)| (s.last_used, s.memory_bytes(), key.clone())).collect();
        let mut total: usize = held.iter().map(|h| h.1).sum();
        if total <= limit {
            return;
        }
        held.sort_unstable();
        for (_, bytes, key) in held {
            if total <= limit {
                break;
            }
            self.served.remove(&key);
            total -= bytes;
        }
    }

    /// The textures that `requests` would have decoded before they are answered (name, and
    /// whether raw), each once, where `generation` is the master's texture cache's: those
    /// [`TextureServer::answer_all`] would decode on the caller's thread. A server that must
    /// keep answering other requests meanwhile decodes them elsewhere ([`TextureServer::decoder`])
    /// and adds them ([`TextureServer::add`]) before it answers.
    pub fn undecoded(
        &mut self,
        generation: u64,
        requests: &[(TexturePart, String, Option<[u8; 32]>)],
    ) -> Vec<(String, bool)> {
        if generation != self.generation {
            self.served.clear();
            self.generation = generation;
        }
        let mut keys: Vec<(String, bool)> = requests
            .iter()
            .filter_map(|(part, name, _)| match *part {
                TexturePart::Pyramid { raw } | TexturePart::Level { raw, .. } | TexturePart::Tile { raw, .. } => {
                    Some((name.clone(), raw))
                }
                TexturePart::Whole(_) => None,
            })
            .filter(|key| !self.served.contains_key(key))
            .collect();
        keys.sort_unstable();
        keys.dedup();
        keys
    }

    /// What decodes textures for this server, on any thread, under the texture cache's
    /// `generation`.
    pub fn decoder(&self, generation: u64) -> TextureDecoder {
        TextureDecoder { generation, tiled_from: self.tiled_from, deflated: self.deflated }
    }

    /// How many textures it serves, decoded.
    pub fn len(&self) -> usize {
        self.served.len()
    }

    /// Whether it serves none.
    pub fn is_empty(&self) -> bool {
        self.served.is_empty()
    }

    /// What the textures served take, in bytes.
    pub fn held_bytes(&self) -> usize {
        self.served.values().map(Served::memory_bytes).sum()
    }

    /// Takes a texture decoded elsewhere, unless the texture cache has been renewed since.
    pub fn add(&mut self, decoded: DecodedTexture) {
        if decoded.generation == self.generation {
            self.served.entry(decoded.key).or_insert(decoded.served);
        }
    }

    /// The encoded answer to one request ([`TextureServer::answer_all`]).
    pub fn answer(
        &mut self,
        generation: u64,
        part: TexturePart,
        name: &str,
        deliver: impl Fn(TextureKind, &str) -> Delivered + Sync,
    ) -> Arc<Vec<u8>> {
        let mut answers = self.answer_all(generation, &[(part, name.to_string(), None)], deliver);
        answers.pop().unwrap_or_default()
    }
}

/// Decodes and mip-maps textures for a [`TextureServer`] away from it.
#[derive(Clone, Copy, Debug)]
pub struct TextureDecoder {
    generation: u64,
    tiled_from: usize,
    deflated: bool,
}

/// A texture as a [`TextureDecoder`] made it ready to serve.
pub struct DecodedTexture {
    generation: u64,
    key: (String, bool),
    served: Served,
}

impl DecodedTexture {
    /// The texture's name, and whether it was read raw.
    pub fn key(&self) -> &(String, bool) {
        &self.key
    }
}

impl TextureDecoder {
    /// Texture `name` (raw: read without conversion) ready to serve, from what the name stands
    /// for (`Context::deliver_texture`).
    pub fn decode(&self, name: String, raw: bool, delivered: Delivered) -> DecodedTexture {
        let served = Served::of(delivered, raw, self.tiled_from, self.deflated);
        DecodedTexture { generation: self.generation, key: (name, raw), served }
    }
}

impl Served {
    fn of(delivered: Delivered, raw: bool, tiled_from: usize, deflated: bool) -> Served {
        let map = image_from_delivered(delivered.clone(), raw).ok().map(|loaded| {
            MipMap::with_wrap(loaded.image, loaded.wrap.unwrap_or([Wrap::Periodic; 2]))
                .with_projection(loaded.projection)
        });
        let whole = Arc::new(encode_answer(&TextureAnswer::Whole(delivered), deflated));
        let digest: [u8; 32] = blake3::hash(&whole).into();
        let tile_side = map.as_ref().filter(|_| whole.len() >= tiled_from).map_or(0, tile_side);
        let pyramid = map
            .as_ref()
            .map(|m| describe(m, digest, tile_side, whole.len(), deflated))
            .filter(|p| worth_sending(p, &whole))
            .map(Arc::new);
        let map = map.filter(|_| pyramid.is_some());
        let sizes = map.as_ref().map_or(Vec::new(), |m| level_sizes(m.width(), m.height()));
        let levels = sizes.iter().map(|_| OnceLock::new()).collect();
        let tiles = sizes
            .iter()
            .map(|&s| tile_grid(s, tile_side).map_or(0, |[a, d]| a * d))
            .map(|count| (0..count).map(|_| OnceLock::new()).collect())
            .collect();
        Served { last_used: 0, whole, digest, map, pyramid, levels, tiles, deflated }
    }

    /// What it holds, in bytes.
    fn memory_bytes(&self) -> usize {
        let map = self.map.as_ref().map_or(0, |m| (0..m.level_count()).map(|i| 4 * m.level(i).data().len()).sum());
        let answers = self.levels.iter().filter_map(|l| l.get().cloned().flatten()).map(|a| a.len()).sum::<usize>();
        let tiles = self.tiles.iter().flat_map(|t| t.iter()).filter_map(|t| t.get()).map(|a| a.len()).sum::<usize>();
        map + answers + tiles + self.whole.len() + self.pyramid.as_ref().map_or(0, |p| p.len())
    }

    /// The answer for tile `tile` of level `level`: its values, encoded once; the whole when
    /// there is no such tile.
    fn tile(&self, level: usize, tile: usize) -> Arc<Vec<u8>> {
        let (Some(map), Some(slot)) = (&self.map, self.tiles.get(level).and_then(|t| t.get(tile))) else {
            return self.whole.clone();
        };
        slot.get_or_init(|| match cut_tile(map.level(level), TILE_SIDE, tile) {
            Some(values) => Arc::new(encode_answer(&TextureAnswer::Level(LevelValues::of(&values)), self.deflated)),
            None => self.whole.clone(),
        })
        .clone()
    }

    fn level(&self, level: usize) -> Arc<Vec<u8>> {
        let (Some(map), Some(slot)) = (&self.map, self.levels.get(level)) else { return self.whole.clone() };
        let encoded = slot.get_or_init(|| {
            let image = map.level(level);
            if image.data().len() > MAX_LEVEL_VALUES {
                return None;
            }
            let encoded = encode_answer(&TextureAnswer::Level(LevelValues::of(image)), self.deflated);
            worth_sending(&encoded, &self.whole).then(|| Arc::new(encoded))
        });
        encoded.clone().unwrap_or_else(|| self.whole.clone())
    }
}

/// Whether `part` of a texture is worth sending rather than `whole`, which gives every part.
fn worth_sending(part: &[u8], whole: &[u8]) -> bool {
    2 * part.len() < whole.len()
}

/// The side of the tiles `map`'s large levels go in: [`TILE_SIDE`], unless a worker would set
/// aside more than [`MAX_TILES_A_MAP`] slots for them (0: whole levels only).
fn tile_side(map: &MipMap) -> usize {
    let sizes = level_sizes(map.width(), map.height());
    let tiles: usize = sizes.iter().filter_map(|&s| tile_grid(s, TILE_SIDE)).map(|[a, d]| a * d).sum();
    if tiles <= MAX_TILES_A_MAP {
        TILE_SIDE
    } else {
        0
    }
}

/// `map`'s description with as many of its coarsest levels as fit [`COARSEST_BYTES`], the side
/// of the tiles its large levels go in, and the digest and size of the texture as given, encoded.
fn describe(map: &MipMap, digest: [u8; 32], tile_side: usize, whole_bytes: usize, deflated: bool) -> Vec<u8> {
    let mut coarsest = Vec::new();
    let mut bytes = 0;
    for level in (0..map.level_count()).rev() {
        let values = LevelValues::of(map.level(level));
        bytes += match &values {
            LevelValues::Floats(v) => 4 * v.len(),
            LevelValues::Bytes(v) => v.len(),
        };
        if !coarsest.is_empty() && bytes > COARSEST_BYTES {
            break;
        }
        coarsest.push(values);
    }
    coarsest.reverse();
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    encode_answer(
        &TextureAnswer::Pyramid(PyramidHeader {
            width: count(map.width()),
            height: count(map.height()),
            channels: count(map.channels()),
            wrap: map.wrap().map(wrap_code),
            projection: map.projection(),
            finite: map.is_finite(),
            coarsest,
            tile_side: count(tile_side),
            whole_bytes: whole_bytes as u64,
            digest,
        }),
        deflated,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{decode_answer, Footprint, LookupOptions, TextureCache};
    use glam::Vec4;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Mutex;

    /// A worker's link to its master in one process: a [`TextureServer`] answering every request
    /// through the encoding they travel in, with what was asked and what failed recorded.
    #[derive(Debug)]
    struct Loopback {
        server: Mutex<TextureServer>,
        /// What the texture's name stands for.
        delivered: Delivered,
        asked: Mutex<Vec<TexturePart>>,
        bytes: Mutex<usize>,
        failures: Mutex<Vec<String>>,
        /// Answers levels with one value too few.
        damaged: AtomicBool,
    }

    impl Loopback {
        fn new(delivered: Delivered) -> Arc<Loopback> {
            Arc::new(Loopback {
                // Every texture's large levels in tiles, however small the texture.
                server: Mutex::new(TextureServer::new().with_tiles_from(0)),
                delivered,
                asked: Mutex::default(),
                bytes: Mutex::default(),
                failures: Mutex::default(),
                damaged: AtomicBool::new(false),
            })
        }

        fn asked(&self) -> Vec<TexturePart> {
            self.asked.lock().unwrap().clone()
        }
    }

    impl TextureSource for Loopback {
        fn fetch(&self, part: TexturePart, name: &str) -> TextureAnswer {
            self.asked.lock().unwrap().push(part);
            let bytes = self.server.lock().unwrap().answer(1, part, name, |_, _| self.delivered.clone());
            *self.bytes.lock().unwrap() += bytes.len();
            match decode_answer(&bytes).unwrap() {
                TextureAnswer::Level(LevelValues::Floats(mut v)) if self.damaged.load(Ordering::Relaxed) => {
                    v.pop();
                    TextureAnswer::Level(LevelValues::Floats(v))
                }
                answer => answer,
            }
        }

        fn failed(&self, message: String) {
            self.failures.lock().unwrap().push(message);
        }
    }

    /// Noise: a hash of `i` (SplitMix64's finaliser), which deflating hardly shrinks, so that the
    /// sizes the master weighs are about those of the values.
    fn noise(i: usize) -> u64 {
        let mut z = (i as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A square RGB image of noisy floats no byte holds.
    fn floats(side: usize) -> TexImage {
        let values = (0..side * side * 3).map(|i| (noise(i) >> 40) as f32 / (1u64 << 24) as f32 + 0.25).collect();
        TexImage::new(side, side, 3, values).unwrap()
    }

    /// A footprint `texels` texels of level 0 wide, of a texture `side` texels square.
    fn wide(texels: f32, side: usize) -> Footprint {
        let d = texels / side as f32;
        Footprint { dsdx: d, dtdx: 0.0, dsdy: 0.0, dtdy: d }
    }

    /// Lookups at 64 places over a footprint, through the cache and straight from `reference`,
    /// compared bit for bit.
    fn same_lookups(cache: &TextureCache, reference: &MipMap, raw: bool, footprint: Footprint) {
        let opts = LookupOptions { raw, ..LookupOptions::default() };
        for k in 0..64 {
            let (s, t) = ((k % 8) as f32 / 8.0 + 0.03, (k / 8) as f32 / 8.0 + 0.07);
            let (mut here, mut there) = ([0.0; 3], [0.0; 3]);
            assert!(cache.texture("t", s, t, footprint, 0, &mut here, &opts));
            reference.filter(s, t, footprint, 0, &mut there, &opts);
            assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "({s}, {t}) over {footprint:?}");
        }
    }

    #[test]
    fn a_worker_fetches_only_the_levels_and_tiles_its_lookups_read_and_sees_what_the_whole_gives() {
        let image = floats(256);
        let reference = MipMap::new(image.clone());
        let source = Loopback::new(Delivered::image(&image));
        let cache = TextureCache::new().with_source(Some(source.clone()));
        let map = cache.get_texture("t", false).unwrap();
        // The pyramid came with its coarsest levels, the 32x32 one and those below it.
        assert_eq!(source.asked(), [TexturePart::Pyramid { raw: false }]);
        let held = |from: usize| (0..map.level_count()).map(|i| map.holds_level(i)).skip(from).collect::<Vec<_>>();
        assert_eq!(held(0), [false, false, false, true, true, true, true, true, true]);
        // Level 0 comes in sixteen tiles of 64x64 texels; level 1, four tiles' worth, whole.
        assert_eq!((map.tiles_held(0), map.tiles_held(1)), (Some([0, 16]), None));
        // Far away: read from what came, nothing more fetched.
        same_lookups(&cache, &reference, false, wide(20.0, 256));
        assert_eq!(source.asked().len(), 1);
        // Nearer: the 64x64 level, fetched alone.
        same_lookups(&cache, &reference, false, wide(5.0, 256));
        assert_eq!(source.asked()[1..], [TexturePart::Level { raw: false, level: 2 }]);
        assert_eq!(held(0)[..3], [false, false, true]);
        // Close, in one corner: the one tile of level 0 under it.
        let opts = LookupOptions::default();
        for k in 0..16 {
            let (s, t) = (0.06 + (k % 4) as f32 * 0.04, 0.07 + (k / 4) as f32 * 0.04);
            let (mut here, mut there) = ([0.0; 3], [0.0; 3]);
            assert!(cache.texture("t", s, t, wide(0.7, 256), 0, &mut here, &opts));
            reference.filter(s, t, wide(0.7, 256), 0, &mut there, &opts);
            assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "({s}, {t})");
        }
        assert_eq!(source.asked()[2..], [TexturePart::Tile { raw: false, level: 0, tile: 0 }]);
        assert_eq!(map.tiles_held(0), Some([1, 16]));
        // Close everywhere, and between levels 0 and 1: the tiles that lookups reach, and level
        // 1 fetched whole; or, once the tiles cost as much as the image, the image, from which
        // the rest is made here.
        same_lookups(&cache, &reference, false, wide(0.7, 256));
        same_lookups(&cache, &reference, false, wide(1.5, 256));
        let later = source.asked()[3..].to_vec();
        let tiles = later.iter().filter(|p| matches!(p, TexturePart::Tile { level: 0, .. })).count();
        assert!(tiles > 4, "{later:?}");
        let image_came = later.contains(&TexturePart::Level { raw: false, level: 0 });
        assert!(image_came || later.contains(&TexturePart::Level { raw: false, level: 1 }), "{later:?}");
        // Four lanes at once, as shaders look up, give the same values.
        let lanes = crate::texture::LookupLanes::splat(0.4, 0.6, wide(3.0, 256), [0.0; 2]);
        let (mut here, mut there) = ([0.0; 12], [0.0; 12]);
        map.filter_lanes(&lanes, [true; 4], [0; 4], &mut here, &LookupOptions::default());
        reference.filter_lanes(&lanes, [true; 4], [0; 4], &mut there, &LookupOptions::default());
        assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits));
        assert!(source.failures.lock().unwrap().is_empty());
        // At most about twice the whole texture travelled, whatever the order of the lookups.
        let whole = encode_answer(&TextureAnswer::Whole(Delivered::image(&image)), true).len();
        assert!(*source.bytes.lock().unwrap() < 2 * whole + whole / 4, "{} of {whole}", source.bytes.lock().unwrap());
    }

    /// Noise over a `w x h` image of `channels`, as floats.
    /// Numbers in [0, 1) from `seed`, a xorshift generator's.
    fn uniform_numbers(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn noisy(w: usize, h: usize, channels: usize) -> TexImage {
        let values = (0..w * h * channels).map(|i| (noise(i + 7) >> 40) as f32 / (1u64 << 24) as f32).collect();
        TexImage::new(w, h, channels, values).unwrap()
    }

    /// A worker's map of `image`, its large levels served in tiles through a loopback source (kept
    /// to ask what was fetched), and the map built from the whole image.
    fn served_in_tiles(image: &TexImage) -> (Arc<MipMap>, MipMap, Arc<Loopback>) {
        let source = Loopback::new(Delivered::image(image));
        let cache = TextureCache::new().with_source(Some(source.clone()));
        let map = cache.get_texture("t", false).expect("the loopback serves the texture");
        (map, MipMap::new(image.clone()), source)
    }

    /// Lookups of every kind on a map whose levels come in tiles, in lanes of different
    /// footprints, over the edges of an image no power of two wide, in every wrap mode: the
    /// values of the map built from the whole image, bit for bit.
    #[test]
    fn textures_decoded_elsewhere_are_served_without_decoding_again() {
        let image = floats(64);
        let delivered = Delivered::image(&image);
        let mut server = TextureServer::new();
        let pyramid = |name: &str| (TexturePart::Pyramid { raw: false }, name.to_string(), None);
        let whole = (TexturePart::Whole(TextureKind::Texture), "w".to_string(), None);
        let requests = [pyramid("t"), pyramid("t"), whole.clone(), pyramid("u")];
        // A whole texture needs no decoding; each other texture is named once.
        assert_eq!(server.undecoded(7, &requests), [("t".into(), false), ("u".into(), false)]);
        // Decoded under another generation of the texture cache: not taken.
        server.add(server.decoder(6).decode("t".into(), false, delivered.clone()));
        assert_eq!(server.undecoded(7, &requests[..1]).len(), 1);
        let decoded = server.decoder(7).decode("t".into(), false, delivered.clone());
        assert_eq!(decoded.key(), &("t".to_string(), false));
        server.add(decoded);
        assert_eq!(server.undecoded(7, &[pyramid("t"), whole.clone()]), []);
        // Answered without asking what the name stands for again, as it would have been answered
        // had the server decoded it itself.
        let asked = AtomicUsize::new(0);
        let deliver = |_, _: &str| {
            asked.fetch_add(1, Ordering::Relaxed);
            delivered.clone()
        };
        let answers = server.answer_all(7, &[pyramid("t")], deliver);
        assert_eq!(asked.load(Ordering::Relaxed), 0);
        let mut fresh = TextureServer::new();
        assert_eq!(answers, fresh.answer_all(7, &[pyramid("t")], |_, _| delivered.clone()));
        // A new generation starts from nothing.
        assert_eq!(server.undecoded(8, &[pyramid("t")]).len(), 1);
    }

    #[test]
    fn lookups_read_through_tiles_as_through_whole_levels() {
        let image = noisy(300, 170, 3);
        for wrap in [[Wrap::Periodic; 2], [Wrap::Clamp, Wrap::Black], [Wrap::Black, Wrap::Periodic]] {
            let reference = MipMap::new(image.clone());
            let source = Loopback::new(Delivered::image(&image));
            let cache = TextureCache::new().with_source(Some(source.clone()));
            let map = cache.get_texture("t", false).unwrap();
            assert_eq!(map.tiles_held(0), Some([0, 15]));
            let opts = LookupOptions { swrap: Some(wrap[0]), twrap: Some(wrap[1]), ..LookupOptions::default() };
            let mut next = uniform_numbers(0x2545_f491_4f6c_dd1du64);
            for round in 0..200 {
                let texels = [0.2, 0.8, 1.3, 2.2, 4.0][round % 5];
                let mut lanes = crate::texture::LookupLanes::splat(0.0, 0.0, wide(texels, 300), [0.0; 2]);
                lanes.s = Vec4::from_array(std::array::from_fn(|_| next() * 1.4 - 0.2));
                lanes.t = Vec4::from_array(std::array::from_fn(|_| next() * 1.4 - 0.2));
                // Lanes of other footprints, eccentric ones among them.
                lanes.dsdx *= Vec4::new(1.0, 0.5, 3.0, 1.0);
                lanes.dtdx = Vec4::new(0.0, 0.002, 0.0, 0.01);
                let active = [true, round % 3 != 0, true, round % 4 != 1];
                let (mut here, mut there) = ([0.0; 12], [0.0; 12]);
                map.filter_lanes(&lanes, active, [0, 1, 0, 2], &mut here, &opts);
                reference.filter_lanes(&lanes, active, [0, 1, 0, 2], &mut there, &opts);
                assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "round {round}");
                let (s, t) = (lanes.s.x, lanes.t.x);
                let footprint = wide(texels, 300);
                let (mut here, mut there) = ([0.0; 2], [0.0; 2]);
                assert!(cache.texture("t", s, t, footprint, 1, &mut here, &opts));
                reference.filter(s, t, footprint, 1, &mut there, &opts);
                assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "({s}, {t}) round {round}");
            }
            assert!(source.failures.lock().unwrap().is_empty());
            assert!(source.asked().iter().any(|p| matches!(p, TexturePart::Tile { .. })));
        }
    }

    /// Four-lane lookups whose probes all read one tile that is here take the four-lane way
    /// through it (in an image a power of two in size and in one that is not, lanes of different
    /// numbers of probes, coordinates a period away): the values of the map built from the
    /// whole image, bit for bit, as those that go tap by tap (over a tile's edge, or the first
    /// time a tile is read).
    #[test]
    fn lookups_within_tiles_here_read_them_four_lanes_at_once() {
        use crate::texture::mip::LANES_THROUGH_TILES;
        for (w, h) in [(512, 256), (300, 170)] {
            let (map, reference, source) = served_in_tiles(&noisy(w, h, 3));
            let opts = LookupOptions::default();
            let mut next = uniform_numbers(0x9e37_79b9_7f4a_7c15u64);
            // A few tiles' worth of places (so that the tiles never cost what the image does),
            // some a period away.
            let lookups: Vec<_> = (0..300)
                .map(|round| {
                    let texels = [0.3, 0.9, 1.6, 2.5][round % 4];
                    let mut lanes = crate::texture::LookupLanes::splat(0.0, 0.0, wide(texels, w), [0.0; 2]);
                    let period = Vec4::new(0.0, 1.0, -2.0, 0.0);
                    lanes.s = Vec4::from_array(std::array::from_fn(|_| 0.3 + 0.1 * next())) + period;
                    lanes.t = Vec4::from_array(std::array::from_fn(|_| 0.25 + 0.2 * next())) - period;
                    lanes.dsdx *= Vec4::new(1.0, 4.0, 2.5, 1.0);
                    lanes.dtdx = Vec4::new(0.0, 0.001, 0.0, 0.004);
                    (lanes, [true, round % 3 != 0, true, round % 5 != 1])
                })
                .collect();
            for pass in 0..std::env::var("PASSES").map_or(2, |p| p.parse().unwrap()) {
                let before = LANES_THROUGH_TILES.with(|c| c.get());
                for (round, (lanes, active)) in lookups.iter().enumerate() {
                    let (mut here, mut there) = ([0.0; 12], [0.0; 12]);
                    map.filter_lanes(lanes, *active, [0, 1, 0, 2], &mut here, &opts);
                    reference.filter_lanes(lanes, *active, [0, 1, 0, 2], &mut there, &opts);
                    assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "{w}x{h}, pass {pass}, round {round}");
                }
                let through = LANES_THROUGH_TILES.with(|c| c.get()) - before;
                if pass == 1 {
                    assert!(through > lookups.len(), "{w}x{h}: {through} lanes read through tiles");
                }
            }
            assert!(!map.holds_level(0), "{w}x{h}: tiles of level 0 only");
            assert!(source.failures.lock().unwrap().is_empty());
        }
    }

    /// Lookups whose texels straddle the edges between tiles (two columns, two rows, or both)
    /// read the one tile that holds their first texel, through its apron, four lanes at once:
    /// bilinear probes, and slanted footprints whose probes run a few texels across an edge. The
    /// values of the map built from the whole image, bit for bit.
    #[test]
    fn lookups_across_tiles_edges_read_one_tile_through_its_apron() {
        use crate::texture::mip::LANES_THROUGH_TILES;
        let (w, h) = (512, 256);
        let (map, reference, source) = served_in_tiles(&noisy(w, h, 3));
        let opts = LookupOptions::default();
        // Texel `i`'s centre is at `i + 0.5`: about `64 k`, a lookup's taps are texels `64 k - 1`
        // and `64 k`, in two tiles. A footprint of a third of a texel reads level 0.
        // A footprint three texels long along s and a third of one along t is slanted: its
        // probes run along s, from about a texel and a half before its centre to as far after.
        let slanted = Footprint { dsdx: 3.0 / w as f32, dtdx: 0.0, dsdy: 0.0, dtdy: 0.3 / h as f32 };
        let places = [(64.0, 100.3), (70.4, 128.0), (128.1, 192.2), (447.9, 63.8)];
        let lookups = [wide(0.3, w), slanted].into_iter().flat_map(|f| places.map(|p| (f, p)));
        for pass in 0..2 {
            let before = LANES_THROUGH_TILES.with(|c| c.get());
            for (k, (footprint, (x, y))) in lookups.clone().enumerate() {
                let mut lanes = crate::texture::LookupLanes::splat(0.0, 0.0, footprint, [0.0; 2]);
                lanes.s = Vec4::from_array(std::array::from_fn(|l| (x + 0.05 * l as f32) / w as f32));
                lanes.t = Vec4::from_array(std::array::from_fn(|l| (y - 0.05 * l as f32) / h as f32));
                let (mut here, mut there) = ([0.0; 12], [0.0; 12]);
                map.filter_lanes(&lanes, [true; 4], [0; 4], &mut here, &opts);
                reference.filter_lanes(&lanes, [true; 4], [0; 4], &mut there, &opts);
                assert_eq!(here.map(f32::to_bits), there.map(f32::to_bits), "pass {pass}, place {k}");
            }
            let through = LANES_THROUGH_TILES.with(|c| c.get()) - before;
            if pass == 1 {
                assert_eq!(through, 4 * 2 * places.len(), "lanes read through tiles once the tiles are here");
            }
        }
        assert!(!map.holds_level(0), "tiles of level 0 only");
        assert!(source.failures.lock().unwrap().is_empty());
    }

    /// Once a worker has fetched as many bytes of tiles as the texture costs whole, the next tile
    /// it lacks brings the image, and every level is made from it.
    #[test]
    fn tiles_give_way_to_the_image_once_they_cost_as_much() {
        // A smooth image, which deflates to a few kilobytes: less than one tile's values.
        let values = (0..512 * 512 * 3).map(|i| ((i / 3 % 512) / 16) as f32 / 64.0 + 0.001).collect();
        let image = TexImage::new(512, 512, 3, values).unwrap();
        let reference = MipMap::new(image.clone());
        let source = Loopback::new(Delivered::image(&image));
        let cache = TextureCache::new().with_source(Some(source.clone()));
        let map = cache.get_texture("t", false).unwrap();
        assert_eq!(map.tiles_held(0), Some([0, 64]));
        same_lookups(&cache, &reference, false, wide(0.5, 512));
        let asked = source.asked();
        assert!(matches!(asked[1], TexturePart::Tile { level: 0, .. }), "{asked:?}");
        assert_eq!(asked[2..], [TexturePart::Level { raw: false, level: 0 }]);
        assert!(map.holds_level(0));
        same_lookups(&cache, &reference, false, wide(1.5, 512));
        same_lookups(&cache, &reference, false, wide(3.0, 512));
        assert_eq!(source.asked().len(), 3, "levels 1 and 2 made here");
        assert!(source.failures.lock().unwrap().is_empty());
    }

    /// An 8-bit file (a PPM) comes whole wherever a level would be more than half as large, and
    /// is decoded here as the master decoded it, raw or as sRGB.
    #[test]
    fn a_level_about_as_large_as_the_file_comes_as_the_file() {
        let side = 256;
        let mut ppm = format!("P6\n{side} {side}\n255\n").into_bytes();
        ppm.extend((0..side * side * 3).map(|i| noise(i) as u8));
        let delivered = Delivered::File { path: "wood.ppm".into(), bytes: ppm };
        for raw in [false, true] {
            let source = Loopback::new(delivered.clone());
            let cache = TextureCache::new().with_source(Some(source.clone()));
            let loaded = image_from_delivered(delivered.clone(), raw).unwrap();
            let reference = MipMap::new(loaded.image);
            // Level 2 is a sixteenth of the file's texels: as floats, a quarter of its bytes.
            same_lookups(&cache, &reference, raw, wide(4.5, side));
            assert_eq!(source.asked()[1..], [TexturePart::Level { raw, level: 2 }]);
            // Level 1 as floats is as large as the file: the file comes, and gives level 0.
            same_lookups(&cache, &reference, raw, wide(2.5, side));
            same_lookups(&cache, &reference, raw, wide(0.5, side));
            assert_eq!(source.asked()[2..], [TexturePart::Level { raw, level: 1 }], "raw {raw}");
            let map = cache.get_texture("t", raw).unwrap();
            assert!(map.holds_level(0));
            assert!(source.failures.lock().unwrap().is_empty());
        }
    }

    /// A level or a tile that comes damaged fails the frame, reads as zeros, and is fetched
    /// again when next read.
    #[test]
    fn a_damaged_level_or_tile_fails_the_frame_and_is_fetched_again_when_next_read() {
        let cases = [
            (128, 0.5, 2.0, TexturePart::Level { raw: false, level: 1 }, "mip level 1"),
            (256, 0.1, 0.5, TexturePart::Tile { raw: false, level: 0, tile: 0 }, "tile 0 of mip level 0"),
        ];
        for (side, at, texels, part, named) in cases {
            let image = floats(side);
            let reference = MipMap::new(image.clone());
            let source = Loopback::new(Delivered::image(&image));
            let cache = TextureCache::new().with_source(Some(source.clone()));
            source.damaged.store(true, Ordering::Relaxed);
            let (mut here, mut there) = ([0.0; 3], [0.0; 3]);
            let opts = LookupOptions::default();
            assert!(cache.texture("t", at, at, wide(texels, side), 0, &mut here, &opts));
            reference.filter(at, at, wide(texels, side), 0, &mut there, &opts);
            assert_ne!(here, there, "zeros stand in for the {named}");
            // A level is asked for once a lookup; a tile by each tap that reads it.
            let failures = source.failures.lock().unwrap().clone();
            assert!((1..=4).contains(&failures.len()), "{failures:?}");
            assert!(failures.iter().all(|f| f.contains(named)), "{failures:?}");
            source.damaged.store(false, Ordering::Relaxed);
            same_lookups(&cache, &reference, false, wide(texels, side));
            assert_eq!(source.asked()[1..=failures.len() + 1], vec![part; failures.len() + 1]);
        }
    }

    #[test]
    fn a_pyramid_that_does_not_hold_is_refused() {
        let image = floats(64);
        let source = Loopback::new(Delivered::image(&image));
        let good = match decode_answer(&encode_answer(
            &TextureAnswer::Pyramid(PyramidHeader {
                width: 64,
                height: 64,
                channels: 3,
                wrap: [0, 1],
                projection: None,
                finite: true,
                coarsest: vec![LevelValues::Floats(vec![0.5; 3])],
                tile_side: 64,
                whole_bytes: 1000,
                digest: [0; 32],
            }),
            true,
        ))
        .unwrap()
        {
            TextureAnswer::Pyramid(p) => p,
            _ => unreachable!(),
        };
        let map = remote_map(good.clone(), source.clone(), "t", false).unwrap();
        assert_eq!((map.width(), map.level_count(), map.wrap()), (64, 7, [Wrap::Periodic, Wrap::Clamp]));
        let damaged = [
            PyramidHeader { width: 0, ..good.clone() },
            PyramidHeader { channels: 0, ..good.clone() },
            PyramidHeader { width: u32::MAX, height: u32::MAX, channels: u32::MAX, ..good.clone() },
            PyramidHeader { wrap: [0, 3], ..good.clone() },
            PyramidHeader { coarsest: vec![LevelValues::Floats(vec![0.5; 4])], ..good.clone() },
            PyramidHeader { coarsest: vec![LevelValues::Bytes(vec![1; 3]); 8], ..good.clone() },
            // No 1x1 level, which every description carries: its channel count, which nothing
            // bounds then, would size the stand-in texel.
            PyramidHeader { channels: u32::MAX, coarsest: vec![], ..good.clone() },
            PyramidHeader { coarsest: vec![], ..good.clone() },
            PyramidHeader { tile_side: 100, ..good.clone() },
            PyramidHeader { tile_side: 8, ..good.clone() },
        ];
        for header in damaged {
            assert!(remote_map(header.clone(), source.clone(), "t", false).is_none(), "{header:?}");
        }
    }

    #[test]
    fn damaged_answers_are_errors() {
        let answer = encode_answer(&TextureAnswer::Level(LevelValues::of(&floats(16))), true);
        assert!(decode_answer(&answer).is_ok());
        for damaged in [&b"not deflated"[..], &answer[..answer.len() / 2], &[]] {
            assert!(decode_answer(damaged).is_err());
        }
    }

    /// A source answering every request for a pyramid and every request for a level with bytes
    /// given, as a worker would get them from a master that sent them.
    #[derive(Debug)]
    struct Scripted {
        pyramid: Vec<u8>,
        level: Vec<u8>,
        tile: Vec<u8>,
    }

    impl TextureSource for Scripted {
        fn fetch(&self, part: TexturePart, _name: &str) -> TextureAnswer {
            let bytes = match part {
                TexturePart::Level { .. } => &self.level,
                TexturePart::Tile { .. } => &self.tile,
                _ => &self.pyramid,
            };
            decode_answer(bytes)
                .unwrap_or_else(|reason| TextureAnswer::Whole(Delivered::Missing { path: None, reason }))
        }
    }

    /// Pyramids, levels and tiles damaged before they were deflated (so that they inflate, and
    /// most decode) are refused, or give a map whose lookups answer without panicking, at every
    /// level.
    #[test]
    fn damaged_pyramids_and_levels_never_panic_a_lookup() {
        // Level 0 comes in nine tiles, the last ones narrower.
        let image = floats(160);
        let plain = |answer: &TextureAnswer| postcard::to_allocvec(answer).unwrap();
        let deflate = |bytes: &[u8]| crate::deflate::pack(&[bytes], true);
        let map = MipMap::new(image.clone());
        let pyramid = decode_answer(&describe(&map, [0; 32], TILE_SIDE, 1 << 20, true)).unwrap();
        let level = TextureAnswer::Level(LevelValues::of(map.level(1)));
        let tile = TextureAnswer::Level(LevelValues::of(&cut_tile(map.level(0), TILE_SIDE, 0).unwrap()));
        let (pyramid, level, tile) = (plain(&pyramid), plain(&level), plain(&tile));
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut maps = 0;
        for round in 0..300 {
            let (mut p, mut l, mut k) = (pyramid.clone(), level.clone(), tile.clone());
            for bytes in [&mut p, &mut l, &mut k] {
                for _ in 0..1 + next() % 3 {
                    let at = (next() % bytes.len() as u64) as usize;
                    bytes[at] ^= 1 << (next() % 8);
                }
                if round % 7 == 0 {
                    let cut = (next() % bytes.len() as u64) as usize;
                    bytes.truncate(cut);
                }
            }
            let source = Arc::new(Scripted { pyramid: deflate(&p), level: deflate(&l), tile: deflate(&k) });
            let cache = TextureCache::new().with_source(Some(source));
            let Some(map) = cache.get_texture("t", false) else { continue };
            maps += 1;
            let mut out = [0.0; 4];
            for texels in [0.3, 1.0, 3.0, 9.0, 40.0] {
                cache.texture("t", 0.3, 0.7, wide(texels, 160), 0, &mut out, &LookupOptions::default());
                cache.texture("t", 0.1, 0.1, wide(texels, 160), 0, &mut out, &LookupOptions::default());
                let lanes = crate::texture::LookupLanes::splat(0.6, 0.2, wide(texels, 160), [0.0; 2]);
                let mut four = [0.0; 16];
                map.filter_lanes(&lanes, [true, false, true, true], [0, 1, 2, 0], &mut four, &LookupOptions::default());
            }
        }
        assert!(maps > 10, "{maps} of 300 damaged pyramids made a map");
    }

    /// Only textures whose whole takes at least the server's threshold send levels in tiles;
    /// every pyramid says what its whole costs.
    #[test]
    fn textures_below_the_threshold_send_whole_levels() {
        let image = floats(256);
        let whole = encode_answer(&TextureAnswer::Whole(Delivered::image(&image)), true);
        assert!(whole.len() < TILED_FROM_BYTES);
        for (server, side) in [(TextureServer::new(), 0), (TextureServer::new().with_tiles_from(whole.len()), 64)] {
            let mut server = server;
            let answer = server.answer(1, TexturePart::Pyramid { raw: false }, "t", |_, _| Delivered::image(&image));
            let Ok(TextureAnswer::Pyramid(header)) = decode_answer(&answer) else { panic!("a pyramid") };
            assert_eq!((header.tile_side, header.whole_bytes), (side, whole.len() as u64));
            let tile = server
                .answer(1, TexturePart::Tile { raw: false, level: 0, tile: 5 }, "t", |_, _| Delivered::image(&image));
            let cut = cut_tile(&image, TILE_SIDE, 5).unwrap();
            let expected = encode_answer(&TextureAnswer::Level(LevelValues::of(&cut)), true);
            assert_eq!(*tile == expected, side != 0, "a tile where tiles are sent, else the whole");
        }
    }

    /// What names stand for is read again when the master's cache is renewed, and only then.
    #[test]
    fn the_server_reads_a_texture_once_per_generation() {
        let image = floats(64);
        let mut server = TextureServer::new();
        let reads = std::sync::atomic::AtomicUsize::new(0);
        let deliver = |_, _: &str| {
            reads.fetch_add(1, Ordering::Relaxed);
            Delivered::image(&image)
        };
        let pyramid = TexturePart::Pyramid { raw: false };
        for (generation, part) in [(1, pyramid), (1, TexturePart::Level { raw: false, level: 0 }), (1, pyramid)] {
            server.answer(generation, part, "t", deliver);
        }
        assert_eq!(reads.load(Ordering::Relaxed), 1);
        server.answer(2, pyramid, "t", deliver);
        server.answer(2, TexturePart::Pyramid { raw: true }, "t", deliver);
        assert_eq!(reads.load(Ordering::Relaxed), 3, "a new generation, and the raw pyramid");
        // Several at once: each texture read once, the answers in the order asked.
        let parts = [
            (TexturePart::Level { raw: false, level: 1 }, "u".to_string(), None),
            (pyramid, "u".to_string(), None),
            (TexturePart::Level { raw: false, level: 2 }, "t".to_string(), None),
        ];
        let answers = server.answer_all(2, &parts, deliver);
        assert_eq!(reads.load(Ordering::Relaxed), 4);
        for ((part, name, _), answer) in parts.iter().zip(&answers) {
            assert_eq!(answer, &server.answer(2, *part, name, deliver), "{part:?} {name}");
        }
        // Asked with the digest of the texture the asker made its map of: unchanged; with another
        // digest, the pyramid again. A level is never answered as unchanged.
        let Ok(TextureAnswer::Pyramid(header)) = decode_answer(&answers[1]) else { panic!("a pyramid") };
        let held = [
            (pyramid, "u".to_string(), Some(header.digest)),
            (pyramid, "u".to_string(), Some([0; 32])),
            (TexturePart::Level { raw: false, level: 1 }, "u".to_string(), Some(header.digest)),
        ];
        let again = server.answer_all(2, &held, deliver);
        assert_eq!(decode_answer(&again[0]), Ok(TextureAnswer::Unchanged));
        assert_eq!(again[1], answers[1]);
        assert_eq!(again[2], answers[0]);
        // A level past the last, or of a name that is no texture, is the whole; so is a tile of
        // a level not cut into tiles, or past the last.
        let whole = encode_answer(&TextureAnswer::Whole(Delivered::image(&image)), true);
        assert_eq!(*server.answer(2, TexturePart::Level { raw: false, level: 99 }, "t", deliver), whole);
        assert_eq!(*server.answer(2, TexturePart::Tile { raw: false, level: 0, tile: 0 }, "t", deliver), whole);
        // Past the limit, the least recently asked for go first.
        server.evict(1);
        assert!(server.served.is_empty());
        server.answer(2, pyramid, "t", deliver);
        assert_eq!(reads.load(Ordering::Relaxed), 5, "read again after it went");
        let missing = |_, _: &str| Delivered::Missing { path: None, reason: "file not found".into() };
        let answer = server.answer(2, TexturePart::Level { raw: false, level: 0 }, "gone", missing);
        assert!(matches!(decode_answer(&answer), Ok(TextureAnswer::Whole(Delivered::Missing { .. }))));
    }
}

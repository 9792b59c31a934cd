//! The messages between the master and its workers, and their encoding: a tag byte, then each
//! field little-endian (integers fixed-size, byte strings and lists length-prefixed). Decoding
//! checks every length against the bytes at hand, so a damaged message is an error, never a
//! panic or an allocation larger than the message.

use crate::render::progressive::PixelLattice;
use crate::texture::{TextureKind, TexturePart};
use rtsl_compiler::interface::ShaderKind;

/// The protocol's version: ranks that speak different versions refuse each other at start-up.
pub const PROTOCOL_VERSION: u32 = 43;

/// What the master's counters add up from a worker's share of a frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameCounts {
    /// Primary, shadow, secondary and transparency rays.
    pub rays: [u64; 4],
    pub shaded_points: u64,
    pub light_evaluations: u64,
    /// Rays cut by their ray trees' budget, and lights left out past `MAX_LIGHTS`.
    pub rays_cut: u64,
    pub lights_dropped: u64,
    /// Thread time spent shading, and of it the time in each type of shader
    /// ([`ShaderKind::ALL`] order), in nanoseconds.
    pub shading_ns: u64,
    pub kind_ns: Vec<u64>,
    /// Global illumination: tracing light paths, and gathering virtual lights (nanoseconds).
    pub light_paths_ns: u64,
    pub gathering_ns: u64,
    /// Per shader: name, type (its index in [`ShaderKind::ALL`]) and nanoseconds.
    pub by_shader: Vec<(String, u8, u64)>,
    /// What the shaders' runtime checks reported.
    pub shader_messages: Vec<String>,
    /// Textures the worker could not load: name, file (empty when none was found) and why.
    pub texture_warnings: Vec<(String, String, String)>,
    /// Demand loading: objects fetched from the master this frame and their bytes, textures
    /// (shadow maps and grids included), the mip levels and tiles of levels fetched after a
    /// texture's first answer, and the bytes of all, objects evicted from the cache before the
    /// frame, objects held after it, and objects rays reached in the frame (held before it or
    /// fetched by it: the fetched ones are the cache's misses); and the objects of a new scene
    /// that took the meshes the last scene had fetched (not fetched again), and the textures that
    /// took the maps the last scene made (their levels not fetched again).
    pub fetched_objects: u64,
    pub fetched_bytes: u64,
    /// Parts of large objects' BVHs fetched when rays first reached them, and their bytes;
    /// parts held after the frame.
    pub fetched_parts: u64,
    pub fetched_part_bytes: u64,
    pub resident_parts: u64,
    /// Parts evicted before the frame.
    pub evicted_parts: u64,
    pub fetched_textures: u64,
    pub fetched_texture_levels: u64,
    pub fetched_texture_tiles: u64,
    pub fetched_texture_bytes: u64,
    pub evicted_objects: u64,
    pub resident_objects: u64,
    pub reached_objects: u64,
    pub kept_objects: u64,
    pub kept_textures: u64,
    /// Where the worker's time went (nanoseconds): bringing its world to the frame's state
    /// (updates, BVHs), the time from then until it reported the frame done, and of that, its
    /// render threads' time spent rendering units (summed over threads).
    pub world_ns: u64,
    pub share_ns: u64,
    pub rendering_ns: u64,
    /// Of `rendering_ns`, the render threads' CPU time (0 where the system does not tell): the
    /// rest is time they waited (for fetches) or were ready to run but off their cores.
    pub rendering_cpu_ns: u64,
    /// Of `rendering_ns`, the render threads' time waiting for fetched meshes and textures, and
    /// decoding fetched meshes and building their BVHs.
    pub fetch_wait_ns: u64,
    pub fetch_build_ns: u64,
    /// Units its render threads set aside to render again, having asked ahead for what they
    /// reached ([`crate::accel::ask_ahead`]).
    pub set_aside: u64,
}

/// What a frame's units of work are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    /// The image's tiles ([`crate::render::TileRenderer::tiles`]), each unit a tile's index; a tile
    /// comes back as [`crate::render::RenderedTile::encode`] writes it.
    Tiles,
    /// Lattices of pixels ([`crate::render::progressive`]), as a viewer traces them: pass `pass`'s
    /// sub-pixel offsets, previews or not. Each unit comes with its lattice and lanes
    /// ([`LatticeUnit`]) and comes back as [`crate::render::progressive::LatticeSamples::encode`]
    /// writes it.
    Lattices { pass: u32, preview: bool },
}

/// A lattice handed out: the pixels, and the lanes of them to trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeUnit {
    pub lattice: PixelLattice,
    pub lanes: u64,
}

/// A message of the protocol.
#[derive(Clone, Debug, PartialEq)]
// A message is held one at a time, between its bytes and what they stand for: a frame's counts
// kept inline cost nothing, boxed they would cost an allocation.
#[allow(clippy::large_enum_variant)]
pub enum Message {
    /// Worker to master, once, first: who it is and whether its scene loaded.
    Hello {
        protocol: u32,
        /// [`build_fingerprint`] of the worker's program.
        build: Vec<u8>,
        threads: u32,
        /// Why the worker cannot render, if it cannot.
        failure: Option<String>,
    },
    /// Master to worker: render frame `frame` (its `job`), after applying `update` to the scene;
    /// these units first (for lattices, each with its [`LatticeUnit`]: `lattices` is as long as
    /// `units`; for tiles it is empty). `last`: no more will come.
    Frame {
        frame: u64,
        update: Vec<u8>,
        /// The frame's light paths as the master traced them (`LightPaths::encode`); empty when
        /// the frame has none or the worker keeps them from the frame before.
        light_paths: Vec<u8>,
        job: Job,
        units: Vec<u32>,
        lattices: Vec<LatticeUnit>,
        last: bool,
    },
    /// Master to worker: more units of the frame, as in `Frame`; `last`: no more will come.
    /// `dropped`: units it was given that another worker has delivered, to leave out if it has not
    /// started them (the master hands a worker with nothing left to do copies of units others
    /// hold, and takes whichever copy comes first).
    Assign { frame: u64, units: Vec<u32>, lattices: Vec<LatticeUnit>, last: bool, dropped: Vec<u32> },
    /// Worker to master: finished units, each its index, the microseconds its thread took over it,
    /// and its pixels (see [`Job`]): all that were ready when the worker sent, so that a master
    /// slow to answer gets fewer, larger messages. `starved`: the worker ran out of units while
    /// waiting for more since its last message.
    Rendered { frame: u64, units: Vec<(u32, u32, Vec<u8>)>, starved: bool },
    /// Worker to master: the worker has sent every unit it was given, or could not render the
    /// frame (`failure`).
    FrameDone { frame: u64, counts: FrameCounts, failure: Option<String> },
    /// Master to worker: stop.
    Quit,
    /// Worker to master: send the meshes of these objects, these parts of objects' BVHs (object,
    /// part) and what these texture names stand for (demand loading), for frame `frame`; with a
    /// texture, the digest of what the worker holds of it from before, if anything (see
    /// `FetchLink::held_digest`).
    Fetch {
        frame: u64,
        objects: Vec<u32>,
        parts: Vec<(u32, u32)>,
        textures: Vec<(TexturePart, String, Option<[u8; 32]>)>,
    },
    /// Master to worker: what was asked for: each object's id and its mesh with the BVH the
    /// master built over it, as `fetch::encode_object` writes them (empty: the object has no mesh
    /// now), each part of an object's BVH asked for, as `fetch::encode_part` writes it (empty: the
    /// master has no such part), and each texture part asked for, its name and the
    /// [`crate::texture::TextureAnswer`] (postcard).
    Data {
        frame: u64,
        meshes: Vec<(u32, Vec<u8>)>,
        parts: Vec<(u32, u32, Vec<u8>)>,
        textures: Vec<(TexturePart, String, Vec<u8>)>,
    },
    /// Master to worker, between frames: another scene replaces the one being replicated. The
    /// worker drops its copy and everything it kept of it (the world and its BVHs, fetched meshes
    /// and textures, programs, light paths) and starts again from an empty scene, which the next
    /// frame's update fills whole.
    NewScene,
}

const HELLO: u8 = 1;
const FRAME: u8 = 2;
const ASSIGN: u8 = 3;
const RENDERED: u8 = 4;
const FRAME_DONE: u8 = 5;
const QUIT: u8 = 6;
const FETCH: u8 = 7;
const DATA: u8 = 8;
const NEW_SCENE: u8 = 9;

/// The protocol version a greeting states, read without decoding the rest: a greeting starts with
/// its kind and the version in every version of the protocol, so that ranks of different versions
/// can tell each other so.
pub fn greeting_version(bytes: &[u8]) -> Option<u32> {
    match bytes {
        [HELLO, a, b, c, d, ..] => Some(u32::from_le_bytes([*a, *b, *c, *d])),
        _ => None,
    }
}

/// Identifies the program a rank runs: the protocol version, the target and a hash of the
/// executable file itself, so that ranks running different builds refuse each other at start-up.
pub fn build_fingerprint() -> Vec<u8> {
    use std::hash::Hasher;
    use std::io::Read;
    // Every `DefaultHasher::new()` of one build hashes alike.
    let mut hasher = std::hash::DefaultHasher::new();
    hasher.write(&PROTOCOL_VERSION.to_le_bytes());
    for part in [env!("CARGO_PKG_VERSION"), std::env::consts::ARCH, std::env::consts::OS] {
        hasher.write(part.as_bytes());
    }
    hasher.write(if cfg!(target_endian = "little") { b"le" } else { b"be" });
    // The executable is read a piece at a time (a build with debug information is hundreds of
    // megabytes, which every rank would otherwise allocate at once); where it cannot be read,
    // the version and target above are all that is compared.
    if let Ok(mut file) = std::env::current_exe().and_then(std::fs::File::open) {
        let mut piece = vec![0u8; 1 << 20];
        loop {
            match file.read(&mut piece) {
                Ok(0) => break,
                Ok(n) => hasher.write(&piece[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(_) => break,
            }
        }
    }
    hasher.finish().to_le_bytes().to_vec()
}

impl Message {
    pub fn encode(&self) -> Vec<u8> {
        let mut w = Writer(Vec::new());
        match self {
            Message::Hello { protocol, build, threads, failure } => {
                w.u8(HELLO);
                w.u32(*protocol);
                w.bytes(build);
                w.u32(*threads);
                w.opt_str(failure.as_deref());
            }
            Message::Frame { frame, update, light_paths, job, units, lattices, last } => {
                w.u8(FRAME);
                w.u64(*frame);
                w.bytes(update);
                w.bytes(light_paths);
                match job {
                    Job::Tiles => w.u8(0),
                    Job::Lattices { pass, preview } => {
                        w.u8(1);
                        w.u32(*pass);
                        w.u8(u8::from(*preview));
                    }
                }
                w.u32s(units);
                w.lattices(lattices);
                w.u8(u8::from(*last));
            }
            Message::Assign { frame, units, lattices, last, dropped } => {
                w.u8(ASSIGN);
                w.u64(*frame);
                w.u32s(units);
                w.lattices(lattices);
                w.u8(u8::from(*last));
                w.u32s(dropped);
            }
            Message::Rendered { frame, units, starved } => {
                w.u8(RENDERED);
                w.u64(*frame);
                w.u8(u8::from(*starved));
                w.u32(units.len() as u32);
                for (tile, micros, pixels) in units {
                    w.u32(*tile);
                    w.u32(*micros);
                    w.bytes(pixels);
                }
            }
            Message::FrameDone { frame, counts, failure } => {
                w.u8(FRAME_DONE);
                w.u64(*frame);
                for n in counts.rays {
                    w.u64(n);
                }
                w.u64(counts.shaded_points);
                w.u64(counts.light_evaluations);
                w.u64(counts.rays_cut);
                w.u64(counts.lights_dropped);
                w.u64(counts.fetched_objects);
                w.u64(counts.fetched_bytes);
                w.u64(counts.fetched_parts);
                w.u64(counts.fetched_part_bytes);
                w.u64(counts.resident_parts);
                w.u64(counts.evicted_parts);
                w.u64(counts.fetched_textures);
                w.u64(counts.fetched_texture_levels);
                w.u64(counts.fetched_texture_tiles);
                w.u64(counts.fetched_texture_bytes);
                w.u64(counts.evicted_objects);
                w.u64(counts.resident_objects);
                w.u64(counts.reached_objects);
                w.u64(counts.kept_objects);
                w.u64(counts.kept_textures);
                w.u64(counts.world_ns);
                w.u64(counts.share_ns);
                w.u64(counts.rendering_ns);
                w.u64(counts.rendering_cpu_ns);
                w.u64(counts.fetch_wait_ns);
                w.u64(counts.fetch_build_ns);
                w.u64(counts.set_aside);
                w.u64(counts.shading_ns);
                w.u64(counts.light_paths_ns);
                w.u64(counts.gathering_ns);
                w.u32(counts.kind_ns.len() as u32);
                for &n in &counts.kind_ns {
                    w.u64(n);
                }
                w.u32(counts.by_shader.len() as u32);
                for (name, kind, ns) in &counts.by_shader {
                    w.str(name);
                    w.u8(*kind);
                    w.u64(*ns);
                }
                w.u32(counts.shader_messages.len() as u32);
                for m in &counts.shader_messages {
                    w.str(m);
                }
                w.u32(counts.texture_warnings.len() as u32);
                for (name, path, reason) in &counts.texture_warnings {
                    w.str(name);
                    w.str(path);
                    w.str(reason);
                }
                w.opt_str(failure.as_deref());
            }
            Message::Quit => w.u8(QUIT),
            Message::NewScene => w.u8(NEW_SCENE),
            Message::Fetch { frame, objects, parts, textures } => {
                w.u8(FETCH);
                w.u64(*frame);
                w.u32s(objects);
                w.u32(parts.len() as u32);
                for (object, part) in parts {
                    w.u32(*object);
                    w.u32(*part);
                }
                w.u32(textures.len() as u32);
                for (part, name, held) in textures {
                    w.part(*part);
                    w.str(name);
                    w.bytes(held.as_ref().map_or(&[][..], |d| &d[..]));
                }
            }
            Message::Data { frame, meshes, parts, textures } => {
                w.u8(DATA);
                w.u64(*frame);
                w.u32(meshes.len() as u32);
                for (object, mesh) in meshes {
                    w.u32(*object);
                    w.bytes(mesh);
                }
                w.u32(parts.len() as u32);
                for (object, part, bytes) in parts {
                    w.u32(*object);
                    w.u32(*part);
                    w.bytes(bytes);
                }
                w.u32(textures.len() as u32);
                for (part, name, bytes) in textures {
                    w.part(*part);
                    w.str(name);
                    w.bytes(bytes);
                }
            }
        }
        w.0
    }

    pub fn decode(bytes: &[u8]) -> Result<Message, String> {
        let mut r = Reader { bytes, at: 0 };
        let m = match r.u8()? {
            HELLO => Message::Hello { protocol: r.u32()?, build: r.bytes()?, threads: r.u32()?, failure: r.opt_str()? },
            FRAME => {
                let (frame, update, light_paths) = (r.u64()?, r.bytes()?, r.bytes()?);
                let job = match r.u8()? {
                    0 => Job::Tiles,
                    1 => Job::Lattices { pass: r.u32()?, preview: r.bool()? },
                    v => return Err(format!("{v} is no kind of job")),
                };
                let (units, lattices, last) = (r.u32s()?, r.lattices()?, r.bool()?);
                Message::Frame { frame, update, light_paths, job, units, lattices, last }
            }
            ASSIGN => Message::Assign {
                frame: r.u64()?,
                units: r.u32s()?,
                lattices: r.lattices()?,
                last: r.bool()?,
                dropped: r.u32s()?,
            },
            RENDERED => {
                let RenderedUnits { frame, units, starved } = RenderedUnits::read(&mut r)?;
                let units = units.into_iter().map(|(unit, micros, pixels)| (unit, micros, pixels.to_vec())).collect();
                Message::Rendered { frame, units, starved }
            }
            FRAME_DONE => {
                let frame = r.u64()?;
                let rays = [r.u64()?, r.u64()?, r.u64()?, r.u64()?];
                let (shaded_points, light_evaluations) = (r.u64()?, r.u64()?);
                let (rays_cut, lights_dropped) = (r.u64()?, r.u64()?);
                let (fetched_objects, fetched_bytes) = (r.u64()?, r.u64()?);
                let (fetched_parts, fetched_part_bytes, resident_parts) = (r.u64()?, r.u64()?, r.u64()?);
                let evicted_parts = r.u64()?;
                let (fetched_textures, fetched_texture_levels) = (r.u64()?, r.u64()?);
                let (fetched_texture_tiles, fetched_texture_bytes) = (r.u64()?, r.u64()?);
                let (evicted_objects, resident_objects, reached_objects) = (r.u64()?, r.u64()?, r.u64()?);
                let (kept_objects, kept_textures) = (r.u64()?, r.u64()?);
                let (world_ns, share_ns, rendering_ns, rendering_cpu_ns) = (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
                let (fetch_wait_ns, fetch_build_ns, set_aside) = (r.u64()?, r.u64()?, r.u64()?);
                let shading_ns = r.u64()?;
                let (light_paths_ns, gathering_ns) = (r.u64()?, r.u64()?);
                let kinds = r.count(8)?;
                let kind_ns = (0..kinds).map(|_| r.u64()).collect::<Result<_, _>>()?;
                let shaders = r.count(13)?;
                let by_shader =
                    (0..shaders).map(|_| Ok((r.str()?, r.u8()?, r.u64()?))).collect::<Result<_, String>>()?;
                let messages = r.count(4)?;
                let shader_messages = (0..messages).map(|_| r.str()).collect::<Result<_, _>>()?;
                let textures = r.count(24)?;
                let texture_warnings =
                    (0..textures).map(|_| Ok((r.str()?, r.str()?, r.str()?))).collect::<Result<_, String>>()?;
                let counts = FrameCounts {
                    rays,
                    shaded_points,
                    light_evaluations,
                    rays_cut,
                    lights_dropped,
                    shading_ns,
                    kind_ns,
                    light_paths_ns,
                    gathering_ns,
                    by_shader,
                    shader_messages,
                    texture_warnings,
                    fetched_objects,
                    fetched_bytes,
                    fetched_parts,
                    fetched_part_bytes,
                    resident_parts,
                    evicted_parts,
                    fetched_textures,
                    fetched_texture_levels,
                    fetched_texture_tiles,
                    fetched_texture_bytes,
                    evicted_objects,
                    resident_objects,
                    reached_objects,
                    kept_objects,
                    kept_textures,
                    world_ns,
                    share_ns,
                    rendering_ns,
                    rendering_cpu_ns,
                    fetch_wait_ns,
                    fetch_build_ns,
                    set_aside,
                };
                Message::FrameDone { frame, counts, failure: r.opt_str()? }
            }
            QUIT => Message::Quit,
            NEW_SCENE => Message::NewScene,
            FETCH => {
                let (frame, objects) = (r.u64()?, r.u32s()?);
                let n = r.count(8)?;
                let parts = (0..n).map(|_| Ok((r.u32()?, r.u32()?))).collect::<Result<_, String>>()?;
                let n = r.count(13)?;
                let textures = (0..n)
                    .map(|_| {
                        let (part, name, held) = (r.part()?, r.str()?, r.bytes()?);
                        let held = match held.len() {
                            0 => None,
                            _ => Some(<[u8; 32]>::try_from(held).map_err(|_| "a texture digest is not 32 bytes")?),
                        };
                        Ok((part, name, held))
                    })
                    .collect::<Result<_, String>>()?;
                Message::Fetch { frame, objects, parts, textures }
            }
            DATA => {
                let frame = r.u64()?;
                let n = r.count(12)?;
                let meshes = (0..n).map(|_| Ok((r.u32()?, r.bytes()?))).collect::<Result<_, String>>()?;
                let n = r.count(16)?;
                let parts = (0..n).map(|_| Ok((r.u32()?, r.u32()?, r.bytes()?))).collect::<Result<_, String>>()?;
                let n = r.count(17)?;
                let textures = (0..n).map(|_| Ok((r.part()?, r.str()?, r.bytes()?))).collect::<Result<_, String>>()?;
                Message::Data { frame, meshes, parts, textures }
            }
            tag => return Err(format!("unknown message kind {tag}")),
        };
        if r.at != bytes.len() {
            return Err(format!("{} bytes after the end of a message", bytes.len() - r.at));
        }
        Ok(m)
    }
}

impl FrameCounts {
    /// The shader type of a [`FrameCounts::by_shader`] entry.
    pub fn kind(index: u8) -> Option<ShaderKind> {
        ShaderKind::ALL.get(usize::from(index)).copied()
    }
}

struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn bytes(&mut self, v: &[u8]) {
        self.u64(v.len() as u64);
        self.0.extend_from_slice(v);
    }
    fn str(&mut self, v: &str) {
        self.bytes(v.as_bytes());
    }
    /// See `Reader::part`.
    fn part(&mut self, part: TexturePart) {
        match part {
            TexturePart::Whole(TextureKind::Texture) => self.u8(0),
            TexturePart::Whole(TextureKind::Shadow) => self.u8(1),
            TexturePart::Whole(TextureKind::Grid) => self.u8(2),
            TexturePart::Pyramid { raw } => {
                self.u8(3);
                self.u8(u8::from(raw));
            }
            TexturePart::Level { raw, level } => {
                self.u8(4);
                self.u8(u8::from(raw));
                self.u32(level);
            }
            TexturePart::Tile { raw, level, tile } => {
                self.u8(5);
                self.u8(u8::from(raw));
                self.u32(level);
                self.u32(tile);
            }
        }
    }
    fn opt_str(&mut self, v: Option<&str>) {
        match v {
            None => self.u8(0),
            Some(s) => {
                self.u8(1);
                self.str(s);
            }
        }
    }
    fn u32s(&mut self, v: &[u32]) {
        self.u32(v.len() as u32);
        for &x in v {
            self.u32(x);
        }
    }
    fn lattices(&mut self, v: &[LatticeUnit]) {
        self.u32(v.len() as u32);
        for u in v {
            for x in [u.lattice.x0, u.lattice.y0, u.lattice.stride] {
                self.u32(x);
            }
            self.u64(u.lanes);
        }
    }
}

/// A [`Message::Rendered`] as it lies in its bytes: each unit's pixels borrowed, not copied. The
/// master reads every batch of finished tiles this way, and copies each tile's pixels once, into
/// the image.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedUnits<'a> {
    pub frame: u64,
    /// Each unit's index, its thread's microseconds over it, and its pixels.
    pub units: Vec<(u32, u32, &'a [u8])>,
    pub starved: bool,
}

impl<'a> RenderedUnits<'a> {
    /// The finished units `bytes` hold; `None` when they hold another kind of message, an error
    /// when a `Rendered` message is damaged.
    pub fn decode(bytes: &'a [u8]) -> Option<Result<RenderedUnits<'a>, String>> {
        let mut r = Reader { bytes, at: 0 };
        if r.u8().ok()? != RENDERED {
            return None;
        }
        Some(RenderedUnits::read(&mut r).and_then(|m| match r.at == bytes.len() {
            true => Ok(m),
            false => Err(format!("{} bytes after the end of a message", bytes.len() - r.at)),
        }))
    }

    /// The message after its kind.
    fn read(r: &mut Reader<'a>) -> Result<RenderedUnits<'a>, String> {
        let (frame, starved) = (r.u64()?, r.bool()?);
        let n = r.count(16)?;
        let units = (0..n).map(|_| Ok((r.u32()?, r.u32()?, r.slice()?))).collect::<Result<_, String>>()?;
        Ok(RenderedUnits { frame, units, starved })
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    /// A length-prefixed byte string, where it lies.
    fn slice(&mut self) -> Result<&'a [u8], String> {
        let n = usize::try_from(self.u64()?).map_err(|_| "a length past the address space".to_string())?;
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or("a message ended early")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or("a message ended early")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn bool(&mut self) -> Result<bool, String> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(format!("{v} is not a truth value")),
        }
    }
    fn u32(&mut self) -> Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> Result<u64, String> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(std::array::from_fn(|i| b[i])))
    }
    /// A count of items at least `min_size` bytes each, checked against the bytes left, so that no
    /// count sizes an allocation beyond what the message holds.
    fn count(&mut self, min_size: usize) -> Result<usize, String> {
        let n = self.u32()? as usize;
        if n.saturating_mul(min_size) > self.bytes.len() - self.at {
            return Err(format!("a message claims {n} items it does not hold"));
        }
        Ok(n)
    }
    fn bytes(&mut self) -> Result<Vec<u8>, String> {
        Ok(self.slice()?.to_vec())
    }
    fn str(&mut self) -> Result<String, String> {
        String::from_utf8(self.bytes()?).map_err(|_| "a string that is not UTF-8".to_string())
    }
    fn opt_str(&mut self) -> Result<Option<String>, String> {
        match self.u8()? {
            0 => Ok(None),
            1 => Ok(Some(self.str()?)),
            v => Err(format!("{v} is not an option marker")),
        }
    }
    fn u32s(&mut self) -> Result<Vec<u32>, String> {
        let n = self.count(4)?;
        (0..n).map(|_| self.u32()).collect()
    }
    /// A [`TexturePart`]: a byte (0 to 2 the whole as a texture, shadow map or grid, 3 a
    /// pyramid, 4 a level, 5 a tile), then for a pyramid, level or tile whether raw (a byte), a
    /// level's index, and a tile's.
    fn part(&mut self) -> Result<TexturePart, String> {
        let tag = self.u8()?;
        let mut raw = || match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(format!("{v} is not a flag")),
        };
        Ok(match tag {
            0 => TexturePart::Whole(TextureKind::Texture),
            1 => TexturePart::Whole(TextureKind::Shadow),
            2 => TexturePart::Whole(TextureKind::Grid),
            3 => TexturePart::Pyramid { raw: raw()? },
            4 => {
                let raw = raw()?;
                TexturePart::Level { raw, level: self.u32()? }
            }
            5 => {
                let raw = raw()?;
                TexturePart::Tile { raw, level: self.u32()?, tile: self.u32()? }
            }
            v => Err(format!("{v} is no part of a texture"))?,
        })
    }
    fn lattices(&mut self) -> Result<Vec<LatticeUnit>, String> {
        let n = self.count(20)?;
        (0..n)
            .map(|_| {
                let lattice = PixelLattice { x0: self.u32()?, y0: self.u32()?, stride: self.u32()? };
                Ok(LatticeUnit { lattice, lanes: self.u64()? })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn examples() -> Vec<Message> {
        vec![
            Message::Hello { protocol: PROTOCOL_VERSION, build: vec![1, 2, 3], threads: 4, failure: None },
            Message::Hello { protocol: 7, build: vec![], threads: 1, failure: Some("no such file".into()) },
            Message::Frame {
                frame: 3,
                update: vec![9; 10],
                light_paths: vec![1, 2],
                job: Job::Tiles,
                units: vec![0, 5, 7],
                lattices: vec![],
                last: false,
            },
            Message::Frame {
                frame: 4,
                update: vec![],
                light_paths: vec![],
                job: Job::Lattices { pass: 9, preview: true },
                units: vec![1],
                lattices: vec![LatticeUnit { lattice: PixelLattice { x0: 8, y0: 16, stride: 2 }, lanes: u64::MAX }],
                last: true,
            },
            Message::Assign { frame: 3, units: vec![], lattices: vec![], last: true, dropped: vec![] },
            Message::Assign { frame: 5, units: vec![], lattices: vec![], last: false, dropped: vec![4, 0, 9] },
            Message::Assign {
                frame: 4,
                units: vec![2, 3],
                lattices: vec![
                    LatticeUnit { lattice: PixelLattice { x0: 0, y0: 0, stride: 1 }, lanes: 5 },
                    LatticeUnit { lattice: PixelLattice { x0: 3, y0: 1, stride: 4 }, lanes: 1 << 63 },
                ],
                last: false,
                dropped: vec![],
            },
            Message::Rendered {
                frame: u64::MAX,
                units: vec![(12, 900, vec![0xAB; 100]), (3, 0, vec![])],
                starved: true,
            },
            Message::FrameDone {
                frame: 1,
                counts: FrameCounts {
                    rays: [1, 2, 3, 4],
                    shaded_points: 5,
                    light_evaluations: 6,
                    rays_cut: 7,
                    lights_dropped: 8,
                    shading_ns: 7,
                    kind_ns: vec![8, 9],
                    light_paths_ns: 17,
                    gathering_ns: 18,
                    by_shader: vec![("plastic".into(), 0, 10)],
                    shader_messages: vec!["plastic: a loop stopped".into()],
                    texture_warnings: vec![("grain".into(), String::new(), "not found".into())],
                    fetched_objects: 11,
                    fetched_bytes: 12,
                    fetched_parts: 28,
                    fetched_part_bytes: 29,
                    resident_parts: 30,
                    evicted_parts: 31,
                    fetched_textures: 15,
                    fetched_texture_levels: 25,
                    fetched_texture_tiles: 31,
                    fetched_texture_bytes: 16,
                    evicted_objects: 13,
                    resident_objects: 14,
                    reached_objects: 24,
                    kept_objects: 26,
                    kept_textures: 27,
                    world_ns: 19,
                    share_ns: 20,
                    rendering_ns: 21,
                    rendering_cpu_ns: 26,
                    fetch_wait_ns: 22,
                    fetch_build_ns: 23,
                    set_aside: 32,
                },
                failure: Some("cannot build".into()),
            },
            Message::Quit,
            Message::NewScene,
            Message::Fetch { frame: 2, objects: vec![4, 1], parts: vec![(4, 0), (9, 77)], textures: vec![] },
            Message::Fetch {
                frame: 2,
                objects: vec![],
                parts: vec![],
                textures: vec![
                    (TexturePart::Whole(TextureKind::Shadow), "key.shad".into(), Some([7; 32])),
                    (TexturePart::Whole(TextureKind::Grid), String::new(), None),
                    (TexturePart::Pyramid { raw: true }, "wood.ppm".into(), Some([0; 32])),
                    (TexturePart::Level { raw: false, level: 3 }, "wood.ppm".into(), None),
                    (TexturePart::Tile { raw: true, level: 1, tile: 70_000 }, "wood.ppm".into(), None),
                ],
            },
            Message::Data {
                frame: 2,
                meshes: vec![(4, vec![1, 2, 3]), (1, vec![])],
                parts: vec![(4, 2, vec![5; 7]), (4, 3, vec![])],
                textures: vec![],
            },
            Message::Data {
                frame: 3,
                meshes: vec![],
                parts: vec![],
                textures: vec![
                    (TexturePart::Whole(TextureKind::Texture), "grain.png".into(), vec![7; 9]),
                    (TexturePart::Level { raw: true, level: u32::MAX }, "grain.png".into(), vec![]),
                ],
            },
        ]
    }

    #[test]
    fn every_message_decodes_to_itself() {
        for m in examples() {
            assert_eq!(Message::decode(&m.encode()), Ok(m.clone()), "{m:?}");
        }
    }

    #[test]
    fn damaged_messages_are_errors() {
        for m in examples() {
            let bytes = m.encode();
            // Every prefix is short, and one byte more is too long.
            for end in 0..bytes.len() {
                assert!(Message::decode(&bytes[..end]).is_err(), "{m:?} cut at {end}");
            }
            let mut longer = bytes.clone();
            longer.push(0);
            assert!(Message::decode(&longer).is_err());
        }
        // A count far past the message's size is refused before anything is allocated for it.
        let mut huge = vec![ASSIGN];
        huge.extend_from_slice(&0u64.to_le_bytes());
        huge.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(Message::decode(&huge).unwrap_err().contains("claims"));
        assert!(Message::decode(&[99]).is_err());
    }

    /// Finished units read where they lie are the units the whole decoding copies out, damaged
    /// `Rendered` messages are errors either way, and other messages are not read as units.
    #[test]
    fn rendered_units_are_read_in_place() {
        for m in examples() {
            let bytes = m.encode();
            match (&m, RenderedUnits::decode(&bytes)) {
                (Message::Rendered { frame, units, starved }, Some(Ok(view))) => {
                    assert_eq!((view.frame, view.starved), (*frame, *starved));
                    let copied: Vec<(u32, u32, Vec<u8>)> =
                        view.units.iter().map(|(u, t, p)| (*u, *t, p.to_vec())).collect();
                    assert_eq!(&copied, units);
                    for end in 0..bytes.len() {
                        assert!(!matches!(RenderedUnits::decode(&bytes[..end]), Some(Ok(_))), "cut at {end}");
                    }
                    let mut longer = bytes.clone();
                    longer.push(0);
                    assert!(matches!(RenderedUnits::decode(&longer), Some(Err(_))));
                }
                (Message::Rendered { .. }, other) => panic!("{other:?}"),
                (_, view) => assert!(view.is_none(), "{m:?}"),
            }
        }
        assert!(RenderedUnits::decode(&[]).is_none());
    }

    #[test]
    fn the_fingerprint_is_stable_within_a_build() {
        assert_eq!(build_fingerprint(), build_fingerprint());
        assert_eq!(build_fingerprint().len(), 8);
    }
}

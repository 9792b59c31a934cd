//! RIB requests onto the API: a parsed RIB stream becomes calls on a [`Context`].
//!
//! RenderMan semantics kept:
//! - The transform current at `WorldBegin` is the camera's (world to camera, camera space x right,
//!   y up, z forward); `Projection "perspective" "fov"` spans the shorter image side;
//!   `Projection "orthographic"` binds the library's `orthographic` camera shader.
//! - Transforms post-multiply the current transform (RenderMan's `Translate` applies to what follows,
//!   as OpenGL's); `Transform`/`ConcatTransform` take RenderMan's row-major matrices.
//! - `AttributeBegin/End` save and restore the colour, opacity, surface shader, the area light and
//!   the transform; `TransformBegin/End` the transform only.
//! - `TrimCurve` and `Attribute "trimcurve" "sense"` are attribute state, kept with the basis and
//!   `TextureCoordinates` (`MeshOptions`): they hold for the `NuPatch`es that follow in the block.
//! - Point-like shader parameters are in the space current at the shader statement.
//! - `Points` disks and `Curves` ribbons without `N` face the camera as it is at `WorldBegin`, seen
//!   from the transform current at the request (`MeshOptions::view`): a retained object's face
//!   the camera from where `ObjectBegin` defines them, wherever `ObjectInstance` places them.
//! - Consecutive geometry under one set of attributes becomes one object (one BVH), instanced once;
//!   `ObjectBegin/End` make a retained object placed by each `ObjectInstance`, which shades it
//!   with the attributes current there (RISpec 3.2: an object's attributes are inherited when it
//!   is instanced) except those the block set itself, which are the block's (PRMan's rule). A
//!   mesh file read inside the block (`ReadArchive "tree.obj"`) adds its objects, one per
//!   material with its own shader, to the ones each `ObjectInstance` places.
//! - `AreaLightSource`: the geometry that follows in the same attribute block both renders and emits
//!   (sampled for soft shadows).
//! - `ReadArchive` of an `.obj`, `.ply`, `.gltf` or `.glb` file adds those meshes under the current
//!   attributes.
//! - `Attribute "trace" "string alphamask" ["leaf.tga"]` (rtsl's own) cuts the geometry that
//!   follows in the block where the texture's alpha is below one half (`Context::alpha_mask`).
//!
//! What cannot be honoured (a shader not found, a parameter the shader lacks or of the wrong type, a
//! request the engine does not support yet) is a warning with the file, line and column, and
//! loading goes on; so does it past a request with a syntax error, which is skipped (RenderMan's
//! behaviour) and reported as an error.

use super::decl::{Class, Ty};
use super::mesh::MeshOptions;
use super::primitive::{mesh_from_request_with, request_segments, request_triangles};
use super::request::{Handle, Location, Orientation, Param, ParamValue as RibValue, Request, RequestKind};
use super::view::{Projection, View};
use super::{
    parse_bytes_into, parse_file_into, RibDiagnostic, RibParse, RibSink, Severity, MAX_BLOCK_DEPTH, MAX_RIB_TRIANGLES,
};
use crate::api::{
    ApiError, AttributeParts, Context, InheritedAppearance, InstanceId, LightId, ObjectId, SavedAttributes,
};
use crate::csg::{Solid, SolidNode, SolidOp, SolidPart};
use crate::geometry::{Deformation, Mesh};
use crate::render::{DisplayMode, RayKind, MAX_PIXEL_SAMPLES};
use crate::scene_file::{add_model_file, add_model_file_placed, Placement, SceneFileError};
use crate::shading::{ParamValue, ShaderProgram};
use glam::{Affine3A, Mat4, Vec3};
use rtsl_compiler::interface::BaseType;
use std::collections::HashMap;
use std::ops::{ControlFlow, Deref, DerefMut};
use std::path::{Path, PathBuf};

/// An image a `Display` request asks for.
#[derive(Clone, Debug, PartialEq)]
pub struct RibDisplay {
    /// The file, frame patterns expanded (relative to the RIB file's directory as written).
    pub name: PathBuf,
    /// The channels it holds.
    pub mode: DisplayMode,
    /// A window rather than a file (driver `framebuffer`, or a renderer's viewer: `it`, `piqsl`,
    /// `idisplay`...): `rtsl view` is the window; `rtsl render` writes no file for it.
    pub window: bool,
    /// The file format the display driver names (`tiff`, `openexr`, `png`, `targa`; `file` where
    /// the name's extension names none, as RenderMan's `file` writes TIFF); `None`: the one the
    /// name's extension names.
    pub format: Option<crate::image_io::ImageFormat>,
    /// A depth map for shadows (driver `zfile` or `shadow`): depth written as a shadow map, an EXR
    /// file with the camera's projection ([`crate::texture::write_shadow_map`]) whatever its name.
    pub depth_map: bool,
    /// An output variable of the surface shaders (the mode names one: an arbitrary output
    /// variable), kept by the frame ([`crate::render::RenderOptions::outputs`]) and written as
    /// RGB (a float in red); `mode` is then [`DisplayMode::Rgb`].
    pub output: Option<String>,
}

/// The value of a `"user"` option or attribute (read by `option("user:name")`,
/// `attribute("user:name")` and `rayinfo`): one float or integer, one colour, point, vector or
/// normal (a point as written, in no particular space), or one string.
fn user_value(p: &Param) -> Option<crate::render::RayValue> {
    use super::decl::Ty;
    use crate::render::RayValue;
    let triple = |v: &[f32]| <[f32; 3]>::try_from(v).ok();
    match (&p.value, p.decl.ty) {
        (super::request::ParamValue::Strings(v), _) if v.len() == 1 => Some(RayValue::String(v[0].clone())),
        (super::request::ParamValue::Ints(v), _) if v.len() == 1 => Some(RayValue::Float(v[0] as f32)),
        (super::request::ParamValue::Floats(v), Ty::Float) if v.len() == 1 => Some(RayValue::Float(v[0])),
        (super::request::ParamValue::Floats(v), Ty::Color) => triple(v).map(RayValue::Color),
        (super::request::ParamValue::Floats(v), Ty::Point | Ty::Vector | Ty::Normal) => triple(v).map(RayValue::Point),
        _ => None,
    }
}

/// The names PRMan, 3Delight and BMRT give the rays shaders trace in `Attribute "visibility"`:
/// rtsl's one `RayKind::Trace`.
const SECONDARY_RAY_KINDS: [&str; 4] = ["trace", "specular", "diffuse", "reflection"];

/// Whether a number parameter says on (nonzero), `None` for one without a number.
fn switched_on(p: &Param) -> Option<bool> {
    let int = p.ints().and_then(|i| i.first()).map(|&i| i != 0);
    int.or_else(|| p.floats().and_then(|v| v.first()).map(|&v| v != 0.0))
}

/// The parameters of PRMan's `RiCamera` (`Camera "name" ...`), by which it is told from a camera
/// shader's `Camera` request.
const PRMAN_CAMERA_PARAMETERS: &[&str] = &[
    "shutteropening",
    "dofmult",
    "extremeoffset",
    "apertureNSides",
    "apertureAngle",
    "apertureRoundness",
    "apertureDensity",
    "focusregion",
];

/// PRMan's and 3Delight's default `Option "limits" "zthreshold"` (each channel).
pub const RENDERMAN_DEPTH_THRESHOLD: f32 = 0.996;

/// A colour option's value (`Option "limits" "othreshold"`): three numbers, or one for all three;
/// each clamped to [0, 1]. `None` for another count or a value that is not a number.
fn color_option(p: &Param) -> Option<[f32; 3]> {
    let values: Vec<f32> = match (p.floats(), p.ints()) {
        (Some(v), _) => v.to_vec(),
        (None, Some(v)) => v.iter().map(|&i| i as f32).collect(),
        (None, None) => return None,
    };
    let rgb = match *values.as_slice() {
        [x] => [x; 3],
        [r, g, b] => [r, g, b],
        _ => return None,
    };
    rgb.iter().all(|v| !v.is_nan()).then(|| rgb.map(|v| v.clamp(0.0, 1.0)))
}

/// The warning for a `"user"` value [`user_value`] does not keep.
fn user_value_skipped(name: &str) -> String {
    format!("user data \"{name}\" skipped: rtsl keeps one float, integer, colour, point, vector, normal or string")
}

/// The parameters of an `Imager` call, with PRMan's name for the colour of its built-in
/// `background` imager (`Imager "background" "color" [r g b]`, a name no shader parameter can have)
/// given as the `background` parameter of a `background` shader that has one.
fn background_color_alias(program: &crate::shading::Program, params: &[Param]) -> Vec<Param> {
    let layout = program.layout();
    let aliased =
        program.name == "background" && layout.param("color").is_none() && layout.param("background").is_some();
    params
        .iter()
        .map(|p| match aliased && p.name == "color" {
            true => Param { name: "background".to_string(), ..p.clone() },
            false => p.clone(),
        })
        .collect()
}

/// What a `Display` driver does with the image.
#[derive(Clone, Copy, Debug, PartialEq)]
enum DisplayDriver {
    /// Shows it in a window: the generic `framebuffer`, and the viewers renderers ship (PRMan's
    /// `it`, Aqsis's `piqsl` and `zframebuffer`, 3Delight's `idisplay`, Houdini's `mplay`, `x11`,
    /// `windows`).
    Window,
    /// Writes a file in the format given, or (`None`) the one the name's extension names.
    File(Option<crate::image_io::ImageFormat>),
}

impl DisplayDriver {
    const NAMES: &'static str =
        "file, tiff, openexr (exr), png, targa (tga), zfile, shadow; windows: framebuffer, it, \
                                 piqsl, zframebuffer, idisplay, mplay, x11, windows";

    /// The driver `driver` is for an image named `name`; `None` for a driver rtsl does not have,
    /// unless the name's extension names a format it writes (then that).
    fn parse(driver: &str, name: &Path) -> Option<DisplayDriver> {
        use crate::image_io::ImageFormat;
        let by_name = ImageFormat::from_path(name);
        let file = |format| Some(DisplayDriver::File(Some(format)));
        match driver.to_ascii_lowercase().as_str() {
            "framebuffer" | "it" | "piqsl" | "zframebuffer" | "idisplay" | "x11" | "windows" | "mplay" => {
                Some(DisplayDriver::Window)
            }
            // Depth maps are written as shadow maps whatever the name.
            "zfile" | "shadow" => Some(DisplayDriver::File(None)),
            // RenderMan's `file` is the renderer's default format, TIFF for PRMan and Aqsis, where
            // the name does not say (`ri.pic`); a name of a format rtsl does not write is refused.
            "file" => {
                let other_image = name.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(
                        e.to_ascii_lowercase().as_str(),
                        "bmp" | "gif" | "jpg" | "jpeg" | "webp" | "hdr" | "pgm" | "psd"
                    )
                });
                Some(DisplayDriver::File(by_name.or((!other_image).then_some(ImageFormat::Tiff))))
            }
            "tiff" => file(ImageFormat::Tiff),
            "openexr" | "exr" => file(ImageFormat::Exr),
            "png" => file(ImageFormat::Png),
            "targa" | "tga" => file(ImageFormat::Tga),
            _ => by_name.map(|f| DisplayDriver::File(Some(f))),
        }
    }
}

/// The output variable a `Display` mode names: `name`, `type name` or `varying type name`
/// (PRMan's inline declaration), `None` for anything else.
fn output_variable(mode: &str) -> Option<&str> {
    let words: Vec<&str> = mode.split_whitespace().collect();
    let (name, decl) = words.split_last()?;
    let types = ["float", "color", "point", "vector", "normal"];
    let declared = match decl {
        [] => true,
        [ty] => types.contains(ty),
        [class, ty] => matches!(*class, "varying" | "vertex" | "uniform") && types.contains(ty),
        _ => false,
    };
    let identifier = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    (declared && identifier).then_some(*name)
}

/// What loading a RIB stream produced besides the scene in the context.
#[derive(Debug, Default)]
pub struct LoadedRib {
    /// The image file the first file `Display` names (relative to the RIB file's directory).
    pub display: Option<PathBuf>,
    /// Every image the `Display` requests ask for, the first one and those named `+name`, in
    /// order.
    pub displays: Vec<RibDisplay>,
    /// Everything that was skipped, ignored or approximated, with its location: a
    /// [`Severity::Omission`] where part of the scene is missing from the picture (a request
    /// skipped, a shader, archive or model not found), a [`Severity::Warning`] otherwise.
    pub warnings: Vec<RibDiagnostic>,
    /// The files the scene was read from besides the RIB file itself: its RIB archives and the
    /// model files `ReadArchive` named (not textures, which load as rendering needs them).
    pub files: Vec<PathBuf>,
    /// How many images the stream asks for (see [`frames`]); at least one.
    pub frames: usize,
    /// The number of the frame loaded: its `FrameBegin` number, or its place among the frames
    /// counting from 1 when it has none.
    pub frame_number: i32,
}

impl LoadedRib {
    /// How many of the diagnostics say that part of the scene is missing from the picture: the
    /// omissions, and the errors (a request that could not be read is skipped).
    pub fn omissions(&self) -> usize {
        self.warnings.iter().filter(|d| d.severity >= Severity::Omission).count()
    }

    /// How many requests could not be read (syntax errors).
    pub fn errors(&self) -> usize {
        self.warnings.iter().filter(|d| d.severity == Severity::Error).count()
    }
}

/// Whether a shader statement names no shader: an empty name, or RISpec's null shader ("a
/// placeholder if no action is to be performed"), which exists for every shader type. (As a
/// surface it is a shader of the library, `null.sl`, since a surface is always shaded.)
fn is_null(name: &str) -> bool {
    name.is_empty() || name == "null"
}

/// Loads a RIB file's first image into `rt`.
pub fn load_file(rt: &mut Context, path: impl AsRef<Path>) -> Result<LoadedRib, SceneFileError> {
    load_file_frame(rt, path, 0)
}

/// Loads the image at `index` (counting from 0, see [`frames`]) of a RIB file into `rt`.
pub fn load_file_frame(rt: &mut Context, path: impl AsRef<Path>, index: usize) -> Result<LoadedRib, SceneFileError> {
    let path = path.as_ref();
    let unreadable = |e: super::RibError| SceneFileError::Rib { path: path.to_path_buf(), message: e.message };
    load_stream(rt, path, index, |sink| parse_file_into(path, sink).map_err(unreadable))
}

/// The numbers of the images a RIB file asks for, in order (see [`Frames::number`]).
pub fn frame_numbers(path: impl AsRef<Path>) -> Result<Vec<i32>, SceneFileError> {
    let path = path.as_ref();
    let mut frames = Frames::default();
    parse_file_into(path, &mut |r| {
        frames.add(&r);
    })
    .map_err(|e| SceneFileError::Rib { path: path.to_path_buf(), message: e.message })?;
    Ok((0..frames.count()).map(|i| frames.number(i)).collect())
}

/// Loads RIB text's first image into `rt`; `name` names it in messages and its directory resolves
/// relative paths.
pub fn load_str(rt: &mut Context, text: &str, name: impl AsRef<Path>) -> Result<LoadedRib, SceneFileError> {
    let name = name.as_ref();
    load_stream(rt, name, 0, |sink| Ok(parse_bytes_into(text.as_bytes(), name, sink)))
}

/// The images a RIB stream asks for, in order, by the frame each request belongs to: every
/// `FrameBegin`/`FrameEnd` block is one, and so is every `WorldBegin`/`WorldEnd` block outside a
/// frame (RISpec 3.2: `WorldEnd` renders the image). Requests outside both belong to no frame: they
/// set options and the camera for every image after them. Worked out request by request, as the
/// stream is read.
#[derive(Default)]
pub struct Frames {
    /// Per image, its `FrameBegin` number.
    numbers: Vec<Option<i32>>,
    in_frame: bool,
    in_world: bool,
}

impl Frames {
    /// Splits `requests` into images.
    pub fn of(requests: &[Request]) -> Frames {
        let mut frames = Frames::default();
        for r in requests {
            frames.add(r);
        }
        frames
    }

    /// Takes the next request of the stream: the index of the image it belongs to, if any.
    pub fn add(&mut self, r: &Request) -> Option<usize> {
        match &r.kind {
            RequestKind::FrameBegin(number) if !self.in_frame => {
                self.in_frame = true;
                self.numbers.push(*number);
            }
            RequestKind::WorldBegin if !self.in_frame && !self.in_world => {
                self.in_world = true;
                self.numbers.push(None);
            }
            _ => {}
        }
        let owner = (self.in_frame || self.in_world).then(|| self.numbers.len() - 1);
        match &r.kind {
            RequestKind::FrameEnd => self.in_frame = false,
            RequestKind::WorldEnd if !self.in_frame => self.in_world = false,
            _ => {}
        }
        owner
    }

    /// Whether the last request taken was inside an image that has not ended.
    pub fn open(&self) -> bool {
        self.in_frame || self.in_world
    }

    /// How many images: at least one (a stream with no world block is one empty image).
    pub fn count(&self) -> usize {
        self.numbers.len().max(1)
    }

    /// The number of the image at `index`: its `FrameBegin` number, or `index + 1`.
    pub fn number(&self, index: usize) -> i32 {
        self.numbers.get(index).copied().flatten().unwrap_or(index as i32 + 1)
    }
}

/// A `Display` name with RenderMan's frame patterns replaced: `#f` by the frame number, `#Nf` by
/// it padded with zeros to N digits, `##` by `#`. Any other `#` stays as written.
pub fn expand_display_name(name: &str, frame: i32) -> String {
    let mut out = String::with_capacity(name.len());
    let mut rest = name;
    while let Some(at) = rest.find('#') {
        out.push_str(&rest[..at]);
        let after = &rest[at + 1..];
        let digits = after.bytes().take_while(u8::is_ascii_digit).count();
        if let Some(after_hash) = after.strip_prefix('#') {
            out.push('#');
            rest = after_hash;
        } else if after[digits..].starts_with('f') && digits <= 2 {
            let width = after[..digits].parse::<usize>().unwrap_or(0);
            out.push_str(&format!("{frame:0width$}"));
            rest = &after[digits + 1..];
        } else {
            out.push('#');
            rest = after;
        }
    }
    out.push_str(rest);
    out
}

/// A stream with syntax errors loads what it could read, as RenderMan renders the rest of a file
/// whose request could not be read: the errors are in [`LoadedRib::warnings`] (as
/// [`Severity::Error`]) and counted by [`LoadedRib::omissions`]. `read` reads the stream, handing
/// each request to the sink it is given as it is read: requests are loaded as they come, and
/// those of other images only counted, so that no stream is held whole.
fn load_stream(
    rt: &mut Context,
    path: &Path,
    index: usize,
    read: impl FnOnce(&mut dyn RibSink) -> Result<RibParse, SceneFileError>,
) -> Result<LoadedRib, SceneFileError> {
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut loader = Loader::new(LoadInto::Borrowed(rt), dir);
    let mut frames = Frames::default();
    let mut mesh_files = Vec::new();
    // Whether this image's requests began, and ended.
    let (mut began, mut ended) = (false, false);
    let mut last: Option<Location> = None;
    let mut fatal = None;
    let mut sink = |r: Request| {
        if let RequestKind::MeshArchive(path) = &r.kind {
            mesh_files.push(path.clone());
        }
        let owner = frames.add(&r);
        if ended || fatal.is_some() {
            return;
        }
        // Requests between frames set up the frames that follow them: none after this frame's end
        // applies to it (a later `Display`, `Format` or `MakeShadow` of its output is the next
        // frame's).
        match owner {
            Some(frame) if frame > index => ended = true,
            Some(frame) if frame < index => {}
            None if began => ended = true,
            _ => {
                began |= owner.is_some();
                last = Some(r.loc.clone());
                if let Err(e) = loader.load(&r) {
                    fatal = Some(e);
                }
            }
        }
    };
    let parse = read(&mut sink)?;
    if let Some(e) = fatal {
        return Err(e);
    }
    if index >= frames.count() {
        return Err(SceneFileError::Rib {
            path: path.to_path_buf(),
            message: format!("there is no image {} (the file has {})", index + 1, frames.count()),
        });
    }
    let mut files = parse.archives;
    files.extend(mesh_files);
    // What reading the stream found comes first, as it did when the stream was read before it
    // was loaded.
    let end = ImageEnd { read: parse.diagnostics, files, frames: frames.count(), number: frames.number(index), last };
    loader.finish(end)?;
    Ok(loader.out)
}

/// The most requests outside every image of a RIB stream that [`load_file_frames`] keeps to
/// repeat for the images after them (options, the camera, displays: a few dozen in a real stream).
/// Past it the rest are not repeated, an omission each image after them reports.
pub const MAX_SHARED_REQUESTS: usize = 1 << 16;

/// An image of a RIB file, loaded by [`load_file_frames`] into a context of its own.
pub struct RibImage {
    /// Its place among the file's images, counting from 0 (see [`Frames`]).
    pub index: usize,
    /// The context it was loaded into.
    pub rt: Context,
    /// What loading it found. Its `warnings` begin with what reading the stream found since the
    /// image before it that was loaded (its own part, images skipped and the requests between);
    /// its `frames` counts the images read so far, its `files` the files read so far.
    pub loaded: LoadedRib,
}

/// What [`load_file_frames`] read besides the images it handed over.
#[derive(Debug, Default)]
pub struct RibImages {
    /// The numbers of the images read, in order (every image of the file, unless the reading was
    /// stopped): their `FrameBegin` numbers, or their places counting from 1.
    pub numbers: Vec<i32>,
    /// What reading found after the last image loaded.
    pub warnings: Vec<RibDiagnostic>,
}

/// Reads a RIB file once, loading each image it asks for (see [`Frames`]) that `wanted` takes (by
/// its index and number) into a context of its own (`new_context`'s), and handing it to `each` as
/// soon as its last request is read: a file of many frames is read in one pass, in memory bounded
/// by its largest image, rather than once for each. Each image is loaded from the requests that
/// [`load_file_frame`] of it would load: the requests outside every image before it (at most
/// [`MAX_SHARED_REQUESTS`] of them), then its own. `each` may stop the reading (`Break`); its
/// error stops it and is returned, as is an image too large to load.
pub fn load_file_frames<E: From<SceneFileError>>(
    path: impl AsRef<Path>,
    new_context: impl FnMut() -> Context,
    wanted: impl FnMut(usize, i32) -> bool,
    each: impl FnMut(RibImage) -> Result<ControlFlow<()>, E>,
) -> Result<RibImages, E> {
    let path = path.as_ref();
    let unreadable = |e: super::RibError| SceneFileError::Rib { path: path.to_path_buf(), message: e.message };
    load_images(path, |sink| parse_file_into(path, sink).map(|_| ()).map_err(unreadable), new_context, wanted, each)
}

/// [`load_file_frames`] of RIB text; `name` names it in messages and its directory resolves
/// relative paths.
pub fn load_str_frames<E: From<SceneFileError>>(
    text: &str,
    name: impl AsRef<Path>,
    new_context: impl FnMut() -> Context,
    wanted: impl FnMut(usize, i32) -> bool,
    each: impl FnMut(RibImage) -> Result<ControlFlow<()>, E>,
) -> Result<RibImages, E> {
    let name = name.as_ref();
    let read = |sink: &mut dyn RibSink| {
        parse_bytes_into(text.as_bytes(), name, sink);
        Ok(())
    };
    load_images(name, read, new_context, wanted, each)
}

/// [`load_file_frames`] of the stream `read` reads (named `path`).
fn load_images<E: From<SceneFileError>>(
    path: &Path,
    read: impl FnOnce(&mut dyn RibSink) -> Result<(), SceneFileError>,
    mut new_context: impl FnMut() -> Context,
    mut wanted: impl FnMut(usize, i32) -> bool,
    mut each: impl FnMut(RibImage) -> Result<ControlFlow<()>, E>,
) -> Result<RibImages, E> {
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    // The first image's loader takes the requests before it as they come.
    let first = Loader::new(LoadInto::Owned(Box::new(new_context())), dir.clone());
    let mut reader = ImageReader {
        dir,
        frames: Frames::default(),
        shared: Vec::new(),
        shared_left_out: None,
        loader: Some(first),
        current: None,
        read: Vec::new(),
        files: Vec::new(),
        last: None,
        error: None,
        new_context: &mut new_context,
        wanted: &mut wanted,
        each: &mut each,
    };
    read(&mut reader)?;
    if reader.error.is_none() {
        reader.end_of_stream();
    }
    if let Some(e) = reader.error {
        return Err(e);
    }
    let numbers = (0..reader.frames.numbers.len()).map(|i| reader.frames.number(i)).collect();
    Ok(RibImages { numbers, warnings: reader.read })
}

/// The sink of [`load_file_frames`]: loads the images it is asked for as their requests come.
struct ImageReader<'f, E> {
    dir: PathBuf,
    frames: Frames,
    /// The requests outside every image so far (at most [`MAX_SHARED_REQUESTS`]).
    shared: Vec<Request>,
    /// The first of them not kept, and how many were not.
    shared_left_out: Option<(Location, usize)>,
    /// The loader of the image being read, when it is wanted (or of the first image, before it).
    loader: Option<Loader<'static>>,
    /// The image being read.
    current: Option<usize>,
    /// What reading found since the last image handed over.
    read: Vec<RibDiagnostic>,
    /// The archives and mesh files read so far.
    files: Vec<PathBuf>,
    /// The last request the loader took.
    last: Option<Location>,
    error: Option<E>,
    new_context: &'f mut dyn FnMut() -> Context,
    wanted: &'f mut dyn FnMut(usize, i32) -> bool,
    each: &'f mut dyn FnMut(RibImage) -> Result<ControlFlow<()>, E>,
}

impl<E: From<SceneFileError>> ImageReader<'_, E> {
    /// Image `index` begins: its loader, with the requests before it, if it is wanted.
    fn begin(&mut self, index: usize) -> Result<(), SceneFileError> {
        self.current = Some(index);
        if !(self.wanted)(index, self.frames.number(index)) {
            self.loader = None;
            return Ok(());
        }
        if self.loader.is_some() {
            return Ok(());
        }
        let mut loader = Loader::new(LoadInto::Owned(Box::new((self.new_context)())), self.dir.clone());
        for r in &self.shared {
            loader.load(r)?;
        }
        if let Some((at, count)) = &self.shared_left_out {
            let message = format!(
                "{count} requests outside the frames, from here on, are not repeated for the frames after them (more \
                 than {MAX_SHARED_REQUESTS})"
            );
            loader.out.warnings.push(RibDiagnostic::omission(at, message));
        }
        self.loader = Some(loader);
        Ok(())
    }

    /// The image being read ended: hands it over if it was loaded.
    fn end(&mut self) -> ControlFlow<()> {
        let (Some(index), Some(mut loader)) = (self.current.take(), self.loader.take()) else {
            return ControlFlow::Continue(());
        };
        let end = ImageEnd {
            read: std::mem::take(&mut self.read),
            files: self.files.clone(),
            frames: self.frames.count(),
            number: self.frames.number(index),
            last: self.last.take(),
        };
        if let Err(e) = loader.finish(end) {
            self.error = Some(e.into());
            return ControlFlow::Break(());
        }
        let Loader { rt, out, .. } = loader;
        let rt = match rt {
            LoadInto::Owned(rt) => *rt,
            LoadInto::Borrowed(_) => unreachable!("an image reader's loaders own their contexts"),
        };
        match (self.each)(RibImage { index, rt, loaded: out }) {
            Ok(flow) => flow,
            Err(e) => {
                self.error = Some(e);
                ControlFlow::Break(())
            }
        }
    }

    /// The stream ended: an image left open ends with it, and a stream with no image is one, made
    /// of its requests.
    fn end_of_stream(&mut self) {
        if self.frames.numbers.is_empty() {
            self.current = Some(0);
            if !(self.wanted)(0, self.frames.number(0)) {
                return;
            }
        }
        let _ = self.end();
    }
}

impl<E: From<SceneFileError>> RibSink for ImageReader<'_, E> {
    fn request(&mut self, r: Request) -> ControlFlow<()> {
        if let RequestKind::MeshArchive(path) = &r.kind {
            self.files.push(path.clone());
        }
        let Some(index) = self.frames.add(&r) else {
            // Before the first image, its loader takes the request now.
            if let (Some(loader), None) = (&mut self.loader, self.current) {
                if let Err(e) = loader.load(&r) {
                    self.error = Some(e.into());
                    return ControlFlow::Break(());
                }
            }
            if self.shared.len() < MAX_SHARED_REQUESTS {
                self.shared.push(r);
            } else {
                let left_out = self.shared_left_out.get_or_insert_with(|| (r.loc.clone(), 0));
                left_out.1 += 1;
            }
            return ControlFlow::Continue(());
        };
        if self.current != Some(index) {
            // An image that begins before the one being read ended (a `FrameBegin` inside a world
            // block) ends that one, as it does when each image is loaded alone (`load_stream`).
            if self.current.is_some() && self.end().is_break() {
                return ControlFlow::Break(());
            }
            if let Err(e) = self.begin(index) {
                self.error = Some(e.into());
                return ControlFlow::Break(());
            }
        }
        if let Some(loader) = &mut self.loader {
            self.last = Some(r.loc.clone());
            if let Err(e) = loader.load(&r) {
                self.error = Some(e.into());
                return ControlFlow::Break(());
            }
        }
        if self.frames.open() {
            return ControlFlow::Continue(());
        }
        self.end()
    }

    fn takes_diagnostics(&self) -> bool {
        true
    }

    fn diagnostic(&mut self, diagnostic: RibDiagnostic) {
        self.read.push(diagnostic);
    }

    fn archive(&mut self, path: &Path) {
        self.files.push(path.to_path_buf());
    }
}

/// What an image's loading is finished with (`Loader::finish`).
struct ImageEnd {
    /// What reading the stream found (it comes before what loading found).
    read: Vec<RibDiagnostic>,
    /// The archives and mesh files read.
    files: Vec<PathBuf>,
    /// How many images the stream has (so far).
    frames: usize,
    /// The image's number.
    number: i32,
    /// The last request loaded.
    last: Option<Location>,
}

/// The context a [`Loader`] loads into: its caller's, or its own (an image of
/// [`load_file_frames`]).
enum LoadInto<'a> {
    Borrowed(&'a mut Context),
    Owned(Box<Context>),
}

impl Deref for LoadInto<'_> {
    type Target = Context;
    fn deref(&self) -> &Context {
        match self {
            LoadInto::Borrowed(rt) => rt,
            LoadInto::Owned(rt) => rt,
        }
    }
}

impl DerefMut for LoadInto<'_> {
    fn deref_mut(&mut self) -> &mut Context {
        match self {
            LoadInto::Borrowed(rt) => rt,
            LoadInto::Owned(rt) => rt,
        }
    }
}

#[derive(Clone, Default)]
struct State {
    area_light: Option<LightId>,
    mesh_options: MeshOptions,
    /// `Detail`: the raster area of the bound it gave (scaled by `RelativeDetail`).
    detail: Option<f32>,
    /// `DetailRange`: minvisible, lowertransition, uppertransition, maxvisible.
    detail_range: Option<[f32; 4]>,
    /// `Attribute "light" "shadows"`: whether the lights declared from here trace shadow rays. Off
    /// by default, as in RenderMan, where a light shadows only through its shader (`shadow()`,
    /// `transmission()`) or this attribute (BMRT's and PRMan's ray-traced shadows).
    shadows: bool,
    /// The current orientation is "inside" (RISpec `Orientation`; Aqsis's `System` `Orientation` 1): the
    /// outside of the geometry that follows is the side `dPdu x dPdv` (a polygon's `(P1 - P0) x
    /// (P2 - P0)`) points away from in its own space, not the side it points to.
    inside: bool,
}

struct Loader<'a> {
    rt: LoadInto<'a>,
    dir: PathBuf,
    out: LoadedRib,
    state: State,
    stack: Vec<State>,
    /// The `AttributeBegin` and `TransformBegin` blocks open, and those opened past
    /// [`MAX_BLOCK_DEPTH`] (which restore nothing).
    open_blocks: usize,
    blocks_refused: usize,
    reported_deep_blocks: bool,
    /// Geometry gathered for one object: the object and the transform it is placed with.
    pending: Option<(ObjectId, Affine3A, Affine3A)>,
    /// Inside `ObjectBegin`: its handle, and the space its geometry is in.
    retained: Option<(Handle, Affine3A)>,
    /// The API objects of each retained object (more than one when it read a mesh file), each
    /// with what its instances take from the attributes current at `ObjectInstance`.
    objects: HashMap<Handle, Vec<(ObjectId, InheritedAppearance)>>,
    /// What instances of the open `ObjectBegin` block's object take from where they stand: the
    /// attributes the block does not set itself.
    retained_inherits: InheritedAppearance,
    /// Lights by handle, with whether they trace shadows.
    lights: HashMap<Handle, (LightId, bool)>,
    /// World-space emitting triangles per area light.
    area_meshes: HashMap<u32, Vec<Mesh>>,
    in_world: bool,
    /// Whether a `Projection` request was read (RenderMan's default is orthographic).
    projection_given: bool,
    /// `RelativeDetail`.
    relative_detail: f32,
    /// Whether the camera projects orthographically (what camera-facing primitives face).
    orthographic: bool,
    /// Inside `MotionBegin`: how many samples were seen.
    motion: Option<u32>,
    /// Inside `MotionBegin`: the matrices of its transform samples (applied at `MotionEnd`).
    motion_transforms: Vec<(bool, Affine3A)>,
    /// Inside `MotionBegin`: its times, and the meshes of its geometry samples (added at
    /// `MotionEnd`, deforming).
    motion_times: Vec<f32>,
    motion_geometry: Vec<(Request, Mesh)>,
    /// The segments of the block's first `Points` or `Curves` sample, which the later ones take.
    motion_segments: Option<std::sync::Arc<[u32]>>,
    /// Triangles of the geometry requests so far, against [`MAX_RIB_TRIANGLES`].
    triangles: usize,
    /// `ClippingPlane`s given before `WorldBegin`, in camera space (point and normal), moved into
    /// world space there.
    camera_clipping_planes: Vec<(Vec3, Vec3)>,
    /// `Resource "name" "attributes"` saves, by name, in `ResourceBegin` scopes (innermost
    /// last): the context's attributes and the loader's.
    resources: Vec<HashMap<String, (SavedAttributes, State)>>,
    /// `ScopedCoordinateSystem`s of the open attribute blocks: the block depth, the name, and the
    /// matrix the name had before (restored when the block ends).
    scoped_spaces: Vec<(usize, String, Option<Affine3A>)>,
    /// The open `SolidBegin` blocks, innermost last.
    solids: Vec<OpenSolid>,
    /// The nodes of the outermost open solid so far, in postfix order: a block's node follows its
    /// operands' as it ends, so one list serves every level, however deep, with no copying.
    solid_nodes: Vec<SolidNode<InstanceId>>,
}

/// An open `SolidBegin` block.
struct OpenSolid {
    /// `None` for `"primitive"`.
    op: Option<SolidOp>,
    /// A block rtsl does not model (a `SolidBegin` inside a primitive or a retained object): its
    /// `SolidEnd` only closes it.
    ignored: bool,
    /// The geometry of this block faces into it: it is subtracted from something, an odd number
    /// of times.
    inward: bool,
    /// An operation's operands so far (their nodes are in [`Loader::solid_nodes`]).
    operands: u32,
    /// The instances placed since this count belong to the block itself (for a primitive, all of
    /// its instances; for an operation, geometry outside any primitive).
    mark: usize,
    /// The instances of the block's own geometry, built reversed.
    reversed: Vec<InstanceId>,
    /// The `SolidBegin`, for the warning when the stream ends before its `SolidEnd`.
    begin: super::request::Location,
}

impl<'a> Loader<'a> {
    fn new(mut rt: LoadInto<'a>, dir: PathBuf) -> Loader<'a> {
        rt.add_texture_search_path(dir.clone());
        // PRMan's bounces (`Attribute "trace" "maxdiffusedepth"` 1, `"maxspeculardepth"` 2) for
        // what the file builds, where the API bounds only the ray depth.
        let prman = crate::render::TraceDepths::RENDERMAN;
        rt.max_diffuse_depth(prman.diffuse);
        rt.max_specular_depth(prman.specular);
        // PRMan's and 3Delight's `Option "limits" "zthreshold"`: semi-transparent surfaces stay
        // out of depth maps.
        rt.options.depth_threshold = [RENDERMAN_DEPTH_THRESHOLD; 3];
        // RenderMan's 8-bit images hold the values as computed (RISpec's default `Exposure 1 1`)
        // and its textures give the values they store: the lights and colours of a RIB file are
        // set for that, not for sRGB.
        rt.options.image_transfer = crate::image_io::Transfer::Linear;
        // Shaders beside the file are found, as Aqsis's default search path begins with "." (the
        // directory a scene is rendered from): after the directories the application gave, before
        // the library. A RIB `Option "searchpath" "shader"` without `&` replaces it.
        if !rt.shader_search_path().contains(&dir) {
            let mut shaders = rt.shader_search_path().to_vec();
            shaders.push(dir.clone());
            rt.set_shader_search_path(shaders);
        }
        Loader {
            rt,
            dir,
            out: LoadedRib::default(),
            state: State::default(),
            stack: Vec::new(),
            open_blocks: 0,
            blocks_refused: 0,
            reported_deep_blocks: false,
            pending: None,
            retained: None,
            objects: HashMap::new(),
            retained_inherits: InheritedAppearance::ALL,
            lights: HashMap::new(),
            area_meshes: HashMap::new(),
            in_world: false,
            projection_given: false,
            relative_detail: 1.0,
            orthographic: false,
            motion: None,
            motion_transforms: Vec::new(),
            motion_times: Vec::new(),
            motion_geometry: Vec::new(),
            motion_segments: None,
            triangles: 0,
            camera_clipping_planes: Vec::new(),
            resources: vec![HashMap::new()],
            scoped_spaces: Vec::new(),
            solids: Vec::new(),
            solid_nodes: Vec::new(),
        }
    }

    /// Loads one request of a stream: what cannot be loaded is an omission, and only an image too
    /// large to load is an error.
    fn load(&mut self, r: &Request) -> Result<(), SceneFileError> {
        match self.request(r) {
            Ok(()) => Ok(()),
            Err(e @ SceneFileError::TooLarge { .. }) => Err(e),
            Err(e) => {
                self.omit(r, e);
                Ok(())
            }
        }
    }

    /// Finishes loading an image: what is still gathered is added, displays are named for the
    /// frame, and area lights get the geometry that followed them.
    fn finish(&mut self, end: ImageEnd) -> Result<(), SceneFileError> {
        let mut warnings = end.read;
        warnings.append(&mut self.out.warnings);
        self.out.warnings = warnings;
        self.out.files = end.files;
        self.out.frames = end.frames;
        self.out.frame_number = end.number;
        self.flush()?;
        if let Some(loc) = end.last {
            self.end_solids(&Request { kind: RequestKind::WorldEnd, loc })?;
        }
        let number = self.out.frame_number;
        for d in &mut self.out.displays {
            d.name = PathBuf::from(expand_display_name(&d.name.to_string_lossy(), number));
        }
        self.out.display = self.out.displays.iter().find(|d| !d.window).map(|d| d.name.clone());
        // Area lights emit from the geometry that followed them (gathered in world space).
        let area_meshes = std::mem::take(&mut self.area_meshes);
        self.rt.push_matrix();
        self.rt.load_identity();
        for (light, meshes) in area_meshes {
            for m in &meshes {
                self.rt.area_light_geometry(LightId(light), m)?;
            }
        }
        self.rt.pop_matrix()?;
        Ok(())
    }

    fn warn(&mut self, r: &Request, message: impl std::fmt::Display) {
        self.out.warnings.push(RibDiagnostic::warning(&r.loc, message.to_string()));
    }

    /// A warning that what `r` asks for is missing from the picture.
    fn omit(&mut self, r: &Request, message: impl std::fmt::Display) {
        self.out.warnings.push(RibDiagnostic::omission(&r.loc, message.to_string()));
    }

    /// Ends the object that gathers geometry, instancing it where it began.
    fn flush(&mut self) -> Result<(), ApiError> {
        if let Some((id, placed, close)) = self.pending.take() {
            self.rt.end_object()?;
            let (now, now_close) = (self.rt.current_matrix(), self.rt.close_matrix());
            self.rt.load_matrix(placed);
            let inst = self.rt.instantiate_object(id)?;
            if self.builds_reversed() {
                if let Some(solid) = self.solids.iter_mut().rev().find(|s| !s.ignored) {
                    solid.reversed.push(inst);
                }
            }
            if close != placed {
                self.rt.set_instance_motion(inst, placed, close)?;
            }
            self.rt.load_matrix(now);
            if now_close != now {
                self.rt.motion_transform(Affine3A::IDENTITY, now.inverse() * now_close);
            }
        }
        Ok(())
    }

    /// An error at `r` when `more` triangles would take the load's past [`MAX_RIB_TRIANGLES`].
    fn check_triangles(&self, r: &Request, more: usize) -> Result<(), SceneFileError> {
        if self.triangles.saturating_add(more) > MAX_RIB_TRIANGLES {
            return Err(SceneFileError::TooLarge {
                at: r.loc.to_string(),
                message: format!(
                    "the scene's geometry passes {MAX_RIB_TRIANGLES} triangles with this request's {more} \
                     (quadrics, patches, subdivision meshes, points and curves count as tessellated); rtsl \
                     loads no more from one RIB file"
                ),
            });
        }
        Ok(())
    }

    /// The camera as the geometry request about to be built sees it: the current transform, and the
    /// camera set at `WorldBegin` with the projection and screen window now in force.
    fn view(&self) -> View {
        let camera = self.rt.camera();
        let world_from_camera = camera.world_from_camera;
        let half = self.rt.options.screen_extent().half;
        // The shorter side of the screen window, in screen units (1 by default).
        let shorter = half.0.abs().min(half.1.abs());
        let projection = if self.orthographic {
            let unit = world_from_camera.matrix3.y_axis.length();
            Projection::Orthographic { forward: world_from_camera.matrix3.z_axis.into(), across: 2.0 * shorter * unit }
        } else {
            let tan = (0.5 * camera.fov_degrees.to_radians()).tan();
            Projection::Perspective { eye: world_from_camera.translation.into(), across: 2.0 * (tan * shorter).atan() }
        };
        View { world_from_object: self.rt.current_matrix(), projection }
    }

    /// Whether the current transform, from the current space to camera space, mirrors (its
    /// determinant is negative): camera space is left-handed, so the current space is then
    /// right-handed.
    fn mirrors_camera_space(&self) -> bool {
        let current = self.rt.current_matrix().matrix3.determinant();
        // Before `WorldBegin` the current transform is camera from current space.
        let camera = if self.in_world { self.rt.camera().world_from_camera.matrix3.determinant() } else { 1.0 };
        current * camera < 0.0
    }

    /// The mesh of geometry request `r` (`None`: nothing to add, its diagnostics reported).
    fn tessellate(&mut self, r: &Request) -> Result<Option<Mesh>, SceneFileError> {
        self.state.mesh_options.view = self.view();
        // Refused before it is tessellated: one patch mesh can ask for more than the limit. A
        // blobby's own limits bound its mesh, whose size only sampling its field tells: it is
        // counted once built.
        let blobby = matches!(r.kind, RequestKind::Blobby { .. });
        if !blobby {
            self.check_triangles(r, request_triangles(r, &self.state.mesh_options))?;
        }
        let mut diags = Vec::new();
        let mesh = mesh_from_request_with(r, &self.state.mesh_options, &mut diags);
        if let Some(mesh) = mesh.as_ref().filter(|_| blobby) {
            self.check_triangles(r, mesh.triangle_count())?;
        }
        // A primitive that could not be built is missing from the picture.
        self.out.warnings.extend(diags.into_iter().map(|d| match d.severity {
            Severity::Error => RibDiagnostic { severity: Severity::Omission, ..d },
            _ => d,
        }));
        Ok(mesh.filter(|m| !m.triangles.is_empty()))
    }

    /// `MotionEnd` of a block of geometry samples: the first sample deforming into the last
    /// (rtsl's motion is linear, as for transforms), given the block's times.
    fn deforming_geometry(&mut self, samples: Vec<(Request, Mesh)>, times: &[f32]) -> Result<(), SceneFileError> {
        let mut samples = samples.into_iter();
        let Some((r, mut first)) = samples.next() else { return Ok(()) };
        let Some((last_r, last)) = samples.last() else { return self.geometry(&r, first) };
        let (open, close) = (times.first().copied().unwrap_or(0.0), times.last().copied().unwrap_or(1.0));
        let same_kind = match (&r.kind, &last_r.kind) {
            (RequestKind::Quadric { quadric: a, .. }, RequestKind::Quadric { quadric: b, .. }) => {
                std::mem::discriminant(a) == std::mem::discriminant(b)
            }
            (a, b) => std::mem::discriminant(a) == std::mem::discriminant(b),
        };
        let same_topology = first.triangles == last.triangles
            && first.positions.len() == last.positions.len()
            && first.normals.is_some() == last.normals.is_some();
        if !(same_kind && same_topology) {
            self.omit(
                &last_r,
                "the samples of this motion block are not one primitive changing shape (another request, or \
                 another number of vertices or faces once tessellated): no deformation blur, the first sample \
                 is rendered",
            );
            return self.geometry(&r, first);
        }
        if open.partial_cmp(&close) != Some(std::cmp::Ordering::Less) {
            self.warn(
                &r,
                format_args!("MotionBegin times {open} and {close} do not increase: the first sample is rendered"),
            );
            return self.geometry(&r, first);
        }
        first.deformation = Some(Deformation { positions: last.positions, normals: last.normals, open, close });
        // An object of its own, so that deformations of other intervals never share one.
        self.flush()?;
        self.geometry(&r, first)?;
        self.flush()?;
        Ok(())
    }

    fn geometry(&mut self, r: &Request, mut mesh: Mesh) -> Result<(), SceneFileError> {
        self.check_triangles(r, mesh.triangles.len())?;
        self.triangles += mesh.triangles.len();
        if let Some(light) = self.state.area_light {
            let m = self.rt.current_matrix();
            let mut world = mesh.clone();
            for p in &mut world.positions {
                *p = m.transform_point3(*p);
            }
            self.area_meshes.entry(light.0).or_default().push(world);
        }
        if self.retained.is_none() && self.pending.is_none() {
            let id = self.rt.begin_object()?;
            self.pending = Some((id, self.rt.current_matrix(), self.rt.close_matrix()));
        }
        // The object's triangles wind so that their normal points outside in its own space, as
        // one-sided culling and interior volumes read them: reversed where the orientation is
        // "inside", or where the geometry is mirrored into the object's space.
        let base = match (&self.pending, &self.retained) {
            (Some((_, placed, _)), _) => *placed,
            (None, Some((_, frame))) => *frame,
            (None, None) => self.rt.current_matrix(),
        };
        let mirrored = base.matrix3.determinant() * self.rt.current_matrix().matrix3.determinant() < 0.0;
        // A subtracted part of a solid faces into the part it is subtracted from (RISpec: "the
        // sense of the orientation of the surfaces being subtracted is automatically reversed"),
        // its shading normals too.
        let subtracted = self.retained.is_none() && self.builds_reversed();
        if (self.state.inside != mirrored) != subtracted {
            for t in &mut mesh.triangles {
                t.swap(1, 2);
            }
        }
        // Normals the surface defines (a patch's, a quadric's: dPdu x dPdv) point to the outside the
        // orientation names, as in RenderMan, where "inside" reverses N; normals the request gives
        // with "N" are kept as given. (A mirroring transform moves normals by its inverse
        // transpose, which keeps their side: it changes only the triangles' winding.)
        let given = geometry_params(&r.kind).iter().any(|p| p.name == "N");
        if (self.state.inside && !given) != subtracted {
            let close = mesh.deformation.as_mut().and_then(|d| d.normals.as_mut());
            for n in mesh.normals.iter_mut().flatten().chain(close.into_iter().flatten()) {
                *n = -*n;
            }
        }
        match self.rt.mesh(&mesh) {
            Ok(()) => Ok(()),
            Err(ApiError::DeformationTimes { .. }) => {
                // Only a retained object gathers deformations of several motion blocks.
                self.warn(
                    r,
                    "this retained object already deforms over other MotionBegin times: this geometry stands still",
                );
                mesh.deformation = None;
                self.rt.mesh(&mesh).inspect_err(|_| self.omit(r, "geometry skipped"))?;
                Ok(())
            }
            Err(e) => {
                self.omit(r, "geometry skipped");
                Err(e.into())
            }
        }
    }

    /// [`Self::geometry`] of a request whose parameter list may hold values for the whole
    /// primitive ([`primitive_constants`]): RISpec passes them to the primitive's shaders, so the
    /// primitive becomes an object of its own whose surface and displacement shaders have them as
    /// parameter values (point-like ones in the current space), and `Cs` and `Os` as its colour
    /// and opacity, as `Color` and `Opacity` would give it. Names no shader has are left unused,
    /// as RenderMan leaves them.
    fn geometry_with_constants(&mut self, r: &Request, mesh: Mesh) -> Result<(), SceneFileError> {
        // RISpec: a primitive variable needs a declaration (`Declare`, or inline) to have a class
        // and a size; without one it could be data of any kind, and none is made of it.
        for p in geometry_params(&r.kind).iter().filter(|p| p.decl.class == Class::Implicit && p.name != "type") {
            let message = format!(
                "\"{}\" is not declared (Declare it, or write its class and type, e.g. \"varying float {}\"): it is ignored",
                p.name, p.name
            );
            self.out.warnings.push(RibDiagnostic::warning(&p.loc, message));
        }
        // Only values some shader (or the colour) takes split the primitive off: exporters attach
        // names and ids to every primitive.
        let shaders: Vec<_> = [self.rt.bound_surface(), self.rt.bound_displacement()]
            .into_iter()
            .flatten()
            .filter_map(|id| self.rt.program(id).ok().cloned())
            .collect();
        let constants: Vec<&Param> = primitive_constants(&r.kind)
            .into_iter()
            .filter(|p| {
                matches!(p.name.as_str(), "Cs" | "Os")
                    || shaders.iter().any(|s| s.interface.parameters.iter().any(|i| i.name == p.name))
            })
            .collect();
        if constants.is_empty() {
            return self.geometry(r, mesh);
        }
        if self.retained.is_some() {
            self.warn(
                r,
                "values for the whole primitive (constant, or uniform on one face) are not passed to shaders \
                 inside ObjectBegin: a retained object has one set of shader parameters",
            );
            return self.geometry(r, mesh);
        }
        self.flush()?;
        self.rt.push_attributes();
        self.apply_constants(&constants);
        let built = self.geometry(r, mesh);
        let flushed = self.flush();
        self.rt.pop_attributes()?;
        built?;
        Ok(flushed?)
    }

    /// Gives the attribute state the values of [`primitive_constants`]: a parameter of the bound
    /// surface or displacement shader of that name takes its value; one of the wrong type or count
    /// is a warning at its name.
    fn apply_constants(&mut self, constants: &[&Param]) {
        for p in constants {
            let expected = p.decl.array_len.unwrap_or(1);
            if p.value_count() != expected {
                let message = format!(
                    "\"{}\" ({}) has {} values where a value for the whole primitive needs {expected}: it is dropped",
                    p.name,
                    p.decl,
                    p.value_count()
                );
                self.out.warnings.push(RibDiagnostic::warning(&p.loc, message));
                continue;
            }
            match (p.name.as_str(), p.floats(), p.decl.ty) {
                ("Cs", Some(c), Ty::Color) => self.rt.color(c[0], c[1], c[2]),
                ("Os", Some(c), Ty::Color) => self.rt.opacity(c[0], c[1], c[2]),
                _ => {}
            }
            let shaders = [(false, self.rt.bound_surface()), (true, self.rt.bound_displacement())];
            for (displacement, id) in shaders {
                let Some(program) = id.and_then(|id| self.rt.program(id).ok()).cloned() else { continue };
                if !program.interface.parameters.iter().any(|i| i.name == p.name) {
                    continue;
                }
                let set = match shader_value(p, &program) {
                    Some(v) if displacement => self.rt.displacement_parameters(&[(p.name.as_str(), v)]),
                    Some(v) => self.rt.parameter(&p.name, v),
                    None => {
                        let message = format!("cannot pass {} to a shader", p.name);
                        self.out.warnings.push(RibDiagnostic::warning(&p.loc, message));
                        continue;
                    }
                };
                if let Err(e) = set {
                    self.out.warnings.push(RibDiagnostic::warning(&p.loc, e.to_string()));
                }
            }
        }
    }

    fn request(&mut self, r: &Request) -> Result<(), SceneFileError> {
        use RequestKind as K;
        if self.retained.is_some() {
            keep_what_the_block_sets(&r.kind, &mut self.retained_inherits);
        }
        let placed = is_geometry(&r.kind) || matches!(r.kind, K::ObjectInstance(_) | K::MeshArchive(_));
        if placed && !self.detail_chosen() {
            return Ok(());
        }
        // Motion blocks: transforms become a motion transform at `MotionEnd` (the first and last
        // samples: rtsl's motion is linear), geometry a deforming mesh; of other requests only the
        // first sample is used.
        if self.motion.is_some() && is_geometry(&r.kind) {
            // Later samples take the first's tessellation, so that every vertex has its counterpart:
            // a quadric's at equal (u, v) whatever the sweep (the surface blends point by point
            // between the samples' parametric surfaces), points' and curves' whatever their size on
            // screen.
            let chosen = self.state.mesh_options.tessellation;
            match (self.motion_geometry.first().map(|(first, _)| &first.kind), &r.kind) {
                (Some(K::Quadric { quadric, .. }), K::Quadric { .. }) => {
                    self.state.mesh_options.tessellation =
                        Some(chosen.unwrap_or_else(|| quadric.default_tessellation()))
                }
                (Some(_), K::Points(_) | K::Curves { .. }) => {
                    self.state.mesh_options.segments = self.motion_segments.clone()
                }
                (None, K::Points(_) | K::Curves { .. }) => {
                    self.state.mesh_options.view = self.view();
                    self.motion_segments = request_segments(r, &self.state.mesh_options);
                }
                _ => {}
            }
            let mesh = self.tessellate(r);
            self.state.mesh_options.tessellation = chosen;
            self.state.mesh_options.segments = None;
            if let Some(mesh) = mesh? {
                self.motion_geometry.push((r.clone(), mesh));
            }
            return Ok(());
        }
        if self.motion.is_some() {
            let sample = match &r.kind {
                K::Translate(t) => Some((false, Affine3A::from_translation(Vec3::new(t[0], t[1], t[2])))),
                K::Rotate { angle, axis } => {
                    let axis = Vec3::new(axis[0], axis[1], axis[2]).normalize_or_zero();
                    (axis != Vec3::ZERO).then(|| (false, Affine3A::from_axis_angle(axis, angle.to_radians())))
                }
                K::Scale(v) if !v.contains(&0.0) => Some((false, Affine3A::from_scale(Vec3::new(v[0], v[1], v[2])))),
                K::ConcatTransform(m) => Some((false, affine(m))),
                K::Transform(m) => Some((true, affine(m))),
                _ => None,
            };
            if let Some(sample) = sample {
                self.motion_transforms.push(sample);
                return Ok(());
            }
        }
        if let (K::MotionEnd, Some(_)) = (&r.kind, self.motion) {
            let (geometry, times) = (std::mem::take(&mut self.motion_geometry), std::mem::take(&mut self.motion_times));
            self.motion_segments = None;
            self.deforming_geometry(geometry, &times)?;
            let samples = std::mem::take(&mut self.motion_transforms);
            if let (Some(&(absolute, open)), Some(&(_, close))) = (samples.first(), samples.last()) {
                self.flush()?;
                if absolute {
                    self.rt.load_matrix(open);
                    self.rt.motion_transform(Affine3A::IDENTITY, open.inverse() * close);
                } else {
                    self.rt.motion_transform(open, close);
                }
            }
        }
        if let Some(seen) = self.motion.as_mut() {
            if !matches!(r.kind, K::MotionEnd) {
                *seen += 1;
                if *seen > 1 {
                    return Ok(());
                }
            }
        }
        let geometry_or_transform = is_geometry(&r.kind)
            || matches!(
                r.kind,
                K::Translate(_)
                    | K::Rotate { .. }
                    | K::Scale(_)
                    | K::ConcatTransform(_)
                    | K::Transform(_)
                    | K::Identity
                    | K::TransformBegin
                    | K::TransformEnd
                    | K::Skew(_)
            );
        if !geometry_or_transform {
            self.flush()?;
        }
        let rt = &mut *self.rt;
        match &r.kind {
            K::Version(_) | K::Declare { .. } => {}
            K::ShadingRate(area) if area.is_finite() && *area > 0.0 => rt.shading_rate(*area),
            K::ShadingRate(area) => {
                self.warn(r, format_args!("ShadingRate {area}: a shading rate is an area above 0; it stays as it was"))
            }
            K::Matte(on) => rt.matte(*on),
            K::Sides(1) => rt.one_sided(true),
            K::Sides(2) => rt.one_sided(false),
            K::Sides(n) => self.warn(r, format_args!("Sides {n}: a surface has 1 or 2 sides; ignored")),
            K::Hider(h) => {
                for p in &h.params {
                    match (p.name.as_str(), p.strings().and_then(|s| s.first()).map(String::as_str)) {
                        ("depthfilter", Some("min")) => self.rt.options.depth_filter = crate::render::DepthFilter::Min,
                        ("depthfilter", Some("midpoint")) => {
                            self.rt.options.depth_filter = crate::render::DepthFilter::Midpoint
                        }
                        ("depthfilter", Some("max")) => self.rt.options.depth_filter = crate::render::DepthFilter::Max,
                        ("depthfilter", other) => self.warn(
                            r,
                            format_args!(
                                "Hider \"depthfilter\" {}: rtsl has \"min\", \"midpoint\" and \"max\"; the depth stays the nearest \
                                 surface's",
                                other.map_or("without a string".to_string(), |s| format!("\"{s}\""))
                            ),
                        ),
                        _ => {}
                    }
                }
            }
            K::ShadingInterpolation(_) | K::GeometricRepresentation(_) | K::Bound(_) => {}
            // The reader evaluates conditionals; a list built by hand may still hold them.
            K::IfBegin(_) | K::ElseIf(_) | K::Else | K::IfEnd => {}
            K::TextureCoordinates(st) => self.state.mesh_options.texture_coordinates = *st,
            K::MotionBegin(times) => {
                self.motion = Some(0);
                self.motion_times = times.clone();
            }
            K::MotionEnd => self.motion = None,
            K::SolidBegin(operation) => self.solid_begin(r, operation),
            K::SolidEnd => self.solid_end(r)?,
            // As Aqsis keeps it: "rh" and "lh" are "outside" or "inside" by the handedness of the
            // current transform when they are given.
            K::Orientation(o) => {
                self.state.inside = match o {
                    Orientation::Outside => false,
                    Orientation::Inside => true,
                    Orientation::RightHanded => !self.mirrors_camera_space(),
                    Orientation::LeftHanded => self.mirrors_camera_space(),
                }
            }
            K::ReverseOrientation => self.state.inside = !self.state.inside,
            K::Format { xres, yres, .. } => {
                // Kept as given (a size too large is refused when the frame is built, unless
                // `--size` replaces it).
                rt.options.width = (*xres).max(1) as u32;
                rt.options.height = (*yres).max(1) as u32;
            }
            K::PixelSamples { x, y } => {
                let most = MAX_PIXEL_SAMPLES as f32;
                rt.options.samples = (x.round().clamp(1.0, most) as u32, y.round().clamp(1.0, most) as u32);
            }
            K::Projection(p) => {
                self.projection_given = true;
                self.orthographic = p.name == "orthographic";
                match p.name.as_str() {
                    "perspective" => {
                        let fov = p.params.iter().find(|q| q.name == "fov").and_then(|q| q.floats()?.first().copied());
                        let mut cam = *rt.camera();
                        cam.fov_degrees = fov.unwrap_or(90.0).clamp(0.01, 179.0);
                        rt.set_camera(cam);
                    }
                    // The library's camera shader, as `DepthOfField` binds `thinlens`.
                    "orthographic" => {
                        let id = rt.find_shader("orthographic")?;
                        rt.camera_shader(Some(id), &[])?;
                    }
                    other => self.warn(r, format_args!("projection \"{other}\" is not supported; perspective is used")),
                }
            }
            // RISpec: what lies on the side the normal points to is clipped from the scene.
            K::ClippingPlane(v) => {
                let (p, n) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
                if n == Vec3::ZERO || !p.is_finite() || !n.is_finite() {
                    self.warn(r, "ClippingPlane needs a finite point and a normal that is not zero; ignored");
                } else {
                    let (p, n) = place_plane(rt.current_matrix(), p, n);
                    if self.in_world {
                        rt.options.clipping_planes.push([p.x, p.y, p.z, n.x, n.y, n.z]);
                    } else {
                        self.camera_clipping_planes.push((p, n));
                    }
                }
            }
            K::Clipping { near, far } => {
                let mut cam = *rt.camera();
                cam.near = *near;
                cam.far = *far;
                rt.set_camera(cam);
            }
            K::Display { name, driver, mode, .. } => self.display(r, name, driver, mode),
            K::Detail(bound) => self.state.detail = Some(self.raster_area(bound) * self.relative_detail),
            K::DetailRange(range) => self.state.detail_range = Some(*range),
            K::RelativeDetail(scale) => self.relative_detail = scale.max(0.0),
            K::Quantize { ty, one, min, max, dither } => match ty.as_str() {
                "rgba" => {
                    rt.options.quantize =
                        Some(crate::image_io::Quantize { one: *one, min: *min, max: *max, dither: *dither })
                }
                // Depth is always stored as floats.
                "z" => {}
                other => self.warn(r, format_args!("Quantize \"{other}\": the type is \"rgba\" or \"z\"")),
            },
            K::Exposure { gain, gamma } => rt.options.exposure = Some((*gain, *gamma)),
            K::FrameBegin(_) | K::FrameEnd => {}
            K::WorldBegin => {
                // RenderMan's projection when none is given is orthographic (RISpec 3.2, 4.1.2).
                if !self.projection_given && rt.camera_shader_id().is_none() {
                    let id = rt.find_shader("orthographic")?;
                    rt.camera_shader(Some(id), &[])?;
                    self.orthographic = true;
                }
                // The transform now is world-to-camera.
                let m = rt.current_matrix();
                let mut cam = *rt.camera();
                cam.world_from_camera = m.inverse();
                rt.set_camera(cam);
                for (p, n) in std::mem::take(&mut self.camera_clipping_planes) {
                    let (p, n) = place_plane(cam.world_from_camera, p, n);
                    rt.options.clipping_planes.push([p.x, p.y, p.z, n.x, n.y, n.z]);
                }
                rt.load_identity();
                self.in_world = true;
            }
            K::WorldEnd => self.end_solids(r)?,
            K::AttributeBegin | K::TransformBegin if self.open_blocks >= MAX_BLOCK_DEPTH => {
                self.blocks_refused += 1;
                if !self.reported_deep_blocks {
                    self.reported_deep_blocks = true;
                    let message = format!(
                        "attribute and transform blocks nest deeper than {MAX_BLOCK_DEPTH}: the requests of \
                         this block, and of any other past the limit (not reported), apply to the block around it"
                    );
                    self.omit(r, message);
                }
            }
            K::AttributeEnd | K::TransformEnd if self.blocks_refused > 0 => self.blocks_refused -= 1,
            K::AttributeBegin => {
                rt.push_attributes();
                self.stack.push(self.state.clone());
                self.open_blocks += 1;
            }
            K::AttributeEnd => {
                rt.pop_attributes()?;
                self.open_blocks = self.open_blocks.saturating_sub(1);
                self.state = self.stack.pop().unwrap_or_default();
                while let Some((depth, name, outer)) = self.scoped_spaces.pop() {
                    if depth <= self.stack.len() {
                        self.scoped_spaces.push((depth, name, outer));
                        break;
                    }
                    if outer.is_some() {
                        self.rt.set_coordinate_system(&name, outer);
                    }
                }
            }
            K::TransformBegin => {
                rt.push_matrix();
                self.open_blocks += 1;
            }
            K::TransformEnd => {
                rt.pop_matrix()?;
                self.open_blocks = self.open_blocks.saturating_sub(1);
            }
            K::Identity => rt.load_identity(),
            K::Transform(m) => rt.load_matrix(affine(m)),
            K::ConcatTransform(m) => rt.mult_matrix(affine(m)),
            K::Translate(t) => rt.translate(t[0], t[1], t[2]),
            K::Rotate { angle, axis } => rt.rotate(*angle, axis[0], axis[1], axis[2]),
            K::Scale(s) => {
                if s.contains(&0.0) {
                    self.warn(r, "a zero scale is ignored");
                } else {
                    rt.scale(s[0], s[1], s[2]);
                }
            }
            K::Skew(s) => match skew(s) {
                Some(m) => rt.mult_matrix(m),
                None => self.warn(
                    r,
                    "Skew needs two axes that are not parallel and an angle less than the one between them; ignored",
                ),
            },
            K::Perspective(_) => {
                self.warn(r, "Perspective (a projective transform) cannot place geometry in rtsl and is ignored")
            }
            K::CoordinateSystem(name) => rt.coordinate_system(name),
            // Named spaces are looked up as the frame renders, one matrix a name: the scoped one
            // is kept after its block unless the name meant another space before it, which is
            // then restored (and this block's shaders see that one).
            K::ScopedCoordinateSystem(name) => {
                let outer = rt.coordinate_system_matrix(name);
                rt.coordinate_system(name);
                // Outside any attribute block it is `CoordinateSystem`.
                if !self.stack.is_empty() {
                    if outer.is_some() {
                        self.warn(
                            r,
                            format_args!(
                                "\"{name}\" already names a space, which is back when this block ends: shaders look \
                                 named spaces up as the frame renders, so this block's see that one"
                            ),
                        );
                    }
                    self.scoped_spaces.push((self.stack.len(), name.clone(), outer));
                }
            }
            K::ResourceBegin => self.resources.push(HashMap::new()),
            K::ResourceEnd => {
                if self.resources.len() > 1 {
                    self.resources.pop();
                } else {
                    self.warn(r, "ResourceEnd without ResourceBegin");
                }
            }
            K::Resource { name, ty, params } => self.resource(r, name, ty, params),
            K::CoordSysTransform(name) => {
                if !rt.load_coordinate_system(name) {
                    if matches!(name.as_str(), "screen" | "NDC" | "raster") {
                        self.warn(
                            r,
                            format_args!(
                                "CoordSysTransform to the projective space \"{name}\" is not supported: the transform is left as it was"
                            ),
                        );
                    } else {
                        self.warn(r, format_args!("no coordinate system named \"{name}\""));
                    }
                }
            }
            K::Surface(s) => {
                let id = rt.find_shader(&s.name)?;
                rt.bind_shader(id)?;
                let program = rt.program(id)?.clone();
                for p in &s.params {
                    match shader_value(p, &program) {
                        Some(v) => {
                            if let Err(e) = rt.parameter(&p.name, v) {
                                self.out.warnings.push(RibDiagnostic::warning(&p.loc, e.to_string()));
                            }
                        }
                        None => {
                            let message = format!("cannot pass {} to a shader", p.name);
                            self.out.warnings.push(RibDiagnostic::warning(&p.loc, message))
                        }
                    }
                }
            }
            // The null light adds nothing; `Illuminate` of its handle then names no light.
            K::LightSource { shader, .. } | K::AreaLightSource { shader, .. } if is_null(&shader.name) => {}
            K::LightSource { shader, handle } | K::AreaLightSource { shader, handle } => {
                let area = matches!(r.kind, K::AreaLightSource { .. });
                let id = rt.find_shader(&shader.name)?;
                let program = rt.program(id)?.clone();
                // A parameter the light lacks, or of the wrong type, is skipped with a warning.
                let kept = typed_params(&program, &shader.params, |_| &r.loc, &mut self.out.warnings);
                let light = rt.light_source(id, &kept)?;
                rt.set_light(light, true, self.state.shadows)?;
                if let Some(h) = handle {
                    self.lights.insert(h.clone(), (light, self.state.shadows));
                }
                if area {
                    self.state.area_light = Some(light);
                }
            }
            K::Illuminate { light, on } => match self.lights.get(light) {
                Some(&(id, shadows)) => self.rt.set_light(id, *on, shadows)?,
                None => self.warn(r, "Illuminate names no light"),
            },
            K::Color(c) => rt.color(c[0], c[1], c[2]),
            K::Opacity(o) => rt.opacity(o[0], o[1], o[2]),
            K::Attribute(a) => self.attribute(r, &a.name, &a.params),
            K::Option(o) => self.option(r, &o.name, &o.params),
            K::Basis { u, ustep, v, vstep } => {
                self.state.mesh_options.u_basis = u.clone();
                self.state.mesh_options.u_step = *ustep;
                self.state.mesh_options.v_basis = v.clone();
                self.state.mesh_options.v_step = *vstep;
            }
            K::Polygon(_)
            | K::GeneralPolygon { .. }
            | K::PointsPolygons { .. }
            | K::PointsGeneralPolygons { .. }
            | K::Patch { .. }
            | K::PatchMesh { .. }
            | K::Quadric { .. }
            | K::SubdivisionMesh { .. }
            | K::NuPatch { .. }
            | K::Geometry { .. }
            | K::Points(_)
            | K::Curves { .. }
            | K::Blobby { .. } => {
                if let Some(mesh) = self.tessellate(r)? {
                    self.geometry_with_constants(r, mesh)?;
                }
            }
            // Attribute state: it trims the NuPatches that follow in the block.
            K::TrimCurve(t) => match super::trim::trim_from_request(t) {
                Ok(trim) => self.state.mesh_options.trim = trim.map(std::sync::Arc::new),
                Err(e) => self.omit(r, format_args!("TrimCurve skipped: {e}")),
            },
            K::ObjectBegin(h) => {
                let frame = rt.current_matrix();
                let id = rt.begin_object()?;
                self.objects.insert(h.clone(), vec![(id, InheritedAppearance::ALL)]);
                self.retained = Some((h.clone(), frame));
                self.retained_inherits = InheritedAppearance::ALL;
            }
            K::ObjectEnd => {
                if let Some((h, _)) = self.retained.take() {
                    rt.end_object()?;
                    // RenderMan's instances take the attributes current at `ObjectInstance`,
                    // except those the object's block set (PRMan's ObjectBegin starts from none).
                    let inherits = self.retained_inherits;
                    for (_, own) in self.objects.entry(h).or_default().iter_mut() {
                        if *own != InheritedAppearance::NONE {
                            *own = inherits;
                        }
                    }
                } else {
                    self.warn(r, "ObjectEnd without ObjectBegin");
                }
            }
            K::ObjectInstance(h) => match self.objects.get(h) {
                Some(ids) => {
                    for &(id, inherited) in ids {
                        rt.instantiate_object_inheriting(id, inherited)?;
                    }
                }
                None => self.omit(r, "ObjectInstance names no object"),
            },
            K::MakeShadow { picture, shadow } => {
                let (from, to) = (self.dir.join(picture), self.dir.join(shadow));
                rt.file_written(&to);
                if let Err(e) = crate::texture::make_shadow(&from, &to) {
                    self.omit(r, format_args!("MakeShadow: {e}"));
                }
            }
            // Resampled into the latitude-longitude map `environment()` reads.
            K::MakeCubeFaceEnvironment { faces, texture, fov, .. } => {
                let paths = faces.clone().map(|f| self.dir.join(f));
                let faces = paths.each_ref().map(|p| p.as_path());
                let raw = rt.options.textures_as_stored();
                rt.file_written(&self.dir.join(texture));
                if let Err(e) = crate::texture::make_cube_face_environment(faces, &self.dir.join(texture), *fov, raw) {
                    self.omit(r, format_args!("MakeCubeFaceEnvironment: {e}"));
                }
            }
            K::MakeTexture { picture, texture, swrap, twrap, .. } => {
                let wrap = |w: &str| match w {
                    "black" => crate::texture::Wrap::Black,
                    "clamp" => crate::texture::Wrap::Clamp,
                    _ => crate::texture::Wrap::Periodic,
                };
                let raw = rt.options.textures_as_stored();
                let opts = crate::texture::MakeTextureOptions { swrap: wrap(swrap), twrap: wrap(twrap), raw };
                rt.file_written(&self.dir.join(texture));
                if let Err(e) = crate::texture::make_texture(self.dir.join(picture), self.dir.join(texture), &opts) {
                    self.omit(r, e);
                }
            }
            K::Imager(s) | K::Pixel(s) if is_null(&s.name) => rt.pixel_shader(None, &[])?,
            K::Imager(s) | K::Pixel(s) => {
                let id = rt.find_shader(&s.name)?;
                let program = rt.program(id)?.clone();
                let given = background_color_alias(&program, &s.params);
                let params = typed_params(&program, &given, |p| &p.loc, &mut self.out.warnings);
                rt.pixel_shader(Some(id), &params)?;
            }
            K::Camera(s) => {
                // PRMan's `RiCamera` (`Camera "world" "float[2] shutteropening" [0 1]`, in every
                // RenderMan for Maya file) names the camera description for later use, where rtsl's
                // `Camera` binds a camera shader: known by its parameters, with no shader of its
                // name, it changes nothing.
                let names_a_description = s.params.iter().any(|p| PRMAN_CAMERA_PARAMETERS.contains(&p.name.as_str()));
                let id = match rt.find_shader(&s.name) {
                    Err(_) if names_a_description => return Ok(()),
                    found => found?,
                };
                self.orthographic = s.name == "orthographic";
                let program = rt.program(id)?.clone();
                let params = typed_params(&program, &s.params, |p| &p.loc, &mut self.out.warnings);
                rt.camera_shader(Some(id), &params)?;
            }
            K::DepthOfField(dof) => {
                rt.options.depth_of_field = Some(*dof);
                // RenderMan's standard camera has depth of field; ours is the thinlens shader.
                if rt.camera_shader_id().is_none() {
                    let id = rt.find_shader("thinlens")?;
                    rt.camera_shader(Some(id), &[])?;
                }
            }
            K::Shutter([open, close]) => rt.options.shutter = (*open, *close),
            K::Atmosphere(s) | K::Interior(s) | K::Displacement(s) => {
                // An empty name, or RenderMan's null shader, removes the binding.
                let (id, params) = if is_null(&s.name) {
                    (None, Vec::new())
                } else {
                    let id = rt.find_shader(&s.name)?;
                    let program = rt.program(id)?.clone();
                    (Some(id), typed_params(&program, &s.params, |p| &p.loc, &mut self.out.warnings))
                };
                match r.kind {
                    K::Atmosphere(_) => rt.atmosphere(id, &params)?,
                    K::Interior(_) => rt.interior(id, &params)?,
                    _ => {
                        rt.displacement(id, &params)?;
                    }
                }
            }
            K::Exterior(s) if is_null(&s.name) => {}
            K::Exterior(s) => self
                .omit(r, format_args!("shader \"{}\": this shader type is not rendered yet, so it is ignored", s.name)),
            K::ScreenWindow(window) => rt.options.screen_window = Some(*window),
            K::FrameAspectRatio(a) => rt.options.frame_aspect_ratio = Some(*a),
            K::CropWindow(window) => {
                let [x0, x1, y0, y1] = window.map(|v| v.clamp(0.0, 1.0));
                // Not a finite, non-empty part of the image: an empty render would pass unnoticed.
                if x0 < x1 && y0 < y1 {
                    rt.options.crop_window = Some(*window);
                } else {
                    let [a, b, c, d] = window;
                    self.omit(r, format_args!("CropWindow {a} {b} {c} {d} covers no part of the image; it is ignored"));
                }
            }
            K::PixelFilter { filter, xwidth, ywidth } => self.pixel_filter(r, filter, *xwidth, *ywidth),
            K::MeshArchive(path) => match self.retained.clone() {
                None => {
                    self.flush()?;
                    add_model_file(&mut self.rt, path)?;
                }
                Some((handle, frame)) => {
                    // The file's objects join the retained one; the block's own geometry goes on
                    // into a fresh object, whatever became of the file.
                    self.rt.end_object()?;
                    let mut ids = Vec::new();
                    let added =
                        add_model_file_placed(&mut self.rt, path, Placement::Retained { frame, objects: &mut ids });
                    // The file's objects are shaded with its materials; the block's own geometry
                    // with the attributes where it is instanced.
                    let own = self.rt.begin_object_in(frame)?;
                    let entries = ids
                        .into_iter()
                        .map(|id| (id, InheritedAppearance::NONE))
                        .chain([(own, InheritedAppearance::ALL)]);
                    self.objects.entry(handle).or_default().extend(entries);
                    added?;
                }
            },
        }
        Ok(())
    }

    /// Whether geometry built now is a subtracted part of a solid: the innermost solid block that
    /// counts (blocks ignored inside a primitive are part of it) is a primitive that faces inward.
    fn builds_reversed(&self) -> bool {
        self.solids.iter().rev().find(|s| !s.ignored).is_some_and(|s| s.op.is_none() && s.inward)
    }

    /// `SolidBegin`: a primitive solid, whose geometry closes a volume, or a set operation on the
    /// solids of the blocks it holds.
    fn solid_begin(&mut self, r: &Request, operation: &str) {
        let op = match operation {
            "primitive" => None,
            other => Some(SolidOp::from_name(other).unwrap_or_else(|| {
                self.warn(
                    r,
                    format_args!(
                        "SolidBegin \"{other}\": the operations are \"primitive\", \"union\", \"intersection\" \
                         and \"difference\"; taken as \"union\""
                    ),
                );
                SolidOp::Union
            })),
        };
        let ignored = if self.retained.is_some() {
            self.warn(r, "a solid inside ObjectBegin is not modelled: its parts are plain surfaces");
            true
        } else if self.solids.last().is_some_and(|s| s.ignored || s.op.is_none()) {
            self.warn(r, "SolidBegin inside a \"primitive\" block (RISpec allows none): ignored with its SolidEnd");
            true
        } else {
            false
        };
        self.take_loose_geometry(r);
        let inward = match self.solids.last() {
            Some(parent) if !ignored => {
                parent.inward != (parent.op == Some(SolidOp::Difference) && parent.operands > 0)
            }
            Some(parent) => parent.inward,
            None => false,
        };
        self.solids.push(OpenSolid {
            op,
            ignored,
            inward,
            operands: 0,
            mark: self.rt.instance_count(),
            reversed: Vec::new(),
            begin: r.loc.clone(),
        });
    }

    /// Instances placed directly in the innermost operation block, outside any primitive (RISpec
    /// allows none there): a primitive of their own, with a warning.
    fn take_loose_geometry(&mut self, r: &Request) {
        let count = self.rt.instance_count();
        let Some(solid) = self.solids.last_mut().filter(|s| s.op.is_some() && !s.ignored) else { return };
        if count > solid.mark {
            let parts = (solid.mark..count).map(|i| SolidPart { instance: InstanceId(i as u32), inward: false });
            self.solid_nodes.push(SolidNode::Primitive(parts.collect()));
            solid.operands += 1;
            solid.mark = count;
            self.warn(
                r,
                "geometry in a solid's operation block, outside any \"primitive\" block, is taken as a primitive",
            );
        }
    }

    /// `SolidEnd`: the block's solid becomes an operand of the block around it, or a solid of the
    /// scene.
    fn solid_end(&mut self, r: &Request) -> Result<(), ApiError> {
        self.take_loose_geometry(r);
        let Some(solid) = self.solids.pop() else {
            self.warn(r, "SolidEnd without SolidBegin");
            return Ok(());
        };
        if solid.ignored {
            return Ok(());
        }
        let count = self.rt.instance_count();
        let node = match solid.op {
            None => {
                // Instances are placed in increasing order, so `reversed` is sorted.
                let parts = (solid.mark..count).map(|i| {
                    let instance = InstanceId(i as u32);
                    SolidPart { instance, inward: solid.reversed.binary_search_by_key(&instance.0, |r| r.0).is_ok() }
                });
                Some(SolidNode::Primitive(parts.collect()))
            }
            Some(_) if solid.operands == 0 => None,
            Some(op) => Some(SolidNode::Op(op, solid.operands)),
        };
        if let Some(node) = node {
            self.solid_nodes.push(node);
            if let Some(parent) = self.solids.last_mut() {
                parent.operands += 1;
            }
        }
        if let Some(parent) = self.solids.last_mut() {
            parent.mark = count;
        } else {
            let nodes = std::mem::take(&mut self.solid_nodes);
            if !nodes.is_empty() {
                if let Err(e) = self.rt.add_solid(Solid { nodes }) {
                    self.warn(r, format_args!("{e}: its parts render as plain surfaces"));
                }
            }
        }
        Ok(())
    }

    /// Ends the solid blocks still open where the world ends (`at`), with a warning.
    fn end_solids(&mut self, at: &Request) -> Result<(), ApiError> {
        while let Some(open) = self.solids.last() {
            let begin = Request { loc: open.begin.clone(), kind: RequestKind::SolidEnd };
            self.warn(&begin, "SolidBegin without SolidEnd: the solid ends with the world");
            self.solid_end(at)?;
        }
        Ok(())
    }

    /// `Resource "name" "attributes" "operation" "save"|"restore" ["subset" "..."]`: PRMan's saved
    /// attribute states; the subsets, comma-separated, are Pixie's: `shading`, `geometrymodification`,
    /// `geometrydefinition`, `hiding`, `transform`, `all` (the default).
    fn resource(&mut self, r: &Request, name: &str, ty: &str, params: &[Param]) {
        if ty != "attributes" {
            return self.omit(r, format_args!("Resource type \"{ty}\" is not supported (rtsl's is \"attributes\")"));
        }
        let string = |key: &str| params.iter().find(|p| p.name == key).and_then(|p| p.strings()?.first().cloned());
        match string("operation").as_deref() {
            Some("save") => {
                let saved = (self.rt.saved_attributes(), self.state.clone());
                if let Some(scope) = self.resources.last_mut() {
                    scope.insert(name.to_string(), saved);
                }
            }
            Some("restore") => {
                let Some((api, state)) = self.resources.iter().rev().find_map(|s| s.get(name)).cloned() else {
                    return self.omit(r, format_args!("no attributes were saved as \"{name}\""));
                };
                let subset = string("subset").unwrap_or_else(|| "all".into());
                let (mut parts, mut definition) = (AttributeParts::default(), false);
                for part in subset.split(',').map(str::trim) {
                    match part {
                        "shading" => parts.shading = true,
                        "geometrymodification" => parts.sides = true,
                        "geometrydefinition" => definition = true,
                        "transform" => parts.transform = true,
                        "hiding" => {}
                        "all" => (parts, definition) = (AttributeParts::ALL, true),
                        other => self.warn(
                            r,
                            format_args!(
                                "unknown Resource subset \"{other}\" (\"shading\", \"geometrymodification\", \
                                 \"geometrydefinition\", \"hiding\", \"transform\" or \"all\")"
                            ),
                        ),
                    }
                }
                self.rt.restore_attributes(&api, parts);
                if parts.shading {
                    self.state.area_light = state.area_light;
                    self.state.shadows = state.shadows;
                }
                if parts.sides {
                    self.state.inside = state.inside;
                    self.state.detail = state.detail;
                    self.state.detail_range = state.detail_range;
                }
                if definition {
                    self.state.mesh_options = state.mesh_options;
                }
            }
            Some(other) => self.warn(r, format_args!("Resource operation \"{other}\": it is \"save\" or \"restore\"")),
            None => self.warn(r, "Resource \"attributes\" needs \"operation\" \"save\" or \"restore\""),
        }
    }

    /// `PixelFilter`: an unknown name is warned about and falls back to the default filter; widths
    /// that are not positive and at most 16 pixels are warned about and leave the filter as it was.
    /// The raster area (pixels) of the box around an object-space bound's projection, as RISpec's
    /// level of detail measures it; infinite where no matrix describes the camera or the bound
    /// reaches behind it.
    fn raster_area(&self, b: &[f32; 6]) -> f32 {
        let Some((_, to_ndc)) = self.rt.depth_map_projection() else { return f32::INFINITY };
        // The row-vector array of a column-vector matrix is its column-major array.
        let to_ndc = Mat4::from_cols_array(&to_ndc);
        let object_to_world = self.rt.current_matrix();
        let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
        for corner in 0..8 {
            let p = Vec3::new(b[corner & 1], b[2 + ((corner >> 1) & 1)], b[4 + ((corner >> 2) & 1)]);
            let h = to_ndc * object_to_world.transform_point3(p).extend(1.0);
            if h.w <= 1e-6 {
                return f32::INFINITY;
            }
            let ndc = glam::Vec2::new(h.x, h.y) / h.w;
            (lo, hi) = (lo.min(ndc), hi.max(ndc));
        }
        let size = (hi - lo) * glam::Vec2::new(self.rt.options.width as f32, self.rt.options.height as f32);
        size.x * size.y
    }

    /// Whether geometry here is the level of detail its `Detail` picks: RISpec's importance of the
    /// `DetailRange` (ramping up from minvisible to lowertransition, down from uppertransition to
    /// maxvisible) at least one half, so of ranges that tile the detail axis exactly one level is
    /// drawn where a renderer would blend two.
    fn detail_chosen(&self) -> bool {
        let (Some(detail), Some([min, low, high, max])) = (self.state.detail, self.state.detail_range) else {
            return true;
        };
        let importance = if detail < low {
            if low > min {
                (detail - min) / (low - min)
            } else if detail >= min {
                1.0
            } else {
                0.0
            }
        } else if detail > high {
            if max > high {
                (max - detail) / (max - high)
            } else if detail <= max {
                1.0
            } else {
                0.0
            }
        } else {
            1.0
        };
        importance >= 0.5
    }

    /// `Display "name" "type" "mode"`: a name starting with `+` adds an image, any other replaces
    /// the list (RISpec 3.2, 4.1.2).
    fn display(&mut self, r: &Request, name: &str, driver: &str, mode: &str) {
        let (additional, name) = match name.strip_prefix('+') {
            Some(rest) => (true, rest),
            None => (false, name),
        };
        let depth_map = matches!(driver, "zfile" | "shadow");
        let parsed = if depth_map { Some(DisplayMode::Z) } else { DisplayMode::parse(mode) };
        let (mode, output) = match (parsed, output_variable(mode)) {
            (Some(m), _) => (m, None),
            (None, Some(variable)) => {
                let outputs = &mut self.rt.options.outputs;
                if !outputs.iter().any(|o| o == variable) {
                    if outputs.len() >= crate::render::world::MAX_FRAME_OUTPUTS {
                        let most = crate::render::world::MAX_FRAME_OUTPUTS;
                        self.omit(
                            r,
                            format_args!("Display \"{variable}\": a frame keeps at most {most} output variables"),
                        );
                        return;
                    }
                    outputs.push(variable.to_string());
                }
                (DisplayMode::Rgb, Some(variable.to_string()))
            }
            (None, None) => {
                self.omit(r, format_args!("Display mode \"{mode}\" is neither a channel set nor an output variable"));
                return;
            }
        };
        if !additional {
            self.out.displays.clear();
        }
        let Some(kind) = DisplayDriver::parse(driver, Path::new(name)) else {
            self.omit(
                r,
                format_args!(
                    "Display \"{name}\": display driver \"{driver}\" is not one rtsl has, and the name's extension \
                     names no format it writes (drivers: {})",
                    DisplayDriver::NAMES
                ),
            );
            return;
        };
        let (window, format) = match kind {
            DisplayDriver::Window => (true, None),
            DisplayDriver::File(format) => (false, format),
        };
        self.out.displays.push(RibDisplay { name: PathBuf::from(name), mode, window, depth_map, output, format });
    }

    fn pixel_filter(&mut self, r: &Request, name: &str, xwidth: f32, ywidth: f32) {
        use crate::render::{FilterKind, PixelFilter};
        let Some(kind) = FilterKind::parse(name) else {
            self.warn(
                r,
                format_args!("unknown pixel filter \"{name}\" (known: {}); using box 1 1", FilterKind::names()),
            );
            self.rt.options.pixel_filter = PixelFilter::default();
            return;
        };
        match PixelFilter::new(kind, xwidth, ywidth) {
            Ok(f) => self.rt.options.pixel_filter = f,
            Err(e) => self.warn(r, format_args!("{e}; the pixel filter stays as it was")),
        }
    }

    fn attribute(&mut self, r: &Request, name: &str, params: &[Param]) {
        for p in params {
            let s = p.strings().and_then(|s| s.first()).map(String::as_str);
            let f = p
                .floats()
                .and_then(|f| f.first())
                .copied()
                .or_else(|| p.ints().and_then(|i| i.first()).map(|i| *i as f32));
            match (name, p.name.as_str()) {
                ("light", "shadows") => self.state.shadows = s.map_or(f.unwrap_or(1.0) != 0.0, |s| s == "on"),
                ("shade", "transmissionhitmode") => self.rt.shadows_from_shader(s == Some("shader")),
                ("photon", "shadingmodel") => match crate::render::world::PhotonModel::parse(s.unwrap_or("")) {
                    Ok(model) => self.rt.photon_shading_model(model),
                    Err(e) => self.warn(r, e),
                },
                // rtsl's own: cut-outs by a texture's alpha ("" for none); see `Context::alpha_mask`.
                ("trace", "alphamask") => self.rt.alpha_mask(s.filter(|s| !s.is_empty())),
                ("trimcurve", "sense") => match s {
                    Some("inside") => self.state.mesh_options.trim_sense = super::trim::TrimSense::Inside,
                    Some("outside") => self.state.mesh_options.trim_sense = super::trim::TrimSense::Outside,
                    _ => self.warn(r, "attribute \"trimcurve\" \"sense\" takes \"inside\" or \"outside\""),
                },
                ("identifier", "name") => self.rt.identifier(s),
                ("identifier", _) | ("displacementbound", "coordinatesystem") => {}
                // How far displacement moves the geometry (in the current space: no bound is
                // used to cull here, so the space does not matter); above 0 it asks for true
                // displacement, unless the attributes below say otherwise.
                ("displacementbound", "sphere") | ("bound", "displacement") => match f {
                    Some(b) if b.is_finite() && b >= 0.0 => self.rt.displacement_bound(b),
                    _ => self.warn(r, format_args!("attribute \"{name}\" \"{}\" takes a distance", p.name)),
                },
                // PRMan's ray-traced displacement and BMRT's true displacement.
                ("trace", "displacements") | ("render", "truedisplacement") => {
                    self.rt.true_displacement(Some(f.unwrap_or(1.0) != 0.0))
                }
                ("visibility", "camera") => self.rt.ray_visibility(RayKind::Camera, f.unwrap_or(1.0) != 0.0),
                // rtsl has one kind of ray for what shaders trace: it sees a surface that any of the
                // request's secondary kinds sees.
                ("visibility", kind) if SECONDARY_RAY_KINDS.contains(&kind) => {
                    let secondary = params.iter().filter(|q| SECONDARY_RAY_KINDS.contains(&q.name.as_str()));
                    let visible = secondary.filter_map(switched_on).any(|on| on);
                    self.rt.ray_visibility(RayKind::Trace, visible);
                }
                ("visibility", "photon" | "indirect") => self.rt.ray_visibility(RayKind::Photon, f.unwrap_or(1.0) != 0.0),
                ("visibility", "transmission") | ("render", "casts_shadows") => match (s, f) {
                    (Some("transparent" | "none"), _) => self.rt.ray_visibility(RayKind::Shadow, false),
                    (Some("opaque" | "Os"), _) => {
                        self.rt.ray_visibility(RayKind::Shadow, true);
                        self.rt.shadows_from_shader(false);
                    }
                    (Some("shader" | "shade"), _) => {
                        self.rt.ray_visibility(RayKind::Shadow, true);
                        self.rt.shadows_from_shader(true);
                    }
                    (None, Some(on)) => self.rt.ray_visibility(RayKind::Shadow, on != 0.0),
                    _ => self.warn(
                        r,
                        format_args!(
                            "attribute \"{name}\" \"{}\" takes 0 or 1, or \"transparent\", \"opaque\", \"Os\" or \"shader\"",
                            p.name
                        ),
                    ),
                },
                // BMRT's: the sum of 1 (camera rays), 2 (reflection rays) and 4 (shadow rays).
                ("render", "visibility") => {
                    let bits = f.unwrap_or(7.0) as u32;
                    self.rt.ray_visibility(RayKind::Camera, bits & 1 != 0);
                    self.rt.ray_visibility(RayKind::Trace, bits & 2 != 0);
                    self.rt.ray_visibility(RayKind::Shadow, bits & 4 != 0);
                }
                ("trace", "maxdiffusedepth" | "maxspeculardepth") => match f {
                    Some(n) if n >= 0.0 && n.is_finite() => {
                        // A float is read as the integer below it; past the largest a `u32` holds,
                        // the ray depth is the only bound anyway.
                        let bounces = n.min(u32::MAX as f32) as u32;
                        if p.name == "maxdiffusedepth" {
                            self.rt.max_diffuse_depth(bounces);
                        } else {
                            self.rt.max_specular_depth(bounces);
                        }
                    }
                    _ => self.warn(
                        r,
                        format_args!(
                            "attribute \"trace\" \"{}\" takes a number of bounces, 0 or more; it stays as it was",
                            p.name
                        ),
                    ),
                },
                ("trace", "bias") => match f {
                    Some(b) if b >= 0.0 && b.is_finite() => self.rt.trace_bias(b),
                    _ => self.warn(r, "attribute \"trace\" \"bias\" takes a distance, 0 or more; it stays as it was"),
                },
                ("light", "nsamples") | ("light", "samples") => {
                    if let (Some(light), Some(n)) = (self.state.area_light, f) {
                        self.rt.set_area_light_samples(light, n.max(1.0) as u32);
                    }
                }
                ("user", _) => match user_value(p) {
                    Some(value) => {
                        if let Err(e) = self.rt.ray_attribute(&p.name, Some(value)) {
                            self.warn(r, e);
                        }
                    }
                    None => self.warn(r, user_value_skipped(&p.name)),
                },
                // REYES's controls of dicing, culling, grid derivatives and shading rates, and of
                // the irradiance cache's interpolation: a ray tracer that shades every hit where
                // it is has no use for them (docs/rib.md).
                ("dice" | "cull" | "stochastic" | "derivatives", _)
                | ("shade", "relativeshadingrate" | "strategy" | "volumeintersectionstrategy")
                | ("sides", "doubleshaded" | "backfacetolerance")
                | ("trace", "decimationrate")
                | ("irradiance", "maxerror" | "maxpixeldist") => {}
                _ => self.warn(r, format_args!("attribute \"{name}\" \"{}\" is not supported", p.name)),
            }
        }
    }

    fn option(&mut self, r: &Request, name: &str, params: &[Param]) {
        for p in params {
            let s = p.strings().and_then(|s| s.first()).cloned();
            let f = p
                .floats()
                .and_then(|f| f.first())
                .copied()
                .or_else(|| p.ints().and_then(|i| i.first()).map(|i| *i as f32));
            match (name, p.name.as_str()) {
                ("searchpath", "shader") => {
                    let dirs = search_path(&s.unwrap_or_default(), &self.dir, self.rt.shader_search_path());
                    self.rt.set_shader_search_path(dirs);
                }
                ("searchpath", "texture") => {
                    for d in search_path(&s.unwrap_or_default(), &self.dir, &[]) {
                        self.rt.add_texture_search_path(d);
                    }
                }
                ("antialiasing", "mode") => {
                    let mode = s.clone().unwrap_or_default();
                    match crate::render::Antialiasing::parse(&mode) {
                        Ok(aa) => self.rt.options.antialiasing = aa,
                        Err(e) => self.warn(r, e),
                    }
                }
                // rtsl's: how the scene's 8-bit images encode colour, written and read
                // (`RenderOptions::image_transfer`; linear, RenderMan's way, unless this says).
                ("image", "transfer") => match crate::image_io::Transfer::parse(s.as_deref().unwrap_or("")) {
                    Ok(transfer) => self.rt.options.image_transfer = transfer,
                    Err(e) => self.warn(r, format_args!("option \"image\" \"transfer\": {e}")),
                },
                ("antialiasing", "threshold") => {
                    if let (Some(t), crate::render::Antialiasing::Adaptive { .. }) = (f, self.rt.options.antialiasing) {
                        self.rt.options.antialiasing = crate::render::Antialiasing::Adaptive { threshold: t.max(0.0) };
                    }
                }
                // Read by the parser as the stream is (`parse.rs`).
                ("searchpath", "archive") => {}
                // Where plug-ins are found: rtsl loads none (its display drivers are its own, and
                // `RunProgram` and `DynamicLoad` are refused).
                ("searchpath", "procedural" | "display" | "resource") => {}
                // REYES's buckets, grids and memory limits; rtsl hands tiles out on demand and
                // keeps no grids (docs/rib.md).
                (
                    "limits",
                    "bucketsize"
                    | "gridsize"
                    | "texturememory"
                    | "eyesplits"
                    | "geocachememory"
                    | "brickmemory"
                    | "octreememory"
                    | "proceduralmemory"
                    | "deepshadowtiles"
                    | "deepshadowmemory"
                    | "radiositycachememory",
                )
                | ("bucket", "order") => {}
                // rtsl prints each frame's statistics whatever the level.
                ("statistics", "endofframe" | "level") => {}
                // BMRT's choice of PRMan's highlight, which is rtsl's `specular`.
                ("render", "prmanspecular") if f.is_some_and(|v| v != 0.0) => {}
                ("render", "prmanspecular") => self.warn(
                    r,
                    "option \"render\" \"prmanspecular\" [0] asks for BMRT's own highlight; rtsl's `specular` is PRMan's",
                ),
                ("limits", "othreshold") => match color_option(p) {
                    Some(threshold) => self.rt.options.opacity_threshold = threshold,
                    None => self.warn(r, "option \"limits\" \"othreshold\" takes a colour (three numbers)"),
                },
                ("limits", "zthreshold") => match color_option(p) {
                    Some(threshold) => self.rt.options.depth_threshold = threshold,
                    None => self.warn(r, "option \"limits\" \"zthreshold\" takes a colour (three numbers)"),
                },
                ("limits", "threads") | ("render", "nthreads") => match f {
                    Some(n) if n >= 1.0 && n.is_finite() => self.rt.options.threads = Some(n.min(4096.0) as u32),
                    _ => self
                        .warn(r, format_args!("option \"{name}\" \"{}\" takes a number of threads, 1 or more", p.name)),
                },
                ("shadow", which @ ("bias" | "bias0" | "bias1")) => match f.filter(|b| b.is_finite()) {
                    Some(b) => {
                        let biases = &mut self.rt.options.shadow_bias;
                        match which {
                            "bias" => *biases = [b; 2],
                            "bias0" => biases[0] = b,
                            _ => biases[1] = b,
                        }
                    }
                    None => self.warn(r, format_args!("option \"shadow\" \"{which}\" takes a number")),
                },
                ("trace", "maxdepth") => {
                    if let Some(n) = f {
                        self.rt.options.max_ray_depth = n.clamp(0.0, 64.0) as u32;
                    }
                }
                (
                    "gi",
                    setting @ ("virtuallights" | "bounces" | "interleave" | "clamp" | "seed" | "causticphotons"
                    | "globalphotons"),
                ) => {
                    use crate::render::world::{MAX_BOUNCES, MAX_INTERLEAVE, MAX_VIRTUAL_LIGHT_PATHS};
                    let Some(v) = f.filter(|v| v.is_finite() && *v >= 0.0) else {
                        self.warn(r, format_args!("option \"gi\" \"{setting}\" takes a number, at least 0"));
                        continue;
                    };
                    let gi = &mut self.rt.options.gi;
                    match setting {
                        "virtuallights" => gi.virtual_lights = v.min(MAX_VIRTUAL_LIGHT_PATHS as f32) as u32,
                        "bounces" => gi.bounces = v.clamp(1.0, MAX_BOUNCES as f32) as u32,
                        "interleave" => gi.interleave = v.clamp(1.0, MAX_INTERLEAVE as f32) as u32,
                        "clamp" => gi.clamp = v,
                        "causticphotons" => gi.caustic_photons = v.min(MAX_VIRTUAL_LIGHT_PATHS as f32) as u32,
                        "globalphotons" => gi.global_photons = v.min(MAX_VIRTUAL_LIGHT_PATHS as f32) as u32,
                        _ => gi.seed = v.min(u32::MAX as f32) as u32,
                    }
                }
                ("user", _) => match user_value(p) {
                    Some(value) => {
                        // A later `Option "user"` of the name wins, whatever its type.
                        self.rt.remove_ray_parameter(&p.name);
                        if let Err(e) = self.rt.set_ray_parameter(&p.name, value) {
                            self.warn(r, e);
                        }
                    }
                    None => self.warn(r, user_value_skipped(&p.name)),
                },
                _ => self.warn(r, format_args!("option \"{name}\" \"{}\" is not supported", p.name)),
            }
        }
    }
}

/// Whether a request is geometry (it becomes part of the object being gathered).
/// The parameter list of a geometry request (empty for other requests).
fn geometry_params(kind: &RequestKind) -> &[Param] {
    use RequestKind as K;
    match kind {
        K::Polygon(params) | K::Points(params) => params,
        K::GeneralPolygon { params, .. }
        | K::PointsPolygons { params, .. }
        | K::PointsGeneralPolygons { params, .. }
        | K::Patch { params, .. }
        | K::PatchMesh { params, .. }
        | K::Quadric { params, .. }
        | K::SubdivisionMesh { params, .. }
        | K::NuPatch { params, .. }
        | K::Geometry { params, .. }
        | K::Curves { params, .. }
        | K::Blobby { params, .. } => params,
        _ => &[],
    }
}

/// The parameters of a geometry request that hold one value for the whole primitive: its
/// `constant` ones, and its `uniform` ones where it has one face (RISpec: one value per facet),
/// a polygon, a patch or a quadric. Positions, normals and texture coordinates are the
/// geometry's own.
fn primitive_constants(kind: &RequestKind) -> Vec<&Param> {
    use RequestKind as K;
    let one_face = matches!(kind, K::Polygon(_) | K::GeneralPolygon { .. } | K::Patch { .. } | K::Quadric { .. });
    geometry_params(kind)
        .iter()
        .filter(|p| p.decl.class == Class::Constant || (one_face && p.decl.class == Class::Uniform))
        .filter(|p| !matches!(p.name.as_str(), "P" | "Pw" | "Pz" | "N" | "Np" | "st" | "s" | "t"))
        .collect()
}

/// Inside `ObjectBegin`: the parts of the appearance `kind` sets, which the object then keeps
/// for its instances instead of taking them from where each stands.
fn keep_what_the_block_sets(kind: &RequestKind, inherits: &mut InheritedAppearance) {
    use RequestKind as K;
    match kind {
        K::Color(_) => inherits.color = false,
        K::Opacity(_) => inherits.opacity = false,
        K::Surface(_) => inherits.surface = false,
        K::Displacement(_) => inherits.displacement = false,
        K::Interior(_) => inherits.interior = false,
        K::Sides(_) => inherits.sides = false,
        K::Matte(_) => inherits.matte = false,
        K::ShadingRate(_) => inherits.shading_rate = false,
        K::Attribute { .. } => inherits.attributes = false,
        // A restored resource may set any of them.
        K::Resource { .. } => *inherits = InheritedAppearance::NONE,
        _ => {}
    }
}

fn is_geometry(kind: &RequestKind) -> bool {
    use RequestKind as K;
    matches!(
        kind,
        K::Polygon(_)
            | K::GeneralPolygon { .. }
            | K::PointsPolygons { .. }
            | K::PointsGeneralPolygons { .. }
            | K::Patch { .. }
            | K::PatchMesh { .. }
            | K::Quadric { .. }
            | K::SubdivisionMesh { .. }
            | K::NuPatch { .. }
            | K::Geometry { .. }
            | K::Points(_)
            | K::Curves { .. }
            | K::Blobby { .. }
    )
}

/// The values of `params` that `program` takes, typed by it; each one it cannot take is a warning
/// (at the parameter for a value with no type, at `bind_loc(param)` for one the shader refuses).
fn typed_params<'p>(
    program: &ShaderProgram,
    params: &'p [Param],
    bind_loc: impl Fn(&'p Param) -> &'p super::request::Location,
    warnings: &mut Vec<RibDiagnostic>,
) -> Vec<(&'p str, ParamValue)> {
    let mut kept = Vec::new();
    for p in params {
        match shader_value(p, program) {
            Some(v) => match crate::shading::bind_param(program, &p.name, &v, &Affine3A::IDENTITY) {
                Ok(_) => kept.push((p.name.as_str(), v)),
                Err(e) => warnings.push(RibDiagnostic::warning(bind_loc(p), e.to_string())),
            },
            None => warnings.push(RibDiagnostic::warning(&p.loc, format!("cannot pass {} to a shader", p.name))),
        }
    }
    kept
}

/// A RIB search path (`"dir1:dir2:&"`, `&` standing for the previous value), relative to `base`.
fn search_path(spec: &str, base: &Path, previous: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for part in spec.split(':').filter(|p| !p.is_empty()) {
        if part == "&" {
            out.extend(previous.iter().cloned());
        } else {
            out.push(base.join(part));
        }
    }
    out
}

/// RISpec's `Skew angle dx1 dy1 dz1 dx2 dy2 dz2`: a shear along the second axis that turns the
/// first axis by `angle` degrees towards it, in the plane of the two. Points move along the second
/// axis by `k` times their distance along `n`, the part of the first axis perpendicular to the
/// second; `k` turns the first axis from its angle `phi` off `n` to `phi + angle`. `None` when the
/// axes are parallel or the turn reaches the second axis.
fn skew(s: &[f32; 7]) -> Option<Affine3A> {
    let (v1, v2) = (Vec3::new(s[1], s[2], s[3]), Vec3::new(s[4], s[5], s[6]));
    let d2 = v2.try_normalize()?;
    let a1 = v1.dot(d2);
    let perpendicular = v1 - a1 * d2;
    let b1 = perpendicular.length();
    let n = perpendicular.try_normalize()?;
    let phi = a1.atan2(b1);
    let turned = phi + s[0].to_radians();
    if turned.is_nan() || turned.abs() >= std::f32::consts::FRAC_PI_2 {
        return None;
    }
    let k = turned.tan() - a1 / b1;
    let shear = glam::Mat3::from_cols(Vec3::X + k * d2 * n.x, Vec3::Y + k * d2 * n.y, Vec3::Z + k * d2 * n.z);
    shear.is_finite().then(|| Affine3A::from_mat3(shear))
}

/// A plane (a point and a normal) moved by `m`: the point as a point, the normal as a normal.
fn place_plane(m: Affine3A, p: Vec3, n: Vec3) -> (Vec3, Vec3) {
    (m.transform_point3(p), Vec3::from(m.matrix3.inverse().transpose() * glam::Vec3A::from(n)))
}

/// A RenderMan matrix as written (row-major, row vectors) as an affine transform; the projective
/// column is dropped.
fn affine(m: &[f32; 16]) -> Affine3A {
    Affine3A::from_mat4(Mat4::from_cols_array(m))
}

/// A RIB parameter as a value for `program`: typed by its declaration, or when it has none by the
/// shader's own declaration of that parameter.
fn shader_value(p: &Param, program: &ShaderProgram) -> Option<ParamValue> {
    let many = p.decl.array_len.is_some() || p.value_count() > 1;
    let mut ty = p.decl.ty;
    match p.decl.class {
        Class::FaceVarying => return None,
        Class::Implicit => {
            let Some(info) = program.interface.parameters.iter().find(|i| i.name == p.name) else {
                // Bound as given, so that binding reports the missing parameter.
                return Some(match &p.value {
                    RibValue::Strings(s) => ParamValue::String(s.first()?.clone()),
                    RibValue::Floats(v) => ParamValue::Floats(v.clone()),
                    RibValue::Ints(v) => ParamValue::Floats(v.iter().map(|i| *i as f32).collect()),
                });
            };
            ty = match info.base {
                BaseType::Color => Ty::Color,
                BaseType::Point => Ty::Point,
                BaseType::Vector => Ty::Vector,
                BaseType::Normal => Ty::Normal,
                BaseType::Matrix => Ty::Matrix,
                BaseType::String => Ty::String,
                _ => Ty::Float,
            };
            let floats = match &p.value {
                RibValue::Floats(v) => v.len(),
                _ => 0,
            };
            let components = ty.components();
            let many = info.array_length.is_some() || (ty != Ty::String && floats > components);
            return typed_value(&p.value, ty, many);
        }
        _ => {}
    }
    typed_value(&p.value, ty, many)
}

fn typed_value(value: &RibValue, ty: Ty, many: bool) -> Option<ParamValue> {
    match (value, ty) {
        (RibValue::Strings(s), Ty::String) => s.first().map(|s| ParamValue::String(s.clone())),
        (RibValue::Ints(v), Ty::Integer) => {
            let f: Vec<f32> = v.iter().map(|i| *i as f32).collect();
            Some(if many { ParamValue::Floats(f) } else { ParamValue::Float(f[0]) })
        }
        (RibValue::Floats(v), Ty::Float) => {
            Some(if many { ParamValue::Floats(v.clone()) } else { ParamValue::Float(v[0]) })
        }
        (RibValue::Floats(v), ty @ (Ty::Color | Ty::Point | Ty::Vector | Ty::Normal)) => {
            let t: Vec<[f32; 3]> = v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            if many {
                return Some(ParamValue::Triples(t));
            }
            let t = *t.first()?;
            Some(match ty {
                Ty::Color => ParamValue::Color(t),
                Ty::Point => ParamValue::Point(t),
                Ty::Vector => ParamValue::Vector(t),
                _ => ParamValue::Normal(t),
            })
        }
        (RibValue::Floats(v), Ty::HPoint) if v.len() >= 4 && v[3] != 0.0 => {
            let w = v[3];
            Some(ParamValue::Point([v[0] / w, v[1] / w, v[2] / w]))
        }
        (RibValue::Floats(v), Ty::Matrix) if v.len() >= 16 => {
            let mut m = [0.0; 16];
            m.copy_from_slice(&v[..16]);
            Some(ParamValue::Matrix(m))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The warning for an unknown driver lists only drivers rtsl has (every word of it, whatever
    /// the image's name).
    #[test]
    fn every_display_driver_the_warning_names_is_one_rtsl_has() {
        let words = DisplayDriver::NAMES.split(|c: char| !c.is_ascii_alphanumeric()).filter(|w| !w.is_empty());
        for driver in words {
            assert!(DisplayDriver::parse(driver, Path::new("image")).is_some(), "{driver}");
        }
        assert!(DisplayDriver::parse("mystery", Path::new("image")).is_none());
    }

    /// Read in one pass, each image is loaded as loading it alone loads it, also where an image
    /// begins before the last one ended (a `FrameBegin` inside a world block begins the next
    /// image; the world block's image ends there).
    #[test]
    fn images_read_in_one_pass_are_the_images_loaded_alone() {
        let dir = tempfile::tempdir().expect("tempdir");
        let streams = [
            "WorldBegin\nFormat 64 48 1\nFrameBegin 7\nFormat 63 48 1\nWorldBegin\nWorldEnd\nFrameEnd\n",
            "Format 32 24 1\nFrameBegin 1\nWorldBegin\nFrameBegin 2\nFormat 31 24 1\nWorldEnd\nFrameEnd\n\
             Format 30 24 1\nWorldBegin\nWorldEnd\n",
            "FrameBegin 1\nFormat 16 12 1\nWorldBegin\nWorldEnd\nFrameEnd\nFormat 15 12 1\nWorldBegin\n\
             FrameBegin 3\nFormat 14 12 1\nFrameEnd\nWorldEnd\n",
        ];
        for (k, rib) in streams.iter().enumerate() {
            let path = dir.path().join(format!("stream{k}.rib"));
            std::fs::write(&path, rib).expect("write");
            let mut in_one_pass = Vec::new();
            load_file_frames(
                &path,
                Context::new,
                |_, _| true,
                |image| -> Result<_, SceneFileError> {
                    in_one_pass.push((image.index, format!("{:?}", image.rt.options)));
                    Ok(ControlFlow::Continue(()))
                },
            )
            .expect("the stream reads");
            assert!(in_one_pass.len() >= 2, "stream {k}: {} images", in_one_pass.len());
            for (index, options) in &in_one_pass {
                let mut alone = Context::new();
                load_file_frame(&mut alone, &path, *index).expect("the image loads");
                assert_eq!(*options, format!("{:?}", alone.options), "stream {k}, image {index}");
            }
        }
    }

    /// Requests between frames set up the frames after them: a `Display` and a `MakeShadow` of
    /// the depth pass's output that follow its `FrameEnd` belong to the beauty frame.
    #[test]
    fn requests_after_a_frames_end_are_the_next_frames() {
        let dir = tempfile::tempdir().expect("tempdir");
        let rib = "Display \"depth.zfile\" \"zfile\" \"z\"\nFrameBegin 1\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\n\
                   FrameEnd\nMakeShadow \"depth.zfile\" \"depth.shad\"\nDisplay \"beauty.tif\" \"file\" \"rgba\"\n\
                   FrameBegin 2\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\nFrameEnd\n";
        let path = dir.path().join("passes.rib");
        std::fs::write(&path, rib).expect("write");
        let names = |loaded: &LoadedRib| loaded.displays.iter().map(|d| d.name.clone()).collect::<Vec<_>>();
        let first = load_file_frame(&mut Context::new(), &path, 0).expect("frame 1");
        assert_eq!(names(&first), vec![PathBuf::from("depth.zfile")]);
        assert!(first.warnings.iter().all(|w| !w.message.contains("MakeShadow")), "{:?}", first.warnings);
        let second = load_file_frame(&mut Context::new(), &path, 1).expect("frame 2");
        assert_eq!(names(&second), vec![PathBuf::from("beauty.tif")]);
    }

    /// A file's images read in one pass (`load_file_frames`) are those loaded one at a time
    /// (`load_file_frame`): the same picture bit for bit, displays, numbers and loading warnings,
    /// with requests between the frames (a format, a camera move, a display) applying to the
    /// frames after them, and a world block outside any frame. A syntax error is reported with
    /// its own image only.
    #[test]
    fn images_read_in_one_pass_are_those_loaded_one_at_a_time() {
        let dir = tempfile::tempdir().expect("tempdir");
        let rib = "Format 16 12 1\nProjection \"perspective\" \"fov\" 40\n\
            FrameBegin 3\nDisplay \"a.#f.exr\" \"file\" \"rgba\"\nTranslate 0 0 4\nWorldBegin\n\
            LightSource \"pointlight\" 1 \"from\" [1 1 -2] \"intensity\" [4]\nSurface \"plastic\"\n\
            Sphere 1 -1 1 360\nSurface \"no_such_shader\"\nWorldEnd\nFrameEnd\n\
            Format 20 10 1\nTranslate 0.3 0 0\n\
            FrameBegin 7\nDisplay \"b.#f.exr\" \"file\" \"rgba\"\nTranslate 0 0 5\nWorldBegin\n\
            Color [1 0 0]\nTranslate 0 [1\nPolygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\nWorldEnd\nFrameEnd\n\
            Translate 0 0 3\nWorldBegin\nSphere 0.5 -0.5 0.5 360\nWorldEnd\n";
        let path = dir.path().join("frames.rib");
        std::fs::write(&path, rib).expect("write");
        let picture = |rt: &mut Context| {
            let world = rt.build_world().expect("a world");
            crate::render::render_frame(&world, None).0.rgba.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        let loading = |loaded: &LoadedRib| {
            let warnings: Vec<String> = loaded
                .warnings
                .iter()
                .filter(|w| w.severity != Severity::Error)
                .map(|w| format!("{}:{} {}", w.loc.line, w.loc.column, w.message))
                .collect();
            (loaded.displays.clone(), loaded.frame_number, warnings)
        };
        let mut one_pass = Vec::new();
        let images = load_file_frames(
            &path,
            Context::new,
            |_, _| true,
            |mut image: RibImage| -> Result<ControlFlow<()>, SceneFileError> {
                let errors = image.loaded.errors();
                one_pass.push((image.index, picture(&mut image.rt), loading(&image.loaded), errors));
                Ok(ControlFlow::Continue(()))
            },
        )
        .expect("the file reads");
        assert_eq!(images.numbers, vec![3, 7, 3]);
        assert!(images.warnings.is_empty(), "{:?}", images.warnings);
        assert_eq!(one_pass.len(), 3);
        for (index, picture_read_once, loaded_read_once, errors) in one_pass {
            let mut rt = Context::new();
            let alone = load_file_frame(&mut rt, &path, index).expect("the image loads");
            assert_eq!(loading(&alone), loaded_read_once, "image {index}");
            assert!(picture(&mut rt) == picture_read_once, "image {index}'s picture");
            assert_eq!(errors, usize::from(index == 1), "image {index}'s syntax errors");
        }

        // One image asked for: the file is read up to its end, no further.
        let mut loaded = Vec::new();
        let images = load_file_frames(
            &path,
            Context::new,
            |_, number| number == 7,
            |image: RibImage| -> Result<ControlFlow<()>, SceneFileError> {
                loaded.push((image.index, image.loaded.frame_number, image.loaded.errors()));
                Ok(ControlFlow::Break(()))
            },
        )
        .expect("the file reads");
        assert_eq!(loaded, vec![(1, 7, 1)]);
        assert_eq!(images.numbers, vec![3, 7]);
    }

    /// Requests outside the frames past `MAX_SHARED_REQUESTS` still reach the first image (its
    /// loader takes them as they come), and are an omission for the images after it.
    #[test]
    fn shared_requests_past_the_limit_are_an_omission_for_later_images() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rib = "Translate 0 0 1\n".repeat(MAX_SHARED_REQUESTS + 2);
        rib.push_str("FrameBegin 1\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\nFrameEnd\n".repeat(2).as_str());
        let path = dir.path().join("long.rib");
        std::fs::write(&path, rib).expect("write");
        let mut omissions = Vec::new();
        load_file_frames(
            &path,
            Context::new,
            |_, _| true,
            |image: RibImage| -> Result<ControlFlow<()>, SceneFileError> {
                let lines: Vec<u32> = image
                    .loaded
                    .warnings
                    .iter()
                    .filter(|w| w.severity == Severity::Omission)
                    .map(|w| w.loc.line)
                    .collect();
                omissions.push(lines);
                Ok(ControlFlow::Continue(()))
            },
        )
        .expect("the file reads");
        assert_eq!(omissions, vec![vec![], vec![MAX_SHARED_REQUESTS as u32 + 1]]);
    }

    /// A stream read request by request hands its sink the requests that reading it whole keeps,
    /// in the same order, and the same diagnostics: through inline archives read twice,
    /// conditionals taken and not, a syntax error, a binary number and a comment.
    #[test]
    fn streamed_requests_are_those_read_whole() {
        let rib =
            b"##RenderMan RIB\nFormat 8 8 1\nArchiveBegin \"part\"\nColor [1 0 0]\nSphere 1 -1 1 360\nArchiveEnd\n\
                    FrameBegin 3\nOption \"user\" \"int pass\" [2]\nIfBegin \"$Option:user:pass == 2\"\n\
                    Translate 0 0 5\nElse\nTranslate 0 0 9\nIfEnd\nWorldBegin\nReadArchive \"part\"\n\
                    Translate 1 [2 3\nReadArchive \"part\" # twice\nTranslate 0 \x80\x05 0\nWorldEnd\nFrameEnd\n";
        let name = Path::new("stream.rib");
        let whole = super::super::parse_bytes(rib, name);
        let mut streamed = Vec::new();
        let rest = parse_bytes_into(rib, name, &mut |r| streamed.push(r));
        assert!(whole.requests.len() > 10, "{:?}", whole.requests);
        assert_eq!(streamed, whole.requests);
        assert!(rest.requests.is_empty());
        assert_eq!(rest.diagnostics, whole.diagnostics);
        assert!(!rest.diagnostics.is_empty(), "the stream has a syntax error");
    }

    /// Attribute and transform blocks nested past [`MAX_BLOCK_DEPTH`] are one omission, restore
    /// nothing, and leave the blocks around them balanced: an extra `AttributeEnd` after they all
    /// close is the only unbalanced end.
    #[test]
    fn blocks_nested_past_the_limit_restore_nothing() {
        let extra = 5;
        let depth = MAX_BLOCK_DEPTH + extra;
        let mut rib = String::from("WorldBegin\n");
        for k in 0..depth {
            rib.push_str(if k % 2 == 0 { "AttributeBegin\n" } else { "TransformBegin\n" });
        }
        rib.push_str("Sphere 1 -1 1 360\n");
        for k in (0..depth).rev() {
            rib.push_str(if k % 2 == 0 { "AttributeEnd\n" } else { "TransformEnd\n" });
        }
        rib.push_str("AttributeEnd\nWorldEnd\n");
        let loaded = load_str(&mut Context::new(), &rib, "deep.rib").expect("loads");
        let deep: Vec<_> = loaded.warnings.iter().filter(|w| w.message.contains("nest deeper")).collect();
        assert_eq!(deep.len(), 1, "{:?}", loaded.warnings);
        assert_eq!(deep[0].loc.line as usize, 2 + MAX_BLOCK_DEPTH, "the first block past the limit");
        // Every other diagnostic is the extra end, on the line before `WorldEnd`.
        let others: Vec<_> = loaded.warnings.iter().filter(|w| !w.message.contains("nest deeper")).collect();
        assert_eq!(others.len(), 1, "{others:?}");
        assert_eq!(others[0].loc.line as usize, 2 + 2 * depth + 1, "{others:?}");
    }

    /// Shaders kept beside a RIB file are found, as Aqsis's default search path begins with ".".
    #[test]
    fn shaders_beside_the_file_are_found() {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("beside.sl"), "surface beside() { Ci = color(1, 0, 0); }").expect("write");
        let path = dir.path().join("scene.rib");
        std::fs::write(&path, "WorldBegin\nSurface \"beside\"\nSphere 1 -1 1 360\nWorldEnd\n").expect("write");
        let mut rt = Context::new();
        let loaded = load_file(&mut rt, &path).expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        assert!(rt.find_shader("beside").is_ok());
        // A search path without `&` replaces it.
        let replaced = "Option \"searchpath\" \"shader\" [\"elsewhere\"]\n";
        std::fs::write(&path, format!("{replaced}WorldBegin\nSurface \"beside\"\nSphere 1 -1 1 360\nWorldEnd\n"))
            .expect("write");
        let loaded = load_file(&mut Context::new(), &path).expect("loads");
        assert!(loaded.warnings.iter().any(|w| w.message.contains("no shader named beside")), "{:?}", loaded.warnings);
    }

    /// "inside" reverses the normals a surface defines, as RenderMan reverses `N`; normals given
    /// with "N" stay as given. (The floor of Aqsis's soft-shadow example faces up by `Orientation
    /// "rh"`: its dPdu x dPdv points down.)
    #[test]
    fn inside_orientation_reverses_the_normals_a_surface_defines() {
        let floor = "Patch \"bilinear\" \"P\" [-10 -1 -10  10 -1 -10  -10 -1 10  10 -1 10]";
        let given = "Polygon \"P\" [0 0 0  1 0 0  1 0 1] \"N\" [0 1 0  0 1 0  0 1 0]";
        let normals_y = |orientation: &str, geometry: &str| {
            let mut rt = Context::new();
            load_str(&mut rt, &format!("WorldBegin\n{orientation}\n{geometry}\nWorldEnd\n"), Path::new("o.rib"))
                .expect("loads");
            let mesh = rt.object_mesh(ObjectId(0)).expect("a mesh").clone();
            mesh.normals
                .as_ref()
                .expect("normals")
                .iter()
                .map(|n| n.y.signum() as i32)
                .collect::<std::collections::BTreeSet<_>>()
        };
        let one = |s: i32| std::iter::once(s).collect::<std::collections::BTreeSet<_>>();
        assert_eq!(normals_y("", floor), one(-1));
        assert_eq!(normals_y("Orientation \"rh\"", floor), one(1));
        assert_eq!(normals_y("ReverseOrientation", floor), one(1));
        assert_eq!(normals_y("Orientation \"inside\"", given), one(1));
    }

    #[test]
    fn skew_turns_the_first_axis_towards_the_second() {
        let m = skew(&[45.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0]).expect("a skew");
        assert!(m.transform_vector3(Vec3::Y).abs_diff_eq(Vec3::new(1.0, 1.0, 0.0), 1e-6));
        // Along the second axis and across the plane nothing moves.
        assert!(m.transform_vector3(Vec3::X).abs_diff_eq(Vec3::X, 1e-6));
        assert!(m.transform_vector3(Vec3::Z).abs_diff_eq(Vec3::Z, 1e-6));
        // Axes 45 degrees apart: turned by 30, the first is 15 degrees off the second.
        let m = skew(&[30.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]).expect("a skew");
        let turned = m.transform_vector3(Vec3::new(1.0, 1.0, 0.0));
        assert!((turned.angle_between(Vec3::X).to_degrees() - 15.0).abs() < 1e-3, "{turned}");
        // Parallel axes, or a turn that reaches the second axis, are refused.
        assert!(skew(&[10.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0]).is_none());
        assert!(skew(&[45.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn display_names_take_renderman_frame_patterns() {
        assert_eq!(expand_display_name("out.#f.tif", 12), "out.12.tif");
        assert_eq!(expand_display_name("out.#4f.exr", 12), "out.0012.exr");
        assert_eq!(expand_display_name("a##b#f", 3), "a#b3");
        // Anything else keeps its `#`; a width past two digits is not a pattern.
        assert_eq!(expand_display_name("#x#123f#", 3), "#x#123f#");
        assert_eq!(expand_display_name("plain.png", 3), "plain.png");
    }

    #[test]
    fn frames_are_frame_blocks_and_world_blocks_outside_them() {
        let parse = crate::rib::parse_str(
            "Format 8 8 1\nFrameBegin 4\nWorldBegin\nWorldEnd\nFrameEnd\nTranslate 0 0 1\n\
             WorldBegin\nWorldEnd\nFrameBegin\nWorldBegin\nWorldEnd\nFrameEnd\n",
            "f.rib",
        );
        let mut frames = Frames::default();
        let owners: Vec<Option<usize>> = parse.requests.iter().map(|r| frames.add(r)).collect();
        assert_eq!(frames.count(), 3);
        assert_eq!((frames.number(0), frames.number(1), frames.number(2)), (4, 2, 3));
        // Format and the Translate between frames belong to none: they hold for the frames after them.
        assert_eq!(
            owners,
            vec![None, Some(0), Some(0), Some(0), Some(0), None, Some(1), Some(1), Some(2), Some(2), Some(2), Some(2)]
        );
        assert_eq!(Frames::of(&[]).count(), 1);
    }

    /// Whether a camera ray from `(x, y, z)` along `dz` (±1) hits the geometry of `world` (the
    /// body of a world block).
    fn camera_hits(before_world: &str, world: &str, rays: &[([f32; 3], f32)]) -> Vec<bool> {
        camera_hit_distances(before_world, world, rays).iter().map(|t| t.is_finite()).collect()
    }

    /// How far camera rays as [`camera_hits`] takes them go to their hits (infinite for none).
    fn camera_hit_distances(before_world: &str, world: &str, rays: &[([f32; 3], f32)]) -> Vec<f32> {
        use crate::ray::{HitPacket, Ray, RayPacket, INVALID_ID};
        let rib = format!("Projection \"perspective\"\n{before_world}\nWorldBegin\n{world}\nWorldEnd\n");
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &rib, "sides.rib").expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let world = rt.build_world().expect("a world");
        let mut packet = RayPacket::new();
        for (i, (o, dz)) in rays.iter().enumerate() {
            packet.set(i, &Ray::new(glam::Vec3A::from_array(*o), glam::Vec3A::new(0.0, 0.0, *dz)));
        }
        let mut hits = HitPacket::default();
        world.intersect_packet(RayKind::Camera, &packet, &mut hits);
        (0..rays.len()).map(|i| if hits.instance.0[i] == INVALID_ID { f32::INFINITY } else { hits.t.0[i] }).collect()
    }

    /// A triangle at z = 0 whose `(P1 - P0) x (P2 - P0)` is +z, seen from behind (from -z) and
    /// from the front (from +z).
    const TRIANGLE: &str = "Polygon \"P\" [0 0 0  1 0 0  0 1 0]";
    const BEHIND_AND_FRONT: [([f32; 3], f32); 2] = [([0.2, 0.2, -5.0], 1.0), ([0.2, 0.2, 5.0], -1.0)];

    #[test]
    fn rib_sides_one_hides_the_back_from_camera_rays() {
        let sees = |world: &str| camera_hits("", world, &BEHIND_AND_FRONT);
        assert_eq!(sees(TRIANGLE), [true, true]);
        assert_eq!(sees(&format!("Sides 2 {TRIANGLE}")), [true, true]);
        assert_eq!(sees(&format!("Sides 1 {TRIANGLE}")), [false, true]);
        assert_eq!(sees(&format!("Sides 1 ReverseOrientation {TRIANGLE}")), [true, false]);
        assert_eq!(sees(&format!("Sides 1 Orientation \"inside\" {TRIANGLE}")), [true, false]);
        // Scoped by attribute blocks.
        assert_eq!(sees(&format!("AttributeBegin Sides 1 AttributeEnd {TRIANGLE}")), [true, true]);
        // "outside" follows the current space: mirrored, the outside turns with it.
        assert_eq!(sees(&format!("Sides 1 Scale 1 1 -1 {TRIANGLE}")), [true, false]);
        // A retained object keeps the side it was defined with; an instance placed mirrored
        // turns it as well.
        let object = format!("AttributeBegin ObjectBegin 1 Sides 1 {TRIANGLE} ObjectEnd AttributeEnd");
        assert_eq!(sees(&format!("{object} ObjectInstance 1")), [false, true]);
        assert_eq!(sees(&format!("{object} Scale 1 1 -1 ObjectInstance 1")), [true, false]);
    }

    #[test]
    fn rib_orientation_rh_and_lh_depend_on_the_handedness_when_given() {
        let sees = |before: &str, world: &str| camera_hits(before, world, &BEHIND_AND_FRONT);
        // Camera space is left-handed: with no mirror, "lh" is "outside" and "rh" "inside".
        assert_eq!(sees("", &format!("Sides 1 Orientation \"lh\" {TRIANGLE}")), [false, true]);
        assert_eq!(sees("", &format!("Sides 1 Orientation \"rh\" {TRIANGLE}")), [true, false]);
        // A mirroring camera transform makes the world right-handed.
        assert_eq!(sees("Scale 1 1 -1", &format!("Sides 1 Orientation \"rh\" {TRIANGLE}")), [false, true]);
        assert_eq!(sees("Scale 1 1 -1", &format!("Sides 1 Orientation \"lh\" {TRIANGLE}")), [true, false]);
        // Given before a mirror, the orientation stays what it was decided to be.
        assert_eq!(sees("", &format!("Sides 1 Orientation \"rh\" Scale 1 1 -1 {TRIANGLE}")), [false, true]);
    }

    #[test]
    fn rib_mirrored_geometry_within_one_object_keeps_its_outside() {
        // Two triangles gathered into one object, the second mirrored into it.
        let world = format!("Sides 1 {TRIANGLE} Translate 2 0 0 Scale 1 1 -1 {TRIANGLE}");
        let rays = [([0.2, 0.2, 5.0], -1.0), ([2.2, 0.2, 5.0], -1.0), ([2.2, 0.2, -5.0], 1.0)];
        assert_eq!(camera_hits("", &world, &rays), [true, false, true]);
    }

    #[test]
    fn rib_sides_other_than_one_or_two_warn() {
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, "Sides 3\n", "sides.rib").expect("loads");
        assert_eq!(loaded.warnings.len(), 1);
        assert_eq!(loaded.warnings[0].severity, Severity::Warning);
    }

    /// A square at z = 0 and another at z = -1, both from -1 to 1 in x and y.
    const TWO_SQUARES: &str = "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] \
                               Polygon \"P\" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1]";

    #[test]
    fn rib_clipping_planes_cut_what_their_normal_points_to() {
        let from_front = [([-0.5, 0.0, 5.0], -1.0), ([0.5, 0.0, 5.0], -1.0)];
        let t = |before: &str, world: &str| camera_hit_distances(before, world, &from_front);
        assert_eq!(t("", TWO_SQUARES), [5.0, 5.0]);
        // x > 0 is cut away, both squares.
        assert_eq!(t("", &format!("ClippingPlane 0 0 0 1 0 0 {TWO_SQUARES}")), [5.0, f32::INFINITY]);
        // z > -0.5 is cut: the rays go on to the square behind.
        assert_eq!(t("", &format!("ClippingPlane 0 0 -0.5 0 0 1 {TWO_SQUARES}")), [6.0, 6.0]);
        // In the current space: moved by the transform, which the geometry after it does not see.
        let moved = format!("TransformBegin Translate 0 0 -1.5 ClippingPlane 0 0 1 0 0 1 TransformEnd {TWO_SQUARES}");
        assert_eq!(t("", &moved), [6.0, 6.0]);
        // Two planes: each cuts.
        let both = format!("ClippingPlane 0 0 0 1 0 0 ClippingPlane 0 0 -0.5 0 0 1 {TWO_SQUARES}");
        assert_eq!(t("", &both), [6.0, f32::INFINITY]);
    }

    #[test]
    fn rib_clipping_planes_before_world_begin_are_in_camera_space() {
        // The plane 5.5 in front of the camera, cutting what is nearer; the world 5 in front.
        let before = "ClippingPlane 0 0 5.5 0 0 -1 Translate 0 0 5";
        let rays = [([0.5, 0.0, -10.0], 1.0)];
        let mirrored_squares = "Scale 1 1 -1 ".to_string() + TWO_SQUARES;
        // The squares at world z = 0 (camera 5, cut) and z = 1 (camera 6, kept).
        assert_eq!(camera_hit_distances(before, &mirrored_squares, &rays), [11.0]);
        assert_eq!(camera_hit_distances("Translate 0 0 5", &mirrored_squares, &rays), [10.0]);
    }

    #[test]
    fn rib_clipping_plane_with_no_normal_warns() {
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, "ClippingPlane 0 0 0 0 0 0\n", "clip.rib").expect("loads");
        assert_eq!(loaded.warnings.len(), 1);
        assert_eq!(loaded.warnings[0].loc.line, 1);
        assert!(rt.options.clipping_planes.is_empty());
    }

    #[test]
    fn rib_make_cube_face_environment_writes_a_latlong_map() {
        let dir = tempfile::tempdir().expect("a directory");
        for (k, face) in ["px", "nx", "py", "ny", "pz", "nz"].iter().enumerate() {
            let bytes: Vec<u8> = (0..16).flat_map(|_| [40 * k as u8, 0, 0]).collect();
            ::image::save_buffer(
                dir.path().join(format!("{face}.png")),
                &bytes,
                4,
                4,
                ::image::ExtendedColorType::Rgb8,
            )
            .expect("a face");
        }
        let rib = "MakeCubeFaceEnvironment \"px.png\" \"nx.png\" \"py.png\" \"ny.png\" \"pz.png\" \"nz.png\" \
                   \"env.tex\" 95 \"gaussian\" 2 2\n";
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, rib, dir.path().join("env.rib")).expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let map = crate::texture::load_texture_image(&dir.path().join("env.tex"), false).expect("a map").image;
        assert_eq!((map.width(), map.height()), (16, 8));
        // A missing face: nothing is written, and the map is missing from the picture.
        let rib = rib.replace("nz.png", "absent.png").replace("env.tex", "other.tex");
        let loaded = load_str(&mut rt, &rib, dir.path().join("env.rib")).expect("loads");
        assert_eq!(loaded.omissions(), 1, "{:?}", loaded.warnings);
        assert!(loaded.warnings[0].message.contains("absent.png"), "{:?}", loaded.warnings);
        assert!(!dir.path().join("other.tex").exists());
    }

    const SAVE: &str = "Resource \"a\" \"attributes\" \"string operation\" \"save\"";
    const RESTORE: &str = "Resource \"a\" \"attributes\" \"string operation\" \"restore\"";

    #[test]
    fn rib_resources_save_and_restore_attribute_subsets() {
        let sees = |world: &str| camera_hits("", world, &BEHIND_AND_FRONT);
        assert_eq!(sees(&format!("Sides 1 {SAVE} Sides 2 {RESTORE} {TRIANGLE}")), [false, true]);
        let only = |subset: &str| format!("Sides 1 {SAVE} Sides 2 {RESTORE} \"string subset\" \"{subset}\" {TRIANGLE}");
        assert_eq!(sees(&only("geometrymodification")), [false, true]);
        assert_eq!(sees(&only("shading")), [true, true]);
        assert_eq!(sees(&only("shading,geometrymodification")), [false, true]);
        // The transform, restored or not.
        let moved = |subset: &str| {
            let world = format!("Translate 0 0 3 {SAVE} Identity {RESTORE} \"string subset\" \"{subset}\" {TRIANGLE}");
            camera_hit_distances("", &world, &[([0.2, 0.2, 5.0], -1.0)])[0]
        };
        assert_eq!(moved("transform"), 2.0);
        assert_eq!(moved("shading"), 5.0);
        // Orientation is a geometry modification too.
        assert_eq!(sees(&format!("Sides 1 {SAVE} ReverseOrientation {RESTORE} {TRIANGLE}")), [false, true]);
    }

    /// The colour of the material of the first instance of the world `rib` makes.
    fn first_colour(rib: &str) -> [f32; 3] {
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &format!("Projection \"perspective\" WorldBegin {rib} WorldEnd"), "r.rib")
            .expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let world = rt.build_world().expect("a world");
        world.materials[world.instances[0].material as usize].color
    }

    #[test]
    fn rib_resources_restore_shading_and_follow_resource_blocks() {
        let colour = |rest: &str| first_colour(&format!("Color 1 0 0 {SAVE} Color 0 1 0 {rest} {TRIANGLE}"));
        assert_eq!(colour(RESTORE), [1.0, 0.0, 0.0]);
        assert_eq!(colour(&format!("{RESTORE} \"string subset\" \"transform\"")), [0.0, 1.0, 0.0]);
        // A name saved in an inner block hides the outer one there, and is forgotten at its end.
        let rib =
            format!("Color 1 0 0 {SAVE} ResourceBegin Color 0 0 1 {SAVE} Color 0 1 0 {RESTORE} ResourceEnd {TRIANGLE}");
        assert_eq!(first_colour(&rib), [0.0, 0.0, 1.0]);
        let rib = format!("Color 0 0 1 ResourceBegin Color 1 0 0 {SAVE} ResourceEnd {RESTORE} {TRIANGLE}");
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &format!("WorldBegin {rib} WorldEnd"), "r.rib").expect("loads");
        assert_eq!(loaded.omissions(), 1, "{:?}", loaded.warnings);
        assert!(loaded.warnings[0].message.contains("no attributes were saved as \"a\""));
    }

    #[test]
    fn rib_resource_mistakes_warn() {
        let mut rt = Context::new();
        let rib = "ResourceEnd\nResource \"a\" \"texture\"\nResource \"a\" \"attributes\"\n\
                   Resource \"a\" \"attributes\" \"string operation\" \"load\"\n\
                   Resource \"a\" \"attributes\" \"string operation\" \"save\"\n\
                   Resource \"a\" \"attributes\" \"string operation\" \"restore\" \"string subset\" \"colour\"\n";
        let loaded = load_str(&mut rt, rib, "r.rib").expect("loads");
        let lines: Vec<(u32, Severity)> = loaded.warnings.iter().map(|w| (w.loc.line, w.severity)).collect();
        assert_eq!(
            lines,
            [
                (1, Severity::Warning),
                (2, Severity::Omission),
                (3, Severity::Warning),
                (4, Severity::Warning),
                (6, Severity::Warning)
            ]
        );
    }

    #[test]
    fn rib_scoped_coordinate_systems_end_with_their_block() {
        let spaces = |rib: &str| {
            let mut rt = Context::new();
            let loaded = load_str(&mut rt, rib, "s.rib").expect("loads");
            let x = rt.coordinate_system_matrix("a").map(|m| m.translation.x);
            (x, loaded.warnings.len())
        };
        // Not named before: kept, so the block's shaders find it as the frame renders.
        assert_eq!(spaces("AttributeBegin Translate 1 0 0 ScopedCoordinateSystem \"a\" AttributeEnd"), (Some(1.0), 0));
        // Named before: that one is back after the block, with a warning.
        let rib = "Translate 2 0 0 CoordinateSystem \"a\" \
                   AttributeBegin Translate 1 0 0 ScopedCoordinateSystem \"a\" AttributeEnd";
        assert_eq!(spaces(rib), (Some(2.0), 1));
        // Nested blocks restore in turn.
        let rib = "Translate 2 0 0 CoordinateSystem \"a\" AttributeBegin Translate 1 0 0 ScopedCoordinateSystem \"a\" \
                   AttributeBegin Translate 1 0 0 ScopedCoordinateSystem \"a\" AttributeEnd";
        assert_eq!(spaces(rib).0, Some(3.0));
        // Outside any block it is `CoordinateSystem`.
        assert_eq!(spaces("Translate 4 0 0 ScopedCoordinateSystem \"a\""), (Some(4.0), 0));
    }

    #[test]
    fn rib_system_is_refused_and_make_bump_makes_a_texture() {
        let dir = tempfile::tempdir().expect("a directory");
        ::image::save_buffer(dir.path().join("b.png"), &[10, 20, 30, 40], 2, 2, ::image::ExtendedColorType::L8)
            .expect("a picture");
        let rib = "System \"make all\"\nMakeBump \"b.png\" \"b.tex\" \"periodic\" \"periodic\" \"box\" 1 1\n";
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, rib, dir.path().join("s.rib")).expect("loads");
        let found: Vec<(u32, Severity)> = loaded.warnings.iter().map(|w| (w.loc.line, w.severity)).collect();
        assert_eq!(found, [(1, Severity::Omission), (2, Severity::Warning)], "{:?}", loaded.warnings);
        assert!(loaded.warnings[0].message.contains("runs a program"));
        assert!(loaded.warnings[1].message.contains("texture()"));
        assert!(dir.path().join("b.tex").is_file());
    }

    #[test]
    fn rib_sides_one_and_clipping_planes_hold_for_secondary_and_shadow_rays() {
        use crate::ray::{Ray, RayPacket};
        let world_of = |body: &str| {
            let mut rt = Context::new();
            let rib = format!("Projection \"perspective\" WorldBegin {body} WorldEnd");
            load_str(&mut rt, &rib, "t.rib").expect("loads");
            rt.build_world().expect("a world")
        };
        // Rays from points off the camera's axis, as a reflection or a shadow ray starts.
        let behind = Ray::segment(glam::Vec3A::new(0.2, 0.2, -3.0), glam::Vec3A::Z, 0.0, 10.0);
        let front = Ray::segment(glam::Vec3A::new(0.2, 0.2, 3.0), -glam::Vec3A::Z, 0.0, 10.0);
        let world = world_of(&format!("Sides 1 {TRIANGLE}"));
        assert!(!world.intersect(RayKind::Camera, &behind).is_hit() && !world.occluded(RayKind::Shadow, &behind));
        assert!(world.intersect(RayKind::Camera, &front).is_hit() && world.occluded(RayKind::Shadow, &front));
        let mut packet = RayPacket::new();
        packet.set(0, &behind);
        packet.set(1, &front);
        assert_eq!(world.occluded_packet(RayKind::Shadow, &packet), 0b10);
        assert_eq!(world.lanes_hitting_triangle(&packet, 0b11, 0, 0), 0, "no shortcut past the filter");
        // Two-sided, both are blocked.
        let world = world_of(TRIANGLE);
        assert!(world.occluded(RayKind::Shadow, &behind) && world.occluded(RayKind::Shadow, &front));
        // What a clipping plane cuts away blocks nothing: x > 0 here.
        let world = world_of(&format!("ClippingPlane 0 0 0 1 0 0 {TRIANGLE}"));
        assert!(!world.occluded(RayKind::Shadow, &front) && !world.intersect(RayKind::Camera, &behind).is_hit());
        assert_eq!(world.occluded_packet(RayKind::Shadow, &packet), 0);
    }

    /// `Attribute "visibility"` (and BMRT's `"render" "visibility"`) hides a surface from the
    /// kinds of rays it names, and from those only.
    #[test]
    fn rib_visibility_hides_surfaces_from_the_rays_it_names() {
        use crate::ray::Ray;
        let seen_by = |attributes: &str| {
            let mut rt = Context::new();
            let rib = format!("Projection \"perspective\" WorldBegin Attribute {attributes} {TRIANGLE} WorldEnd");
            let loaded = load_str(&mut rt, &rib, "t.rib").expect("loads");
            assert!(loaded.warnings.is_empty(), "{attributes}: {:?}", loaded.warnings);
            let world = rt.build_world().expect("a world");
            let ray = Ray::segment(glam::Vec3A::new(0.2, 0.2, 3.0), -glam::Vec3A::Z, 0.0, 10.0);
            let kinds = [RayKind::Camera, RayKind::Trace, RayKind::Shadow, RayKind::Photon];
            let hits = kinds.map(|k| world.intersect(k, &ray).is_hit());
            let occludes = kinds.map(|k| world.occluded(k, &ray));
            assert_eq!(hits, occludes, "{attributes}");
            hits
        };
        assert_eq!(seen_by("\"identifier\" \"name\" \"t\""), [true; 4]);
        assert_eq!(seen_by("\"visibility\" \"int camera\" [0]"), [false, true, true, true]);
        assert_eq!(seen_by("\"visibility\" \"int trace\" [0]"), [true, false, true, true]);
        assert_eq!(seen_by("\"visibility\" \"int transmission\" [0]"), [true, true, false, true]);
        assert_eq!(seen_by("\"visibility\" \"string transmission\" \"transparent\""), [true, true, false, true]);
        assert_eq!(seen_by("\"visibility\" \"integer indirect\" [0]"), [true, true, true, false]);
        assert_eq!(seen_by("\"visibility\" \"int photon\" [0] \"int camera\" [1]"), [true, true, true, false]);
        // One kind of secondary ray: seen where either of PRMan's is.
        assert_eq!(seen_by("\"visibility\" \"int diffuse\" [0] \"int specular\" [1]"), [true; 4]);
        assert_eq!(seen_by("\"visibility\" \"int specular\" [1] \"int diffuse\" [0]"), [true; 4]);
        assert_eq!(seen_by("\"visibility\" \"int specular\" [0] \"int diffuse\" [0]"), [true, false, true, true]);
        assert_eq!(seen_by("\"render\" \"integer visibility\" [4]"), [false, false, true, true]);
        assert_eq!(seen_by("\"render\" \"string casts_shadows\" \"none\""), [true, true, false, true]);

        // Attribute blocks scope it, and a value that means nothing is reported.
        let mut rt = Context::new();
        let rib = format!(
            "Projection \"perspective\" WorldBegin AttributeBegin Attribute \"visibility\" \"int camera\" [0] \
             AttributeEnd Attribute \"visibility\" \"string transmission\" \"sometimes\" {TRIANGLE} WorldEnd"
        );
        let loaded = load_str(&mut rt, &rib, "t.rib").expect("loads");
        assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
        assert!(loaded.warnings[0].message.contains("takes 0 or 1, or \"transparent\""), "{:?}", loaded.warnings);
        let world = rt.build_world().expect("a world");
        let ray = Ray::segment(glam::Vec3A::new(0.2, 0.2, 3.0), -glam::Vec3A::Z, 0.0, 10.0);
        assert!(world.intersect(RayKind::Camera, &ray).is_hit() && world.occluded(RayKind::Shadow, &ray));
    }

    #[test]
    fn rib_camera_rays_through_transparent_surfaces_still_skip_backs_and_clipped_parts() {
        use crate::ray::Ray;
        // Half-transparent glass at z = 1, and behind it a triangle whose back faces the camera.
        let rib = format!(
            "Projection \"perspective\" WorldBegin AttributeBegin Opacity [.5 .5 .5] \
             Polygon \"P\" [-5 -5 1  5 -5 1  5 5 1  -5 5 1] AttributeEnd \
             Translate 0 0 3 Sides 1 {TRIANGLE} WorldEnd"
        );
        let mut rt = Context::new();
        load_str(&mut rt, &rib, "t.rib").expect("loads");
        let world = rt.build_world().expect("a world");
        let from_camera = Ray::new(glam::Vec3A::new(0.2, 0.2, 2.0), glam::Vec3A::Z);
        assert!(!world.intersect(RayKind::Camera, &from_camera).is_hit());
        assert!(world.scene.intersect(&from_camera).is_hit());
    }
}

//! What a frame renders: the traceable scene plus everything shading needs (materials, lights, the
//! camera, named coordinate systems, options). The API ([`crate::api::Context`]) and the RIB reader
//! build a [`World`]; the frame loop only reads it.

use super::filter::PixelFilter;
use crate::ray::{Hit, HitCandidate, HitPacket, Ray, RayPacket, PACKET_SIZE};
use crate::scene::Scene;
use crate::shading::{LightKind, ShaderInstance};
use crate::texture::TextureCache;
use glam::{Affine3A, Vec3A};
use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::Arc;

/// How an object's surface looks: its surface shader (none: a matte grey, see [`Material::DEFAULT`]),
/// its colour and opacity (the `Cs` and `Os` globals when its mesh carries none per vertex).
#[derive(Clone, Debug)]
pub struct Material {
    pub surface: Option<Arc<ShaderInstance>>,
    pub color: [f32; 3],
    pub opacity: [f32; 3],
    /// How light paths (virtual lights, photons) meet the surface: its shader is not run on them
    /// (RIB `Attribute "photon" "shadingmodel"`).
    pub photon: PhotonModel,
    /// Shadow rays run the surface shader at hits on this material to find their opacity (PRMan's
    /// `Attribute "shade" "transmissionhitmode" "shader"`); otherwise `opacity` is used.
    pub shadow_by_shader: bool,
    /// The volume shader of the object's inside (RIB `Interior`): it runs on ray segments that
    /// reach this material's surface from behind (`render/volume.rs`).
    pub interior: Option<Arc<ShaderInstance>>,
    /// The displacement shader, run before the surface shader as bump mapping (its `N` becomes
    /// the surface shader's; the geometry does not move), or, with `true_displacement`, over the
    /// points of the diced mesh before the frame (`render/true_displacement.rs`).
    pub displacement: Option<Arc<ShaderInstance>>,
    /// Whether the displacement shader moves the geometry: the object is diced and the shader's
    /// `P` moves its points (RIB `Attribute "displacementbound"`, `"trace" "displacements"`); see
    /// [`Material::displacing_shader`].
    pub true_displacement: bool,
    /// The area in pixels of the micropolygons a truly displaced object is diced into
    /// (RenderMan's `ShadingRate`): their edges are about its square root in pixels long.
    pub shading_rate: f32,
    /// Rays do not see the back of its triangles (RIB `Sides 1`): the side their winding's normal
    /// `(b - a) x (c - a)` points away from ([`World::intersect_packet`]).
    pub one_sided: bool,
    /// The kinds of rays that see the surface (RenderMan's `Attribute "visibility"`).
    pub visibility: Visibility,
    /// A holdout (RenderMan's `Matte 1`): where camera rays meet it, the image is transparent
    /// black and nothing behind it shows; it is not shaded for them. Other rays meet it as any
    /// surface.
    pub matte: bool,
    /// The object's name (RIB `Attribute "identifier" "name"`), which `attribute("identifier:name")`
    /// answers.
    pub identifier: Option<Arc<str>>,
    /// The bounces rays may take beyond the surface ([`TraceDepths`]).
    pub trace_depths: TraceDepths,
    /// How far along the rays its shading spawns start (RenderMan's `Attribute "trace" "bias"`,
    /// in world units): their first hit is at least this far, or rtsl's own offset
    /// ([`super::work::launch_epsilon`]) where that is longer. 0 by default.
    pub trace_bias: f32,
    /// An id the pixel shader and adaptive sampling may read (`objectid`).
    pub object_id: u32,
    /// Shade with Rust code instead of `surface` (`render/native.rs`).
    pub native: Option<Arc<dyn super::native::NativeSurface>>,
    /// The object's own ray parameter values, which rays reaching it and the rays its shading
    /// spawns read (`render/ray_params.rs`).
    pub ray_values: Vec<(String, super::RayValue)>,
}

/// The simplified shading model light paths use at a surface instead of its shader (PRMan's and
/// 3Delight's `Attribute "photon" "shadingmodel"`), its colour the material's `Color`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PhotonModel {
    /// Diffuse reflection: virtual lights and photons are left here.
    #[default]
    Matte,
    /// A mirror: paths reflect, tinted by the colour.
    Chrome,
    /// A dielectric of refractive index `eta`: paths reflect or refract in Fresnel's proportions,
    /// the refracted ones tinted by the colour.
    Glass { eta: f32 },
    /// Paths pass through unchanged.
    Transparent,
}

impl PhotonModel {
    /// The model a RIB names: `matte` (or `""`), `chrome`, `glass` (1.5), `water` (1.33),
    /// `dielectric` (1.5), `refractive:ior=N`, `transparent`.
    pub fn parse(name: &str) -> Result<PhotonModel, String> {
        Ok(match name {
            "" | "matte" => PhotonModel::Matte,
            "chrome" => PhotonModel::Chrome,
            "glass" | "dielectric" => PhotonModel::Glass { eta: 1.5 },
            "water" => PhotonModel::Glass { eta: 1.33 },
            "transparent" => PhotonModel::Transparent,
            other => match other.strip_prefix("refractive:ior=").map(str::parse::<f32>) {
                Some(Ok(eta)) if eta.is_finite() && eta >= 1.0 => PhotonModel::Glass { eta },
                _ => {
                    return Err(format!(
                        "photon shading model \"{other}\" is none of matte, chrome, glass, water, dielectric, transparent, refractive:ior=N (N at least 1)"
                    ))
                }
            },
        })
    }
}

/// The material of geometry with none (a stale id, or the default slot).
pub static DEFAULT_MATERIAL: Material = Material::DEFAULT;

impl Material {
    pub const DEFAULT: Material = Material {
        surface: None,
        color: [1.0; 3],
        opacity: [1.0; 3],
        photon: PhotonModel::Matte,
        shadow_by_shader: false,
        interior: None,
        displacement: None,
        true_displacement: false,
        shading_rate: 1.0,
        one_sided: false,
        visibility: Visibility::ALL,
        matte: false,
        identifier: None,
        trace_depths: TraceDepths::UNBOUNDED,
        trace_bias: 0.0,
        object_id: 0,
        native: None,
        ray_values: Vec::new(),
    };

    /// The shader whose `P` moves the object's points under true displacement (`None` where the
    /// material does not truly displace), and whether the `N` it leaves becomes the points'
    /// normals. The displacement shader, with its normals; without one, a surface shader that
    /// assigns `P`, as a REYES renderer moves the micropolygons wherever the surface shader leaves
    /// them (the inverted hull of a toon outline), with the normals kept: a surface shader's `N`
    /// serves its own shading, not the geometry's. Where there is a displacement shader, only its
    /// `P` moves the geometry.
    pub fn displacing_shader(&self) -> Option<(&Arc<ShaderInstance>, bool)> {
        if !self.true_displacement {
            return None;
        }
        if let Some(displacement) = &self.displacement {
            return Some((displacement, true));
        }
        let surface = self.surface.as_ref()?;
        surface.program.slots.p.is_some_and(|p| p.written).then_some((surface, false))
    }

    /// Whether light passes through this material without running its shader.
    pub fn is_opaque_for_shadows(&self) -> bool {
        !self.shadow_by_shader && self.opacity.iter().all(|o| *o >= 1.0)
    }
}

/// What a shadow ray does at a triangle, by its material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowKind {
    /// It stops there (the material is opaque for shadows).
    Blocked,
    /// It passes, dimmed by the material's opacity.
    Crossed,
    /// The material's shader says how much passes (`Material::shadow_by_shader`).
    ByShader,
}

/// How a pixel's depth (the `z` channel, shadow maps) is taken from the surfaces its first camera
/// ray meets: RenderMan's `Hider "hidden" "depthfilter"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum DepthFilter {
    /// The nearest surface's (of those opaque enough: [`RenderOptions::depth_threshold`]).
    #[default]
    Min,
    /// The farthest surface's of those opaque enough that the camera ray meets before it stops
    /// (at the opacity threshold, or an opaque surface): Aqsis's `"max"`.
    Max,
    /// Halfway between the nearest surface and the next one behind it, infinitely far where there
    /// is none (Woo's midpoint shadow maps, as Aqsis computes them): a surface is then never behind
    /// its own depth in a shadow map, so it does not shadow itself, with no bias.
    Midpoint,
}

/// What a ray is traced for, which decides the surfaces it sees ([`Visibility`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayKind {
    /// Camera rays, and the rays going on from them through transparent surfaces.
    Camera,
    /// Rays shaders trace (`trace`, `gather`, `occlusion`, `indirectdiffuse`, reflections and
    /// refractions), and those going on from them.
    Trace,
    /// Shadow rays toward lights (and from virtual lights), and `transmission`.
    Shadow,
    /// Light paths: virtual lights' and photons' paths from the lights.
    Photon,
}

/// The kinds of rays that see a surface: RenderMan's `Attribute "visibility"` ("camera",
/// "trace" or "specular" and "diffuse", "transmission", "photon" or "indirect"). Every kind sees
/// every surface unless told otherwise (unlike PRMan, whose ray tracing is opt-in).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Visibility(u8);

impl Visibility {
    pub const ALL: Visibility = Visibility(0b1111);

    fn bit(kind: RayKind) -> u8 {
        match kind {
            RayKind::Camera => 1,
            RayKind::Trace => 2,
            RayKind::Shadow => 4,
            RayKind::Photon => 8,
        }
    }

    /// Whether rays of `kind` see the surface.
    #[inline]
    pub fn sees(self, kind: RayKind) -> bool {
        self.0 & Visibility::bit(kind) != 0
    }

    /// This visibility with rays of `kind` seeing the surface or not.
    pub fn with(self, kind: RayKind, visible: bool) -> Visibility {
        let bit = Visibility::bit(kind);
        Visibility(if visible { self.0 | bit } else { self.0 & !bit })
    }
}

impl Default for Visibility {
    fn default() -> Self {
        Visibility::ALL
    }
}

/// How many diffuse and how many specular bounces rays may take beyond a surface (RenderMan's
/// `Attribute "trace" "maxdiffusedepth"` and `"maxspeculardepth"`). A diffuse bounce is a ray of
/// `indirectdiffuse()`; a specular one a ray of `trace()` (reflections, refractions). A ray
/// carries the bounces its path took and the most it may take; where it reaches a surface, that
/// most becomes the smaller of what it carried and its bounces so far plus the surface's own
/// (PRMan's rule), so a surface can lower what rays beyond it do but not raise what an earlier
/// surface allowed. A call whose ray would take a bounce past that answers as past the ray
/// depth. `Option "trace" "maxdepth"` bounds all rays together beside them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TraceDepths {
    pub diffuse: u32,
    pub specular: u32,
}

impl TraceDepths {
    /// No bound but the ray depth: the API's default.
    pub const UNBOUNDED: TraceDepths = TraceDepths { diffuse: u32::MAX, specular: u32::MAX };
    /// PRMan's defaults, which RIB files get: one diffuse bounce and two specular ones.
    pub const RENDERMAN: TraceDepths = TraceDepths { diffuse: 1, specular: 2 };
}

impl Default for TraceDepths {
    fn default() -> Self {
        TraceDepths::UNBOUNDED
    }
}

/// What shadow rays do at the triangles of one instance, worked out once a frame: a shadow ray's
/// hit filter asks for every candidate, and finding the triangle's material and then the
/// material's opacity would be two dependent loads a candidate (in a city with glass windows, most
/// candidates are on its few transparent parts).
#[derive(Clone, Debug, PartialEq)]
pub enum InstanceShadows {
    /// Every material of the instance blocks shadows.
    Opaque,
    /// Each part's kind (as `InstanceParts::materials`), and the instance material's, which
    /// triangles without a part get (as [`InstanceShading::material_at`]).
    Some { parts: Option<Box<[ShadowKind]>>, fallback: ShadowKind },
}

impl InstanceShadows {
    /// The kind of triangle `primitive` of `inst` (the instance these were worked out for):
    /// [`World::shadow_kind`] of its [`InstanceShading::material_at`].
    #[inline]
    pub fn kind(&self, inst: &InstanceShading, primitive: u32) -> ShadowKind {
        match self {
            InstanceShadows::Opaque => ShadowKind::Blocked,
            InstanceShadows::Some { parts, fallback } => {
                let part = inst.parts.as_ref().and_then(|p| p.of_triangle.get(primitive as usize));
                part.and_then(|&k| parts.as_ref()?.get(k as usize)).copied().unwrap_or(*fallback)
            }
        }
    }
}

/// How one instance of the scene is shaded: its material and where it is.
#[derive(Clone, Debug)]
pub struct InstanceShading {
    /// The material of the whole object, or of its first part when it has parts.
    pub material: u32,
    pub object: u32,
    pub world_from_object: Affine3A,
    /// The materials of an object built in parts (`Context::end_part`), `None` for one material.
    pub parts: Option<InstanceParts>,
    /// Whether `object` is a mesh its displacement shaders moved already (true displacement,
    /// `render/true_displacement.rs`): hits on its truly displacing materials are not displaced
    /// again (other parts' displacement shaders bump-map as ever).
    pub displaced: bool,
}

/// Which material shades each triangle of an object built in parts.
#[derive(Clone, Debug)]
pub struct InstanceParts {
    /// Each triangle's part.
    pub of_triangle: Arc<[u32]>,
    /// Each part's material.
    pub materials: Arc<[u32]>,
}

impl InstanceShading {
    /// The material that shades triangle `primitive` of the instance's object (the object's own
    /// for a triangle the parts do not know).
    #[inline]
    pub fn material_at(&self, primitive: u32) -> u32 {
        match &self.parts {
            None => self.material,
            Some(p) => {
                let part = p.of_triangle.get(primitive as usize).copied();
                part.and_then(|k| p.materials.get(k as usize).copied()).unwrap_or(self.material)
            }
        }
    }

    /// Every material of the instance: its own, or each part's.
    pub fn materials(&self) -> impl Iterator<Item = u32> + '_ {
        let parts = self.parts.as_ref().map(|p| &p.materials[..]).unwrap_or(&[]);
        std::iter::once(self.material).filter(move |_| parts.is_empty()).chain(parts.iter().copied())
    }
}

/// A light source: a light shader instance and whether it casts shadows.
#[derive(Clone, Debug)]
pub struct LightSource {
    pub shader: Arc<ShaderInstance>,
    pub kind: LightKind,
    /// The renderer traces shadow rays towards the light (RenderMan ray tracers' `Attribute "light"
    /// "shadows" "on"`); lights that compute their own shadows turn this off.
    pub shadows: bool,
    /// The categories the light belongs to (its `__category` parameter, comma separated).
    pub categories: Vec<String>,
    /// For area lights: the instance of the geometry that emits, sampled for soft shadows.
    pub area: Option<AreaLight>,
}

/// The emitting geometry of an area light: triangles in world space with their cumulative areas.
#[derive(Clone, Debug, Default)]
pub struct AreaLight {
    pub triangles: Vec<[Vec3A; 3]>,
    pub cumulative_area: Vec<f32>,
    /// Samples per shading point.
    pub samples: u32,
}

/// The most samples an area light takes per shading point (each is a light in the `illuminance` loop).
pub const MAX_AREA_SAMPLES: u32 = 24;

impl AreaLight {
    pub fn new(triangles: Vec<[Vec3A; 3]>, samples: u32) -> AreaLight {
        let mut total = 0.0;
        let cumulative_area = triangles
            .iter()
            .map(|[a, b, c]| {
                total += 0.5 * (*b - *a).cross(*c - *a).length();
                total
            })
            .collect();
        AreaLight { triangles, cumulative_area, samples: samples.max(1) }
    }

    pub fn area(&self) -> f32 {
        self.cumulative_area.last().copied().unwrap_or(0.0)
    }

    /// A point on the light for the two uniform numbers `r1`, `r2` in [0, 1), and its unit normal.
    pub fn sample(&self, r0: f32, r1: f32, r2: f32) -> Option<(Vec3A, Vec3A)> {
        let total = self.area();
        if total <= 0.0 {
            return None;
        }
        let target = r0 * total;
        let i = self.cumulative_area.partition_point(|c| *c < target).min(self.triangles.len() - 1);
        let [a, b, c] = self.triangles[i];
        let (mut u, mut v) = (r1, r2);
        if u + v > 1.0 {
            u = 1.0 - u;
            v = 1.0 - v;
        }
        let p = a + (b - a) * u + (c - a) * v;
        Some((p, (b - a).cross(c - a).normalize_or_zero()))
    }
}

impl LightSource {
    pub fn in_category(&self, category: &str) -> bool {
        if category.is_empty() {
            return true;
        }
        // RISpec: a leading '-' excludes the category.
        match category.strip_prefix('-') {
            Some(c) => !self.categories.iter().any(|x| x == c),
            None => self.categories.iter().any(|x| x == category),
        }
    }
}

/// A pinhole camera in RenderMan's terms: camera space has +x right, +y up and +z forward, and the
/// field of view spans the shorter side of the image.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraSetup {
    pub world_from_camera: Affine3A,
    pub fov_degrees: f32,
    pub near: f32,
    pub far: f32,
}

impl Default for CameraSetup {
    fn default() -> Self {
        CameraSetup { world_from_camera: Affine3A::IDENTITY, fov_degrees: 90.0, near: 1e-2, far: 1e4 }
    }
}

impl CameraSetup {
    /// A camera at `eye` looking at `target`, `up` pointing up in the image.
    pub fn look_at(eye: Vec3A, target: Vec3A, up: Vec3A, fov_degrees: f32) -> CameraSetup {
        let forward = (target - eye).normalize_or(Vec3A::NEG_Z);
        let right = forward.cross(up).normalize_or(Vec3A::X);
        let up = right.cross(forward);
        // Camera space is left-handed, so this matrix mirrors: its determinant is negative.
        let world_from_camera = Affine3A::from_cols(right, up, forward, eye);
        CameraSetup { world_from_camera, fov_degrees, ..CameraSetup::default() }
    }

    pub fn eye(&self) -> Vec3A {
        self.world_from_camera.translation
    }
}

/// How pixels are sampled (OpenRT paper, 5.1.2).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Antialiasing {
    /// The `samples` grid in every pixel, at the cells' centres or jittered within them.
    Grid { jitter: bool },
    /// Quasi-Monte Carlo interleaved sampling (Keller and Heidrich 2001): the pixels of each 4x4
    /// block take successive runs of one Halton sequence.
    Interleaved,
    /// One sample per pixel, then a jittered grid of extra samples (`samples`, or 2x2) where a pixel
    /// differs from a neighbour by more than `threshold` in a colour channel or in what it hit
    /// (what is compared: [`RenderOptions::refine_on`]).
    Adaptive { threshold: f32 },
}

impl Antialiasing {
    /// Parses `grid`, `regular`, `jittered`, `interleaved` (`qmc`) or `adaptive[:THRESHOLD]`.
    pub fn parse(s: &str) -> Result<Antialiasing, String> {
        let (name, arg) = s.split_once(':').map_or((s, None), |(a, b)| (a, Some(b)));
        match (name, arg) {
            ("regular", None) => Ok(Antialiasing::Grid { jitter: false }),
            ("grid" | "jittered", None) => Ok(Antialiasing::Grid { jitter: true }),
            ("interleaved" | "qmc", None) => Ok(Antialiasing::Interleaved),
            ("adaptive", None) => Ok(Antialiasing::Adaptive { threshold: 0.05 }),
            ("adaptive", Some(t)) => t
                .parse::<f32>()
                .ok()
                .filter(|t| t.is_finite() && *t >= 0.0)
                .map(|threshold| Antialiasing::Adaptive { threshold })
                .ok_or_else(|| format!("`{t}` is not a threshold (a number, at least 0)")),
            _ => Err(format!("unknown anti-aliasing mode `{s}` (regular, jittered, interleaved, adaptive[:T])")),
        }
    }
}

/// What adaptive anti-aliasing compares between neighbouring pixels' first samples
/// ([`Antialiasing::Adaptive`]): a pixel is refined where any chosen criterion differs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RefineOn {
    /// A colour or alpha channel differing by more than the threshold.
    pub color: bool,
    /// Another object hit (its `objectid`), or a hit beside a miss.
    pub object: bool,
    /// Another material (shader binding) hit.
    pub shader: bool,
    /// An output variable of the surface shader of the first hit (a float or a triple: a mask, a
    /// normal, a material parameter), a component differing by more than the threshold. Where
    /// the shader has no such output (or a miss) it reads 0.
    pub output: Option<String>,
}

impl Default for RefineOn {
    fn default() -> RefineOn {
        RefineOn { color: true, object: true, shader: true, output: None }
    }
}

impl RefineOn {
    /// Parses a comma-separated list of `color`, `object`, `shader` and `output:NAME` (at least
    /// one).
    pub fn parse(s: &str) -> Result<RefineOn, String> {
        let mut on = RefineOn { color: false, object: false, shader: false, output: None };
        for item in s.split(',').map(str::trim) {
            match item.split_once(':') {
                None if item == "color" || item == "colour" => on.color = true,
                None if item == "object" => on.object = true,
                None if item == "shader" => on.shader = true,
                Some(("output", name)) if !name.trim().is_empty() => on.output = Some(name.trim().to_string()),
                _ => return Err(format!("`{item}` is not color, object, shader or output:NAME")),
            }
        }
        if !(on.color || on.object || on.shader || on.output.is_some()) {
            return Err(format!("`{s}` names nothing to refine on"));
        }
        Ok(on)
    }
}

/// The most output variables a frame keeps per pixel ([`RenderOptions::outputs`], and the one
/// adaptive sampling may refine on).
pub const MAX_FRAME_OUTPUTS: usize = 4;

/// The most pixels a side of an image may have.
pub const MAX_IMAGE_SIDE: u32 = 32768;

/// The most pixels an image may have (`8192 x 4096`, or `5792 x 5792`). A frame's framebuffer, its
/// tiles' samples and the encoded file all grow with the pixel count; the cap keeps them under
/// 3 GiB together (`docs/rendering.md`, "Limits").
pub const MAX_IMAGE_PIXELS: u64 = 1 << 25;

/// Whether `width x height` is an image size rtsl renders: at least one pixel, at most
/// [`MAX_IMAGE_SIDE`] a side and [`MAX_IMAGE_PIXELS`] in all. The error says which limit is passed.
pub fn check_image_size(width: u64, height: u64) -> Result<(), String> {
    let size = format!("{width}x{height}");
    if width == 0 || height == 0 {
        return Err(format!("image size {size} has no pixels"));
    }
    if width > u64::from(MAX_IMAGE_SIDE) || height > u64::from(MAX_IMAGE_SIDE) {
        return Err(format!("image size {size} is too large: at most {MAX_IMAGE_SIDE} pixels a side"));
    }
    if width * height > MAX_IMAGE_PIXELS {
        return Err(format!(
            "image size {size} is too large: {} pixels, at most {MAX_IMAGE_PIXELS} (8192x4096)",
            width * height
        ));
    }
    Ok(())
}

/// Samples per pixel along each axis: what RIB's `PixelSamples` and the command line's `--samples`
/// may ask for, and what a frame takes of [`RenderOptions::samples`] (64x64 is more than any image
/// needs; it keeps a pixel's sample indices far inside `u32`).
pub const MAX_PIXEL_SAMPLES: u32 = 64;

/// Render settings (RenderMan's options).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel along x and y (RIB `PixelSamples`), on a jittered grid; a frame takes
    /// each as 1 to [`MAX_PIXEL_SAMPLES`] ([`RenderOptions::pixel_samples`]).
    pub samples: (u32, u32),
    /// The deepest `trace` recursion (primary rays are depth 0).
    pub max_ray_depth: u32,
    /// The colour of rays that hit nothing.
    pub background: [f32; 3],
    /// Most transparent surfaces a ray continues through.
    pub max_transparent_layers: u32,
    /// RenderMan's opacity threshold (RIB `Option "limits" "othreshold"`): a camera ray goes on
    /// through the surfaces it meets until the opacity they add up to reaches this in every
    /// channel; what lies behind is then hidden. The default is 255/256: PRMan's 0.996, to the
    /// nearest 1/256.
    #[serde(default = "default_opacity_threshold")]
    pub opacity_threshold: [f32; 3],
    /// RenderMan's depth threshold (RIB `Option "limits" "zthreshold"`): a pixel's depth (`z`
    /// displays, `zfile` and `shadow` maps) is that of the first surface its camera ray meets
    /// whose own opacity reaches this in every channel, infinitely far where none does. `[0, 0,
    /// 0]` (the API's default) takes the first surface whatever its opacity; a RIB file gets
    /// PRMan's and 3Delight's 0.996, which leaves semi-transparent surfaces out.
    #[serde(default)]
    pub depth_threshold: [f32; 3],
    /// The threads a frame renders on, as the scene asks (RIB `Option "limits" "threads"`,
    /// 3Delight's `"render" "nthreads"`) where whoever renders lets it decide (`rtsl render`
    /// without `--threads`); `None`: one a core.
    #[serde(default)]
    pub threads: Option<u32>,
    /// The bias of shadow-map lookups that give none (`shadow()` without `"bias"`): RIB's
    /// `Option "shadow" "bias"` (both), `"bias0"` and `"bias1"` (Aqsis's ramp: a point is
    /// lit up to the lower bias behind the stored depth and in shadow from the higher one,
    /// gradually in between). `[0, 0]` by default, as Aqsis.
    #[serde(default)]
    pub shadow_bias: [f32; 2],
    /// The depth a pixel's first camera sample gives it (RIB `Hider "hidden" "depthfilter"`).
    #[serde(default)]
    pub depth_filter: DepthFilter,
    /// RIB's `Exposure gain gamma`, applied to the finished colours: `(gain * c) ^ (1 / gamma)`.
    pub exposure: Option<(f32, f32)>,
    /// The transfer curve of the scene's 8- and 16-bit images, the files a render writes and the
    /// textures it reads: sRGB by default (what displays expect of such files); linear for RIB
    /// scenes, which RenderMan writes as computed (RISpec's default `Exposure 1 1`) and whose
    /// textures it reads as stored.
    #[serde(default)]
    pub image_transfer: crate::image_io::Transfer,
    /// RIB's `Quantize "rgba"`: how colour and alpha are stored in the images written (`None`:
    /// 8 bits, rounded; see [`crate::image_io::Quantize`]).
    pub quantize: Option<crate::image_io::Quantize>,
    pub antialiasing: Antialiasing,
    /// The shutter interval (RIB `Shutter open close`): each primary ray gets a time in it, and
    /// moving instances are where they are at that time. `(0, 0)`: no motion blur.
    pub shutter: (f32, f32),
    /// RIB's `DepthOfField fstop focallength focaldistance`, which the `thinlens` camera shader
    /// reads (`option("DepthOfField", ...)`); the built-in camera is a pinhole.
    pub depth_of_field: Option<[f32; 3]>,
    /// RIB's `ScreenWindow left right bottom top`: the part of screen space (the perspective
    /// projection, `x / (z tan(fov/2))`) the image shows. `None`: the shorter side of the image
    /// spans [-1, 1], centred.
    pub screen_window: Option<[f32; 4]>,
    /// RIB's `FrameAspectRatio`: the default screen window's aspect (`None`: the image's).
    pub frame_aspect_ratio: Option<f32>,
    /// RIB's `CropWindow xmin xmax ymin ymax` (NDC, y down): only pixels from `ceil(width * xmin)`
    /// to `ceil(width * xmax) - 1` (and likewise in y) are rendered; the rest stay empty (black,
    /// alpha 0). `None`: the whole image.
    pub crop_window: Option<[f32; 4]>,
    /// User clipping planes (RIB `ClippingPlane`), each a point on the plane and its normal in
    /// world space: no ray sees what lies on the side the normal points to.
    #[serde(default)]
    pub clipping_planes: Vec<[f32; 6]>,
    /// RIB's `PixelFilter "name" xwidth ywidth`: how samples are weighted into pixels. The default
    /// is box 1x1, each pixel the plain mean of its own samples (RenderMan's default is gaussian
    /// 2x2; box 1x1 keeps images as they were and one sample per pixel sharp). Any other filter
    /// splats every sample onto the pixels within its support (`render/film.rs`).
    pub pixel_filter: PixelFilter,
    /// Whether frames time their shaders: the report's shading time and its split by shader type
    /// and by shader. Timing reads the clock on entering and leaving every shader batch and every
    /// tracer call made while shading (a few percent of a frame of many small batches); a caller
    /// that only wants frames and ray counts (BART playback) turns it off, and the report's
    /// shading times are then zero.
    pub time_shaders: bool,
    /// Whether the frame's framebuffer gets each pixel's depth and object id
    /// ([`super::Framebuffer::depth`], [`super::Framebuffer::object_id`]); off, they keep their
    /// blank values (infinity, `u32::MAX`). An application that reads only colour turns it off:
    /// a distributed frame's tiles then travel without them, two thirds of the bytes.
    pub depth_and_ids: bool,
    /// Whether a batch of hits whose surface shader calls `trace` runs the shader twice, so that
    /// the rays of all its chunks are traced and shaded together (`render/trace_ahead.rs`). The
    /// images are the same either way; off, each chunk's rays are traced and shaded on their own
    /// (kept for comparisons).
    pub trace_ahead: bool,
    /// Global illumination by virtual point lights (RIB `Option "gi"`): off unless
    /// `gi.virtual_lights` is set.
    pub gi: GiOptions,
    /// What adaptive anti-aliasing refines on (colour, object and shader by default).
    pub refine_on: RefineOn,
    /// Output variables of the surface shaders a frame keeps per pixel (arbitrary output
    /// variables: RIB `Display` modes that name one): each pixel's mean over its samples of the
    /// value the shader of the first surface hit left (a float in the first of three components;
    /// zero where nothing was hit or the shader has no such output), in
    /// [`super::Framebuffer::outputs`]. At most [`MAX_FRAME_OUTPUTS`] are kept.
    #[serde(default)]
    pub outputs: Vec<String>,
    /// Named values the frame's rays carry, which shaders read with `rayinfo`
    /// (`render/ray_params.rs`); the float parameter [`super::RELEVANCE`] also sets how many
    /// samples each pixel takes.
    pub ray_parameters: super::RayParameters,
}

/// [`RenderOptions::opacity_threshold`]'s default.
fn default_opacity_threshold() -> [f32; 3] {
    [1.0 - 1.0 / 256.0; 3]
}

/// The screen window as centre and half extents, the form the cameras use: screen `x` of raster
/// `x` is `(2 x / w - 1) * half.0 + centre.0` (y up: `(1 - 2 y / h) * half.1 + centre.1`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenExtent {
    pub centre: (f32, f32),
    pub half: (f32, f32),
}

impl RenderOptions {
    /// [`RenderOptions::samples`] as a frame takes them: each 1 to [`MAX_PIXEL_SAMPLES`].
    pub fn pixel_samples(&self) -> (u32, u32) {
        (self.samples.0.clamp(1, MAX_PIXEL_SAMPLES), self.samples.1.clamp(1, MAX_PIXEL_SAMPLES))
    }

    /// The screen window in use (see [`RenderOptions::screen_window`]).
    pub fn screen_extent(&self) -> ScreenExtent {
        let (w, h) = (self.width.max(1) as f32, self.height.max(1) as f32);
        match self.screen_window {
            Some([l, r, b, t]) if l != r && b != t && [l, r, b, t].iter().all(|v| v.is_finite()) => {
                ScreenExtent { centre: (0.5 * (l + r), 0.5 * (b + t)), half: (0.5 * (r - l), 0.5 * (t - b)) }
            }
            _ => {
                let half = match self.frame_aspect_ratio.filter(|a| a.is_finite() && *a > 0.0) {
                    Some(a) if a >= 1.0 => (a, 1.0),
                    Some(a) => (1.0, 1.0 / a),
                    None if w >= h => (w / h, 1.0),
                    None => (1.0, h / w),
                };
                ScreenExtent { centre: (0.0, 0.0), half }
            }
        }
    }

    /// The transfer of this frame's 8-bit images: [`RenderOptions::image_transfer`], unless the
    /// scene applies a gamma of its own (RIB `Exposure` with a gamma other than 1), which then takes
    /// its place.
    pub fn transfer(&self) -> crate::image_io::Transfer {
        match self.exposure {
            Some((_, gamma)) if gamma != 1.0 => crate::image_io::Transfer::Linear,
            _ => self.image_transfer,
        }
    }

    /// Whether 8- and 16-bit textures are read as stored rather than decoded from sRGB.
    pub fn textures_as_stored(&self) -> bool {
        self.image_transfer == crate::image_io::Transfer::Linear
    }

    /// The pixels rendered, `x0..x1` by `y0..y1`: the whole image, or the crop window's.
    pub fn pixel_range(&self) -> (u32, u32, u32, u32) {
        let (w, h) = (self.width, self.height);
        match self.crop_window {
            Some([x0, x1, y0, y1]) if [x0, x1, y0, y1].iter().all(|v| v.is_finite()) => {
                let at = |f: f32, n: u32| ((f.clamp(0.0, 1.0) * n as f32).ceil() as u32).min(n);
                (at(x0, w), at(x1, w), at(y0, h), at(y1, h))
            }
            _ => (0, w, 0, h),
        }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 640,
            height: 480,
            samples: (1, 1),
            max_ray_depth: 6,
            background: [0.0; 3],
            max_transparent_layers: 16,
            opacity_threshold: default_opacity_threshold(),
            depth_threshold: [0.0; 3],
            threads: None,
            shadow_bias: [0.0; 2],
            depth_filter: DepthFilter::Min,
            exposure: None,
            image_transfer: crate::image_io::Transfer::Srgb,
            quantize: None,
            antialiasing: Antialiasing::Grid { jitter: true },
            shutter: (0.0, 0.0),
            depth_of_field: None,
            screen_window: None,
            frame_aspect_ratio: None,
            crop_window: None,
            clipping_planes: Vec::new(),
            pixel_filter: PixelFilter::default(),
            time_shaders: true,
            depth_and_ids: true,
            trace_ahead: true,
            gi: GiOptions::default(),
            refine_on: RefineOn::default(),
            outputs: Vec::new(),
            ray_parameters: super::RayParameters::default(),
        }
    }
}

/// What the application sets for global illumination by virtual point lights (RIB `Option "gi"`,
/// `render/virtual_lights.rs`, `docs/global_illumination.md`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GiOptions {
    /// Light paths traced per frame, over all the lights; 0 turns virtual lights off
    /// (`indirectdiffuse()` then samples the hemisphere with rays).
    pub virtual_lights: u32,
    /// Diffuse bounces a path makes: 1 leaves virtual lights where paths first land (one bounce
    /// of indirect light), 2 where they land next too, and so on.
    pub bounces: u32,
    /// The side of the pixel blocks whose pixels use different sets of virtual lights (1: every
    /// pixel uses every light).
    pub interleave: u32,
    /// The least distance a virtual light counts at, in world units; 0: 1% of the scene's diagonal.
    pub clamp: f32,
    /// Another seed gives another set of paths (a viewer accumulating frames changes it).
    pub seed: u32,
    /// Paths traced per frame for the caustic photon map (`photonmap("caustic", ...)`): those
    /// whose first surface is specular leave a photon on the first diffuse one; 0: no map.
    pub caustic_photons: u32,
    /// Paths traced per frame for the global photon map (`photonmap("global", ...)`): each leaves
    /// a photon on every diffuse surface it reaches, directly or through others, up to `bounces`
    /// + 1 of them; 0: no map.
    pub global_photons: u32,
}

impl Default for GiOptions {
    fn default() -> Self {
        GiOptions {
            virtual_lights: 0,
            bounces: 1,
            interleave: 3,
            clamp: 0.0,
            seed: 0,
            caustic_photons: 0,
            global_photons: 0,
        }
    }
}

/// The most paths a frame traces (for virtual lights, and for caustic photons), and the deepest
/// they go: what any option is clamped to.
pub const MAX_VIRTUAL_LIGHT_PATHS: u32 = 1 << 20;
pub const MAX_BOUNCES: u32 = 8;
pub const MAX_INTERLEAVE: u32 = 8;

/// Everything a frame renders. Build one with [`crate::api::Context`] or the RIB reader.
/// What bringing the acceleration structures up to date cost when the world was built: the
/// BVHs of objects whose geometry changed, and the top level over the instances (rebuilt every
/// frame). Reported with each frame ([`super::FrameReport::accel`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AccelUpdate {
    /// Objects whose BVH was (re)built for this frame.
    pub objects_rebuilt: usize,
    pub object_bvhs: std::time::Duration,
    pub top_level: std::time::Duration,
    pub instances: usize,
    /// Heap bytes of meshes and BVHs (each object once however often instanced).
    pub memory_bytes: usize,
    /// Triangles after instancing (each instance counts its object's triangles).
    pub instanced_triangles: usize,
}

impl AccelUpdate {
    pub fn total(&self) -> std::time::Duration {
        self.object_bvhs + self.top_level
    }
}

pub struct World {
    pub scene: Scene,
    /// What updating the BVHs for this world cost.
    pub accel: AccelUpdate,
    pub materials: Vec<Material>,
    /// One per scene instance, in the scene's instance order.
    pub instances: Vec<InstanceShading>,
    pub lights: Vec<LightSource>,
    /// The pixel shader (RenderMan's imager), run on every finished tile.
    pub pixel: Option<Arc<ShaderInstance>>,
    /// The atmosphere volume shader, run on every ray segment that ends on a surface outside any
    /// object with an interior shader (`render/volume.rs`).
    pub atmosphere: Option<Arc<ShaderInstance>>,
    pub camera: CameraSetup,
    /// The camera shader that generates primary rays; `None` is the built-in pinhole camera.
    pub camera_shader: Option<Arc<ShaderInstance>>,
    pub options: RenderOptions,
    /// Named coordinate systems (`CoordinateSystem`), world from the system.
    pub spaces: HashMap<String, Affine3A>,
    /// Texture, environment and shadow maps, loaded on first use.
    pub textures: Arc<TextureCache>,
    /// Vertex-scope bindings by (instance, material): shader parameter index -> mesh attribute
    /// index, worked out by [`World::prepare`] (only where there is one).
    pub(crate) vertex_params: HashMap<(u32, u32), Vec<(usize, usize)>>,
    /// Which contents the world has, for what is kept across frames traced from it
    /// ([`super::work::LightPathCache`]): unique to each world, renewed by [`World::prepare`].
    version: u64,
    /// Ray parameter names shaders asked for that nothing sets ([`World::shader_messages`]
    /// reports each once; a context shares its own with the worlds it builds).
    pub ray_parameter_misses: Arc<super::ray_params::RayParameterMisses>,
    /// Whether rays filter their hits ([`World::intersect_packet`]): some material is one-sided
    /// or hidden from some rays, or a clipping plane is set. Worked out by [`World::prepare`].
    filters: bool,
    /// Some material is a holdout ([`Material::matte`]).
    mattes: bool,
}

/// The next [`World::version`].
static NEXT_WORLD_VERSION: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn next_world_version() -> u64 {
    NEXT_WORLD_VERSION.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl World {
    pub fn new(scene: Scene) -> World {
        World {
            scene,
            accel: AccelUpdate::default(),
            materials: vec![Material::DEFAULT],
            instances: Vec::new(),
            lights: Vec::new(),
            pixel: None,
            atmosphere: None,
            camera: CameraSetup::default(),
            camera_shader: None,
            options: RenderOptions::default(),
            spaces: HashMap::new(),
            textures: Arc::new(TextureCache::new()),
            vertex_params: HashMap::new(),
            version: next_world_version(),
            ray_parameter_misses: Default::default(),
            filters: false,
            mattes: false,
        }
    }

    /// Which contents the world has: another number for every world and after every
    /// [`World::prepare`], so that what was traced from it before can be told apart.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Commits the scene and works out the bindings that depend on both meshes and shaders. Call
    /// after any change, before rendering.
    pub fn prepare(&mut self) {
        self.version = next_world_version();
        let start = std::time::Instant::now();
        self.scene.commit();
        self.accel.top_level = start.elapsed();
        self.accel.instances = self.scene.instance_count();
        self.accel.memory_bytes = self.scene.memory_bytes();
        self.accel.instanced_triangles = self.scene.instanced_triangle_count();
        let mut vertex_params = HashMap::new();
        for (index, inst) in self.instances.iter().enumerate() {
            // By name, so that a demand-loaded object is not fetched.
            let attributes = self.scene.attribute_names(crate::scene::ObjectId(inst.object));
            if attributes.is_empty() {
                continue;
            }
            for material in inst.materials() {
                let Some(program) = self.materials.get(material as usize).and_then(|m| m.surface.as_ref()) else {
                    continue;
                };
                let layout = program.program.layout();
                let bound: Vec<_> = layout
                    .params
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p.varying && !p.string && !p.output)
                    .filter_map(|(i, p)| {
                        let a = attributes.iter().position(|(name, n)| *name == p.name && *n == p.floats())?;
                        Some((i, a))
                    })
                    .collect();
                if !bound.is_empty() {
                    vertex_params.insert((index as u32, material), bound);
                }
            }
        }
        self.vertex_params = vertex_params;
        self.filters = self.materials.iter().any(|m| m.one_sided || m.visibility != Visibility::ALL)
            || !self.options.clipping_planes.is_empty();
        self.mattes = self.materials.iter().any(|m| m.matte);
    }

    /// Closest hits of a packet of rays of one kind: [`Scene::intersect_packet`], except that
    /// the back of a one-sided material's triangles is not seen, nor what a clipping plane
    /// ([`RenderOptions::clipping_planes`]) cuts away, nor a surface rays of `kind` do not see
    /// ([`Material::visibility`]). RISpec clips geometry from the scene, and PRMan's ray tracing
    /// honours `Sides` for every ray, so no ray meets what the camera cannot see. The tests run
    /// only for scenes that have such a material or plane (a hit filter), so other scenes trace
    /// exactly as before.
    pub fn intersect_packet(&self, kind: RayKind, packet: &RayPacket, out: &mut HitPacket) {
        if !self.filters {
            return self.scene.intersect_packet(packet, out);
        }
        let sees =
            |c: &HitCandidate| c.lane as usize >= PACKET_SIZE || self.sees(kind, &packet.get(c.lane as usize), c);
        self.scene.intersect_packet_filtered(packet, out, Some(&sees));
    }

    /// The closest hit of one ray, as [`World::intersect_packet`] finds those of a packet.
    pub fn intersect(&self, kind: RayKind, ray: &Ray) -> Hit {
        if !self.filters {
            return self.scene.intersect(ray);
        }
        let sees = |c: &HitCandidate| self.sees(kind, ray, c);
        self.scene.intersect_filtered(ray, Some(&sees))
    }

    /// Whether anything rays of `kind` see ([`World::intersect_packet`]) lies on `ray`.
    pub fn occluded(&self, kind: RayKind, ray: &Ray) -> bool {
        if !self.filters {
            return self.scene.occluded(ray);
        }
        let sees = |c: &HitCandidate| self.sees(kind, ray, c);
        self.scene.occluded_filtered(ray, Some(&sees))
    }

    /// The lanes of a packet blocked by what rays of `kind` see ([`World::intersect_packet`]).
    pub fn occluded_packet(&self, kind: RayKind, packet: &RayPacket) -> u64 {
        self.occluded_packet_filtered(kind, packet, None)
    }

    /// [`World::occluded_packet`] by the hits `filter` accepts too (asked only of hits the rays
    /// see).
    pub fn occluded_packet_filtered(&self, kind: RayKind, packet: &RayPacket, filter: crate::ray::HitFilter) -> u64 {
        if !self.filters {
            return self.scene.occluded_packet_filtered(packet, filter);
        }
        let sees = |c: &HitCandidate| {
            (c.lane as usize >= PACKET_SIZE || self.sees(kind, &packet.get(c.lane as usize), c))
                && filter.is_none_or(|f| f(c))
        };
        self.scene.occluded_packet_filtered(packet, Some(&sees))
    }

    /// Whether each of `rays` (of `kind`) is blocked (`blocked[i]` for `rays[i]`), traced as
    /// packets of one direction octant each (see [`in_octant_packets`]).
    pub fn occluded_rays(&self, kind: RayKind, rays: &[Ray], blocked: &mut Vec<bool>) {
        blocked.clear();
        if rays.len() < FEWEST_PACKED_RAYS {
            blocked.extend(rays.iter().map(|r| self.occluded(kind, r)));
            return;
        }
        blocked.resize(rays.len(), false);
        in_octant_packets(rays, |packet, lanes| {
            let hit = self.occluded_packet(kind, packet);
            for (lane, &i) in lanes.iter().enumerate() {
                blocked[i as usize] = hit >> lane & 1 != 0;
            }
        });
    }

    /// The closest hit of each of `rays` (of `kind`; `hits[i]` for `rays[i]`), traced as packets
    /// of one direction octant each (see [`in_octant_packets`]): the hits [`World::intersect`]
    /// finds ray by ray (where two surfaces lie at one distance, either may be the one reported,
    /// as between packets and single rays anywhere).
    pub fn intersect_rays(&self, kind: RayKind, rays: &[Ray], hits: &mut Vec<Hit>) {
        hits.clear();
        if rays.len() < FEWEST_PACKED_RAYS {
            hits.extend(rays.iter().map(|r| self.intersect(kind, r)));
            return;
        }
        hits.resize(rays.len(), Hit::MISS);
        let mut out = HitPacket::default();
        in_octant_packets(rays, |packet, lanes| {
            self.intersect_packet(kind, packet, &mut out);
            for (lane, &i) in lanes.iter().enumerate() {
                hits[i as usize] = out.get(lane);
            }
        });
    }

    /// [`Scene::lanes_hitting_triangle`] for a world whose rays see every hit; none where some
    /// are not seen (a one-sided triangle from behind, a point clipped away, a surface hidden from
    /// some rays), which depends on each ray.
    pub fn lanes_hitting_triangle(&self, packet: &RayPacket, lanes: u64, instance: u32, primitive: u32) -> u64 {
        if self.filters {
            return 0;
        }
        self.scene.lanes_hitting_triangle(packet, lanes, instance, primitive)
    }

    /// Whether camera rays meeting `hit` meet a holdout ([`Material::matte`]).
    #[inline]
    pub fn is_holdout(&self, hit: &Hit) -> bool {
        self.mattes
            && self
                .instances
                .get(hit.instance as usize)
                .and_then(|inst| self.materials.get(inst.material_at(hit.primitive) as usize))
                .is_some_and(|m| m.matte)
    }

    /// Whether ray `ray` of `kind` sees candidate hit `c`: a surface visible to its kind, not the
    /// back of a one-sided triangle, nor a point a clipping plane cuts away. The side is tested in
    /// object space, where it means what it means in world space (a direction and a normal moved
    /// by a matrix and its inverse transpose keep their dot product), so that a mirroring
    /// instance keeps its outside.
    fn sees(&self, kind: RayKind, ray: &Ray, c: &HitCandidate) -> bool {
        let material = self
            .instances
            .get(c.instance as usize)
            .and_then(|inst| self.materials.get(inst.material_at(c.primitive) as usize));
        if material.is_some_and(|m| !m.visibility.sees(kind)) {
            return false;
        }
        let at = ray.at(c.t);
        let clipped = self
            .options
            .clipping_planes
            .iter()
            .any(|&[x, y, z, nx, ny, nz]| (at - Vec3A::new(x, y, z)).dot(Vec3A::new(nx, ny, nz)) > 0.0);
        if clipped {
            return false;
        }
        if !material.is_some_and(|m| m.one_sided) {
            return true;
        }
        let Some(data) = self.scene.instance_data(c.instance) else { return true };
        let Some(mesh) = self.scene.mesh(crate::scene::ObjectId(c.object)) else { return true };
        if c.primitive as usize >= mesh.triangle_count() {
            return true;
        }
        let [a, b, p] = mesh.corners_at(c.primitive as usize, ray.time);
        let object_from_world = match data.motion {
            None => data.object_from_world,
            Some(_) => data.world_from_object_at(ray.time).inverse(),
        };
        let d = glam::Vec3::from(object_from_world.transform_vector3a(ray.direction));
        (b - a).cross(p - a).dot(d) <= 0.0
    }

    /// Shades every material whose surface shader is `shader` with the Rust surface `make` builds
    /// from that shader's instance (its parameter values); returns how many materials changed.
    pub fn use_native_surface(
        &mut self,
        shader: &str,
        make: impl Fn(&ShaderInstance) -> Arc<dyn super::native::NativeSurface>,
    ) -> usize {
        let mut changed = 0;
        for m in &mut self.materials {
            let Some(surface) = &m.surface else { continue };
            if surface.program.name != shader {
                continue;
            }
            m.native = Some(make(surface));
            changed += 1;
        }
        changed
    }

    /// The runtime checks' findings of every shader in the world since they were last asked.
    pub fn shader_messages(&self) -> Vec<String> {
        let mut seen: Vec<*const crate::shading::ShaderProgram> = Vec::new();
        let mut out = Vec::new();
        let programs = self
            .materials
            .iter()
            .filter_map(|m| m.surface.as_ref())
            .chain(self.lights.iter().map(|l| &l.shader))
            .chain(self.materials.iter().filter_map(|m| m.interior.as_ref()))
            .chain(self.materials.iter().filter_map(|m| m.displacement.as_ref()))
            .chain(self.pixel.iter())
            .chain(self.camera_shader.iter())
            .chain(self.atmosphere.iter())
            .map(|i| &i.program);
        for p in programs {
            let ptr = Arc::as_ptr(p);
            if seen.contains(&ptr) {
                continue;
            }
            seen.push(ptr);
            out.extend(p.code.runtime_errors().into_iter().map(|e| format!("shader {}: {e}", p.name)));
        }
        for name in self.ray_parameter_misses.take_new() {
            out.push(format!(
                "rayinfo(\"{name}\"): no ray parameter of that name is set; rayinfo returned 0 and left its variable \
                 as it was"
            ));
        }
        out
    }

    /// Whether any material lets light through (then shadow rays must look at what they pass).
    pub fn has_transparent_shadows(&self) -> bool {
        self.materials.iter().any(|m| !m.is_opaque_for_shadows())
    }

    /// For each instance, whether every material it may shade a triangle with is opaque for
    /// shadows.
    pub fn opaque_instances_for_shadows(&self) -> Vec<bool> {
        self.instance_shadows().iter().map(|s| *s == InstanceShadows::Opaque).collect()
    }

    /// What a shadow ray does at material `m` (the default material for an id out of range).
    pub fn shadow_kind(&self, m: u32) -> ShadowKind {
        let material = self.materials.get(m as usize).unwrap_or(&DEFAULT_MATERIAL);
        if material.is_opaque_for_shadows() {
            ShadowKind::Blocked
        } else if material.shadow_by_shader {
            ShadowKind::ByShader
        } else {
            ShadowKind::Crossed
        }
    }

    /// For each instance, what shadow rays do at its triangles ([`InstanceShadows::kind`]).
    pub fn instance_shadows(&self) -> Vec<InstanceShadows> {
        self.instances
            .iter()
            .map(|inst| {
                let fallback = self.shadow_kind(inst.material);
                let parts = inst.parts.as_ref().map(|p| p.materials.iter().map(|&m| self.shadow_kind(m)).collect());
                let all_blocked = |kinds: &[ShadowKind]| kinds.iter().all(|k| *k == ShadowKind::Blocked);
                match parts {
                    _ if fallback != ShadowKind::Blocked => InstanceShadows::Some { parts, fallback },
                    Some(kinds) if !all_blocked(&kinds) => InstanceShadows::Some { parts: Some(kinds), fallback },
                    _ => InstanceShadows::Opaque,
                }
            })
            .collect()
    }

    /// Whether any ray segment may run a volume shader: an atmosphere, or a material with an
    /// interior.
    pub fn has_volumes(&self) -> bool {
        self.atmosphere.is_some() || self.materials.iter().any(|m| m.interior.is_some())
    }
}

/// Fewer rays than this are traced one by one by [`World::intersect_rays`] and
/// [`World::occluded_rays`] (a chunk's `trace` rays, a few samples): spread over octants, they
/// would make packets of a few lanes each, which the tracer traces one by one anyway, after the
/// packing's set-up.
const FEWEST_PACKED_RAYS: usize = 8;

/// Hands `rays` to `trace` as packets, each of rays of one direction octant, with the index in
/// `rays` of each of its lanes (in order, from lane 0). Rays that leave points in all directions
/// (a point's virtual lights, a hemisphere's samples, reflections off a curved surface) would
/// otherwise make packets of mixed octants, which the tracer splits into sparse packets that each
/// pay a whole packet's set-up for a few lanes; rays of one direction (reflections off a flat
/// mirror, rays going on through a transparent surface) fill whole packets.
fn in_octant_packets(rays: &[Ray], mut trace: impl FnMut(&RayPacket, &[u32])) {
    let mut packer = OctantPacker::take();
    for (i, ray) in rays.iter().enumerate() {
        packer.push(i as u32, ray, &mut trace);
    }
    packer.finish(&mut trace);
}

/// Rays packed by direction octant as they come: each octant's packet is handed on when it is
/// full, and what is left when the rays end. Its packets are the same whatever order the octants'
/// rays are interleaved in: an octant's rays in the order they came, cut into whole packets.
struct OctantPacker {
    packets: Box<[RayPacket; 8]>,
    /// Each packet's lanes' ray indices.
    indices: [[u32; PACKET_SIZE]; 8],
    filled: [usize; 8],
}

impl OctantPacker {
    /// A packer with no rays (its buffers kept per thread: a shading point's virtual lights or
    /// samples come a few hundred rays at a time, and fresh packets cost more to clear than those
    /// rays take to pack). Hand it back with [`OctantPacker::finish`].
    fn take() -> Box<OctantPacker> {
        super::scratch::take(&OCTANT_PACKERS).unwrap_or_else(|| {
            Box::new(OctantPacker {
                packets: Box::new(std::array::from_fn(|_| RayPacket::new())),
                indices: [[0; PACKET_SIZE]; 8],
                filled: [0; 8],
            })
        })
    }

    /// Adds `ray`, the ray of index `index`, handing its octant's packet to `trace` when that fills.
    #[inline(always)]
    fn push(&mut self, index: u32, ray: &Ray, trace: &mut impl FnMut(&RayPacket, &[u32])) {
        let d = ray.direction;
        let octant = usize::from(d.x.is_sign_negative())
            | usize::from(d.y.is_sign_negative()) << 1
            | usize::from(d.z.is_sign_negative()) << 2;
        let n = self.filled[octant];
        let packet = &mut self.packets[octant];
        packet.set(n, ray);
        self.indices[octant][n] = index;
        if n + 1 < PACKET_SIZE {
            self.filled[octant] = n + 1;
            return;
        }
        trace(packet, &self.indices[octant]);
        // A packet's lanes outside `active` are never read (the tracer gives them an active
        // lane's ray): emptying it is clearing `active`.
        packet.active = 0;
        self.filled[octant] = 0;
    }

    /// Hands the packets not yet traced to `trace`, and the packer back to its thread.
    fn finish(mut self: Box<Self>, trace: &mut impl FnMut(&RayPacket, &[u32])) {
        for octant in 0..8 {
            let n = self.filled[octant];
            if n > 0 {
                trace(&self.packets[octant], &self.indices[octant][..n]);
                self.packets[octant].active = 0;
                self.filled[octant] = 0;
            }
        }
        super::scratch::give(&OCTANT_PACKERS, Some(self));
    }
}

thread_local! {
    /// Packers not in use, one per level of recursion (tracing a packet may shade surfaces whose
    /// shaders trace rays of their own).
    static OCTANT_PACKERS: RefCell<Vec<Option<Box<OctantPacker>>>> = const { RefCell::new(Vec::new()) };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An instance is opaque for shadows when every material it may use is; otherwise each
    /// triangle's kind is its material's, parts' triangles and those past the parts' table alike.
    #[test]
    fn shadows_are_blocked_crossed_or_shaded_as_each_triangles_material_says() {
        let mut world = World::new(Scene::new());
        let glass = Material { opacity: [0.5; 3], ..Material::DEFAULT };
        let by_shader = Material { shadow_by_shader: true, ..Material::DEFAULT };
        // 0: the default, 1: opaque, 2: glass, 3: shadows by shader.
        world.materials = vec![Material::DEFAULT, Material::DEFAULT, glass, by_shader];
        let instance = |material: u32, parts: Option<&[u32]>| InstanceShading {
            material,
            object: 0,
            world_from_object: Affine3A::IDENTITY,
            parts: parts.map(|m| InstanceParts { of_triangle: vec![0; m.len()].into(), materials: m.into() }),
            displaced: false,
        };
        world.instances = vec![
            instance(1, None),
            instance(2, None),
            instance(3, None),
            instance(1, Some(&[1, 0])),
            instance(1, Some(&[1, 2])),
            // Out of range: the default material, opaque.
            instance(9, None),
        ];
        assert_eq!(world.opaque_instances_for_shadows(), [true, false, false, true, false, true]);
        // Per triangle: the kind of the material it is shaded with, parts' triangles and those
        // past the parts' table alike.
        let shadows = world.instance_shadows();
        for inst in &mut world.instances {
            if let Some(p) = &mut inst.parts {
                p.of_triangle = vec![1, 0, 1, 7].into();
            }
        }
        let kinds = |k: usize| {
            let inst = &world.instances[k];
            (0..6).map(|t| shadows[k].kind(inst, t)).collect::<Vec<_>>()
        };
        for k in 0..world.instances.len() {
            let want: Vec<_> = (0..6).map(|t| world.shadow_kind(world.instances[k].material_at(t))).collect();
            assert_eq!(kinds(k), want, "instance {k}");
        }
        use ShadowKind::*;
        assert_eq!(kinds(4), [Crossed, Blocked, Crossed, Blocked, Blocked, Blocked]);
        assert_eq!(kinds(2), [ByShader; 6]);
    }

    /// Rays in every direction octant, more than a packet's worth in some, traced in octant
    /// packets: each answer is the one its ray gets alone.
    #[test]
    fn occluded_rays_answer_as_each_ray_alone() {
        let (world, rays) = gapped_cube_and_rays();
        // Few rays (traced one by one) and many (packed).
        for rays in [&rays[..0], &rays[..5], &rays[..]] {
            let mut blocked = vec![true; 3];
            world.occluded_rays(RayKind::Shadow, rays, &mut blocked);
            let alone: Vec<bool> = rays.iter().map(|r| world.occluded(RayKind::Shadow, r)).collect();
            assert_eq!(blocked, alone);
        }
        let alone: Vec<bool> = rays.iter().map(|r| world.occluded(RayKind::Shadow, r)).collect();
        assert!(alone.iter().any(|&b| b) && alone.iter().any(|&b| !b), "both answers are tested");
    }

    /// The closest hits of rays in every octant (more than a packet's worth in some), traced in
    /// octant packets, are each ray's own: the same triangle at the same distance and barycentrics,
    /// or, where the ray meets a quad's diagonal, its other triangle at that distance.
    #[test]
    fn intersect_rays_answer_as_each_ray_alone() {
        let (world, all) = gapped_cube_and_rays();
        let mut hits = vec![Hit::MISS; 5];
        // Few rays (traced one by one) and many (packed); the many are left in `hits`.
        for rays in [&all[..0], &all[..5], &all[..]] {
            world.intersect_rays(RayKind::Trace, rays, &mut hits);
            assert_eq!(hits.len(), rays.len());
            for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
                let alone = world.intersect(RayKind::Trace, ray);
                let same = if (alone.instance, alone.primitive) == (hit.instance, hit.primitive) {
                    (alone.t, alone.u, alone.v) == (hit.t, hit.u, hit.v) || !alone.is_hit()
                } else {
                    alone.is_hit() && hit.is_hit() && (alone.t - hit.t).abs() <= 1e-5 * alone.t
                };
                assert!(same, "ray {i} of {}: alone {alone:?}, with the others {hit:?}", rays.len());
            }
        }
        let met = hits.iter().filter(|h| h.is_hit()).count();
        assert!(met > 100 && met < all.len() - 100, "{met} of {} rays meet the cube", all.len());
    }

    /// A cube of small quads around the origin, with gaps between them, so that rays from the
    /// centre meet it in some directions and not in others; and 700 rays from near its centre in
    /// all directions, one in five stopping short of it.
    fn gapped_cube_and_rays() -> (World, Vec<Ray>) {
        use crate::geometry::Mesh;
        use glam::Vec3;
        let (mut positions, mut triangles) = (Vec::new(), Vec::new());
        for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                for (i, j) in (0..4).flat_map(|i| (0..4).map(move |j| (i, j))) {
                    let corner = |a: f32, b: f32| {
                        let mut p = [0.0; 3];
                        p[axis] = side;
                        p[(axis + 1) % 3] = -1.0 + 0.5 * (i as f32 + a);
                        p[(axis + 2) % 3] = -1.0 + 0.5 * (j as f32 + b);
                        Vec3::from_array(p)
                    };
                    let base = positions.len() as u32;
                    positions.extend([corner(0.1, 0.1), corner(0.9, 0.1), corner(0.9, 0.9), corner(0.1, 0.9)]);
                    triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
                }
            }
        }
        let mut scene = Scene::new();
        let mesh = Mesh::from_triangles(positions, triangles).expect("a valid mesh");
        let object = scene.add_object(mesh);
        scene.add_instance(object, Affine3A::IDENTITY).expect("an instance");
        scene.commit();
        let world = World::new(scene);
        use crate::render::sampling::{mix, unit};
        let mut state = 7u64;
        let mut next = || {
            state = mix(state);
            unit(state) * 2.0 - 1.0
        };
        let rays = (0..700)
            .map(|k| {
                let origin = Vec3A::new(next(), next(), next()) * 0.3;
                let reach = if k % 5 == 0 { 0.5 } else { f32::INFINITY };
                Ray::segment(origin, Vec3A::new(next(), next(), next()).normalize_or(Vec3A::X), 1e-4, reach)
            })
            .collect();
        (world, rays)
    }
}

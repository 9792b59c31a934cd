//! What the reference interpreter asks of the renderer, one shading point at a time, and a
//! deterministic test host.
//!
//! The JIT calls the renderer once per batch through the packet ABI (`docs/packet-abi.md`); the
//! interpreter is the oracle those calls are checked against, so it asks the same questions for one
//! lane. Everything a shader can learn from outside its inputs goes through [`Services`].

use super::value::Value;
use crate::builtins::Builtin;
use crate::shadeops::gather::GatherHit;
use crate::shadeops::{matrix, M4, V3};

/// One light reaching a point, as an `illuminance` loop or `diffuse()` sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// From the surface point to the light (not normalised: its length is the distance).
    pub l: V3,
    /// The light's colour arriving at the point (shadows already applied).
    pub cl: V3,
    /// The light's opacity.
    pub ol: V3,
    /// An ambient light (no `illuminate`/`solar`): only `ambient()` counts it.
    pub ambient: bool,
    /// The light's `__nondiffuse` and `__nonspecular` outputs (0 when it has none): `diffuse()`
    /// weighs it by `1 - nondiffuse`, `specular()` and `phong()` by `1 - nonspecular`.
    pub nondiffuse: f32,
    pub nonspecular: f32,
}

/// The filter footprint of a `texture` lookup: the screen-space derivatives of its coordinates,
/// already scaled by the lookup's `"swidth"`/`"twidth"` (or `"width"`) options, and its blur in s
/// and t, `"sblur"`/`"tblur"` (or `"blur"`) (`docs/packet-abi.md`, "Derivatives"). All zero: a
/// point sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TextureFootprint {
    pub dsdx: f32,
    pub dtdx: f32,
    pub dsdy: f32,
    pub dtdy: f32,
    pub sblur: f32,
    pub tblur: f32,
}

/// A `shadow()` lookup: the point, the region its filter covers and the options RSL gives it
/// (`docs/textures.md`, "Shadow maps").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowQuery {
    /// The point looked up (world space); the four-point form's centre.
    pub p: V3,
    /// The region the filter covers: the four points of `shadow(name, P1, P2, P3, P4)`, or the
    /// shading point's pixel footprint `P ± dPdx/2 ± dPdy/2` (all `p` without derivatives).
    pub corners: [V3; 4],
    /// `"samples"`: percentage-closer samples (default 16).
    pub samples: f32,
    /// `"sblur"`/`"tblur"` (or `"blur"` for both): added kernel width, in map coordinates.
    pub sblur: f32,
    pub tblur: f32,
    /// `"swidth"`/`"twidth"` (or `"width"` for both): scales the region's extent on the map.
    pub swidth: f32,
    pub twidth: f32,
    /// `"bias"`: subtracted from the point's depth before comparing; NaN where the call gives
    /// none, for the renderer's default (RIB's `Option "shadow" "bias"`).
    pub bias: f32,
}

/// An `environment()` lookup: the direction, how it changes over one pixel step in x and y (its
/// screen derivatives; the four-direction form's differences `D2 - D1` and `D3 - D1`), and the
/// options RSL gives it (`docs/textures.md`, "Environment maps").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvironmentQuery {
    /// The direction looked up; the four-direction form's mean.
    pub dir: V3,
    pub ddx: V3,
    pub ddy: V3,
    /// `"sblur"`/`"tblur"` (or `"blur"` for both): added filter width, in map coordinates.
    pub sblur: f32,
    pub tblur: f32,
    /// `"swidth"`/`"twidth"` (or `"width"` for both): scales the footprint on the map.
    pub swidth: f32,
    pub twidth: f32,
    /// `"fill"`: the value of channels the map does not have.
    pub fill: f32,
}

impl EnvironmentQuery {
    /// A point sample along `dir` with the default options.
    pub fn along(dir: V3) -> EnvironmentQuery {
        EnvironmentQuery {
            dir,
            ddx: [0.0; 3],
            ddy: [0.0; 3],
            sblur: 0.0,
            tblur: 0.0,
            swidth: 1.0,
            twidth: 1.0,
            fill: 0.0,
        }
    }
}

impl ShadowQuery {
    /// A lookup at `p` alone with the default options.
    pub fn at(p: V3) -> ShadowQuery {
        ShadowQuery { p, corners: [p; 4], samples: 16.0, sblur: 0.0, tblur: 0.0, swidth: 1.0, twidth: 1.0, bias: 0.0 }
    }
}

/// The renderer, as one shading point sees it.
pub trait Services {
    /// The matrix taking points from space `from` to space `to` ("current" is world space in rtsl),
    /// or `None` for an unknown space.
    fn matrix(&mut self, from: &str, to: &str) -> Option<M4>;
    /// The lights of `category` ("" for all) reaching `p` (the interpreter applies cones itself).
    fn lights(&mut self, category: &str, p: V3) -> Vec<LightSample>;
    /// A filtered texture lookup at (s, t), `channels` values from `first_channel` on: those the
    /// texture has (fewer when it lacks some; the caller gives the rest the fill value), or `None`
    /// when the texture cannot be read (the caller uses the fill value).
    fn texture(&mut self, name: &str, s: f32, t: f32, first_channel: usize, channels: usize) -> Option<Vec<f32>>;
    /// A texture lookup filtered over `footprint` (for mip-mapping); the default ignores the
    /// footprint and asks [`Services::texture`].
    fn texture_filtered(
        &mut self,
        name: &str,
        s: f32,
        t: f32,
        footprint: &TextureFootprint,
        first_channel: usize,
        channels: usize,
    ) -> Option<Vec<f32>> {
        let _ = footprint;
        self.texture(name, s, t, first_channel, channels)
    }
    /// A trilinear lookup in the 3-D grid file `name` (`docs/volumes.md`) at `p`, given in the
    /// grid's own coordinates (its header's bounds); `None` when the file cannot be read (the
    /// caller uses the fill value). The default knows no grids.
    fn texture3d(&mut self, name: &str, p: V3) -> Option<f32> {
        let _ = (name, p);
        None
    }
    /// Channel `name` of the pixel at raster `(x, y)` of the image a pixel shader is finishing
    /// (`pixelvalue`): `"Ci"` a colour, `"N"` a normal (zero where the pixel sees nothing),
    /// `"alpha"`, `"z"`, `"objectid"`, `"shaderid"` a float in the first component. `None` where
    /// there is no such image or channel (the caller answers 0). The default has no image.
    fn pixel_value(&mut self, name: &str, x: f32, y: f32) -> Option<V3> {
        let _ = (name, x, y);
        None
    }
    /// The irradiance photon map `name` estimates at `p` facing `n` (zero: any way) from its
    /// `estimator` nearest photons (`photonmap`); `None` for a map there is not (the caller
    /// answers black). The default has no maps.
    fn photonmap(&mut self, name: &str, p: V3, n: V3, estimator: f32) -> Option<V3> {
        let _ = (name, p, n, estimator);
        None
    }
    /// An environment-map lookup filtered over the query's footprint: `channels` values from
    /// `first_channel` on (channels the map lacks are `query.fill`); `None` when the map cannot be
    /// read (the caller uses the fill value).
    fn environment(
        &mut self,
        name: &str,
        query: &EnvironmentQuery,
        first_channel: usize,
        channels: usize,
    ) -> Option<Vec<f32>>;
    /// The fraction of the query's region in shadow according to the shadow map `name`.
    fn shadow(&mut self, name: &str, query: &ShadowQuery) -> f32;
    /// The colour seen along a ray, and the hit distance (infinite on a miss).
    fn trace(&mut self, from: V3, dir: V3) -> (V3, f32);
    /// What a `gather` ray of `category` from `from` along the unit direction `dir` hits within
    /// `maxdist`, shaded (`shadeops::gather`); `None` on a miss.
    fn gather_ray(&mut self, category: &str, from: V3, dir: V3, maxdist: f32) -> Option<GatherHit>;
    /// How much light passes from `from` to `to` (1 where nothing blocks).
    fn transmission(&mut self, from: V3, to: V3) -> V3;
    /// The fraction of the hemisphere around `n` that is blocked.
    fn occlusion(&mut self, p: V3, n: V3, samples: f32) -> f32;
    /// Diffuse light arriving from other surfaces.
    fn indirect_diffuse(&mut self, p: V3, n: V3, samples: f32) -> V3;
    /// Message passing and renderer queries (`surface("Kd", x)`, `option("Format", f)`, ...).
    fn message(&mut self, which: Builtin, name: &str) -> Option<Value>;
    /// `incident(name)` and `opposite(name)`: a parameter of the volume shader inside the surface
    /// (`interior`) or outside it (the exterior: the atmosphere in rtsl). The default knows none.
    fn volume_message(&mut self, interior: bool, name: &str) -> Option<Value> {
        let _ = (interior, name);
        None
    }
    /// `printf` output.
    fn print(&mut self, text: &str);
    /// Normalised camera depth of a point.
    fn depth(&mut self, p: V3) -> f32;
    /// How many bounces led to this ray.
    fn ray_depth(&mut self) -> f32;
    /// The name of this shader (`None`) or of the one bound as the given type.
    fn shader_name(&mut self, kind: Option<&str>) -> String;
    /// Called once for a built-in the renderer accepts but cannot honour.
    fn unsupported(&mut self, which: Builtin);
}

/// A deterministic host for tests, documented value by value:
/// - spaces: "current", "world" and "camera" are the identity except that "camera" is translated by
///   (0, 0, 5); "object" and "shader" are translated by (1, 2, 3); other names are unknown;
/// - lights: an ambient light of 0.1 grey, and a white distant light shining down the -z axis from
///   +z (L = (0, 0, 1000) from every point); categories are ignored;
/// - textures: any name but "missing" is a checkerboard of 8x8 cells in s and t, channel c of a
///   white cell is 1 - 0.1c and of a black cell 0.1c; "missing" cannot be read; a filtered lookup
///   whose footprint (`max(|dsdx| + |dsdy|, |dtdx| + |dtdy|) + blur`) exceeds a cell (1/8) is the
///   checkerboard's average, 0.5 in every channel;
/// - 3-D grids (`texture3d`): any name but "missing" is the linear ramp `x/4 + y/2 + z/8` of the
///   point; "missing" cannot be read;
/// - environment: the direction mapped to a colour, `0.5 + 0.5 * normalize(dir)`;
/// - lights: an ambient light (category "ambient"), a distant "key" light along +z and, when
///   [`TestHost::point_light`] is set, a "fill" point light; a category `"name"` selects that
///   category's lights, `"-name"` all the others;
/// - shadow: 0 (nothing in shadow); transmission: white; occlusion: 0.25; indirect: 0.05 grey;
/// - trace: the environment colour of the direction, distance 10;
/// - gather rays: a ceiling 10 above every point, facing down: a ray with a positive z component
///   hits it (length `10 / dir.z`, unless beyond `maxdist`) with Ci the environment colour of the
///   direction, Oi white, P on the ceiling and N (0, 0, -1); other rays miss;
/// - messages: `option("Format")` is [640 480 1], `option("FieldOfView")` 90 (degrees: the rays a
///   pinhole camera shader then makes are those `testshade` gives a camera shader on entry),
///   `rendererinfo("renderer")` is "rtsl", `attribute`
///   and other shaders' parameters are unknown (`None`); `rayinfo("depth")` is 0, and
///   `rayinfo(name)` (or `"user:name"`) one of [`TestHost::ray_parameters`], `"relevance"` 1 when
///   they do not hold it;
/// - `printf` output is collected in [`TestHost::printed`]; depth is `p.z / 100`; ray depth 0.
#[derive(Debug, Default)]
pub struct TestHost {
    pub printed: Vec<String>,
    pub unsupported: Vec<Builtin>,
    /// A point light at this position besides the two fixed lights, whose colour varies with the
    /// lit point and which sets `__nondiffuse` 0.25 and `__nonspecular` 0.5: lanes then differ in
    /// their lights' directions, colours and sides.
    pub point_light: Option<V3>,
    /// The ray parameters `rayinfo` reads, by name.
    pub ray_parameters: Vec<(String, Value)>,
}

fn space(name: &str) -> Option<M4> {
    let t = |x: f32, y: f32, z: f32| matrix::translate(&matrix::identity(), [x, y, z]);
    match name {
        "current" | "world" => Some(matrix::identity()),
        "camera" => Some(t(0.0, 0.0, 5.0)),
        "object" | "shader" => Some(t(1.0, 2.0, 3.0)),
        _ => None,
    }
}

/// The test host's sky: the direction's components mapped from [-1, 1] to [0, 1] (grey for none).
fn sky(dir: V3) -> V3 {
    let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    if len == 0.0 {
        return [0.5; 3];
    }
    dir.map(|d| 0.5 + 0.5 * d / len)
}

impl Services for TestHost {
    fn matrix(&mut self, from: &str, to: &str) -> Option<M4> {
        // A space's matrix takes its points to world space; from -> to is from * inverse(to).
        let a = space(from)?;
        let b = space(to)?;
        Some(matrix::mul(&a, &matrix::inverse(&b)?))
    }

    fn lights(&mut self, category: &str, p: V3) -> Vec<LightSample> {
        // The fixed non-ambient light is a "key" light, the point light a "fill" light; a
        // category "-name" leaves that category's lights out (RISpec's `__category`).
        let wanted = |of: &str| match category {
            "" => true,
            c => match c.strip_prefix('-') {
                Some(not) => not != of,
                None => c == of,
            },
        };
        let point = self.point_light.map(|from| LightSample {
            l: [from[0] - p[0], from[1] - p[1], from[2] - p[2]],
            cl: [0.8, 0.25 + 0.5 * p[0].abs().min(1.0), 0.4],
            ol: [0.0; 3],
            ambient: false,
            nondiffuse: 0.25,
            nonspecular: 0.5,
        });
        let fixed = [
            LightSample { l: [0.0; 3], cl: [0.1; 3], ol: [0.0; 3], ambient: true, nondiffuse: 0.0, nonspecular: 0.0 },
            LightSample {
                l: [0.0, 0.0, 1000.0],
                cl: [1.0; 3],
                ol: [0.0; 3],
                ambient: false,
                nondiffuse: 0.0,
                nonspecular: 0.0,
            },
        ];
        let [ambient, key] = fixed;
        Some(ambient)
            .filter(|_| wanted("ambient"))
            .into_iter()
            .chain(Some(key).filter(|_| wanted("key")))
            .chain(point.filter(|_| wanted("fill")))
            .collect()
    }

    /// An RGB checkerboard of 8 x 8 squares whose channels differ; no texture "missing".
    fn texture(&mut self, name: &str, s: f32, t: f32, first_channel: usize, channels: usize) -> Option<Vec<f32>> {
        if name == "missing" {
            return None;
        }
        let white = ((s * 8.0).floor() as i64 + (t * 8.0).floor() as i64).rem_euclid(2) == 0;
        Some(
            (first_channel..(first_channel + channels).min(3))
                .map(|c| if white { 1.0 - 0.1 * c as f32 } else { 0.1 * c as f32 })
                .collect(),
        )
    }

    fn texture_filtered(
        &mut self,
        name: &str,
        s: f32,
        t: f32,
        fp: &TextureFootprint,
        first_channel: usize,
        channels: usize,
    ) -> Option<Vec<f32>> {
        let width = (fp.dsdx.abs() + fp.dsdy.abs() + fp.sblur).max(fp.dtdx.abs() + fp.dtdy.abs() + fp.tblur);
        if name != "missing" && width > 0.125 {
            return Some(vec![0.5; (first_channel + channels).min(3).saturating_sub(first_channel)]);
        }
        self.texture(name, s, t, first_channel, channels)
    }

    fn texture3d(&mut self, name: &str, p: V3) -> Option<f32> {
        (name != "missing").then(|| 0.25 * p[0] + 0.5 * p[1] + 0.125 * p[2])
    }

    /// A map "caustic" whose estimate is a function of every argument; no other.
    fn photonmap(&mut self, name: &str, p: V3, n: V3, estimator: f32) -> Option<V3> {
        (name == "caustic").then(|| [p[0] + estimator, p[1] * n[1], p[2] - n[0] + n[2]])
    }

    /// An image of 8 x 6 pixels whose channels are functions of the pixel (the nearest inside, as
    /// the renderer finds it; none at a coordinate that is not finite); no channel "missing".
    fn pixel_value(&mut self, name: &str, x: f32, y: f32) -> Option<V3> {
        if !x.is_finite() || !y.is_finite() {
            return None;
        }
        let nearest = |v: f32, last: u32| (v.floor().max(0.0) as u32).min(last) as f32;
        let (px, py) = (nearest(x, 7), nearest(y, 5));
        match name {
            "Ci" => Some([px / 8.0, py / 6.0, (px + py) / 14.0]),
            "missing" => None,
            _ => Some([px + 10.0 * py + name.len() as f32, 0.0, 0.0]),
        }
    }

    /// The sky's colour along the direction, moved by every other field of the query so that the
    /// JIT's and the interpreter's queries can be compared through it; channels past the third
    /// are the fill. No map "missing".
    fn environment(
        &mut self,
        name: &str,
        q: &EnvironmentQuery,
        first_channel: usize,
        channels: usize,
    ) -> Option<Vec<f32>> {
        if name == "missing" {
            return None;
        }
        let sky = sky(q.dir);
        let spread: f32 = q.ddx.iter().chain(&q.ddy).map(|x| x.abs()).sum();
        let options = 0.7 * spread + 0.1 * q.sblur - 0.2 * q.tblur + 0.3 * (q.swidth - 1.0) + 0.05 * (q.twidth - 1.0);
        Some(
            (first_channel..first_channel + channels)
                .map(|c| sky.get(c).map_or(q.fill, |x| x + options + 0.01 * c as f32))
                .collect(),
        )
    }

    /// Not a shadow map: a value in [0, 1) that every field of the query changes, so the
    /// JIT's and the interpreter's queries can be compared through it.
    fn shadow(&mut self, _name: &str, q: &ShadowQuery) -> f32 {
        let spread: f32 = q.corners.iter().map(|c| (c[0] - q.p[0]).abs() + (c[1] - q.p[1]).abs()).sum();
        let x = q.p[0] + 0.5 * q.p[1] + 0.25 * q.p[2] + 0.7 * spread + 0.01 * q.samples + 0.1 * q.sblur - 0.2 * q.tblur
            + 0.3 * q.swidth
            + 0.05 * q.twidth
            + 0.9 * if q.bias.is_nan() { 0.375 } else { q.bias };
        x - x.floor()
    }

    fn trace(&mut self, _from: V3, dir: V3) -> (V3, f32) {
        (sky(dir), 10.0)
    }

    fn gather_ray(&mut self, _category: &str, from: V3, dir: V3, maxdist: f32) -> Option<GatherHit> {
        if dir[2] <= 0.0 {
            return None;
        }
        let length = 10.0 / dir[2];
        (length <= maxdist).then(|| GatherHit {
            length,
            ci: sky(dir),
            oi: [1.0; 3],
            p: [from[0] + dir[0] * length, from[1] + dir[1] * length, from[2] + dir[2] * length],
            n: [0.0, 0.0, -1.0],
        })
    }

    fn transmission(&mut self, _from: V3, _to: V3) -> V3 {
        [1.0; 3]
    }

    fn occlusion(&mut self, _p: V3, _n: V3, _samples: f32) -> f32 {
        0.25
    }

    fn indirect_diffuse(&mut self, _p: V3, _n: V3, _samples: f32) -> V3 {
        [0.05; 3]
    }

    fn message(&mut self, which: Builtin, name: &str) -> Option<Value> {
        match (which, name) {
            (Builtin::Option, "Format") => Some(Value::Triple([640.0, 480.0, 1.0])),
            (Builtin::Option, "FieldOfView") => Some(Value::Float(90.0)),
            (Builtin::Rendererinfo, "renderer") => Some(Value::String("rtsl".into())),
            (Builtin::Rayinfo, "depth") => Some(Value::Float(0.0)),
            (Builtin::Rayinfo, name) => {
                let name = name.strip_prefix("user:").unwrap_or(name);
                let given = self.ray_parameters.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone());
                given.or_else(|| (name == "relevance").then_some(Value::Float(1.0)))
            }
            _ => None,
        }
    }

    /// "side": 1 inside, 2 outside; "ior": an interior's index of refraction only.
    fn volume_message(&mut self, interior: bool, name: &str) -> Option<Value> {
        match (name, interior) {
            ("side", _) => Some(Value::Float(if interior { 1.0 } else { 2.0 })),
            ("ior", true) => Some(Value::Float(1.5)),
            _ => None,
        }
    }

    fn print(&mut self, text: &str) {
        self.printed.push(text.to_string());
    }

    fn depth(&mut self, p: V3) -> f32 {
        p[2] / 100.0
    }

    fn ray_depth(&mut self) -> f32 {
        0.0
    }

    fn shader_name(&mut self, kind: Option<&str>) -> String {
        kind.map(|k| format!("<{k}>")).unwrap_or_else(|| "<this>".into())
    }

    fn unsupported(&mut self, which: Builtin) {
        if !self.unsupported.contains(&which) {
            self.unsupported.push(which);
        }
    }
}

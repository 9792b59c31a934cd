//! Calls into the renderer: the [`HostTable`] the runtime implements, an implementation backed by any
//! [`Services`] (so tests ask one [`crate::interp::TestHost`] for the JIT and the interpreter), and
//! the chunk helpers generated code calls.
//!
//! Invariants:
//! - Generated code never calls the renderer per lane: it calls a **host helper**
//!   `extern "C" fn(batch: *mut Batch, mask: *const i32, in: *const f32, out: *mut f32)` once per
//!   chunk of four lanes, with the lanes that need the call in `mask` (4 entries, -1 or 0) and its
//!   arguments in stack buffers (argument `k` of lane `l` at `in[4k + l]`, result `j` of lane `l` at
//!   `out[4j + l]`). A helper reads and writes only the lanes of `mask`; for a uniform call generated
//!   code passes the mask `[-1, 0, 0, 0]` and splats lane 0 of the result.
//! - Strings are `u32` handles carried in the bits of an `f32` (lane 0: strings are uniform); helpers
//!   resolve them in the batch's [`StringTable`] (an out-of-range handle reads as ""), and intern the
//!   strings the renderer returns. Generated code never sees a pointer to string data.
//! - A helper asks the [`HostTable`] once per chunk (lights, textures, rays, depth), once per batch
//!   (each pair of spaces' matrix, remembered in [`HostCtx`]) or once per call (messages, ray depth,
//!   shader names); a null table answers "unknown" everywhere (no
//!   space, no light, unreadable textures, black rays, no message).
//! - What a helper computes from the renderer's answers (cones, the light sums of `diffuse`,
//!   `specular`, `phong`, `ambient`, texture fill values, message shapes) repeats the interpreter's
//!   formulas operation for operation, so the two agree bit for bit (they share no code).

use super::{Batch, StringTable};
use crate::builtins::Builtin;
use crate::interp::{EnvironmentQuery, Services, ShadowQuery, TextureFootprint, Value};
use crate::shadeops::format::{self, FormatArg};
use crate::shadeops::gather::{self, GatherHit};
use crate::shadeops::transcendental;
use crate::shadeops::{color, geom, matrix, spline, M4, V3};
use std::ffi::c_void;

mod light_sums;
use light_sums::Lanes3;

/// A borrowed string across the C ABI (not NUL-terminated).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StrRef {
    pub ptr: *const u8,
    pub len: usize,
}

impl StrRef {
    pub fn new(s: &str) -> StrRef {
        StrRef { ptr: s.as_ptr(), len: s.len() }
    }

    /// # Safety
    /// `ptr` must point to `len` bytes of UTF-8 that outlive `'a`.
    pub unsafe fn as_str<'a>(self) -> &'a str {
        if self.ptr.is_null() {
            return "";
        }
        // SAFETY: the caller's contract. Every `StrRef` the JIT and the host pass is made by
        // `StrRef::new` from a `&str`; checking the bytes again would scan a file path (a texture's
        // name) for every lookup.
        unsafe { std::str::from_utf8_unchecked(std::slice::from_raw_parts(self.ptr, self.len)) }
    }
}

/// One light reaching one lane.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HostLight {
    /// From the surface point to the light.
    pub l: [f32; 3],
    pub cl: [f32; 3],
    pub ol: [f32; 3],
    /// Nonzero for an ambient light (only `ambient()` counts it).
    pub ambient: u32,
    /// The light's `__nondiffuse` and `__nonspecular` outputs (0 when it has none): `diffuse()`
    /// weighs it by `1 - nondiffuse`, `specular()` and `phong()` by `1 - nonspecular`.
    pub nondiffuse: f32,
    pub nonspecular: f32,
    /// Which light this is, for [`HostTable::light_message`] (the renderer's numbering).
    pub id: u32,
}

/// The `k`-th light of each of a chunk's four lanes, a row per component (structure of arrays):
/// what `HostTable::lights` writes, one entry per light slot, so that the light sums load rows
/// (`Vec4`s) instead of gathering each lane's light, and a renderer hands a chunk's lights over in
/// one copy. Lane `l`'s light is [`LightLanes::lane`]`(l)`.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightLanes {
    /// From the surface point to the light: x, y, z rows.
    pub l: [[f32; 4]; 3],
    pub cl: [[f32; 4]; 3],
    pub ol: [[f32; 4]; 3],
    pub ambient: [u32; 4],
    pub nondiffuse: [f32; 4],
    pub nonspecular: [f32; 4],
    pub id: [u32; 4],
}

impl LightLanes {
    /// Lane `l`'s light (`l < 4`).
    #[inline]
    pub fn lane(&self, l: usize) -> HostLight {
        let v3 = |rows: &[[f32; 4]; 3]| [rows[0][l], rows[1][l], rows[2][l]];
        HostLight {
            l: v3(&self.l),
            cl: v3(&self.cl),
            ol: v3(&self.ol),
            ambient: self.ambient[l],
            nondiffuse: self.nondiffuse[l],
            nonspecular: self.nonspecular[l],
            id: self.id[l],
        }
    }

    /// Lane `l`'s direction to the light.
    #[inline]
    pub fn lane_l(&self, l: usize) -> [f32; 3] {
        [self.l[0][l], self.l[1][l], self.l[2][l]]
    }

    /// Makes lane `l`'s light `h` (`l < 4`).
    #[inline]
    pub fn set_lane(&mut self, l: usize, h: &HostLight) {
        for k in 0..3 {
            self.l[k][l] = h.l[k];
            self.cl[k][l] = h.cl[k];
            self.ol[k][l] = h.ol[k];
        }
        self.ambient[l] = h.ambient;
        self.nondiffuse[l] = h.nondiffuse;
        self.nonspecular[l] = h.nonspecular;
        self.id[l] = h.id;
    }

    /// Scales lane `l`'s colour by `a` (a shadow's transmission).
    #[inline]
    pub fn scale_cl(&mut self, l: usize, a: [f32; 3]) {
        for (row, a) in self.cl.iter_mut().zip(a) {
            row[l] *= a;
        }
    }
}

/// The most lights `HostTable::lights` reports per lane (more are dropped).
pub const MAX_LIGHTS: usize = 32;
/// Rows of a light query's cone: the axis (3), then the cosine of its half-angle.
pub const CONE_ROWS: usize = 4;
/// A cone's cosine that asks for every light.
pub const EVERY_LIGHT: f32 = -2.0;
/// A cone's cosine that asks for no non-ambient light (`ambient()`).
pub const NO_LIGHT: f32 = 2.0;

/// The most floats a message value may hold.
pub const MESSAGE_FLOATS: usize = 64;

/// Whether a light from direction `l` may count for a query with cone (`axis`, `cos`): the lights
/// `diffuse()`, `specular()` and `illuminance` use must all pass. It errs toward `true` (a slack
/// on the cosine; NaN passes), so a renderer that traces shadows only for these lights never
/// leaves one the shader uses unshadowed.
pub fn light_in_cone(l: [f32; 3], axis: [f32; 3], cos: f32) -> bool {
    if cos <= -1.0 {
        return true;
    }
    // The cosine `la / sqrt(lengths)` against `c`, compared squared: no square root or division
    // (this runs for every pending light of a lane at every light query). Rounding differs from
    // normalising first by a few ulps, far inside the slack.
    let c = cos - 1e-3;
    let (la, lengths) = (dot(l, axis), dot(l, l) * dot(axis, axis));
    if la.is_nan() || c.is_nan() || !lengths.is_finite() {
        return true;
    }
    if lengths == 0.0 {
        // A zero vector, which `normalize` leaves zero: a cosine of 0.
        return c <= 0.0;
    }
    if la >= 0.0 {
        c <= 0.0 || la * la >= c * c * lengths
    } else {
        c < 0.0 && la * la <= c * c * lengths
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Categories compare as strings do, the empty one included.
    #[test]
    fn categories_compare_as_strings() {
        let names = ["", "a", "b", "ab", "ba", "-a", "specular", "specula"];
        for a in names {
            for b in names {
                assert_eq!(same_category(a, b), a == b, "{a:?} {b:?}");
            }
        }
    }

    /// The cone test without normalising agrees with the normalising one except within a hair of
    /// the slack's edge, and takes in every light exactly inside the cone.
    #[test]
    fn the_cone_test_by_squares_matches_the_normalised_one() {
        let normalised = |l: V3, axis: V3, cos: f32| {
            let d = dot(geom::normalize(l), geom::normalize(axis));
            cos <= -1.0 || d.is_nan() || cos.is_nan() || d >= cos - 1e-3
        };
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        // Zero vectors have a cosine of 0; infinite and NaN ones, and NaN cosines, count as inside
        // (erring toward true); a cosine above 1 takes in nothing.
        let z = [0.0, 0.0, 1.0];
        let x = [1.0, 0.0, 0.0];
        for (l, axis, cos, want) in [
            ([0.0; 3], z, 0.0, true),
            ([0.0; 3], z, 0.5, false),
            (x, [0.0; 3], -0.5, true),
            ([f32::INFINITY, 0.0, 0.0], x, 0.5, true),
            ([f32::NAN, 0.0, 0.0], x, 0.5, true),
            (x, x, f32::NAN, true),
            (x, x, 2.0, false),
            (z, x, -2.0, true),
            ([0.0, 0.0, 1e30], [0.0, 0.0, 1e30], 0.5, true),
            ([1e-30, 0.0, 0.0], [0.0, 1e-30, 0.0], 0.0, true),
        ] {
            assert_eq!(light_in_cone(l, axis, cos), want, "{l:?} {axis:?} {cos}");
        }
        for _ in 0..200_000 {
            let scale = 10f32.powf(next() * 6.0);
            let l = [next() * scale, next() * scale, next() * scale];
            let axis = [next(), next(), next()];
            let cos = [0.0, -2.0, 2.0, next(), next() * 0.1][(next().abs() * 4.99) as usize];
            let (got, want) = (light_in_cone(l, axis, cos), normalised(l, axis, cos));
            // Where normalising overflows or underflows, the old test's cosine means nothing (a
            // vector 1e30 long normalised to zero); the new one errs toward true there.
            let fine = |v: V3| (1e-30..1e30).contains(&dot(v, v));
            if !(fine(l) && fine(axis)) {
                continue;
            }
            let d = dot(geom::normalize(l), geom::normalize(axis));
            if got != want {
                assert!((d - (cos - 1e-3)).abs() < 1e-5, "{l:?} {axis:?} {cos}: {got} against {want} (cosine {d})");
            }
            if d >= cos {
                assert!(got, "{l:?} {axis:?} {cos}: inside the cone (cosine {d})");
            }
        }
    }
}

/// A message-passing answer: `kind` 0 none, 1 float, 2 triple, 3 matrix, 4 string, 5 bool; `len` 0
/// for a single value or the array length; `floats` element-major; `string` valid until the next
/// call on the table.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MessageOut {
    pub kind: u32,
    pub len: u32,
    pub floats: [f32; MESSAGE_FLOATS],
    pub string: StrRef,
}

/// The renderer's calls, filled once by the runtime. Every array argument is SoA over one chunk of
/// four lanes (`x[4k + l]`) with a `mask` of 4 `i32`s (-1 active); implementations answer only the
/// active lanes.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct HostTable {
    pub ctx: *mut c_void,
    /// The matrix taking points from `from` to `to` (row-major, 16 floats); 0 for an unknown space.
    pub matrix: unsafe extern "C" fn(ctx: *mut c_void, from: StrRef, to: StrRef, out: *mut f32) -> u32,
    /// The lights of `category` reaching each active lane at `p` (3 x 4 floats): lane `l`'s light
    /// `k` in lane `l` of `out[k]` (room for `MAX_LIGHTS` rows of lights), its count in
    /// `counts[l]`.
    /// `cone` ([`CONE_ROWS`] rows: an axis, then a cosine) says which lights the caller will use:
    /// lane `l` counts only the non-ambient lights whose `L` lies within `acos(cos)` of its axis
    /// (see [`light_in_cone`]; a cosine of -1 or less: every light; above 1: none). The renderer
    /// may leave the shadows of the others untraced, their `cl` unshadowed, and says which in
    /// `pending[l]` (bit `k`: lane `l`'s light `k`). `chunk` is the batch's chunk asking
    /// ([`super::Batch::chunk`]; `u32::MAX` when unknown).
    pub lights: unsafe extern "C" fn(
        ctx: *mut c_void,
        category: StrRef,
        chunk: u32,
        mask: *const i32,
        p: *const f32,
        cone: *const f32,
        out: *mut LightLanes,
        counts: *mut u32,
        pending: *mut u32,
    ),
    /// Texture lookups: `kind` 0 `texture` (`coords` [`TEXTURE_ROWS`] rows of 4 lanes: s, t, then
    /// the filter footprint ds/dx, dt/dx, ds/dy, dt/dy (scaled by the lookup's width options),
    /// sblur and tblur, as `interp::TextureFootprint`, then the fill value that channels the
    /// texture lacks read; `first[l]` the first channel; `channels` values), 1 `environment`
    /// (`coords` [`ENVIRONMENT_ROWS`] rows: the direction, its change over a pixel step in x and in
    /// y, then sblur, tblur, swidth, twidth and fill, as `interp::EnvironmentQuery`; `first[l]`
    /// the first channel; `channels` values, at most 3), 2 `shadow` (`coords` [`SHADOW_ROWS`] rows: the point, the
    /// four corners of the region its kernel covers, then samples, sblur, tblur, swidth, twidth
    /// and bias, as `interp::ShadowQuery`; 1 value), 3 `texture3d`'s
    /// grid lookup (`coords` a point in the grid's coordinates; 1 value), 4 `pixelvalue` (`name`
    /// the channel, `coords` the raster x and y; 3 values), 5 `photonmap` (`name` the map, `coords`
    /// the point, the normal and the estimator's photon count; 3 values). Results in
    /// `out[4c + l]`; `ok[l]` 0 where the map cannot be read.
    pub texture: unsafe extern "C" fn(
        ctx: *mut c_void,
        kind: u32,
        name: StrRef,
        mask: *const i32,
        coords: *const f32,
        first: *const f32,
        channels: u32,
        out: *mut f32,
        ok: *mut u32,
    ),
    /// Rays: `kind` 0 `trace` (`a` origin, `b` direction; colour and distance: 4 results),
    /// 1 `transmission` (`a` from, `b` to; 3), 2 `occlusion` (`a` point, `b` normal, `samples`; 1),
    /// 3 `indirectdiffuse` (as occlusion; 3). `chunk` as for `lights`: the renderer charges each
    /// lane's rays to the ray tree the lane belongs to.
    pub rays: unsafe extern "C" fn(
        ctx: *mut c_void,
        kind: u32,
        chunk: u32,
        mask: *const i32,
        a: *const f32,
        b: *const f32,
        samples: *const f32,
        out: *mut f32,
    ),
    /// `gather` rays of `category` (`shadeops::gather`): from `from` along the unit `dir` (3 x 4
    /// floats each) up to `maxdist` (4); for each active lane, `out` row 0 is 1 where the ray hit a
    /// surface and 0 where it missed, and rows 1 to 13 the hit's [`GatherHit`] rows (length, the
    /// hit shader's Ci and Oi, the point, the geometric normal). `chunk` as for `rays`.
    pub gather: unsafe extern "C" fn(
        ctx: *mut c_void,
        category: StrRef,
        chunk: u32,
        mask: *const i32,
        from: *const f32,
        dir: *const f32,
        maxdist: *const f32,
        out: *mut f32,
    ),
    /// Normalised camera depth of each active lane's `p`.
    pub depth: unsafe extern "C" fn(ctx: *mut c_void, mask: *const i32, p: *const f32, out: *mut f32),
    /// How many bounces led to this batch's rays.
    pub ray_depth: unsafe extern "C" fn(ctx: *mut c_void) -> f32,
    /// Message passing and queries: `which` is the built-in's index in `Builtin::ALL`, asked for
    /// lane `lane` of chunk `chunk` (a renderer answers `rayinfo` from that lane's ray; `chunk` as
    /// for `rays`). Returns 0 when unknown.
    pub message:
        unsafe extern "C" fn(ctx: *mut c_void, which: u32, chunk: u32, lane: u32, name: StrRef, out: *mut MessageOut) -> u32,
    /// `lightsource(name)` inside an `illuminance` loop: a parameter of light `light` (a
    /// [`HostLight::id`]). Returns 0 when unknown.
    pub light_message: unsafe extern "C" fn(ctx: *mut c_void, light: u32, name: StrRef, out: *mut MessageOut) -> u32,
    /// `incident(name)`/`opposite(name)`: a parameter of the volume shader inside the surface being
    /// shaded (`interior` 1) or outside it (0); the helper picks the side per lane
    /// (`shadeops::geom::asks_interior`). Returns 0 when unknown.
    pub volume_message:
        unsafe extern "C" fn(ctx: *mut c_void, interior: u32, name: StrRef, out: *mut MessageOut) -> u32,
    /// The name of this shader (`has_kind` 0) or of the one bound as `kind`; valid until the next call.
    pub shader_name: unsafe extern "C" fn(ctx: *mut c_void, has_kind: u32, kind: StrRef) -> StrRef,
    /// `printf` output.
    pub print: unsafe extern "C" fn(ctx: *mut c_void, text: StrRef),
    /// For a pixel shader that reads other pixels: the image it finishes, which generated code
    /// reads inline (`pixelvalue` of a channel named by a literal). Null where there is none or
    /// the renderer answers through `texture` (kind 4): generated code then calls the helper.
    pub pixels: *const PixelView,
    /// For a surface batch: the lights the renderer computed for the batch's own points, which a
    /// query of every light (category `""`) at those points reads in place rather than through
    /// `lights`. Null where there are none; see [`BatchLightsView`] for what may change and when.
    pub batch_lights: *const BatchLightsView,
}

/// A surface batch's lights as the renderer computed them for the batch's points
/// ([`HostTable::batch_lights`]), by chunk as generated code asks: chunk `c`'s points are `points[c]`
/// (x, y and z rows of four lanes, the bits the renderer filled `P` with), its lanes that have one
/// are those of `lanes[c]` (-1), lane `l` has `counts[c][l]` lights (at most `slots`), in lane `l`
/// of rows `lights[c * slots ..]`, and those of them whose shadows are still untraced are the bits
/// of `pending[c][l]` (their `cl` unshadowed).
///
/// `chunks` is 0 until the renderer has computed the lights (at the batch's first query, through
/// `lights`). From then on, for the rest of the run, the arrays stay where they are with `chunks`
/// entries (`chunks * slots` rows), and change only inside calls to `lights` (which traces pending
/// shadows a query needs): generated code reads them between calls and holds no reference across
/// one. A query at other points (a shader that moved `P`), of other lanes, or whose cone takes in
/// a pending light goes to `lights`, which answers it as it answers any query.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct BatchLightsView {
    pub chunks: u32,
    pub slots: u32,
    pub points: *const [f32; 12],
    pub lanes: *const [i32; 4],
    pub counts: *const [u32; 4],
    pub pending: *const [u32; 4],
    pub lights: *const LightLanes,
}

impl Default for BatchLightsView {
    /// No lights computed yet.
    fn default() -> BatchLightsView {
        BatchLightsView {
            chunks: 0,
            slots: 0,
            points: std::ptr::null(),
            lanes: std::ptr::null(),
            counts: std::ptr::null(),
            pending: std::ptr::null(),
            lights: std::ptr::null(),
        }
    }
}

/// The image a pixel shader finishes, as generated code reads it (`pixelvalue`): `width x height`
/// pixels, row by row, each array holding one entry per pixel. [`PixelView::new`] checks what
/// generated code relies on: at least one pixel, arrays of the image's size, and an index below
/// `i32::MAX` (generated code computes `y * width + x` in 32-bit lanes).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct PixelView {
    pub width: u32,
    pub height: u32,
    /// `Ci` and alpha.
    pub rgba: *const [f32; 4],
    /// Camera-space depth.
    pub depth: *const f32,
    /// Object and shader ids (`u32::MAX` for none: -1 to a shader).
    pub object_id: *const u32,
    pub shader_id: *const u32,
    /// The unit geometric normal facing the camera (zero for none).
    pub normal: *const [f32; 3],
    /// The output variables the shader reads ([`PixelView::with_outputs`]): `output_count`
    /// pointers, the `k`-th to the array of `CompiledShader::pixel_outputs()[k]` (one entry per
    /// pixel) or null where the image keeps no such output. Null and 0 for none.
    pub outputs: *const *const [f32; 3],
    pub output_count: u32,
}

impl PixelView {
    /// A view of the image's arrays, or `None` when they do not hold `width * height` pixels each
    /// or the image is empty or too large to index in 32 bits. The view borrows the arrays: it is
    /// valid while they are neither moved, resized nor dropped.
    pub fn new(
        (width, height): (u32, u32),
        rgba: &[[f32; 4]],
        depth: &[f32],
        (object_id, shader_id): (&[u32], &[u32]),
        normal: &[[f32; 3]],
    ) -> Option<PixelView> {
        let pixels = (width as usize).checked_mul(height as usize)?;
        let fits = pixels > 0 && pixels <= i32::MAX as usize;
        let sized = [rgba.len(), depth.len(), object_id.len(), shader_id.len(), normal.len()].iter().all(|&n| n == pixels);
        (fits && sized).then_some(PixelView {
            width,
            height,
            rgba: rgba.as_ptr(),
            depth: depth.as_ptr(),
            object_id: object_id.as_ptr(),
            shader_id: shader_id.as_ptr(),
            normal: normal.as_ptr(),
            outputs: std::ptr::null(),
            output_count: 0,
        })
    }

    /// The view with the output variables `outputs` (made for an image of as many pixels; for
    /// another size the view is left without). The view borrows `outputs`'s pointers as it
    /// borrows the arrays.
    pub fn with_outputs(self, outputs: &PixelOutputs) -> PixelView {
        let pixels = self.width as usize * self.height as usize;
        if outputs.pixels != pixels || outputs.arrays.len() > u32::MAX as usize {
            return self;
        }
        PixelView { outputs: outputs.arrays.as_ptr(), output_count: outputs.arrays.len() as u32, ..self }
    }
}

/// The output-variable arrays of an image, in the order of the shader's
/// `CompiledShader::pixel_outputs` ([`PixelView::with_outputs`]).
#[derive(Clone, Debug, Default)]
pub struct PixelOutputs {
    pixels: usize,
    arrays: Vec<*const [f32; 3]>,
}

impl PixelOutputs {
    /// The arrays of an image of `pixels` pixels (`None` where the image has no such output);
    /// `None` when an array holds another number of entries.
    pub fn new<'a>(pixels: usize, arrays: impl IntoIterator<Item = Option<&'a [[f32; 3]]>>) -> Option<PixelOutputs> {
        let mut pointers = Vec::new();
        for array in arrays {
            match array {
                Some(a) if a.len() != pixels => return None,
                Some(a) => pointers.push(a.as_ptr()),
                None => pointers.push(std::ptr::null()),
            }
        }
        Some(PixelOutputs { pixels, arrays: pointers })
    }
}

/// The channels of [`PixelView`] generated code reads, by the names `pixelvalue` gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelChannel {
    Ci,
    Alpha,
    Z,
    ObjectId,
    ShaderId,
    N,
}

impl PixelChannel {
    /// The channel `pixelvalue` calls `name`; `None` for another name.
    pub fn of(name: &str) -> Option<PixelChannel> {
        Some(match name {
            "Ci" => PixelChannel::Ci,
            "alpha" => PixelChannel::Alpha,
            "z" => PixelChannel::Z,
            "objectid" => PixelChannel::ObjectId,
            "shaderid" => PixelChannel::ShaderId,
            "N" => PixelChannel::N,
            _ => return None,
        })
    }
}

/// A [`HostTable`] backed by a [`Services`] implementation, asking it lane by lane.
pub struct ServicesHost<'a> {
    host: &'a mut dyn Services,
    text: String,
    pixels: Option<PixelView>,
}

impl<'a> ServicesHost<'a> {
    pub fn new(host: &'a mut dyn Services) -> ServicesHost<'a> {
        ServicesHost { host, text: String::new(), pixels: None }
    }

    /// A host whose table also points generated code to `pixels` (see [`HostTable::pixels`]),
    /// which should hold the image `host` answers `pixel_value` from.
    pub fn with_pixels(host: &'a mut dyn Services, pixels: Option<PixelView>) -> ServicesHost<'a> {
        ServicesHost { pixels, ..ServicesHost::new(host) }
    }

    /// The table; valid while `self` is neither moved nor dropped.
    pub fn table(&mut self) -> HostTable {
        HostTable {
            ctx: self as *mut ServicesHost<'a> as *mut c_void,
            matrix: sv_matrix,
            lights: sv_lights,
            texture: sv_texture,
            rays: sv_rays,
            gather: sv_gather,
            depth: sv_depth,
            ray_depth: sv_ray_depth,
            message: sv_message,
            light_message: sv_light_message,
            volume_message: sv_volume_message,
            shader_name: sv_shader_name,
            print: sv_print,
            pixels: self.pixels.as_ref().map_or(std::ptr::null(), |v| v as *const PixelView),
            batch_lights: std::ptr::null(),
        }
    }
}

/// # Safety
/// `ctx` is the `ctx` of a table made by [`ServicesHost::table`], still alive.
unsafe fn sv<'x>(ctx: *mut c_void) -> &'x mut ServicesHost<'x> {
    // SAFETY: the caller's contract.
    unsafe { &mut *(ctx as *mut ServicesHost<'x>) }
}

fn lanes_of(mask: *const i32) -> [bool; 4] {
    // SAFETY: every caller passes 4 mask entries.
    let m = unsafe { std::slice::from_raw_parts(mask, 4) };
    [m[0] != 0, m[1] != 0, m[2] != 0, m[3] != 0]
}

/// # Safety
/// `p` points to `4 * k` floats.
unsafe fn lane3(p: *const f32, k: usize, l: usize) -> V3 {
    // SAFETY: the caller's contract.
    unsafe { [*p.add(4 * k + l), *p.add(4 * (k + 1) + l), *p.add(4 * (k + 2) + l)] }
}

unsafe extern "C" fn sv_matrix(ctx: *mut c_void, from: StrRef, to: StrRef, out: *mut f32) -> u32 {
    // SAFETY: the table's contract.
    let (h, from, to) = unsafe { (sv(ctx), from.as_str(), to.as_str()) };
    match h.host.matrix(from, to) {
        Some(m) => {
            // SAFETY: `out` holds 16 floats.
            unsafe { std::ptr::copy_nonoverlapping(m.as_ptr(), out, 16) };
            1
        }
        None => 0,
    }
}

unsafe extern "C" fn sv_lights(
    ctx: *mut c_void,
    category: StrRef,
    _chunk: u32,
    mask: *const i32,
    p: *const f32,
    _cone: *const f32,
    out: *mut LightLanes,
    counts: *mut u32,
    pending: *mut u32,
) {
    // SAFETY: the table's contract.
    let (h, category) = unsafe { (sv(ctx), category.as_str()) };
    // SAFETY: `pending` holds 4 entries. The services answer every light shadowed.
    unsafe { std::ptr::write_bytes(pending, 0, 4) };
    for (l, on) in lanes_of(mask).into_iter().enumerate() {
        if !on {
            continue;
        }
        // SAFETY: `p` holds 3 x 4 floats; `out` room for MAX_LIGHTS rows of lights, `counts` 4.
        unsafe {
            let lights = h.host.lights(category, lane3(p, 0, l));
            let n = lights.len().min(MAX_LIGHTS);
            for (k, s) in lights.iter().take(n).enumerate() {
                let light = HostLight {
                    l: s.l,
                    cl: s.cl,
                    ol: s.ol,
                    ambient: u32::from(s.ambient),
                    nondiffuse: s.nondiffuse,
                    nonspecular: s.nonspecular,
                    id: k as u32,
                };
                (*out.add(k)).set_lane(l, &light);
            }
            *counts.add(l) = n as u32;
        }
    }
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn sv_texture(
    ctx: *mut c_void,
    kind: u32,
    name: StrRef,
    mask: *const i32,
    coords: *const f32,
    first: *const f32,
    channels: u32,
    out: *mut f32,
    ok: *mut u32,
) {
    // SAFETY: the table's contract.
    let (h, name) = unsafe { (sv(ctx), name.as_str()) };
    for (l, on) in lanes_of(mask).into_iter().enumerate() {
        if !on {
            continue;
        }
        // SAFETY: the sizes the table documents.
        unsafe {
            let c = lane3(coords, 0, l);
            let got: Option<Vec<f32>> = match kind {
                0 => {
                    let f = *first.add(l);
                    let row = |k: usize| *coords.add(4 * k + l);
                    let fp = TextureFootprint {
                        dsdx: row(2),
                        dtdx: row(3),
                        dsdy: row(4),
                        dtdy: row(5),
                        sblur: row(6),
                        tblur: row(7),
                    };
                    let got = h.host.texture_filtered(name, c[0], c[1], &fp, f.max(0.0) as usize, channels as usize);
                    // Channels the texture lacks read the fill value (row 8).
                    got.map(|mut got| {
                        got.resize(channels as usize, row(8));
                        got
                    })
                }
                1 => {
                    let rows = std::slice::from_raw_parts(coords, 4 * ENVIRONMENT_ROWS);
                    let first = (*first.add(l)).max(0.0) as usize;
                    h.host.environment(name, &environment_query_of(rows, l), first, channels as usize)
                }
                3 => h.host.texture3d(name, c).map(|v| vec![v]),
                4 => h.host.pixel_value(name, c[0], c[1]).map(|v| v.to_vec()),
                5 => {
                    let row = |k: usize| *coords.add(4 * k + l);
                    h.host.photonmap(name, c, [row(3), row(4), row(5)], row(6)).map(|v| v.to_vec())
                }
                _ => {
                    let rows = std::slice::from_raw_parts(coords, 4 * SHADOW_ROWS);
                    Some(vec![h.host.shadow(name, &shadow_query_of(rows, l))])
                }
            };
            *ok.add(l) = u32::from(got.is_some());
            for (j, x) in got.unwrap_or_default().iter().take(channels.max(1) as usize).enumerate() {
                *out.add(4 * j + l) = *x;
            }
        }
    }
}

/// Lane `l`'s shadow query from a table call's coordinate rows (see [`HostTable::texture`]:
/// [`SHADOW_ROWS`] rows of 4 lanes; missing rows read 0).
pub fn shadow_query_of(coords: &[f32], l: usize) -> ShadowQuery {
    let row = |k: usize| coords.get(4 * k + l).copied().unwrap_or(0.0);
    let triple = |k: usize| [row(k), row(k + 1), row(k + 2)];
    ShadowQuery {
        p: triple(0),
        corners: [triple(3), triple(6), triple(9), triple(12)],
        samples: row(15),
        sblur: row(16),
        tblur: row(17),
        swidth: row(18),
        twidth: row(19),
        bias: row(20),
    }
}

/// Lane `l`'s environment query from a table call's coordinate rows (see [`HostTable::texture`]:
/// [`ENVIRONMENT_ROWS`] rows of 4 lanes; missing rows read 0).
pub fn environment_query_of(coords: &[f32], l: usize) -> EnvironmentQuery {
    let row = |k: usize| coords.get(4 * k + l).copied().unwrap_or(0.0);
    let triple = |k: usize| [row(k), row(k + 1), row(k + 2)];
    EnvironmentQuery {
        dir: triple(0),
        ddx: triple(3),
        ddy: triple(6),
        sblur: row(9),
        tblur: row(10),
        swidth: row(11),
        twidth: row(12),
        fill: row(13),
    }
}

unsafe extern "C" fn sv_rays(
    ctx: *mut c_void,
    kind: u32,
    _chunk: u32,
    mask: *const i32,
    a: *const f32,
    b: *const f32,
    samples: *const f32,
    out: *mut f32,
) {
    // SAFETY: the table's contract.
    let h = unsafe { sv(ctx) };
    for (l, on) in lanes_of(mask).into_iter().enumerate() {
        if !on {
            continue;
        }
        // SAFETY: the sizes the table documents.
        unsafe {
            let (x, y) = (lane3(a, 0, l), lane3(b, 0, l));
            let r: Vec<f32> = match kind {
                0 => {
                    let (c, d) = h.host.trace(x, y);
                    vec![c[0], c[1], c[2], d]
                }
                1 => h.host.transmission(x, y).to_vec(),
                2 => vec![h.host.occlusion(x, y, *samples.add(l))],
                _ => h.host.indirect_diffuse(x, y, *samples.add(l)).to_vec(),
            };
            for (j, v) in r.iter().enumerate() {
                *out.add(4 * j + l) = *v;
            }
        }
    }
}

unsafe extern "C" fn sv_gather(
    ctx: *mut c_void,
    category: StrRef,
    _chunk: u32,
    mask: *const i32,
    from: *const f32,
    dir: *const f32,
    maxdist: *const f32,
    out: *mut f32,
) {
    // SAFETY: the table's contract.
    let (h, category) = unsafe { (sv(ctx), category.as_str()) };
    for (l, on) in lanes_of(mask).into_iter().enumerate() {
        if !on {
            continue;
        }
        // SAFETY: the sizes the table documents (3 x 4 floats of `from` and `dir`, 4 of `maxdist`,
        // 14 x 4 of `out`).
        unsafe {
            let hit = h.host.gather_ray(category, lane3(from, 0, l), lane3(dir, 0, l), *maxdist.add(l));
            *out.add(l) = if hit.is_some() { 1.0 } else { 0.0 };
            if let Some(g) = hit {
                let rows = [
                    g.length, g.ci[0], g.ci[1], g.ci[2], g.oi[0], g.oi[1], g.oi[2], g.p[0], g.p[1], g.p[2], g.n[0],
                    g.n[1], g.n[2],
                ];
                for (j, x) in rows.iter().enumerate() {
                    *out.add(4 * (j + 1) + l) = *x;
                }
            }
        }
    }
}

unsafe extern "C" fn sv_depth(ctx: *mut c_void, mask: *const i32, p: *const f32, out: *mut f32) {
    // SAFETY: the table's contract.
    let h = unsafe { sv(ctx) };
    for (l, on) in lanes_of(mask).into_iter().enumerate() {
        if on {
            // SAFETY: `p` 3 x 4 floats, `out` 4.
            unsafe { *out.add(l) = h.host.depth(lane3(p, 0, l)) };
        }
    }
}

unsafe extern "C" fn sv_ray_depth(ctx: *mut c_void) -> f32 {
    // SAFETY: the table's contract.
    unsafe { sv(ctx) }.host.ray_depth()
}

/// A `Services` host has one answer for `lightsource()` whichever the light (the interpreter's).
unsafe extern "C" fn sv_light_message(ctx: *mut c_void, _light: u32, name: StrRef, out: *mut MessageOut) -> u32 {
    // SAFETY: the caller's contract, passed on.
    unsafe { sv_message(ctx, Builtin::Lightsource as u32, 0, 0, name, out) }
}

unsafe extern "C" fn sv_message(
    ctx: *mut c_void,
    which: u32,
    _chunk: u32,
    _lane: u32,
    name: StrRef,
    out: *mut MessageOut,
) -> u32 {
    // SAFETY: the table's contract.
    let (h, name, out) = unsafe { (sv(ctx), name.as_str(), &mut *out) };
    let Some(b) = Builtin::ALL.get(which as usize) else { return 0 };
    let Some(v) = h.host.message(*b, name) else { return 0 };
    put_value(h, v, out)
}

unsafe extern "C" fn sv_volume_message(ctx: *mut c_void, interior: u32, name: StrRef, out: *mut MessageOut) -> u32 {
    // SAFETY: the table's contract.
    let (h, name, out) = unsafe { (sv(ctx), name.as_str(), &mut *out) };
    let Some(v) = h.host.volume_message(interior != 0, name) else { return 0 };
    put_value(h, v, out)
}

/// A message's answer into the table's reply: 1, or 0 when it has no reply's shape.
fn put_value(h: &mut ServicesHost<'_>, v: Value, out: &mut MessageOut) -> u32 {
    fn kind(v: &Value) -> u32 {
        match v {
            Value::Float(_) => 1,
            Value::Triple(_) => 2,
            Value::Matrix(_) => 3,
            Value::String(_) => 4,
            Value::Bool(_) => 5,
            _ => 0,
        }
    }
    fn floats(v: &Value, out: &mut Vec<f32>) {
        match v {
            Value::Float(x) => out.push(*x),
            Value::Bool(x) => out.push(f32::from(u8::from(*x))),
            Value::Triple(t) => out.extend_from_slice(t),
            Value::Matrix(m) => out.extend_from_slice(m),
            _ => {}
        }
    }
    let mut fl = Vec::new();
    match &v {
        Value::Array(items) => {
            let k = items.first().map(kind).unwrap_or(0);
            if items.iter().any(|i| kind(i) != k) || k == 4 {
                return 0;
            }
            out.kind = k;
            out.len = items.len() as u32;
            items.iter().for_each(|i| floats(i, &mut fl));
        }
        Value::String(s) => {
            out.kind = 4;
            out.len = 0;
            h.text = s.to_string();
            out.string = StrRef::new(&h.text);
        }
        other => {
            out.kind = kind(other);
            out.len = 0;
            floats(other, &mut fl);
        }
    }
    if fl.len() > MESSAGE_FLOATS {
        return 0;
    }
    out.floats[..fl.len()].copy_from_slice(&fl);
    1
}

unsafe extern "C" fn sv_shader_name(ctx: *mut c_void, has_kind: u32, kind: StrRef) -> StrRef {
    // SAFETY: the table's contract.
    let (h, kind) = unsafe { (sv(ctx), kind.as_str()) };
    h.text = h.host.shader_name((has_kind != 0).then_some(kind));
    StrRef::new(&h.text)
}

unsafe extern "C" fn sv_print(ctx: *mut c_void, text: StrRef) {
    // SAFETY: the table's contract.
    let (h, text) = unsafe { (sv(ctx), text.as_str()) };
    h.host.print(text);
}

// ---- The helpers' side of a batch ----

/// What `Batch::ctx` points to while a batch is shaded: the table and the lights of the light loops
/// run so far (a loop asks once per chunk and keeps them here while its body runs).
pub struct HostCtx {
    table: *const HostTable,
    /// Where runtime checks (loop budget, array indices) record what they found.
    errors: *const super::RuntimeErrors,
    light_sets: Vec<LightSet>,
    light_buffer: Vec<LightLanes>,
    /// The last light query (category, points' bits, lanes) and its counts, answered from
    /// `light_buffer`.
    last_lights: Option<(LightQueryKey, LightAnswer)>,
    /// The space matrices asked so far, by (from, to) string handle: each pair is asked of the
    /// renderer once per batch, however many chunks use it.
    matrices: Vec<((u32, u32), Option<M4>)>,
    /// Whether the buffers above came from this thread's spares ([`HostCtx::use_spare_buffers`]).
    pooled: bool,
}

/// What identifies a light query: category, the points' bits, the lanes asking.
type LightQueryKey = (String, [u32; 12], [bool; 4]);

/// The answer kept for the last light query: counts, and the lights left unshadowed per lane.
type LightAnswer = ([u32; 4], [u32; 4]);

/// A chunk's lights ([`Cx::lights`]): each lane's count, and where the rows are: in the batch's
/// view (a pointer to its first row and how many rows), or (`None`) in the context's buffer.
#[derive(Clone, Copy)]
struct LightsAnswer {
    counts: [u32; 4],
    batch_rows: Option<(*const LightLanes, usize)>,
}

/// The bits of the first `count` lights (all 32 from 32 on).
fn kept_lights(count: u32) -> u32 {
    if count >= 32 {
        u32::MAX
    } else {
        (1u32 << count) - 1
    }
}

struct LightSet {
    lights: Vec<HostLight>,
    /// Per lane, the indices of its non-ambient lights in order.
    order: [Vec<usize>; 4],
}

/// A [`HostCtx`]'s buffers, reused from run to run: a renderer runs shaders batch after batch,
/// and allocating them afresh for each would be thousands of allocations a frame.
#[derive(Default)]
struct CtxBuffers {
    light_sets: Vec<LightSet>,
    light_buffer: Vec<LightLanes>,
    matrices: Vec<((u32, u32), Option<M4>)>,
}

/// Buffers kept per thread: as many as runs nest (a surface's lights, the shading of traced rays).
const KEPT_CTX_BUFFERS: usize = 16;

thread_local! {
    static CTX_BUFFERS: std::cell::RefCell<Vec<CtxBuffers>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl HostCtx {
    pub(super) fn new(table: *const HostTable, errors: *const super::RuntimeErrors) -> HostCtx {
        HostCtx {
            table,
            errors,
            light_sets: Vec::new(),
            light_buffer: Vec::new(),
            last_lights: None,
            matrices: Vec::new(),
            pooled: false,
        }
    }

    /// The image the table's renderer gives pixel shaders to read inline (null for none).
    pub(super) fn pixels(&self) -> *const PixelView {
        if self.table.is_null() {
            return std::ptr::null();
        }
        // SAFETY: a non-null table is valid for the run (`CompiledShader::run`'s caller).
        unsafe { (*self.table).pixels }
    }

    /// Takes this thread's spare buffers before the first use of any: only runs that use them
    /// take them (many runs, a light shader's or a small batch's, need none), and a run that took
    /// none gives none back.
    fn use_spare_buffers(&mut self) {
        if self.pooled {
            return;
        }
        self.pooled = true;
        let taken = CTX_BUFFERS.try_with(|s| s.try_borrow_mut().ok().and_then(|mut s| s.pop())).ok().flatten();
        let CtxBuffers { mut light_sets, light_buffer, mut matrices } = taken.unwrap_or_default();
        light_sets.clear();
        // Not cleared: the renderer writes the entries it counts before any is read, and clearing
        // it would make each batch's first query write all `MAX_LIGHTS` rows (6.6 KB) again.
        matrices.clear();
        (self.light_sets, self.light_buffer, self.matrices) = (light_sets, light_buffer, matrices);
    }
}

impl Drop for HostCtx {
    fn drop(&mut self) {
        if !self.pooled {
            return;
        }
        let buffers = CtxBuffers {
            light_sets: std::mem::take(&mut self.light_sets),
            light_buffer: std::mem::take(&mut self.light_buffer),
            matrices: std::mem::take(&mut self.matrices),
        };
        let _ = CTX_BUFFERS.try_with(|s| {
            if let Ok(mut s) = s.try_borrow_mut() {
                if s.len() < KEPT_CTX_BUFFERS {
                    s.push(buffers);
                }
            }
        });
    }
}

/// The pieces of a batch a helper works with.
struct Cx<'a> {
    table: Option<&'a HostTable>,
    /// The chunk being shaded (`Batch::chunk`).
    chunk: u32,
    strings: &'a mut StringTable,
    ctx: &'a mut HostCtx,
    mask: [bool; 4],
    input: &'a [f32],
    out: &'a mut [f32],
}

impl Cx<'_> {
    fn f(&self, k: usize, l: usize) -> f32 {
        self.input[4 * k + l]
    }
    fn v3(&self, k: usize, l: usize) -> V3 {
        [self.f(k, l), self.f(k + 1, l), self.f(k + 2, l)]
    }
    /// A string argument (uniform: lane 0).
    fn s(&self, k: usize) -> String {
        self.str(k).to_string()
    }
    /// A string argument, borrowed.
    fn str(&self, k: usize) -> &str {
        self.strings.get(self.input[4 * k].to_bits())
    }
    /// Lane `l`'s string of argument `k` (generated code splats uniform strings).
    fn str_lane(&self, k: usize, l: usize) -> &str {
        self.strings.get(self.input[4 * k + l].to_bits())
    }
    fn set(&mut self, j: usize, l: usize, x: f32) {
        self.out[4 * j + l] = x;
    }
    fn set3(&mut self, j: usize, l: usize, v: V3) {
        for (k, x) in v.iter().enumerate() {
            self.set(j + k, l, *x);
        }
    }
    /// Output triple `j` of the active lanes from rows of four lanes; inactive lanes keep theirs.
    fn set3_lanes(&mut self, j: usize, v: &Lanes3) {
        let mask = glam::BVec4A::from_array(self.mask);
        for (k, row) in v.0.iter().enumerate() {
            let Some(out) = self.out.get_mut(4 * (j + k)..4 * (j + k) + 4) else { return };
            glam::Vec4::select(mask, *row, glam::Vec4::from_slice(out)).write_to_slice(out);
        }
    }
    fn active(&self) -> impl Iterator<Item = usize> {
        let m = self.mask;
        (0..4).filter(move |l| m[*l])
    }
    /// Records that a runtime check of `kind` failed at `site` (once each: see `RuntimeErrors`).
    fn report(&self, kind: u32, site: u32) {
        // SAFETY: `errors` is null or points to the compiled shader's log, alive while it runs.
        if let Some(errors) = unsafe { self.ctx.errors.as_ref() } {
            errors.record(kind, site);
        }
    }
    /// Lane `l`'s handle of a string the shader made at `site`, `cut` when it was longer than
    /// `MAX_STRING_LEN`; the empty string past the batch's `STRING_BYTES_BUDGET`. Both reported.
    fn made_string(&mut self, text: &str, cut: bool, site: u32) -> u32 {
        if cut {
            self.report(super::lower::RUNTIME_STRING_CUT, site);
        }
        match self.strings.intern_made(text) {
            Some(h) => h,
            None => {
                self.report(super::lower::RUNTIME_STRINGS_FULL, site);
                self.strings.intern("")
            }
        }
    }
    /// The matrix from space `from` to `to`, asked of the renderer once per batch (the answers are
    /// kept in the batch's `HostCtx`: spaces do not change while a batch is shaded).
    fn matrix(&mut self, from: u32, to: u32) -> Option<M4> {
        if let Some((_, m)) = self.ctx.matrices.iter().find(|(k, _)| *k == (from, to)) {
            return *m;
        }
        let m = self.table.and_then(|t| {
            let (f, g) = (self.strings.get(from), self.strings.get(to));
            let mut m = [0.0f32; 16];
            // SAFETY: the runtime's table; `m` holds 16 floats.
            let ok = unsafe { (t.matrix)(t.ctx, StrRef::new(f), StrRef::new(g), m.as_mut_ptr()) };
            (ok != 0).then_some(m)
        });
        self.ctx.use_spare_buffers();
        self.ctx.matrices.push(((from, to), m));
        m
    }
    /// The lights reaching the chunk's active lanes at `p` (argument `k`): lane `l`'s `i`-th light
    /// is lane `l` of `self.light_rows(&answer)[i]`, for `i < answer.counts[l]`. `cone` as
    /// `HostTable::lights` takes it.
    fn lights(&mut self, category: &str, k: usize, cone: Cone) -> LightsAnswer {
        if category.is_empty() {
            if let Some(answer) = self.batch_lights(k, cone) {
                return answer;
            }
        }
        let rows = cone.rows(self.input);
        LightsAnswer { counts: self.asked_lights(category, k, &rows), batch_rows: None }
    }

    /// The rows of a [`Cx::lights`] answer.
    fn light_rows(&self, answer: &LightsAnswer) -> &[LightLanes] {
        match answer.batch_rows {
            // SAFETY: rows of the batch's view, valid while the run lasts and unchanged until the
            // next call into the renderer (`BatchLightsView`), which this borrow of `self` (the
            // helper's) outlasts no helper call.
            Some((rows, n)) => unsafe { std::slice::from_raw_parts(rows, n) },
            None => &self.ctx.light_buffer,
        }
    }

    /// A query of every light at argument `k`, answered from the batch's own lights in place
    /// ([`HostTable::batch_lights`]) when the chunk's asking lanes are at the batch's points and
    /// the query's cone takes in none of their pending lights; `None` for the renderer to answer.
    fn batch_lights(&self, k: usize, cone: Cone) -> Option<LightsAnswer> {
        // SAFETY: the table's pointer is null or valid for the run.
        let view = unsafe { self.table?.batch_lights.as_ref() }?;
        let c = self.chunk as usize;
        if c >= view.chunks as usize {
            return None;
        }
        let rows: &[f32; 12] = self.input.get(4 * k..4 * k + 12)?.try_into().ok()?;
        // SAFETY: `c` is below `chunks`, each array's length (`BatchLightsView`).
        let (points, lanes, counts, pending) =
            unsafe { (&*view.points.add(c), *view.lanes.add(c), *view.counts.add(c), *view.pending.add(c)) };
        // Bit for bit, each asking lane a lane of the batch's: no bit of any difference is set.
        let differ = (0..4).fold(0u32, |acc, l| {
            let lane = (0..3).fold(u32::from(lanes[l] == 0), |d, r| d | (points[4 * r + l].to_bits() ^ rows[4 * r + l].to_bits()));
            acc | if self.mask[l] { lane } else { 0 }
        });
        if differ != 0 {
            return None;
        }
        let slots = (view.slots as usize).min(MAX_LIGHTS) as u32;
        let counts: [u32; 4] = std::array::from_fn(|l| if self.mask[l] { counts[l].min(slots) } else { 0 });
        let pending: [u32; 4] = std::array::from_fn(|l| pending[l] & kept_lights(counts[l]));
        let most = counts.iter().copied().max().unwrap_or(0) as usize;
        // SAFETY: chunk `c`'s rows start at `c * slots` of `chunks * slots`, and `most <= slots`.
        let first = unsafe { view.lights.add(c * view.slots as usize) };
        let rows = unsafe { std::slice::from_raw_parts(first, most) };
        if pending.iter().any(|&p| p != 0) && light_sums::pending_in_cone(rows, pending, &cone.rows(self.input)) {
            return None;
        }
        Some(LightsAnswer { counts, batch_rows: Some((first, most)) })
    }

    /// [`Cx::lights`] asked of the renderer (`HostTable::lights`), its rows in `light_buffer`.
    fn asked_lights(&mut self, category: &str, k: usize, cone: &[f32; 4 * CONE_ROWS]) -> [u32; 4] {
        let mut counts = [0u32; 4];
        let Some(t) = self.table else { return counts };
        // `ambient()`, `diffuse()` and `specular()` of one chunk ask for the same lights: the
        // renderer is asked once per (category, points, lanes), and again only when a query's cone
        // takes in a light the last answer left unshadowed.
        let Some(Ok(rows)) = self.input.get(4 * k..4 * k + 12).map(<&[f32; 12]>::try_from) else { return counts };
        let points: [u32; 12] = rows.map(f32::to_bits);
        if let Some(((cat, p, m), (counts, pending))) = &self.ctx.last_lights {
            // Points first (they differ from chunk to chunk), all twelve words at once: an array
            // comparison is a memcmp call, a short-circuiting one a branch per word.
            let differ = p.iter().zip(&points).fold(0, |acc, (a, b)| acc | (a ^ b));
            if differ == 0 && *m == self.mask && same_category(cat, category) {
                let any_pending = pending.iter().fold(0, |acc, p| acc | p) != 0;
                let needs_more = any_pending && light_sums::pending_in_cone(&self.ctx.light_buffer, *pending, cone);
                if !needs_more {
                    return *counts;
                }
            }
        }
        // One buffer per batch: the renderer writes the entries it counts, and only those are read.
        self.ctx.use_spare_buffers();
        let out = &mut self.ctx.light_buffer;
        out.resize(MAX_LIGHTS, LightLanes::default());
        let mask: [i32; 4] = self.mask.map(|m| if m { -1 } else { 0 });
        let mut pending = [0u32; 4];
        // SAFETY: the table's documented sizes.
        unsafe {
            (t.lights)(
                t.ctx,
                StrRef::new(category),
                self.chunk,
                mask.as_ptr(),
                self.input[4 * k..].as_ptr(),
                cone.as_ptr(),
                out.as_mut_ptr(),
                counts.as_mut_ptr(),
                pending.as_mut_ptr(),
            )
        };
        let counts = counts.map(|c| c.min(MAX_LIGHTS as u32));
        let pending: [u32; 4] =
            std::array::from_fn(|l| if self.mask[l] { pending[l] & kept_lights(counts[l]) } else { 0 });
        // The key's string is kept from query to query: a chunk's first query must not allocate.
        match &mut self.ctx.last_lights {
            Some(((cat, p, m), answer)) => {
                if !same_category(cat, category) {
                    cat.clear();
                    cat.push_str(category);
                }
                (*p, *m, *answer) = (points, self.mask, (counts, pending));
            }
            None => self.ctx.last_lights = Some(((category.to_string(), points, self.mask), (counts, pending))),
        }
        counts
    }


    /// Lane `l`'s lights of a [`Cx::lights`] answer (its count of them).
    fn lane_lights<'s>(&'s self, answer: &LightsAnswer, l: usize) -> impl Iterator<Item = HostLight> + 's {
        let n = answer.counts.get(l).copied().unwrap_or(0);
        self.light_rows(answer).iter().take(n as usize).map(move |x| x.lane(l))
    }
}

/// The cone of a light query ([`Cx::lights`]), as `HostTable::lights` takes it (axis rows, then
/// each lane's cosine), made only where it is read: most queries are answered from the batch's
/// lights, which read it only for lights left unshadowed.
#[derive(Clone, Copy)]
enum Cone<'a> {
    /// These rows.
    Rows(&'a [f32; 4 * CONE_ROWS]),
    /// The hemisphere around each lane's normal, input `k` of the helper: what `diffuse()`,
    /// `specular()` and `phong()` sum over.
    Hemisphere(usize),
    /// No light but the ambient ones (`ambient()`).
    Nothing,
}

impl Cone<'_> {
    fn rows(self, input: &[f32]) -> [f32; 4 * CONE_ROWS] {
        match self {
            Cone::Rows(rows) => *rows,
            Cone::Hemisphere(k) => {
                let mut cone = [0.0; 4 * CONE_ROWS];
                if let Some(rows) = input.get(4 * k..4 * k + 12) {
                    cone[..12].copy_from_slice(rows);
                }
                cone
            }
            Cone::Nothing => {
                let mut cone = [0.0; 4 * CONE_ROWS];
                cone[12..].fill(NO_LIGHT);
                cone
            }
        }
    }
}

/// A host helper's body: runs `f` with the batch's pieces.
///
/// # Safety
/// `batch` is the record `CompiledShader::run` made; `mask` 4 entries; `input`/`out` the sizes the
/// helper declares.
unsafe fn with(
    batch: *mut Batch,
    mask: *const i32,
    input: *const f32,
    out: *mut f32,
    ins: usize,
    outs: usize,
    f: impl FnOnce(&mut Cx<'_>),
) {
    // SAFETY: the caller's contract; `strings` and `ctx` point to live values owned by `run`'s frame
    // and by the batch, distinct from the buffers generated code passes. A variadic helper's input
    // 1 (lane 0) holds its number of inputs.
    unsafe {
        let ins = if ins == VARIADIC { (*input.add(4)) as usize } else { ins };
        let b = &mut *batch;
        let ctx = &mut *b.ctx;
        let table = ctx.table.as_ref();
        let mut cx = Cx {
            table,
            chunk: b.chunk,
            strings: &mut *b.strings,
            ctx,
            mask: lanes_of(mask),
            input: std::slice::from_raw_parts(input, 4 * ins),
            out: std::slice::from_raw_parts_mut(out, 4 * outs.max(1)),
        };
        f(&mut cx)
    }
}

/// Whether two light categories are the same. Most are empty (every light): an empty one is
/// told by its length, where `==` would still call `memcmp` (three light queries a chunk), and
/// glibc's EVEX `memcmp` makes a masked load at an empty string's dangling address: a
/// fault-suppressed load, very slow on some CPUs.
#[inline]
pub fn same_category(a: &str, b: &str) -> bool {
    a.len() == b.len() && (a.is_empty() || a == b)
}

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// The cosine of the angle between `a` and `b`, in `[-1, 1]` (NaN where one is not finite).
pub(super) fn cosine_between(a: V3, b: V3) -> f32 {
    dot(geom::normalize(a), geom::normalize(b)).clamp(-1.0, 1.0)
}

/// The interpreter's cone test: the angle between `a` and `b`, by RSL's `acos` (whose four-lane
/// form gives the same bits).
pub(super) fn angle_between(a: V3, b: V3) -> f32 {
    transcendental::acos(cosine_between(a, b))
}

/// The scalar reference of [`light_sums::specular`]'s weight (the interpreter's `specular_brdf`
/// with `l`, `n` and `v` normalised by the caller).
#[cfg(test)]
fn specular_brdf(l: V3, n: V3, v: V3, roughness: f32) -> f32 {
    let h = geom::normalize(add(l, v));
    transcendental::pow(dot(n, h).max(0.0), geom::specular_exponent(roughness))
}

/// `sum_lights` of the interpreter over one lane's lights; `weight` gets each light and its unit
/// direction. Bit for bit the interpreter's: `in_hemisphere` and the weights normalise the same
/// vectors, here once each. The reference the four-lane sums (`light_sums`) are tested against.
#[cfg(test)]
fn sum_lights(lights: impl Iterator<Item = HostLight>, n: V3, weight: impl Fn(&HostLight, V3) -> f32) -> V3 {
    let mut sum = [0.0; 3];
    let unit_n = geom::normalize(n);
    for l in lights.filter(|l| l.ambient == 0) {
        let unit_l = geom::normalize(l.l);
        // `geom::in_hemisphere(l.l, n)`: a NaN cosine is not facing either.
        let facing = dot(unit_l, unit_n) >= 0.0;
        if !facing {
            continue;
        }
        let w = weight(&l, unit_l);
        sum = add(sum, l.cl.map(|c| c * w));
    }
    sum
}

/// Writes a message answer into lane `l` of a message helper's outputs: `[found, value...]`, found
/// only when the answer has exactly the destination's shape (the interpreter's `same_shape`;
/// textureinfo: the same scalar kind).
fn put_message(cx: &mut Cx<'_>, l: usize, found: u32, out: &MessageOut, class: u32, len: u32, textureinfo: bool) {
    let fits = found != 0 && out.kind == class && out.len == len && !(textureinfo && len != 0);
    cx.set(0, l, if fits { 1.0 } else { 0.0 });
    if !fits {
        return;
    }
    if class == 4 {
        // SAFETY: the table's contract: valid until the next call.
        let s = unsafe { out.string.as_str() }.to_string();
        let h = cx.strings.intern(&s);
        cx.set(1, l, f32::from_bits(h));
    } else {
        let per = match class {
            1 => 1,
            2 => 3,
            _ => 16,
        };
        for j in 0..(per * len.max(1) as usize).min(MESSAGE_FLOATS) {
            cx.set(1 + j, l, out.floats[j]);
        }
    }
}

/// The input arity of a variadic host helper (`format`, `printf`): its input 1 holds the number of
/// inputs.
pub(super) const VARIADIC: usize = usize::MAX;

/// A host helper: its symbol, function and arity (in `f32x4` values).
pub(super) struct HostHelper {
    pub name: &'static str,
    f: unsafe extern "C" fn(*mut Batch, *const i32, *const f32, *mut f32),
    pub ins: usize,
    pub outs: usize,
}

impl HostHelper {
    pub fn ptr(&self) -> *const u8 {
        self.f as *const u8
    }
}

macro_rules! host_helpers {
    ($($fname:ident $sym:literal $i:expr => $o:literal |$cx:ident| $body:block)*) => {
        $(
            /// # Safety
            /// See [`with`].
            unsafe extern "C" fn $fname(batch: *mut Batch, mask: *const i32, input: *const f32, out: *mut f32) {
                let body = |$cx: &mut Cx<'_>| $body;
                // SAFETY: generated code passes the batch record and buffers of the declared sizes.
                unsafe { with(batch, mask, input, out, $i, $o, body) }
            }
        )*
        pub(super) static HOST_HELPERS: &[HostHelper] = &[
            $(HostHelper { name: $sym, f: $fname, ins: $i, outs: $o },)*
        ];
    };
}

/// Message destination classes (`msg_class`): 1 float, 2 triple, 3 matrix, 4 string.
pub(super) fn msg_class(base: crate::ir::BaseType) -> Option<u32> {
    use crate::ir::BaseType as T;
    match base {
        T::Float => Some(1),
        b if b.is_triple() => Some(2),
        T::Matrix => Some(3),
        T::String => Some(4),
        _ => None,
    }
}

host_helpers! {
    // [from, to] -> [m; 16, found]
    h_matrix "rtsl_h_matrix" 2 => 17 |cx| {
        let (from, to) = (cx.input[0].to_bits(), cx.input[4].to_bits());
        let m = cx.matrix(from, to);
        for l in cx.active() {
            for (j, x) in m.unwrap_or(matrix::IDENTITY).iter().enumerate() {
                cx.set(j, l, *x);
            }
            cx.set(16, l, if m.is_some() { 1.0 } else { 0.0 });
        }
    }
    // [space, c] -> c in RGB (unchanged for an unknown space)
    h_to_rgb "rtsl_h_to_rgb" 4 => 3 |cx| {
        let space = cx.s(0);
        for l in cx.active() {
            let c = cx.v3(1, l);
            cx.set3(0, l, color::to_rgb(&space, c).unwrap_or(c));
        }
    }
    // [a, b, c, three]: ctransform(a, b, c) when three, else ctransform(a, c)
    h_ctransform "rtsl_h_ctransform" 6 => 3 |cx| {
        let (a, b) = (cx.s(0), cx.s(1));
        for l in cx.active() {
            let c = cx.v3(2, l);
            let r = if cx.f(5, l) != 0.0 { color::ctransform(&a, &b, c) } else { color::from_rgb(&a, c) };
            cx.set3(0, l, r.unwrap_or(c));
        }
    }
    // [category, P, axis, angle, cone, nesting] -> [set, count]: the lights of an illuminance loop,
    // kept in the context at the loop's nesting depth. A loop's set is read only in its body, and
    // a loop at depth `d` starts only once the last one at `d` has ended, so it replaces that
    // one's set and those of loops nested in it: the sets kept are bounded by the nesting depth,
    // not by how many times loops run (an illuminance in a long `for` loop).
    h_lights "rtsl_h_lights" 10 => 2 |cx| {
        let category = cx.s(0);
        let cone: [f32; 4 * CONE_ROWS] = std::array::from_fn(|i| match i {
            0..12 => cx.input[16 + i],
            _ if cx.f(8, i - 12) != 0.0 => cx.f(7, i - 12).cos(),
            _ => EVERY_LIGHT,
        });
        let mut answer = cx.lights(&category, 1, Cone::Rows(&cone));
        answer.counts = std::array::from_fn(|l| if cx.mask[l] { answer.counts[l] } else { 0 });
        let order: [Vec<usize>; 4] = std::array::from_fn(|l| {
            cx.lane_lights(&answer, l).enumerate().filter(|(_, x)| x.ambient == 0).map(|(i, _)| i).collect()
        });
        let count = order.iter().map(Vec::len).max().unwrap_or(0);
        let flat: Vec<HostLight> = (0..4).flat_map(|l| {
            let mut v: Vec<HostLight> = cx.lane_lights(&answer, l).collect();
            v.resize(MAX_LIGHTS, HostLight::default());
            v
        }).collect();
        cx.ctx.use_spare_buffers();
        let nesting = cx.input[36].max(0.0) as usize;
        let set = nesting.min(cx.ctx.light_sets.len());
        cx.ctx.light_sets.truncate(set);
        cx.ctx.light_sets.push(LightSet { lights: flat, order });
        for l in 0..4 {
            cx.set(0, l, set as f32);
            cx.set(1, l, count as f32);
        }
    }
    // [set, k, axis, angle, cone] -> [mask bits, L, Cl, Ol]: each lane's k-th non-ambient light
    h_light "rtsl_h_light" 7 => 10 |cx| {
        for l in 0..4 {
            cx.set(0, l, f32::from_bits(0));
        }
        let set = cx.f(0, 0) as usize;
        let k = cx.f(1, 0) as usize;
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let Some(s) = cx.ctx.light_sets.get(set) else { continue };
            let Some(i) = s.order[l].get(k) else { continue };
            let light = s.lights[l * MAX_LIGHTS + i];
            if cx.f(6, l) != 0.0 && angle_between(light.l, cx.v3(2, l)) > cx.f(5, l) {
                continue;
            }
            cx.set(0, l, f32::from_bits(u32::MAX));
            cx.set3(1, l, light.l);
            cx.set3(4, l, light.cl);
            cx.set3(7, l, light.ol);
        }
    }
    // [P] -> the ambient lights' sum
    h_ambient "rtsl_h_ambient" 3 => 3 |cx| {
        let answer = cx.lights("", 0, Cone::Nothing);
        let sum = light_sums::ambient(cx.light_rows(&answer), answer.counts, cx.mask);
        cx.set3_lanes(0, &sum);
    }
    // [P, N] -> diffuse
    h_diffuse "rtsl_h_diffuse" 6 => 3 |cx| {
        let answer = cx.lights("", 0, Cone::Hemisphere(3));
        let n = Lanes3::of_rows(cx.input, 3).normalized();
        let sum = light_sums::diffuse(cx.light_rows(&answer), answer.counts, cx.mask, &n);
        cx.set3_lanes(0, &sum);
    }
    // [P, N, V, roughness] -> specular
    h_specular "rtsl_h_specular" 10 => 3 |cx| {
        let answer = cx.lights("", 0, Cone::Hemisphere(3));
        let n = Lanes3::of_rows(cx.input, 3).normalized();
        let view = Lanes3::of_rows(cx.input, 6).normalized();
        let roughness = glam::Vec4::from_array(std::array::from_fn(|l| cx.f(9, l)));
        let sum = light_sums::specular(cx.light_rows(&answer), answer.counts, cx.mask, &n, &view, roughness);
        cx.set3_lanes(0, &sum);
    }
    // [P, N, V, size] -> phong
    h_phong "rtsl_h_phong" 10 => 3 |cx| {
        let answer = cx.lights("", 0, Cone::Hemisphere(3));
        let n = Lanes3::of_rows(cx.input, 3).normalized();
        let view = Lanes3::of_rows(cx.input, 6).normalized();
        let size = glam::Vec4::from_array(std::array::from_fn(|l| cx.f(9, l)));
        let sum = light_sums::phong(cx.light_rows(&answer), answer.counts, cx.mask, &n, &view, size);
        cx.set3_lanes(0, &sum);
    }
    // [name, s, t, first channel, fill, channels, dsdx, dtdx, dsdy, dtdy, sblur, tblur] -> 3
    h_texture "rtsl_h_texture" 12 => 3 |cx| {
        let n = (cx.f(5, 0) as u32).min(MAX_TEXTURE_CHANNELS);
        let (vals, ok) = texture_call(cx, 0, n);
        for l in cx.active() {
            let fill = cx.f(4, l);
            for j in 0..n as usize {
                cx.set(j, l, if ok[l] != 0 { vals[4 * j + l] } else { fill });
            }
        }
    }
    // [name, dir, ddx, ddy, sblur, tblur, swidth, twidth, fill, first channel, channels] -> 3
    h_environment "rtsl_h_environment" 17 => 3 |cx| {
        let n = (cx.f(16, 0) as u32).clamp(1, 3);
        let (vals, ok) = texture_call(cx, 1, n);
        for l in cx.active() {
            let fill = cx.f(14, l);
            for j in 0..n as usize {
                cx.set(j, l, if ok[l] != 0 { vals[4 * j + l] } else { fill });
            }
        }
    }
    // [name, p, fill] -> 3: texture3d's grid lookup, one value splatted
    // [name, s, t, N, dPds, dPdt] -> the bumped normal
    h_bump "rtsl_h_bump" 12 => 3 |cx| {
        let mut heights = [[0.0f32; 4]; 3];
        for (k, (ds, dt)) in [(0.0, 0.0), (geom::BUMP_STEP, 0.0), (0.0, geom::BUMP_STEP)].into_iter().enumerate() {
            let s: [f32; 4] = std::array::from_fn(|l| cx.f(1, l) + ds);
            let t: [f32; 4] = std::array::from_fn(|l| cx.f(2, l) + dt);
            heights[k] = point_heights(cx, s, t);
        }
        for l in cx.active() {
            let n = geom::bump(cx.v3(3, l), cx.v3(6, l), cx.v3(9, l), heights[0][l], heights[1][l], heights[2][l]);
            cx.set3(0, l, n);
        }
    }
    h_texture3d "rtsl_h_texture3d" 5 => 3 |cx| {
        let (vals, ok) = texture_call(cx, 3, 1);
        for l in cx.active() {
            let x = if ok[l] != 0 { vals[l] } else { cx.f(4, l) };
            for j in 0..3 {
                cx.set(j, l, x);
            }
        }
    }
    // [name, p, 4 corners, samples, sblur, tblur, swidth, twidth, bias] -> 1 (0 without a renderer)
    h_shadow "rtsl_h_shadow" 22 => 1 |cx| {
        let (vals, ok) = texture_call(cx, 2, 1);
        for l in cx.active() {
            cx.set(0, l, if ok[l] != 0 { vals[l] } else { 0.0 });
        }
    }
    // [name, p, n, estimator] -> 3 (black without the map)
    h_photonmap "rtsl_h_photonmap" 8 => 3 |cx| {
        let (vals, ok) = texture_call(cx, 5, 3);
        for l in cx.active() {
            for j in 0..3 {
                cx.set(j, l, if ok[l] != 0 { vals[4 * j + l] } else { 0.0 });
            }
        }
    }
    // [channel, x, y] -> 3 (0 without an image)
    h_pixelvalue "rtsl_h_pixelvalue" 3 => 3 |cx| {
        let (vals, ok) = texture_call(cx, 4, 3);
        for l in cx.active() {
            for j in 0..3 {
                cx.set(j, l, if ok[l] != 0 { vals[4 * j + l] } else { 0.0 });
            }
        }
    }
    // [from, dir] -> [colour, distance]
    h_trace "rtsl_h_trace" 6 => 4 |cx| { rays_call(cx, 0, 4) }
    h_transmission "rtsl_h_transmission" 6 => 3 |cx| { rays_call(cx, 1, 3) }
    // [p, n, samples] -> 1 / 3
    h_occlusion "rtsl_h_occlusion" 7 => 1 |cx| { rays_call(cx, 2, 1) }
    h_indirect "rtsl_h_indirectdiffuse" 7 => 3 |cx| { rays_call(cx, 3, 3) }
    // [category, P, axis, angle, k, n, maxdist, bias, distribution] -> a gather::Record
    h_gather "rtsl_h_gather" 13 => 20 |cx| { gather_call(cx) }
    h_depth "rtsl_h_depth" 3 => 1 |cx| {
        let mut out = [0.0f32; 4];
        let mask: [i32; 4] = cx.mask.map(|m| if m { -1 } else { 0 });
        if let Some(t) = cx.table {
            // SAFETY: the table's documented sizes.
            unsafe { (t.depth)(t.ctx, mask.as_ptr(), cx.input.as_ptr(), out.as_mut_ptr()) };
        }
        for l in cx.active() {
            cx.set(0, l, out[l]);
        }
    }
    h_raydepth "rtsl_h_raydepth" 0 => 1 |cx| {
        // SAFETY: the runtime's table.
        let d = cx.table.map(|t| unsafe { (t.ray_depth)(t.ctx) }).unwrap_or(0.0);
        for l in 0..4 {
            cx.set(0, l, d);
        }
    }
    // [which, name, class, len] -> [found, value...]: message passing into a destination of that shape
    h_message "rtsl_h_message" 4 => 65 |cx| {
        let which = cx.f(0, 0) as u32;
        let name = cx.s(1);
        let (class, len) = (cx.f(2, 0) as u32, cx.f(3, 0) as u32);
        let textureinfo = Builtin::ALL.get(which as usize) == Some(&Builtin::Textureinfo);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let mut out = MessageOut { kind: 0, len: 0, floats: [0.0; MESSAGE_FLOATS], string: StrRef::new("") };
            let found = match cx.table {
                // SAFETY: the runtime's table.
                Some(t) => unsafe { (t.message)(t.ctx, which, cx.chunk, l as u32, StrRef::new(&name), &mut out) },
                None => 0,
            };
            put_message(cx, l, found, &out, class, len, textureinfo);
        }
    }
    // [set, k, name, class, len] -> [found, value...]: `lightsource()` of each lane's k-th light
    // of the enclosing illuminance loop's set
    h_light_message "rtsl_h_light_message" 5 => 65 |cx| {
        let (set, k) = (cx.f(0, 0) as usize, cx.f(1, 0) as usize);
        let name = cx.s(2);
        let (class, len) = (cx.f(3, 0) as u32, cx.f(4, 0) as u32);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let light = cx.ctx.light_sets.get(set).and_then(|s| Some(s.lights[l * MAX_LIGHTS + *s.order[l].get(k)?]));
            let mut out = MessageOut { kind: 0, len: 0, floats: [0.0; MESSAGE_FLOATS], string: StrRef::new("") };
            let found = match (cx.table, light) {
                // SAFETY: the runtime's table.
                (Some(t), Some(light)) => unsafe { (t.light_message)(t.ctx, light.id, StrRef::new(&name), &mut out) },
                _ => 0,
            };
            put_message(cx, l, found, &out, class, len, false);
        }
    }
    // [which, name, class, len, I, Ng] -> [found, value...]: `incident()`/`opposite()` of the
    // volume on the side of each lane's surface its ray comes from or goes to
    h_volume_message "rtsl_h_volume_message" 10 => 65 |cx| {
        let opposite = Builtin::ALL.get(cx.f(0, 0) as usize) == Some(&Builtin::Opposite);
        let name = cx.s(1);
        let (class, len) = (cx.f(2, 0) as u32, cx.f(3, 0) as u32);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let interior = geom::asks_interior(cx.v3(4, l), cx.v3(7, l), opposite);
            let mut out = MessageOut { kind: 0, len: 0, floats: [0.0; MESSAGE_FLOATS], string: StrRef::new("") };
            let found = match cx.table {
                // SAFETY: the runtime's table.
                Some(t) => unsafe { (t.volume_message)(t.ctx, u32::from(interior), StrRef::new(&name), &mut out) },
                None => 0,
            };
            put_message(cx, l, found, &out, class, len, false);
        }
    }
    // [kind, has kind] -> handle
    h_shadername "rtsl_h_shadername" 2 => 1 |cx| {
        let (kind, has) = (cx.s(0), cx.f(1, 0) != 0.0);
        let name = match cx.table {
            // SAFETY: the runtime's table; the string is copied before the next call.
            Some(t) => unsafe { (t.shader_name)(t.ctx, u32::from(has), StrRef::new(&kind)).as_str() }.to_string(),
            None => String::new(),
        };
        let h = cx.strings.intern(&name);
        for l in 0..4 {
            cx.set(0, l, f32::from_bits(h));
        }
    }
    // [basis, x, knots] -> [first knot of the segment, four weights]: `spline`'s segment and weights
    h_spline "rtsl_h_spline" 3 => 5 |cx| {
        let basis = spline::Basis::parse(cx.str(0));
        let n = cx.f(2, 0) as usize;
        let x = std::array::from_fn(|l| cx.f(1, l));
        let (first, w) = basis.weights4(x, n).unwrap_or(([0; 4], [[1.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]]));
        for l in cx.active() {
            cx.set(0, l, first[l] as f32);
            for (k, row) in w.iter().enumerate() {
                cx.set(1 + k, l, row[l]);
            }
        }
    }
    // [site, inputs, strings...] -> handle of the strings one after the other
    h_concat "rtsl_h_concat" VARIADIC => 1 |cx| {
        let (site, n) = (cx.f(0, 0) as u32, cx.input.len() / 4);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let (text, cut) = format::concat((2..n).map(|k| cx.str_lane(k, l)));
            let h = cx.made_string(&text, cut, site);
            cx.set(0, l, f32::from_bits(h));
        }
    }
    // [pattern, subject] -> 1 or 0
    h_match "rtsl_h_match" 2 => 1 |cx| {
        for l in cx.active() {
            let m = format::regex_match(cx.str_lane(0, l), cx.str_lane(1, l));
            cx.set(0, l, if m { 1.0 } else { 0.0 });
        }
    }
    // [fmt, inputs, n, kinds; n, values...] -> each running lane's handle
    h_format "rtsl_h_format" VARIADIC => 1 |cx| {
        let site = format_site(cx);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let (text, cut) = format_lane(cx, l);
            let h = cx.made_string(&text, cut, site);
            cx.set(0, l, f32::from_bits(h));
        }
    }
    // As `format`; prints each active lane's text, in lane order.
    // [kind, site] -> nothing: a runtime check failed (recorded once per site, see `RuntimeErrors`)
    h_runtime_error "rtsl_h_runtime_error" 2 => 1 |cx| {
        cx.report(cx.f(0, 0) as u32, cx.f(1, 0) as u32);
    }
    h_printf "rtsl_h_printf" VARIADIC => 1 |cx| {
        let site = format_site(cx);
        let active: Vec<usize> = cx.active().collect();
        for l in active {
            let (text, cut) = format_lane(cx, l);
            if cut {
                cx.report(super::lower::RUNTIME_STRING_CUT, site);
            }
            if let Some(t) = cx.table {
                // SAFETY: the runtime's table; the text outlives the call.
                unsafe { (t.print)(t.ctx, StrRef::new(&text)) };
            }
        }
    }
}

/// Kinds of `format`/`printf` arguments in the helpers' input header.
pub(super) const FMT_FLOAT: u32 = 1;
pub(super) const FMT_TRIPLE: u32 = 2;
pub(super) const FMT_MATRIX: u32 = 3;
pub(super) const FMT_STRING: u32 = 4;
pub(super) const FMT_BOOL: u32 = 5;

/// The site of a `format` or `printf` call: its last input.
fn format_site(cx: &Cx<'_>) -> u32 {
    (cx.input.len() / 4).checked_sub(1).map_or(0, |k| cx.f(k, 0) as u32)
}

/// The text of `format(fmt, args...)` in lane `l`, and whether it was cut to `MAX_STRING_LEN`:
/// input 0 the format, 2 the argument count `n`, `3..3+n` their kinds (`FMT_*`), then their values
/// (a bool as a lane mask, a string a handle), as the interpreter passes them to `shadeops::format`
/// (a bool is the float 0 or 1), then the call's site.
fn format_lane(cx: &Cx<'_>, l: usize) -> (String, bool) {
    enum A {
        F(f32),
        T(V3),
        M(M4),
        S(String),
    }
    let n = cx.f(2, 0) as usize;
    let mut at = 3 + n;
    let mut parts = Vec::with_capacity(n);
    for i in 0..n {
        let (part, size) = match cx.f(3 + i, 0) as u32 {
            FMT_FLOAT => (A::F(cx.f(at, l)), 1),
            FMT_TRIPLE => (A::T(cx.v3(at, l)), 3),
            FMT_MATRIX => (A::M(std::array::from_fn(|k| cx.f(at + k, l))), 16),
            FMT_STRING => (A::S(cx.str_lane(at, l).to_string()), 1),
            _ => (A::F(if cx.f(at, l).to_bits() != 0 { 1.0 } else { 0.0 }), 1),
        };
        parts.push(part);
        at += size;
    }
    let args: Vec<FormatArg<'_>> = parts
        .iter()
        .map(|p| match p {
            A::F(x) => FormatArg::Float(*x),
            A::T(t) => FormatArg::Triple(*t),
            A::M(m) => FormatArg::Matrix(m),
            A::S(s) => FormatArg::Str(s),
        })
        .collect();
    format::format_cut(cx.str_lane(0, l), &args)
}

/// The most channels one texture lookup returns (a colour and its alpha).
const MAX_TEXTURE_CHANNELS: u32 = 4;

/// The rows of a shadow lookup's coordinates in the table's `texture` call: the point (3), the
/// region's four corners (12) and six options.
pub const SHADOW_ROWS: usize = 21;

/// Rows of four lanes a `texture` lookup passes the table's texture entry (kind 0): s, t, the four
/// footprint derivatives, sblur, tblur and fill (the value of channels the texture lacks).
pub const TEXTURE_ROWS: usize = 9;

/// Rows of four lanes an `environment` lookup passes the table's texture entry (kind 1): the
/// direction (3), its changes over a pixel step in x (3) and y (3), sblur, tblur, swidth, twidth
/// and fill.
pub const ENVIRONMENT_ROWS: usize = 14;
// `texture_call` gathers any kind's rows into a buffer of the shadow's size.
const _: () = assert!(ENVIRONMENT_ROWS <= SHADOW_ROWS);

/// A texture query of one chunk through the renderer's table, the name at argument 0: the values
/// (`vals[4 * channel + lane]`, at most [`MAX_TEXTURE_CHANNELS`]) and which lanes found them.
/// Allocates nothing: volume shaders call it at every step of their march.
fn texture_call(cx: &Cx<'_>, kind: u32, channels: u32) -> ([f32; 4 * MAX_TEXTURE_CHANNELS as usize], [u32; 4]) {
    let name = cx.strings.get(cx.input[0].to_bits());
    let channels = channels.clamp(1, MAX_TEXTURE_CHANNELS);
    let mut vals = [0.0f32; 4 * MAX_TEXTURE_CHANNELS as usize];
    let mut ok = [0u32; 4];
    let Some(t) = cx.table else { return (vals, ok) };
    let mask: [i32; 4] = cx.mask.map(|m| if m { -1 } else { 0 });
    // Texture: coords s, t (args 1, 2), then the footprint dsdx, dtdx, dsdy, dtdy, sblur, tblur
    // (args 6..12) and the fill (arg 4), and the first channel (arg 3); environment: the query's rows (args 1..15) and
    // the first channel (arg 15); shadows: every argument after the name; otherwise a triple at
    // arg 1.
    let mut coords = [0.0f32; 4 * SHADOW_ROWS];
    let mut first = [0.0f32; 4];
    // Arguments `k..k + n` (rows of four lanes) into `to`.
    let rows = |to: &mut [f32], k: usize, n: usize| {
        if let (Some(to), Some(from)) = (to.get_mut(..4 * n), cx.input.get(4 * k..4 * (k + n))) {
            to.copy_from_slice(from);
        }
    };
    match kind {
        0 => {
            rows(&mut coords[..8], 1, 2);
            rows(&mut coords[8..32], 6, 6);
            rows(&mut coords[32..36], 4, 1);
            rows(&mut first, 3, 1);
        }
        1 => {
            rows(&mut coords[..4 * ENVIRONMENT_ROWS], 1, ENVIRONMENT_ROWS);
            rows(&mut first, 1 + ENVIRONMENT_ROWS, 1);
        }
        2 => rows(&mut coords, 1, SHADOW_ROWS),
        4 => rows(&mut coords[..8], 1, 2),
        5 => rows(&mut coords[..28], 1, 7),
        _ => rows(&mut coords, 1, 3),
    }
    // SAFETY: the table's documented sizes.
    unsafe {
        (t.texture)(
            t.ctx,
            kind,
            StrRef::new(name),
            mask.as_ptr(),
            coords.as_ptr(),
            first.as_ptr(),
            channels,
            vals.as_mut_ptr(),
            ok.as_mut_ptr(),
        )
    };
    (vals, ok)
}

/// Channel 0 of the texture named by argument 0, point-sampled at each running lane's (s, t); 0
/// where it cannot be read.
fn point_heights(cx: &Cx<'_>, s: [f32; 4], t: [f32; 4]) -> [f32; 4] {
    let mut out = [0.0f32; 4];
    let Some(table) = cx.table else { return out };
    let mask: [i32; 4] = cx.mask.map(|m| if m { -1 } else { 0 });
    // A point sample: the footprint and blur rows stay zero.
    let mut coords = [0.0f32; 4 * TEXTURE_ROWS];
    coords[..4].copy_from_slice(&s);
    coords[4..8].copy_from_slice(&t);
    let (first, mut vals, mut ok) = ([0.0f32; 4], [0.0f32; 4 * MAX_TEXTURE_CHANNELS as usize], [0u32; 4]);
    let name = cx.strings.get(cx.input[0].to_bits());
    // SAFETY: the table's documented sizes (`TEXTURE_ROWS` rows of coordinates, one channel).
    unsafe {
        (table.texture)(
            table.ctx,
            0,
            StrRef::new(name),
            mask.as_ptr(),
            coords.as_ptr(),
            first.as_ptr(),
            1,
            vals.as_mut_ptr(),
            ok.as_mut_ptr(),
        )
    };
    for l in 0..4 {
        if ok[l] != 0 {
            out[l] = vals[l];
        }
    }
    out
}

/// One sample of a `gather` for the chunk: the rays from `shadeops::gather` (as the interpreter
/// makes them), traced together through the table.
fn gather_call(cx: &mut Cx<'_>) {
    let traced = gather::traces(cx.str(0));
    let cosine = gather::Options::is_cosine(cx.str(12));
    let mut rays = [([0.0f32; 3], [0.0f32; 3], 0.0f32); 4];
    let mut trace_mask = [0i32; 4];
    for l in cx.active() {
        let mut options = gather::Options { cosine, ..gather::Options::default() };
        options.set_float(0, cx.f(10, l));
        options.set_float(1, cx.f(11, l));
        let (k, n) = (cx.f(8, l) as u32, cx.f(9, l) as u32);
        let (origin, dir) = gather::sample_ray(cx.v3(1, l), cx.v3(4, l), cx.f(7, l), k, n, &options);
        rays[l] = (origin, dir, options.maxdist);
        if traced && dir != [0.0; 3] {
            trace_mask[l] = -1;
        }
    }
    let mut answer = [0.0f32; 4 * (1 + GatherHit::ROWS)];
    if let (Some(t), true) = (cx.table, trace_mask.iter().any(|m| *m != 0)) {
        let rows = |f: fn(&(V3, V3, f32)) -> V3| -> [f32; 12] { std::array::from_fn(|i| f(&rays[i % 4])[i / 4]) };
        let (from, dir) = (rows(|r| r.0), rows(|r| r.1));
        let maxdist: [f32; 4] = std::array::from_fn(|l| rays[l].2);
        let category = StrRef::new(cx.str(0));
        // SAFETY: the table's documented sizes; `category` borrows the batch's string table,
        // which the call does not touch.
        unsafe {
            (t.gather)(
                t.ctx,
                category,
                cx.chunk,
                trace_mask.as_ptr(),
                from.as_ptr(),
                dir.as_ptr(),
                maxdist.as_ptr(),
                answer.as_mut_ptr(),
            )
        };
    }
    for l in cx.active() {
        let hit = (trace_mask[l] != 0 && answer[l] != 0.0)
            .then(|| GatherHit::from_rows(&std::array::from_fn(|j| answer[4 * (j + 1) + l])));
        let rec = gather::record(rays[l].0, rays[l].1, hit.as_ref(), traced);
        for (j, x) in rec.iter().enumerate() {
            cx.set(j, l, *x);
        }
    }
}

/// Rays: arguments `a` (0..3), `b` (3..6), samples (6) when the helper has them.
fn rays_call(cx: &mut Cx<'_>, kind: u32, outs: usize) {
    let mut out = [0.0f32; 16];
    if kind == 0 || kind == 1 {
        // Without a renderer: black, at infinity (trace); nothing blocks (transmission).
        for l in 0..4 {
            out[12 + l] = f32::INFINITY;
            if kind == 1 {
                out[l] = 1.0;
                out[4 + l] = 1.0;
                out[8 + l] = 1.0;
            }
        }
    }
    if let Some(t) = cx.table {
        let mask: [i32; 4] = cx.mask.map(|m| if m { -1 } else { 0 });
        // On the stack: a `Vec` here was an allocation per chunk of every `trace` call.
        let samples: [f32; 4] = match cx.input.get(24..28) {
            Some(s) if kind >= 2 => [s[0], s[1], s[2], s[3]],
            _ => [0.0; 4],
        };
        // SAFETY: the table's documented sizes.
        unsafe {
            (t.rays)(
                t.ctx,
                kind,
                cx.chunk,
                mask.as_ptr(),
                cx.input.as_ptr(),
                cx.input[12..].as_ptr(),
                samples.as_ptr(),
                out.as_mut_ptr(),
            )
        };
    }
    for l in cx.active() {
        for j in 0..outs {
            cx.set(j, l, out[4 * j + l]);
        }
    }
}

pub(super) fn host_helper(name: &str) -> Option<&'static HostHelper> {
    HOST_HELPERS.iter().find(|h| h.name == name)
}

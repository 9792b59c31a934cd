//! Shading a grid of points without a scene, like OSL's `testshade`: the engine of `rtsl shade`.
//!
//! Every shader type runs over a `W x H` grid; point `(x, y)` (row `y` from the top) has
//! `s = u = (x + 0.5) / W` and `t = v = (y + 0.5) / H` in what follows. The grid is the unit square
//! in the z = 0 plane, seen by an eye at `E = (0.5, 0.5, 1)` looking down -z. What each type is
//! given on entry:
//!
//! - **surface**, **lightfield** and **displacement**: `P = (s, t, 0)`, `N = Ng = (0, 0, 1)`,
//!   `I = P - E`, `E`, `s`, `t`, `u`, `v`, `du = 1 / W`, `dv = 1 / H`, `dPdu = (1, 0, 0)`,
//!   `dPdv = (0, 1, 0)`, `Cs = Os = Oi = 1`, `Ci = 0`, and the screen-space derivatives of one grid
//!   step (`P`, `I`, `s`, `u` change by `1 / W` along x; `P`, `I`, `t`, `v` by `1 / H` along y).
//! - **light**: the grid point is the point being lit, `Ps = (s, t, 0)` (derivatives one grid
//!   step); `P` is the light's own position, the origin of "shader" space as the host places it,
//!   `N = 0` and `E` the eye, as the renderer runs a light that is not an area light; `L`, `Cl` and
//!   `Ol` start at 0 (`illuminate` sets `L = Ps - from`).
//! - **volume** (an atmosphere along the eye ray to the grid point): `P = (s, t, 0)`, `E`,
//!   `I = P - E`, and the colour arriving from the surface `Ci = (s, t, 0)`, `Oi = 1`.
//! - **imager** (`pixel`): the grid is an image of `W x H` pixels with `Ci = (s, t, 0)`,
//!   `Oi = alpha = 1`, `P = (x + 0.5, y + 0.5, 0)` the pixel's centre, `zdepth = 1` (the grid's
//!   distance from the eye), `objectid = shaderid = 0`.
//! - **camera**: the grid is the image: `P = (x + 0.5, y + 0.5, 0)` the raster position, `s`, `t`
//!   the screen-window position (the shorter side spans [-1, 1], `t` up), the lens sample
//!   `u = v = 0.5`; on entry `E` is the origin of "camera" space, `I` the 90-degree pinhole ray
//!   `(s, t, 1)` of camera space, and `Ci = 1` (`docs/cameras.md`).
//!
//! Every type has `ncomps = 3`, `time = dtime = 0`, and every other global starts at 0. The
//! renderer's side is whatever `Services` the caller passes; `rtsl shade` uses `interp::TestHost`
//! (an ambient light and a distant light from +z; "shader" space at (1, 2, 3), "camera" space at
//! (0, 0, 5)).
//!
//! After shading, [`Grid::image_of`] reads any global the shader type can see or any output
//! parameter at every point as an image: a float as grey, a triple as RGB.

use crate::back::jit::{self, BatchData, CompiledShader, JitError, SavedValues};
use crate::globals::{Access, GLOBALS};
use crate::interp::Services;
use crate::ir::Module;
use crate::ir::ShaderKind;
use crate::shadeops::{matrix, M4, V3};

/// A value given on the command line for a parameter: `0.5`, `1,0,0` or text.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamArg {
    Floats(Vec<f32>),
    String(String),
}

/// Parses `NAME=VALUE`: numbers separated by commas are floats, anything else a string.
pub fn parse_param(arg: &str) -> Result<(String, ParamArg), String> {
    let (name, value) = arg.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{arg}`"))?;
    if name.is_empty() {
        return Err(format!("no parameter name in `{arg}`"));
    }
    let numbers: Result<Vec<f32>, _> = value.split(',').map(|v| v.trim().parse::<f32>()).collect();
    Ok(match numbers {
        Ok(v) if !value.is_empty() => (name.to_string(), ParamArg::Floats(v)),
        _ => (name.to_string(), ParamArg::String(value.trim_matches('"').to_string())),
    })
}

/// Why a grid cannot be shaded, or a variable not written as an image.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    #[error(transparent)]
    Jit(#[from] JitError),
    #[error("the shader has no parameter `{0}`")]
    NoParameter(String),
    #[error("parameter `{name}` takes {expected} number(s), {given} given")]
    WrongCount { name: String, expected: usize, given: usize },
    #[error("a grid of {width}x{height} points is too large: at most {MAX_GRID_POINTS}")]
    TooLarge { width: usize, height: usize },
    #[error("{kind} shader has no global or output parameter `{name}`: it can write {writable}")]
    NoVariable { name: String, kind: String, writable: String },
    #[error("`{0}` is not a float or a triple (a colour, point, vector or normal), so it cannot be an image")]
    NotAnImage(String),
    #[error("{kind} shader reads no float or triple global `{name}` on entry")]
    NoEntryGlobal { name: String, kind: String },
    #[error("global `{name}` takes {expected} numbers, {given} given")]
    WrongEntryCount { name: String, expected: usize, given: usize },
}

/// A global's value on entry that replaces the type's own (`rtsl shade --global`, `--input`).
#[derive(Clone, Debug, PartialEq)]
pub enum EntryValue {
    /// The same value at every point (1 float, or 3 for a triple).
    Constant(Vec<f32>),
    /// One value a point, in grid order (row by row from the top), each of the global's floats.
    PerPoint(Vec<f32>),
}

/// The most points a grid may have: the renderer's image pixel cap
/// (`rtsl_runtime::render::world::MAX_IMAGE_PIXELS`), as the grid is written as an image and
/// holds some 200 bytes a point.
pub const MAX_GRID_POINTS: usize = 1 << 25;

/// The most lanes per batch.
pub const BATCH: usize = 64;

/// Where the host puts the spaces the entry values of lights and cameras depend on.
#[derive(Clone, Copy, Debug)]
struct Placement {
    /// The origin of "shader" space (a light's position).
    shader_origin: V3,
    /// "camera" space to "current".
    camera: M4,
}

impl Placement {
    fn of(host: &mut dyn Services) -> Placement {
        let shader = host.matrix("shader", "current").unwrap_or_else(matrix::identity);
        let camera = host.matrix("camera", "current").unwrap_or_else(matrix::identity);
        Placement { shader_origin: matrix::transform_point(&shader, [0.0; 3]), camera }
    }
}

/// The eye of the grid.
const EYE: V3 = [0.5, 0.5, 1.0];

/// A compiled shader and the batches covering a grid, ready to shade again and again.
pub struct Grid {
    kind: ShaderKind,
    shader: CompiledShader,
    batches: Vec<BatchData>,
    /// Each batch as it was before its first shading (globals, parameters), once the host placed it.
    initial: Vec<SavedValues>,
    placement: Option<Placement>,
    /// Entry values given in place of the type's own, in the order given.
    entries: Vec<(&'static str, EntryValue)>,
    width: usize,
    height: usize,
}

impl Grid {
    pub fn new(module: &Module, width: usize, height: usize, params: &[(String, ParamArg)]) -> Result<Grid, GridError> {
        Self::with_sources(module, None, width, height, params)
    }

    /// As [`Grid::new`], with the compilation's sources so runtime checks name file and line.
    pub fn with_sources(
        module: &Module,
        sources: Option<&crate::source::SourceMap>,
        width: usize,
        height: usize,
        params: &[(String, ParamArg)],
    ) -> Result<Grid, GridError> {
        let (w, h) = (width.max(1), height.max(1));
        let total = w.checked_mul(h).filter(|&n| n <= MAX_GRID_POINTS).ok_or(GridError::TooLarge { width, height })?;
        let kind = module.shader.as_ref().map(|s| s.kind).ok_or(JitError::NoShader)?;
        let shader = jit::compile_with(module, sources, &jit::JitOptions::default())?;
        let mut batches = Vec::new();
        for start in (0..total).step_by(BATCH) {
            let lanes = BATCH.min(total - start);
            let mut b = shader.batch(lanes);
            for lane in 0..lanes {
                b.set_seed(lane, (start + lane) as u64);
                for (name, value) in params {
                    bind(&mut b, lane, name, value)?;
                }
            }
            batches.push(b);
        }
        Ok(Grid {
            kind,
            shader,
            batches,
            initial: Vec::new(),
            placement: None,
            entries: Vec::new(),
            width: w,
            height: h,
        })
    }

    /// Gives global `name` this value on entry at every later [`Grid::shade`], in place of the
    /// type's own (a volume's or imager's incoming image, a surface's `Cs` from a texture, a
    /// normal): any float or triple global the shader type reads.
    pub fn set_entry(&mut self, name: &str, value: EntryValue) -> Result<(), GridError> {
        let g = GLOBALS
            .iter()
            .find(|g| {
                g.name == name
                    && g.access(self.kind) != Access::None
                    && (g.ty.is_triple() || g.ty == crate::ir::BaseType::Float)
            })
            .ok_or_else(|| GridError::NoEntryGlobal { name: name.to_string(), kind: self.kind.with_article() })?;
        let comps = if g.ty.is_triple() { 3 } else { 1 };
        let (given, expected) = match &value {
            EntryValue::Constant(v) => (v.len(), comps),
            EntryValue::PerPoint(v) => (v.len(), comps * self.points()),
        };
        if given != expected {
            return Err(GridError::WrongEntryCount { name: name.to_string(), expected, given });
        }
        self.entries.retain(|(n, _)| *n != g.name);
        self.entries.push((g.name, value));
        // The batches are set up again from the new entry values at the next shading.
        self.placement = None;
        self.initial.clear();
        Ok(())
    }

    /// The globals of point `k` on entry: the type's own, then those given by `set_entry`.
    fn entry_of(&self, placement: &Placement, k: usize) -> Vec<(&'static str, Vec<f32>)> {
        let mut v = entry_values(self.kind, placement, self.width, self.height, k);
        for (name, value) in &self.entries {
            let x = match value {
                EntryValue::Constant(c) => c.clone(),
                EntryValue::PerPoint(all) => {
                    let n = all.len() / self.points().max(1);
                    all[k * n..(k + 1) * n].to_vec()
                }
            };
            match v.iter_mut().find(|(g, _)| g == name) {
                Some(slot) => slot.1 = x,
                None => v.push((name, x)),
            }
        }
        v
    }

    /// The type of the shader.
    pub fn kind(&self) -> ShaderKind {
        self.kind
    }

    /// Shades every point of the grid once; every run starts from the same entry values.
    pub fn shade(&mut self, host: &mut dyn Services) {
        if self.placement.is_none() {
            let placement = Placement::of(host);
            self.placement = Some(placement);
            let mut batches = std::mem::take(&mut self.batches);
            for (i, b) in batches.iter_mut().enumerate() {
                for lane in 0..b.lanes() {
                    let k = i * BATCH + lane;
                    for (name, value) in self.entry_of(&placement, k) {
                        b.set_global(name, lane, &value);
                    }
                    for (name, dx, dy) in entry_derivatives(self.kind, self.width, self.height) {
                        b.set_global_derivs(name, lane, &dx, &dy);
                    }
                }
                let mut saved = SavedValues::default();
                b.save_values(&mut saved);
                self.initial.push(saved);
            }
            self.batches = batches;
        } else {
            for (b, saved) in self.batches.iter_mut().zip(&self.initial) {
                b.restore_values(saved);
            }
        }
        for b in &mut self.batches {
            self.shader.shade_with(b, host);
        }
    }

    /// What the shader's runtime checks found (see `CompiledShader::runtime_errors`).
    pub fn runtime_errors(&self) -> Vec<String> {
        self.shader.runtime_errors()
    }

    pub fn points(&self) -> usize {
        self.width * self.height
    }

    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// What `rtsl shade -o FILE` writes for this type of shader: `Ci` for surfaces, lightfields,
    /// volumes and imagers, `P` for displacements, `Cl` for lights, `I` (the ray direction) for
    /// cameras.
    pub fn default_output(&self) -> &'static str {
        match self.kind {
            ShaderKind::Surface | ShaderKind::Lightfield | ShaderKind::Volume | ShaderKind::Imager => "Ci",
            ShaderKind::Displacement => "P",
            ShaderKind::Light => "Cl",
            ShaderKind::Camera => "I",
        }
    }

    /// The globals this type of shader writes, then its output parameters: what
    /// [`Grid::image_of`] is mostly asked for (it takes any global the type can read too).
    pub fn writable(&self) -> Vec<String> {
        let globals = GLOBALS.iter().filter(|g| g.access(self.kind) == Access::Write).map(|g| g.name.to_string());
        let params = self.shader.layout().params.iter().filter(|p| p.output).map(|p| p.name.clone());
        globals.chain(params).collect()
    }

    /// Floats per point of `name` (1 or 3), or why it cannot be an image.
    pub fn check_output(&self, name: &str) -> Result<usize, GridError> {
        if let Some(g) = GLOBALS.iter().find(|g| g.name == name && g.access(self.kind) != Access::None) {
            return Ok(if g.ty.is_triple() { 3 } else { 1 });
        }
        match self.shader.layout().param(name) {
            Some((_, p)) if p.output => {
                if p.string || p.len != 1 || !matches!(p.components, 1 | 3) {
                    Err(GridError::NotAnImage(name.to_string()))
                } else {
                    Ok(p.components)
                }
            }
            _ => Err(GridError::NoVariable {
                name: name.to_string(),
                kind: self.kind.with_article(),
                writable: format!(
                    "{} (or read any global of {} shader)",
                    self.writable().join(", "),
                    self.kind.with_article()
                ),
            }),
        }
    }

    /// `name` (a global the shader type can see, or an output parameter) at every point as RGBA,
    /// rows top to bottom: a float as grey, a triple as RGB. The alpha is the mean of `Oi` for
    /// `Ci` of a surface, lightfield or volume, `alpha` for `Ci` of an imager, else 1. A global the
    /// shader never touches reads as its entry value.
    pub fn image_of(&self, name: &str) -> Result<Vec<f32>, GridError> {
        let n = self.check_output(name)?;
        let placement = self.placement.unwrap_or(Placement { shader_origin: [0.0; 3], camera: matrix::identity() });
        let value = |b: &BatchData, name: &str, k: usize, lane: usize| -> Option<Vec<f32>> {
            b.global(name, lane)
                .or_else(|| b.param(name, lane))
                .or_else(|| self.entry_of(&placement, k).into_iter().find(|(g, _)| *g == name).map(|(_, v)| v))
        };
        let alpha_of = |b: &BatchData, k: usize, lane: usize| -> f32 {
            match (name, self.kind) {
                ("Ci", ShaderKind::Imager) => value(b, "alpha", k, lane).map_or(1.0, |a| a[0]),
                ("Ci", ShaderKind::Surface | ShaderKind::Lightfield | ShaderKind::Volume) => {
                    value(b, "Oi", k, lane).map_or(1.0, |o| (o[0] + o[1] + o[2]) / 3.0)
                }
                _ => 1.0,
            }
        };
        let mut out = Vec::with_capacity(4 * self.points());
        for (i, b) in self.batches.iter().enumerate() {
            for lane in 0..b.lanes() {
                let k = i * BATCH + lane;
                let v = value(b, name, k, lane).unwrap_or_else(|| vec![0.0; n]);
                match v.as_slice() {
                    [g] => out.extend_from_slice(&[*g; 3]),
                    [r, g, b, ..] => out.extend_from_slice(&[*r, *g, *b]),
                    _ => out.extend_from_slice(&[0.0; 3]),
                }
                out.push(alpha_of(b, k, lane));
            }
        }
        Ok(out)
    }

    /// [`Grid::image_of`] the type's [`Grid::default_output`] (`Ci` and the mean of `Oi` for a
    /// surface).
    pub fn image(&self) -> Vec<f32> {
        self.image_of(self.default_output()).unwrap_or_default()
    }
}

/// The globals of point `k` of a `w x h` grid on entry to a shader of `kind` (the module comment).
fn entry_values(
    kind: ShaderKind,
    placement: &Placement,
    w: usize,
    h: usize,
    k: usize,
) -> Vec<(&'static str, Vec<f32>)> {
    let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
    let (fw, fh) = (w as f32, h as f32);
    let (s, t) = (x / fw, y / fh);
    let p = vec![s, t, 0.0];
    let i = vec![s - EYE[0], t - EYE[1], -EYE[2]];
    let mut v: Vec<(&'static str, Vec<f32>)> = vec![("ncomps", vec![3.0]), ("time", vec![0.0]), ("dtime", vec![0.0])];
    match kind {
        ShaderKind::Surface | ShaderKind::Lightfield | ShaderKind::Displacement => v.extend([
            ("P", p),
            ("N", vec![0.0, 0.0, 1.0]),
            ("Ng", vec![0.0, 0.0, 1.0]),
            ("I", i),
            ("E", EYE.to_vec()),
            ("s", vec![s]),
            ("t", vec![t]),
            ("u", vec![s]),
            ("v", vec![t]),
            ("du", vec![1.0 / fw]),
            ("dv", vec![1.0 / fh]),
            ("dPdu", vec![1.0, 0.0, 0.0]),
            ("dPdv", vec![0.0, 1.0, 0.0]),
            ("Cs", vec![1.0; 3]),
            ("Os", vec![1.0; 3]),
            ("Oi", vec![1.0; 3]),
            ("Ci", vec![0.0; 3]),
        ]),
        ShaderKind::Light => v.extend([
            ("Ps", p),
            ("P", placement.shader_origin.to_vec()),
            ("N", vec![0.0; 3]),
            ("E", EYE.to_vec()),
            ("L", vec![0.0; 3]),
            ("Cl", vec![0.0; 3]),
            ("Ol", vec![0.0; 3]),
        ]),
        ShaderKind::Volume => {
            v.extend([("P", p), ("E", EYE.to_vec()), ("I", i), ("Ci", vec![s, t, 0.0]), ("Oi", vec![1.0; 3])])
        }
        ShaderKind::Imager => v.extend([
            ("P", vec![x, y, 0.0]),
            ("Ci", vec![s, t, 0.0]),
            ("Oi", vec![1.0; 3]),
            ("alpha", vec![1.0]),
            ("zdepth", vec![1.0]),
            ("objectid", vec![0.0]),
            ("shaderid", vec![0.0]),
        ]),
        ShaderKind::Camera => {
            let side = fw.min(fh);
            let (cs, ct) = ((2.0 * x - fw) / side, (fh - 2.0 * y) / side);
            v.extend([
                ("P", vec![x, y, 0.0]),
                ("s", vec![cs]),
                ("t", vec![ct]),
                ("u", vec![0.5]),
                ("v", vec![0.5]),
                ("E", matrix::transform_point(&placement.camera, [0.0; 3]).to_vec()),
                ("I", matrix::transform_vector(&placement.camera, [cs, ct, 1.0]).to_vec()),
                ("Ci", vec![1.0; 3]),
            ]);
        }
    }
    v
}

/// The screen-space derivatives (d/dx, d/dy) of the globals that change over a `w x h` grid.
fn entry_derivatives(kind: ShaderKind, w: usize, h: usize) -> Vec<(&'static str, Vec<f32>, Vec<f32>)> {
    let (dx, dy) = (1.0 / w as f32, 1.0 / h as f32);
    let step = |name| (name, vec![dx, 0.0, 0.0], vec![0.0, dy, 0.0]);
    match kind {
        ShaderKind::Surface | ShaderKind::Lightfield | ShaderKind::Displacement => vec![
            step("P"),
            step("I"),
            ("s", vec![dx], vec![0.0]),
            ("u", vec![dx], vec![0.0]),
            ("t", vec![0.0], vec![dy]),
            ("v", vec![0.0], vec![dy]),
        ],
        ShaderKind::Light => vec![step("Ps")],
        ShaderKind::Volume => vec![step("P"), step("I")],
        ShaderKind::Imager | ShaderKind::Camera => Vec::new(),
    }
}

fn bind(b: &mut BatchData, lane: usize, name: &str, value: &ParamArg) -> Result<(), GridError> {
    let Some((_, slot)) = b.layout().param(name).map(|(i, p)| (i, p.clone())) else {
        return Err(GridError::NoParameter(name.to_string()));
    };
    match value {
        ParamArg::String(s) => {
            if !b.set_string_param(name, s) {
                return Err(GridError::WrongCount { name: name.to_string(), expected: slot.floats(), given: 0 });
            }
        }
        ParamArg::Floats(v) => {
            // One number for a triple is copied to the three components.
            let v = if v.len() == 1 && slot.components == 3 && slot.len == 1 { vec![v[0]; 3] } else { v.clone() };
            if !b.set_param(name, lane, &v) {
                return Err(GridError::WrongCount { name: name.to_string(), expected: slot.floats(), given: v.len() });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interp::TestHost;

    fn module(src: &str) -> Module {
        let c = crate::compile_source("t.sl", src, &crate::Options::default());
        assert!(c.ok(), "{}", c.render());
        c.module.expect("a module")
    }

    #[test]
    fn parameters_parse() {
        assert_eq!(parse_param("Kd=0.5"), Ok(("Kd".into(), ParamArg::Floats(vec![0.5]))));
        assert_eq!(parse_param("c=1,0, 0"), Ok(("c".into(), ParamArg::Floats(vec![1.0, 0.0, 0.0]))));
        assert_eq!(parse_param("map=\"a.png\""), Ok(("map".into(), ParamArg::String("a.png".into()))));
        assert!(parse_param("nothing").is_err());
        assert!(parse_param("=1").is_err());
    }

    /// A grid past `MAX_GRID_POINTS`, or one whose point count overflows, is refused before
    /// anything is allocated.
    #[test]
    fn grids_past_the_cap_are_refused() {
        let m = module("surface g() { Oi = 1; Ci = color(s, t, 0); }");
        for (w, h) in [(MAX_GRID_POINTS, 2), (usize::MAX, usize::MAX), (1 << 13, 1 << 13)] {
            let e = Grid::new(&m, w, h, &[]).err().expect("refused");
            assert!(matches!(e, GridError::TooLarge { .. }), "{e}");
            assert!(e.to_string().contains(&MAX_GRID_POINTS.to_string()), "{e}");
        }
        assert!(Grid::new(&m, 64, 2, &[]).is_ok_and(|g| g.points() == 128));
    }

    #[test]
    fn the_grid_sees_s_and_t_and_bound_parameters() {
        let m = module("surface g(float k = 1; color c = 0;) { Oi = 1; Ci = color(s, t, 0) * k + c; }");
        let params = [("k".to_string(), ParamArg::Floats(vec![2.0])), ("c".to_string(), ParamArg::Floats(vec![0.25]))];
        let mut g = Grid::new(&m, 4, 2, &params).expect("a grid");
        g.shade(&mut TestHost::default());
        let img = g.image();
        assert_eq!(img.len(), 4 * 8);
        // Point (1, 1): s = 0.375, t = 0.75.
        let p = &img[4 * 5..4 * 6];
        assert_eq!(p, &[2.0 * 0.375 + 0.25, 2.0 * 0.75 + 0.25, 0.25, 1.0]);
        assert!(matches!(
            Grid::new(&m, 2, 2, &[("nope".into(), ParamArg::Floats(vec![1.0]))]),
            Err(GridError::NoParameter(_))
        ));
        assert!(matches!(
            Grid::new(&m, 2, 2, &[("c".into(), ParamArg::Floats(vec![1.0, 2.0]))]),
            Err(GridError::WrongCount { .. })
        ));
    }

    #[test]
    fn derivatives_are_one_grid_step() {
        let m = module("surface g() { Oi = 1; Ci = color(Du(s), Dv(t), area(P)); }");
        let mut g = Grid::new(&m, 8, 4, &[]).expect("a grid");
        g.shade(&mut TestHost::default());
        let img = g.image();
        let p = &img[..4];
        assert!((p[0] - 1.0).abs() < 1e-5 && (p[1] - 1.0).abs() < 1e-5, "{p:?}");
        assert!((p[2] - 1.0 / 32.0).abs() < 1e-6, "area is du * dv: {p:?}");
    }

    /// Shading again starts from the entry values, not from what the last run left.
    #[test]
    fn every_run_starts_from_the_entry_values() {
        let m = module("displacement d() { P += N; }");
        let mut g = Grid::new(&m, 2, 2, &[]).expect("a grid");
        let mut host = TestHost::default();
        g.shade(&mut host);
        g.shade(&mut host);
        assert_eq!(g.default_output(), "P");
        assert_eq!(&g.image()[..4], &[0.25, 0.25, 1.0, 1.0]);
    }

    /// What `image_of` takes: the globals of the shader type and the output parameters.
    #[test]
    fn outputs_are_globals_of_the_type_and_output_parameters() {
        let m = module(
            "light l(float k = 1; output varying float seen = 0; output float m[2] = {0, 0};) { seen = k; Cl = k; }",
        );
        let mut g = Grid::new(&m, 2, 1, &[]).expect("a grid");
        g.shade(&mut TestHost::default());
        assert_eq!(g.writable(), ["L", "Cl", "Ol", "seen", "m"]);
        assert_eq!(g.check_output("Ps").ok(), Some(3));
        assert_eq!(g.check_output("seen").ok(), Some(1));
        assert!(matches!(g.check_output("m"), Err(GridError::NotAnImage(_))));
        assert!(matches!(g.check_output("k"), Err(GridError::NoVariable { .. })), "an input parameter");
        assert!(matches!(g.check_output("Ci"), Err(GridError::NoVariable { .. })), "no Ci in a light");
        // The light's position is the origin of the host's "shader" space.
        assert_eq!(&g.image_of("P").expect("P")[..4], &[1.0, 2.0, 3.0, 1.0]);
        assert_eq!(&g.image_of("Ps").expect("Ps")[4..8], &[0.75, 0.5, 0.0, 1.0]);
    }
}

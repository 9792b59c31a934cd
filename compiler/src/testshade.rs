//! Shading a grid of points without a scene, like OSL's `testshade`: the engine of `rtsl shade`.
//!
//! The grid is the unit square in the z = 0 plane, seen by a camera at (0.5, 0.5, 1) looking down
//! -z: point `(x, y)` of a `W x H` grid has `s = u = (x + 0.5) / W`, `t = v = (y + 0.5) / H` (t
//! grows downwards, as in RenderMan), `P = (s, t, 0)`, `N = Ng = (0, 0, 1)`, `I = P - E`,
//! `dPdu = (1, 0, 0)`, `dPdv = (0, 1, 0)`, `du = 1 / W`, `dv = 1 / H`, `Cs = Os = 1`, and the
//! screen-space derivatives of one grid step (`P`, `s`, `u` change by `1 / W` along x; `P`, `t`, `v`
//! by `1 / H` along y). The renderer's side is whatever `Services` the caller passes; `rtsl shade`
//! uses `interp::TestHost` (an ambient light and a distant light from +z).

use crate::back::jit::{self, BatchData, CompiledShader, JitError};
use crate::interp::Services;
use crate::ir::Module;
use crate::ir::ShaderKind;

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

/// Why a grid cannot be shaded.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    #[error(transparent)]
    Jit(#[from] JitError),
    #[error("the shader is {} shader; only surface shaders shade a grid", .0.with_article())]
    NotSurface(ShaderKind),
    #[error("the shader has no parameter `{0}`")]
    NoParameter(String),
    #[error("parameter `{name}` takes {expected} number(s), {given} given")]
    WrongCount { name: String, expected: usize, given: usize },
    #[error("a grid of {width}x{height} points is too large: at most {MAX_GRID_POINTS}")]
    TooLarge { width: usize, height: usize },
}

/// The most points a grid may have: the renderer's image pixel cap
/// (`rtsl_runtime::render::world::MAX_IMAGE_PIXELS`), as the grid is written as an image and
/// holds some 200 bytes a point.
pub const MAX_GRID_POINTS: usize = 1 << 25;

/// The most lanes per batch.
pub const BATCH: usize = 64;

/// A compiled shader and the batches covering a grid, ready to shade again and again.
pub struct Grid {
    shader: CompiledShader,
    batches: Vec<BatchData>,
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
        if kind != ShaderKind::Surface {
            return Err(GridError::NotSurface(kind));
        }
        let shader = jit::compile_with(module, sources, &jit::JitOptions::default())?;
        let mut batches = Vec::new();
        let (fw, fh) = (w as f32, h as f32);
        for start in (0..total).step_by(BATCH) {
            let lanes = BATCH.min(total - start);
            let mut b = shader.batch(lanes);
            for lane in 0..lanes {
                let k = start + lane;
                let (x, y) = ((k % w) as f32, (k / w) as f32);
                let (s, t) = ((x + 0.5) / fw, (y + 0.5) / fh);
                let p = [s, t, 0.0];
                let set = |b: &mut BatchData, name: &str, v: &[f32]| {
                    b.set_global(name, lane, v);
                };
                set(&mut b, "P", &p);
                set(&mut b, "N", &[0.0, 0.0, 1.0]);
                set(&mut b, "Ng", &[0.0, 0.0, 1.0]);
                set(&mut b, "I", &[s - 0.5, t - 0.5, -1.0]);
                set(&mut b, "E", &[0.5, 0.5, 1.0]);
                set(&mut b, "s", &[s]);
                set(&mut b, "t", &[t]);
                set(&mut b, "u", &[s]);
                set(&mut b, "v", &[t]);
                set(&mut b, "du", &[1.0 / fw]);
                set(&mut b, "dv", &[1.0 / fh]);
                set(&mut b, "dPdu", &[1.0, 0.0, 0.0]);
                set(&mut b, "dPdv", &[0.0, 1.0, 0.0]);
                set(&mut b, "Cs", &[1.0; 3]);
                set(&mut b, "Os", &[1.0; 3]);
                set(&mut b, "Oi", &[1.0; 3]);
                let (dx, dy) = (1.0 / fw, 1.0 / fh);
                b.set_global_derivs("P", lane, &[dx, 0.0, 0.0], &[0.0, dy, 0.0]);
                b.set_global_derivs("I", lane, &[dx, 0.0, 0.0], &[0.0, dy, 0.0]);
                b.set_global_derivs("s", lane, &[dx], &[0.0]);
                b.set_global_derivs("u", lane, &[dx], &[0.0]);
                b.set_global_derivs("t", lane, &[0.0], &[dy]);
                b.set_global_derivs("v", lane, &[0.0], &[dy]);
                b.set_seed(lane, k as u64);
                for (name, value) in params {
                    bind(&mut b, lane, name, value)?;
                }
            }
            batches.push(b);
        }
        Ok(Grid { shader, batches, width: w, height: h })
    }

    /// Shades every point of the grid once.
    pub fn shade(&mut self, host: &mut dyn Services) {
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

    /// `Ci` and the mean of `Oi` per point as RGBA, rows top to bottom.
    pub fn image(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(4 * self.points());
        for b in &self.batches {
            for lane in 0..b.lanes() {
                let ci = b.global("Ci", lane).unwrap_or_else(|| vec![0.0; 3]);
                let oi = b.global("Oi", lane).unwrap_or_else(|| vec![1.0; 3]);
                out.extend_from_slice(&ci);
                out.push((oi[0] + oi[1] + oi[2]) / 3.0);
            }
        }
        out
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
}

//! The reference interpreter: runs checked IR for one shading point (one lane) at a time.
//!
//! It is the oracle the JIT is tested against, so it favours obviousness over speed: values are
//! [`Value`]s, variables live in a frame vector, control flow is Rust control flow, and every built-in
//! is computed by the scalar reference implementations in [`crate::shadeops`] or asked of the
//! renderer through [`Services`]. It shares no code with the JIT.
//!
//! Semantics it fixes (the JIT must agree):
//! - array and component indices are truncated toward zero and clamped into range;
//! - a user function call copies arguments in and output (and captured) arguments back out, in
//!   parameter order, when the call returns;
//! - `illuminance` visits the non-ambient lights the renderer reports for the category, in order,
//!   skipping those outside the cone (angle between `L` and the axis greater than the cone angle);
//! - `illuminate` runs its body only where `Ps` lies within the cone around the axis from the light
//!   position, with `L = Ps - position`; `solar` with a cone sets `L` to the axis;
//! - loop iterations are budgeted per run, all loops together, exactly as the JIT budgets a
//!   chunk's (`ir::LOOP_BUDGET`): past the budget the loop is left as by `break`, every loop reached
//!   later stops at once, and the run goes on ([`RunResult::stopped_loops`]);
//! - calls, lights and `gather` samples are budgeted too ([`Limits::steps`]): a shader that runs
//!   away there stops with an error instead of hanging the test;
//! - a string `concat` or `format` makes, and the text `printf` prints, is cut to
//!   `shadeops::format::MAX_STRING_LEN` bytes, and once the distinct strings made in a run pass
//!   `STRING_BYTES_BUDGET` new ones are empty, as in a JIT batch of one point
//!   ([`RunResult::string_limits`]);
//! - derivatives come from the renderer's screen-space derivatives of the globals
//!   ([`ShadingPoint::derivs`]): the values `ir::deriv` marks are evaluated as duals (`deriv.rs`).
//!
//! - `gather` takes its samples in order (`shadeops::gather`): each sample's ray from
//!   [`gather::sample_ray`], its outputs written (the `ray:` ones always, the `surface:` ones on a
//!   hit, in parameter order, indices evaluated at each write), then `body` on a hit (every sample of
//!   `"samplepattern"`) or `otherwise` on a miss; it counts as a loop for `break`/`continue`.
//! - `bump` point-samples channel 0 of its height map at (s, t) and one `geom::BUMP_STEP` along
//!   each, with a zero footprint, as the JIT's helper does.

mod builtins;
mod deriv;
pub mod host;
pub mod value;

pub use host::{EnvironmentQuery, LightSample, Services, ShadowQuery, TestHost, TextureFootprint};
pub use value::Value;

use crate::globals::{Global, GLOBALS};
use crate::ir::ShaderKind;
use crate::ir::{self, Arg, BaseType, BinaryOp, Block, ExprId, ExprKind, Function, Module, Place, PlaceBase, StmtKind};
use crate::shadeops::gather::{self, Output};
use crate::shadeops::{color, geom, matrix, V3};
use std::rc::Rc;

/// Why a run stopped early.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InterpError {
    /// The module defines no shader.
    NoShader,
    /// A construct the interpreter does not implement yet.
    Unsupported(&'static str),
    /// The call budget ran out.
    Budget,
    /// The shader is over `ir::INLINE_BUDGET` or `ir::STORAGE_BUDGET` (the checker refuses such
    /// source): why, in words.
    OverBudget(String),
}

impl std::fmt::Display for InterpError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InterpError::NoShader => write!(f, "the module defines no shader"),
            InterpError::Unsupported(what) => write!(f, "the interpreter does not support {what} yet"),
            InterpError::Budget => write!(f, "the shader ran past its call budget"),
            InterpError::OverBudget(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for InterpError {}

/// How much work one run may do.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Calls, lights visited by light loops, and `gather` samples.
    pub steps: u64,
    /// Loop iterations, all loops of the run together (the JIT's `JitOptions::loop_budget`).
    pub loop_iterations: u32,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits { steps: 10_000_000, loop_iterations: ir::LOOP_BUDGET }
    }
}

/// The globals of one shading point, indexed by [`Global`].
#[derive(Clone, Debug)]
pub struct ShadingPoint {
    pub globals: Vec<Value>,
    /// Seeds `random()`: the renderer gives every shading point its own (e.g. from the pixel and
    /// sample); successive calls in one run give successive values.
    pub seed: u64,
    /// Per global (indexed like `globals`): its derivatives with respect to screen x and y, of the
    /// global's shape (zero by default). The renderer fills them from ray differentials
    /// (`docs/packet-abi.md`, "Derivatives"); `Du`, `Dv` and the rest read them.
    pub derivs: Vec<[Value; 2]>,
}

impl ShadingPoint {
    /// A point with every global at a neutral default: zero, except `N`/`Ng` = (0,0,1),
    /// `I` = (0,0,-1), `E` = (0,0,5), `Cs`/`Os` = 1, `Oi` = 1, `ncomps` = 3, `Ci` = 0 (1 for camera
    /// shaders, whose `Ci` is the ray weight).
    pub fn new(kind: ShaderKind) -> ShadingPoint {
        let globals: Vec<Value> = GLOBALS
            .iter()
            .map(|g| match g.name {
                "N" | "Ng" => Value::Triple([0.0, 0.0, 1.0]),
                "I" => Value::Triple([0.0, 0.0, -1.0]),
                "E" => Value::Triple([0.0, 0.0, 5.0]),
                "Cs" | "Os" | "Oi" => Value::Triple([1.0; 3]),
                "Ci" if kind == ShaderKind::Camera => Value::Triple([1.0; 3]),
                "ncomps" => Value::Float(3.0),
                _ => Value::zero(ir::Type::scalar(g.ty)),
            })
            .collect();
        let derivs = globals.iter().map(|g: &Value| [deriv::zero_like(g), deriv::zero_like(g)]).collect();
        ShadingPoint { globals, seed: 0, derivs }
    }

    pub fn get(&self, name: &str) -> Option<&Value> {
        Global::lookup(name).map(|g| &self.globals[g.0 as usize])
    }

    pub fn set(&mut self, name: &str, v: Value) {
        if let Some(g) = Global::lookup(name) {
            self.globals[g.0 as usize] = v;
        }
    }

    /// Sets a global's screen-space derivatives (`d/dx`, `d/dy`, of the global's shape).
    pub fn set_derivs(&mut self, name: &str, dx: Value, dy: Value) {
        if let Some(g) = Global::lookup(name) {
            self.derivs[g.0 as usize] = [dx, dy];
        }
    }

    /// A global's screen-space derivatives.
    pub fn derivs(&self, name: &str) -> Option<&[Value; 2]> {
        Global::lookup(name).map(|g| &self.derivs[g.0 as usize])
    }

    /// Sets a global from outside the shader's dataflow (a light loop): zero derivatives.
    fn set_plain(&mut self, name: &str, v: Value) {
        if let Some(g) = Global::lookup(name) {
            self.derivs[g.0 as usize] = [deriv::zero_like(&v), deriv::zero_like(&v)];
            self.globals[g.0 as usize] = v;
        }
    }
}

/// The result of a run: the final values of the shader's parameters (outputs included).
#[derive(Clone, Debug)]
pub struct RunResult {
    pub params: Vec<(String, Value)>,
    /// Where the loop budget stopped a loop, each place once, in the order they stopped.
    pub stopped_loops: Vec<crate::source::Span>,
    /// Where a string `concat`, `format` or `printf` made passed a limit, each (limit, place) once,
    /// in the order they did.
    pub string_limits: Vec<(StringLimit, crate::source::Span)>,
}

/// What became of a string the shader made that passed a limit (the JIT reports the same).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StringLimit {
    /// Longer than `shadeops::format::MAX_STRING_LEN`: cut to it.
    Cut,
    /// The run's strings passed `shadeops::format::STRING_BYTES_BUDGET`: left empty.
    Dropped,
}

/// Runs a module's shader on one shading point. `bound` overrides parameter defaults by name.
pub fn run(
    module: &Module,
    bound: &[(&str, Value)],
    point: &mut ShadingPoint,
    host: &mut dyn Services,
    limits: Limits,
) -> Result<RunResult, InterpError> {
    let shader = module.shader.as_ref().ok_or(InterpError::NoShader)?;
    // Frames hold every variable: a module that did not go through the checker could ask for any
    // amount of memory.
    ir::within_budgets(module).map_err(InterpError::OverBudget)?;
    let body = module.function(shader.body);
    let info = ir::deriv::analyse(module);
    let mut m = Machine {
        module,
        point,
        host,
        steps: limits.steps,
        loop_iterations: 0,
        loop_budget: limits.loop_iterations,
        stopped_loops: Vec::new(),
        light_depth: 0,
        random_calls: 0,
        info: &info,
        ret_d: None,
        call_site: shader.span,
        strings: made_strings_seed(module, bound),
        string_bytes: 0,
        string_limits: Vec::new(),
    };
    let mut frame = Frame::new(shader.body, body);
    for p in &shader.params {
        // A bound parameter has zero derivatives (the renderer supplies none for parameters).
        let (value, dx, dy) = match bound.iter().find(|(n, _)| *n == p.name) {
            Some((_, v)) => (v.clone(), deriv::zero_like(v), deriv::zero_like(v)),
            None => m.dual(body, &mut frame, p.default)?,
        };
        let i = p.var.0 as usize;
        frame.vars[i] = value;
        frame.dx[i] = dx;
        frame.dy[i] = dy;
    }
    m.block(body, &mut frame, &body.body)?;
    Ok(RunResult {
        params: shader.params.iter().map(|p| (p.name.clone(), frame.vars[p.var.0 as usize].clone())).collect(),
        stopped_loops: m.stopped_loops,
        string_limits: m.string_limits,
    })
}

/// The strings a JIT batch holds before its shader makes any, which cost nothing when made again:
/// the empty string, the module's string constants and the bound string parameters.
fn made_strings_seed(module: &Module, bound: &[(&str, Value)]) -> rustc_hash::FxHashSet<Rc<str>> {
    let mut seed = rustc_hash::FxHashSet::default();
    seed.insert(Rc::from(""));
    for f in &module.functions {
        for e in &f.exprs {
            if let ExprKind::Const(ir::Constant::String(s)) = &e.kind {
                seed.insert(Rc::from(s.as_str()));
            }
        }
    }
    for (_, v) in bound {
        if let Value::String(s) = v {
            seed.insert(s.clone());
        }
    }
    seed
}

struct Frame {
    fid: ir::FuncId,
    vars: Vec<Value>,
    /// The variables' tangents (kept for the variables `ir::deriv` marks; zero for the others).
    dx: Vec<Value>,
    dy: Vec<Value>,
}

impl Frame {
    fn new(fid: ir::FuncId, f: &Function) -> Frame {
        let vars: Vec<Value> = f.vars.iter().map(|v| Value::zero(v.ty)).collect();
        let dx: Vec<Value> = vars.iter().map(deriv::zero_like).collect();
        Frame { fid, dy: dx.clone(), dx, vars }
    }
}

enum Flow {
    Next,
    Break(u32),
    Continue(u32),
    Return(Value),
}

struct Machine<'a> {
    module: &'a Module,
    point: &'a mut ShadingPoint,
    host: &'a mut dyn Services,
    steps: u64,
    /// Loop iterations begun in this run (every loop's condition tests), against `loop_budget`.
    loop_iterations: u32,
    loop_budget: u32,
    stopped_loops: Vec<crate::source::Span>,
    light_depth: u32,
    random_calls: u64,
    info: &'a ir::deriv::DerivInfo,
    /// The tangents of the value a function whose result is differentiated returned last.
    ret_d: Option<(Value, Value)>,
    /// The built-in call being evaluated, for reports: set by its caller, and again by
    /// `builtin` once the arguments, which may call built-ins too, are evaluated.
    call_site: crate::source::Span,
    /// The strings held as a JIT batch of one lane would hold them: what a string made again
    /// costs nothing against `STRING_BYTES_BUDGET`.
    strings: rustc_hash::FxHashSet<Rc<str>>,
    /// What the strings made in this run take (see `StringTable::intern_made`).
    string_bytes: usize,
    string_limits: Vec<(StringLimit, crate::source::Span)>,
}

type R<T> = Result<T, InterpError>;

fn index_of(v: &Value, len: usize) -> usize {
    let i = v.f();
    if !i.is_finite() || i < 0.0 || len == 0 {
        0
    } else {
        (i as usize).min(len - 1)
    }
}

fn normalize(v: V3) -> V3 {
    geom::normalize(v)
}

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The angle of a cone test, by RSL's `acos` (the JIT's cone tests compute the same bits).
fn angle_between(a: V3, b: V3) -> f32 {
    crate::shadeops::transcendental::acos(dot(normalize(a), normalize(b)).clamp(-1.0, 1.0))
}

impl Machine<'_> {
    /// Notes that a string made at the current call passed a limit (each place once).
    fn note(&mut self, limit: StringLimit) {
        let entry = (limit, self.call_site);
        if !self.string_limits.contains(&entry) {
            self.string_limits.push(entry);
        }
    }

    /// A string the shader made at the current call, `cut` when it was longer than
    /// `MAX_STRING_LEN`; the empty string once the run's strings pass `STRING_BYTES_BUDGET`, as a
    /// JIT batch of one lane does.
    fn made_string(&mut self, text: String, cut: bool) -> Value {
        use crate::shadeops::format::{STRING_BYTES_BUDGET, STRING_OVERHEAD};
        if cut {
            self.note(StringLimit::Cut);
        }
        if let Some(s) = self.strings.get(text.as_str()) {
            return Value::String(s.clone());
        }
        let cost = text.len().saturating_add(STRING_OVERHEAD);
        if self.string_bytes.saturating_add(cost) > STRING_BYTES_BUDGET {
            self.note(StringLimit::Dropped);
            return Value::String(Rc::from(""));
        }
        self.string_bytes += cost;
        let s: Rc<str> = Rc::from(text);
        self.strings.insert(s.clone());
        Value::String(s)
    }

    fn step(&mut self) -> R<()> {
        if self.steps == 0 {
            return Err(InterpError::Budget);
        }
        self.steps -= 1;
        Ok(())
    }

    fn global(&self, name: &str) -> Value {
        self.point.get(name).cloned().unwrap_or(Value::Void)
    }

    fn block(&mut self, f: &Function, frame: &mut Frame, b: &Block) -> R<Flow> {
        for s in &b.stmts {
            let flow = self.stmt(f, frame, s)?;
            if !matches!(flow, Flow::Next) {
                return Ok(flow);
            }
        }
        Ok(Flow::Next)
    }

    /// Runs a loop body's flow: `Some(flow)` leaves the loop with that flow.
    fn loop_flow(flow: Flow) -> Option<Flow> {
        match flow {
            Flow::Next | Flow::Continue(1) => None,
            Flow::Break(1) => Some(Flow::Next),
            Flow::Break(n) => Some(Flow::Break(n - 1)),
            Flow::Continue(n) => Some(Flow::Continue(n - 1)),
            r @ Flow::Return(_) => Some(r),
        }
    }

    fn stmt(&mut self, f: &Function, frame: &mut Frame, s: &ir::Stmt) -> R<Flow> {
        match &s.kind {
            StmtKind::Expr(e) => {
                self.expr(f, frame, *e)?;
                Ok(Flow::Next)
            }
            StmtKind::If { cond, then, otherwise } => {
                if self.expr(f, frame, *cond)?.b() {
                    self.block(f, frame, then)
                } else {
                    self.block(f, frame, otherwise)
                }
            }
            StmtKind::Loop { cond, body, step } => loop {
                self.loop_iterations = self.loop_iterations.saturating_add(1);
                if self.loop_iterations > self.loop_budget {
                    if !self.stopped_loops.contains(&s.span) {
                        self.stopped_loops.push(s.span);
                    }
                    return Ok(Flow::Next);
                }
                if let Some(c) = cond {
                    if !self.expr(f, frame, *c)?.b() {
                        return Ok(Flow::Next);
                    }
                }
                let flow = self.block(f, frame, body)?;
                if let Some(out) = Self::loop_flow(flow) {
                    return Ok(out);
                }
                self.block(f, frame, step)?;
            },
            StmtKind::Break(n) => Ok(Flow::Break(*n)),
            StmtKind::Continue(n) => Ok(Flow::Continue(*n)),
            StmtKind::Return(v) => {
                let value = match v {
                    Some(e) if self.info.ret[frame.fid.0 as usize] => {
                        let (v, dx, dy) = self.dual(f, frame, *e)?;
                        self.ret_d = Some((dx, dy));
                        v
                    }
                    Some(e) => self.expr(f, frame, *e)?,
                    None => Value::Void,
                };
                Ok(Flow::Return(value))
            }
            StmtKind::Illuminance { category, position, cone, body } => {
                let category = match category {
                    Some(c) => self.expr(f, frame, *c)?.s().to_string(),
                    None => String::new(),
                };
                let p = self.expr(f, frame, *position)?.v3();
                let cone = match cone {
                    Some((a, b)) => Some((self.expr(f, frame, *a)?.v3(), self.expr(f, frame, *b)?.f())),
                    None => None,
                };
                let saved = (self.global("L"), self.global("Cl"), self.global("Ol"));
                let lights = self.host.lights(&category, p);
                let mut result = Flow::Next;
                for light in lights.iter().filter(|l| !l.ambient) {
                    self.step()?;
                    if let Some((axis, angle)) = cone {
                        if angle_between(light.l, axis) > angle {
                            continue;
                        }
                    }
                    self.point.set_plain("L", Value::Triple(light.l));
                    self.point.set_plain("Cl", Value::Triple(light.cl));
                    self.point.set_plain("Ol", Value::Triple(light.ol));
                    self.light_depth += 1;
                    let flow = self.block(f, frame, body);
                    self.light_depth -= 1;
                    if let Some(out) = Self::loop_flow(flow?) {
                        result = out;
                        break;
                    }
                }
                self.point.set_plain("L", saved.0);
                self.point.set_plain("Cl", saved.1);
                self.point.set_plain("Ol", saved.2);
                Ok(result)
            }
            StmtKind::Illuminate { position, cone, body } => {
                let from = self.expr(f, frame, *position)?.v3();
                let cone = match cone {
                    Some((a, b)) => Some((self.expr(f, frame, *a)?.v3(), self.expr(f, frame, *b)?.f())),
                    None => None,
                };
                let ps = self.global("Ps").v3();
                let l = [ps[0] - from[0], ps[1] - from[1], ps[2] - from[2]];
                if let Some((axis, angle)) = cone {
                    if angle_between(l, axis) > angle {
                        return Ok(Flow::Next);
                    }
                }
                self.point.set_plain("L", Value::Triple(l));
                self.block(f, frame, body)
            }
            StmtKind::Solar { cone, body } => {
                if let Some((a, b)) = cone {
                    let axis = self.expr(f, frame, *a)?.v3();
                    self.expr(f, frame, *b)?;
                    self.point.set_plain("L", Value::Triple(axis));
                }
                self.block(f, frame, body)
            }
            StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                let category = self.expr(f, frame, *category)?.s().to_string();
                let from = self.expr(f, frame, *position)?.v3();
                let axis = self.expr(f, frame, *direction)?.v3();
                let angle = self.expr(f, frame, *angle)?.f();
                let n = gather::sample_count(self.expr(f, frame, *samples)?.f());
                let mut options = gather::Options::default();
                let mut outputs = Vec::new();
                for (name, arg) in params {
                    let name = self.expr(f, frame, *name)?.s().to_string();
                    match arg {
                        Arg::Value(x) => match (self.expr(f, frame, *x)?, gather::Options::float_slot(&name)) {
                            (Value::Float(x), Some(slot)) => options.set_float(slot, x),
                            (Value::String(s), None) if name == "distribution" => {
                                options.cosine = gather::Options::is_cosine(&s)
                            }
                            _ => {}
                        },
                        Arg::Ref(p) => {
                            if let Some(o) = Output::parse(&name).filter(|o| o.fits(p.ty)) {
                                outputs.push((o, p));
                            }
                        }
                    }
                }
                let trace = gather::traces(&category);
                for k in 0..n {
                    self.step()?;
                    let (origin, dir) = gather::sample_ray(from, axis, angle, k, n, &options);
                    let hit = if trace && dir != [0.0; 3] {
                        self.host.gather_ray(&category, origin, dir, options.maxdist)
                    } else {
                        None
                    };
                    let rec = gather::record(origin, dir, hit.as_ref(), trace);
                    for (o, p) in &outputs {
                        if rec[0] == gather::HIT || o.on_miss() {
                            let r = o.row();
                            let v = match o.components() {
                                1 => Value::Float(rec[r]),
                                _ => Value::Triple([rec[r], rec[r + 1], rec[r + 2]]),
                            };
                            self.write_place(f, frame, p, v)?;
                        }
                    }
                    let flow = self.block(f, frame, if rec[0] != gather::MISS { body } else { otherwise })?;
                    if let Some(out) = Self::loop_flow(flow) {
                        return Ok(out);
                    }
                }
                Ok(Flow::Next)
            }
        }
    }

    fn read_place(&mut self, f: &Function, frame: &mut Frame, p: &Place) -> R<Value> {
        Ok(self.read_place_d(f, frame, p)?.0)
    }

    /// A place's value and tangents (indices evaluated once).
    fn read_place_d(&mut self, f: &Function, frame: &mut Frame, p: &Place) -> R<deriv::Dual> {
        let (mut v, mut dx, mut dy) = match p.base {
            PlaceBase::Var(var) => {
                let i = var.0 as usize;
                (frame.vars[i].clone(), frame.dx[i].clone(), frame.dy[i].clone())
            }
            PlaceBase::Global(g) => {
                let i = g.0 as usize;
                let [dx, dy] = self.point.derivs[i].clone();
                (self.point.globals[i].clone(), dx, dy)
            }
        };
        for idx in [p.index, p.component].into_iter().flatten() {
            let i = self.expr(f, frame, idx)?;
            let sel = |v: Value| match v {
                Value::Array(items) => {
                    let k = index_of(&i, items.len());
                    items.get(k).cloned().unwrap_or(Value::Void)
                }
                Value::Triple(t) => Value::Float(t[index_of(&i, 3)]),
                other => other,
            };
            v = sel(v);
            dx = sel(dx);
            dy = sel(dy);
        }
        Ok((v, dx, dy))
    }

    /// Evaluates a place's indices, then stores `value` there (zero tangents when the place keeps
    /// tangents: a built-in's output).
    fn write_place(&mut self, f: &Function, frame: &mut Frame, p: &Place, value: Value) -> R<()> {
        self.write_place_d(f, frame, p, value, None)
    }

    /// Evaluates a place's indices, then stores `value` there, and its tangents (`None`: zero)
    /// when the place keeps tangents.
    fn write_place_d(
        &mut self,
        f: &Function,
        frame: &mut Frame,
        p: &Place,
        value: Value,
        d: Option<(Value, Value)>,
    ) -> R<()> {
        let mut indices = Vec::new();
        for idx in [p.index, p.component].into_iter().flatten() {
            indices.push(self.expr(f, frame, idx)?);
        }
        let keeps = match p.base {
            PlaceBase::Var(var) => self.info.var(frame.fid, var),
            PlaceBase::Global(g) => self.info.global(g),
        };
        if keeps {
            let (dx, dy) = d.unwrap_or_else(|| (deriv::zero_like(&value), deriv::zero_like(&value)));
            let pair = match p.base {
                PlaceBase::Var(var) => {
                    let i = var.0 as usize;
                    [&mut frame.dx[i], &mut frame.dy[i]]
                }
                PlaceBase::Global(g) => {
                    let [x, y] = &mut self.point.derivs[g.0 as usize];
                    [x, y]
                }
            };
            let [sx, sy] = pair;
            store(sx, &indices, dx);
            store(sy, &indices, dy);
        }
        let slot = match p.base {
            PlaceBase::Var(var) => &mut frame.vars[var.0 as usize],
            PlaceBase::Global(g) => &mut self.point.globals[g.0 as usize],
        };
        store(slot, &indices, value);
        Ok(())
    }

    fn expr(&mut self, f: &Function, frame: &mut Frame, id: ExprId) -> R<Value> {
        let e = f.expr(id);
        if matches!(e.kind, ExprKind::Assign { .. } | ExprKind::Call { .. }) && self.info.expr(frame.fid, id) {
            // Stores tangents (or keeps a callee's result tangents) as it evaluates.
            return Ok(self.dual(f, frame, id)?.0);
        }
        Ok(match &e.kind {
            ExprKind::Const(ir::Constant::Float(v)) => Value::Float(*v),
            ExprKind::Const(ir::Constant::String(s)) => Value::String(Rc::from(s.as_str())),
            ExprKind::Var(v) => frame.vars[v.0 as usize].clone(),
            ExprKind::Global(g) => self.point.globals[g.0 as usize].clone(),
            ExprKind::Index { base, index } => {
                let b = self.expr(f, frame, *base)?;
                let i = self.expr(f, frame, *index)?;
                match b {
                    Value::Array(items) => items.get(index_of(&i, items.len())).cloned().unwrap_or(Value::Void),
                    Value::Triple(t) => Value::Float(t[index_of(&i, 3)]),
                    other => other,
                }
            }
            ExprKind::Unary { op, arg } => {
                let a = self.expr(f, frame, *arg)?;
                match op {
                    ir::UnaryOp::Not => Value::Bool(!a.b()),
                    ir::UnaryOp::Neg => match a {
                        Value::Float(x) => Value::Float(-x),
                        Value::Triple(t) => Value::Triple(t.map(|x| -x)),
                        Value::Matrix(m) => Value::Matrix(m.map(|x| -x)),
                        other => other,
                    },
                }
            }
            ExprKind::Binary { op: BinaryOp::And, lhs, rhs } => {
                let a = self.expr(f, frame, *lhs)?.b();
                Value::Bool(a && self.expr(f, frame, *rhs)?.b())
            }
            ExprKind::Binary { op: BinaryOp::Or, lhs, rhs } => {
                let a = self.expr(f, frame, *lhs)?.b();
                Value::Bool(a || self.expr(f, frame, *rhs)?.b())
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.expr(f, frame, *lhs)?;
                let b = self.expr(f, frame, *rhs)?;
                binary(*op, &a, &b)
            }
            ExprKind::Convert { arg } => {
                let a = self.expr(f, frame, *arg)?;
                convert(a, e.ty.base)
            }
            ExprKind::Construct { args } => {
                let mut vals = Vec::with_capacity(args.len());
                for a in args {
                    vals.push(self.expr(f, frame, *a)?.f());
                }
                if e.ty.base == BaseType::Matrix {
                    let mut m = [0.0; 16];
                    for (slot, v) in m.iter_mut().zip(vals) {
                        *slot = v;
                    }
                    Value::Matrix(m)
                } else {
                    Value::Triple([vals[0], vals[1], vals[2]])
                }
            }
            ExprKind::SpaceCast { space, arg } => {
                let space = self.expr(f, frame, *space)?;
                let v = self.expr(f, frame, *arg)?;
                self.space_cast(e.ty.base, space.s(), v)
            }
            ExprKind::Select { cond, a, b } => {
                if self.expr(f, frame, *cond)?.b() {
                    self.expr(f, frame, *a)?
                } else {
                    self.expr(f, frame, *b)?
                }
            }
            ExprKind::CallBuiltin { builtin, overload, args } => {
                self.call_site = e.span;
                self.builtin(f, frame, *builtin, *overload, args, e.ty)?.0
            }
            ExprKind::Call { func, args } => self.call(f, frame, *func, args)?.0,
            ExprKind::Assign { place, op, value } => {
                let v = self.expr(f, frame, *value)?;
                let stored = match op {
                    Some(op) => {
                        let current = self.read_place(f, frame, place)?;
                        binary(*op, &current, &v)
                    }
                    None => v,
                };
                self.write_place(f, frame, place, stored.clone())?;
                stored
            }
            ExprKind::ArrayLiteral { elements } => {
                let mut vals = Vec::with_capacity(elements.len());
                for el in elements {
                    vals.push(self.expr(f, frame, *el)?);
                }
                Value::Array(vals)
            }
        })
    }

    fn space_cast(&mut self, ty: BaseType, space: &str, v: Value) -> Value {
        match ty {
            BaseType::Color => Value::Triple(color::to_rgb(space, v.v3()).unwrap_or(v.v3())),
            BaseType::Matrix => match self.host.matrix(space, "current") {
                Some(m) => Value::Matrix(matrix::mul(&v.m4(), &m)),
                None => v,
            },
            _ => match self.host.matrix(space, "current") {
                Some(m) => Value::Triple(match ty {
                    BaseType::Point => matrix::transform_point(&m, v.v3()),
                    BaseType::Vector => matrix::transform_vector(&m, v.v3()),
                    _ => matrix::transform_normal(&m, v.v3()),
                }),
                None => v,
            },
        }
    }

    /// Calls a user function; returns its result and, when the result is differentiated, its
    /// tangents. Differentiated parameters are copied in (and out) with their tangents.
    fn call(
        &mut self,
        f: &Function,
        frame: &mut Frame,
        func: ir::FuncId,
        args: &[Arg],
    ) -> R<(Value, Option<(Value, Value)>)> {
        self.step()?;
        let module = self.module;
        let callee = module.function(func);
        let mut inner = Frame::new(func, callee);
        for (a, p) in args.iter().zip(&callee.params) {
            let marked = self.info.var(func, *p);
            let (v, dx, dy) = match a {
                Arg::Value(e) if marked => self.dual(f, frame, *e)?,
                Arg::Value(e) => {
                    let v = self.expr(f, frame, *e)?;
                    let z = deriv::zero_like(&v);
                    (v, z.clone(), z)
                }
                Arg::Ref(place) => self.read_place_d(f, frame, place)?,
            };
            let i = p.0 as usize;
            inner.vars[i] = v;
            inner.dx[i] = dx;
            inner.dy[i] = dy;
        }
        self.ret_d = None;
        let result = match self.block(callee, &mut inner, &callee.body)? {
            Flow::Return(v) => v,
            _ => Value::Void,
        };
        let ret_d = if self.info.ret[func.0 as usize] { self.ret_d.take() } else { None };
        for (a, p) in args.iter().zip(&callee.params) {
            if let Arg::Ref(place) = a {
                let i = p.0 as usize;
                let v = inner.vars[i].clone();
                let d = self.info.var(func, *p).then(|| (inner.dx[i].clone(), inner.dy[i].clone()));
                self.write_place_d(f, frame, place, v, d)?;
            }
        }
        Ok((result, ret_d))
    }
}

/// Stores `value` into `slot` at the given array index and/or triple component.
fn store(slot: &mut Value, indices: &[Value], value: Value) {
    match (indices.first(), slot) {
        (None, slot) => *slot = value,
        (Some(i), Value::Array(items)) => {
            let k = index_of(i, items.len());
            if let Some(item) = items.get_mut(k) {
                store(item, &indices[1..], value);
            }
        }
        (Some(i), Value::Triple(t)) => t[index_of(i, 3)] = value.f(),
        (Some(_), _) => {}
    }
}

/// Converts a value to a base type as `ExprKind::Convert` specifies.
fn convert(v: Value, to: BaseType) -> Value {
    match (v, to) {
        (Value::Array(items), to) => Value::Array(items.into_iter().map(|i| convert(i, to)).collect()),
        (Value::Float(x), b) if b.is_triple() => Value::Triple([x; 3]),
        (Value::Float(x), BaseType::Matrix) => Value::Matrix(Value::Float(x).m4()),
        (Value::Bool(x), BaseType::Float) => Value::Float(f32::from(u8::from(x))),
        (Value::Triple(t), BaseType::Float) => Value::Float(t[0]),
        (v, _) => v,
    }
}

fn zip3(a: V3, b: V3, op: fn(f32, f32) -> f32) -> V3 {
    [op(a[0], b[0]), op(a[1], b[1]), op(a[2], b[2])]
}

/// A binary operator on operands of the types the IR guarantees.
fn binary(op: BinaryOp, a: &Value, b: &Value) -> Value {
    use BinaryOp::*;
    let arith: Option<fn(f32, f32) -> f32> = match op {
        Add => Some(|x, y| x + y),
        Sub => Some(|x, y| x - y),
        Mul => Some(|x, y| x * y),
        Div => Some(|x, y| x / y),
        _ => None,
    };
    match (op, a, b) {
        (Mul, Value::Matrix(x), Value::Matrix(y)) => Value::Matrix(matrix::mul(x, y)),
        (Div, Value::Matrix(x), Value::Matrix(y)) => Value::Matrix(matrix::div(x, y)),
        (Add | Sub, Value::Matrix(x), Value::Matrix(y)) => {
            let g = arith.unwrap_or(|x, _| x);
            let mut m = [0.0; 16];
            for i in 0..16 {
                m[i] = g(x[i], y[i]);
            }
            Value::Matrix(m)
        }
        (Add | Sub | Mul | Div, Value::Float(x), Value::Float(y)) => {
            Value::Float(arith.map(|g| g(*x, *y)).unwrap_or(0.0))
        }
        (Add | Sub | Mul | Div, Value::Triple(x), Value::Triple(y)) => {
            Value::Triple(arith.map(|g| zip3(*x, *y, g)).unwrap_or([0.0; 3]))
        }
        (Cross, _, _) => {
            let (x, y) = (a.v3(), b.v3());
            Value::Triple([x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]])
        }
        (Dot, _, _) => Value::Float(dot(a.v3(), b.v3())),
        (Lt, _, _) => Value::Bool(a.f() < b.f()),
        (Gt, _, _) => Value::Bool(a.f() > b.f()),
        (Le, _, _) => Value::Bool(a.f() <= b.f()),
        (Ge, _, _) => Value::Bool(a.f() >= b.f()),
        (Eq, _, _) => Value::Bool(a == b),
        (Ne, _, _) => Value::Bool(a != b),
        (And, _, _) => Value::Bool(a.b() && b.b()),
        (Or, _, _) => Value::Bool(a.b() || b.b()),
        _ => Value::Void,
    }
}

#[cfg(test)]
mod tests;

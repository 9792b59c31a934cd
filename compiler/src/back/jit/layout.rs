//! Where a compiled shader's inputs and outputs live in a batch.
//!
//! Invariants:
//! - **Varying slots**: first every varying global the module mentions (in [`GLOBALS`] order, one
//!   slot per component, so a triple takes three consecutive slots x, y, z), then every varying
//!   shader parameter in declaration order (`components * array length` slots each, element-major:
//!   element `k` component `j` is slot `offset + k * components + j`). Slot `s` of lane `l` is
//!   `varying[s * stride + l]`.
//! - **Uniform block**: first the uniform globals the module mentions (`ncomps`, `time`, `dtime`),
//!   then every uniform parameter in declaration order, the same element-major order, one `f32` each.
//! - Every shader parameter has an entry (in declaration order), and `bound[i]` of the batch says
//!   whether parameter `i` was given a value (otherwise the shader evaluates its default).
//! - **Random seeds**: a module that calls `random()` gets two more varying slots after the
//!   parameters ([`Layout::seed`]): each lane's 64-bit seed (the interpreter's `ShadingPoint::seed`),
//!   low 32 bits then high 32 bits, carried in the bits of `f32`s (see `BatchData::set_seed`).
//! - **Derivatives**: the varying globals come first, so slots `0..deriv_slots` are exactly the
//!   globals' slots; `Batch::derivs` holds, for each of them, d/dx at `derivs[2s * stride + l]` and
//!   d/dy at `derivs[(2s + 1) * stride + l]`. A module that differentiates (`ir::deriv`) always has
//!   `u`, `v`, `du`, `dv` (and, with `calculatenormal`, `dPdu`, `dPdv`, `Ng`) in its layout.
//! - The layout depends only on the module, never on the batch size.

use crate::globals::{Global, GLOBALS};
use crate::ir::{Arg, BaseType, ExprKind, Module, PlaceBase, Type};

/// Where one global lives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GlobalSlot {
    pub global: Global,
    pub name: &'static str,
    /// Varying (SoA slots) or uniform (the uniform block).
    pub varying: bool,
    /// First slot (varying) or index in the uniform block (uniform).
    pub offset: usize,
    pub components: usize,
    /// Assigned somewhere in the module: the shader stores it back.
    pub written: bool,
    /// The shader never uses the value the global holds on entry: a top-level statement of the
    /// shader body (which every lane reaches) assigns the whole of it before anything might read
    /// it. A caller need not fill it.
    pub entry_unused: bool,
    /// The code reads the renderer's derivatives of this global (it keeps tangents for it: see
    /// `ir::deriv`); a renderer need fill only these of the derivative buffer.
    pub derivs: bool,
}

/// Where one shader parameter lives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamSlot {
    pub name: String,
    pub varying: bool,
    pub output: bool,
    pub offset: usize,
    /// Floats per element: 1 for float (and string handles), 3 for triples, 16 for matrices.
    pub components: usize,
    /// A string parameter: its uniform slot holds a string handle (see `BatchData::set_string_param`).
    pub string: bool,
    /// Array length (1 for a scalar).
    pub len: usize,
}

impl ParamSlot {
    pub fn floats(&self) -> usize {
        self.components * self.len
    }
}

/// The batch layout table of one compiled shader.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    pub globals: Vec<GlobalSlot>,
    pub params: Vec<ParamSlot>,
    /// Number of varying slots (each `stride` floats).
    pub varying_slots: usize,
    /// Number of floats in the uniform block.
    pub uniform_len: usize,
    /// The shader's string constants: handles `0..strings.len()` of every batch's string table.
    pub strings: Vec<String>,
    /// The first of the two varying slots holding each lane's `random()` seed (low, high 32 bits),
    /// when the module calls `random()`.
    pub seed: Option<usize>,
    /// The varying slots that have derivatives in `Batch::derivs` (the globals' slots, `0..n`):
    /// the derivative buffer holds `2 * deriv_slots * stride` floats.
    pub deriv_slots: usize,
}

impl Layout {
    pub fn global(&self, name: &str) -> Option<&GlobalSlot> {
        self.globals.iter().find(|g| g.name == name)
    }

    pub fn param(&self, name: &str) -> Option<(usize, &ParamSlot)> {
        self.params.iter().enumerate().find(|(_, p)| p.name == name)
    }
}

/// Floats per element of a type the JIT stores (`None` for void and bools): a string is one uniform
/// float whose bits are its handle, a matrix sixteen floats (row-major).
pub(super) fn components(ty: Type) -> Option<usize> {
    match ty.base {
        BaseType::Float | BaseType::String => Some(1),
        b if b.is_triple() => Some(3),
        BaseType::Matrix => Some(16),
        _ => None,
    }
}

/// Computes the layout of a module's shader. Parameters of types the JIT cannot store are reported
/// as `Err(what)`.
pub(super) fn layout(m: &Module) -> Result<Layout, &'static str> {
    let shader = m.shader.as_ref().ok_or("a module without a shader")?;
    let mut used = vec![false; GLOBALS.len()];
    let mut random = false;
    let mut written = vec![false; GLOBALS.len()];
    // Whether anything may read a global's value (conservatively: a partial or compound assignment
    // and a reference argument read it too).
    let mut read = vec![false; GLOBALS.len()];
    for f in &m.functions {
        for e in &f.exprs {
            match &e.kind {
                ExprKind::Global(g) => {
                    used[g.0 as usize] = true;
                    read[g.0 as usize] = true;
                }
                ExprKind::Assign { place, op, .. } => {
                    if let PlaceBase::Global(g) = place.base {
                        used[g.0 as usize] = true;
                        written[g.0 as usize] = true;
                        read[g.0 as usize] |= op.is_some() || place.index.is_some() || place.component.is_some();
                    }
                }
                ExprKind::Call { args, .. } | ExprKind::CallBuiltin { args, .. } => {
                    for a in args {
                        if let Arg::Ref(p) = a {
                            if let PlaceBase::Global(g) = p.base {
                                used[g.0 as usize] = true;
                                written[g.0 as usize] = true;
                                read[g.0 as usize] = true;
                            }
                        }
                    }
                    // Built-ins that read globals implicitly.
                    if let ExprKind::CallBuiltin { builtin, args, .. } = &e.kind {
                        use crate::builtins::Builtin as Bi;
                        random |= *builtin == Bi::Random;
                        for name in implicit_reads(*builtin, args.len()) {
                            if let Some(g) = Global::lookup(name) {
                                used[g.0 as usize] = true;
                                read[g.0 as usize] = true;
                            }
                        }
                    }
                }
                _ => {}
            }
        }
    }
    // Globals read behind the statements' backs (by derivatives and light statements).
    let mut behind = vec![false; GLOBALS.len()];
    // Derivatives need the parameters' differentials (and calculatenormal the orientation).
    let info = crate::ir::deriv::analyse(m);
    if info.any {
        let mut names = vec!["u", "v", "du", "dv"];
        if info.normals {
            names.extend(["dPdu", "dPdv", "Ng"]);
        }
        for name in names {
            if let Some(g) = Global::lookup(name) {
                used[g.0 as usize] = true;
                read[g.0 as usize] = true;
                behind[g.0 as usize] = true;
            }
        }
    }
    // Light statements read and write the light globals.
    let mut by_lights = vec![false; GLOBALS.len()];
    for f in &m.functions {
        light_globals(&f.body, &mut by_lights, &mut written);
    }
    for (i, lit) in by_lights.into_iter().enumerate() {
        used[i] |= lit;
        read[i] |= lit;
        behind[i] |= lit;
    }
    let assigned_first = assigned_before_read(m.function(shader.body));
    let mut l = Layout::default();
    for pass_varying in [true, false] {
        for (i, g) in GLOBALS.iter().enumerate() {
            let varying = g.varying_in(Some(shader.kind));
            if !used[i] || varying != pass_varying {
                continue;
            }
            let comps = g.ty.components();
            if !(comps == 1 || comps == 3) || g.ty == BaseType::String {
                return Err("a matrix or string global");
            }
            let offset = if varying { &mut l.varying_slots } else { &mut l.uniform_len };
            l.globals.push(GlobalSlot {
                global: Global(i as u8),
                name: g.name,
                varying,
                offset: *offset,
                components: comps,
                written: written[i],
                entry_unused: !behind[i] && assigned_first[i],
                derivs: varying && (info.global(Global(i as u8)) || (info.any && matches!(g.name, "u" | "v"))),
            });
            *offset += comps;
        }
    }
    // Only a shader that differentiates something reads derivatives; the others get no buffer
    // (`deriv_slots` 0), so renderers fill nothing for them.
    l.deriv_slots = if info.any || info.globals.iter().any(|g| *g) { l.varying_slots } else { 0 };
    for p in &shader.params {
        let comps = components(p.ty).ok_or("a shader parameter of an unstorable type")?;
        let string = p.ty.base == BaseType::String;
        if string && p.varying {
            return Err("a varying string parameter");
        }
        let len = match p.ty.array {
            None => 1,
            Some(_) => p.ty.array_len().ok_or("an unsized array parameter")? as usize,
        };
        let offset = if p.varying { &mut l.varying_slots } else { &mut l.uniform_len };
        l.params.push(ParamSlot {
            name: p.name.clone(),
            varying: p.varying,
            output: p.output,
            offset: *offset,
            components: comps,
            string,
            len,
        });
        *offset += comps * len;
    }
    if random {
        l.seed = Some(l.varying_slots);
        l.varying_slots += 2;
    }
    Ok(l)
}

/// The built-in's globals that it reads without taking them as arguments.
fn implicit_reads(builtin: crate::builtins::Builtin, args: usize) -> &'static [&'static str] {
    use crate::builtins::Builtin as Bi;
    match builtin {
        Bi::Faceforward if args == 2 => &["Ng"],
        Bi::Ambient | Bi::Diffuse | Bi::Specular | Bi::Phong => &["P"],
        Bi::Texture | Bi::Bump => &["s", "t"],
        Bi::Incident | Bi::Opposite => &["I", "Ng"],
        _ => &[],
    }
}

/// The globals whose value on entry the shader body never reads: its top-level statements, in
/// order, assign each of them whole (`g = value`, which every lane runs: a shader body cannot
/// `return`, the checker refuses it) before any statement that might read it. The scan stops at
/// the first statement it cannot see through (a call of a user function, which may read any
/// global, or a light, gather or jump statement); globals not yet assigned by then count as read.
/// Reads behind the statements' backs (derivatives, light statements) are the caller's to add.
fn assigned_before_read(body: &crate::ir::Function) -> Vec<bool> {
    use crate::ir::StmtKind;
    let mut assigned = vec![false; GLOBALS.len()];
    // Read or assigned (even in part, or under a condition) by an earlier statement.
    let mut touched = vec![false; GLOBALS.len()];
    for s in &body.body.stmts {
        let (mut reads, mut writes) = (vec![false; GLOBALS.len()], vec![false; GLOBALS.len()]);
        if !stmt_reads(body, s, &mut reads, &mut writes) {
            break;
        }
        let whole = match s.kind {
            StmtKind::Expr(e) => match &body.expr(e).kind {
                ExprKind::Assign { place, op: None, .. } => match (place.base, place.index, place.component) {
                    (PlaceBase::Global(g), None, None) => Some(g.0 as usize),
                    _ => None,
                },
                _ => None,
            },
            _ => None,
        };
        if let Some(g) = whole.filter(|&g| !touched[g] && !reads[g]) {
            assigned[g] = true;
        }
        for ((t, r), w) in touched.iter_mut().zip(&reads).zip(&writes) {
            *t |= *r || *w;
        }
    }
    assigned
}

/// Marks in `reads` the globals statement `s` might read and in `assigned` those it assigns
/// (nested ones included); `false` when it cannot tell (see [`assigned_before_read`]).
fn stmt_reads(f: &crate::ir::Function, s: &crate::ir::Stmt, reads: &mut [bool], assigned: &mut [bool]) -> bool {
    use crate::ir::StmtKind;
    let block = |b: &crate::ir::Block, reads: &mut [bool], assigned: &mut [bool]| {
        b.stmts.iter().all(|s| stmt_reads(f, s, reads, assigned))
    };
    match &s.kind {
        StmtKind::Expr(e) => expr_reads(f, *e, reads, assigned),
        StmtKind::If { cond, then, otherwise } => {
            expr_reads(f, *cond, reads, assigned) && block(then, reads, assigned) && block(otherwise, reads, assigned)
        }
        StmtKind::Loop { cond, body, step } => {
            cond.is_none_or(|c| expr_reads(f, c, reads, assigned))
                && block(body, reads, assigned)
                && block(step, reads, assigned)
        }
        _ => false,
    }
}

/// [`stmt_reads`] of an expression.
fn expr_reads(f: &crate::ir::Function, e: crate::ir::ExprId, reads: &mut [bool], assigned: &mut [bool]) -> bool {
    let place = |p: &crate::ir::Place, reads: &mut [bool], assigned: &mut [bool]| {
        [p.index, p.component].into_iter().flatten().all(|i| expr_reads(f, i, reads, assigned))
    };
    match &f.expr(e).kind {
        ExprKind::Global(g) => {
            reads[g.0 as usize] = true;
            true
        }
        ExprKind::Call { .. } => false,
        ExprKind::CallBuiltin { builtin, args, .. } => {
            for name in implicit_reads(*builtin, args.len()) {
                if let Some(g) = Global::lookup(name) {
                    reads[g.0 as usize] = true;
                }
            }
            args.iter().all(|a| match a {
                Arg::Value(v) => expr_reads(f, *v, reads, assigned),
                Arg::Ref(p) => {
                    if let PlaceBase::Global(g) = p.base {
                        reads[g.0 as usize] = true;
                        assigned[g.0 as usize] = true;
                    }
                    place(p, reads, assigned)
                }
            })
        }
        ExprKind::Assign { place: p, op, value } => {
            if let PlaceBase::Global(g) = p.base {
                reads[g.0 as usize] |= op.is_some() || p.index.is_some() || p.component.is_some();
                assigned[g.0 as usize] = true;
            }
            expr_reads(f, *value, reads, assigned) && place(p, reads, assigned)
        }
        ExprKind::Const(_) | ExprKind::Var(_) => true,
        ExprKind::Index { base, index } => {
            expr_reads(f, *base, reads, assigned) && expr_reads(f, *index, reads, assigned)
        }
        ExprKind::Unary { arg, .. } | ExprKind::Convert { arg } => expr_reads(f, *arg, reads, assigned),
        ExprKind::Binary { lhs, rhs, .. } => {
            expr_reads(f, *lhs, reads, assigned) && expr_reads(f, *rhs, reads, assigned)
        }
        ExprKind::Construct { args } | ExprKind::ArrayLiteral { elements: args } => {
            args.iter().all(|a| expr_reads(f, *a, reads, assigned))
        }
        ExprKind::SpaceCast { space, arg } => {
            expr_reads(f, *space, reads, assigned) && expr_reads(f, *arg, reads, assigned)
        }
        ExprKind::Select { cond, a, b } => {
            expr_reads(f, *cond, reads, assigned)
                && expr_reads(f, *a, reads, assigned)
                && expr_reads(f, *b, reads, assigned)
        }
    }
}

/// Marks `L`, `Cl`, `Ol` (illuminance: set per light and restored), `L` and `Ps` (illuminate, solar)
/// as used, and the globals those statements set as written.
fn light_globals(blk: &crate::ir::Block, used: &mut [bool], written: &mut [bool]) {
    use crate::ir::StmtKind;
    fn mark(names: &[&str], write: bool, used: &mut [bool], written: &mut [bool]) {
        for name in names {
            if let Some(g) = Global::lookup(name) {
                used[g.0 as usize] = true;
                written[g.0 as usize] |= write;
            }
        }
    }
    for s in &blk.stmts {
        match &s.kind {
            StmtKind::If { then, otherwise, .. } => {
                light_globals(then, used, written);
                light_globals(otherwise, used, written);
            }
            StmtKind::Loop { body, step, .. } => {
                light_globals(body, used, written);
                light_globals(step, used, written);
            }
            StmtKind::Illuminance { body, .. } => {
                mark(&["L", "Cl", "Ol"], false, used, written);
                light_globals(body, used, written);
            }
            StmtKind::Illuminate { body, .. } => {
                mark(&["Ps"], false, used, written);
                mark(&["L"], true, used, written);
                light_globals(body, used, written);
            }
            StmtKind::Solar { cone, body } => {
                if cone.is_some() {
                    mark(&["L"], true, used, written);
                }
                light_globals(body, used, written);
            }
            StmtKind::Gather { body, otherwise, .. } => {
                light_globals(body, used, written);
                light_globals(otherwise, used, written);
            }
            _ => {}
        }
    }
}

//! IR to Cranelift: the chunk loop, the shader body with every user function inlined, masks.
//!
//! Invariants:
//! - **Shapes**: a value is uniform (scalars: `f32`, bools `i8`) or varying (`f32x4`, masks
//!   `i32x4`), decided from its operands, so uniform IR stays scalar and is splatted only where it
//!   meets a varying value. Storage (variables, globals, parameters) has a fixed shape: a variable
//!   the IR marks varying is `f32x4` per component; a uniform one is `f32`.
//! - **exec**: the Cranelift variable `exec` (an `i32x4`) holds the lanes running the current
//!   statement; every store to varying storage is `bitselect(exec [& index], new, old)`.
//! - **Control flow**: a uniform condition branches. A varying `if` runs each side under
//!   `exec & cond` / `exec & !cond`, skipping a side no lane takes (`vany_true`). Every loop keeps an
//!   exit accumulator and a continue accumulator; `break n`/`continue n`/`return` move the running
//!   lanes into the target's accumulator and clear `exec`. When no varying condition lies between
//!   the statement and its target (`vdepth` equal), every running lane leaves together and the code
//!   also jumps. Statements after `break`/`continue`/`return` in a block are dead and not lowered.
//! - **Uniform storage under divergence**: a uniform variable is written unmasked, so a write is
//!   allowed only when no divergence (`div`) was entered since the variable was created; otherwise
//!   the shader is `Unsupported` (valid IR never needs it: the checker makes such variables varying).
//! - **Calls** are inlined with the interpreter's copy-in/copy-out semantics: arguments to output
//!   and captured parameters are read when the call starts and written back (under the call's
//!   `exec`) when it returns; place indices are evaluated once.
//! - **Uniform mode**: a call whose callee reads no varying state and whose arguments are all
//!   uniform is lowered with uniform locals and uniform control flow (`Frame::uniform`), whatever the
//!   checker inferred for the callee's locals in general; its result can then reach uniform storage.
//! - **Strings** are `f32`s holding a handle's bits, uniform or varying like floats (handles are
//!   interned per batch: `==` is an integer compare); a built-in given a varying string runs once
//!   per distinct string (`split_strings`); **matrices** 16 components, row-major, identity when uninitialised; matrix
//!   products, inverses and everything from the renderer go through chunk helpers (`math.rs`,
//!   `host.rs`), one call per chunk.
//! - **Light loops**: see `illuminance`; `illuminate` masks by its cone, `solar` sets `L`.
//! - **`random()`** draws from the lane's seed (two varying slots, `Layout::seed`) and the lane's
//!   call count (`random_calls`, an `i32x4` counting the calls each lane ran in this chunk, bumped
//!   under `exec`): the interpreter's `seed * 0x9E3779B97F4A7C15 + calls`, so they agree lane for
//!   lane wherever the call sits.
//! - **`gather`**: see `gather`; sample rays come from `shadeops::gather`, as in the interpreter.
//! - **`spline`**: the host helper `rtsl_h_spline` returns each lane's segment and weights; knots
//!   are selected and summed inline (see `spline`). **String built-ins** (`concat`, `match`,
//!   `format`) are host-helper calls reading each running lane's strings, whose string results are
//!   interned in the batch's table (one per lane when varying); `printf` calls `rtsl_h_printf` once per chunk, which formats and prints each
//!   running lane's text (`format`/`printf` pass a header of argument kinds: `host::format_lane`).
//! - **Derivatives** (`deriv.rs`): the values `ir::deriv` marks are lowered as duals, a value and
//!   two tangents (`f32x4` per component, always varying; `None` is zero); marked varying storage
//!   has two tangent stores beside it (`Frame::dvars`, `Lower::dglobals`), written under the same
//!   masks as the value. Every other write to such storage (a built-in's output, a light loop's
//!   globals) zeroes its tangents.
//! - Unsupported here: `gather` options named by computed strings, a category of `gather` or
//!   `illuminance` that varies, `bump`, point clouds, and built-ins not handled in `builtin` or
//!   `builtin_ext`.

use super::batch::{OFF_BOUND, OFF_CHUNK, OFF_DERIVS, OFF_MASK, OFF_STRIDE, OFF_UNIFORM, OFF_VARYING};
use super::hoist::Prefix;
use super::host;
use super::layout::{components, Layout};
use super::mask::{self, and, any, choose, fconst, is_vec, konst, merge, not, or, to_mask, widen};
use super::math;
use super::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::globals::{Global, GLOBALS};
use crate::ir::{
    self, Arg, BaseType, BinaryOp, Constant, ExprId, ExprKind, FuncId, Function, Module, Place, PlaceBase, StmtKind,
    Type, UnaryOp, VarKind,
};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{
    types, AbiParam, Block, FuncRef, InstBuilder, MemFlagsData, StackSlotData, StackSlotKind, Value,
};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_jit::JITModule;
use cranelift_module::{Linkage, Module as _};
use std::collections::HashMap;

#[path = "deriv.rs"]
mod deriv;

pub(super) use deriv::Dual;

type R<T> = Result<T, JitError>;

/// A value: its components (one for floats and bools, three for triples, `len * comps` for arrays).
#[derive(Clone, Debug)]
struct Val {
    vary: bool,
    c: Vec<Value>,
}

/// Storage of a variable, global or parameter: one Cranelift variable per float.
#[derive(Clone, Debug)]
struct Store {
    vary: bool,
    vars: Vec<Variable>,
    comps: usize,
    /// `div` when the storage was created: uniform writes need the same level.
    div: u32,
    /// Storage whose lanes outside the chunk's mask are never observed, so that a write outside
    /// varying control flow, where every lane of the mask runs, need not keep them: a global that
    /// a chunk starts as zeros and blends with the batch under the chunk's mask at its end (see
    /// `load_globals`), or a local of the shader body.
    fresh: bool,
}

#[derive(Clone, Copy)]
struct LoopCx {
    exit_acc: Variable,
    cont_acc: Variable,
    exit: Block,
    cont: Block,
    depth: u32,
}

struct Frame<'m> {
    fid: FuncId,
    f: &'m Function,
    vars: Vec<Option<Store>>,
    /// Tangent stores (d/dx, d/dy) of the varying variables `ir::deriv` marks.
    dvars: Vec<Option<[Store; 2]>>,
    ret: Option<Store>,
    /// Tangent stores of the result, when the result is differentiated.
    dret: Option<[Store; 2]>,
    ret_block: Block,
    depth: u32,
    loops: Vec<LoopCx>,
    /// Lowered in uniform mode (see `call`): every local is uniform storage and the IR's varying
    /// flags, which describe the general case, are ignored in favour of the actual shapes.
    uniform: bool,
}

/// An array element or triple component, known at compile time or computed per lane.
#[derive(Clone, Copy)]
enum Idx {
    Const(usize),
    /// A float holding an integer in range (uniform or varying).
    Dyn(Value),
}

/// The storage positions a place covers: (flat position, component of the value, condition).
struct Targets {
    base: PlaceBase,
    list: Vec<(usize, usize, Option<Value>)>,
    comps: usize,
}

/// Runtime checks reported through `rtsl_h_runtime_error` (see `CompiledShader::runtime_errors`).
pub(super) const RUNTIME_LOOP_BUDGET: u32 = 0;
pub(super) const RUNTIME_INDEX: u32 = 1;
pub(super) const RUNTIME_UNSUPPORTED: u32 = 2;

fn mem() -> MemFlagsData {
    MemFlagsData::trusted()
}

/// Memory that nothing writes while the shader runs: loads from it are pure.
fn readonly() -> MemFlagsData {
    MemFlagsData::trusted().with_readonly().with_can_move()
}

struct Lower<'m, 'b> {
    m: &'m Module,
    layout: &'m Layout,
    b: FunctionBuilder<'b>,
    jit: &'m mut JITModule,
    helpers: HashMap<&'static str, FuncRef>,
    /// The helpers called through a register-preserving trampoline (see `call_helper_keeping_registers`):
    /// each trampoline's id in the module and the helper it calls, for `define` to compile.
    trampolines: Vec<(cranelift_module::FuncId, &'static str)>,
    /// Host helper calls emitted so far (they read the batch's current chunk).
    host_calls: usize,
    exec: Variable,
    vdepth: u32,
    div: u32,
    frames: Vec<Frame<'m>>,
    globals: Vec<Option<Store>>,
    ptr: types::Type,
    chunk_base: Option<Value>,
    stride_bytes: Option<Value>,
    uniform: Option<Value>,
    fn_div: HashMap<u32, bool>,
    /// The batch record (the entry's argument), passed to host helpers.
    batch: Option<Value>,
    /// The string constants, by handle (`""` is handle 0, so zeroed storage is the empty string).
    strings: Vec<String>,
    /// Per lane, how many `random()` calls it has run in this chunk (`i32x4`, zero at its start):
    /// the interpreter's `random_calls`.
    random_calls: Variable,
    /// Which values are duals (`ir::deriv`).
    info: ir::deriv::DerivInfo,
    /// Tangent stores of the globals that keep tangents.
    dglobals: Vec<Option<[Store; 2]>>,
    /// Argument values a built-in call evaluated as duals before lowering the call: `expr` returns
    /// them instead of evaluating again (key: frame depth, expression).
    cache: HashMap<(usize, u32), Val>,
    /// The `cache` entries `split_strings` added (removed when its built-in call is lowered).
    split_keys: Vec<(usize, u32)>,
    /// Expressions of the shader body that the prologue evaluated (`hoist::Prefix::consts`): their
    /// values, defined before the chunk loop.
    batch_consts: HashMap<u32, Val>,
    /// The matrices (and whether the space is known) of the space-name expressions the prologue
    /// looked up (`hoist::Prefix::spaces`).
    batch_matrices: HashMap<u32, (Val, Value)>,
    /// While the prologue evaluates the batch constants and the casts' matrices: the matrices
    /// looked up so far, by the bits of their two constant space names (see `prologue`).
    prologue_matrices: Option<Vec<((u32, u32), SpaceMatrix)>>,
    /// The arguments (as duals) of the built-in call being lowered by `builtin_dual`.
    arg_duals: Vec<Option<Dual>>,
    /// The `rtsl_sincos` results of a value (sin, cos) and the block whose call made them: a
    /// `sin` or `cos` of the same value later in that block reuses them.
    sincos_results: HashMap<Value, (Option<Block>, [Value; 2])>,
    /// The enclosing `illuminance` loops, innermost last: their light set (from `rtsl_h_lights`)
    /// and iteration counter, for `lightsource()` in their bodies.
    light_loops: Vec<(Value, Variable)>,
    /// The renderer's derivatives for this chunk (`Batch::derivs + 16 * chunk`; null base: zeros).
    derivs_base: Option<Value>,
    derivs_null: Option<Value>,
    /// The most loop iterations one invocation (a chunk) may run, all loops together.
    loop_budget: u32,
    /// The loop iterations the current chunk has run so far (`I32`): one counter for every loop,
    /// so that nested loops cannot multiply the budget.
    loop_count: Variable,
    /// Where each runtime check sits (`file:line:col`, or a byte offset without sources).
    sites: Vec<String>,
    site_ids: HashMap<crate::source::Span, usize>,
    sources: Option<&'m crate::source::SourceMap>,
    /// The entry block and the chunk loop's blocks: its fixed ones, and every block numbered
    /// from the second value on (those lowered for the chunk's body), for `invariants.rs`.
    loop_blocks: Option<(Block, Vec<Block>, usize)>,
}

/// Lowers the module's shader into `func` (signature `fn(*mut Batch)`); returns the number of
/// Cranelift instructions emitted and the string constants (handles `0..n`).
/// What lowering produced besides the function.
pub(super) struct Lowered {
    pub insts: usize,
    pub strings: Vec<String>,
    pub sites: Vec<String>,
    /// The entry block and the chunk loop's blocks (see `Lower::loop_blocks`).
    pub loop_blocks: Option<(Block, Vec<Block>, usize)>,
    /// The register-preserving trampolines the code calls, to define in the module (see
    /// `super::define_trampoline`): each one's id and the helper it calls.
    pub trampolines: Vec<(cranelift_module::FuncId, &'static str)>,
    /// The names of the helpers the code calls, directly or through a trampoline (a name may
    /// come twice).
    pub helpers: Vec<&'static str>,
}

pub(super) fn lower(
    m: &Module,
    layout: &Layout,
    jit: &mut JITModule,
    func: &mut cranelift_codegen::ir::Function,
    options: &super::JitOptions,
    sources: Option<&crate::source::SourceMap>,
) -> R<Lowered> {
    let mut fctx = FunctionBuilderContext::new();
    let config = jit.target_config();
    let ptr = config.pointer_type();
    let mut b = FunctionBuilder::new(func, &mut fctx);
    let exec = b.declare_var(types::I32X4);
    let random_calls = b.declare_var(types::I32X4);
    let loop_count = b.declare_var(types::I32);
    let mut l = Lower {
        m,
        layout,
        b,
        jit,
        helpers: HashMap::new(),
        trampolines: Vec::new(),
        host_calls: 0,
        exec,
        vdepth: 0,
        div: 0,
        frames: Vec::new(),
        globals: vec![None; GLOBALS.len()],
        ptr,
        chunk_base: None,
        stride_bytes: None,
        uniform: None,
        fn_div: HashMap::new(),
        batch: None,
        strings: vec![String::new()],
        random_calls,
        info: ir::deriv::analyse(m),
        dglobals: vec![None; GLOBALS.len()],
        cache: HashMap::new(),
        split_keys: Vec::new(),
        batch_consts: HashMap::new(),
        batch_matrices: HashMap::new(),
        prologue_matrices: None,
        arg_duals: Vec::new(),
        sincos_results: HashMap::new(),
        light_loops: Vec::new(),
        derivs_base: None,
        derivs_null: None,
        loop_budget: options.loop_budget.max(1),
        loop_count,
        sites: Vec::new(),
        site_ids: HashMap::new(),
        sources,
        loop_blocks: None,
    };
    l.shade()?;
    l.b.seal_all_blocks();
    let n = l.b.func.dfg.num_insts();
    let strings = std::mem::take(&mut l.strings);
    let sites = std::mem::take(&mut l.sites);
    let loop_blocks = l.loop_blocks.take();
    let trampolines = std::mem::take(&mut l.trampolines);
    let helpers: Vec<&'static str> = l.helpers.keys().chain(trampolines.iter().map(|(_, h)| h)).copied().collect();
    l.b.finalize(config);
    Ok(Lowered { insts: n, strings, sites, loop_blocks, trampolines, helpers })
}

/// A space's matrix (uniform, 16 entries) and whether the lookup found the space (a uniform bool).
type SpaceMatrix = (Val, Value);

/// The bits of a scalar `f32` constant (a string handle is one), if `v` is one.
fn constant_bits(b: &FunctionBuilder<'_>, v: Value) -> Option<u32> {
    use cranelift_codegen::ir::{InstructionData, Opcode, ValueDef};
    let dfg = &b.func.dfg;
    match dfg.value_def(dfg.resolve_aliases(v)) {
        ValueDef::Result(def, _) => match dfg.insts[def] {
            InstructionData::UnaryIeee32 { opcode: Opcode::F32const, imm } => Some(imm.bits()),
            _ => None,
        },
        _ => None,
    }
}

/// The interpreter's `index_of` on a constant.
fn const_index(x: f32, n: usize) -> usize {
    if !x.is_finite() || x < 0.0 || n == 0 {
        0
    } else {
        (x as usize).min(n - 1)
    }
}

impl<'m> Lower<'m, '_> {
    fn frame(&self) -> &Frame<'m> {
        self.frames.last().expect("a frame")
    }

    fn func(&self) -> &'m Function {
        self.frame().f
    }

    fn exec(&mut self) -> Value {
        self.b.use_var(self.exec)
    }

    fn set_exec(&mut self, v: Value) {
        self.b.def_var(self.exec, v);
    }

    fn new_store(&mut self, vary: bool, n: usize, comps: usize) -> Store {
        let ty = if vary { types::F32X4 } else { types::F32 };
        let vars = (0..n).map(|_| self.b.declare_var(ty)).collect();
        Store { vary, vars, comps, div: self.div, fresh: false }
    }

    fn zero_store(&mut self, vary: bool, n: usize, comps: usize) -> Store {
        let s = self.new_store(vary, n, comps);
        let z = fconst(&mut self.b, 0.0, vary);
        for v in &s.vars {
            self.b.def_var(*v, z);
        }
        s
    }

    fn read_store(&mut self, s: &Store) -> Val {
        Val { vary: s.vary, c: s.vars.iter().map(|v| self.b.use_var(*v)).collect() }
    }

    /// Initialises storage (no mask: the storage is fresh or being loaded).
    fn init_store(&mut self, s: &Store, v: &Val) -> R<()> {
        if v.vary && !s.vary {
            return unsupported("a varying value stored in uniform storage");
        }
        if v.c.len() != s.vars.len() {
            return unsupported("a value of unexpected size");
        }
        for (var, x) in s.vars.iter().zip(&v.c) {
            let x = widen(&mut self.b, *x, s.vary);
            self.b.def_var(*var, x);
        }
        Ok(())
    }

    fn addr(&mut self, slot: usize) -> Value {
        let (base, sb) = (self.chunk_base.expect("chunk"), self.stride_bytes.expect("chunk"));
        if slot == 0 {
            return base;
        }
        let off = self.b.ins().imul_imm_s(sb, slot as i64);
        self.b.ins().iadd(base, off)
    }

    fn load_slot(&mut self, vary: bool, offset: usize) -> Value {
        self.load_slot_with(vary, offset, mem())
    }

    fn load_slot_with(&mut self, vary: bool, offset: usize, flags: MemFlagsData) -> Value {
        if vary {
            let a = self.addr(offset);
            self.b.ins().load(types::F32X4, flags, a, 0)
        } else {
            let u = self.uniform.expect("chunk");
            self.b.ins().load(types::F32, flags, u, (offset * 4) as i32)
        }
    }

    fn store_slot(&mut self, vary: bool, offset: usize, v: Value) {
        if vary {
            let a = self.addr(offset);
            self.b.ins().store(mem(), v, a, 0);
        } else {
            let u = self.uniform.expect("chunk");
            self.b.ins().store(mem(), v, u, (offset * 4) as i32);
        }
    }

    // ---- The function: chunk loop, prologue, epilogue ----

    fn shade(&mut self) -> R<()> {
        let shader = self.m.shader.as_ref().ok_or(JitError::NoShader)?;
        let entry = self.b.create_block();
        self.b.append_block_params_for_function_params(entry);
        self.b.switch_to_block(entry);
        let batch = self.b.block_params(entry)[0];
        self.batch = Some(batch);
        let stride32 = self.b.ins().load(types::I32, mem(), batch, OFF_STRIDE);
        let stride = self.b.ins().uextend(self.ptr, stride32);
        let mask_p = self.b.ins().load(self.ptr, mem(), batch, OFF_MASK);
        let varying_p = self.b.ins().load(self.ptr, mem(), batch, OFF_VARYING);
        let uniform_p = self.b.ins().load(self.ptr, mem(), batch, OFF_UNIFORM);
        let bound_p = self.b.ins().load(self.ptr, mem(), batch, OFF_BOUND);
        // Shaders that differentiate nothing never touch `derivs` (no extra instruction).
        let derivs_p = if self.info.any || self.info.globals.iter().any(|g| *g) {
            let p = self.b.ins().load(self.ptr, mem(), batch, OFF_DERIVS);
            self.derivs_null = Some(self.b.ins().icmp_imm_u(IntCC::Equal, p, 0));
            Some(p)
        } else {
            None
        };
        let nchunks = self.b.ins().ushr_imm_u(stride, 2);
        let stride_bytes = self.b.ins().ishl_imm_u(stride, 2);
        let counter = self.b.declare_var(self.ptr);
        let zero = self.b.ins().iconst(self.ptr, 0);
        self.b.def_var(counter, zero);
        let (header, body, run, next, exit) = (
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
        );
        let prefix = super::hoist::uniform_prefix(self.m, shader, self.layout);
        let zero32 = self.b.ins().iconst(types::I32, 0);
        self.b.def_var(self.loop_count, zero32);
        // The prologue's loop iterations count for every chunk, as if each chunk had run them.
        let mut prologue_loops = None;
        let hoisted = if prefix.any() {
            // The prologue runs when the batch has a chunk, with chunk 0's buffers: it reads nothing
            // varying (`hoist.rs`), and whatever it lowers stays within the batch.
            let prologue = self.b.create_block();
            let some = self.b.ins().icmp_imm_u(IntCC::NotEqual, nchunks, 0);
            self.b.ins().brif(some, prologue, &[], exit, &[]);
            self.b.switch_to_block(prologue);
            self.chunk_base = Some(varying_p);
            self.derivs_base = derivs_p;
            self.stride_bytes = Some(stride_bytes);
            self.uniform = Some(uniform_p);
            let ones = self.b.ins().iconst(types::I32, -1);
            let all = self.b.ins().splat(types::I32X4, ones);
            self.set_exec(all);
            let z = mask::zero_mask(&mut self.b);
            self.b.def_var(self.random_calls, z);
            let vars = self.prologue(shader, bound_p, &prefix)?;
            prologue_loops = Some(self.b.use_var(self.loop_count));
            self.cache.clear();
            Some((vars, prefix))
        } else {
            None
        };
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let c = self.b.use_var(counter);
        let more = self.b.ins().icmp(IntCC::UnsignedLessThan, c, nchunks);
        self.b.ins().brif(more, body, &[], exit, &[]);
        self.b.switch_to_block(body);
        let off = self.b.ins().ishl_imm_u(c, 4);
        let mp = self.b.ins().iadd(mask_p, off);
        let chunk_mask = self.b.ins().load(types::I32X4, mem(), mp, 0);
        let live = any(&mut self.b, chunk_mask);
        self.b.ins().brif(live, run, &[], next, &[]);
        self.b.switch_to_block(run);
        let c32 = if self.ptr == types::I32 { c } else { self.b.ins().ireduce(types::I32, c) };
        // Only host helpers read the chunk: without one in the chunk's code the store goes again.
        let chunk_store = self.b.ins().store(mem(), c32, batch, OFF_CHUNK);
        let host_calls_before = self.host_calls;
        self.chunk_base = Some(self.b.ins().iadd(varying_p, off));
        self.derivs_base = derivs_p.map(|p| self.b.ins().iadd(p, off));
        self.stride_bytes = Some(stride_bytes);
        self.uniform = Some(uniform_p);
        self.set_exec(chunk_mask);
        let z = mask::zero_mask(&mut self.b);
        self.b.def_var(self.random_calls, z);
        let loops_at_start = match prologue_loops {
            Some(v) => v,
            None => self.b.ins().iconst(types::I32, 0),
        };
        self.b.def_var(self.loop_count, loops_at_start);
        let first_chunk_block = self.b.func.dfg.num_blocks();
        self.loop_blocks = Some((entry, vec![header, body, run, next], first_chunk_block));
        self.chunk(shader, bound_p, hoisted.as_ref())?;
        if self.host_calls == host_calls_before {
            self.b.func.layout.remove_inst(chunk_store);
        }
        self.b.ins().jump(next, &[]);
        self.b.switch_to_block(next);
        let c = self.b.use_var(counter);
        let c1 = self.b.ins().iadd_imm_u(c, 1);
        self.b.def_var(counter, c1);
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        self.b.ins().return_(&[]);
        Ok(())
    }

    /// Loads the globals of the current chunk (set up by the caller) into their stores. With
    /// `fresh_outputs`, the varying globals whose value on entry the body never reads
    /// ([`fresh_output`]) start as zeros instead: the chunk's end blends them with the batch's
    /// values under the chunk's mask, so their inactive lanes keep their bits all the same, and the
    /// old values need not live (in registers or spilled) through the whole chunk.
    fn load_globals(&mut self, fresh_outputs: bool) -> R<()> {
        for gs in self.layout.globals.clone() {
            let mut s = self.new_store(gs.varying, gs.components, gs.components);
            let zero = (fresh_outputs && fresh_output(&gs)).then(|| fconst(&mut self.b, 0.0, true));
            s.fresh = zero.is_some();
            for (k, var) in s.vars.iter().enumerate() {
                let v = match zero {
                    Some(z) => z,
                    // A global the shader never writes is read-only memory while it runs (no
                    // helper writes the batch's globals): its load is pure, so the optimiser drops
                    // it where nothing uses it and places it at its first use, not at the chunk's
                    // start with the value alive (or spilled) until then.
                    None if !gs.written => self.load_slot_with(gs.varying, gs.offset + k, readonly()),
                    None => self.load_slot(gs.varying, gs.offset + k),
                };
                self.b.def_var(*var, v);
            }
            self.globals[gs.global.0 as usize] = Some(s);
        }
        self.load_global_derivs()
    }

    /// Sets shader parameter `i` in the current frame: its bound value, or its default.
    fn load_param(&mut self, i: usize, p: &'m ir::ShaderParam, bound_p: Value) -> R<()> {
        let slot = self.layout.params[i].clone();
        let store = self.frame().vars[p.var.0 as usize]
            .clone()
            .ok_or_else(|| JitError::Unsupported(format!("parameter {} of type {}", p.name, p.ty)))?;
        let flag = self.b.ins().load(types::I32, mem(), bound_p, (4 * i) as i32);
        let (load_b, default_b, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().brif(flag, load_b, &[], default_b, &[]);
        self.b.switch_to_block(load_b);
        for (k, var) in store.vars.iter().enumerate() {
            let v = self.load_slot(slot.varying, slot.offset + k);
            self.b.def_var(*var, v);
        }
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(default_b);
        if store.vary {
            // Inactive lanes keep what the batch holds (an output is stored back).
            for (k, var) in store.vars.iter().enumerate() {
                let v = self.load_slot(true, slot.offset + k);
                self.b.def_var(*var, v);
            }
        }
        let v = self.dual(p.default)?;
        self.write_store(&store, &v.v)?;
        if let Some(ds) = self.frame().dvars[p.var.0 as usize].clone() {
            self.write_tangents(&ds, &v)?;
        }
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(())
    }

    /// The once-per-batch prologue (`hoist.rs`): the uniform parameters and the body's hoisted
    /// statements in a frame of their own; returns, by variable, the values it left in the
    /// variables it wrote, for each chunk's frame to start from.
    fn prologue(&mut self, shader: &'m ir::Shader, bound_p: Value, prefix: &Prefix) -> R<Vec<Option<Vec<Value>>>> {
        self.load_globals(false)?;
        let body = self.m.function(shader.body);
        let frame = self.new_frame(shader.body, body, &[], &[], false)?;
        self.frames.push(frame);
        for (i, p) in shader.params.iter().enumerate() {
            if prefix.writes.contains(&p.var) {
                self.load_param(i, p, bound_p)?;
            }
        }
        for s in &body.body.stmts[..prefix.len] {
            if self.stmt(s)? {
                return Err(JitError::Codegen("a hoisted statement left the body".into()));
            }
        }
        // The batch constants and the casts' matrices look each pair of space names up once (a
        // constant `point "camera" (0, 0, 0)` and a cast of a varying vector to "camera" share
        // one): straight-line code, so a lookup dominates every later one it stands for.
        self.prologue_matrices = Some(Vec::new());
        for id in &prefix.consts {
            let v = self.expr(*id)?;
            if !v.vary {
                self.batch_consts.insert(id.0, v);
            }
        }
        for id in &prefix.spaces {
            let sp = self.expr(*id)?;
            if !sp.vary {
                let current = self.const_string("current");
                let m = self.space_matrix(&sp, &current)?;
                self.batch_matrices.insert(id.0, m);
            }
        }
        self.prologue_matrices = None;
        let frame = self.frames.pop().expect("frame");
        // The values the prologue leaves, read here, before the chunk loop: read inside it, each
        // would become a loop-carried block parameter of the loop's header.
        let mut values = vec![None; frame.vars.len()];
        for v in &prefix.writes {
            if let Some(store) = &frame.vars[v.0 as usize] {
                values[v.0 as usize] = Some(store.vars.iter().map(|var| self.b.use_var(*var)).collect());
            }
        }
        Ok(values)
    }

    /// One chunk: load globals and parameters (or take the prologue's), run the rest of the body,
    /// store results.
    fn chunk(
        &mut self,
        shader: &'m ir::Shader,
        bound_p: Value,
        hoisted: Option<&(Vec<Option<Vec<Value>>>, Prefix)>,
    ) -> R<()> {
        self.load_globals(true)?;
        let body = self.m.function(shader.body);
        let frame = self.new_frame(shader.body, body, &[], &[], false)?;
        self.frames.push(frame);
        let saved = self.exec();
        // A fresh frame with the prologue's results copied in: the state this chunk would have
        // reached by running the hoisted statements itself.
        let copied: &[ir::VarId] = match hoisted {
            Some((vars, prefix)) => {
                for v in &prefix.writes {
                    let from = vars[v.0 as usize].clone();
                    let to = self.frame().vars[v.0 as usize].clone();
                    let (Some(from), Some(to)) = (from, to) else {
                        return Err(JitError::Codegen("a hoisted variable without storage".into()));
                    };
                    for (x, b) in from.iter().zip(&to.vars) {
                        self.b.def_var(*b, *x);
                    }
                }
                &prefix.writes
            }
            None => &[],
        };
        for (i, p) in shader.params.iter().enumerate() {
            if !copied.contains(&p.var) {
                self.load_param(i, p, bound_p)?;
            }
        }
        let ret_block = self.frame().ret_block;
        let skip = hoisted.map_or(0, |(_, prefix)| prefix.len);
        for s in &body.body.stmts[skip..] {
            if self.stmt(s)? {
                break;
            }
        }
        self.b.ins().jump(ret_block, &[]);
        self.b.switch_to_block(ret_block);
        self.set_exec(saved);
        let frame = self.frames.pop().expect("frame");
        let globals = self.layout.globals.clone();
        let written = |gs: &&super::layout::GlobalSlot| gs.written && gs.varying;
        // The fresh outputs' inactive lanes come from the batch: a blend under the chunk's mask,
        // or, in a chunk whose lanes all ran (nearly every chunk), plain stores.
        if globals.iter().filter(written).any(fresh_output) {
            let (whole, partial, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
            let all = self.b.ins().vall_true(saved);
            self.b.ins().brif(all, whole, &[], partial, &[]);
            for (block, blend) in [(whole, false), (partial, true)] {
                self.b.switch_to_block(block);
                for gs in globals.iter().filter(written).filter(|gs| fresh_output(gs)) {
                    let s = self.globals[gs.global.0 as usize].clone().expect("loaded");
                    for (k, var) in s.vars.iter().enumerate() {
                        let mut v = self.b.use_var(*var);
                        if blend {
                            let old = self.load_slot(true, gs.offset + k);
                            v = merge(&mut self.b, saved, v, old);
                        }
                        self.store_slot(true, gs.offset + k, v);
                    }
                }
                self.b.ins().jump(join, &[]);
            }
            self.b.switch_to_block(join);
        }
        for gs in globals.iter().filter(written).filter(|gs| !fresh_output(gs)) {
            let s = self.globals[gs.global.0 as usize].clone().expect("loaded");
            for (k, var) in s.vars.iter().enumerate() {
                let v = self.b.use_var(*var);
                self.store_slot(true, gs.offset + k, v);
            }
        }
        for (i, p) in shader.params.iter().enumerate() {
            if !p.output {
                continue;
            }
            let slot = self.layout.params[i].clone();
            let s = frame.vars[p.var.0 as usize].clone().expect("parameter storage");
            for (k, var) in s.vars.iter().enumerate() {
                let v = self.b.use_var(*var);
                self.store_slot(slot.varying, slot.offset + k, v);
            }
        }
        Ok(())
    }

    /// A frame for `f` with zeroed locals and parameters initialised from `args` (copy-in).
    fn new_frame(
        &mut self,
        fid: FuncId,
        f: &'m Function,
        args: &[(Val, Option<bool>)],
        dargs: &[Option<[Vec<Value>; 2]>],
        uniform: bool,
    ) -> R<Frame<'m>> {
        let mut vars = Vec::with_capacity(f.vars.len());
        let mut dvars = Vec::with_capacity(f.vars.len());
        for (i, var) in f.vars.iter().enumerate() {
            let comps = match components(var.ty) {
                Some(c) => c,
                None => {
                    vars.push(None);
                    continue;
                }
            };
            let param = f.params.iter().position(|p| p.0 as usize == i);
            while dvars.len() < vars.len() {
                dvars.push(None);
            }
            let store = match (var.kind, param) {
                (VarKind::ShaderParam { index, .. }, _) => {
                    let slot = &self.layout.params[index as usize];
                    self.zero_store(slot.varying, slot.floats(), comps)
                }
                (_, Some(k)) => {
                    let (v, by_ref) =
                        args.get(k).cloned().ok_or_else(|| JitError::Codegen("missing argument".into()))?;
                    // Specialised per call: a parameter the callee never assigns takes the
                    // argument's shape, so uniform arguments keep uniform code in the callee.
                    let vary = by_ref.unwrap_or(v.vary || (var.varying && assigned(f, i) && !uniform));
                    let s = self.new_store(vary, v.c.len(), comps);
                    self.init_store(&s, &v)?;
                    s
                }
                _ => {
                    let n = match var.ty.array {
                        None => 1,
                        Some(_) => match var.ty.array_len() {
                            Some(n) => n as usize,
                            None => return unsupported("an unsized array local"),
                        },
                    };
                    let vary = var.varying && !uniform;
                    let mut s = self.zero_store(vary, n * comps, comps);
                    // The shader body's locals: a lane outside the chunk's mask never shows what
                    // they hold (outputs and globals merge under that mask), so writes outside
                    // varying control flow need no merge either.
                    s.fresh = self.frames.is_empty();
                    if var.ty.base == BaseType::Matrix {
                        // An uninitialised matrix is the identity (the interpreter's zero value).
                        let one = fconst(&mut self.b, 1.0, vary);
                        for (k, v) in s.vars.iter().enumerate() {
                            if (k % 16) % 5 == 0 {
                                self.b.def_var(*v, one);
                            }
                        }
                    }
                    s
                }
            };
            if var.ty.base == BaseType::String && store.vary && matches!(var.kind, VarKind::ShaderParam { .. }) {
                return unsupported("a varying string parameter");
            }
            let d = if store.vary && self.info.var(fid, ir::VarId(i as u32)) {
                let n = store.vars.len();
                let pair = [self.zero_store(true, n, store.comps), self.zero_store(true, n, store.comps)];
                if let Some(Some(t)) = param.and_then(|k| dargs.get(k)) {
                    for (s, tc) in pair.iter().zip(t) {
                        self.init_store(s, &Val { vary: true, c: tc.clone() })?;
                    }
                }
                Some(pair)
            } else {
                None
            };
            vars.push(Some(store));
            dvars.push(d);
        }
        while dvars.len() < vars.len() {
            dvars.push(None);
        }
        let ret_block = self.b.create_block();
        Ok(Frame {
            fid,
            f,
            vars,
            dvars,
            ret: None,
            dret: None,
            ret_block,
            depth: self.vdepth,
            loops: Vec::new(),
            uniform,
        })
    }

    // ---- Statements ----

    /// Lowers a block; returns early after a statement that leaves it.
    fn block(&mut self, blk: &'m ir::Block) -> R<()> {
        for s in &blk.stmts {
            if self.stmt(s)? {
                break;
            }
        }
        Ok(())
    }

    /// After a jump: continue in a fresh, unreachable block.
    fn jump_away(&mut self, target: Block) {
        self.b.ins().jump(target, &[]);
        let dead = self.b.create_block();
        self.b.switch_to_block(dead);
    }

    /// Lowers one statement; true when it leaves the block (break, continue, return).
    fn stmt(&mut self, s: &'m ir::Stmt) -> R<bool> {
        let f = self.func();
        match &s.kind {
            StmtKind::Expr(e) => {
                self.expr(*e)?;
            }
            StmtKind::If { cond, then, otherwise } => {
                let c = self.expr(*cond)?;
                if !c.vary {
                    let (tb, eb, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
                    self.b.ins().brif(c.c[0], tb, &[], eb, &[]);
                    self.b.switch_to_block(tb);
                    self.block(then)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(eb);
                    self.block(otherwise)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(join);
                } else {
                    let cm = to_mask(&mut self.b, c.c[0]);
                    let save = self.exec();
                    self.vdepth += 1;
                    self.div += 1;
                    let tm = self.b.ins().band(save, cm);
                    let t = self.masked_block(tm, then)?;
                    let em = self.b.ins().band_not(save, cm);
                    let e = if otherwise.stmts.is_empty() { em } else { self.masked_block(em, otherwise)? };
                    let all = self.b.ins().bor(t, e);
                    self.set_exec(all);
                    self.vdepth -= 1;
                    self.div -= 1;
                }
            }
            StmtKind::Loop { cond, body, step } => {
                let uniform = self.frame().uniform;
                let vary_cond = !uniform && cond.is_some_and(|c| f.expr(c).varying);
                let divergent = !uniform && (vary_cond || divergent_exit(f, body, step));
                if vary_cond {
                    self.vdepth += 1;
                }
                if divergent {
                    self.div += 1;
                }
                let exit_acc = self.b.declare_var(types::I32X4);
                let cont_acc = self.b.declare_var(types::I32X4);
                let z = mask::zero_mask(&mut self.b);
                self.b.def_var(exit_acc, z);
                self.b.def_var(cont_acc, z);
                let iterations = self.loop_count;
                let site = self.site(s.span);
                let (header, body_b, cont_b, exit_b) =
                    (self.b.create_block(), self.b.create_block(), self.b.create_block(), self.b.create_block());
                self.b.ins().jump(header, &[]);
                self.b.switch_to_block(header);
                // The iteration budget, shared by every loop of the invocation: past it, the running
                // lanes leave this loop (as by `break`), every later loop header stops too, and the
                // renderer is told once per loop where.
                let count = self.b.use_var(iterations);
                let count = self.b.ins().iadd_imm_u(count, 1);
                self.b.def_var(iterations, count);
                let over = self.b.ins().icmp_imm_u(IntCC::UnsignedGreaterThan, count, i64::from(self.loop_budget));
                let (stop_b, go_b) = (self.b.create_block(), self.b.create_block());
                self.b.ins().brif(over, stop_b, &[], go_b, &[]);
                self.b.switch_to_block(stop_b);
                self.runtime_error(RUNTIME_LOOP_BUDGET, site)?;
                let e = self.exec();
                let acc = self.b.use_var(exit_acc);
                let acc = self.b.ins().bor(acc, e);
                self.b.def_var(exit_acc, acc);
                self.b.ins().jump(exit_b, &[]);
                self.b.switch_to_block(go_b);
                if let Some(c) = cond {
                    let cv = self.expr(*c)?;
                    let cm = to_mask(&mut self.b, cv.c[0]);
                    let e = self.exec();
                    let leaving = self.b.ins().band_not(e, cm);
                    let acc = self.b.use_var(exit_acc);
                    let acc = self.b.ins().bor(acc, leaving);
                    self.b.def_var(exit_acc, acc);
                    let stay = self.b.ins().band(e, cm);
                    self.set_exec(stay);
                }
                let e = self.exec();
                let live = any(&mut self.b, e);
                self.b.ins().brif(live, body_b, &[], exit_b, &[]);
                self.b.switch_to_block(body_b);
                let z = mask::zero_mask(&mut self.b);
                self.b.def_var(cont_acc, z);
                let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: cont_b, depth: self.vdepth };
                self.frames.last_mut().expect("frame").loops.push(lp);
                self.block(body)?;
                self.b.ins().jump(cont_b, &[]);
                self.b.switch_to_block(cont_b);
                let e = self.exec();
                let ca = self.b.use_var(cont_acc);
                let e = self.b.ins().bor(e, ca);
                self.set_exec(e);
                self.block(step)?;
                self.b.ins().jump(header, &[]);
                self.frames.last_mut().expect("frame").loops.pop();
                self.b.switch_to_block(exit_b);
                let acc = self.b.use_var(exit_acc);
                self.set_exec(acc);
                if vary_cond {
                    self.vdepth -= 1;
                }
                if divergent {
                    self.div -= 1;
                }
            }
            StmtKind::Break(n) | StmtKind::Continue(n) => {
                let loops = &self.frame().loops;
                let lp = *loops
                    .get(loops.len().wrapping_sub(*n as usize))
                    .ok_or_else(|| JitError::Codegen("break outside a loop".into()))?;
                let is_break = matches!(s.kind, StmtKind::Break(_));
                let (acc, target) = if is_break { (lp.exit_acc, lp.exit) } else { (lp.cont_acc, lp.cont) };
                let e = self.exec();
                let a = self.b.use_var(acc);
                let a = self.b.ins().bor(a, e);
                self.b.def_var(acc, a);
                let z = mask::zero_mask(&mut self.b);
                self.set_exec(z);
                if self.vdepth == lp.depth {
                    self.jump_away(target);
                }
                return Ok(true);
            }
            StmtKind::Return(v) => {
                if let Some(v) = v {
                    let val = self.dual(*v)?;
                    let ret = self.frame().ret.clone().ok_or_else(|| JitError::Codegen("return value".into()))?;
                    self.write_store(&ret, &val.v)?;
                    if let Some(ds) = self.frame().dret.clone() {
                        self.write_tangents(&ds, &val)?;
                    }
                }
                let z = mask::zero_mask(&mut self.b);
                self.set_exec(z);
                let (depth, rb) = (self.frame().depth, self.frame().ret_block);
                if self.vdepth == depth {
                    self.jump_away(rb);
                }
                return Ok(true);
            }
            StmtKind::Illuminance { category, position, cone, body } => {
                self.illuminance(*category, *position, *cone, body)?;
            }
            StmtKind::Illuminate { position, cone, body } => {
                let from = self.expr(*position)?;
                let cone = match cone {
                    Some((a, b)) => Some((self.expr(*a)?, self.expr(*b)?)),
                    None => None,
                };
                let ps = self.global_val("Ps")?;
                let l = self.binary(BinaryOp::Sub, Type::POINT, &ps, &from)?;
                match cone {
                    None => {
                        self.set_global("L", &l)?;
                        self.block(body)?
                    }
                    Some((axis, angle)) => {
                        let all = self.concat(&[l.clone(), axis, angle]);
                        let ok = self.call_helper("rtsl_cone", &all.c, true)?[0];
                        let zero = self.fconst(0.0, true);
                        let ok = self.b.ins().fcmp(FloatCC::NotEqual, ok, zero);
                        let save = self.exec();
                        self.vdepth += 1;
                        self.div += 1;
                        let run = self.b.ins().band(save, ok);
                        // L is set only where the body runs.
                        self.set_exec(run);
                        self.set_global("L", &l)?;
                        let after = self.masked_block(run, body)?;
                        let skipped = self.b.ins().band_not(save, ok);
                        let e = self.b.ins().bor(after, skipped);
                        self.set_exec(e);
                        self.vdepth -= 1;
                        self.div -= 1;
                    }
                }
            }
            StmtKind::Solar { cone, body } => {
                if let Some((a, b)) = cone {
                    let axis = self.expr(*a)?;
                    self.expr(*b)?;
                    self.set_global("L", &axis)?;
                }
                self.block(body)?;
            }
            StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                let cone = [*category, *position, *direction, *angle, *samples];
                self.gather(cone, params, body, otherwise)?;
            }
        }
        Ok(false)
    }

    /// Runs `blk` under `m` (skipped when no lane is set); returns `exec` after it.
    fn masked_block(&mut self, m: Value, blk: &'m ir::Block) -> R<Value> {
        self.set_exec(m);
        let (run, after) = (self.b.create_block(), self.b.create_block());
        let live = any(&mut self.b, m);
        self.b.ins().brif(live, run, &[], after, &[]);
        self.b.switch_to_block(run);
        self.block(blk)?;
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        Ok(self.exec())
    }

    /// Writes a whole value into storage: masked by `exec` when varying.
    fn write_store(&mut self, s: &Store, v: &Val) -> R<()> {
        if !s.vary {
            if v.vary {
                return unsupported("a varying value stored in uniform storage");
            }
            if self.div != s.div {
                return unsupported("a uniform variable assigned under varying control flow");
            }
            return self.init_store(s, v);
        }
        let e = self.exec();
        for (var, x) in s.vars.iter().zip(&v.c) {
            let old = self.b.use_var(*var);
            let new = merge(&mut self.b, e, *x, old);
            self.b.def_var(*var, new);
        }
        Ok(())
    }

    // ---- Places ----

    fn store_of(&self, base: PlaceBase) -> R<Store> {
        match base {
            PlaceBase::Var(v) => self.frame().vars[v.0 as usize].clone(),
            PlaceBase::Global(g) => self.globals[g.0 as usize].clone(),
        }
        .ok_or_else(|| JitError::Unsupported("a string or matrix variable".into()))
    }

    fn index(&mut self, e: ExprId, n: usize) -> R<Idx> {
        if let ExprKind::Const(Constant::Float(x)) = self.func().expr(e).kind {
            return Ok(Idx::Const(const_index(x, n)));
        }
        let v = self.expr(e)?;
        let span = self.func().expr(e).span;
        self.check_index(v.c[0], n, span)?;
        Ok(self.dyn_index(v.c[0], n))
    }

    /// Reports (once per site, through the renderer) a running lane whose index is outside
    /// `0..n`; the index is then clamped as the interpreter does.
    fn check_index(&mut self, i: Value, n: usize, span: crate::source::Span) -> R<()> {
        let site = self.site(span);
        let b = &mut self.b;
        let zero = konst(b, 0.0, i);
        let end = konst(b, n as f32, i);
        let ge = b.ins().fcmp(FloatCC::GreaterThanOrEqual, i, zero);
        let lt = b.ins().fcmp(FloatCC::LessThan, i, end);
        let ok = b.ins().band(ge, lt);
        let bad = if is_vec(b, i) {
            let m = to_mask(b, ok);
            let e = self.exec();
            let bad = self.b.ins().band_not(e, m);
            any(&mut self.b, bad)
        } else {
            let e = self.exec();
            let running = any(&mut self.b, e);
            let not_ok = self.b.ins().bxor_imm_u(ok, 1);
            self.b.ins().band(running, not_ok)
        };
        let (report, go) = (self.b.create_block(), self.b.create_block());
        self.b.ins().brif(bad, report, &[], go, &[]);
        self.b.switch_to_block(report);
        self.runtime_error(RUNTIME_INDEX, site)?;
        self.b.ins().jump(go, &[]);
        self.b.switch_to_block(go);
        Ok(())
    }

    /// The site of a runtime check at `span`. Inlined copies of a function share their sites, so
    /// that a check is reported once per place in the source, as the interpreter reports it.
    fn site(&mut self, span: crate::source::Span) -> usize {
        if let Some(&i) = self.site_ids.get(&span) {
            return i;
        }
        let text = self.location_text(span);
        self.sites.push(text);
        self.site_ids.insert(span, self.sites.len() - 1);
        self.sites.len() - 1
    }

    fn location_text(&self, span: crate::source::Span) -> String {
        match self.sources {
            Some(src) => src.location(span).to_string(),
            None => format!("byte {} of file {}", span.start, span.file.0),
        }
    }

    /// Calls the runtime-error helper for `kind` at `site` (lane 0; the helper records it once).
    /// Reports (once per site, see `RuntimeErrors`) that a running lane called a built-in rtsl
    /// accepts but cannot honour.
    fn report_unsupported(&mut self, bi: Builtin, span: crate::source::Span) -> R<()> {
        let site = self.site(span);
        self.sites[site] = format!("`{}` at {}", bi.name(), self.location_text(span));
        let e = self.exec();
        let running = any(&mut self.b, e);
        let (report, go) = (self.b.create_block(), self.b.create_block());
        self.b.ins().brif(running, report, &[], go, &[]);
        self.b.switch_to_block(report);
        self.runtime_error(RUNTIME_UNSUPPORTED, site)?;
        self.b.ins().jump(go, &[]);
        self.b.switch_to_block(go);
        Ok(())
    }

    fn runtime_error(&mut self, kind: u32, site: usize) -> R<()> {
        let k = self.b.ins().f32const(kind as f32);
        let s = self.b.ins().f32const(site as f32);
        self.call_helper("rtsl_h_runtime_error", &[k, s], false)?;
        Ok(())
    }

    /// The interpreter's `index_of` per lane: non-finite or negative gives 0, else `min(trunc, n-1)`.
    fn dyn_index(&mut self, i: Value, n: usize) -> Idx {
        let b = &mut self.b;
        let zero = konst(b, 0.0, i);
        let inf = konst(b, f32::INFINITY, i);
        let ge = b.ins().fcmp(FloatCC::GreaterThanOrEqual, i, zero);
        let lt = b.ins().fcmp(FloatCC::LessThan, i, inf);
        let ok = b.ins().band(ge, lt);
        let t = b.ins().trunc(i);
        let hi = konst(b, (n.max(1) - 1) as f32, i);
        let small = b.ins().fcmp(FloatCC::LessThan, t, hi);
        let t = choose(b, small, t, hi);
        Idx::Dyn(choose(b, ok, t, zero))
    }

    fn idx_cond(&mut self, idx: Idx, k: usize) -> Option<Option<Value>> {
        match idx {
            Idx::Const(c) => (c == k).then_some(None),
            Idx::Dyn(v) => {
                let kc = konst(&mut self.b, k as f32, v);
                Some(Some(self.b.ins().fcmp(FloatCC::Equal, v, kc)))
            }
        }
    }

    fn place_targets(&mut self, p: &Place) -> R<Targets> {
        let store = self.store_of(p.base)?;
        let base_ty = match p.base {
            PlaceBase::Var(v) => self.func().var(v).ty,
            PlaceBase::Global(g) => Type::scalar(g.def().ty),
        };
        let total = store.vars.len();
        let comps = store.comps;
        let mut list = Vec::new();
        match (p.index, p.component) {
            (None, _) => list.extend((0..total).map(|k| (k, k, None))),
            (Some(i), comp) if base_ty.is_array() => {
                let n = total / comps;
                let idx = self.index(i, n)?;
                let cidx = match comp {
                    Some(c) => Some(self.index(c, comps)?),
                    None => None,
                };
                for e in 0..n {
                    let Some(ce) = self.idx_cond(idx, e) else { continue };
                    for j in 0..comps {
                        match cidx {
                            None => list.push((e * comps + j, j, ce)),
                            Some(ci) => {
                                let Some(cj) = self.idx_cond(ci, j) else { continue };
                                let cond = match (ce, cj) {
                                    (Some(a), Some(b)) => Some(and(&mut self.b, a, b)),
                                    (a, b) => a.or(b),
                                };
                                list.push((e * comps + j, 0, cond));
                            }
                        }
                    }
                }
            }
            (Some(i), _) => {
                let idx = self.index(i, total)?;
                for k in 0..total {
                    if let Some(c) = self.idx_cond(idx, k) {
                        list.push((k, 0, c));
                    }
                }
            }
        }
        let out = components(p.ty).unwrap_or(1) * p.ty.array_len().unwrap_or(1) as usize;
        Ok(Targets { base: p.base, list, comps: out })
    }

    fn read_targets(&mut self, t: &Targets) -> R<Val> {
        let store = self.store_of(t.base)?;
        self.read_targets_in(&store, t)
    }

    fn read_targets_in(&mut self, store: &Store, t: &Targets) -> R<Val> {
        let mut c = Vec::with_capacity(t.comps);
        let mut vary = store.vary;
        for j in 0..t.comps {
            let mut acc: Option<Value> = None;
            for (flat, vj, cond) in &t.list {
                if *vj != j {
                    continue;
                }
                let x = self.b.use_var(store.vars[*flat]);
                acc = Some(match (acc, cond) {
                    (None, _) | (_, None) => x,
                    (Some(a), Some(cnd)) => {
                        vary |= is_vec(&self.b, *cnd);
                        choose(&mut self.b, *cnd, x, a)
                    }
                });
            }
            c.push(acc.ok_or_else(|| JitError::Codegen("empty place".into()))?);
        }
        let c = c.into_iter().map(|x| widen(&mut self.b, x, vary)).collect();
        Ok(Val { vary, c })
    }

    /// Writes a place; its tangents (when it keeps them) become zero.
    fn write_targets(&mut self, t: &Targets, v: &Val) -> R<()> {
        self.write_targets_d(t, &Dual { v: v.clone(), d: None })
    }

    /// Writes a place and, when it keeps tangents, the value's tangents (under the same masks).
    fn write_targets_d(&mut self, t: &Targets, v: &Dual) -> R<()> {
        let store = self.store_of(t.base)?;
        self.write_targets_in(&store, t, &v.v)?;
        if let Some(ds) = self.tangent_stores(t.base) {
            let [dx, dy] = self.tangents(v);
            self.write_targets_in(&ds[0], t, &Val { vary: true, c: dx })?;
            self.write_targets_in(&ds[1], t, &Val { vary: true, c: dy })?;
        }
        Ok(())
    }

    fn write_targets_in(&mut self, store: &Store, t: &Targets, v: &Val) -> R<()> {
        let store = store.clone();
        if !store.vary {
            if v.vary || t.list.iter().any(|(_, _, c)| c.is_some_and(|c| is_vec(&self.b, c))) {
                return unsupported("a varying value stored in uniform storage");
            }
            if self.div != store.div {
                return unsupported("a uniform variable assigned under varying control flow");
            }
        }
        let e = if store.vary { Some(self.exec()) } else { None };
        // In the shader body outside varying control flow every lane of the chunk's mask runs, and
        // a fresh global's other lanes are blended back at the chunk's end (a body's local's are
        // never read into anything that is stored): no merge.
        let whole = store.fresh && self.div == 0 && self.frames.len() == 1;
        for (flat, j, cond) in &t.list {
            let var = store.vars[*flat];
            let old = self.b.use_var(var);
            let x = v.c[*j];
            let new = match (e, cond) {
                (Some(e), Some(c)) => {
                    let cm = to_mask(&mut self.b, *c);
                    let m = self.b.ins().band(e, cm);
                    merge(&mut self.b, m, x, old)
                }
                (Some(_), None) if whole => widen(&mut self.b, x, true),
                (Some(e), None) => merge(&mut self.b, e, x, old),
                (None, Some(c)) => self.b.ins().select(*c, x, old),
                (None, None) => x,
            };
            self.b.def_var(var, new);
        }
        Ok(())
    }

    // ---- Expressions ----

    fn fconst(&mut self, x: f32, vary: bool) -> Value {
        fconst(&mut self.b, x, vary)
    }

    fn expr(&mut self, id: ExprId) -> R<Val> {
        // The prologue's values, in the shader body itself (inlined functions have ids of their own).
        if self.frames.len() == 1 {
            if let Some(v) = self.batch_consts.get(&id.0) {
                return Ok(v.clone());
            }
        }
        if !self.cache.is_empty() {
            if let Some(v) = self.cache.get(&(self.frames.len(), id.0)) {
                return Ok(v.clone());
            }
        }
        let f = self.func();
        let e = f.expr(id);
        let marked = self.info.expr(self.frame().fid, id);
        match &e.kind {
            ExprKind::Assign { .. } | ExprKind::Call { .. } if marked => return Ok(self.dual(id)?.v),
            ExprKind::CallBuiltin { builtin, overload, args }
                if ir::deriv::is_deriv_builtin(*builtin) || matches!(builtin, Builtin::Texture | Builtin::Shadow) =>
            {
                return Ok(self.builtin_dual(*builtin, *overload, args, e, false)?.v)
            }
            _ => {}
        }
        match &e.kind {
            ExprKind::Const(Constant::Float(x)) => Ok(Val { vary: false, c: vec![self.b.ins().f32const(*x)] }),
            ExprKind::Const(Constant::String(x)) => {
                let h = self.string_handle(x);
                Ok(Val { vary: false, c: vec![self.b.ins().f32const(f32::from_bits(h))] })
            }
            ExprKind::Var(v) => {
                let s = self.store_of(PlaceBase::Var(*v))?;
                Ok(self.read_store(&s))
            }
            ExprKind::Global(g) => {
                let s = self.store_of(PlaceBase::Global(*g))?;
                Ok(self.read_store(&s))
            }
            ExprKind::Index { base, index } => {
                let bt = f.expr(*base).ty;
                let bv = self.expr(*base)?;
                let comps = if bt.is_array() { components(bt.element()).unwrap_or(1) } else { 1 };
                let n = bv.c.len() / comps;
                let idx = self.index(*index, n)?;
                self.select_elem(&bv, comps, idx)
            }
            ExprKind::Unary { op: UnaryOp::Neg, arg } => {
                let a = self.expr(*arg)?;
                if !(e.ty.base.is_numeric() || e.ty.base == BaseType::Matrix) {
                    return unsupported(format!("negation of {}", e.ty));
                }
                Ok(Val { vary: a.vary, c: a.c.iter().map(|x| self.b.ins().fneg(*x)).collect() })
            }
            ExprKind::Unary { op: UnaryOp::Not, arg } => {
                let a = self.expr(*arg)?;
                Ok(Val { vary: a.vary, c: vec![not(&mut self.b, a.c[0])] })
            }
            ExprKind::Binary { op: op @ (BinaryOp::And | BinaryOp::Or), lhs, rhs } => {
                self.logic(*op, *lhs, *rhs, e.varying)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let lt = f.expr(*lhs).ty;
                let a = self.expr(*lhs)?;
                let b = self.expr(*rhs)?;
                self.binary(*op, lt, &a, &b)
            }
            ExprKind::Convert { arg } => {
                let from = f.expr(*arg).ty;
                let a = self.expr(*arg)?;
                self.convert(a, from, e.ty)
            }
            ExprKind::Construct { args } => {
                let mut vals = Vec::new();
                for a in args {
                    vals.push(self.expr(*a)?);
                }
                Ok(self.concat(&vals))
            }
            ExprKind::SpaceCast { space, arg } => {
                let sp = self.expr(*space)?;
                let v = self.expr(*arg)?;
                let m = self.batch_matrix(*space);
                self.space_cast(e.ty.base, &sp, v, m)
            }
            ExprKind::Select { cond, a, b } => self.select(e, *cond, *a, *b),
            ExprKind::CallBuiltin { builtin, overload, args } => self.builtin(*builtin, *overload, args, e),
            ExprKind::Call { func, args } => Ok(self.call(*func, args, e)?.v),
            ExprKind::Assign { place, op, value } => {
                let v = self.expr(*value)?;
                let t = self.place_targets(place)?;
                let stored = match op {
                    Some(op) => {
                        let cur = self.read_targets(&t)?;
                        self.binary(*op, place.ty, &cur, &v)?
                    }
                    None => v,
                };
                self.write_targets(&t, &stored)?;
                Ok(stored)
            }
            ExprKind::ArrayLiteral { elements } => {
                let mut vals = Vec::new();
                for el in elements {
                    vals.push(self.expr(*el)?);
                }
                Ok(self.concat(&vals))
            }
        }
    }

    /// Components of several values in order, all varying if any is.
    fn concat(&mut self, vals: &[Val]) -> Val {
        let vary = vals.iter().any(|v| v.vary);
        let c = vals.iter().flat_map(|v| v.c.iter().copied()).collect::<Vec<_>>();
        Val { vary, c: c.into_iter().map(|x| widen(&mut self.b, x, vary)).collect() }
    }

    fn select_elem(&mut self, bv: &Val, comps: usize, idx: Idx) -> R<Val> {
        let n = bv.c.len() / comps.max(1);
        match idx {
            Idx::Const(k) => Ok(Val { vary: bv.vary, c: bv.c[k * comps..(k + 1) * comps].to_vec() }),
            Idx::Dyn(i) => {
                let vary = bv.vary || is_vec(&self.b, i);
                let mut c: Vec<Value> = bv.c[..comps].iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                for k in 1..n {
                    let kc = konst(&mut self.b, k as f32, i);
                    let eq = self.b.ins().fcmp(FloatCC::Equal, i, kc);
                    for (j, cj) in c.iter_mut().enumerate() {
                        *cj = choose(&mut self.b, eq, bv.c[k * comps + j], *cj);
                    }
                }
                Ok(Val { vary, c })
            }
        }
    }

    fn logic(&mut self, op: BinaryOp, lhs: ExprId, rhs: ExprId, vary_flag: bool) -> R<Val> {
        let l = self.expr(lhs)?;
        if l.vary || (vary_flag && !self.frame().uniform) {
            let lm = to_mask(&mut self.b, l.c[0]);
            let save = self.exec();
            let m = if op == BinaryOp::And { self.b.ins().band(save, lm) } else { self.b.ins().band_not(save, lm) };
            self.set_exec(m);
            self.div += 1;
            self.vdepth += 1;
            let r = self.expr(rhs);
            self.div -= 1;
            self.vdepth -= 1;
            self.set_exec(save);
            let r = r?;
            let rm = to_mask(&mut self.b, r.c[0]);
            let res = if op == BinaryOp::And { self.b.ins().band(lm, rm) } else { self.b.ins().bor(lm, rm) };
            return Ok(Val { vary: true, c: vec![res] });
        }
        let res = self.b.declare_var(types::I8);
        self.b.def_var(res, l.c[0]);
        let (rb, join) = (self.b.create_block(), self.b.create_block());
        if op == BinaryOp::And {
            self.b.ins().brif(l.c[0], rb, &[], join, &[]);
        } else {
            self.b.ins().brif(l.c[0], join, &[], rb, &[]);
        }
        self.b.switch_to_block(rb);
        let r = self.expr(rhs)?;
        if r.vary {
            return unsupported("a varying operand of a uniform && or ||");
        }
        self.b.def_var(res, r.c[0]);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(Val { vary: false, c: vec![self.b.use_var(res)] })
    }

    fn select(&mut self, e: &ir::Expr, cond: ExprId, a: ExprId, b: ExprId) -> R<Val> {
        let f = self.func();
        let c = self.expr(cond)?;
        let n = match e.ty.base {
            BaseType::Bool => 1,
            _ => components(e.ty).ok_or_else(|| JitError::Unsupported(format!("a select of {}", e.ty)))?,
        } * e.ty.array_len().unwrap_or(1) as usize;
        if c.vary || (f.expr(cond).varying && !self.frame().uniform) {
            let cm = to_mask(&mut self.b, c.c[0]);
            let save = self.exec();
            self.div += 1;
            self.vdepth += 1;
            let m = self.b.ins().band(save, cm);
            self.set_exec(m);
            let av = self.expr(a);
            let m = self.b.ins().band_not(save, cm);
            self.set_exec(m);
            let bv = av.and_then(|av| Ok((av, self.expr(b)?)));
            self.div -= 1;
            self.vdepth -= 1;
            self.set_exec(save);
            let (av, bv) = bv?;
            let c = av.c.iter().zip(&bv.c).map(|(x, y)| choose(&mut self.b, cm, *x, *y)).collect();
            return Ok(Val { vary: true, c });
        }
        let vary = e.varying && !self.frame().uniform;
        let ty = match (e.ty.base, vary) {
            (BaseType::Bool, false) => types::I8,
            (BaseType::Bool, true) => types::I32X4,
            (_, false) => types::F32,
            (_, true) => types::F32X4,
        };
        let vars: Vec<Variable> = (0..n).map(|_| self.b.declare_var(ty)).collect();
        let (tb, eb, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().brif(c.c[0], tb, &[], eb, &[]);
        for (blk, side) in [(tb, a), (eb, b)] {
            self.b.switch_to_block(blk);
            let v = self.expr(side)?;
            if v.vary && !vary {
                return unsupported("a varying side of a uniform select");
            }
            for (var, x) in vars.iter().zip(&v.c) {
                let x = widen(&mut self.b, *x, vary);
                self.b.def_var(*var, x);
            }
            self.b.ins().jump(join, &[]);
        }
        self.b.switch_to_block(join);
        Ok(Val { vary, c: vars.iter().map(|v| self.b.use_var(*v)).collect() })
    }

    fn convert(&mut self, a: Val, from: Type, to: Type) -> R<Val> {
        if from.is_array() {
            return if from.base == to.base || (from.base.is_triple() && to.base.is_triple()) {
                Ok(a)
            } else {
                unsupported("an array conversion")
            };
        }
        match (from.base, to.base) {
            (x, y) if x == y => Ok(a),
            (x, y) if x.is_triple() && y.is_triple() => Ok(a),
            (BaseType::Float, y) if y.is_triple() => Ok(Val { vary: a.vary, c: vec![a.c[0]; 3] }),
            (BaseType::Float, BaseType::Matrix) => {
                let zero = self.fconst(0.0, a.vary);
                let c = (0..16).map(|k| if k % 5 == 0 { a.c[0] } else { zero }).collect();
                Ok(Val { vary: a.vary, c })
            }
            (x, BaseType::Float) if x.is_triple() => Ok(Val { vary: a.vary, c: vec![a.c[0]] }),
            (BaseType::Bool, BaseType::Float) => {
                let one = self.fconst(1.0, a.vary);
                let zero = self.fconst(0.0, a.vary);
                Ok(Val { vary: a.vary, c: vec![choose(&mut self.b, a.c[0], one, zero)] })
            }
            _ => unsupported(format!("a conversion from {from} to {to}")),
        }
    }

    /// Component-wise binary operators on operands of one type (`lt`), as `interp::binary`.
    fn binary(&mut self, op: BinaryOp, lt: Type, a: &Val, b: &Val) -> R<Val> {
        use BinaryOp::*;
        let vary = a.vary || b.vary;
        if lt.base == BaseType::String {
            // Handles are interned per batch: equal handles are equal strings.
            let ty = if vary { types::I32X4 } else { types::I32 };
            let (x, y) = (widen(&mut self.b, a.c[0], vary), widen(&mut self.b, b.c[0], vary));
            let flags = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
            let x = self.b.ins().bitcast(ty, flags, x);
            let y = self.b.ins().bitcast(ty, flags, y);
            let cc = match op {
                Eq => IntCC::Equal,
                Ne => IntCC::NotEqual,
                _ => return unsupported(format!("{op:?} on strings")),
            };
            return Ok(Val { vary, c: vec![self.b.ins().icmp(cc, x, y)] });
        }
        if lt.base == BaseType::Matrix && matches!(op, Mul | Div) {
            let all = self.concat(&[a.clone(), b.clone()]);
            let name = if op == Mul { "rtsl_mmul" } else { "rtsl_mdiv" };
            let c = self.call_helper(name, &all.c, all.vary)?;
            return Ok(Val { vary: all.vary, c });
        }
        let x: Vec<Value> = a.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let y: Vec<Value> = b.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let ins = |s: &mut Self, f: fn(&mut FunctionBuilder<'_>, Value, Value) -> Value| -> Vec<Value> {
            x.iter().zip(&y).map(|(p, q)| f(&mut s.b, *p, *q)).collect()
        };
        let c = match op {
            Add => ins(self, |b, p, q| b.ins().fadd(p, q)),
            Sub => ins(self, |b, p, q| b.ins().fsub(p, q)),
            Mul => ins(self, |b, p, q| b.ins().fmul(p, q)),
            Div => ins(self, |b, p, q| b.ins().fdiv(p, q)),
            Dot => vec![self.dot(&x, &y)],
            Cross => {
                let m = |s: &mut Self, i: usize, j: usize| {
                    let p = s.b.ins().fmul(x[i], y[j]);
                    let q = s.b.ins().fmul(x[j], y[i]);
                    s.b.ins().fsub(p, q)
                };
                vec![m(self, 1, 2), m(self, 2, 0), m(self, 0, 1)]
            }
            Lt | Gt | Le | Ge => {
                let cc = match op {
                    Lt => FloatCC::LessThan,
                    Gt => FloatCC::GreaterThan,
                    Le => FloatCC::LessThanOrEqual,
                    _ => FloatCC::GreaterThanOrEqual,
                };
                vec![self.b.ins().fcmp(cc, x[0], y[0])]
            }
            Eq | Ne if lt.base == BaseType::Bool => {
                let d = self.b.ins().bxor(x[0], y[0]);
                vec![if op == Ne { d } else { not(&mut self.b, d) }]
            }
            Eq | Ne => {
                let cc = if op == Eq { FloatCC::Equal } else { FloatCC::NotEqual };
                let mut acc = self.b.ins().fcmp(cc, x[0], y[0]);
                for k in 1..x.len() {
                    let c = self.b.ins().fcmp(cc, x[k], y[k]);
                    acc = if op == Eq { and(&mut self.b, acc, c) } else { or(&mut self.b, acc, c) };
                }
                vec![acc]
            }
            And | Or => return unsupported("logic outside its expression"),
        };
        Ok(Val { vary, c })
    }

    fn dot(&mut self, x: &[Value], y: &[Value]) -> Value {
        let p0 = self.b.ins().fmul(x[0], y[0]);
        let p1 = self.b.ins().fmul(x[1], y[1]);
        let p2 = self.b.ins().fmul(x[2], y[2]);
        let s = self.b.ins().fadd(p0, p1);
        self.b.ins().fadd(s, p2)
    }

    // ---- Calls ----

    /// Inlines a call; the result is a dual when the callee's result is differentiated.
    fn call(&mut self, fid: FuncId, args: &'m [Arg], e: &ir::Expr) -> R<Dual> {
        let callee = self.m.function(fid);
        let mut inputs = Vec::with_capacity(args.len());
        let mut dargs = Vec::with_capacity(args.len());
        let mut places = Vec::with_capacity(args.len());
        for (k, a) in args.iter().enumerate() {
            let marked = callee.params.get(k).is_some_and(|p| self.info.var(fid, *p));
            match a {
                Arg::Value(x) => {
                    let d = if marked { self.dual(*x)? } else { Dual { v: self.expr(*x)?, d: None } };
                    inputs.push((d.v, None));
                    dargs.push(d.d);
                    places.push(None);
                }
                Arg::Ref(p) => {
                    let t = self.place_targets(p)?;
                    let v = self.read_targets(&t)?;
                    let vary = self.store_of(p.base)?.vary;
                    let d = match self.tangent_stores(p.base) {
                        Some(ds) if marked => {
                            let x = self.read_targets_in(&ds[0], &t)?;
                            let y = self.read_targets_in(&ds[1], &t)?;
                            Some([x.c, y.c])
                        }
                        _ => None,
                    };
                    inputs.push((v, Some(vary)));
                    dargs.push(d);
                    places.push(Some(t));
                }
            }
        }
        // After a divergent return the lanes still running may update uniform locals (the lanes
        // that left never read them again), but not uniform output or captured parameters, which
        // every calling lane reads back.
        // Uniform mode: a callee that reads no varying state, called with uniform arguments (values
        // and output places alike), computes the same value in every lane, whatever the checker
        // inferred for its locals in general (it infers once per function, for every call site).
        // Its locals become uniform storage and its control flow uniform, so a uniform result can
        // flow into uniform storage (e.g. `uniform float n = halvings(1 / cellsize, 1)`).
        let uniform = !callee.reads_varying && inputs.iter().all(|(v, _)| !v.vary);
        let fdiv = !uniform && self.fn_divergent(fid);
        let mut frame = self.new_frame(fid, callee, &inputs, &dargs, uniform)?;
        if fdiv {
            for (k, (_, by_ref)) in inputs.iter().enumerate() {
                if by_ref.is_some() {
                    if let Some(s) = frame.vars[callee.params[k].0 as usize].as_mut() {
                        s.div = u32::MAX;
                    }
                }
            }
        }
        if callee.return_type.base != BaseType::Void {
            let comps = components(callee.return_type)
                .ok_or_else(|| JitError::Unsupported(format!("a function returning {}", callee.return_type)))?;
            if callee.return_type.is_array() {
                return unsupported("a function returning an array");
            }
            // A function that may return under a varying condition returns into varying storage.
            let vary = (e.varying && !uniform) || fdiv;
            frame.ret = Some(self.zero_store(vary, comps, comps));
            if vary && self.info.ret[fid.0 as usize] {
                frame.dret = Some([self.zero_store(true, comps, comps), self.zero_store(true, comps, comps)]);
            }
        }
        let save = self.exec();
        let rb = frame.ret_block;
        self.frames.push(frame);
        let r = self.block(&callee.body);
        let frame = self.frames.pop().expect("frame");
        r?;
        self.b.ins().jump(rb, &[]);
        self.b.switch_to_block(rb);
        self.set_exec(save);
        for (k, t) in places.iter().enumerate() {
            let Some(t) = t else { continue };
            let pv = callee.params[k];
            let s = frame.vars[pv.0 as usize].clone().ok_or_else(|| JitError::Codegen("parameter".into()))?;
            let v = self.read_store(&s);
            let d = frame.dvars[pv.0 as usize].clone().map(|[x, y]| [self.read_store(&x).c, self.read_store(&y).c]);
            self.write_targets_d(t, &Dual { v, d })?;
        }
        let v = match &frame.ret {
            Some(s) => self.read_store(s),
            None => Val { vary: false, c: Vec::new() },
        };
        let d = frame.dret.clone().map(|[x, y]| [self.read_store(&x).c, self.read_store(&y).c]);
        Ok(Dual { v, d })
    }

    fn fn_divergent(&mut self, fid: FuncId) -> bool {
        if let Some(d) = self.fn_div.get(&fid.0) {
            return *d;
        }
        let f = self.m.function(fid);
        let d = divergent_return(f, &f.body, 0);
        self.fn_div.insert(fid.0, d);
        d
    }

    fn helper_ref(&mut self, name: &'static str, params: usize) -> R<FuncRef> {
        if let Some(r) = self.helpers.get(name) {
            return Ok(*r);
        }
        let mut sig = self.jit.make_signature();
        for _ in 0..params {
            sig.params.push(AbiParam::new(self.ptr));
        }
        let id =
            self.jit.declare_function(name, Linkage::Import, &sig).map_err(|e| JitError::Codegen(e.to_string()))?;
        let r = self.jit.declare_func_in_func(id, self.b.func);
        self.helpers.insert(name, r);
        Ok(r)
    }

    /// Calls a per-chunk helper on `inputs` (scalars are splatted); results are uniform again when
    /// every input was.
    ///
    /// Host helpers (`host::HOST_HELPERS`) also receive the batch record and a mask: the lanes of
    /// `exec` when `vary`, else lane 0 alone (the result is uniform).
    fn call_helper(&mut self, name: &'static str, inputs: &[Value], vary: bool) -> R<Vec<Value>> {
        self.call_helper_as(name, inputs, vary, false)
    }

    /// [`Lower::call_helper`] for a call on a cold path: on x86-64 through a trampoline that
    /// preserves every register (`CallConv::PreserveAll`), so that the values live across the call
    /// stay in their registers instead of being spilled (at their definitions, which the hot path
    /// then pays too). A per-chunk (not host) helper.
    fn call_helper_keeping_registers(&mut self, name: &'static str, inputs: &[Value]) -> R<Vec<Value>> {
        self.call_helper_as(name, inputs, true, cfg!(target_arch = "x86_64"))
    }

    /// The reference to the register-preserving trampoline of per-chunk helper `name`.
    fn trampoline_ref(&mut self, name: &'static str) -> R<FuncRef> {
        let key: &'static str = match name {
            "rtsl_sincos" => "rtsl_sincos_keep",
            _ => return Err(JitError::Codegen(format!("no register-preserving trampoline for {name}"))),
        };
        if let Some(r) = self.helpers.get(key) {
            return Ok(*r);
        }
        let mut sig = self.jit.make_signature();
        sig.call_conv = CallConv::PreserveAll;
        sig.params.extend([AbiParam::new(self.ptr), AbiParam::new(self.ptr)]);
        let id = self.jit.declare_function(key, Linkage::Local, &sig).map_err(|e| JitError::Codegen(e.to_string()))?;
        self.trampolines.push((id, name));
        let r = self.jit.declare_func_in_func(id, self.b.func);
        self.helpers.insert(key, r);
        Ok(r)
    }

    fn call_helper_as(&mut self, name: &'static str, inputs: &[Value], vary: bool, keep: bool) -> R<Vec<Value>> {
        let (hname, ins, outs, is_host) = match (math::helper(name), host::host_helper(name)) {
            (Some(h), _) => (h.name, h.ins, h.outs, false),
            (None, Some(h)) => (h.name, h.ins, h.outs, true),
            _ => return Err(JitError::Codegen(format!("no helper {name}"))),
        };
        let ins = if ins == host::VARIADIC { inputs.len() } else { ins };
        if ins != inputs.len() {
            return Err(JitError::Codegen(format!("{name} takes {ins} inputs, not {}", inputs.len())));
        }
        let fr = if keep && !is_host {
            self.trampoline_ref(hname)?
        } else {
            self.helper_ref(hname, if is_host { 4 } else { 2 })?
        };
        let slot = |n: usize| StackSlotData::new(StackSlotKind::ExplicitSlot, 16 * n.max(1) as u32, 4);
        let sin = self.b.create_sized_stack_slot(slot(ins));
        let sout = self.b.create_sized_stack_slot(slot(outs));
        for (k, x) in inputs.iter().enumerate() {
            let x = if is_vec(&self.b, *x) && self.b.func.dfg.value_type(*x) == types::I32X4 {
                mask::mask_as_f32(&mut self.b, *x)
            } else {
                widen(&mut self.b, *x, true)
            };
            self.b.ins().stack_store(self.ptr, x, sin, (16 * k) as i32);
        }
        let pin = self.b.ins().stack_addr(self.ptr, sin, 0);
        let pout = self.b.ins().stack_addr(self.ptr, sout, 0);
        if is_host {
            let smask = self.b.create_sized_stack_slot(slot(1));
            let m = if vary {
                self.exec()
            } else {
                let z = self.b.ins().iconst(types::I32, 0);
                let z = self.b.ins().splat(types::I32X4, z);
                let on = self.b.ins().iconst(types::I32, -1);
                self.b.ins().insertlane(z, on, 0)
            };
            self.b.ins().stack_store(self.ptr, m, smask, 0);
            let pmask = self.b.ins().stack_addr(self.ptr, smask, 0);
            let batch = self.batch.expect("batch");
            self.host_calls += 1;
            self.b.ins().call(fr, &[batch, pmask, pin, pout]);
        } else {
            self.b.ins().call(fr, &[pin, pout]);
        }
        let mut out = Vec::with_capacity(outs);
        for j in 0..outs {
            let v = self.b.ins().stack_load(self.ptr, types::F32X4, sout, (16 * j) as i32);
            out.push(if vary { v } else { self.b.ins().extractlane(v, 0) });
        }
        Ok(out)
    }

    /// `sin` (`which` 0) or `cos` (1) of each component. Both come from one `rtsl_sincos` call,
    /// whose results are kept for the rest of the block: `sin(a)` and `cos(a)` of the same value
    /// (a rotation, a point on a circle) then cost one call and one range reduction.
    fn sin_cos(&mut self, v: &Val, which: usize) -> R<Val> {
        let mut c = Vec::with_capacity(v.c.len());
        for &x in &v.c {
            let block = self.b.current_block();
            let cached = self.sincos_results.get(&x).filter(|(b, _)| *b == block).map(|(_, r)| *r);
            let results = match cached {
                Some(r) => r,
                None => {
                    let r = if v.vary && self.b.func.dfg.value_type(x) == types::F32X4 {
                        self.sincos_inline(x)?
                    } else {
                        let r = self.call_helper("rtsl_sincos", &[x], v.vary)?;
                        [r[0], r[1]]
                    };
                    // The inline form may end in a new block (after its fallback).
                    let block = self.b.current_block();
                    self.sincos_results.insert(x, (block, r));
                    r
                }
            };
            c.push(results[which]);
        }
        Ok(Val { vary: v.vary, c })
    }

    /// `sin` and `cos` of four lanes in the chunk's own code ([`math::sincos4`]: the same bits as
    /// the helper and the interpreter). A chunk with a lane beyond `TRIG_MAX` (or NaN) calls the
    /// helper instead, which computes those lanes the slow way. Inline because the call cost more
    /// than the arithmetic. The fallback goes through a register-preserving trampoline: with an
    /// ordinary call every vector live across it was spilled where it was defined, on the hot path.
    fn sincos_inline(&mut self, x: Value) -> R<[Value; 2]> {
        let (sin_v, cos_v, in_range) = math::sincos4(&mut self.b, x);
        // Lanes out of range: the helper, for the whole chunk (its in-range lanes are these bits).
        let (slow, join) = (self.b.create_block(), self.b.create_block());
        let (sin_p, cos_p) =
            (self.b.append_block_param(join, types::F32X4), self.b.append_block_param(join, types::F32X4));
        self.b.ins().brif(in_range, join, &[sin_v.into(), cos_v.into()], slow, &[]);
        self.b.set_cold_block(slow);
        self.b.switch_to_block(slow);
        self.b.seal_block(slow);
        let r = self.call_helper_keeping_registers("rtsl_sincos", &[x])?;
        self.b.ins().jump(join, &[r[0].into(), r[1].into()]);
        self.b.switch_to_block(join);
        self.b.seal_block(join);
        Ok([sin_p, cos_p])
    }

    /// A one-input helper applied to each component.
    fn map_helper(&mut self, name: &'static str, v: &Val) -> R<Val> {
        let mut c = Vec::new();
        for x in &v.c {
            c.push(self.call_helper(name, &[*x], v.vary)?[0]);
        }
        Ok(Val { vary: v.vary, c })
    }

    fn map2_helper(&mut self, name: &'static str, a: &Val, b: &Val) -> R<Val> {
        let vary = a.vary || b.vary;
        let mut c = Vec::new();
        for (x, y) in a.c.iter().zip(&b.c) {
            c.push(self.call_helper(name, &[*x, *y], vary)?[0]);
        }
        Ok(Val { vary, c })
    }

    fn map1(&mut self, v: &Val, f: fn(&mut FunctionBuilder<'_>, Value) -> Value) -> Val {
        Val { vary: v.vary, c: v.c.iter().map(|x| f(&mut self.b, *x)).collect() }
    }

    /// Component-wise over operands widened to one shape; a one-component operand is broadcast.
    fn mapn(&mut self, vals: &[&Val], f: impl Fn(&mut FunctionBuilder<'_>, &[Value]) -> Value) -> Val {
        let vary = vals.iter().any(|v| v.vary);
        let n = vals.iter().map(|v| v.c.len()).max().unwrap_or(0);
        let mut c = Vec::with_capacity(n);
        for k in 0..n {
            let args: Vec<Value> = vals
                .iter()
                .map(|v| {
                    let x = if v.c.len() == 1 { v.c[0] } else { v.c[k] };
                    widen(&mut self.b, x, vary)
                })
                .collect();
            c.push(f(&mut self.b, &args));
        }
        Val { vary, c }
    }

    fn builtin(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        let mark = self.split_keys.len();
        let r = self.builtin_once(bi, overload, args, e);
        for k in self.split_keys.split_off(mark) {
            self.cache.remove(&k);
        }
        r
    }

    fn builtin_once(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        use Builtin as Bi;
        if let Some(r) = self.split_strings(bi, overload, args, e)? {
            return Ok(r);
        }
        if let Some(r) = self.builtin_ext(bi, overload, args, e)? {
            return Ok(r);
        }
        let f = self.func();
        let supported = matches!(
            bi,
            Bi::Abs
                | Bi::Sign
                | Bi::Floor
                | Bi::Ceil
                | Bi::Round
                | Bi::Sqrt
                | Bi::InverseSqrt
                | Bi::Exp
                | Bi::Log
                | Bi::Pow
                | Bi::Sin
                | Bi::Cos
                | Bi::Tan
                | Bi::Asin
                | Bi::Acos
                | Bi::Atan
                | Bi::Radians
                | Bi::Degrees
                | Bi::Mod
                | Bi::Min
                | Bi::Max
                | Bi::Clamp
                | Bi::Mix
                | Bi::Step
                | Bi::Smoothstep
                | Bi::Noise
                | Bi::Cellnoise
                | Bi::Xcomp
                | Bi::Ycomp
                | Bi::Zcomp
                | Bi::SetXcomp
                | Bi::SetYcomp
                | Bi::SetZcomp
                | Bi::Length
                | Bi::Normalize
                | Bi::Distance
                | Bi::Ptlined
                | Bi::Faceforward
                | Bi::Reflect
                | Bi::Specularbrdf
                | Bi::Comp
                | Bi::SetComp
        );
        if !supported {
            return unsupported(format!("the built-in {}", bi.name()));
        }
        let mut vals = Vec::with_capacity(args.len());
        let mut refs = Vec::with_capacity(args.len());
        for a in args {
            match a {
                Arg::Value(x) => {
                    if components(f.expr(*x).ty).is_none() {
                        return unsupported(format!("{} with a {} argument", bi.name(), f.expr(*x).ty));
                    }
                    vals.push(self.expr(*x)?);
                    refs.push(None);
                }
                Arg::Ref(p) => {
                    if components(p.ty).is_none() {
                        return unsupported(format!("{} with a {} argument", bi.name(), p.ty));
                    }
                    let t = self.place_targets(p)?;
                    vals.push(self.read_targets(&t)?);
                    refs.push(Some(t));
                }
            }
        }
        let v = |i: usize| vals[i].clone();
        let void = Val { vary: false, c: Vec::new() };
        let r = match bi {
            Bi::Abs => self.map1(&v(0), |b, x| b.ins().fabs(x)),
            Bi::Sign => self.map1(&v(0), math::sign),
            Bi::Floor => self.map1(&v(0), |b, x| b.ins().floor(x)),
            Bi::Ceil => self.map1(&v(0), |b, x| b.ins().ceil(x)),
            Bi::Round => self.map1(&v(0), math::round),
            Bi::Sqrt => self.map1(&v(0), math::sqrt),
            Bi::InverseSqrt => self.map1(&v(0), math::inversesqrt),
            Bi::Exp => self.map_helper("rtsl_exp", &v(0))?,
            Bi::Log if vals.len() == 2 => self.map2_helper("rtsl_logb", &v(0), &v(1))?,
            Bi::Log => self.map_helper("rtsl_log", &v(0))?,
            Bi::Pow => self.map2_helper("rtsl_pow", &v(0), &v(1))?,
            Bi::Sin => self.sin_cos(&v(0), 0)?,
            Bi::Cos => self.sin_cos(&v(0), 1)?,
            Bi::Tan => self.map_helper("rtsl_tan", &v(0))?,
            Bi::Asin => self.map_helper("rtsl_asin", &v(0))?,
            Bi::Acos => self.map_helper("rtsl_acos", &v(0))?,
            Bi::Atan if vals.len() == 2 => self.map2_helper("rtsl_atan2", &v(0), &v(1))?,
            Bi::Atan => self.map_helper("rtsl_atan", &v(0))?,
            Bi::Radians | Bi::Degrees => {
                let k = if bi == Bi::Radians { 1.0f32.to_radians() } else { 1.0f32.to_degrees() };
                let a = v(0);
                let kc = self.fconst(k, a.vary);
                Val { vary: a.vary, c: a.c.iter().map(|x| self.b.ins().fmul(*x, kc)).collect() }
            }
            Bi::Mod => self.mapn(&[&v(0), &v(1)], |b, a| math::modulo(b, a[0], a[1])),
            Bi::Min | Bi::Max => {
                let mut acc = v(0);
                for x in &vals[1..] {
                    acc = if bi == Bi::Min {
                        self.mapn(&[&acc, x], |b, a| math::min(b, a[0], a[1]))
                    } else {
                        self.mapn(&[&acc, x], |b, a| math::max(b, a[0], a[1]))
                    };
                }
                acc
            }
            Bi::Clamp => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::clamp(b, a[0], a[1], a[2])),
            Bi::Mix => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::mix(b, a[0], a[1], a[2])),
            Bi::Step => self.mapn(&[&v(0), &v(1)], |b, a| math::step(b, a[0], a[1])),
            Bi::Smoothstep => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::smoothstep(b, a[0], a[1], a[2])),
            Bi::Noise | Bi::Cellnoise => {
                let first_triple = args.first().is_some_and(|a| match a {
                    Arg::Value(x) => f.expr(*x).ty.base.is_triple(),
                    Arg::Ref(p) => p.ty.base.is_triple(),
                });
                let dims = if first_triple { 2 + vals.len() } else { vals.len() };
                let triple = e.ty.base != BaseType::Float;
                let name: &'static str = match (bi == Bi::Noise, triple, dims) {
                    (true, false, 1) => "rtsl_noise1",
                    (true, false, 2) => "rtsl_noise2",
                    (true, false, 3) => "rtsl_noise3",
                    (true, false, _) => "rtsl_noise4",
                    (true, true, 1) => "rtsl_vnoise1",
                    (true, true, 2) => "rtsl_vnoise2",
                    (true, true, 3) => "rtsl_vnoise3",
                    (true, true, _) => "rtsl_vnoise4",
                    (false, false, 1) => "rtsl_cellnoise1",
                    (false, false, 2) => "rtsl_cellnoise2",
                    (false, false, 3) => "rtsl_cellnoise3",
                    (false, false, _) => "rtsl_cellnoise4",
                    (false, true, 1) => "rtsl_vcellnoise1",
                    (false, true, 2) => "rtsl_vcellnoise2",
                    (false, true, 3) => "rtsl_vcellnoise3",
                    (false, true, _) => "rtsl_vcellnoise4",
                };
                let all = self.concat(&vals);
                let c = self.call_helper(name, &all.c, all.vary)?;
                Val { vary: all.vary, c }
            }
            Bi::Xcomp | Bi::Ycomp | Bi::Zcomp => {
                let k = [Bi::Xcomp, Bi::Ycomp, Bi::Zcomp].iter().position(|x| *x == bi).unwrap_or(0);
                Val { vary: vals[0].vary, c: vec![vals[0].c[k]] }
            }
            Bi::SetXcomp | Bi::SetYcomp | Bi::SetZcomp => {
                let k = [Bi::SetXcomp, Bi::SetYcomp, Bi::SetZcomp].iter().position(|x| *x == bi).unwrap_or(0);
                let mut t = v(0);
                let x = v(1);
                let vary = t.vary || x.vary;
                t.c[k] = x.c[0];
                let t = self.concat(&[Val { vary, c: t.c }]);
                self.write_ref(&refs, &t)?;
                void
            }
            Bi::Comp | Bi::SetComp if vals[0].c.len() != 3 => {
                return unsupported("matrices");
            }
            Bi::Comp => {
                let idx = self.arg_index(args, 1, &vals[1], 3);
                self.select_elem(&v(0), 1, idx)?
            }
            Bi::SetComp => {
                let idx = self.arg_index(args, 1, &vals[1], 3);
                let t = v(0);
                let x = v(2);
                let vary = t.vary || x.vary || matches!(idx, Idx::Dyn(i) if is_vec(&self.b, i));
                let mut c = Vec::new();
                for j in 0..3 {
                    c.push(match self.idx_cond(idx, j) {
                        None => t.c[j],
                        Some(None) => x.c[0],
                        Some(Some(cond)) => choose(&mut self.b, cond, x.c[0], t.c[j]),
                    });
                }
                let t = self.concat(&[Val { vary, c }]);
                self.write_ref(&refs, &t)?;
                void
            }
            Bi::Length => {
                let a = v(0);
                let d = self.dot(&a.c, &a.c);
                Val { vary: a.vary, c: vec![self.b.ins().sqrt(d)] }
            }
            Bi::Distance => {
                let d = self.binary(BinaryOp::Sub, Type::POINT, &v(0), &v(1))?;
                let s = self.dot(&d.c, &d.c);
                Val { vary: d.vary, c: vec![self.b.ins().sqrt(s)] }
            }
            Bi::Normalize => {
                let a = v(0);
                let d = self.dot(&a.c, &a.c);
                let len = self.b.ins().sqrt(d);
                let zero = konst(&mut self.b, 0.0, len);
                let one = konst(&mut self.b, 1.0, len);
                let is0 = self.b.ins().fcmp(FloatCC::Equal, len, zero);
                let inv = self.b.ins().fdiv(one, len);
                let c =
                    a.c.iter()
                        .map(|x| {
                            let s = self.b.ins().fmul(*x, inv);
                            choose(&mut self.b, is0, *x, s)
                        })
                        .collect();
                Val { vary: a.vary, c }
            }
            Bi::Ptlined => {
                let all = self.concat(&vals);
                let c = self.call_helper("rtsl_ptlined", &all.c, all.vary)?;
                Val { vary: all.vary, c }
            }
            Bi::Specularbrdf => {
                // A colour whose three components are the one weight.
                let all = self.concat(&vals);
                let w = self.call_helper("rtsl_specularbrdf", &all.c, all.vary)?;
                Val { vary: all.vary, c: vec![w[0], w[0], w[0]] }
            }
            Bi::Faceforward => {
                let nref = if vals.len() == 3 {
                    v(2)
                } else {
                    let g = Global::lookup("Ng").ok_or_else(|| JitError::Codegen("Ng".into()))?;
                    let s = self.store_of(PlaceBase::Global(g))?;
                    self.read_store(&s)
                };
                let (n, i) = (v(0), v(1));
                let vary = n.vary || i.vary || nref.vary;
                let iw: Vec<Value> = i.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let rw: Vec<Value> = nref.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let d = self.dot(&iw, &rw);
                let zero = konst(&mut self.b, 0.0, d);
                let flip = self.b.ins().fcmp(FloatCC::GreaterThan, d, zero);
                let c =
                    n.c.iter()
                        .map(|x| {
                            let neg = self.b.ins().fneg(*x);
                            choose(&mut self.b, flip, neg, *x)
                        })
                        .collect();
                Val { vary, c }
            }
            Bi::Reflect => {
                let (i, n) = (v(0), v(1));
                let vary = i.vary || n.vary;
                let iw: Vec<Value> = i.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let nw: Vec<Value> = n.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let d = self.dot(&iw, &nw);
                let two = konst(&mut self.b, 2.0, d);
                let s = self.b.ins().fmul(two, d);
                let c = iw
                    .iter()
                    .zip(&nw)
                    .map(|(p, q)| {
                        let m = self.b.ins().fmul(*q, s);
                        self.b.ins().fsub(*p, m)
                    })
                    .collect();
                Val { vary, c }
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }

    fn arg_index(&mut self, args: &[Arg], k: usize, v: &Val, n: usize) -> Idx {
        if let Some(Arg::Value(x)) = args.get(k) {
            if let ExprKind::Const(Constant::Float(c)) = self.func().expr(*x).kind {
                return Idx::Const(const_index(c, n));
            }
        }
        self.dyn_index(v.c[0], n)
    }

    fn write_ref(&mut self, refs: &[Option<Targets>], v: &Val) -> R<()> {
        match refs.first() {
            Some(Some(t)) => self.write_targets(t, v),
            _ => Err(JitError::Codegen("output argument".into())),
        }
    }
}

/// Whether variable `var` of `f` is assigned anywhere in `f` (directly or as an output argument).
fn assigned(f: &Function, var: usize) -> bool {
    let hit = |p: &Place| p.base == PlaceBase::Var(ir::VarId(var as u32));
    f.exprs.iter().any(|e| match &e.kind {
        ExprKind::Assign { place, .. } => hit(place),
        ExprKind::Call { args, .. } | ExprKind::CallBuiltin { args, .. } => {
            args.iter().any(|a| matches!(a, Arg::Ref(p) if hit(p)))
        }
        _ => false,
    })
}

/// Whether a `return` in `blk` can run under a varying condition (`vdepth > 0`).
fn divergent_return(f: &Function, blk: &ir::Block, vdepth: u32) -> bool {
    blk.stmts.iter().any(|s| match &s.kind {
        StmtKind::Return(_) => vdepth > 0,
        StmtKind::If { cond, then, otherwise } => {
            let d = vdepth + u32::from(f.expr(*cond).varying);
            divergent_return(f, then, d) || divergent_return(f, otherwise, d)
        }
        StmtKind::Loop { cond, body, step } => {
            let d = vdepth + u32::from(cond.is_some_and(|c| f.expr(c).varying));
            divergent_return(f, body, d) || divergent_return(f, step, d)
        }
        _ => false,
    })
}

/// Whether a loop's body or step can leave the loop (or an outer one) or continue it under a
/// varying condition, so that its lanes part ways.
fn divergent_exit(f: &Function, body: &ir::Block, step: &ir::Block) -> bool {
    fn walk(f: &Function, blk: &ir::Block, vdepth: u32, nest: u32) -> bool {
        blk.stmts.iter().any(|s| match &s.kind {
            StmtKind::Break(n) | StmtKind::Continue(n) => *n > nest && vdepth > 0,
            StmtKind::If { cond, then, otherwise } => {
                let d = vdepth + u32::from(f.expr(*cond).varying);
                walk(f, then, d, nest) || walk(f, otherwise, d, nest)
            }
            StmtKind::Loop { cond, body, step } => {
                let d = vdepth + u32::from(cond.is_some_and(|c| f.expr(c).varying));
                walk(f, body, d, nest + 1) || walk(f, step, d, nest + 1)
            }
            _ => false,
        })
    }
    walk(f, body, 0, 0) || walk(f, step, 0, 0)
}

/// The `"name", value` pairs after the fixed arguments: the value of `name` (names must be constants).
fn param_arg<'m>(f: &'m Function, args: &'m [Arg], fixed: usize, name: &str) -> R<Option<&'m Arg>> {
    let rest = args.get(fixed..).unwrap_or(&[]);
    for pair in rest.chunks(2) {
        let [Arg::Value(n), v] = pair else { continue };
        match &f.expr(*n).kind {
            ExprKind::Const(Constant::String(s)) if s == name => return Ok(Some(v)),
            ExprKind::Const(Constant::String(_)) => {}
            _ => return unsupported("a parameter list with computed names"),
        }
    }
    Ok(None)
}

impl<'m> Lower<'m, '_> {
    fn string_handle(&mut self, s: &str) -> u32 {
        match self.strings.iter().position(|x| x == s) {
            Some(h) => h as u32,
            None => {
                self.strings.push(s.to_string());
                (self.strings.len() - 1) as u32
            }
        }
    }

    fn const_string(&mut self, s: &str) -> Val {
        let h = self.string_handle(s);
        Val { vary: false, c: vec![self.b.ins().f32const(f32::from_bits(h))] }
    }

    fn arg_val(&mut self, a: &Arg) -> R<Val> {
        match a {
            Arg::Value(x) => self.expr(*x),
            Arg::Ref(p) => {
                let t = self.place_targets(p)?;
                self.read_targets(&t)
            }
        }
    }

    /// The matrix from space `from` to `to` (uniform) and whether the renderer knows it.
    fn space_matrix(&mut self, from: &Val, to: &Val) -> R<(Val, Value)> {
        if from.vary || to.vary {
            return unsupported("varying space names");
        }
        let names = constant_bits(&self.b, from.c[0]).zip(constant_bits(&self.b, to.c[0]));
        if let (Some(names), Some(known)) = (names, &self.prologue_matrices) {
            if let Some((_, m)) = known.iter().find(|(k, _)| *k == names) {
                return Ok(m.clone());
            }
        }
        let out = self.call_helper("rtsl_h_matrix", &[from.c[0], to.c[0]], false)?;
        let zero = self.b.ins().f32const(0.0);
        let ok = self.b.ins().fcmp(FloatCC::NotEqual, out[16], zero);
        let m = (Val { vary: false, c: out[..16].to_vec() }, ok);
        if let (Some(names), Some(known)) = (names, &mut self.prologue_matrices) {
            known.push((names, m.clone()));
        }
        Ok(m)
    }

    /// A built-in whose string arguments differ between lanes (a texture name, a space, a light
    /// category per lane) runs once per distinct string: the first string argument that is
    /// varying is evaluated once, then each round takes the string of the first pending lane, runs
    /// the call under the lanes holding that string (with it as a uniform argument: the call may
    /// split again on another string argument), and merges the result under those lanes. `None`
    /// when no string argument varies; string arguments are then left evaluated in `cache`.
    /// `concat`, `match`, `format` and `printf` need no split: their helpers read every lane's
    /// strings.
    fn split_strings(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Option<Val>> {
        use Builtin as Bi;
        if matches!(bi, Bi::Concat | Bi::Match | Bi::Format | Bi::Printf) {
            return Ok(None);
        }
        let f = self.func();
        let depth = self.frames.len();
        let strings: Vec<ExprId> = args
            .iter()
            .filter_map(|a| match a {
                Arg::Value(x) if f.expr(*x).ty.base == BaseType::String => Some(*x),
                _ => None,
            })
            .collect();
        let mut split = None;
        for x in &strings {
            let v = match self.cache.get(&(depth, x.0)) {
                Some(v) => v.clone(),
                None => {
                    let v = self.expr(*x)?;
                    self.cache.insert((depth, x.0), v.clone());
                    self.split_keys.push((depth, x.0));
                    v
                }
            };
            if v.vary && split.is_none() {
                split = Some((*x, v));
            }
        }
        let Some((x, names)) = split else { return Ok(None) };
        let comps = match e.ty.base {
            BaseType::Void => 0,
            _ => components(e.ty).ok_or_else(|| JitError::Unsupported(format!("a built-in returning {}", e.ty)))?,
        };
        let save = self.exec();
        self.div += 1;
        self.vdepth += 1;
        let pending = self.b.declare_var(types::I32X4);
        self.b.def_var(pending, save);
        let acc: Vec<Variable> = (0..comps).map(|_| self.b.declare_var(types::F32X4)).collect();
        let zero = self.fconst(0.0, true);
        for a in &acc {
            self.b.def_var(*a, zero);
        }
        let (header, body, done) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let p = self.b.use_var(pending);
        let live = any(&mut self.b, p);
        self.b.ins().brif(live, body, &[], done, &[]);

        self.b.switch_to_block(body);
        let flags = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
        let handles = self.b.ins().bitcast(types::I32X4, flags, names.c[0]);
        // The handle of the first pending lane.
        let mut h = self.b.ins().extractlane(handles, 3);
        for l in (0..3u8).rev() {
            let on = self.b.ins().extractlane(p, l);
            let hl = self.b.ins().extractlane(handles, l);
            h = self.b.ins().select(on, hl, h);
        }
        let hs = self.b.ins().splat(types::I32X4, h);
        let same = self.b.ins().icmp(IntCC::Equal, handles, hs);
        let m = self.b.ins().band(p, same);
        self.set_exec(m);
        let one = self.b.ins().bitcast(types::F32, flags, h);
        self.cache.insert((depth, x.0), Val { vary: false, c: vec![one] });
        let r = self.builtin(bi, overload, args, e);
        self.cache.insert((depth, x.0), names);
        let r = r?;
        for (a, c) in acc.iter().zip(&r.c) {
            let old = self.b.use_var(*a);
            let new = merge(&mut self.b, m, *c, old);
            self.b.def_var(*a, new);
        }
        let rest = self.b.ins().band_not(p, m);
        self.b.def_var(pending, rest);
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(done);
        self.div -= 1;
        self.vdepth -= 1;
        self.set_exec(save);
        let c = acc.iter().map(|a| self.b.use_var(*a)).collect();
        Ok(Some(Val { vary: true, c }))
    }

    /// `helper(a, b)` where `ok`, else `fallback` (of the result's size).
    fn apply_if(&mut self, helper: &'static str, ok: Value, a: &Val, b: &Val, fallback: &Val) -> R<Val> {
        if let Some(point) = match helper {
            "rtsl_xform_point" => Some(true),
            "rtsl_xform_vector" => Some(false),
            _ => None,
        } {
            let vary = a.vary || b.vary || fallback.vary;
            if vary && !is_vec(&self.b, ok) {
                // A uniform lookup result: one branch around the transform, not a blend per
                // component in every chunk.
                let ty = types::F32X4;
                let (found, join) = (self.b.create_block(), self.b.create_block());
                let params: Vec<Value> = fallback.c.iter().map(|_| self.b.append_block_param(join, ty)).collect();
                let kept: Vec<cranelift_codegen::ir::BlockArg> =
                    fallback.c.iter().map(|x| widen(&mut self.b, *x, true).into()).collect();
                self.b.ins().brif(ok, found, &[], join, &kept);
                self.b.switch_to_block(found);
                self.b.seal_block(found);
                let r = self.transform_inline(a, b, point);
                let made: Vec<cranelift_codegen::ir::BlockArg> =
                    r.c.iter().map(|x| widen(&mut self.b, *x, true).into()).collect();
                self.b.ins().jump(join, &made);
                self.b.switch_to_block(join);
                self.b.seal_block(join);
                return Ok(Val { vary: true, c: params });
            }
            let r = self.transform_inline(a, b, point);
            let c = r.c.iter().zip(&fallback.c).map(|(x, y)| choose(&mut self.b, ok, *x, *y)).collect();
            return Ok(Val { vary: r.vary || fallback.vary, c });
        }
        let all = self.concat(&[a.clone(), b.clone()]);
        let r = self.call_helper(helper, &all.c, all.vary)?;
        let c = r.iter().zip(&fallback.c).map(|(x, y)| choose(&mut self.b, ok, *x, *y)).collect();
        Ok(Val { vary: all.vary || fallback.vary, c })
    }

    /// `p` times the 4x4 matrix `m` in the code itself, by the operations of
    /// `shadeops::matrix::transform_point` (or `transform_vector`, without translation and divide)
    /// in their order, so the same bits: a helper call would move 19 values a lane through memory
    /// for 12 multiply-adds, and space casts sit in the inner loops of most shaders.
    fn transform_inline(&mut self, m: &Val, p: &Val, point: bool) -> Val {
        let vary = m.vary || p.vary;
        // The matrix's own (scalar) entries when it is uniform.
        let uniform_m = (!m.vary).then(|| m.c.clone());
        let m: Vec<Value> = m.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
        let p: Vec<Value> = p.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
        let mut out: Vec<Value> = (0..3).map(|j| self.transform_column(&m, &p, j, point)).collect();
        if !point {
            return Val { vary, c: out };
        }
        match uniform_m {
            // A uniform affine matrix (last column 0 0 0 1) makes w 1, or NaN where p is not
            // finite: no division either way, so that case skips the w column and the divisions
            // (space casts to "camera" or "shader" space are mostly of this kind).
            Some(um) => {
                let ty = self.b.func.dfg.value_type(out[0]);
                let vars: Vec<Variable> = out
                    .iter()
                    .map(|x| {
                        let v = self.b.declare_var(ty);
                        self.b.def_var(v, *x);
                        v
                    })
                    .collect();
                let mut affine = None;
                for (k, want) in [(3, 0.0), (7, 0.0), (11, 0.0), (15, 1.0)] {
                    let c = self.b.ins().f32const(want);
                    let eq = self.b.ins().fcmp(FloatCC::Equal, um[k], c);
                    affine = Some(match affine {
                        Some(a) => self.b.ins().band(a, eq),
                        None => eq,
                    });
                }
                let affine = affine.expect("four entries");
                let (divide_b, join) = (self.b.create_block(), self.b.create_block());
                self.b.ins().brif(affine, join, &[], divide_b, &[]);
                self.b.switch_to_block(divide_b);
                let divided = self.divide_by_w(&m, &p, &out);
                for (v, x) in vars.iter().zip(divided) {
                    self.b.def_var(*v, x);
                }
                self.b.ins().jump(join, &[]);
                self.b.switch_to_block(join);
                out = vars.iter().map(|v| self.b.use_var(*v)).collect();
            }
            None => out = self.divide_by_w(&m, &p, &out),
        }
        Val { vary, c: out }
    }

    /// Column `j` of `p` (with a 1 appended for a point) times `m`, in `transform_point`'s order.
    fn transform_column(&mut self, m: &[Value], p: &[Value], j: usize, point: bool) -> Value {
        let mut sum = self.b.ins().fmul(p[0], m[j]);
        for (k, pk) in p.iter().enumerate().skip(1) {
            let term = self.b.ins().fmul(*pk, m[4 * k + j]);
            sum = self.b.ins().fadd(sum, term);
        }
        if point {
            sum = self.b.ins().fadd(sum, m[12 + j]);
        }
        sum
    }

    /// `xyz` divided by the point's w (`transform_column` 3) unless w is 1, 0 or not finite.
    fn divide_by_w(&mut self, m: &[Value], p: &[Value], xyz: &[Value]) -> Vec<Value> {
        let w = self.transform_column(m, p, 3, true);
        let one = konst(&mut self.b, 1.0, w);
        let zero = konst(&mut self.b, 0.0, w);
        let inf = konst(&mut self.b, f32::INFINITY, w);
        let not_one = self.b.ins().fcmp(FloatCC::NotEqual, w, one);
        let not_zero = self.b.ins().fcmp(FloatCC::NotEqual, w, zero);
        let abs = self.b.ins().fabs(w);
        let finite = self.b.ins().fcmp(FloatCC::LessThan, abs, inf);
        let divide = and(&mut self.b, not_one, not_zero);
        let divide = and(&mut self.b, divide, finite);
        xyz.iter()
            .map(|x| {
                let q = self.b.ins().fdiv(*x, w);
                choose(&mut self.b, divide, q, *x)
            })
            .collect()
    }

    /// `spline([basis,] x, knots... | knots[])`: the host helper finds each lane's segment and its
    /// four weights (`shadeops::spline::Basis::weights`, the interpreter's code); the knots are
    /// selected per lane and summed here in the interpreter's order
    /// (`w0 k[s] + w1 k[s+1] + w2 k[s+2] + w3 k[s+3]`). Fewer than 4 knots give the first one.
    fn spline(&mut self, args: &[Arg], vals: &[Val], e: &ir::Expr) -> R<Val> {
        let f = self.func();
        let has_basis = match &args[0] {
            Arg::Value(x) => f.expr(*x).ty.base == BaseType::String,
            Arg::Ref(p) => p.ty.base == BaseType::String,
        };
        let (basis, rest) = if has_basis { (vals[0].clone(), 1) } else { (self.const_string(""), 0) };
        if basis.vary {
            return unsupported("varying strings");
        }
        let x = vals[rest].clone();
        let comps = if e.ty.base == BaseType::Float { 1 } else { 3 };
        let knots = self.concat(&vals[rest + 1..]);
        let n = knots.c.len() / comps;
        if n < 4 {
            return Ok(match n {
                0 => Val { vary: false, c: vec![self.fconst(0.0, false); comps] },
                _ => Val { vary: knots.vary, c: knots.c[..comps].to_vec() },
            });
        }
        let nv = self.fconst(n as f32, false);
        let w = self.call_helper("rtsl_h_spline", &[basis.c[0], x.c[0], nv], x.vary)?;
        let vary = x.vary || knots.vary;
        let w: Vec<Value> = w.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let k: Vec<Value> = knots.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        // Segment starts 1..=n-4 (0 is the default of every select).
        let mut at = Vec::with_capacity(n - 3);
        for s in 1..=n - 4 {
            let sc = konst(&mut self.b, s as f32, w[0]);
            at.push(self.b.ins().fcmp(FloatCC::Equal, w[0], sc));
        }
        let mut c = Vec::with_capacity(comps);
        for j in 0..comps {
            let mut sum: Option<Value> = None;
            for i in 0..4 {
                let mut pick = k[i * comps + j];
                for (s, eq) in at.iter().enumerate() {
                    pick = choose(&mut self.b, *eq, k[(s + 1 + i) * comps + j], pick);
                }
                let term = self.b.ins().fmul(w[1 + i], pick);
                sum = Some(match sum {
                    None => term,
                    Some(acc) => self.b.ins().fadd(acc, term),
                });
            }
            c.push(sum.expect("four terms"));
        }
        Ok(Val { vary, c })
    }

    /// The prologue's matrix for the space name `space`, in the shader body itself.
    fn batch_matrix(&self, space: ExprId) -> Option<(Val, Value)> {
        if self.frames.len() == 1 {
            self.batch_matrices.get(&space.0).cloned()
        } else {
            None
        }
    }

    /// `v` cast from `space` to "current"; `matrix` is that transform when already known.
    fn space_cast(&mut self, ty: BaseType, space: &Val, v: Val, matrix: Option<(Val, Value)>) -> R<Val> {
        if ty == BaseType::Color {
            if space.vary {
                return unsupported("varying space names");
            }
            let all = self.concat(&[space.clone(), v]);
            let c = self.call_helper("rtsl_h_to_rgb", &all.c, all.vary)?;
            return Ok(Val { vary: all.vary, c });
        }
        let (m, ok) = match matrix {
            Some(m) => m,
            None => {
                let current = self.const_string("current");
                self.space_matrix(space, &current)?
            }
        };
        match ty {
            // mul(v, m): the value first.
            BaseType::Matrix => self.apply_if("rtsl_mmul", ok, &v, &m, &v),
            BaseType::Point => self.apply_if("rtsl_xform_point", ok, &m, &v, &v),
            BaseType::Vector => self.apply_if("rtsl_xform_vector", ok, &m, &v, &v),
            BaseType::Normal => self.apply_if("rtsl_xform_normal", ok, &m, &v, &v),
            _ => unsupported(format!("a space cast of {ty}")),
        }
    }

    /// Built-ins of the later slices (matrices, the renderer's services); `None` for the others.
    fn builtin_ext(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Option<Val>> {
        use Builtin as Bi;
        let f = self.func();
        let sig = &crate::builtins::signatures(bi)[overload as usize];
        let fixed = if sig.repeat_last { args.len() } else { sig.params.len().min(args.len()) };
        let is_matrix_arg = |k: usize| match args.get(k) {
            Some(Arg::Value(x)) => f.expr(*x).ty.base == BaseType::Matrix,
            Some(Arg::Ref(p)) => p.ty.base == BaseType::Matrix,
            None => false,
        };
        let handled = match bi {
            Bi::Comp | Bi::SetComp => is_matrix_arg(0),
            Bi::Rotate => e.ty.base == BaseType::Matrix || args.len() == 4,
            Bi::Determinant
            | Bi::Translate
            | Bi::Scale
            | Bi::Transform
            | Bi::Vtransform
            | Bi::Ntransform
            | Bi::Mtransform
            | Bi::Ctransform
            | Bi::Refract
            | Bi::Fresnel
            | Bi::Depth
            | Bi::Raydepth
            | Bi::Shadername
            | Bi::Ambient
            | Bi::Diffuse
            | Bi::Specular
            | Bi::Phong
            | Bi::Texture
            | Bi::Environment
            | Bi::Shadow
            | Bi::Texture3d
            | Bi::Bump
            | Bi::Bake3d
            | Bi::Photonmap
            | Bi::Pixelvalue
            | Bi::Trace
            | Bi::Transmission
            | Bi::Visibility
            | Bi::Occlusion
            | Bi::Indirectdiffuse
            | Bi::Atmosphere
            | Bi::Displacement
            | Bi::Lightsource
            | Bi::Surface
            | Bi::Incident
            | Bi::Opposite
            | Bi::Attribute
            | Bi::Option
            | Bi::Rendererinfo
            | Bi::Rayinfo
            | Bi::Textureinfo
            | Bi::Spline
            | Bi::Pnoise
            | Bi::Filterstep
            | Bi::Random
            | Bi::Concat
            | Bi::Format
            | Bi::Printf
            | Bi::Match => true,
            _ => false,
        };
        if !handled {
            return Ok(None);
        }
        // Message passing evaluates the name, then reads nothing else before the call.
        if matches!(
            bi,
            Bi::Atmosphere
                | Bi::Displacement
                | Bi::Lightsource
                | Bi::Surface
                | Bi::Incident
                | Bi::Opposite
                | Bi::Attribute
                | Bi::Option
                | Bi::Rendererinfo
                | Bi::Rayinfo
                | Bi::Textureinfo
        ) {
            return self.message(bi, args, e).map(Some);
        }
        // Fixed arguments, left to right (parameter lists: the whole list, in order).
        let mut vals = Vec::with_capacity(args.len());
        let mut refs = Vec::with_capacity(args.len());
        for a in args {
            match a {
                Arg::Value(x) => {
                    vals.push(self.expr(*x)?);
                    refs.push(None);
                }
                Arg::Ref(p) => {
                    let t = self.place_targets(p)?;
                    vals.push(self.read_targets(&t)?);
                    refs.push(Some(t));
                }
            }
        }
        let v = |i: usize| vals[i].clone();
        let void = Val { vary: false, c: Vec::new() };
        // In uniform mode the IR's flag describes the callee's general case, not this call: only
        // the built-in's own variation (`random`, ...) and the actual operands count.
        let ir_varying =
            if self.frame().uniform { bi.flags() & crate::builtins::flags::VARYING != 0 } else { e.varying };
        let mut vary = ir_varying || vals.iter().any(|x| x.vary);
        let helper = |s: &mut Self, name: &'static str, parts: &[Val], vary: bool| -> R<Val> {
            let all = s.concat(parts);
            let c = s.call_helper(name, &all.c, vary || all.vary)?;
            Ok(Val { vary: vary || all.vary, c })
        };
        let global = |s: &mut Self, name: &str| -> R<Val> {
            let g = Global::lookup(name).ok_or_else(|| JitError::Codegen(name.into()))?;
            let st = s.store_of(PlaceBase::Global(g))?;
            Ok(s.read_store(&st))
        };
        let r = match bi {
            Bi::Spline => self.spline(args, &vals, e)?,
            Bi::Pnoise => {
                let first_triple = vals[0].c.len() == 3;
                let name: &'static str = match (e.ty.base != BaseType::Float, first_triple, vals.len()) {
                    (false, false, 4) => "rtsl_pnoise2",
                    (false, false, _) => "rtsl_pnoise1",
                    (false, true, 4) => "rtsl_pnoise4",
                    (false, true, _) => "rtsl_pnoise3",
                    (true, false, 4) => "rtsl_vpnoise2",
                    (true, false, _) => "rtsl_vpnoise1",
                    (true, true, 4) => "rtsl_vpnoise4",
                    (true, true, _) => "rtsl_vpnoise3",
                };
                helper(self, name, &vals, false)?
            }
            Bi::Filterstep => {
                let (edge, x) = (v(0), v(1));
                let width = if fixed == 3 {
                    let d = self.binary(BinaryOp::Sub, Type::FLOAT, &v(2), &x)?;
                    self.map1(&d, |b, w| b.ins().fabs(w))
                } else {
                    match param_arg(f, args, fixed, "width")? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            vals[i].clone()
                        }
                        None => self.filter_width(1)?,
                    }
                };
                helper(self, "rtsl_filterstep", &[edge, x, width], false)?
            }
            Bi::Random => {
                let slot = self.layout.seed.ok_or_else(|| JitError::Codegen("no seed slots".into()))?;
                let lo = self.load_slot(true, slot);
                let hi = self.load_slot(true, slot + 1);
                let calls = self.b.use_var(self.random_calls);
                let name = if e.ty.base == BaseType::Float { "rtsl_random" } else { "rtsl_vrandom" };
                let c = self.call_helper(name, &[lo, hi, calls], true)?;
                // Running lanes count the call (exec is -1 there).
                let e = self.exec();
                let next = self.b.ins().isub(calls, e);
                self.b.def_var(self.random_calls, next);
                Val { vary: true, c }
            }
            Bi::Concat => {
                // Each lane's strings (a varying call interns a result per lane).
                let mut acc = v(0);
                for x in &vals[1..] {
                    acc = helper(self, "rtsl_h_concat", &[acc, x.clone()], false)?;
                }
                acc
            }
            Bi::Match => helper(self, "rtsl_h_match", &[v(0), v(1)], false)?,
            Bi::Format | Bi::Printf => {
                let printf = bi == Bi::Printf;
                let mut kinds = Vec::new();
                for a in &args[1..] {
                    let ty = match a {
                        Arg::Value(x) => f.expr(*x).ty,
                        Arg::Ref(p) => p.ty,
                    };
                    if ty.is_array() {
                        return unsupported("an array argument of format or printf");
                    }
                    kinds.push(match ty.base {
                        BaseType::Float => host::FMT_FLOAT,
                        b if b.is_triple() => host::FMT_TRIPLE,
                        BaseType::Matrix => host::FMT_MATRIX,
                        BaseType::String => host::FMT_STRING,
                        BaseType::Bool => host::FMT_BOOL,
                        _ => return unsupported(format!("a {ty} argument of format or printf")),
                    });
                }
                let data: usize = vals[1..].iter().map(|x| x.c.len()).sum();
                let mut header = vec![v(0).c[0]];
                header.push(self.fconst((3 + kinds.len() + data) as f32, false));
                header.push(self.fconst(kinds.len() as f32, false));
                for k in &kinds {
                    header.push(self.fconst(*k as f32, false));
                }
                let mut inputs = header;
                for x in &vals[1..] {
                    inputs.extend(x.c.iter().copied());
                }
                if printf {
                    self.call_helper("rtsl_h_printf", &inputs, true)?;
                    Val { vary: false, c: Vec::new() }
                } else {
                    // A varying call formats and interns each running lane's text.
                    vary = vals.iter().any(|x| x.vary);
                    let c = self.call_helper("rtsl_h_format", &inputs, vary)?;
                    Val { vary, c }
                }
            }
            Bi::Comp => {
                let r = helper(self, "rtsl_mcomp", &[v(0), v(1), v(2)], false)?;
                Val { vary: r.vary, c: r.c }
            }
            Bi::SetComp => {
                let m = helper(self, "rtsl_msetcomp", &[v(0), v(1), v(2), v(3)], false)?;
                self.write_ref(&refs, &m)?;
                void
            }
            Bi::Rotate if e.ty.base == BaseType::Matrix => helper(self, "rtsl_rotate", &[v(0), v(1), v(2)], false)?,
            Bi::Rotate => helper(self, "rtsl_rotate_point", &[v(0), v(1), v(2), v(3)], false)?,
            Bi::Translate => helper(self, "rtsl_translate", &[v(0), v(1)], false)?,
            Bi::Scale => helper(self, "rtsl_scale", &[v(0), v(1)], false)?,
            Bi::Determinant => helper(self, "rtsl_determinant", &[v(0)], false)?,
            Bi::Refract => helper(self, "rtsl_refract", &[v(0), v(1), v(2)], false)?,
            Bi::Fresnel => {
                let r = helper(self, "rtsl_fresnel", &[v(0), v(1), v(2)], false)?;
                let part = |a: usize, b: usize| Val { vary: r.vary, c: r.c[a..b].to_vec() };
                for (k, (a, b)) in [(3, (0, 1)), (4, (1, 2)), (5, (2, 5)), (6, (5, 8))] {
                    if let Some(Some(t)) = refs.get(k) {
                        self.write_targets(t, &part(a, b))?;
                    }
                }
                void
            }
            Bi::Transform | Bi::Vtransform | Bi::Ntransform => {
                let name = match bi {
                    Bi::Transform => "rtsl_xform_point",
                    Bi::Vtransform => "rtsl_xform_vector",
                    _ => "rtsl_xform_normal",
                };
                let p = v(vals.len() - 1);
                let (m, ok) = match vals.len() {
                    2 if is_matrix_arg(0) => {
                        let t = self.b.ins().iconst(types::I8, 1);
                        (v(0), t)
                    }
                    2 => {
                        let cur = self.const_string("current");
                        self.space_matrix(&cur, &v(0))?
                    }
                    _ if is_matrix_arg(1) => {
                        let cur = self.const_string("current");
                        let (to_current, ok) = self.space_matrix(&v(0), &cur)?;
                        let m = helper(self, "rtsl_mmul", &[v(1), to_current], false)?;
                        (m, ok)
                    }
                    _ => self.space_matrix(&v(0), &v(1))?,
                };
                self.apply_if(name, ok, &m, &p, &p)?
            }
            Bi::Mtransform => {
                let m = v(vals.len() - 1);
                let (space, ok) = if vals.len() == 3 {
                    self.space_matrix(&v(0), &v(1))?
                } else {
                    let cur = self.const_string("current");
                    self.space_matrix(&cur, &v(0))?
                };
                self.apply_if("rtsl_mmul", ok, &m, &space, &m)?
            }
            Bi::Ctransform => {
                let c = v(vals.len() - 1);
                let three = vals.len() == 3;
                let b = if three { v(1) } else { v(0) };
                let flag = self.fconst(if three { 1.0 } else { 0.0 }, false);
                let flag = Val { vary: false, c: vec![flag] };
                helper(self, "rtsl_h_ctransform", &[v(0), b, c, flag], false)?
            }
            Bi::Depth => helper(self, "rtsl_h_depth", &[v(0)], true)?,
            Bi::Raydepth => {
                vary = false;
                helper(self, "rtsl_h_raydepth", &[], false)?
            }
            Bi::Shadername => {
                let (kind, has) = if vals.is_empty() { (self.const_string(""), 0.0) } else { (v(0), 1.0) };
                let has = Val { vary: false, c: vec![self.fconst(has, false)] };
                if kind.vary {
                    return unsupported("varying strings");
                }
                vary = false;
                helper(self, "rtsl_h_shadername", &[kind, has], false)?
            }
            Bi::Ambient => {
                let p = global(self, "P")?;
                helper(self, "rtsl_h_ambient", &[p], true)?
            }
            Bi::Diffuse => {
                let p = global(self, "P")?;
                helper(self, "rtsl_h_diffuse", &[p, v(0)], true)?
            }
            Bi::Specular | Bi::Phong => {
                let p = global(self, "P")?;
                let name = if bi == Bi::Specular { "rtsl_h_specular" } else { "rtsl_h_phong" };
                helper(self, name, &[p, v(0), v(1), v(2)], true)?
            }
            Bi::Texture | Bi::Environment | Bi::Shadow => {
                if vals[0].vary {
                    return unsupported("varying texture names");
                }
                let opt = |s: &mut Self, name: &str, default: f32| -> R<Val> {
                    match param_arg(f, args, fixed, name)? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            Ok(vals[i].clone())
                        }
                        None => Ok(Val { vary: false, c: vec![s.fconst(default, false)] }),
                    }
                };
                let n = if e.ty.base == BaseType::Float { 1 } else { 3 };
                match bi {
                    Bi::Texture => {
                        let (s_, t_) = match fixed {
                            1 => (global(self, "s")?, global(self, "t")?),
                            3 => (v(1), v(2)),
                            _ => {
                                // The centre of the four corners: (a + b + c + d) / 4.
                                let sum = |s: &mut Self, ks: [usize; 4]| -> R<Val> {
                                    let mut acc = vals[ks[0]].clone();
                                    for k in &ks[1..] {
                                        acc = s.binary(BinaryOp::Add, Type::FLOAT, &acc, &vals[*k])?;
                                    }
                                    let four = Val { vary: false, c: vec![s.fconst(4.0, false)] };
                                    s.binary(BinaryOp::Div, Type::FLOAT, &acc, &four)
                                };
                                (sum(self, [1, 3, 5, 7])?, sum(self, [2, 4, 6, 8])?)
                            }
                        };
                        let first = opt(self, "channel", 0.0)?;
                        let fill = opt(self, "fill", 0.0)?;
                        let nv = Val { vary: false, c: vec![self.fconst(n as f32, false)] };
                        // The footprint (the interpreter's `footprint`).
                        let width = opt(self, "width", 1.0)?;
                        let sw = if param_arg(f, args, fixed, "swidth")?.is_some() {
                            opt(self, "swidth", 1.0)?
                        } else {
                            width.clone()
                        };
                        let tw = if param_arg(f, args, fixed, "twidth")?.is_some() {
                            opt(self, "twidth", 1.0)?
                        } else {
                            width
                        };
                        let blur = opt(self, "blur", 0.0)?;
                        let d = self.texture_derivs(fixed, &vals)?;
                        let fp: Vec<Val> = d
                            .iter()
                            .enumerate()
                            .map(|(k, x)| {
                                let w = if k % 2 == 0 { &sw } else { &tw };
                                let wv = widen(&mut self.b, w.c[0], true);
                                let c = vec![self.b.ins().fmul(x.c[0], wv)];
                                Val { vary: true, c }
                            })
                            .collect();
                        let mut parts = vec![v(0), s_, t_, first, fill, nv];
                        parts.extend(fp);
                        parts.push(blur);
                        let r = helper(self, "rtsl_h_texture", &parts, true)?;
                        Val { vary: true, c: r.c[..n].to_vec() }
                    }
                    Bi::Environment => {
                        let fill = opt(self, "fill", 0.0)?;
                        let r = helper(self, "rtsl_h_environment", &[v(0), v(1), fill], true)?;
                        Val { vary: true, c: r.c[..n].to_vec() }
                    }
                    _ => {
                        // The interpreter's `shadow_query`: the region, then the options, each
                        // one float ("sblur" over "blur", "swidth" over "width").
                        let given = |name: &str| -> R<bool> { Ok(param_arg(f, args, fixed, name)?.is_some()) };
                        let first = |x: Val| Val { vary: x.vary, c: x.c[..1].to_vec() };
                        let blur = first(opt(self, "blur", 0.0)?);
                        let width = first(opt(self, "width", 1.0)?);
                        let mut inputs = vec![v(0)];
                        inputs.extend(self.shadow_region(&vals, fixed)?);
                        inputs.push(first(opt(self, "samples", 16.0)?));
                        for (name, fallback) in
                            [("sblur", &blur), ("tblur", &blur), ("swidth", &width), ("twidth", &width)]
                        {
                            let x = if given(name)? { first(opt(self, name, 0.0)?) } else { fallback.clone() };
                            inputs.push(x);
                        }
                        inputs.push(first(opt(self, "bias", 0.0)?));
                        let r = helper(self, "rtsl_h_shadow", &inputs, true)?;
                        Val { vary: true, c: vec![r.c[0]; n] }
                    }
                }
            }
            Bi::Bump => {
                let (s, t) = (global(self, "s")?, global(self, "t")?);
                helper(self, "rtsl_h_bump", &[v(0), s, t, v(1), v(2), v(3)], true)?
            }
            // Point clouds: reported once per call site when a lane runs the
            // call, which returns its documented value (the built-in table) and writes nothing.
            Bi::Photonmap => {
                let n = if fixed == 3 { v(2) } else { Val { vary: false, c: vec![self.fconst(0.0, false); 3] } };
                let estimator = match param_arg(f, args, fixed, "estimator")? {
                    Some(a) => {
                        let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                        vals[i].clone()
                    }
                    None => Val { vary: false, c: vec![self.fconst(50.0, false)] },
                };
                if vals[0].vary {
                    return unsupported("varying photon map names");
                }
                helper(self, "rtsl_h_photonmap", &[v(0), v(1), n, estimator], true)?
            }
            Bi::Bake3d | Bi::Texture3d if bi != Bi::Texture3d || fixed != 2 => {
                self.report_unsupported(bi, e.span)?;
                let n = components(e.ty).unwrap_or(1);
                Val { vary: false, c: vec![self.fconst(0.0, false); n] }
            }
            Bi::Texture3d => {
                if vals[0].vary {
                    return unsupported("varying texture names");
                }
                let fill = match param_arg(f, args, fixed, "fill")? {
                    Some(a) => {
                        let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                        vals[i].clone()
                    }
                    None => Val { vary: false, c: vec![self.fconst(0.0, false)] },
                };
                let n = if e.ty.base == BaseType::Float { 1 } else { 3 };
                let r = helper(self, "rtsl_h_texture3d", &[v(0), v(1), fill], true)?;
                Val { vary: true, c: r.c[..n].to_vec() }
            }
            Bi::Trace => {
                let r = helper(self, "rtsl_h_trace", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    Val { vary: true, c: vec![r.c[3]] }
                } else {
                    Val { vary: true, c: r.c[..3].to_vec() }
                }
            }
            Bi::Transmission => helper(self, "rtsl_h_transmission", &[v(0), v(1)], true)?,
            Bi::Pixelvalue => {
                let c = helper(self, "rtsl_h_pixelvalue", &[v(0), v(1), v(2)], true)?;
                if e.ty.base == BaseType::Float {
                    Val { vary: true, c: vec![c.c[0]] }
                } else {
                    c
                }
            }
            Bi::Visibility => {
                let t = helper(self, "rtsl_h_transmission", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    let zero = self.fconst(0.0, true);
                    let mut any_pos = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[0], zero);
                    for k in 1..3 {
                        let c = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[k], zero);
                        any_pos = self.b.ins().bor(any_pos, c);
                    }
                    let one = self.fconst(1.0, true);
                    Val { vary: true, c: vec![choose(&mut self.b, any_pos, one, zero)] }
                } else {
                    t
                }
            }
            Bi::Occlusion | Bi::Indirectdiffuse => {
                let samples = if fixed == 3 {
                    v(2)
                } else {
                    match param_arg(f, args, fixed, "samples")? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            vals[i].clone()
                        }
                        None => Val { vary: false, c: vec![self.fconst(16.0, false)] },
                    }
                };
                let name = if bi == Bi::Occlusion { "rtsl_h_occlusion" } else { "rtsl_h_indirectdiffuse" };
                helper(self, name, &[v(0), v(1), samples], true)?
            }
            _ => return Ok(None),
        };
        if vary && !r.vary {
            return Ok(Some(self.concat(&[Val { vary: true, c: r.c }])));
        }
        Ok(Some(r))
    }

    /// Message passing: `f(name, output dest)` (`textureinfo(tex, name, dest)`): 1 and the value
    /// written where the renderer knows the name with the destination's shape, else 0.
    fn message(&mut self, bi: Builtin, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        let (name_arg, dest_arg) = if bi == Builtin::Textureinfo { (1, 2) } else { (0, 1) };
        let mut name = None;
        for (k, a) in args.iter().enumerate() {
            let v = self.arg_val(a)?;
            if k == name_arg {
                name = Some(v);
            }
        }
        let name = name.ok_or_else(|| JitError::Codegen("message name".into()))?;
        let Some(Arg::Ref(place)) = args.get(dest_arg) else { return unsupported("a message without a destination") };
        let class = host::msg_class(place.ty.base)
            .ok_or_else(|| JitError::Unsupported(format!("a message into {}", place.ty)))?;
        let len = place.ty.array_len().unwrap_or(0);
        let floats = components(place.ty).unwrap_or(1) * len.max(1) as usize;
        if floats > host::MESSAGE_FLOATS || name.vary {
            return unsupported("a message of this shape");
        }
        let vary = e.varying;
        let cl = self.fconst(class as f32, false);
        let ln = self.fconst(len as f32, false);
        // Inside an illuminance loop, `lightsource()` asks about each lane's current light.
        let out = match self.light_loops.last() {
            Some(&(set, k)) if bi == Builtin::Lightsource => {
                let k = self.b.use_var(k);
                self.call_helper("rtsl_h_light_message", &[set, k, name.c[0], cl, ln], true)?
            }
            // `incident()` and `opposite()` ask about the volume on one side of each lane's surface.
            _ if matches!(bi, Builtin::Incident | Builtin::Opposite) => {
                let which = self.fconst(bi as u32 as f32, false);
                let mut inputs = vec![which, name.c[0], cl, ln];
                for g in ["I", "Ng"] {
                    inputs.extend(self.global_val(g)?.c);
                }
                self.call_helper("rtsl_h_volume_message", &inputs, true)?
            }
            _ => {
                let which = self.fconst(bi as u32 as f32, false);
                self.call_helper("rtsl_h_message", &[which, name.c[0], cl, ln], vary)?
            }
        };
        let vary = vary || (bi == Builtin::Lightsource && !self.light_loops.is_empty());
        let found = out[0];
        let value = Val { vary, c: out[1..1 + floats].to_vec() };
        let t = self.place_targets(place)?;
        let zero = self.fconst(0.0, vary);
        let ok = self.b.ins().fcmp(FloatCC::NotEqual, found, zero);
        if vary {
            let save = self.exec();
            let okm = to_mask(&mut self.b, ok);
            let m = self.b.ins().band(save, okm);
            self.set_exec(m);
            self.div += 1;
            let r = self.write_targets(&t, &value);
            self.div -= 1;
            self.set_exec(save);
            r?;
        } else {
            let (wb, join) = (self.b.create_block(), self.b.create_block());
            self.b.ins().brif(ok, wb, &[], join, &[]);
            self.b.switch_to_block(wb);
            self.write_targets(&t, &value)?;
            self.b.ins().jump(join, &[]);
            self.b.switch_to_block(join);
        }
        Ok(Val { vary, c: vec![found] })
    }
}

impl<'m> Lower<'m, '_> {
    fn global_val(&mut self, name: &str) -> R<Val> {
        let g = Global::lookup(name).ok_or_else(|| JitError::Codegen(name.into()))?;
        let st = self.store_of(PlaceBase::Global(g))?;
        Ok(self.read_store(&st))
    }

    /// Writes a global under `exec` (nothing when the shader's layout does not hold it).
    fn set_global(&mut self, name: &str, v: &Val) -> R<()> {
        let Some(g) = Global::lookup(name) else { return Ok(()) };
        if let Some(ds) = self.dglobals[g.0 as usize].clone() {
            self.write_tangents(&ds, &Dual { v: v.clone(), d: None })?;
        }
        match self.globals[g.0 as usize].clone() {
            Some(st) => self.write_store(&st, v),
            None => Ok(()),
        }
    }

    /// `gather` (`shadeops::gather`): the arguments and options once, then per sample `k` one
    /// `rtsl_h_gather` call for the chunk's lanes with `k` below their sample count, the outputs
    /// written (`ray:` under those lanes, `surface:` under the hits), `body` under the hits and
    /// `otherwise` under the misses. Lanes whose samples are done leave through the exit
    /// accumulator; `break`/`continue` use the loop accumulators as in `illuminance`.
    fn gather(
        &mut self,
        [category, position, direction, angle, samples]: [ExprId; 5],
        params: &'m [(ExprId, Arg)],
        body: &'m ir::Block,
        otherwise: &'m ir::Block,
    ) -> R<()> {
        use crate::shadeops::gather::{self as g, Output};
        let f = self.func();
        let cat = self.expr(category)?;
        let p = self.expr(position)?;
        let axis = self.expr(direction)?;
        let ang = self.expr(angle)?;
        let count = self.expr(samples)?;
        let mut maxdist = Val { vary: false, c: vec![self.fconst(f32::INFINITY, false)] };
        let mut bias = Val { vary: false, c: vec![self.fconst(0.0, false)] };
        let mut distribution = self.const_string("");
        let mut outputs: Vec<(Output, &'m Place)> = Vec::new();
        for (name, arg) in params {
            let ExprKind::Const(Constant::String(name)) = &f.expr(*name).kind else {
                return unsupported("a gather parameter named by a computed string");
            };
            match arg {
                Arg::Value(x) => {
                    let ty = f.expr(*x).ty;
                    let v = self.expr(*x)?;
                    match g::Options::float_slot(name) {
                        Some(0) if ty == Type::FLOAT => maxdist = v,
                        Some(_) if ty == Type::FLOAT => bias = v,
                        None if name == "distribution" && ty == Type::STRING => distribution = v,
                        _ => {}
                    }
                }
                Arg::Ref(place) => {
                    if let Some(o) = Output::parse(name).filter(|o| o.fits(place.ty)) {
                        outputs.push((o, place));
                    }
                }
            }
        }
        if cat.vary || distribution.vary {
            return unsupported("varying strings");
        }
        // The sample count, `gather::sample_count` per lane: NaN and negatives give 0.
        let n = {
            let x = widen(&mut self.b, count.c[0], true);
            let zero = self.fconst(0.0, true);
            let top = self.fconst(g::MAX_SAMPLES, true);
            let pos = self.b.ins().fcmp(FloatCC::GreaterThan, x, zero);
            let x = choose(&mut self.b, pos, x, zero);
            let below = self.b.ins().fcmp(FloatCC::LessThan, x, top);
            let x = choose(&mut self.b, below, x, top);
            self.b.ins().ceil(x)
        };

        self.vdepth += 1;
        self.div += 1;
        let k = self.b.declare_var(types::F32);
        let z = self.b.ins().f32const(0.0);
        self.b.def_var(k, z);
        let exit_acc = self.b.declare_var(types::I32X4);
        let cont_acc = self.b.declare_var(types::I32X4);
        let zm = mask::zero_mask(&mut self.b);
        self.b.def_var(exit_acc, zm);
        self.b.def_var(cont_acc, zm);
        let (header, body_b, leave, exit_b) =
            (self.b.create_block(), self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(header);
        let kv = self.b.use_var(k);
        let kv = self.b.ins().splat(types::F32X4, kv);
        let more = self.b.ins().fcmp(FloatCC::LessThan, kv, n);
        let e = self.exec();
        let go = self.b.ins().band(e, more);
        let done = self.b.ins().band_not(e, more);
        let acc = self.b.use_var(exit_acc);
        let acc = self.b.ins().bor(acc, done);
        self.b.def_var(exit_acc, acc);
        self.set_exec(go);
        let live = any(&mut self.b, go);
        self.b.ins().brif(live, body_b, &[], leave, &[]);

        self.b.switch_to_block(body_b);
        let kv = self.b.use_var(k);
        let kval = Val { vary: false, c: vec![kv] };
        let nval = Val { vary: true, c: vec![n] };
        let inputs = self.concat(&[
            cat,
            p.clone(),
            axis.clone(),
            ang.clone(),
            kval,
            nval,
            maxdist.clone(),
            bias.clone(),
            distribution,
        ]);
        let rec = self.call_helper("rtsl_h_gather", &inputs.c, true)?;
        let e = self.exec();
        let miss = self.fconst(g::MISS, true);
        let hit = self.fconst(g::HIT, true);
        let ran = self.b.ins().fcmp(FloatCC::NotEqual, rec[0], miss);
        let ran = self.b.ins().band(e, ran);
        let surf = self.b.ins().fcmp(FloatCC::Equal, rec[0], hit);
        let surf = self.b.ins().band(e, surf);
        for (o, place) in &outputs {
            self.set_exec(if o.on_miss() { e } else { surf });
            let t = self.place_targets(place)?;
            let row = o.row();
            self.write_targets(&t, &Val { vary: true, c: rec[row..row + o.components()].to_vec() })?;
        }
        self.b.def_var(cont_acc, zm);
        let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: header, depth: u32::MAX };
        self.frames.last_mut().expect("frame").loops.push(lp);
        let after_hit = self.masked_block(ran, body);
        let missed = self.b.ins().band_not(e, ran);
        let after = after_hit.and_then(|h| Ok((h, self.masked_block(missed, otherwise)?)));
        self.frames.last_mut().expect("frame").loops.pop();
        let (after_hit, after_miss) = after?;
        let ca = self.b.use_var(cont_acc);
        let next = self.b.ins().bor(after_hit, after_miss);
        let next = self.b.ins().bor(next, ca);
        self.set_exec(next);
        let kv = self.b.use_var(k);
        let one = self.b.ins().f32const(1.0);
        let k1 = self.b.ins().fadd(kv, one);
        self.b.def_var(k, k1);
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(leave);
        self.b.ins().jump(exit_b, &[]);
        self.b.switch_to_block(exit_b);
        self.vdepth -= 1;
        self.div -= 1;
        let after = self.b.use_var(exit_acc);
        self.set_exec(after);
        Ok(())
    }

    /// `illuminance`: one `lights` call per chunk, then the body once per light index `k` under the
    /// lanes whose `k`-th non-ambient light exists and passes the cone. Lanes without it wait in
    /// `skip`; `break`/`continue` use the loop accumulators (never jumping: other lanes may be
    /// waiting). `L`, `Cl`, `Ol` are restored afterwards for the lanes that ran the statement.
    fn illuminance(
        &mut self,
        category: Option<ExprId>,
        position: ExprId,
        cone: Option<(ExprId, ExprId)>,
        body: &'m ir::Block,
    ) -> R<()> {
        let cat = match category {
            Some(c) => self.expr(c)?,
            None => self.const_string(""),
        };
        if cat.vary {
            return unsupported("varying strings");
        }
        let p = self.expr(position)?;
        let (axis, angle, has) = match cone {
            Some((a, b)) => (self.expr(a)?, self.expr(b)?, 1.0),
            None => {
                let z = self.fconst(0.0, false);
                (Val { vary: false, c: vec![z; 3] }, Val { vary: false, c: vec![z] }, 0.0)
            }
        };
        let has = Val { vary: false, c: vec![self.fconst(has, false)] };
        let saved: Vec<(&str, Option<Val>)> =
            ["L", "Cl", "Ol"].into_iter().map(|n| (n, self.global_val(n).ok())).collect();
        let entry = self.exec();
        // The cone goes with the query too: the renderer need not trace the shadows of lights
        // outside it.
        let nesting = Val { vary: false, c: vec![self.fconst(self.light_loops.len() as f32, false)] };
        let all = self.concat(&[cat, p, axis.clone(), angle.clone(), has.clone(), nesting]);
        let out = self.call_helper("rtsl_h_lights", &all.c, true)?;
        let set = self.b.ins().extractlane(out[0], 0);
        let count = self.b.ins().extractlane(out[1], 0);

        self.vdepth += 1;
        self.div += 1;
        let k = self.b.declare_var(types::F32);
        let z = self.b.ins().f32const(0.0);
        self.b.def_var(k, z);
        let exit_acc = self.b.declare_var(types::I32X4);
        let cont_acc = self.b.declare_var(types::I32X4);
        let skip = self.b.declare_var(types::I32X4);
        let zm = mask::zero_mask(&mut self.b);
        self.b.def_var(exit_acc, zm);
        self.b.def_var(cont_acc, zm);
        self.b.def_var(skip, zm);
        let (header, body_b, cont_b, leave, exit_b) = (
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
        );
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let kv = self.b.use_var(k);
        let more = self.b.ins().fcmp(FloatCC::LessThan, kv, count);
        let e = self.exec();
        let live = any(&mut self.b, e);
        let go = self.b.ins().band(more, live);
        self.b.ins().brif(go, body_b, &[], leave, &[]);

        self.b.switch_to_block(body_b);
        let kv = self.b.use_var(k);
        let inputs = self.concat(&[Val { vary: false, c: vec![set, kv] }, axis.clone(), angle.clone(), has.clone()]);
        let r = self.call_helper("rtsl_h_light", &inputs.c, true)?;
        let lm = self.b.ins().bitcast(
            types::I32X4,
            MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little),
            r[0],
        );
        let e = self.exec();
        let run = self.b.ins().band(e, lm);
        let skipped = self.b.ins().band_not(e, lm);
        self.b.def_var(skip, skipped);
        self.b.def_var(cont_acc, zm);
        self.set_exec(run);
        for (name, at) in [("L", 1), ("Cl", 4), ("Ol", 7)] {
            let v = Val { vary: true, c: r[at..at + 3].to_vec() };
            self.set_global(name, &v)?;
        }
        let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: cont_b, depth: u32::MAX };
        self.frames.last_mut().expect("frame").loops.push(lp);
        let (run_b, after) = (self.b.create_block(), self.b.create_block());
        let live = any(&mut self.b, run);
        self.b.ins().brif(live, run_b, &[], after, &[]);
        self.b.switch_to_block(run_b);
        self.light_loops.push((set, k));
        let r = self.block(body);
        self.light_loops.pop();
        self.frames.last_mut().expect("frame").loops.pop();
        r?;
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        self.b.ins().jump(cont_b, &[]);
        self.b.switch_to_block(cont_b);
        let e = self.exec();
        let ca = self.b.use_var(cont_acc);
        let sk = self.b.use_var(skip);
        let e = self.b.ins().bor(e, ca);
        let e = self.b.ins().bor(e, sk);
        self.set_exec(e);
        let kv = self.b.use_var(k);
        let one = self.b.ins().f32const(1.0);
        let k1 = self.b.ins().fadd(kv, one);
        self.b.def_var(k, k1);
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(leave);
        let e = self.exec();
        let acc = self.b.use_var(exit_acc);
        let acc = self.b.ins().bor(acc, e);
        self.b.def_var(exit_acc, acc);
        self.b.ins().jump(exit_b, &[]);
        self.b.switch_to_block(exit_b);
        self.vdepth -= 1;
        self.div -= 1;
        let after = self.b.use_var(exit_acc);
        self.set_exec(entry);
        for (name, v) in saved {
            if let Some(v) = v {
                self.set_global(name, &v)?;
            }
        }
        self.set_exec(after);
        Ok(())
    }
}

/// Whether a chunk may start `gs` as zeros rather than loading it (see `load_globals`): a varying
/// global the shader writes and whose value on entry its body never reads, since its top-level
/// statements assign it whole, under the chunk's mask, before anything could read it.
fn fresh_output(gs: &super::layout::GlobalSlot) -> bool {
    gs.varying && gs.written && gs.entry_unused
}

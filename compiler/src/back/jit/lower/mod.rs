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
//!   `illuminance` that varies, point clouds, and built-ins not handled in `builtin` or
//!   `builtin_ext`.
//!
//! Files: this one holds the shared types and the driver (the chunk loop, the prologue, frames);
//! - `stmt.rs`: statements and blocks, loops and their masks, the divergence analyses;
//! - `expr.rs`: expressions, operators and conversions, and inlined calls of user functions;
//! - `storage.rs`: stores, batch slots, places and their targets, indices, runtime checks;
//! - `helpers.rs`: calls of the `extern "C"` chunk and host helpers, component-wise maps;
//! - `lights.rs`: `illuminance` and `gather` loops, and the globals they set;
//! - `deriv.rs`: derivatives as duals;
//! - `builtins/`: built-in calls, one file per family (see `builtins/mod.rs`).

use super::batch::{OFF_BOUND, OFF_CHUNK, OFF_DERIVS, OFF_MASK, OFF_STRIDE, OFF_UNIFORM, OFF_VARYING};
use super::hoist::Prefix;
use super::layout::{components, Layout};
use super::mask::{self, any, fconst, merge};
use super::{unsupported, JitError};
use crate::globals::GLOBALS;
use crate::ir::{self, BaseType, FuncId, Function, Module, PlaceBase, VarKind};
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, Block, FuncRef, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_jit::JITModule;
use cranelift_module::Module as _;
use std::collections::HashMap;

mod builtins;
mod deriv;
mod expr;
mod helpers;
mod lights;
mod stmt;
mod storage;

use deriv::Dual;
use stmt::assigned;

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
/// A string `concat`, `format` or `printf` made was cut to `shadeops::format::MAX_STRING_LEN`.
pub(super) const RUNTIME_STRING_CUT: u32 = 3;
/// A string was left empty: the batch's strings passed `shadeops::format::STRING_BYTES_BUDGET`.
pub(super) const RUNTIME_STRINGS_FULL: u32 = 4;

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

/// Lowers the module's shader into `func` (signature `fn(*mut Batch)`): the Cranelift
/// instructions emitted, the string constants (handles `0..n`) and the rest of [`Lowered`].
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
}

/// Whether a chunk may start `gs` as zeros rather than loading it (see `load_globals`): a varying
/// global the shader writes and whose value on entry its body never reads, since its top-level
/// statements assign it whole, under the chunk's mask, before anything could read it.
fn fresh_output(gs: &super::layout::GlobalSlot) -> bool {
    gs.varying && gs.written && gs.entry_unused
}

//! The Cranelift packet JIT.
//!
//! [`compile`] turns a validated [`ir::Module`] into a [`CompiledShader`]: one `JITModule` holding one
//! function `extern "C" fn(*mut Batch)` that shades every active lane of a batch (the ABI of
//! `docs/packet-abi.md`). The function walks the batch in chunks of four lanes (`f32x4`) and runs the
//! whole shader, with every user function inlined, once per chunk that has an active lane; leading
//! uniform statements that every chunk would compute alike run once before the loop (`hoist.rs`).
//!
//! Invariants:
//! - **Never panics on input IR**: anything outside the supported subset is
//!   `Err(JitError::Unsupported(what))` (see `lower/mod.rs` for the list).
//! - **Memory safety**: generated code computes addresses only from the batch record, compile-time
//!   slot numbers and the chunk counter, never from shader data; [`BatchData`] sizes every buffer from
//!   the [`Layout`], and [`CompiledShader::shade`] refuses a batch made for another layout.
//! - **Masks**: a lane whose mask is 0 keeps the bits it had in every buffer (stores are whole
//!   `f32x4` chunks that write back the loaded bits in inactive lanes; wholly inactive chunks are not
//!   touched at all).
//! - **Agreement**: every lane computes what the reference interpreter computes for that lane
//!   (differential tests in `compiler/tests/jit_*.rs`); arithmetic is evaluated in the interpreter's
//!   order, and transcendental and noise functions call the same scalar Rust code per lane (one
//!   helper call per chunk), so results agree bit for bit except where noted in `math.rs`.
//! - The Cranelift verifier runs in debug and test builds only.

mod batch;
mod facts;
mod hoist;
mod host;
mod invariants;
mod layout;
mod lower;
mod mask;
mod math;
mod profile;

pub use batch::{Batch, BatchData, RawBatch, SavedValues, ShadeFn, StringTable};
pub use facts::LightKind;
pub use host::{
    environment_query_of, light_in_cone, same_category, shadow_query_of, BatchLightsView, HostLight, HostTable, LightLanes, MessageOut, PixelChannel, PixelOutputs, PixelView,
    ServicesHost, StrRef, CONE_ROWS, EVERY_LIGHT, MAX_LIGHTS, NO_LIGHT, ENVIRONMENT_ROWS, SHADOW_ROWS, TEXTURE_ROWS,
};
pub use layout::{GlobalSlot, Layout, ParamSlot};

use crate::ir;
use crate::shadeops::format;
use cranelift_codegen::ir::{AbiParam, UserFuncName};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module, ModuleReloc};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// JIT modules alive in this process (see [`live_modules`]).
static LIVE_MODULES: AtomicUsize = AtomicUsize::new(0);
/// Bytes of machine code those modules hold (see [`live_code_bytes`]).
static LIVE_CODE_BYTES: AtomicUsize = AtomicUsize::new(0);

/// How many compiled shaders (each one `JITModule`) are alive in this process, whoever made them:
/// one more for each successful [`compile_with`], one less when a [`CompiledShader`] is dropped and
/// its memory freed. Hot reload uses it to show that replaced code is freed (`docs/api.md`).
/// Process-wide: tests that compare it must not run beside other tests that compile shaders.
pub fn live_modules() -> usize {
    LIVE_MODULES.load(Ordering::SeqCst)
}

/// The bytes of machine code (Cranelift's `CodeInfo::total_size` of every function defined: code
/// and its constant pool) held by the live compiled shaders of this process. The JIT maps memory
/// by pages, so what the modules reserve is this rounded up to at least one page per module and
/// section; this counts what the code actually uses.
pub fn live_code_bytes() -> usize {
    LIVE_CODE_BYTES.load(Ordering::SeqCst)
}

/// Why a module could not be compiled.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JitError {
    /// A construct this slice of the JIT does not compile yet.
    Unsupported(String),
    /// The module has no shader.
    NoShader,
    /// Cranelift rejected the generated code (a JIT bug).
    Codegen(String),
    /// The shader is over `ir::INLINE_BUDGET` or `ir::STORAGE_BUDGET` (the checker refuses such
    /// source, the validator such artifacts): why, in words.
    OverBudget(String),
}

impl std::fmt::Display for JitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JitError::Unsupported(what) => write!(f, "the JIT does not support {what} yet"),
            JitError::NoShader => write!(f, "the module defines no shader"),
            JitError::Codegen(e) => write!(f, "code generation failed: {e}"),
            JitError::OverBudget(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for JitError {}

/// Settings of code generation.
#[derive(Clone, Debug)]
pub struct JitOptions {
    /// The most loop iterations one invocation runs, every loop together (counted per chunk of
    /// four lanes: an iteration any of its lanes runs); past it the running lanes leave the loop
    /// they are in, every loop they reach later stops at once, the shader goes on, and each stop is
    /// reported ([`CompiledShader::runtime_errors`]). The interpreter's `Limits::loop_iterations`.
    pub loop_budget: u32,
}

impl Default for JitOptions {
    fn default() -> Self {
        JitOptions { loop_budget: crate::ir::LOOP_BUDGET }
    }
}

/// What the runtime checks of a compiled shader found, each (check, site) once.
#[derive(Debug, Default)]
pub struct RuntimeErrors {
    seen: std::sync::Mutex<Vec<(u32, u32)>>,
    unread: std::sync::atomic::AtomicBool,
}

impl RuntimeErrors {
    fn record(&self, kind: u32, site: u32) {
        let mut seen = self.seen.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if !seen.contains(&(kind, site)) {
            seen.push((kind, site));
            self.unread.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// A shader compiled to machine code, with its batch layout.
pub struct CompiledShader {
    module: Option<JITModule>,
    entry: ShadeFn,
    layout: Arc<Layout>,
    /// Where each runtime check sits, and what they found.
    sites: Vec<String>,
    errors: RuntimeErrors,
    options: JitOptions,
    /// How many of `errors` were already reported.
    reported: std::sync::Mutex<usize>,
    /// Cranelift IR instructions emitted (before optimisation), for compile-cost measurements.
    pub ir_insts: usize,
    /// Uses of loop invariants inside the chunk loop that load from memory (`invariants.rs`).
    pub invariant_loads: usize,
    /// Bytes of machine code in `module` (counted in [`live_code_bytes`] while `self` lives).
    code_bytes: usize,
    /// The built-ins that shoot rays which the code calls.
    ray_calls: RayCalls,
    /// Whether the code reads other pixels of the image (`pixelvalue`).
    reads_pixels: bool,
    /// See [`CompiledShader::pixel_outputs`].
    pixel_outputs: Vec<String>,
    light_kind: LightKind,
    lane_invariant: bool,
}

/// The built-ins that shoot rays which a compiled shader calls (see [`CompiledShader::ray_calls`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCalls {
    /// `trace`.
    pub trace: bool,
    /// `transmission`.
    pub transmission: bool,
    /// `occlusion` or `indirectdiffuse`.
    pub hemisphere: bool,
    /// `occlusion`.
    pub occlusion: bool,
    /// `indirectdiffuse`.
    pub indirect: bool,
    /// `gather`.
    pub gather: bool,
}

impl RayCalls {
    /// The ray built-ins among the helpers a shader's code calls (by symbol).
    fn of(helpers: &[&str]) -> RayCalls {
        let calls = |symbol: &str| helpers.contains(&symbol);
        RayCalls {
            trace: calls("rtsl_h_trace"),
            transmission: calls("rtsl_h_transmission"),
            hemisphere: calls("rtsl_h_occlusion") || calls("rtsl_h_indirectdiffuse"),
            occlusion: calls("rtsl_h_occlusion"),
            indirect: calls("rtsl_h_indirectdiffuse"),
            gather: calls("rtsl_h_gather"),
        }
    }
}

impl std::fmt::Debug for CompiledShader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CompiledShader").field("layout", &self.layout).finish()
    }
}

impl Drop for CompiledShader {
    fn drop(&mut self) {
        if let Some(m) = self.module.take() {
            // SAFETY: the code is reachable only through `self.entry`, which dies with `self`
            // (`shade` borrows `self`), so nothing can run it after this point.
            unsafe { m.free_memory() };
            LIVE_MODULES.fetch_sub(1, Ordering::SeqCst);
            LIVE_CODE_BYTES.fetch_sub(self.code_bytes, Ordering::SeqCst);
        }
    }
}

// SAFETY: through `&self` a `CompiledShader` only reads its layout and calls its entry point; the
// `JITModule` (which is `Send` but not `Sync`) is touched only by `drop`, which needs ownership. The
// generated code keeps no state between calls, so many threads may run it at once.
unsafe impl Sync for CompiledShader {}

impl CompiledShader {
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// Which of the built-ins that shoot rays the code calls.
    pub fn ray_calls(&self) -> RayCalls {
        self.ray_calls
    }

    /// Whether a pixel shader's code reads other pixels of the image (`pixelvalue`): the renderer
    /// then runs it once the whole image is there, not tile by tile.
    pub fn reads_pixels(&self) -> bool {
        self.reads_pixels
    }

    /// The output variables of surface shaders a pixel shader reads per pixel: the channels its
    /// `pixelvalue` calls name by literals that are none of the image's own (`Ci`, `N`, `z`...).
    /// The renderer keeps them for every pixel (`docs/global_illumination.md`: the interleave
    /// filter reads the indirect light that way).
    pub fn pixel_outputs(&self) -> &[String] {
        &self.pixel_outputs
    }

    /// For a light shader: how it emits, read from its code (`illuminate`: local, `solar`:
    /// distant, neither: ambient).
    pub fn light_kind(&self) -> LightKind {
        self.light_kind
    }

    /// Every lane of a batch gets the same results: the code reads no global's value on entry,
    /// calls no function or built-in (no lookups, messages, noise or `random()`) and has no
    /// `illuminance`, `illuminate`, `solar` or `gather`. Its outputs are then functions of its
    /// parameters alone, and one lane may be run for all (an `ambientlight`, for instance).
    pub fn lane_invariant(&self) -> bool {
        self.lane_invariant
    }

    /// Bytes of machine code this shader holds (its share of [`live_code_bytes`]).
    pub fn code_bytes(&self) -> usize {
        self.code_bytes
    }

    /// Whether the loop budget has stopped a loop in any run so far (reported by
    /// [`CompiledShader::runtime_errors`] too; this reads without marking anything reported).
    pub fn stopped_a_loop(&self) -> bool {
        let seen = self.errors.seen.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        seen.iter().any(|(kind, _)| *kind == lower::RUNTIME_LOOP_BUDGET)
    }

    /// The runtime checks that failed since the last call, once each, as messages naming the place
    /// in the source ("the loop at shader.sl:12:5 was stopped: the shader ran more than 1048576 loop
    /// iterations",
    /// "an array index at shader.sl:8:14 was out of range and was clamped").
    pub fn runtime_errors(&self) -> Vec<String> {
        if !self.errors.unread.swap(false, std::sync::atomic::Ordering::Relaxed) {
            return Vec::new();
        }
        let seen = self.errors.seen.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
        let mut reported = self.reported.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let new = seen.get(*reported..).unwrap_or(&[]).to_vec();
        *reported = seen.len();
        new.into_iter()
            .map(|(kind, site)| {
                let at = self.sites.get(site as usize).map_or("?", String::as_str);
                if kind == lower::RUNTIME_LOOP_BUDGET {
                    format!(
                        "the loop at {at} was stopped: the shader ran more than {} loop iterations",
                        self.options.loop_budget
                    )
                } else if kind == lower::RUNTIME_UNSUPPORTED {
                    format!("{at} is not supported by rtsl (no point clouds or bake files): it returned 0")
                } else if kind == lower::RUNTIME_STRING_CUT {
                    format!("a string made at {at} was longer than {} bytes and was cut", format::MAX_STRING_LEN)
                } else if kind == lower::RUNTIME_STRINGS_FULL {
                    format!(
                        "a string made at {at} was left empty: the batch's strings took more than {} bytes",
                        format::STRING_BYTES_BUDGET
                    )
                } else {
                    format!("an array index at {at} was out of range and was clamped")
                }
            })
            .collect()
    }

    /// A batch of `lanes` lanes for this shader: every lane active, every value 0, no parameter
    /// bound (the shader evaluates defaults).
    pub fn batch(&self, lanes: usize) -> BatchData {
        BatchData::new(self.layout.clone(), lanes)
    }

    /// Shades every active lane of `batch`.
    ///
    /// # Panics
    /// If `batch` was made by another compiled shader with a different layout.
    pub fn shade(&self, batch: &mut BatchData) {
        self.run(batch, std::ptr::null());
    }

    /// Shades every active lane of `batch`, asking `host` what the renderer knows (spaces, lights,
    /// textures, rays, messages): the JIT's calls go through a [`HostTable`] backed by `host`, so
    /// tests use one [`crate::interp::TestHost`] for the JIT and the interpreter.
    ///
    /// # Panics
    /// As [`CompiledShader::shade`].
    pub fn shade_with(&self, batch: &mut BatchData, host: &mut dyn crate::interp::Services) {
        self.shade_with_pixels(batch, host, None);
    }

    /// [`CompiledShader::shade_with`], the code reading `pixelvalue` of literal channels from
    /// `pixels` (which should hold the image `host` answers from) where given.
    ///
    /// # Panics
    /// As [`CompiledShader::shade`].
    pub fn shade_with_pixels(
        &self,
        batch: &mut BatchData,
        host: &mut dyn crate::interp::Services,
        pixels: Option<PixelView>,
    ) {
        let mut sh = ServicesHost::with_pixels(host, pixels);
        let table = sh.table();
        self.shade_with_table(batch, &table);
    }

    /// Shades every active lane of `batch` with the renderer's call table.
    ///
    /// # Panics
    /// As [`CompiledShader::shade`].
    pub fn shade_with_table(&self, batch: &mut BatchData, table: &HostTable) {
        self.run(batch, table);
    }

    fn run(&self, batch: &mut BatchData, table: *const HostTable) {
        assert!(batch.made_for(&self.layout), "a batch made for another shader layout");
        let mut ctx = host::HostCtx::new(table, &self.errors);
        let mut rec = batch.record(&mut ctx);
        // SAFETY: the buffers have the sizes the layout implies (BatchData::new), the layout is the
        // one the code was compiled for (checked above), and the code stays alive while `self` is
        // borrowed.
        unsafe { (self.entry)(&mut rec) }
    }
}

fn unsupported<T>(what: impl Into<String>) -> Result<T, JitError> {
    Err(JitError::Unsupported(what.into()))
}

/// Compiles the shader of a validated module with the default options; runtime checks name their
/// place by byte offset (see [`compile_with`]).
pub fn compile(m: &ir::Module) -> Result<CompiledShader, JitError> {
    compile_with(m, None, &JitOptions::default())
}

/// Compiles the shader of a validated module; `sources` (the compilation's) lets runtime checks
/// name file, line and column.
pub fn compile_with(
    m: &ir::Module,
    sources: Option<&crate::source::SourceMap>,
    options: &JitOptions,
) -> Result<CompiledShader, JitError> {
    let shader = m.shader.as_ref().ok_or(JitError::NoShader)?;
    // Code and memory grow with these measures: past them Cranelift runs out of memory or of
    // the values a block may take.
    ir::within_budgets(m).map_err(JitError::OverBudget)?;
    let mut layout = layout::layout(m).map_err(|w| JitError::Unsupported(w.to_string()))?;

    let mut flags = settings::builder();
    let set = |f: &mut settings::Builder, k: &str, v: &str| f.set(k, v).map_err(|e| JitError::Codegen(e.to_string()));
    set(&mut flags, "opt_level", "speed")?;
    set(&mut flags, "use_colocated_libcalls", "false")?;
    set(&mut flags, "is_pic", "false")?;
    set(&mut flags, "enable_verifier", if cfg!(debug_assertions) { "true" } else { "false" })?;
    let isa = cranelift_native::builder()
        .map_err(|e| JitError::Codegen(e.to_string()))?
        .finish(settings::Flags::new(flags.clone()))
        .map_err(|e| JitError::Codegen(e.to_string()))?;
    // The final compilation's: the function arrives optimised (see `define`).
    set(&mut flags, "opt_level", "none")?;
    let final_isa = cranelift_native::builder()
        .map_err(|e| JitError::Codegen(e.to_string()))?
        .finish(settings::Flags::new(flags))
        .map_err(|e| JitError::Codegen(e.to_string()))?;
    let mut builder = JITBuilder::with_isa(isa, default_libcall_names());
    for h in math::helpers() {
        builder.symbol(h.name, h.ptr());
    }
    for h in host::HOST_HELPERS {
        builder.symbol(h.name, h.ptr());
    }
    let mut jit = JITModule::new(builder);
    match define(m, &mut layout, &mut jit, &*final_isa, &shader.name, options, sources) {
        Ok(Defined { entry, ir_insts, invariant_loads, sites, code_bytes, helpers }) => {
            LIVE_MODULES.fetch_add(1, Ordering::SeqCst);
            LIVE_CODE_BYTES.fetch_add(code_bytes, Ordering::SeqCst);
            let (light_kind, lane_invariant) = (facts::light_kind(m), facts::lane_invariant(m, &layout));
            Ok(CompiledShader {
                module: Some(jit),
                entry,
                layout: Arc::new(layout),
                ir_insts,
                invariant_loads,
                code_bytes,
                ray_calls: RayCalls::of(&helpers),
                reads_pixels: helpers.contains(&"rtsl_h_pixelvalue"),
                pixel_outputs: facts::pixel_outputs(m),
                light_kind,
                lane_invariant,
                sites,
                errors: RuntimeErrors::default(),
                options: options.clone(),
                reported: std::sync::Mutex::new(0),
            })
        }
        Err(e) => {
            // SAFETY: nothing was handed out that could run code of this module.
            unsafe { jit.free_memory() };
            Err(e)
        }
    }
}

/// What defining a shader's function produced.
struct Defined {
    entry: ShadeFn,
    /// Cranelift IR instructions emitted (before optimisation).
    ir_insts: usize,
    /// Uses of loop invariants that load from memory (`invariants.rs`).
    invariant_loads: usize,
    /// Where each runtime check sits.
    sites: Vec<String>,
    /// Bytes of machine code.
    code_bytes: usize,
    /// The helpers the code calls.
    helpers: Vec<&'static str>,
}

/// Lowers and defines the shader function in `jit`.
fn define(
    m: &ir::Module,
    layout: &mut Layout,
    jit: &mut JITModule,
    final_isa: &dyn cranelift_codegen::isa::TargetIsa,
    name: &str,
    options: &JitOptions,
    sources: Option<&crate::source::SourceMap>,
) -> Result<Defined, JitError> {
    let ptr = jit.target_config().pointer_type();
    let mut ctx = jit.make_context();
    ctx.func.signature.params.push(AbiParam::new(ptr));
    let id = jit
        .declare_function(&format!("shade_{name}"), Linkage::Export, &ctx.func.signature)
        .map_err(|e| JitError::Codegen(e.to_string()))?;
    ctx.func.name = UserFuncName::user(0, id.as_u32());
    let lowered = lower::lower(m, layout, jit, &mut ctx.func, options, sources)?;
    layout.strings = lowered.strings;
    ctx.set_disasm(profile::disasm_dir().is_some());
    // Optimised here, then the invariants pass (`invariants.rs`) puts its loads beside the
    // instructions that use them, and the final compilation optimises nothing more: a second
    // e-graph pass would move every pure instruction down to its first side-effecting user, and
    // so away from its loads again.
    let fail = |e: cranelift_codegen::CodegenError| JitError::Codegen(format!("{e:?}"));
    let mut ctrl = Default::default();
    ctx.optimize(jit.isa(), &mut ctrl).map_err(fail)?;
    let mut invariant_loads = 0;
    if let Some((entry, fixed, first)) = &lowered.loop_blocks {
        let in_loop = |b: cranelift_codegen::ir::Block| fixed.contains(&b) || b.as_u32() as usize >= *first;
        invariant_loads = invariants::keep_in_memory(&mut ctx.func, ptr, *entry, &in_loop);
    }
    ctx.compile(final_isa, &mut ctrl).map_err(|e| fail(e.inner))?;
    let compiled = ctx.compiled_code().ok_or_else(|| JitError::Codegen("no code".into()))?;
    let alignment = u64::from(compiled.buffer.alignment);
    let relocs: Vec<ModuleReloc> =
        compiled.buffer.relocs().iter().map(|r| ModuleReloc::from_mach_reloc(r, &ctx.func, id)).collect();
    let code_bytes = compiled.code_info().total_size as usize;
    let disasm = compiled.vcode.clone();
    jit.define_function_bytes(id, alignment, compiled.code_buffer(), &relocs)
        .map_err(|e| JitError::Codegen(format!("{e:?}")))?;
    jit.clear_context(&mut ctx);
    for (trampoline, helper) in &lowered.trampolines {
        define_trampoline(jit, *trampoline, helper)?;
    }
    jit.finalize_definitions().map_err(|e| JitError::Codegen(e.to_string()))?;
    let code = jit.get_finalized_function(id);
    profile::record(&format!("shade_{name}"), code, code_bytes, disasm.as_deref());
    // SAFETY: `code` is the function just defined with the signature `fn(*mut Batch)` (one pointer
    // argument, no result, the platform's C calling convention).
    let entry: ShadeFn = unsafe { std::mem::transmute::<*const u8, ShadeFn>(code) };
    Ok(Defined {
        entry,
        ir_insts: lowered.insts,
        invariant_loads,
        sites: lowered.sites,
        code_bytes,
        helpers: lowered.helpers,
    })
}

/// Defines `id`, a trampoline with `CallConv::PreserveAll` that calls the per-chunk helper
/// `helper` (`extern "C" fn(in, out)`) with its two arguments. Cranelift saves every register the
/// trampoline clobbers, the helper call's clobbers included, so a caller keeps all its registers
/// across a call (see `Lower::call_helper_keeping_registers`).
fn define_trampoline(jit: &mut JITModule, id: cranelift_module::FuncId, helper: &str) -> Result<(), JitError> {
    use cranelift_codegen::ir::InstBuilder;
    let codegen = |e: &dyn std::fmt::Display| JitError::Codegen(e.to_string());
    let config = jit.target_config();
    let ptr = config.pointer_type();
    let mut ctx = jit.make_context();
    ctx.func.signature.call_conv = cranelift_codegen::isa::CallConv::PreserveAll;
    ctx.func.signature.params.extend([AbiParam::new(ptr), AbiParam::new(ptr)]);
    ctx.func.name = UserFuncName::user(0, id.as_u32());
    let mut callee = jit.make_signature();
    callee.params.extend([AbiParam::new(ptr), AbiParam::new(ptr)]);
    let callee = jit.declare_function(helper, Linkage::Import, &callee).map_err(|e| codegen(&e))?;
    let callee = jit.declare_func_in_func(callee, &mut ctx.func);
    let mut fctx = cranelift_frontend::FunctionBuilderContext::new();
    let mut b = cranelift_frontend::FunctionBuilder::new(&mut ctx.func, &mut fctx);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    b.seal_block(entry);
    let args = b.block_params(entry).to_vec();
    b.ins().call(callee, &args);
    b.ins().return_(&[]);
    b.finalize(config);
    jit.define_function(id, &mut ctx).map_err(|e| JitError::Codegen(format!("{e:?}")))?;
    jit.clear_context(&mut ctx);
    Ok(())
}

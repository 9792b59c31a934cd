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
//!   `Err(JitError::Unsupported(what))` (see `lower.rs` for the list).
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

mod facts;
mod hoist;
mod host;
mod invariants;
mod layout;
mod lower;
mod mask;
mod math;
mod profile;

pub use facts::LightKind;
pub use host::{
    light_in_cone, same_category, shadow_query_of, HostLight, HostTable, LightLanes, MessageOut, ServicesHost, StrRef,
    CONE_ROWS, EVERY_LIGHT, MAX_LIGHTS, NO_LIGHT, SHADOW_ROWS,
};
pub use layout::{GlobalSlot, Layout, ParamSlot};

use crate::ir;
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
}

impl std::fmt::Display for JitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JitError::Unsupported(what) => write!(f, "the JIT does not support {what} yet"),
            JitError::NoShader => write!(f, "the module defines no shader"),
            JitError::Codegen(e) => write!(f, "code generation failed: {e}"),
        }
    }
}

impl std::error::Error for JitError {}

/// The batch record the compiled function reads (`docs/packet-abi.md`). All pointers must be valid
/// for the sizes the shader's [`Layout`] implies; [`BatchData`] guarantees it.
#[repr(C)]
#[derive(Debug)]
pub struct Batch {
    /// Number of lanes `n`.
    pub lanes: u32,
    /// `n` rounded up to a multiple of 4: the length of every varying array.
    pub stride: u32,
    /// `stride` entries, -1 active, 0 inactive.
    pub mask: *const i32,
    /// `varying_slots * stride` floats: slot `s` of lane `l` at `s * stride + l`.
    pub varying: *mut f32,
    /// `uniform_len` floats.
    pub uniform: *mut f32,
    /// One entry per shader parameter: nonzero when the parameter was given a value.
    pub bound: *const u32,
    /// The batch's string table (opaque to generated code, which only passes the batch record to
    /// helpers; string values are `u32` handles into it).
    pub strings: *mut StringTable,
    /// Screen-space derivatives of the varying globals (`Layout::deriv_slots` slots): slot `s` of
    /// lane `l` has d/dx at `derivs[2s * stride + l]` and d/dy at `derivs[(2s + 1) * stride + l]`.
    /// Null: every derivative is zero.
    pub derivs: *const f32,
    /// The renderer's call table and the helpers' scratch (opaque to generated code; may be null:
    /// then every renderer query answers "unknown").
    pub ctx: *mut host::HostCtx,
    /// The chunk generated code is shading, written at the start of each (`u32::MAX` before the
    /// first) by code that calls host helpers: they pass it on to the renderer, which keeps
    /// per-lane state for the batch. Code without host calls in its chunks does not write it.
    pub chunk: u32,
}

/// The strings one batch can name, each once (so equal handles are equal strings and the reverse:
/// generated code compares strings by handle). Handles `0..k` are the shader's constants
/// ([`Layout::strings`]); parameters and strings returned by the renderer are added after them.
#[derive(Clone, Debug, Default)]
pub struct StringTable {
    strings: Vec<String>,
    index: rustc_hash::FxHashMap<String, u32>,
    /// How many of `strings` are the shader's constants (fewer than `Layout::strings` when those
    /// repeat): what [`StringTable::reset`] keeps.
    constants: usize,
    /// Strings dropped by [`StringTable::reset`], whose buffers the next ones reuse: a batch is
    /// reset for every call, and a renderer's calls intern their string parameters again each
    /// time (two allocations a string, thousands a frame).
    spare: Vec<String>,
}

/// Spare string buffers kept by a table.
const SPARE_STRINGS: usize = 32;

impl StringTable {
    pub fn new(constants: &[String]) -> StringTable {
        let mut t = StringTable::default();
        for c in constants {
            t.intern(c);
        }
        t.constants = t.strings.len();
        t
    }

    /// Back to the constants alone, as [`StringTable::new`] made it (same handles), without
    /// building it again: a batch is reset for every call, and most calls add no string.
    pub fn reset(&mut self) {
        while self.strings.len() > self.constants {
            if let Some(s) = self.strings.pop() {
                if let Some((key, _)) = self.index.remove_entry(&s) {
                    self.keep_spare(key);
                }
                self.keep_spare(s);
            }
        }
    }

    fn keep_spare(&mut self, s: String) {
        if self.spare.len() < SPARE_STRINGS {
            self.spare.push(s);
        }
    }

    /// A copy of `s`, in a spare buffer when there is one.
    fn copy(&mut self, s: &str) -> String {
        let mut copy = self.spare.pop().unwrap_or_default();
        copy.clear();
        copy.push_str(s);
        copy
    }

    /// The handle of `s`, added when new.
    pub fn intern(&mut self, s: &str) -> u32 {
        if let Some(h) = self.index.get(s) {
            return *h;
        }
        let h = self.strings.len() as u32;
        let (value, key) = (self.copy(s), self.copy(s));
        self.strings.push(value);
        self.index.insert(key, h);
        h
    }

    /// The string of a handle; "" for a handle out of range.
    pub fn get(&self, h: u32) -> &str {
        self.strings.get(h as usize).map(String::as_str).unwrap_or("")
    }
}

pub(crate) const OFF_STRIDE: i32 = 4;
pub(crate) const OFF_MASK: i32 = 8;
pub(crate) const OFF_VARYING: i32 = 16;
pub(crate) const OFF_UNIFORM: i32 = 24;
pub(crate) const OFF_BOUND: i32 = 32;
pub(crate) const OFF_DERIVS: i32 = 48;
pub(crate) const OFF_CHUNK: i32 = 64;

// Generated code addresses the record's fields by these offsets.
const _: () = {
    use std::mem::offset_of;
    assert!(offset_of!(Batch, stride) == OFF_STRIDE as usize);
    assert!(offset_of!(Batch, mask) == OFF_MASK as usize);
    assert!(offset_of!(Batch, varying) == OFF_VARYING as usize);
    assert!(offset_of!(Batch, uniform) == OFF_UNIFORM as usize);
    assert!(offset_of!(Batch, bound) == OFF_BOUND as usize);
    assert!(offset_of!(Batch, derivs) == OFF_DERIVS as usize);
    assert!(offset_of!(Batch, chunk) == OFF_CHUNK as usize);
};

/// The entry point of a compiled shader.
pub type ShadeFn = unsafe extern "C" fn(*mut Batch);

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
                    format!("{at} is not supported by rtsl (no point clouds or photon maps): it returned 0")
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
        let mut sh = ServicesHost::new(host);
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
        assert!(
            Arc::ptr_eq(&self.layout, &batch.layout) || *self.layout == *batch.layout,
            "a batch made for another shader layout"
        );
        let mut ctx = host::HostCtx::new(table, &self.errors);
        let mut rec = Batch {
            lanes: batch.lanes as u32,
            stride: batch.stride as u32,
            mask: batch.mask.as_ptr(),
            varying: batch.varying.as_mut_ptr(),
            uniform: batch.uniform.as_mut_ptr(),
            bound: batch.bound.as_ptr(),
            strings: &mut batch.strings,
            derivs: if batch.derivs.is_empty() { std::ptr::null() } else { batch.derivs.as_ptr() },
            ctx: &mut ctx,
            chunk: u32::MAX,
        };
        // SAFETY: the buffers have the sizes the layout implies (BatchData::new), the layout is the
        // one the code was compiled for (checked above), and the code stays alive while `self` is
        // borrowed.
        unsafe { (self.entry)(&mut rec) }
    }
}

/// The buffers of one batch, owned, with accessors by name.
#[derive(Clone, Debug)]
pub struct BatchData {
    layout: Arc<Layout>,
    lanes: usize,
    stride: usize,
    mask: Vec<i32>,
    varying: Vec<f32>,
    uniform: Vec<f32>,
    bound: Vec<u32>,
    strings: StringTable,
    /// `2 * deriv_slots * stride` floats (see [`Batch::derivs`]). The rows of the globals whose
    /// derivatives the code reads (`GlobalSlot::derivs`) are zero until the renderer sets them;
    /// the others are never read, and a reset leaves whatever they held.
    derivs: Vec<f32>,
}

impl BatchData {
    pub fn new(layout: Arc<Layout>, lanes: usize) -> BatchData {
        let stride = lanes.div_ceil(4) * 4;
        let mut mask = vec![0; stride];
        mask[..lanes].fill(-1);
        BatchData {
            lanes,
            stride,
            mask,
            varying: vec![0.0; layout.varying_slots * stride],
            uniform: vec![0.0; layout.uniform_len],
            bound: vec![0; layout.params.len()],
            strings: StringTable::new(&layout.strings),
            derivs: vec![0.0; 2 * layout.deriv_slots * stride],
            layout,
        }
    }

    pub fn lanes(&self) -> usize {
        self.lanes
    }

    pub fn stride(&self) -> usize {
        self.stride
    }

    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    pub fn set_active(&mut self, lane: usize, active: bool) {
        if lane < self.lanes {
            self.mask[lane] = if active { -1 } else { 0 };
        }
    }

    pub fn is_active(&self, lane: usize) -> bool {
        self.mask.get(lane).is_some_and(|m| *m != 0)
    }

    /// Every varying float (all slots, all lanes, padding included) set to `value`.
    pub fn fill_varying(&mut self, value: f32) {
        self.varying.fill(value);
    }

    /// The raw varying array (`slot * stride + lane`).
    pub fn varying(&self) -> &[f32] {
        &self.varying
    }

    fn get_lane(&self, varying: bool, offset: usize, n: usize, lane: usize) -> Vec<f32> {
        if varying {
            (0..n).map(|k| self.varying[(offset + k) * self.stride + lane]).collect()
        } else {
            self.uniform[offset..offset + n].to_vec()
        }
    }

    fn set_lane(&mut self, varying: bool, offset: usize, values: &[f32], lane: usize) {
        for (k, v) in values.iter().enumerate() {
            if varying {
                self.varying[(offset + k) * self.stride + lane] = *v;
            } else {
                self.uniform[offset + k] = *v;
            }
        }
    }

    /// Sets a global of one lane (uniform globals ignore `lane`). Returns false when the shader does
    /// not use the global, the lane is out of range, or the value has the wrong number of floats.
    pub fn set_global(&mut self, name: &str, lane: usize, value: &[f32]) -> bool {
        let Some(g) = self.layout.global(name).cloned() else { return false };
        if value.len() != g.components || lane >= self.lanes {
            return false;
        }
        self.set_lane(g.varying, g.offset, value, lane);
        true
    }

    /// Sets the screen-space derivatives (`d/dx`, `d/dy`) of a varying global in one lane: the
    /// renderer's ray differentials (`docs/packet-abi.md`, "Derivatives"). Returns false when the
    /// shader does not use the global or it is uniform, the lane is out of range, or a slice has the
    /// wrong number of floats, or the shader differentiates nothing (`Layout::deriv_slots` is 0:
    /// there is nothing to set). Unset derivatives are 0.
    pub fn set_global_derivs(&mut self, name: &str, lane: usize, dx: &[f32], dy: &[f32]) -> bool {
        let Some(s) = self.global_slot(name) else { return false };
        let n = self.layout.global(name).map_or(0, |g| g.components);
        if dx.len() != n || dy.len() != n || lane >= self.lanes || s + n > self.layout.deriv_slots {
            return false;
        }
        for k in 0..n {
            self.derivs[2 * (s + k) * self.stride + lane] = dx[k];
            self.derivs[(2 * (s + k) + 1) * self.stride + lane] = dy[k];
        }
        true
    }

    /// The first derivative slot of a varying global (a triple has three: x, y, z), for a renderer
    /// that fills [`BatchData::derivs_mut`] directly: component `k`'s d/dx of lane `l` is at
    /// `(2 * (slot + k)) * stride + l`, its d/dy at `(2 * (slot + k) + 1) * stride + l`. `None` when
    /// the shader does not use the global or it is uniform.
    pub fn global_slot(&self, name: &str) -> Option<usize> {
        let g = self.layout.global(name)?;
        g.varying.then_some(g.offset)
    }

    /// The raw derivative buffer (`2 * Layout::deriv_slots * stride` floats; see [`Batch::derivs`]).
    /// After a reset only the rows of the globals whose derivatives the code reads are zero.
    pub fn derivs_mut(&mut self) -> &mut [f32] {
        &mut self.derivs
    }

    /// The raw derivative buffer.
    pub fn derivs(&self) -> &[f32] {
        &self.derivs
    }

    /// A global of one lane (`None` when the shader does not use it).
    pub fn global(&self, name: &str, lane: usize) -> Option<Vec<f32>> {
        let g = self.layout.global(name)?;
        (lane < self.lanes).then(|| self.get_lane(g.varying, g.offset, g.components, lane))
    }

    /// Binds a parameter for one lane (uniform parameters ignore `lane`): arrays take
    /// `components * len` floats, element by element. Returns false as `set_global` does.
    pub fn set_param(&mut self, name: &str, lane: usize, value: &[f32]) -> bool {
        let Some((i, p)) = self.layout.param(name).map(|(i, p)| (i, p.clone())) else { return false };
        if value.len() != p.floats() || lane >= self.lanes {
            return false;
        }
        self.set_lane(p.varying, p.offset, value, lane);
        self.bound[i] = 1;
        true
    }

    /// Binds a string parameter (strings are uniform). Returns false when the shader has no string
    /// parameter of that name.
    pub fn set_string_param(&mut self, name: &str, value: &str) -> bool {
        let Some((i, p)) = self.layout.param(name).map(|(i, p)| (i, p.clone())) else { return false };
        if !p.string {
            return false;
        }
        let h = self.strings.intern(value);
        self.uniform[p.offset] = f32::from_bits(h);
        self.bound[i] = 1;
        true
    }

    /// Sets the `random()` seed of one lane (the interpreter's `ShadingPoint::seed`: the `k`-th
    /// `random()` of the lane draws from `seed * 0x9E3779B97F4A7C15 + k`). Returns false when the
    /// shader never calls `random()` or the lane is out of range. Unset seeds are 0 in a fresh batch.
    pub fn set_seed(&mut self, lane: usize, seed: u64) -> bool {
        let Some(slot) = self.layout.seed else { return false };
        if lane >= self.lanes {
            return false;
        }
        self.varying[slot * self.stride + lane] = f32::from_bits(seed as u32);
        self.varying[(slot + 1) * self.stride + lane] = f32::from_bits((seed >> 32) as u32);
        true
    }

    /// A string parameter's value (after shading: its final value when it is an output).
    pub fn string_param(&self, name: &str) -> Option<&str> {
        let (_, p) = self.layout.param(name)?;
        p.string.then(|| self.strings.get(self.uniform[p.offset].to_bits()))
    }

    /// A parameter's value in one lane (after shading: its final value when it is an output).
    pub fn param(&self, name: &str, lane: usize) -> Option<Vec<f32>> {
        let (_, p) = self.layout.param(name)?;
        (lane < self.lanes).then(|| self.get_lane(p.varying, p.offset, p.floats(), lane))
    }
}

/// The buffers of a [`BatchData`] for a renderer that fills batches itself, by the slot numbers
/// of the [`Layout`] (slot `s` of lane `l` at `varying[s * stride + l]`).
/// A batch's values, saved by [`BatchData::save_values`].
#[derive(Clone, Debug, Default)]
pub struct SavedValues {
    mask: Vec<i32>,
    varying: Vec<f32>,
    uniform: Vec<f32>,
    bound: Vec<u32>,
    derivs: Vec<f32>,
}

pub struct RawBatch<'a> {
    pub lanes: usize,
    pub stride: usize,
    pub mask: &'a mut [i32],
    pub varying: &'a mut [f32],
    pub uniform: &'a mut [f32],
    pub bound: &'a mut [u32],
    pub strings: &'a mut StringTable,
    /// Screen-space derivatives of the varying globals (see [`Batch::derivs`]).
    pub derivs: &'a mut [f32],
}

impl BatchData {
    /// Makes the batch `lanes` lanes long with every lane active, every value 0 and no parameter
    /// bound, reusing the buffers (a renderer keeps one batch per shader and thread).
    pub fn reset(&mut self, lanes: usize) {
        self.reset_except(lanes, &[]);
    }

    /// [`reset`](Self::reset), except that the varying slots in `filled` (ranges of slot indices)
    /// keep whatever they held: for a caller that writes every lane of them before running the
    /// shader, or whose shader assigns them for every lane before reading them (a global's
    /// `entry_unused`), so that zeroing them first would be wasted. The values stay a function of
    /// what the caller and the shader write, never of an earlier call.
    pub fn reset_except(&mut self, lanes: usize, filled: &[std::ops::Range<usize>]) {
        let stride = lanes.div_ceil(4) * 4;
        self.lanes = lanes;
        self.stride = stride;
        self.mask.clear();
        self.mask.resize(stride, 0);
        self.mask[..lanes].fill(-1);
        let slots = self.layout.varying_slots;
        // The filled slots as bits (a batch has rarely more than a few dozen slots; past 256 all
        // are zeroed).
        let mut kept = [0u64; 4];
        for r in filled {
            for slot in r.clone().take_while(|&slot| slot < 256) {
                kept[slot / 64] |= 1 << (slot % 64);
            }
        }
        if kept == [0; 4] {
            self.varying.clear();
            self.varying.resize(slots * stride, 0.0);
        } else {
            // A new stride moves every row, but a kept row is written over all the same. The rows
            // are zeroed a run at a time, from one kept row's padding lanes past `lanes` (which
            // nobody fills) to the next kept row: a `memset` call per row costs more than the
            // zeroing itself in small batches (light batches of incoherent rays).
            self.varying.resize(slots * stride, 0.0);
            let mut zero_from = 0;
            for (word, bits) in kept.iter().enumerate() {
                let mut bits = *bits;
                while bits != 0 {
                    let slot = 64 * word + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if slot >= slots {
                        break;
                    }
                    let row = slot * stride;
                    self.varying[zero_from..row].fill(0.0);
                    zero_from = row + lanes;
                }
            }
            self.varying[zero_from..].fill(0.0);
        }
        // Only the derivatives the code reads (`GlobalSlot::derivs`) are zeroed: the others' rows
        // are never read, and zeroing all of them was most of a batch's reset.
        self.derivs.resize(2 * self.layout.deriv_slots * stride, 0.0);
        for g in self.layout.globals.iter().filter(|g| g.varying && g.derivs) {
            let rows = 2 * g.offset * stride..2 * (g.offset + g.components) * stride;
            if let Some(rows) = self.derivs.get_mut(rows) {
                rows.fill(0.0);
            }
        }
        self.uniform.fill(0.0);
        self.bound.fill(0);
        self.strings.reset();
    }

    /// The raw buffers, to fill inputs and read outputs by slot.
    /// Copies the batch's values (mask, globals, parameters, outputs and derivatives) into `to`,
    /// for [`restore_values`](Self::restore_values). Not its strings: handles stay valid as the
    /// table grows, and equal strings keep one handle.
    pub fn save_values(&self, to: &mut SavedValues) {
        to.mask.clone_from(&self.mask);
        to.varying.clone_from(&self.varying);
        to.uniform.clone_from(&self.uniform);
        to.bound.clone_from(&self.bound);
        to.derivs.clone_from(&self.derivs);
    }

    /// Puts back the values [`save_values`](Self::save_values) copied from this batch, so that
    /// running a shader again starts where the first run did.
    pub fn restore_values(&mut self, from: &SavedValues) {
        self.mask.clone_from(&from.mask);
        self.varying.clone_from(&from.varying);
        self.uniform.clone_from(&from.uniform);
        self.bound.clone_from(&from.bound);
        self.derivs.clone_from(&from.derivs);
    }

    pub fn raw_mut(&mut self) -> RawBatch<'_> {
        RawBatch {
            lanes: self.lanes,
            stride: self.stride,
            mask: &mut self.mask,
            varying: &mut self.varying,
            uniform: &mut self.uniform,
            bound: &mut self.bound,
            strings: &mut self.strings,
            derivs: &mut self.derivs,
        }
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

#[cfg(test)]
mod tests {
    use super::{BatchData, Layout};
    use std::sync::Arc;

    /// A reset zeroes every varying row but the kept ones, whose padding lanes past the batch's
    /// lanes it zeroes too, whatever the batch held and whatever its earlier size.
    #[test]
    fn a_reset_zeroes_all_but_the_kept_rows_lanes() {
        let layout = Arc::new(Layout { varying_slots: 70, ..Layout::default() });
        let mut batch = BatchData::new(layout, 64);
        let kept = [0..1, 5..8, 63..66, 69..75];
        for lanes in [64, 5, 1, 8, 13, 64] {
            // Sized for `lanes` first, so that every value the second reset finds is nonzero.
            batch.reset_except(lanes, &kept);
            for (i, v) in batch.raw_mut().varying.iter_mut().enumerate() {
                *v = 1.0 + i as f32;
            }
            batch.reset_except(lanes, &kept);
            let stride = lanes.div_ceil(4) * 4;
            let raw = batch.raw_mut();
            assert_eq!(raw.varying.len(), 70 * stride);
            for (slot, row) in raw.varying.chunks_exact(stride).enumerate() {
                let is_kept = kept.iter().any(|r| r.contains(&slot));
                for (lane, v) in row.iter().enumerate() {
                    let zeroed = !is_kept || lane >= lanes;
                    assert_eq!(*v == 0.0, zeroed, "{lanes} lanes: slot {slot}, lane {lane} is {v}");
                }
            }
        }
    }

    /// Reset and interned again, in reused buffers, strings keep one handle each and read back
    /// as themselves; the constants keep theirs.
    #[test]
    fn string_tables_reuse_their_buffers_and_keep_handles_straight() {
        let mut t = StringTable::new(&["k".to_string(), "k".to_string(), "m".to_string()]);
        assert_eq!((t.intern("k"), t.intern("m")), (0, 1));
        for round in 0..3 {
            let names = if round % 2 == 0 { ["tex.png", "other", "tex.png"] } else { ["b", "a-longer-name", "b"] };
            let handles = names.map(|n| t.intern(n));
            assert_eq!(handles, [2, 3, 2], "round {round}");
            assert_eq!([t.get(2), t.get(3)], [names[0], names[1]], "round {round}");
            assert_eq!(t.intern("m"), 1);
            t.reset();
            assert_eq!(t.get(2), "", "round {round}: gone after a reset");
        }
    }
    use super::StringTable;

    #[test]
    fn a_reset_string_table_is_a_new_one() {
        let constants = ["camera".to_string(), "world".to_string(), "camera".to_string()];
        let fresh = StringTable::new(&constants);
        let mut used = StringTable::new(&constants);
        let added = used.intern("FieldOfView");
        assert_eq!(used.get(added), "FieldOfView");
        used.intern("more");
        used.reset();
        for c in &constants {
            assert_eq!(used.intern(c), fresh.clone().intern(c), "the handle of constant {c}");
        }
        assert_eq!(used.get(added), "", "strings added after the constants are gone");
        assert_eq!(used.intern("other"), added, "and their handles are given out again");
        assert_eq!(used.strings.len(), 3);
    }
}

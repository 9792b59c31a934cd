//! Shaders in the renderer: compiled programs, parameter binding, shader instances (a program with
//! bound values and its "shader" space), and filling the packet batches the JIT code runs on.
//!
//! Invariant: the runtime never parses shader source itself; [`program`] hands source to
//! `rtsl-compiler` and keeps what comes back.

pub mod library;
pub mod params;
pub mod program;

pub use params::{bind_param, BoundParam, ParamError, ParamValue};
pub use program::{GlobalSlots, LightKind, Program, ShaderError, ShaderProgram, Slot};

use glam::{Affine3A, Vec3A};
use rtsl_compiler::abi::{BatchData, RawBatch};
use std::cell::RefCell;
use std::sync::{Arc, Weak};

/// A program with bound parameter values, placed in the world: what `bind_shader` + `parameter`
/// produce, and what a light source, an object's surface or a volume refers to.
#[derive(Clone, Debug)]
pub struct ShaderInstance {
    pub program: Program,
    pub params: Vec<BoundParam>,
    /// The "shader" coordinate system: the transform current when the instance was made.
    pub world_from_shader: Affine3A,
}

impl ShaderInstance {
    pub fn new(program: Program, world_from_shader: Affine3A) -> ShaderInstance {
        ShaderInstance { program, params: Vec::new(), world_from_shader }
    }

    /// Binds (or rebinds) parameter `name`; point-like values are in the space `world_from_current`.
    pub fn set(&mut self, name: &str, value: &ParamValue, world_from_current: &Affine3A) -> Result<(), ParamError> {
        let b = bind_param(&self.program, name, value, world_from_current)?;
        match self.params.iter_mut().find(|p| p.index == b.index) {
            Some(p) => *p = b,
            None => self.params.push(b),
        }
        Ok(())
    }

    /// The bound value of a string parameter, or its constant default.
    pub fn string_param(&self, name: &str) -> Option<String> {
        let (index, _) = self.program.layout().param(name)?;
        if let Some(b) = self.params.iter().find(|p| p.index == index) {
            return b.string.clone();
        }
        match &self.program.interface.parameters[index].default {
            Some(rtsl_compiler::interface::Value::String(s)) => Some(s.clone()),
            _ => None,
        }
    }

    /// The value of a float parameter: bound, or its constant default.
    pub fn float_param(&self, name: &str) -> Option<f32> {
        self.constant_floats(name).and_then(|v| (v.len() == 1).then(|| v[0]))
    }

    /// The value of a triple parameter (colour, point...): bound, or its constant default.
    pub fn triple_param(&self, name: &str) -> Option<[f32; 3]> {
        self.constant_floats(name).and_then(|v| (v.len() == 3).then(|| [v[0], v[1], v[2]]))
    }

    fn constant_floats(&self, name: &str) -> Option<Vec<f32>> {
        let (index, _) = self.program.layout().param(name)?;
        if let Some(b) = self.params.iter().find(|p| p.index == index) {
            return Some(b.floats.clone());
        }
        match &self.program.interface.parameters[index].default {
            Some(rtsl_compiler::interface::Value::Float(x)) => Some(vec![*x]),
            Some(rtsl_compiler::interface::Value::Triple(t)) if t.space.is_none() => Some(t.value.to_vec()),
            _ => None,
        }
    }

    /// Writes the bound parameters into lanes `0..raw.lanes` of a batch of this instance's program.
    pub fn write_params(&self, raw: &mut RawBatch<'_>) {
        let layout = self.program.layout();
        for b in &self.params {
            let slot = &layout.params[b.index];
            raw.bound[b.index] = 1;
            if let Some(s) = &b.string {
                let h = raw.strings.intern(s);
                raw.uniform[slot.offset] = f32::from_bits(h);
            } else if slot.varying {
                for (k, v) in b.floats.iter().enumerate() {
                    let row = (slot.offset + k) * raw.stride;
                    raw.varying[row..row + raw.lanes].fill(*v);
                }
            } else {
                raw.uniform[slot.offset..slot.offset + b.floats.len()].copy_from_slice(&b.floats);
            }
        }
    }
}

/// Writes a float global of one lane (uniform globals are written whatever the lane).
#[inline]
pub fn put1(raw: &mut RawBatch<'_>, slot: Option<Slot>, lane: usize, v: f32) {
    if let Some(s) = slot {
        if s.varying {
            raw.varying[s.offset * raw.stride + lane] = v;
        } else {
            raw.uniform[s.offset] = v;
        }
    }
}

/// Writes the same float global into lanes `0..raw.lanes` (one row fill, not a store per lane).
pub fn fill1(raw: &mut RawBatch<'_>, slot: Option<Slot>, v: f32) {
    if let Some(s) = slot {
        if s.varying {
            let row = s.offset * raw.stride;
            raw.varying[row..row + raw.lanes].fill(v);
        } else {
            raw.uniform[s.offset] = v;
        }
    }
}

/// Writes the same triple global into lanes `0..raw.lanes`.
pub fn fill3(raw: &mut RawBatch<'_>, slot: Option<Slot>, v: Vec3A) {
    if let Some(s) = slot {
        for (k, x) in v.to_array().into_iter().enumerate() {
            fill1(raw, Some(Slot { offset: s.offset + k, ..s }), x);
        }
    }
}

/// Writes a triple global of one lane.
#[inline]
pub fn put3(raw: &mut RawBatch<'_>, slot: Option<Slot>, lane: usize, v: Vec3A) {
    if let Some(s) = slot {
        if s.varying {
            let st = raw.stride;
            raw.varying[s.offset * st + lane] = v.x;
            raw.varying[(s.offset + 1) * st + lane] = v.y;
            raw.varying[(s.offset + 2) * st + lane] = v.z;
        } else {
            raw.uniform[s.offset..s.offset + 3].copy_from_slice(&v.to_array());
        }
    }
}

/// Reads a triple global of one lane, `default` when the shader does not have it.
#[inline]
pub fn get3(raw: &RawBatch<'_>, slot: Option<Slot>, lane: usize, default: Vec3A) -> Vec3A {
    match slot {
        Some(s) if s.varying => {
            let st = raw.stride;
            Vec3A::new(
                raw.varying[s.offset * st + lane],
                raw.varying[(s.offset + 1) * st + lane],
                raw.varying[(s.offset + 2) * st + lane],
            )
        }
        Some(s) => Vec3A::new(raw.uniform[s.offset], raw.uniform[s.offset + 1], raw.uniform[s.offset + 2]),
        None => default,
    }
}

/// Writes component `comp` of a global for every lane at once: lane `l` gets `values[l]`. The
/// same as [`put1`] lane by lane (a uniform global takes the last lane's value), written as one
/// row.
pub fn put_row(raw: &mut RawBatch<'_>, slot: Option<Slot>, comp: usize, values: &[f32]) {
    put_row_at(raw, slot, comp, 0, values);
}

/// [`put_row`] for the lanes from `first` on: lane `first + l` gets `values[l]` (a batch holding
/// several packets takes each packet's row at its own lanes).
pub fn put_row_at(raw: &mut RawBatch<'_>, slot: Option<Slot>, comp: usize, first: usize, values: &[f32]) {
    let Some(s) = slot else { return };
    let n = raw.lanes.saturating_sub(first).min(values.len());
    if s.varying {
        let row = (s.offset + comp) * raw.stride + first;
        raw.varying[row..row + n].copy_from_slice(&values[..n]);
    } else if n > 0 {
        raw.uniform[s.offset + comp] = values[n - 1];
    }
}

/// Reads component `comp` of a global for every lane into `out` (`default` when the shader does
/// not have the global): [`get3`] lane by lane, as one row.
pub fn get_row(raw: &RawBatch<'_>, slot: Option<Slot>, comp: usize, default: f32, out: &mut [f32]) {
    get_row_at(raw, slot, comp, 0, default, out);
}

/// [`get_row`] for the lanes from `first` on: `out[l]` gets lane `first + l`.
pub fn get_row_at(raw: &RawBatch<'_>, slot: Option<Slot>, comp: usize, first: usize, default: f32, out: &mut [f32]) {
    let n = raw.lanes.saturating_sub(first).min(out.len());
    match slot {
        Some(s) if s.varying => {
            let row = (s.offset + comp) * raw.stride + first;
            out[..n].copy_from_slice(&raw.varying[row..row + n]);
        }
        Some(s) => out[..n].fill(raw.uniform[s.offset + comp]),
        None => out[..n].fill(default),
    }
}

/// A batch kept for reuse, with the program it was made for; `None` while a caller has it. The
/// entry outlives the loan, so taking and giving back touch neither the program's reference counts
/// (atomics on a line every thread shares, which a `Weak` dropped and made again would touch for
/// every light of every batch) nor the batch (boxed: a few hundred bytes).
type PooledBatch = (Weak<ShaderProgram>, Option<Box<BatchData>>);

/// Most batches kept per thread (a frame uses a handful of programs, recursion a few more).
const POOL_SIZE: usize = 32;

thread_local! {
    static BATCHES: RefCell<Vec<PooledBatch>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` with a batch of `lanes` lanes for `program`, reset (all lanes active, zeros, nothing
/// bound), taken from this thread's pool and returned to it afterwards. Shading recurses (a surface
/// traces rays whose hits are shaded with the same program), so a batch is taken out of the pool
/// while in use rather than borrowed.
pub fn with_batch<R>(program: &Program, lanes: usize, f: impl FnOnce(&mut BatchData) -> R) -> R {
    with_filled_batch(program, lanes, &[], f)
}

/// The varying slots of globals (each with its number of components) as ranges of slot indices,
/// for [`with_filled_batch`]: empty for a global the shader does not use or has uniform.
pub fn varying_rows<const N: usize>(globals: [(Option<Slot>, usize); N]) -> [std::ops::Range<usize>; N] {
    globals.map(|(slot, comps)| match slot {
        Some(s) if s.varying => s.offset..s.offset + comps,
        _ => 0..0,
    })
}

/// [`with_batch`] for a caller that fills the varying slots in `filled` (ranges of slot indices)
/// for every lane itself, or leaves them to a shader that assigns them first thing: the reset does
/// not zero them (see [`BatchData::reset_except`]).
pub fn with_filled_batch<R>(
    program: &Program,
    lanes: usize,
    filled: &[std::ops::Range<usize>],
    f: impl FnOnce(&mut BatchData) -> R,
) -> R {
    // Identity by address is sound: the pool's `Weak` keeps the program's allocation from being
    // reused by another program while the batch is pooled.
    let me = Arc::as_ptr(program);
    let of_mine = |owner: &Weak<ShaderProgram>| std::ptr::eq(owner.as_ptr(), me);
    let taken = BATCHES.with(|b| {
        let mut b = b.borrow_mut();
        b.iter_mut().rev().find(|(owner, batch)| batch.is_some() && of_mine(owner)).and_then(|(_, batch)| batch.take())
    });
    let mut batch = taken.unwrap_or_else(|| Box::new(program.code.batch(lanes)));
    batch.reset_except(lanes, filled);
    let r = {
        let _timer = crate::render::ShaderKindTimer::enter(program);
        f(&mut batch)
    };
    BATCHES.with(|b| {
        let mut b = b.borrow_mut();
        if let Some((_, empty)) = b.iter_mut().rev().find(|(owner, batch)| batch.is_none() && of_mine(owner)) {
            *empty = Some(batch);
            return;
        }
        if b.len() >= POOL_SIZE {
            // Forget the batches of programs that are gone first, then the oldest.
            b.retain(|(owner, _)| owner.strong_count() > 0);
            if b.len() >= POOL_SIZE {
                b.remove(0);
            }
        }
        b.push((Arc::downgrade(program), Some(batch)));
    });
    r
}

//! The batch record generated code reads (`docs/packet-abi.md`): its layout and the offsets the
//! code addresses its fields by, the string table behind its string handles, and [`BatchData`],
//! the owned buffers a caller fills, hands to [`super::CompiledShader::shade`] and reads back.
//!
//! **Memory safety**: [`BatchData`] sizes every buffer from the [`Layout`] it was made for, so a
//! record made from it is valid for the code compiled with that layout.

use super::host;
use super::layout::Layout;
use crate::shadeops::format;
use std::sync::Arc;

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
    /// The image a pixel shader finishes ([`host::HostTable::pixels`]), which generated code
    /// reads inline; null where there is none (then `pixelvalue` calls its helper).
    pub pixels: *const host::PixelView,
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
    /// What the strings the shader made take, against `shadeops::format::STRING_BYTES_BUDGET`.
    made_bytes: usize,
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
        self.made_bytes = 0;
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

    /// The handle of a string the shader made (`concat`, `format`), added when new unless the
    /// strings made since the last reset would then take more than
    /// `shadeops::format::STRING_BYTES_BUDGET`: `None`, and the caller uses the empty string.
    pub fn intern_made(&mut self, s: &str) -> Option<u32> {
        if let Some(h) = self.index.get(s) {
            return Some(*h);
        }
        let cost = s.len().saturating_add(format::STRING_OVERHEAD);
        if self.made_bytes.saturating_add(cost) > format::STRING_BYTES_BUDGET {
            return None;
        }
        self.made_bytes += cost;
        Some(self.intern(s))
    }

    /// The string of a handle; "" for a handle out of range.
    pub fn get(&self, h: u32) -> &str {
        self.strings.get(h as usize).map(String::as_str).unwrap_or("")
    }
}

pub(super) const OFF_STRIDE: i32 = 4;
pub(super) const OFF_MASK: i32 = 8;
pub(super) const OFF_VARYING: i32 = 16;
pub(super) const OFF_UNIFORM: i32 = 24;
pub(super) const OFF_BOUND: i32 = 32;
pub(super) const OFF_DERIVS: i32 = 48;
pub(super) const OFF_CHUNK: i32 = 64;
pub(super) const OFF_PIXELS: i32 = 72;

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
    assert!(offset_of!(Batch, pixels) == OFF_PIXELS as usize);
};

/// The entry point of a compiled shader.
pub type ShadeFn = unsafe extern "C" fn(*mut Batch);

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

/// A batch's values, saved by [`BatchData::save_values`].
#[derive(Clone, Debug, Default)]
pub struct SavedValues {
    mask: Vec<i32>,
    varying: Vec<f32>,
    uniform: Vec<f32>,
    bound: Vec<u32>,
    derivs: Vec<f32>,
}

/// The buffers of a [`BatchData`] for a renderer that fills batches itself, by the slot numbers
/// of the [`Layout`] (slot `s` of lane `l` at `varying[s * stride + l]`).
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

    /// The raw buffers, to fill inputs and read outputs by slot.
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

    /// Whether the batch was made for `layout` (that one, or an equal one).
    pub(super) fn made_for(&self, layout: &Arc<Layout>) -> bool {
        Arc::ptr_eq(layout, &self.layout) || **layout == *self.layout
    }

    /// The record generated code reads, pointing into this batch's buffers, with `ctx` as its
    /// call table and helpers' scratch, before the first chunk.
    pub(super) fn record(&mut self, ctx: &mut host::HostCtx) -> Batch {
        Batch {
            lanes: self.lanes as u32,
            stride: self.stride as u32,
            mask: self.mask.as_ptr(),
            varying: self.varying.as_mut_ptr(),
            uniform: self.uniform.as_mut_ptr(),
            bound: self.bound.as_ptr(),
            strings: &mut self.strings,
            derivs: if self.derivs.is_empty() { std::ptr::null() } else { self.derivs.as_ptr() },
            pixels: ctx.pixels(),
            ctx,
            chunk: u32::MAX,
        }
    }
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

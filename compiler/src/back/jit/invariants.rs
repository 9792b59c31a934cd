//! Loop invariants kept in memory: the vector constants and the prologue's values that the chunk
//! loop uses are stored once, in a stack slot, and loaded where the loop uses them.
//!
//! Why: Cranelift hoists every loop-invariant pure value (a splatted constant, a space's matrix
//! entry, a uniform computed before the loop) out of the loop, and x86-64 has 16 vector registers.
//! A shader with more invariants than registers then had them split by the register allocator:
//! reloaded from spill slots inside the chunk and stored back to those slots on every iteration's
//! back edge (a fisheye camera paid 19 such stores a chunk). Loaded from memory at each use
//! instead, an invariant holds no register across the loop, there is nothing to store back, and a
//! load used once next to its user becomes that instruction's memory operand.
//!
//! Invariants:
//! - Moved: vector constants, and values of 128-bit vector, `f32` and integer types (pointers, row
//!   offsets, flags) defined outside the loop. Scalar constants stay as they are (Cranelift
//!   rematerialises them).
//! - A constant is stored at the function's entry, before anything runs; any other value right
//!   after its definition (the first instruction of its block, for a block parameter), so the store
//!   dominates every load that replaces one of its uses.
//! - Loads go only into loop blocks (`in_loop`); uses outside the loop keep the value itself.
//! - Nothing else writes the slot, so a load reads what the value was when its use would have run.
//! - The pass runs on optimised code and nothing optimises after it (`define` in `mod.rs`): a
//!   second e-graph pass would sink every pure instruction to its first side-effecting user, away
//!   from the loads placed beside it.

use cranelift_codegen::cursor::{Cursor, FuncCursor};
use cranelift_codegen::ir::{
    types, Block, ConstantData, Function, Inst, InstBuilder, InstructionData, MemFlagsData, Opcode, StackSlotData,
    StackSlotKind, Type, Value, ValueDef,
};
use std::collections::HashMap;

/// What a use in the loop refers to.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Invariant {
    /// A vector constant of this type and these bytes (little endian).
    Constant(Type, u128),
    /// A value defined outside the loop.
    Value(Value),
}

/// Moves the loop's uses of invariants (see the module docs) to loads from a stack slot; `entry`
/// is the function's entry block, `in_loop` tells the chunk loop's blocks. Returns how many uses
/// now load.
///
/// One 16-byte entry per invariant, loaded afresh at every use: nothing after this pass merges
/// loads (alias analysis runs in the e-graph pass, which the final compilation skips).
pub(super) fn keep_in_memory(func: &mut Function, ptr: Type, entry: Block, in_loop: &dyn Fn(Block) -> bool) -> usize {
    let mut uses: Vec<(Inst, Value, Invariant)> = Vec::new();
    for block in func.layout.blocks() {
        if !in_loop(block) {
            continue;
        }
        for inst in func.layout.block_insts(block) {
            for v in func.dfg.inst_values(inst) {
                if let Some(inv) = classify(func, v, in_loop) {
                    if !uses.iter().rev().take_while(|u| u.0 == inst).any(|u| u.1 == v) {
                        uses.push((inst, v, inv));
                    }
                }
            }
        }
    }
    let Some(last) = func.layout.last_inst(entry).filter(|_| !uses.is_empty()) else { return 0 };
    // The invariants in the order first used, and each one's offset in the slot.
    let mut invariants: Vec<Invariant> = Vec::new();
    let mut offsets: HashMap<Invariant, i32> = HashMap::new();
    for (_, _, inv) in &uses {
        offsets.entry(*inv).or_insert_with(|| {
            invariants.push(*inv);
            ((invariants.len() - 1) * 16) as i32
        });
    }
    let size = (invariants.len() * 16) as u32;
    let slot = func.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, size, 4));
    let offset = |inv: &Invariant| offsets.get(inv).copied().unwrap_or(0);
    let mut pos = FuncCursor::new(func);
    for inv in &invariants {
        let value = match *inv {
            Invariant::Constant(ty, bits) => {
                pos.goto_inst(last);
                let handle = pos.func.dfg.constants.insert(ConstantData::from(bits.to_le_bytes().to_vec()));
                pos.ins().vconst(ty, handle)
            }
            Invariant::Value(v) => {
                match pos.func.dfg.value_def(v) {
                    ValueDef::Result(def, _) => pos.goto_after_inst(def),
                    ValueDef::Param(block, _) => pos.goto_first_insertion_point(block),
                    _ => continue,
                }
                v
            }
        };
        pos.ins().stack_store(ptr, value, slot, offset(inv));
    }
    // The slot's address, in a register through the loop: a load from it plus an offset is then a
    // memory operand (one addressed as a stack slot costs an extra `lea` when sunk).
    pos.goto_inst(last);
    let base = pos.ins().stack_addr(ptr, slot, 0);
    for (inst, v, inv) in &uses {
        let ty = match *inv {
            Invariant::Constant(ty, _) => ty,
            Invariant::Value(x) => pos.func.dfg.value_type(x),
        };
        pos.goto_inst(*inst);
        // Aligned (the slot and its entries are 16-byte aligned): x86-64 sinks only an aligned
        // 128-bit load into a float instruction's memory operand.
        let loaded = pos.ins().load(ty, MemFlagsData::trusted(), base, offset(inv));
        pos.func.dfg.map_inst_values(*inst, |x| if x == *v { loaded } else { x });
    }
    uses.len()
}

/// The invariant a loop instruction's operand `v` is, if it is one to keep in memory.
fn classify(func: &Function, v: Value, in_loop: &dyn Fn(Block) -> bool) -> Option<Invariant> {
    let dfg = &func.dfg;
    let v = dfg.resolve_aliases(v);
    let ty = dfg.value_type(v);
    if !(ty == types::F32 || ty.is_int() || (ty.is_vector() && ty.bits() == 128)) {
        return None;
    }
    match dfg.value_def(v) {
        ValueDef::Result(def, _) => {
            if ty.is_vector() {
                if let Some(bits) = vector_constant(func, def, ty) {
                    return Some(Invariant::Constant(ty, bits));
                }
            } else if matches!(dfg.insts[def].opcode(), Opcode::F32const | Opcode::Iconst) {
                return None;
            }
            let block = func.layout.inst_block(def)?;
            (!in_loop(block)).then_some(Invariant::Value(v))
        }
        ValueDef::Param(block, _) => (!in_loop(block)).then_some(Invariant::Value(v)),
        _ => None,
    }
}

/// The bytes of a vector constant defined by `def` (a `vconst`, or a `splat` of a 32-bit integer
/// or float constant).
pub(super) fn vector_constant(func: &Function, def: Inst, ty: Type) -> Option<u128> {
    let dfg = &func.dfg;
    match dfg.insts[def] {
        InstructionData::UnaryConst { opcode: Opcode::Vconst, constant_handle } => {
            let bytes = dfg.constants.get(constant_handle).as_slice();
            let mut all = [0u8; 16];
            (bytes.len() == 16).then(|| {
                all.copy_from_slice(bytes);
                u128::from_le_bytes(all)
            })
        }
        InstructionData::Unary { opcode: Opcode::Splat, arg } if ty.lane_bits() == 32 => {
            let lane = match dfg.value_def(dfg.resolve_aliases(arg)) {
                ValueDef::Result(c, _) => match dfg.insts[c] {
                    InstructionData::UnaryIeee32 { opcode: Opcode::F32const, imm } => imm.bits(),
                    InstructionData::UnaryImm { opcode: Opcode::Iconst, imm } => imm.bits() as u32,
                    _ => return None,
                },
                _ => return None,
            };
            let lane = u128::from(lane);
            Some(lane | lane << 32 | lane << 64 | lane << 96)
        }
        _ => None,
    }
}

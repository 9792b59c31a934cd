//! Back ends that turn validated IR into code.
//!
//! [`jit`] is the Cranelift packet JIT: one compiled function shades a whole batch of lanes in SoA form
//! under an active-lane mask (the ABI of `docs/packet-abi.md`). The reference interpreter
//! (`crate::interp`) is the other back end and the JIT's oracle; the two share no code.

pub mod jit;

//! The packet JIT's public face: compile a checked [`Module`](crate::Module) to native code that
//! shades a batch of lanes per call, and what the compiled code says about itself (its batch
//! [`Layout`], the ray calls it makes, how a light emits). The data the code reads and writes at
//! run time is the packet ABI, in [`crate::abi`].

pub use crate::back::jit::{
    compile, compile_with, live_code_bytes, live_modules, CompiledShader, GlobalSlot, JitError, JitOptions, Layout,
    LightKind, ParamSlot, RayCalls, RuntimeErrors,
};

//! rtsl: a RenderMan-like shading language and the interactive ray tracer that runs it.
//!
//! This facade re-exports the two library crates: [`compiler`] (`.sl` source to checked IR and native
//! code) and [`runtime`] (scenes, the packet ray tracer, shading, the API). The `rtsl` binary is a thin
//! command line over them, with the benchmarks ([`bench`]) that time them through their public API.

pub use rtsl_compiler as compiler;
pub use rtsl_runtime as runtime;

pub mod bench;
pub mod default_scene;
pub mod preview;

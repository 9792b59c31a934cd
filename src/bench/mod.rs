//! The benchmarks behind `rtsl bench trace` and `rtsl bench shade`, kept out of the libraries: they
//! drive the tracer and the compiled shaders through the same public API an application uses.

pub mod native_plastic;
pub mod shading;
pub mod trace;

pub use trace::{run_bench, BenchError, BenchOptions, BenchReport};

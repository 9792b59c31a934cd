//! The rtsl shading language compiler.
//!
//! The pipeline: [`front::preprocess`] (a C preprocessor over [`front::lex`] tokens) ->
//! [`front::parse`] (a lalrpop LR(1) grammar, to an AST with spans) -> `front::check` (name resolution,
//! RSL's typing rules, overloads against the one table of built-ins, uniform/varying inference,
//! lowering to the typed IR in `ir`) -> `valid` (IR invariants and the facts back ends need) -> a
//! back end (the Cranelift packet JIT, or the reference interpreter).
//!
//! The compiler knows nothing of scenes or the frame loop: the renderer reaches it only through this
//! crate's public API, and shaders reach the renderer only through the services trait it defines.

/// The compiler's internals: public with the `internals` feature (the compiler's own tests,
/// benchmarks and fuzz targets enable it), crate-private otherwise, so that a renderer can use only
/// the compile API, the interface, artifacts, [`jit`] and [`abi`].
macro_rules! internal_modules {
    ($($(#[$attr:meta])* $name:ident;)*) => {
        $(
            $(#[$attr])*
            #[cfg(feature = "internals")]
            pub mod $name;
            $(#[$attr])*
            #[cfg(not(feature = "internals"))]
            pub(crate) mod $name;
        )*
    };
}

internal_modules! {
    /// Back ends: the Cranelift packet JIT (its public face is [`jit`]).
    back;
    /// Preprocessor, lexer, parser and checker.
    front;
    /// The typed IR every back end reads.
    ir;
    /// The IR validator.
    valid;
}

pub mod abi;
pub mod artifact;
pub mod builtins;
pub mod compile;
pub mod diagnostic;
pub mod globals;
pub mod interface;
pub mod interp;
pub mod jit;
pub mod shadeops;
pub mod source;
pub mod symbol;
pub mod testshade;

pub use compile::{compile_file, compile_source, compile_source_at, Compilation, Options, Session};
pub use diagnostic::{Code, Diagnostic, Severity};
/// A compilation's checked IR: what the JIT compiles and an artifact carries. Outside the compiler
/// it is opaque (the `internals` feature opens the IR).
pub use ir::Module;

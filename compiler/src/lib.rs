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

pub mod abi;
pub mod artifact;
pub mod back;
pub mod bench;
pub mod builtins;
pub mod compile;
pub mod diagnostic;
pub mod front;
pub mod globals;
pub mod interface;
pub mod interp;
pub mod ir;
pub mod shadeops;
pub mod source;
pub mod symbol;
pub mod testshade;
pub mod valid;

pub use compile::{compile_file, compile_source, compile_source_at, Compilation, Options, Session};
pub use diagnostic::{Code, Diagnostic, Severity};

//! Front end: source text to a checked IR.
//!
//! `preprocess` (tokens, directives, macros) -> `parse` (lalrpop, to the AST in `parse::ast`) ->
//! `check` (names, types, overloads, uniform/varying, lowering to [`crate::ir`]). Each phase reports
//! problems as diagnostics and returns a value anyway, so later phases still run on what parsed.

pub mod check;
pub mod lex;
pub mod parse;
pub mod preprocess;

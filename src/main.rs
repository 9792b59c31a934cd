//! The `rtsl` command line. Each subcommand parses its flags into an options struct and calls the
//! libraries; `main` only maps results to exit codes.

mod cli;

/// The compiler and the renderer allocate many small, short-lived objects (AST nodes, IR, packets of
/// hits) from several threads; mimalloc handles that pattern markedly faster than the system
/// allocator (measured: `rtsl bench frontend`, see the commit that added it).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            // A closed pipe (`rtsl info x | head`) is not an error.
            if e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            }) {
                return ExitCode::SUCCESS;
            }
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

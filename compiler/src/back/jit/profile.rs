//! Hooks that let outside profilers see JIT code, switched on by environment variables so that
//! release binaries can be profiled as they are:
//!
//! - `RTSL_PERF_MAP=1` appends each compiled shader's address range to `/tmp/perf-<pid>.map`, the
//!   file `perf report` reads to name code that no ELF file describes (the convention wasmtime's
//!   `--profile=perfmap` and V8's `--perf-basic-prof` follow).
//! - `RTSL_JIT_DISASM=DIR` writes each shader's machine code as Cranelift prints it (with block
//!   labels and the register allocator's spills) to `DIR/shade_<name>.s`.
//!
//! Failures to write are reported once on stderr and otherwise ignored: profiling aids must not
//! make a render fail.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};

/// Whether `RTSL_JIT_DISASM` asks for disassembly (read once per process).
pub fn disasm_dir() -> Option<&'static PathBuf> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| std::env::var_os("RTSL_JIT_DISASM").filter(|d| !d.is_empty()).map(PathBuf::from)).as_ref()
}

fn perf_map_enabled() -> bool {
    static ON: OnceLock<bool> = OnceLock::new();
    *ON.get_or_init(|| std::env::var_os("RTSL_PERF_MAP").is_some_and(|v| !v.is_empty() && v != "0"))
}

/// Records a finished function: `code` is its first byte, `bytes` its length.
pub fn record(name: &str, code: *const u8, bytes: usize, disasm: Option<&str>) {
    if perf_map_enabled() {
        // One writer at a time, so that lines from shaders compiled on several threads stay whole.
        static MAP: Mutex<()> = Mutex::new(());
        let _guard = MAP.lock().unwrap_or_else(|e| e.into_inner());
        let path = format!("/tmp/perf-{}.map", std::process::id());
        let line = format!("{:x} {:x} {name}\n", code as usize, bytes.max(1));
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .and_then(|mut f| f.write_all(line.as_bytes()));
        if let Err(e) = written {
            warn_once(&format!("RTSL_PERF_MAP: cannot write {path}: {e}"));
        }
    }
    if let (Some(dir), Some(text)) = (disasm_dir(), disasm) {
        let header = format!("; {name} at {:#x}, {bytes} bytes\n", code as usize);
        if let Err(e) = write_disasm(dir, name, &(header + text)) {
            warn_once(&format!("RTSL_JIT_DISASM: cannot write {name}.s in {}: {e}", dir.display()));
        }
    }
}

/// Writes `DIR/<name>.s`, making `dir` if it is missing.
fn write_disasm(dir: &std::path::Path, name: &str, text: &str) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join(format!("{name}.s")), text)
}

fn warn_once(message: &str) {
    static WARNED: OnceLock<()> = OnceLock::new();
    if WARNED.set(()).is_ok() {
        eprintln!("warning: {message}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disassembly_goes_into_a_made_directory_and_a_bad_one_is_an_error() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let dir = tmp.path().join("nested/dis");
        write_disasm(&dir, "shade_x", "; code\n").expect("written");
        assert_eq!(std::fs::read_to_string(dir.join("shade_x.s")).expect("read"), "; code\n");
        // A "directory" that is a file: an error to warn about, not a panic.
        let file = tmp.path().join("plain");
        std::fs::write(&file, "").expect("file");
        assert!(write_disasm(&file, "shade_x", "; code\n").is_err());
    }
}

//! The `rtsl` command line. Each subcommand parses its flags into an options struct and calls the
//! libraries; `main` only maps results to exit codes.

mod cli;

/// The compiler and the renderer allocate many small, short-lived objects (IR, diagnostics, packets
/// of hits) from several threads; mimalloc handles that pattern markedly faster than the system
/// allocator (measured: `rtsl bench frontend`, see the commit that added it).
#[global_allocator]
static GLOBAL: MiMalloc = MiMalloc;

/// mimalloc as the global allocator, through its plain entry points where the alignment allows.
///
/// The `mimalloc` crate's allocator calls `mi_malloc_aligned` for every allocation, which in
/// mimalloc 3 takes a slower path than `mi_malloc` even when the alignment is one that `mi_malloc`
/// guarantees anyway: 1.5% of the front end's instructions (`rtsl bench frontend` under callgrind).
struct MiMalloc;

/// The alignment every `mi_malloc` block has on 64-bit targets (`MI_MAX_ALIGN_SIZE`).
const MI_MALLOC_ALIGN: usize = 16;

// SAFETY: every block comes from mimalloc with at least the layout's alignment (`mi_malloc` and
// friends for alignments it guarantees, the `_aligned` variants otherwise) and goes back to
// `mi_free`/`mi_realloc*`, which accept blocks from either family.
unsafe impl std::alloc::GlobalAlloc for MiMalloc {
    #[inline]
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        use libmimalloc_sys::{mi_malloc, mi_malloc_aligned};
        unsafe {
            if layout.align() <= MI_MALLOC_ALIGN {
                mi_malloc(layout.size()).cast()
            } else {
                mi_malloc_aligned(layout.size(), layout.align()).cast()
            }
        }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        use libmimalloc_sys::{mi_zalloc, mi_zalloc_aligned};
        unsafe {
            if layout.align() <= MI_MALLOC_ALIGN {
                mi_zalloc(layout.size()).cast()
            } else {
                mi_zalloc_aligned(layout.size(), layout.align()).cast()
            }
        }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, _layout: std::alloc::Layout) {
        unsafe { libmimalloc_sys::mi_free(ptr.cast()) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        use libmimalloc_sys::{mi_realloc, mi_realloc_aligned};
        unsafe {
            if layout.align() <= MI_MALLOC_ALIGN {
                mi_realloc(ptr.cast(), new_size).cast()
            } else {
                mi_realloc_aligned(ptr.cast(), new_size, layout.align()).cast()
            }
        }
    }
}

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

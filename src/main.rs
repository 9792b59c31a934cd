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
/// guarantees anyway, which shows in allocation-heavy code such as the front end's.
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

/// Whether this CPU has the instructions the build was compiled for (`.cargo/config.toml`
/// targets x86-64-v3), or the first one it lacks. Without them the program would stop with an
/// illegal instruction somewhere in its first vector loop.
fn check_instruction_set() -> Result<(), &'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        macro_rules! require {
            ($($feature:tt),*) => {
                $(if cfg!(target_feature = $feature) && !std::arch::is_x86_feature_detected!($feature) {
                    return Err($feature);
                })*
            };
        }
        require!("avx", "avx2", "fma", "bmi1", "bmi2", "f16c", "lzcnt", "movbe");
    }
    Ok(())
}

/// `mi_option_arena_purge_mult` in mimalloc 3's `mi_option_e` (mimalloc.h), which
/// libmimalloc-sys does not name without its `extended` feature.
const MI_OPTION_ARENA_PURGE_MULT: std::ffi::c_int = 24;

/// `mi_option_allow_thp` in mimalloc 3's `mi_option_e`.
#[cfg(any(feature = "mpi", test))]
const MI_OPTION_ALLOW_THP: std::ffi::c_int = 43;

unsafe extern "C" {
    fn mi_option_set_default(option: std::ffi::c_int, value: std::ffi::c_long);
    #[cfg(any(feature = "mpi", test))]
    fn mi_option_set(option: std::ffi::c_int, value: std::ffi::c_long);
    #[cfg(test)]
    fn mi_option_get(option: std::ffi::c_int) -> std::ffi::c_long;
}

/// Hands memory that frames free back to the system every ten seconds rather than every second
/// (mimalloc's default; `MIMALLOC_ARENA_PURGE_MULT` still overrides this).
///
/// A frame frees its large buffers (the framebuffer, tiles' samples, batches) when it ends, and
/// the next frame asks for them again. Each time mimalloc purges the free memory, the frames
/// after it fault it back in and the kernel zeroes it (`clear_page_erms` in `perf`); with the
/// longer delay an animation's frames reuse the memory instead.
fn keep_freed_memory_for_the_next_frames() {
    // The purge delay (1000 ms by default) times this multiplier is how long free arena memory
    // stays committed.
    // SAFETY: mimalloc's option setter takes any option number and value, and is thread safe.
    unsafe { mi_option_set_default(MI_OPTION_ARENA_PURGE_MULT, 10) }
}

/// Turns transparent huge pages off for this process, unless `MIMALLOC_ALLOW_THP` says
/// otherwise (mimalloc's own switch, which it reads before `main`). Called where a process joins
/// a distributed render (`cli::mpi::transport`); other runs keep them.
///
/// mimalloc asks for huge pages on its arenas, so the first touch of any fresh part of one
/// faults in and zeroes two megabytes. A distributed worker's memory grows all through its first
/// frames, with the meshes it fetches and the messages that bring them, and each growth paid for
/// the zeroing on the render thread: most of its system time, and the first frame several times
/// as long as with small pages (`docs/bart.md`). A renderer in one process grows mostly as it
/// loads the scene and builds its BVHs; for it huge pages mean fewer TLB misses when rays reach
/// the large arrays at random and a 512th of the faults when a build first touches them
/// (`docs/tracer.md`).
#[cfg(any(feature = "mpi", test))]
pub(crate) fn no_transparent_huge_pages() {
    if std::env::var_os("MIMALLOC_ALLOW_THP").is_some() {
        return;
    }
    // SAFETY: mimalloc's option setter takes any option number and value, and is thread safe;
    // PR_SET_THP_DISABLE takes a flag and changes only this process's future page faults.
    unsafe {
        mi_option_set(MI_OPTION_ALLOW_THP, 0);
        #[cfg(target_os = "linux")]
        libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0);
    }
}

use std::process::ExitCode;

fn main() -> ExitCode {
    if let Err(missing) = check_instruction_set() {
        eprintln!(
            "error: this build of rtsl needs a CPU with {missing} (x86-64-v3, `.cargo/config.toml`); \
             rebuild it with RUSTFLAGS=\"-C target-cpu=x86-64\" for this one"
        );
        return ExitCode::from(2);
    }
    keep_freed_memory_for_the_next_frames();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The option number is mimalloc's arena purge multiplier: its neighbours in `mi_option_e`
    /// read their own defaults (the purge delay, 1000 ms, and the arena reserve, 1 GiB in KiB),
    /// and it reads its own default or the value set.
    #[test]
    fn the_arena_purge_multiplier_is_the_option_set() {
        // SAFETY: reading and setting options is thread safe and takes any option number.
        unsafe {
            assert_eq!(mi_option_get(MI_OPTION_ARENA_PURGE_MULT - 9), 1000, "mi_option_purge_delay");
            assert_eq!(mi_option_get(MI_OPTION_ARENA_PURGE_MULT - 1), 1024 * 1024, "mi_option_arena_reserve");
            keep_freed_memory_for_the_next_frames();
            // The default applies only if no purge has read the option yet (other tests may
            // have freed memory first).
            assert!([1, 10].contains(&mi_option_get(MI_OPTION_ARENA_PURGE_MULT)));
        }
    }

    /// The option number is mimalloc's huge page switch: its neighbours in `mi_option_e` read
    /// their own defaults (cross-thread page reclaims, 32, and two after it the largest object
    /// an arena holds, 2 GiB in KiB), and once turned off it reads 0, and the process has huge
    /// pages off.
    #[test]
    fn transparent_huge_pages_are_turned_off() {
        if std::env::var_os("MIMALLOC_ALLOW_THP").is_some() {
            return;
        }
        // SAFETY: reading options is thread safe and takes any option number; PR_GET_THP_DISABLE
        // only reads.
        unsafe {
            assert_eq!(mi_option_get(MI_OPTION_ALLOW_THP - 1), 32, "mi_option_page_cross_thread_max_reclaim");
            assert_eq!(mi_option_get(MI_OPTION_ALLOW_THP + 2), 2 << 20, "mi_option_arena_max_object_size");
            no_transparent_huge_pages();
            assert_eq!(mi_option_get(MI_OPTION_ALLOW_THP), 0);
            #[cfg(target_os = "linux")]
            assert_eq!(libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0), 1);
        }
    }
}

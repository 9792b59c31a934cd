//! The instruction set this crate's vector code was compiled for, against the CPU it runs on.
//!
//! rtsl's own builds target x86-64-v3 (AVX2, FMA: `.cargo/config.toml`), and the `rtsl` binary
//! refuses a CPU without it. An application that depends on these crates compiles them with its
//! own flags, which by default target plain x86-64 (SSE2): everything works, but traversal,
//! texture filtering and the shading batches run their slower forms. Cranelift's shader code is
//! unaffected (it picks the host's instructions when it compiles). [`build_note`] says when that
//! happened on a CPU that could do better, and [`crate::api::Context`] reports it once per process
//! as a warning.

use std::sync::atomic::{AtomicBool, Ordering};

/// A note for an application whose build of this crate lacks AVX2 and FMA on a CPU that has them,
/// saying how to build it for them; `None` when the build fits the CPU (or is not for x86-64).
pub fn build_note() -> Option<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        let built_for_v3 = cfg!(target_feature = "avx2") && cfg!(target_feature = "fma");
        let cpu_has_v3 = std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma");
        if !built_for_v3 && cpu_has_v3 {
            return Some(
                "rtsl-runtime was compiled without AVX2 and FMA, which this CPU has, so its vector code \
                 runs slower than it could: build the application with RUSTFLAGS=\"-C target-cpu=x86-64-v3\" \
                 (or a `[target.x86_64-unknown-linux-gnu] rustflags` entry in .cargo/config.toml), as rtsl's \
                 own builds are",
            );
        }
    }
    None
}

/// [`build_note`], the first time it is asked for in this process only.
pub(crate) fn build_note_once() -> Option<&'static str> {
    static TOLD: AtomicBool = AtomicBool::new(false);
    build_note().filter(|_| !TOLD.swap(true, Ordering::Relaxed))
}

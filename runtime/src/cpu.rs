//! The instruction set this crate's vector code was compiled for, against the CPU it runs on.
//!
//! rtsl's own builds target x86-64-v3 (AVX2, FMA: `.cargo/config.toml`), and the `rtsl` binary
//! refuses a CPU without it. An application that depends on these crates compiles them with its
//! own flags, which by default target plain x86-64 (SSE2): everything works, but traversal,
//! texture filtering and the shading batches run their slower forms. Cranelift's shader code is
//! unaffected (it picks the host's instructions when it compiles). [`build_note`] says when that
//! happened on a CPU that could do better, and [`crate::api::Context`] reports it once per process
//! as a warning.
//!
//! The packet-traversal kernels are also compiled a second time for AVX-512 (x86-64-v4) and that
//! form runs where the processor has it ([`kernel_isa`]), so one binary serves both.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

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

/// The instruction set the packet-traversal kernels run with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelIsa {
    /// The instruction set this crate was compiled for (x86-64-v3 in rtsl's own builds).
    Built,
    /// AVX-512 (the x86-64-v4 set: F, BW, CD, DQ, VL, with x86-64-v3's): 32 vector registers,
    /// mask registers and three-operand logic for the same eight-lane code.
    Avx512,
}

impl KernelIsa {
    /// The name `RTSL_ISA` takes and `rtsl bench` prints.
    pub fn name(self) -> &'static str {
        match self {
            KernelIsa::Avx512 => "avx512",
            KernelIsa::Built if cfg!(all(target_feature = "avx2", target_feature = "fma")) => "avx2",
            KernelIsa::Built if cfg!(target_arch = "x86_64") => "sse2",
            KernelIsa::Built => "baseline",
        }
    }
}

/// Whether this processor has every feature the AVX-512 kernels are compiled with (the
/// `target_feature` list of `accel::packet`'s `Avx512` kernels). Asked for every packet: looked up
/// once.
pub(crate) fn has_avx512() -> bool {
    static HAS: OnceLock<bool> = OnceLock::new();
    *HAS.get_or_init(detect_avx512)
}

fn detect_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        has!("avx512f")
            && has!("avx512bw")
            && has!("avx512cd")
            && has!("avx512dq")
            && has!("avx512vl")
            && has!("avx2")
            && has!("fma")
            && has!("bmi1")
            && has!("bmi2")
            && has!("lzcnt")
            && has!("popcnt")
            && has!("f16c")
            && has!("movbe")
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// The kernels' instruction set in this process: AVX-512 where the processor has it, unless the
/// environment variable `RTSL_ISA` is `avx2` (to compare the two in one binary); decided once.
/// Any other value of `RTSL_ISA` than `avx2` and `avx512` is reported on standard error, once,
/// and ignored.
pub fn kernel_isa() -> KernelIsa {
    static DECIDED: OnceLock<KernelIsa> = OnceLock::new();
    *DECIDED.get_or_init(|| {
        let requested = std::env::var("RTSL_ISA").ok();
        choose_isa(requested.as_deref(), has_avx512()).unwrap_or_else(|value| {
            // Decided once, so said once.
            eprintln!("rtsl: RTSL_ISA={value:?} is neither `avx2` nor `avx512`; ignored");
            choose_isa(None, has_avx512()).unwrap_or(KernelIsa::Built)
        })
    })
}

/// The kernels for the value of `RTSL_ISA` (`None` when unset or empty) on a processor with
/// AVX-512 or without: never AVX-512 without it. `Err` gives back a value it does not know.
fn choose_isa(requested: Option<&str>, avx512: bool) -> Result<KernelIsa, String> {
    let best = if avx512 { KernelIsa::Avx512 } else { KernelIsa::Built };
    match requested.map(str::trim) {
        None | Some("") | Some("avx512") => Ok(best),
        Some("avx2") => Ok(KernelIsa::Built),
        Some(other) => Err(other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn avx512_kernels_run_only_where_the_processor_has_them() {
        assert_eq!(choose_isa(None, true), Ok(KernelIsa::Avx512));
        assert_eq!(choose_isa(Some("avx512"), true), Ok(KernelIsa::Avx512));
        assert_eq!(choose_isa(Some("avx512"), false), Ok(KernelIsa::Built));
        assert_eq!(choose_isa(None, false), Ok(KernelIsa::Built));
        assert_eq!(choose_isa(Some("avx2"), true), Ok(KernelIsa::Built));
        assert_eq!(choose_isa(Some(""), true), Ok(KernelIsa::Avx512));
        assert_eq!(choose_isa(Some("avx1024"), true), Err("avx1024".to_string()));
        // The decision this process made is one the processor can run.
        assert!(kernel_isa() == KernelIsa::Built || has_avx512());
    }
}

//! Contexts whose shaders come from one cache for the whole fuzzing run, as the frames of one
//! render share theirs: the library shaders an input's scene names are compiled once for the run
//! rather than once per input. Compiling them under the fuzzer's instrumentation was nearly all of
//! an input's time in the targets whose scenes have materials (about one RIB input a second); the
//! `compile` and `differential` targets fuzz the compiler itself.
//!
//! The run's own shaders ([`RUN_SHADERS`]) are on every context's search path, so that inputs
//! reach what no library shader does: `fuzzgrow` is a surface shader that moves `P`, which truly
//! displaces an object under a `displacementbound`.

use rtsl_runtime::api::{Context, ShaderCache};
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// Shaders written for the run, by file name.
const RUN_SHADERS: &[(&str, &str)] = &[(
    "fuzzgrow.sl",
    "surface fuzzgrow(float amount = 0.2) {
        P += amount * (noise(P) - 0.5) * normalize(N);
        N = calculatenormal(P);
        normal Nf = faceforward(normalize(N), I);
        Oi = Os;
        Ci = Os * Cs * (ambient() + diffuse(Nf));
    }",
)];

/// A new context that takes its shaders from the run's cache.
pub fn context() -> Context {
    static SHADERS: OnceLock<Arc<ShaderCache>> = OnceLock::new();
    let mut rt = Context::new();
    rt.share_shader_cache(SHADERS.get_or_init(Default::default).clone());
    if let Some(dir) = run_shader_dir() {
        rt.set_shader_search_path([dir]);
    }
    rt
}

/// The folder holding [`RUN_SHADERS`], written once for the run (`None` where it cannot be).
fn run_shader_dir() -> Option<&'static PathBuf> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("rtsl-fuzz-shaders-{}", std::process::id()));
        std::fs::create_dir_all(&dir).ok()?;
        for (name, source) in RUN_SHADERS {
            std::fs::write(dir.join(name), source).ok()?;
        }
        Some(dir)
    })
    .as_ref()
}

//! Contexts whose shaders come from one cache for the whole fuzzing run, as the frames of one
//! render share theirs: the library shaders an input's scene names are compiled once for the run
//! rather than once per input. Compiling them under the fuzzer's instrumentation was nearly all of
//! an input's time in the targets whose scenes have materials (about one RIB input a second); the
//! `compile` and `differential` targets fuzz the compiler itself.

use rtsl_runtime::api::{Context, ShaderCache};
use std::sync::{Arc, OnceLock};

/// A new context that takes its shaders from the run's cache.
pub fn context() -> Context {
    static SHADERS: OnceLock<Arc<ShaderCache>> = OnceLock::new();
    let mut rt = Context::new();
    rt.share_shader_cache(SHADERS.get_or_init(Default::default).clone());
    rt
}

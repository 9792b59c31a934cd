//! What hot reload did to a context's shaders, as the context queues it for the application
//! ([`super::Context::take_shader_events`]); `crate::reload` makes the events.

use super::ShaderId;
use std::path::PathBuf;

/// What hot reload did, for an application to show: drained from
/// [`super::Context::take_shader_events`].
#[derive(Clone, Debug, PartialEq)]
pub enum ShaderEvent {
    /// Shader `shader` (named `name`, from `path`) was recompiled and the next frame uses it.
    Reloaded { shader: ShaderId, name: String, path: PathBuf, compile_ms: f64 },
    /// An edit did not compile (or the new shader is of another type); the last good code stays.
    /// `diagnostics` is the compiler's rustc-style rendering.
    Failed { shader: ShaderId, name: String, path: PathBuf, diagnostics: String },
    /// A value bound to `parameter` does not fit the new parameter list of shader `shader` (the
    /// parameter is gone or has another type, said by `reason`): frames leave it out (the
    /// parameter takes its default) until a later version takes it again.
    ParameterDropped { shader: ShaderId, name: String, parameter: String, reason: String },
}

impl std::fmt::Display for ShaderEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ShaderEvent::Reloaded { name, path, compile_ms, .. } => {
                write!(f, "reloaded {name} ({}) in {compile_ms:.1} ms", path.display())
            }
            ShaderEvent::Failed { name, path, diagnostics, .. } => {
                write!(f, "{name} ({}) did not compile; the last good version stays:\n{diagnostics}", path.display())
            }
            ShaderEvent::ParameterDropped { reason, .. } => write!(f, "{reason}; the value is not used"),
        }
    }
}

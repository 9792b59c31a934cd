//! The rendering engine: a [`World`] (scene, materials, lights, camera, options) rendered frame by
//! frame. `frame.rs` generates primary packets over tiles; `shade.rs` shades hits through the JIT
//! code; `host.rs` answers the shaders' calls into the renderer (spaces, `trace`, textures,
//! messages); `lights.rs` runs light shaders over a batch and traces their shadows; `stats.rs`
//! counts; `differential.rs` carries ray differentials; `native.rs` is the hand-written baseline;
//! `progressive.rs` renders chosen pixels pass by pass into an accumulator (interactive viewers).

pub mod differential;
pub mod frame;
mod host;
mod lights;
pub mod native;
pub mod progressive;
pub mod shade;
mod stats;
pub mod world;

pub use frame::{camera_ray, primary_packet, render_frame, sample_offset, FrameReport, Framebuffer, TILE_SIZE};
pub use shade::{Frame, Sample};
pub use stats::Stats;
pub use world::{
    AccelUpdate, Antialiasing, AreaLight, CameraSetup, InstanceShading, LightSource, Material, RenderOptions, World,
    MAX_AREA_SAMPLES,
};

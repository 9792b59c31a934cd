//! The rendering engine: a [`World`] (scene, materials, lights, camera, options) rendered frame by
//! frame. `frame.rs` generates primary packets over tiles; `shade.rs` shades hits through the JIT
//! code and answers its calls into the renderer (lights, shadows, `trace`, spaces).

pub mod differential;
pub mod frame;
pub mod native;
pub mod shade;
pub mod world;

pub use frame::{primary_packet, render_frame, FrameReport, Framebuffer, TILE_SIZE};
pub use shade::{Frame, Sample, Stats};
pub use world::{
    AreaLight, CameraSetup, InstanceShading, LightSource, Material, RenderOptions, World, MAX_AREA_SAMPLES,
};

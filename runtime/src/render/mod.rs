//! The rendering engine: a [`World`] (scene, materials, lights, camera, options) rendered frame by
//! frame. `frame.rs` generates primary packets over tiles; `shade.rs` shades hits through the JIT
//! code, a group of hits by rows at a time (`jobs.rs`), from their geometry (`hit_geometry.rs`); `host.rs` answers the shaders' calls into the renderer (spaces, `trace`, textures,
//! messages); `lights.rs` runs light shaders over a batch and traces their shadows; `stats.rs`
//! counts; `volume.rs` runs atmosphere and interior shaders on ray segments; `differential.rs` carries ray differentials; `native.rs` lets Rust code shade a surface;
//! `progressive.rs` renders chosen pixels pass by pass into an accumulator (interactive viewers);
//! `primary.rs` makes primary rays (the built-in camera or the camera shader); `filter.rs` holds the
//! pixel filters and `film.rs` splats samples through them; `true_displacement.rs` moves the
//! geometry of objects whose displacement shaders ask to, before a frame.

mod caustic_aim;
pub mod differential;
mod emission;
mod film;
pub mod filter;
pub mod frame;
mod globals;
mod group;
mod hemisphere;
mod hit_geometry;
mod host;
mod jobs;
mod lanes;
mod lights;
pub mod native;
mod photon_map;
mod pixel;
pub mod primary;
pub mod progressive;
mod ray_budget;
pub mod ray_params;
pub mod remote_displacement;
mod sampling;
mod scratch;
pub mod shade;
mod stats;
mod trace_ahead;
pub mod true_displacement;
mod virtual_lights;
mod volume;
mod work;
pub mod world;

pub use filter::{FilterKind, PixelFilter};
pub use frame::{
    camera_ray, camera_samples, make_primary_rays, primary_packet, primary_packet_into, render_frame, sample_offset,
    trace_primary_rays, DisplayMode, FrameReport, Framebuffer, RenderedTile, TileRenderer, TILE_SIZE,
};
pub use primary::{primary_rays, primary_rays_into, CameraSample, PrimaryRays};
pub use ray_budget::RAY_TREE_BUDGET;
pub use ray_params::{RayField, RayParameterError, RayParameters, RayValue, RELEVANCE};
pub(crate) use stats::ShaderKindTimer;
pub use stats::Stats;
pub use work::{Frame, LightPathCache, LightPaths, Sample, SampleRows};
pub use world::{
    check_image_size, AccelUpdate, Antialiasing, AreaLight, CameraSetup, DepthFilter, InstanceParts, InstanceShading,
    LightSource, Material, RayKind, RefineOn, RenderOptions, TraceDepths, Visibility, World, MAX_AREA_SAMPLES,
    MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_PIXEL_SAMPLES,
};

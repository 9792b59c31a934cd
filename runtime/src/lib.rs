//! The rtsl rendering engine: scenes, acceleration structures, the packet ray tracer, shading
//! dispatch and the application API.
//!
//! The tracer (this crate's core so far) intersects rays with a two-level BVH: a top-level BVH
//! over instances, rebuilt every frame by [`Scene::commit`], whose leaves point at objects' own
//! BVHs (built with obvhs once per geometry change). Coherent 8x8 packets use packet traversal
//! ([`Scene::intersect_packet`], [`Scene::occluded_packet`]); incoherent rays use single-ray
//! traversal ([`Scene::intersect`], [`Scene::occluded`]). Tiles of the image are handed out
//! demand-driven over rayon ([`tiles::render_tiles`]). `docs/tracer.md` describes the design.
//!
//! Invariant: this crate never parses shader source itself: shaders reach it through
//! `rtsl-compiler`'s public API.

pub mod accel;
pub mod api;
pub mod bart;
pub mod camera;
pub mod cpu;
pub mod csg;
pub(crate) mod deflate;
pub mod distributed;
mod file_stamp;
pub mod geometry;
pub mod image_io;
pub mod lightfield;
pub mod load;
pub mod mesh_io;
pub mod ray;
pub mod reload;
pub mod render;
pub mod rib;
pub mod scene;
pub mod scene_file;
pub mod shading;
pub mod shared_files;
pub mod texture;
pub mod tiles;
pub mod vrml;

pub use accel::bvh4::BuildQuality;
pub use camera::Camera;
pub use geometry::{Attribute, Mesh, MeshError};
/// The vector maths of the API (positions, directions, transforms).
pub use glam;
pub use image_io::ByteTable;
pub use image_io::{diff_image, read_image, write_image, ImageDiff, ImageError, RgbaImage, Transfer, WriteOptions};
pub use load::{is_rib_path, load_rib_frames, load_scene, load_scene_frame, load_scene_with, LoadOptions, LoadedScene};
pub use mesh_io::{load_mesh, MeshIoError};
pub use ray::{offset_ray_origin, Hit, HitCandidate, HitFilter, HitPacket, Ray, RayPacket, INVALID_ID, PACKET_SIZE};
pub use scene::{scene_from_mesh, InstanceId, ObjectId, Scene, SceneError, SurfaceHit};
pub use texture::{Footprint, LookupOptions, TextureCache, TextureWarning, Wrap};

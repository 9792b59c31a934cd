//! BART, the Benchmark for Animated Ray Tracing (Lext, Assarsson and Möller, 2001): its scene
//! format and the playback of its animations.
//!
//! - `aff.rs`: the AFF reader (NFF plus keyframes, transform nodes, meshes, textures, includes)
//!   into an [`aff::AffScene`];
//! - `animation.rs`: the keyframe tracks and their Kochanek-Bartels interpolation;
//! - `load.rs`: the scene onto the API, one object (BVH) per rigid part and material, instances
//!   moved per frame by [`BartScene::set_time`].
//!
//! `docs/bart.md` describes the format support and the mapping; `rtsl bart` plays the scenes.

pub mod aff;
pub mod animation;
pub mod load;

pub use aff::{parse_file, parse_str, AffError, AffScene};
pub use load::{load_file, load_parsed, BartError, BartScene, Summary};

//! The packet ABI: what a renderer needs from compiled shaders to call them and to answer their
//! callbacks. `docs/packet-abi.md` is its specification: batches of lanes in structure-of-arrays
//! form under a mask, the host table of callbacks, the light rows of illuminance loops, strings
//! as references into a table, and the sizes these have.
//!
//! The JIT back end defines these types, which its generated code reads and writes at fixed
//! offsets; a renderer names them here, and nothing else of the back end but the compile API
//! ([`crate::jit`]).

pub use crate::back::jit::{
    environment_query_of, light_in_cone, same_category, shadow_query_of, BatchData, BatchLightsView, HostLight,
    HostTable, LightLanes, MessageOut, PixelChannel, PixelOutputs, PixelView, RawBatch, SavedValues, StrRef, CONE_ROWS,
    ENVIRONMENT_ROWS, EVERY_LIGHT, MAX_LIGHTS, NO_LIGHT, SHADOW_ROWS, TEXTURE_ROWS,
};
/// The built-ins, numbered as the host's query callbacks name the one asking (`option`,
/// `rendererinfo` and the like: `Builtin::ALL[which]`).
pub use crate::builtins::Builtin;
/// A `gather` sample's hit as the host's gather callback writes it (`GatherHit::ROWS` floats).
pub use crate::shadeops::gather::GatherHit;

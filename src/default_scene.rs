//! The default scene: what `rtsl render`, `rtsl view` and `rtsl lightfield capture` show when no
//! scene is named. It is the office of `examples/office/office.rib` (every shader type composing in
//! one room, docs/office.md), embedded in the binary together with the data files it reads, so it
//! renders from any directory on a fresh machine.

use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::rib::load::{load_str, LoadedRib};
use std::path::Path;

/// The scene's RIB text.
pub const RIB: &str = include_str!("../examples/office/office.rib");

/// The files the RIB names, by the names it uses for them (relative to `examples/office/`).
const DATA: [(&str, &[u8]); 2] = [
    ("data/neghip32.grid", include_bytes!("../examples/office/data/neghip32.grid")),
    ("data/spot_lightfield.png", include_bytes!("../examples/office/data/spot_lightfield.png")),
];

/// Loads the default scene into `rt`, its data files from memory.
pub fn load(rt: &mut Context) -> anyhow::Result<LoadedRib> {
    register_data(rt)?;
    Ok(load_str(rt, RIB, Path::new("<default scene>"))?)
}

fn register_data(rt: &mut Context) -> Result<(), ApiError> {
    for (name, bytes) in DATA {
        if name.ends_with(".grid") {
            rt.grid_file_in_memory(name, bytes)?;
        } else {
            rt.texture_file_in_memory(name, bytes)?;
        }
    }
    Ok(())
}

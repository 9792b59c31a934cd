//! What one rank of a distributed render reads from another, damaged or made up: a protocol
//! message, a rendered tile, a viewer lattice's samples, a texture as the master delivers it, a
//! frame's light paths as the master traced them. The
//! first byte picks the reader; each refuses what it cannot read with an error, never a panic or
//! an allocation larger than the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::distributed::Message;
use rtsl_runtime::render::progressive::{LatticeSamples, PixelLattice};
use rtsl_runtime::render::{LightPaths, RenderedTile, TileRenderer, World};
use std::sync::OnceLock;

/// A 40x24 frame of an empty scene, for the tiles to belong to.
fn world() -> &'static World {
    static WORLD: OnceLock<World> = OnceLock::new();
    WORLD.get_or_init(|| {
        let mut rt = rtsl_runtime::api::Context::new();
        rt.options.width = 40;
        rt.options.height = 24;
        rt.build_world().expect("an empty world builds")
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else { return };
    match which % 5 {
        0 => {
            if let Ok(m) = Message::decode(rest) {
                // What decodes encodes to the same bytes.
                assert_eq!(Message::decode(&m.encode()).as_ref(), Ok(&m));
            }
        }
        1 => {
            let world = world();
            let tiles = TileRenderer::new(world).tiles();
            let tile = tiles[usize::from(rest.first().copied().unwrap_or(0)) % tiles.len()];
            let _ = RenderedTile::decode(world, tile, rest.get(1..).unwrap_or(&[]));
        }
        2 => {
            let lattice = PixelLattice { x0: 8, y0: 0, stride: 2 };
            let lanes = rest.iter().take(8).fold(0u64, |m, &b| m << 8 | u64::from(b));
            let _ = LatticeSamples::decode(world(), lattice, lanes, rest);
        }
        3 => {
            let _ = postcard::from_bytes::<rtsl_runtime::texture::Delivered>(rest);
        }
        _ => {
            if let Ok(paths) = LightPaths::decode(rest) {
                // What decodes encodes to the same bytes (empty bytes are no paths, encoded as a flag).
                let mut again = Vec::new();
                paths.encode(&mut again);
                assert!(rest.is_empty() || again == rest);
            }
        }
    }
});

//! What one rank of a distributed render reads from another, damaged or made up: a protocol
//! message, a rendered tile, a viewer lattice's samples, a texture's pyramid and levels as the
//! master delivers them (looked up), a frame's light paths as the master traced them. The
//! first byte picks the reader; each refuses what it cannot read with an error, never a panic or
//! an allocation larger than the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::distributed::Message;
use rtsl_runtime::render::progressive::{LatticeSamples, PixelLattice};
use rtsl_runtime::render::{LightPaths, RenderedTile, TileRenderer, World};
use rtsl_runtime::texture::{
    decode_answer, Delivered, Footprint, LookupOptions, TextureAnswer, TextureCache, TexturePart, TextureSource,
};
use std::sync::{Arc, OnceLock};

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

/// A master that answers a texture's first request with `first` and every level with `level`.
#[derive(Debug)]
struct Answers {
    first: Vec<u8>,
    level: Vec<u8>,
}

impl TextureSource for Answers {
    fn fetch(&self, part: TexturePart, _name: &str) -> TextureAnswer {
        let bytes = if matches!(part, TexturePart::Level { .. }) { &self.level } else { &self.first };
        decode_answer(bytes).unwrap_or_else(|reason| TextureAnswer::Whole(Delivered::Missing { path: None, reason }))
    }
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
            // A texture answer, whatever it holds: the first answer of a texture's lookups, and
            // the answer to every level they fetch.
            let cut = usize::from(rest.first().copied().unwrap_or(0)).min(rest.len());
            let (first, level) = rest.split_at(cut);
            let source = Arc::new(Answers { first: first.to_vec(), level: level.to_vec() });
            let cache = TextureCache::new().with_source(Some(source));
            let mut out = [0.0; 4];
            for width in [0.0, 0.01, 0.3] {
                let footprint = Footprint { dsdx: width, dtdx: 0.0, dsdy: 0.0, dtdy: width };
                cache.texture("t", 0.3, 0.7, footprint, 0, &mut out, &LookupOptions::default());
            }
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

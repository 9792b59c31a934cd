//! What one rank of a distributed render reads from another, damaged or made up: a protocol
//! message, a rendered tile, a viewer lattice's samples, a texture's pyramid and levels as the
//! master delivers them (looked up), a frame's light paths as the master traced them, an
//! object's BVH as it comes with a mesh (whole, a small tree, or a part: traced once decoded). The
//! first byte picks the reader; each refuses what it cannot read with an error, never a panic or
//! an allocation larger than the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::accel::object::{Object, ObjectBvh};
use rtsl_runtime::accel::wire::{decode_bvh4, decode_part, decode_small_tree};
use rtsl_runtime::distributed::Message;
use rtsl_runtime::geometry::Mesh;
use rtsl_runtime::ray::{HitPacket, Ray, RayPacket};
use rtsl_runtime::render::progressive::{LatticeSamples, PixelLattice};
use rtsl_runtime::render::{LightPaths, RenderedTile, TileRenderer, World};
use rtsl_runtime::scene::Scene;
use rtsl_runtime::texture::{
    decode_answer, Delivered, Footprint, LookupOptions, TextureAnswer, TextureCache, TexturePart, TextureSource,
};
use std::sync::{Arc, OnceLock};

/// The mesh the trees are for: a rippled grid of 12 x 12 quads.
fn mesh() -> &'static Arc<Mesh> {
    static MESH: OnceLock<Arc<Mesh>> = OnceLock::new();
    MESH.get_or_init(|| {
        let n = 12u32;
        let positions = (0..=n)
            .flat_map(|y| (0..=n).map(move |x| [x as f32, y as f32, ((x * 7 + y * 3) % 5) as f32 * 0.1].into()))
            .collect();
        let triangles = (0..n)
            .flat_map(|y| (0..n).map(move |x| y * (n + 1) + x))
            .flat_map(|k| [[k, k + 1, k + n + 1], [k + 1, k + n + 2, k + n + 1]])
            .collect();
        Arc::new(Mesh::from_triangles(positions, triangles).expect("a grid"))
    })
}

/// Traces single rays, occlusion rays and a packet through an object of `bvh`.
fn trace(bvh: ObjectBvh) {
    let mesh = mesh();
    let mut scene = Scene::new();
    let id = scene.add_object(mesh.clone());
    scene.objects_mut()[0] = Object::with_bvh(mesh.clone(), Arc::new(bvh));
    scene.add_instance(id, rtsl_runtime::glam::Affine3A::IDENTITY).expect("an instance");
    scene.commit();
    let mut packet = RayPacket::new();
    for i in 0..64 {
        let o = rtsl_runtime::glam::Vec3A::new(i as f32 * 0.19, (i * 7 % 12) as f32, 4.0);
        let ray = Ray::new(o, rtsl_runtime::glam::Vec3A::new(0.1, -0.05, -1.0));
        let _ = (scene.intersect(&ray), scene.occluded(&ray));
        packet.set(i, &ray);
    }
    let mut hits = HitPacket::default();
    scene.intersect_packet(&packet, &mut hits);
    let _ = scene.occluded_packet(&packet);
}

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

/// A master that answers a texture's first request with `first` and every level and tile of a
/// level with `level`.
#[derive(Debug)]
struct Answers {
    first: Vec<u8>,
    level: Vec<u8>,
}

impl TextureSource for Answers {
    fn fetch(&self, part: TexturePart, _name: &str) -> TextureAnswer {
        let tiled = matches!(part, TexturePart::Level { .. } | TexturePart::Tile { .. });
        let bytes = if tiled { &self.level } else { &self.first };
        decode_answer(bytes).unwrap_or_else(|reason| TextureAnswer::Whole(Delivered::Missing { path: None, reason }))
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else { return };
    match which % 6 {
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
            // the answer to every level and tile they fetch.
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
        5 => {
            // An object's tree as it comes with the mesh: whole, a small tree (its parts not
            // here: they trace as empty), or a part of the triangle count and box the input says.
            let mesh = mesh();
            let Some((&kind, rest)) = rest.split_first() else { return };
            let bvh = match kind % 3 {
                0 => decode_bvh4(rest, mesh).ok().map(|b| ObjectBvh::from_bvh4(mesh, b)),
                1 => decode_small_tree(rest, mesh).ok().map(|(small, parts)| ObjectBvh::parted(mesh, small, parts)),
                _ => {
                    let word = |k: usize| {
                        rest.get(4 * k..4 * k + 4).map_or(0, |w| u32::from_le_bytes(w.try_into().unwrap_or_default()))
                    };
                    let corner = |k: usize| {
                        let f = |k: usize| f32::from_bits(word(k));
                        rtsl_runtime::glam::Vec3A::new(f(k), f(k + 1), f(k + 2))
                    };
                    let bounds = (corner(1), corner(4));
                    let tree = rest.get(28..).unwrap_or(&[]);
                    decode_part(tree, mesh, word(0), bounds).ok().map(|b| ObjectBvh::from_bvh4(mesh, b))
                }
            };
            if let Some(bvh) = bvh {
                trace(bvh);
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

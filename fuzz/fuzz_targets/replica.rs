//! A worker's scene update (`Context::apply_update`), damaged: a valid update of a small scene
//! with the input's edits applied (each three bytes: a position and a value to XOR there; a
//! leading byte picks whole meshes, demand-loaded summaries, or summaries with the world's truly
//! displaced instances, and where to cut the update). An update is refused with an error, or
//! applied to a context (whose demand-loaded meshes come empty) that then builds a world.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::accel::object::{FetchedMesh, MeshSource};
use rtsl_runtime::api::{Context, Primitive, Replicator};
use rtsl_runtime::shading::ParamValue;
use std::sync::atomic::AtomicU32;
use std::sync::{Arc, OnceLock};

/// Delivers an empty mesh for every object (the world is built, not rendered).
#[derive(Debug, Default)]
struct Empty {
    clock: Arc<AtomicU32>,
}

impl MeshSource for Empty {
    fn fetch(&self, _key: u32) -> FetchedMesh {
        FetchedMesh::default()
    }
    fn clock(&self) -> Arc<AtomicU32> {
        self.clock.clone()
    }
}

fn scene() -> Result<Context, rtsl_runtime::api::ApiError> {
    let mut rt = Context::new();
    rt.options.width = 8;
    rt.options.height = 8;
    let surface = rt.compile_shader("fuzz", "surface fuzz(float Kd = 1) { Ci = Kd * color texture(\"t\", s, t); }")?;
    let light = rt.compile_shader("lamp", "light lamp(float intensity = 1) { solar() { Cl = intensity; } }")?;
    rt.tex_image_2d("t", 2, 2, 1, &[0.0, 1.0, 1.0, 0.0])?;
    let quad = rt.begin_object()?;
    rt.bind_shader(surface)?;
    rt.parameter("Kd", ParamValue::Float(0.5))?;
    rt.begin(Primitive::Quads)?;
    for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        rt.tex_coord(x, y);
        rt.vertex(x, y, 3.0)?;
    }
    rt.end()?;
    let bumps = rt.compile_shader("bumps", "displacement bumps() { P += 0.1 * sin(10 * s) * normalize(N); }")?;
    rt.displacement(Some(bumps), &[])?;
    rt.true_displacement(Some(true));
    rt.end_part()?;
    rt.displacement(None, &[])?;
    rt.true_displacement(None);
    rt.color(0.2, 0.4, 0.6);
    rt.begin(Primitive::Triangles)?;
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
        rt.vertex(x, y, 2.0)?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.instantiate_object(quad)?;
    rt.translate(0.5, 0.0, 0.0);
    rt.instantiate_object(quad)?;
    rt.light_source(light, &[("intensity", ParamValue::Float(2.0))])?;
    Ok(rt)
}

/// The updates of the scene with whole meshes, with summaries, and with summaries and the
/// displaced instances of the world the scene builds.
fn updates() -> &'static [Vec<u8>; 3] {
    static UPDATES: OnceLock<[Vec<u8>; 3]> = OnceLock::new();
    UPDATES.get_or_init(|| {
        let mut rt = scene().expect("the fuzz scene builds");
        let whole = Replicator::new().update(&rt, None).expect("an update");
        let summaries = Replicator::demand_loading().update(&rt, None).expect("an update");
        let world = rt.build_world().expect("the fuzz scene's world");
        assert!(world.instances.iter().any(|i| i.displaced), "the fuzz scene is displaced");
        let displaced = Replicator::demand_loading().update(&rt, Some(&world)).expect("an update");
        [whole, summaries, displaced]
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&first, edits)) = data.split_first() else { return };
    let mut bytes = updates()[usize::from(first % 3)].clone();
    for edit in edits.chunks_exact(3) {
        let at = usize::from(u16::from_le_bytes([edit[0], edit[1]])) % bytes.len();
        bytes[at] ^= edit[2];
    }
    if first & 0x80 != 0 {
        bytes.truncate(usize::from(first & 0x7e) * bytes.len() / 128);
    }
    let mut rt = Context::new();
    rt.set_mesh_source(Arc::new(Empty::default()));
    if rt.apply_update(&bytes).is_ok() {
        let _ = rt.build_world();
    }
});

//! Writes `examples/forest/forest.rib`: the mountain terrain of `../shared/scenes/mountain_terrain`
//! under several hundred instances of the oak tree (`../shared/scenes/oak_tree`, alpha-masked
//! leaves) and a few instances of the full Stanford dragon, lit by a low sun with sharp shadows.
//! Instancing at scale: two meshes of the tree and one dragon are stored once, and the
//! instances add up to more than 8 million triangles.
//!
//! Trees and dragons stand where a ray cast straight down meets the terrain, on slopes gentle
//! enough to hold them and below a tree line; positions, turns and sizes come from a fixed seed, so
//! the file is the same on every run.
//!
//! ```text
//! cargo run --release --example forest > examples/forest/forest.rib
//! rtsl render examples/forest/forest.rib -o forest.png
//! rtsl bench render examples/forest/forest.rib --threads 2
//! ```

use rtsl::runtime::glam::{Vec3, Vec3A};
use rtsl::runtime::{load_mesh, scene_from_mesh, BuildQuality, Ray};
use std::fmt::Write as _;
use std::path::Path;

/// Where the shared scenes are, relative to `examples/forest/` (the RIB's directory).
const SHARED: &str = "../../../shared/scenes";
const TREES: usize = 640;
const DRAGONS: usize = 9;
/// Trees grow below this height (the terrain spans y = 7 to 25).
const TREE_LINE: f32 = 15.0;
/// The steepest ground a tree or dragon stands on: the smallest `y` of the unit normal.
const MIN_UPNESS: f32 = 0.8;
/// The oak is about 207 units tall; a tree here is 0.9 to 1.4 units.
const OAK_SCALE: (f32, f32) = (0.0045, 0.0068);
/// The dragon is 0.145 units tall with its feet at y = 0.0527; a dragon here is about 1.8 units.
const DRAGON_SCALE: f32 = 12.0;
const DRAGON_FEET: f32 = 0.0527;

/// SplitMix64: a fixed sequence, so the scene is the same on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// RenderMan's row-major world-to-camera matrix of a camera at `eye` looking at `target`
/// (camera space: x right, y up, z forward). The meshes are right-handed (OBJ, PLY), so the
/// camera's right is `forward x up`: they are not seen mirrored.
fn look_at(eye: Vec3, target: Vec3) -> [f32; 16] {
    let f = (target - eye).normalize();
    let r = f.cross(Vec3::Y).normalize();
    let u = r.cross(f);
    [r.x, u.x, f.x, 0.0, r.y, u.y, f.y, 0.0, r.z, u.z, f.z, 0.0, -r.dot(eye), -u.dot(eye), -f.dot(eye), 1.0]
}

fn main() -> anyhow::Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let terrain_path = root.join("..").join("shared/scenes/mountain_terrain/mountain.obj");
    let terrain = load_mesh(&terrain_path)?;
    let scene = scene_from_mesh(terrain, BuildQuality::High);
    let (lo, hi) = scene.bounds().ok_or_else(|| anyhow::anyhow!("the terrain is empty"))?;
    // Where a ray straight down at (x, z) meets ground gentle and low enough to stand on.
    let ground = |x: f32, z: f32, max_height: f32| -> Option<Vec3> {
        let ray = Ray::new(Vec3A::new(x, hi.y + 1.0, z), Vec3A::NEG_Y);
        let hit = scene.intersect(&ray);
        let s = scene.surface(&hit)?;
        (s.ng.y.abs() >= MIN_UPNESS && s.p.y < max_height).then(|| s.p.into())
    };
    let mut rng = Rng(0x0A4_F0E5);
    let mut place = |count: usize, max_height: f32, spacing: f32, taken: &mut Vec<Vec3>| -> Vec<(Vec3, f32, f32)> {
        let mut out = Vec::new();
        for _ in 0..200_000 {
            if out.len() == count {
                break;
            }
            let (x, z) = (rng.range(lo.x, hi.x), rng.range(lo.z, hi.z));
            let (turn, size) = (rng.range(0.0, 360.0), rng.next());
            let Some(p) = ground(x, z, max_height) else { continue };
            if taken.iter().any(|q| (p - *q).length_squared() < spacing * spacing) {
                continue;
            }
            taken.push(p);
            out.push((p, turn, size));
        }
        out
    };
    let mut taken = Vec::new();
    let dragons = place(DRAGONS, hi.y, 3.0, &mut taken);
    let trees = place(TREES, TREE_LINE, 0.6, &mut taken);

    let mut rib = String::new();
    let (eye, target) = (Vec3::new(5.0, 21.0, 30.0), Vec3::new(0.0, 11.0, 2.0));
    let camera = look_at(eye, target).map(|v| format!("{v:.6}")).join(" ");
    let triangles = |n: usize, per: usize| n * per;
    writeln!(
        rib,
        "##RenderMan RIB
# The instanced forest, written by `cargo run --release --example forest`
# (examples/forest.rs); do not edit by hand. The mountain terrain under {} oaks (alpha-masked
# leaves through the tracer's hit test) and {} full Stanford dragons: about {:.1} M triangles after
# instancing, of which 0.9 M are stored. A low sun casts sharp shadows.
# Data: ../shared/scenes (see its README for the licences).
Display \"forest.png\" \"file\" \"rgba\"
Format 640 480 1
Projection \"perspective\" \"fov\" [45]
Transform [{camera}]
Imager \"background\" \"background\" [0.3 0.45 0.75]
# Linear colours (textures are decoded to linear) shown with a 2.2 display gamma.
Exposure 1 2.2
WorldBegin
  LightSource \"ambientlight\" 1 \"intensity\" [0.3] \"lightcolor\" [0.75 0.85 1]
  LightSource \"distantlight\" 2 \"intensity\" [1.15] \"from\" [-15 12 8] \"to\" [0 0 0] \"lightcolor\" [1 0.93 0.8]
  ObjectBegin \"oak\"
    # Bark and leaves are two objects, each with its OBJ material.
    ReadArchive \"{SHARED}/oak_tree/oak.obj\"
  ObjectEnd
  ObjectBegin \"dragon\"
    Surface \"plastic\" \"Ks\" [0.4] \"roughness\" [0.15]
    Color [0.3 0.04 0.02]
    TransformBegin
      Translate 0 {:.4} 0
      ReadArchive \"{SHARED}/stanford_dragon/dragon_vrip.ply\"
    TransformEnd
  ObjectEnd
  AttributeBegin
    Surface \"matte\"
    Color [0.2 0.26 0.09]
    ReadArchive \"{SHARED}/mountain_terrain/mountain.obj\"
  AttributeEnd",
        trees.len(),
        dragons.len(),
        (triangles(trees.len(), 555) + triangles(dragons.len(), 871_414) + 50_562) as f64 / 1e6,
        -DRAGON_FEET,
    )?;
    for (p, turn, size) in &dragons {
        let s = DRAGON_SCALE * (0.85 + 0.3 * size);
        writeln!(
            rib,
            "  AttributeBegin Translate {:.4} {:.4} {:.4} Rotate {turn:.1} 0 1 0 Scale {s:.3} {s:.3} {s:.3} ObjectInstance \"dragon\" AttributeEnd",
            p.x, p.y, p.z
        )?;
    }
    for (p, turn, size) in &trees {
        let s = OAK_SCALE.0 + (OAK_SCALE.1 - OAK_SCALE.0) * size;
        // Sunk a little, so that no root floats over a slope.
        writeln!(
            rib,
            "  AttributeBegin Translate {:.4} {:.4} {:.4} Rotate {turn:.1} 0 1 0 Scale {s:.5} {s:.5} {s:.5} ObjectInstance \"oak\" AttributeEnd",
            p.x,
            p.y - 0.05,
            p.z
        )?;
    }
    writeln!(rib, "WorldEnd")?;
    print!("{rib}");
    Ok(())
}

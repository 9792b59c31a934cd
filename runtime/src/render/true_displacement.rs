//! True displacement: displacement shaders that move their objects' geometry, as a REYES
//! renderer's do, rather than bending the shading normal (bump mapping, `shade::displace`).
//!
//! Before a frame, each instance whose material asks for it ([`Material::true_displacement`]) has
//! its mesh diced (`geometry::dice`): every triangle cut into `n * n` and every edge into `e`
//! pieces, each rate chosen so that where the camera sees the triangle (or edge) nearest, a
//! micropolygon's edges are about the square root of its `ShadingRate` in pixels, within a
//! triangle budget: near triangles finely, far ones coarsely, edges shared at one rate. A triangle
//! much nearer the camera at one end than at the other (a floor running to the horizon) is first
//! split into pieces (`dice::split_at`), each then diced at the rate its own distance asks. The displacement shader then runs once at
//! every diced point, as at a hit there (the same globals and parameters; derivatives over the
//! dicing's own spacing), and the points and normals it leaves make a new mesh, which the
//! instance is traced and shaded as: silhouettes, shadows and reflections see the displaced
//! shape, and its hits are not displaced again ([`InstanceShading::displaced`]). Where the shader
//! moves no point (it only sets `N`), the instance keeps its mesh and bump mapping. Without a
//! displacement shader, a surface shader that assigns `P` moves the points the same way, its
//! normals left as they were ([`Material::displacing_shader`]), as a REYES renderer moves the
//! micropolygons a surface shader moves.
//!
//! Invariant: shared edges are diced once (`geometry::dice`) and each diced point displaced
//! once, so a closed mesh stays closed however its shader moves it.
//!
//! The displaced meshes are kept from frame to frame ([`DisplacedMeshes`]) while the source mesh,
//! the shaders, the placement and the split stay the same and each dicing rate is within a step
//! of the ladder of the one asked ([`Key::serves`]).

use super::differential::RayDifferential;
use super::hit_geometry::UNDISPLACED_POSITIONS;
use super::jobs::JobRows;
use super::ray_budget::RayBudget;
use super::work::{Frame, Pending};
use super::world::{InstanceParts, InstanceShading, Material, World};
use crate::geometry::dice::{dice_at, diced_triangle_count_at, split_at, Diced, DicedVertex, Pieces};
use crate::geometry::{Attribute, Deformation, Mesh};
use crate::ray::{Hit, Ray, PACKET_SIZE};
use crate::scene::ObjectId;
use crate::shading::ShaderInstance;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use std::sync::Arc;

/// The most triangles one displaced object is diced into: a finer rate is lowered to fit.
pub const MAX_DICED_TRIANGLES: usize = 1 << 20;

/// The most diced triangles one world holds: objects beyond keep bump mapping, with a warning.
pub const MAX_WORLD_DICED_TRIANGLES: usize = 1 << 22;

/// The dicing rates used: a needed rate is rounded up to the next. Steps of about 1.4 keep a
/// moving camera from dicing again each frame, at less than twice the triangles needed. The
/// finest cuts one triangle into [`MAX_DICED_TRIANGLES`], so that a large polygon seen whole
/// (a wall facing the camera) is diced as finely as the budget allows.
pub const DICING_RATES: [u32; 20] = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024];

/// The displaced meshes of the last frame, and the scene objects that hold them, for the next.
#[derive(Default)]
pub struct DisplacedMeshes {
    kept: Vec<Kept>,
    /// Scene objects of displaced meshes no longer used, emptied, to be used again.
    free: Vec<ObjectId>,
}

impl DisplacedMeshes {
    /// How many displaced meshes are kept.
    pub fn len(&self) -> usize {
        self.kept.iter().filter(|k| k.displaced.is_some()).count()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The displaced meshes of the last world: each one's scene object, its mesh and how many of
    /// its triangles each source triangle was diced into (they come in source order).
    pub fn placed(&self) -> impl Iterator<Item = (ObjectId, &Arc<Mesh>, &[u32])> {
        self.kept.iter().filter_map(|k| k.displaced.as_ref().map(|m| (m.object, &m.mesh, &m.per_source[..])))
    }
}

/// One instance's displacement, as worked out for a frame.
struct Kept {
    key: Key,
    /// The displaced mesh; `None` where the shaders moved no point.
    displaced: Option<Moved>,
    triangles: usize,
}

/// A displaced mesh, the scene object that holds it, and which source triangle each of its
/// triangles comes from.
struct Moved {
    object: ObjectId,
    mesh: Arc<Mesh>,
    of_triangle: Arc<[u32]>,
    /// Per source triangle: how many triangles of `mesh` it was diced into.
    per_source: Vec<u32>,
}

impl Kept {
    /// Whether `scene` holds this displacement's mesh where it was put (a context's scene comes
    /// back frame after frame; another scene has other objects there).
    fn is_in(&self, scene: &crate::scene::Scene) -> bool {
        match &self.displaced {
            Some(m) => scene.mesh(m.object).is_some_and(|mesh| Arc::ptr_eq(mesh, &m.mesh)),
            None => true,
        }
    }
}

/// What a displaced mesh depends on.
struct Key {
    mesh: Arc<Mesh>,
    /// Per material of the instance: its displacement shader where it truly displaces, and the
    /// colour and opacity its shader sees as `Cs` and `Os`.
    shaders: Vec<(Option<Arc<ShaderInstance>>, [u32; 6])>,
    world_from_object: [u32; 12],
    rates: Rates,
}

/// The rates one instance's mesh is diced at (see [`dice_at`]).
#[derive(Clone, Debug, PartialEq)]
struct Rates {
    /// Per source triangle: the rate it is first split at ([`split_at`]), into pieces each diced
    /// at a rate of its own; empty where no triangle is split (each is diced whole).
    split: Vec<u32>,
    /// Per triangle diced: per piece where triangles are split, else per source triangle.
    triangles: Vec<u32>,
    /// Per edge of each triangle diced, in [`dice_at`]'s order (`[a-b, b-c, c-a]`).
    edges: Vec<[u32; 3]>,
}

impl Rates {
    /// Whether a dicing at these rates serves one asked at `asked`: the same split, and each
    /// rate at most one step of the ladder from the one asked.
    fn serves(&self, asked: &Rates) -> bool {
        let step = |r: u32| DICING_RATES.iter().position(|&l| l >= r).unwrap_or(DICING_RATES.len());
        let near = |(&a, &b): (&u32, &u32)| step(a).abs_diff(step(b)) <= 1;
        self.split == asked.split
            && self.triangles.len() == asked.triangles.len()
            && self.edges.len() == asked.edges.len()
            && self.triangles.iter().zip(&asked.triangles).all(near)
            && self.edges.iter().flatten().zip(asked.edges.iter().flatten()).all(near)
    }

    /// The triangles dicing at these rates makes (saturated).
    fn count(&self) -> usize {
        diced_triangle_count_at(&self.triangles).unwrap_or(usize::MAX)
    }

    /// Every dicing rate (the split kept) times `scale` (below 1), down to the ladder, never
    /// below 1: about `scale^2` as many triangles.
    fn scale(&mut self, scale: f64) {
        scale_rates(self.triangles.iter_mut(), scale);
        scale_rates(self.edges.iter_mut().flatten(), scale);
    }
}

impl Key {
    /// Whether the mesh displaced for this key serves a frame that asks for `other`: the same
    /// mesh, placement, shaders and split, each rate within one step of the ladder of the rate
    /// asked. The step either way keeps a moving camera from dicing again each frame: the
    /// distances of an object's many pieces cross some step of the ladder at almost any move.
    fn serves(&self, other: &Key) -> bool {
        let same_shader = |a: &(Option<Arc<ShaderInstance>>, [u32; 6]), b: &(Option<Arc<ShaderInstance>>, [u32; 6])| {
            a.1 == b.1
                && match (&a.0, &b.0) {
                    (Some(x), Some(y)) => Arc::ptr_eq(x, y) || same_instance(x, y),
                    (None, None) => true,
                    _ => false,
                }
        };
        Arc::ptr_eq(&self.mesh, &other.mesh)
            && self.world_from_object == other.world_from_object
            && self.rates.serves(&other.rates)
            && self.shaders.len() == other.shaders.len()
            && self.shaders.iter().zip(&other.shaders).all(|(a, b)| same_shader(a, b))
    }
}

/// Whether two shader instances are the same program with the same values in the same space:
/// a material is made again each frame for an instance with attributes of its own (RIB
/// `ObjectInstance`), with the same shaders.
fn same_instance(a: &ShaderInstance, b: &ShaderInstance) -> bool {
    let bits = |m: &glam::Affine3A| m.to_cols_array().map(f32::to_bits);
    let same_floats =
        |x: &[f32], y: &[f32]| x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits());
    Arc::ptr_eq(&a.program, &b.program)
        && bits(&a.world_from_shader) == bits(&b.world_from_shader)
        && a.params.len() == b.params.len()
        && a.params
            .iter()
            .zip(&b.params)
            .all(|(p, q)| p.index == q.index && p.string == q.string && same_floats(&p.floats, &q.floats))
}

/// Whether `material` has a shader move the geometry ([`Material::displacing_shader`]).
fn truly_displaces(material: Option<&Material>) -> bool {
    material.is_some_and(|m| m.displacing_shader().is_some())
}

/// What an instance's displacement is this frame.
enum Planned {
    /// The one kept from the last frame, at this index.
    Kept(usize),
    /// Made now.
    New(Box<Kept>),
}

/// Displaces the geometry of every instance of `world` whose material asks for it (see the
/// module's notes), after [`World::prepare`]; prepares the world again where any instance
/// changed. `kept` carries the displaced meshes from frame to frame and must go with the same
/// scene. Returns warnings (budgets exceeded, meshes that could not be diced).
pub fn displace_world(world: &mut World, kept: &mut DisplacedMeshes) -> Vec<String> {
    let mut warnings = Vec::new();
    let wanted: Vec<usize> = (0..world.instances.len())
        .filter(|&i| world.instances[i].materials().any(|m| truly_displaces(world.materials.get(m as usize))))
        .collect();
    if wanted.is_empty() && kept.kept.is_empty() {
        return warnings;
    }
    let start = std::time::Instant::now();
    let mut plans: Vec<(usize, Planned)> = Vec::new();
    let mut total = 0usize;
    let mut built = 0;
    {
        let world = &*world;
        let frame = Frame::new(world);
        // Each instance's mesh, the rate it asks for and the pieces it is split into first.
        let mut rated: Vec<(usize, Arc<Mesh>, Rates, Option<Pieces>)> = Vec::with_capacity(wanted.len());
        let mut pieces_left = MAX_WORLD_SPLIT_PIECES;
        for &i in &wanted {
            let inst = &world.instances[i];
            let id = ObjectId(inst.object);
            // A demand-loaded mesh is not fetched for this: such an object keeps bump mapping.
            if world.scene.objects().get(id.0 as usize).is_none_or(|o| o.digest().is_some()) {
                continue;
            }
            let Some(mesh) = world.scene.mesh(id).cloned() else { continue };
            if mesh.triangles.is_empty() {
                continue;
            }
            let (rates, pieces) = dicing_rates(&frame, inst, &mesh, &mut pieces_left);
            rated.push((i, mesh, rates, pieces));
        }
        if let Some(asked) = fit_world_budget(&mut rated.iter_mut().map(|r| &mut r.2).collect::<Vec<_>>()) {
            warnings.push(format!(
                "true displacement: the scene's displaced objects would make {asked} triangles, more than \
                 {MAX_WORLD_DICED_TRIANGLES}; they are diced coarser than their shading rates ask"
            ));
        }
        for (i, mesh, rates, pieces) in rated {
            let inst = &world.instances[i];
            let count = rates.count();
            let key = key_of(world, inst, mesh.clone(), rates);
            // A kept mesh may be a step finer than asked: within the world's budget still.
            let fits = |e: &Kept| total.saturating_add(e.triangles) <= MAX_WORLD_DICED_TRIANGLES;
            if let Some(k) = kept.kept.iter().position(|e| e.key.serves(&key) && fits(e) && e.is_in(&world.scene)) {
                total += kept.kept[k].triangles;
                plans.push((i, Planned::Kept(k)));
                continue;
            }
            if total.saturating_add(count) > MAX_WORLD_DICED_TRIANGLES {
                warnings.push(format!(
                    "true displacement: the scene's displaced objects would make more than {MAX_WORLD_DICED_TRIANGLES} \
                     triangles; object {} keeps bump mapping",
                    describe(world, inst)
                ));
                continue;
            }
            let diced_from = pieces.as_ref().map_or(&*mesh, |p| &p.diced.mesh);
            let diced = match dice_at(diced_from, &key.rates.triangles, &key.rates.edges) {
                Ok(d) => d,
                Err(e) => {
                    warnings.push(format!("true displacement: object {} cannot be diced: {e}", describe(world, inst)));
                    continue;
                }
            };
            let spacing = dicing_spacing(inst, diced_from, &key.rates.triangles, &diced.origins);
            let diced = match &pieces {
                Some(p) => p.compose(diced),
                None => diced,
            };
            total += count;
            let moved = displaced_mesh(&frame, (i as u32, inst), (diced, &spacing));
            built += usize::from(moved.is_some());
            // The object is found when the scene can be changed, below.
            let displaced = moved.map(|(displaced, of_triangle)| {
                let mut per_source = vec![0u32; mesh.triangles.len()];
                for &t in of_triangle.iter() {
                    if let Some(n) = per_source.get_mut(t as usize) {
                        *n += 1;
                    }
                }
                Moved { object: ObjectId(u32::MAX), mesh: displaced, of_triangle, per_source }
            });
            plans.push((i, Planned::New(Box::new(Kept { key, displaced, triangles: count }))));
        }
    }
    // The kept entries no plan takes give their objects back.
    let mut taken = vec![false; kept.kept.len()];
    for (_, p) in &plans {
        if let Planned::Kept(k) = p {
            taken[*k] = true;
        }
    }
    let old = std::mem::take(&mut kept.kept);
    let mut reused: Vec<Option<Kept>> = Vec::with_capacity(old.len());
    for (entry, taken) in old.into_iter().zip(taken) {
        if taken {
            reused.push(Some(entry));
        } else {
            let in_scene = entry.is_in(&world.scene);
            if let Some(m) = entry.displaced.filter(|_| in_scene) {
                if let Ok(empty) = Mesh::from_triangles(Vec::new(), Vec::new()) {
                    if world.scene.set_object_mesh(m.object, empty).is_ok() {
                        kept.free.push(m.object);
                    }
                }
            }
            reused.push(None);
        }
    }
    // Kept entries stay where they were in `reused` (instances placed alike share one); new
    // ones go after them.
    let mut changed = false;
    for (i, plan) in plans {
        let k = match plan {
            Planned::Kept(k) => k,
            Planned::New(mut entry) => {
                if let Some(m) = &mut entry.displaced {
                    m.object = match kept.free.pop() {
                        Some(free) if world.scene.set_object_mesh(free, m.mesh.clone()).is_ok() => free,
                        _ => world.scene.add_object(m.mesh.clone()),
                    };
                }
                reused.push(Some(*entry));
                reused.len() - 1
            }
        };
        let Some(Some(Kept { displaced: Some(m), .. })) = reused.get(k) else { continue };
        if world.scene.set_instance_object(i as u32, m.object).is_ok() {
            let inst = &mut world.instances[i];
            inst.object = m.object.0;
            inst.displaced = true;
            inst.parts = inst.parts.take().map(|parts| diced_parts(&parts, &m.of_triangle));
            changed = true;
        }
    }
    kept.kept.extend(reused.into_iter().flatten());
    if changed {
        world.prepare();
    }
    // Dicing, displacing and building the displaced objects' BVHs is the frame's geometry update.
    world.accel.objects_rebuilt += built;
    world.accel.object_bvhs += start.elapsed();
    warnings
}

/// Over the world's budget, lowers every instance's rate alike (each to the finest rate of the
/// ladder at most its rate times the same factor) so that their diced triangles fit, rather than
/// leaving the last ones bump-mapped; returns the triangles they asked for where it did.
fn fit_world_budget(rated: &mut [&mut Rates]) -> Option<usize> {
    let asked = rated.iter().map(|rates| rates.count()).fold(0usize, usize::saturating_add);
    if asked <= MAX_WORLD_DICED_TRIANGLES {
        return None;
    }
    // Triangles go with the square of the rate.
    let scale = (MAX_WORLD_DICED_TRIANGLES as f64 / asked as f64).sqrt();
    for rates in rated.iter_mut() {
        rates.scale(scale);
    }
    Some(asked)
}

/// The instance's material or object, as a warning names it.
fn describe(world: &World, inst: &InstanceShading) -> String {
    let name = world.materials.get(inst.material as usize).and_then(|m| m.identifier.clone());
    match name {
        Some(name) => format!("\"{name}\""),
        None => format!("#{}", inst.object),
    }
}

fn key_of(world: &World, inst: &InstanceShading, mesh: Arc<Mesh>, rates: Rates) -> Key {
    let shaders = inst
        .materials()
        .map(|m| {
            let material = world.materials.get(m as usize);
            let shader = material.and_then(|m| m.displacing_shader()).map(|(s, _)| s.clone());
            let [r, g, b] = material.map_or([1.0; 3], |m| m.color);
            let [x, y, z] = material.map_or([1.0; 3], |m| m.opacity);
            (shader, [r, g, b, x, y, z].map(f32::to_bits))
        })
        .collect();
    let world_from_object = inst.world_from_object.to_cols_array().map(f32::to_bits);
    Key { mesh, shaders, world_from_object, rates }
}

/// The parts of a diced mesh: each diced triangle in its source triangle's part.
fn diced_parts(parts: &InstanceParts, of_triangle: &[u32]) -> InstanceParts {
    let source = &parts.of_triangle;
    let of = of_triangle.iter().map(|&t| source.get(t as usize).copied().unwrap_or(u32::MAX)).collect();
    InstanceParts { of_triangle: of, materials: parts.materials.clone() }
}

/// The most pieces one object's triangles are split into before they are diced ([`split_at`]):
/// split rates are lowered alike to fit.
pub const MAX_SPLIT_PIECES: usize = 1 << 16;

/// The most pieces all truly displaced objects of a frame are split into: the objects past it
/// are diced whole.
pub const MAX_WORLD_SPLIT_PIECES: usize = 1 << 20;

/// The finest rate a triangle is split at before it is diced.
pub const FINEST_SPLIT: u32 = 128;

/// The first rate of the dicing ladder at least `pieces` (the finest where none is).
fn ladder(pieces: f32) -> u32 {
    let finest = DICING_RATES[DICING_RATES.len() - 1];
    match pieces.is_finite() {
        true => DICING_RATES.iter().copied().find(|&r| r as f32 >= pieces).unwrap_or(finest),
        false => finest,
    }
}

/// Every rate of `rates` times `scale` (below 1), down to the ladder, never below 1: about
/// `scale^2` as many triangles.
fn scale_rates<'r>(rates: impl Iterator<Item = &'r mut u32>, scale: f64) {
    for r in rates {
        let fits = f64::from(*r) * scale;
        *r = DICING_RATES.iter().rev().copied().find(|&r| f64::from(r) <= fits).unwrap_or(1);
    }
}

/// How the camera sees one instance's triangles, for their dicing rates.
struct Ruler {
    eye: Vec3A,
    /// The angle one pixel spans (radians, at least a tiny one).
    spread: f32,
    /// A micropolygon's edge in pixels: `sqrt(ShadingRate)`, the finest any truly displacing
    /// material of the instance asks for.
    piece: f32,
    xf: glam::Affine3A,
}

impl Ruler {
    fn of(frame: &Frame, inst: &InstanceShading) -> Ruler {
        let world = frame.world;
        let shading_rate = inst
            .materials()
            .filter_map(|m| world.materials.get(m as usize))
            .filter(|m| truly_displaces(Some(m)))
            .map(|m| m.shading_rate)
            .fold(f32::INFINITY, f32::min);
        let piece = if shading_rate.is_finite() && shading_rate > 0.0 { shading_rate.sqrt() } else { 1.0 };
        Ruler { eye: world.camera.eye(), spread: frame.pixel_spread.max(1e-9), piece, xf: inst.world_from_object }
    }

    /// How many micropolygon edges `length` makes, seen from `distance` (infinite where the eye
    /// is on it).
    fn pieces(&self, length: f32, distance: f32) -> f32 {
        length / (distance.max(1e-6) * self.spread) / self.piece
    }

    /// Triangle `tri` of `mesh` in world space.
    fn corners(&self, mesh: &Mesh, tri: &[u32; 3]) -> [Vec3A; 3] {
        tri.map(|k| {
            self.xf.transform_point3a(Vec3A::from(mesh.positions.get(k as usize).copied().unwrap_or(Vec3::ZERO)))
        })
    }

    /// Per triangle of `mesh`: the rate its pieces are diced at.
    fn rates(&self, mesh: &Mesh) -> (Vec<u32>, Vec<[u32; 3]>) {
        /// A triangle's edges as pairs of its corners, in [`dice_at`]'s order.
        const EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];
        mesh.triangles
            .par_iter()
            .map(|t| {
                let c = self.corners(mesh, t);
                let lengths = EDGES.map(|[p, q]| (c[p] - c[q]).length());
                let edges = EDGES.map(|[p, q]| distance_to_segment(self.eye, c[p], c[q]));
                let edges = [0, 1, 2].map(|k| ladder(self.pieces(lengths[k], edges[k])));
                let longest = lengths.into_iter().fold(0.0, f32::max);
                let inside = ladder(self.pieces(longest, distance_to_triangle(self.eye, c)));
                (inside.max(edges[0]).max(edges[1]).max(edges[2]), edges)
            })
            .unzip()
    }

    /// Per triangle of `mesh`: the rate it is split at before dicing, so that over each piece the
    /// distance to the eye changes by about its nearest or less, and each piece can be diced at
    /// one rate. A triangle whose far end is not much farther than its near one, or that is diced
    /// coarsely anyway, stays whole (rate 1).
    fn splits(&self, mesh: &Mesh) -> Vec<u32> {
        let mut splits: Vec<u32> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                let c = self.corners(mesh, t);
                let longest =
                    [(c[0] - c[1]), (c[1] - c[2]), (c[2] - c[0])].iter().map(|e| e.length()).fold(0.0, f32::max);
                let nearest = distance_to_triangle(self.eye, c);
                let deep = longest / nearest.max(1e-6);
                let split = deep.min(self.pieces(longest, nearest) / 4.0);
                if split >= 2.0 {
                    ladder(split).min(FINEST_SPLIT)
                } else {
                    1
                }
            })
            .collect();
        let count = diced_triangle_count_at(&splits).unwrap_or(usize::MAX);
        if count > MAX_SPLIT_PIECES {
            scale_rates(splits.iter_mut(), (MAX_SPLIT_PIECES as f64 / count as f64).sqrt());
        }
        splits
    }
}

/// The rates `mesh` (placed by `inst`) is diced at, and the pieces it is split into first where
/// some of its triangles are much nearer the camera at one end than at the other: each triangle
/// diced (each piece, where split) cut so that its longest edge, where the camera sees the
/// triangle nearest, makes pieces about `sqrt(ShadingRate)` pixels long (the finest any truly
/// displacing material of the instance asks for), and each edge likewise where the camera sees it
/// nearest (so never finer than its triangles); all lowered alike to keep the object within
/// [`MAX_DICED_TRIANGLES`].
fn dicing_rates(
    frame: &Frame,
    inst: &InstanceShading,
    mesh: &Mesh,
    pieces_left: &mut usize,
) -> (Rates, Option<Pieces>) {
    let ruler = Ruler::of(frame, inst);
    let splits = ruler.splits(mesh);
    // Past the world's pieces, an object's triangles are diced whole.
    let split_pieces = diced_triangle_count_at(&splits).unwrap_or(usize::MAX);
    let fits = split_pieces <= *pieces_left;
    if fits {
        *pieces_left -= split_pieces;
    }
    let pieces = match fits && splits.iter().any(|&k| k > 1) {
        true => {
            let edges: Vec<[u32; 3]> = splits.iter().map(|&k| [k; 3]).collect();
            split_at(mesh, &splits, &edges).ok()
        }
        false => None,
    };
    let (triangles, edges) = ruler.rates(pieces.as_ref().map_or(mesh, |p| &p.diced.mesh));
    let split = if pieces.is_some() { splits } else { Vec::new() };
    let mut rates = Rates { split, triangles, edges };
    let asked = rates.count();
    if asked > MAX_DICED_TRIANGLES {
        rates.scale((MAX_DICED_TRIANGLES as f64 / asked as f64).sqrt());
    }
    (rates, pieces)
}

/// The distance from `p` to the nearest point of segment `a`-`b`.
fn distance_to_segment(p: Vec3A, a: Vec3A, b: Vec3A) -> f32 {
    let ab = b - a;
    let along = ab.dot(p - a) / ab.length_squared();
    let t = if along.is_finite() { along.clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length()
}

/// The distance from `p` to the nearest point of triangle `[a, b, c]`: by the region of the
/// triangle's plane `p` projects into (a corner's, an edge's or the inside), as in Ericson's
/// *Real-Time Collision Detection*, 5.1.5; a triangle of no area by its edges.
fn distance_to_triangle(p: Vec3A, [a, b, c]: [Vec3A; 3]) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let (va, vb, vc) = (d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2);
    let on_edge = if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        Some(distance_to_segment(p, a, b))
    } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        Some(distance_to_segment(p, a, c))
    } else if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        Some(distance_to_segment(p, b, c))
    } else {
        None
    };
    let inside = || {
        let sum = va + vb + vc;
        let (v, w) = (vb / sum, vc / sum);
        (p - (a + ab * v + ac * w)).length()
    };
    match on_edge.unwrap_or_else(inside) {
        d if d.is_finite() => d,
        _ => distance_to_segment(p, a, b).min(distance_to_segment(p, b, c)).min(distance_to_segment(p, c, a)),
    }
}

/// Per vertex of a dicing (`origins`, on the triangles of `diced_from` diced at `rates`): the
/// spacing of the dicing there in world units, the step of the displacement shader's derivatives:
/// the longest edge of the triangle it was diced from over that triangle's rate.
fn dicing_spacing(inst: &InstanceShading, diced_from: &Mesh, rates: &[u32], origins: &[DicedVertex]) -> Vec<f32> {
    let xf = inst.world_from_object;
    let per_triangle: Vec<f32> = diced_from
        .triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let c = tri.map(|k| {
                xf.transform_point3a(Vec3A::from(diced_from.positions.get(k as usize).copied().unwrap_or(Vec3::ZERO)))
            });
            let longest = [(c[0] - c[1]), (c[1] - c[2]), (c[2] - c[0])].iter().map(|e| e.length()).fold(0.0, f32::max);
            longest / rates.get(t).copied().unwrap_or(1).max(1) as f32
        })
        .collect();
    origins.iter().map(|o| per_triangle.get(o.triangle as usize).copied().unwrap_or(0.0)).collect()
}

/// Where a displacement shader left a point and its normal (world space), if it ran there.
type DisplacedPoint = Option<(Vec3A, Vec3A)>;

/// Runs instance `index`'s displacement shaders at every point of its diced mesh: the mesh with
/// the points where they moved them and the normals they left (object space), and which source
/// triangle each triangle comes from; `None` when no point moved. A deforming mesh is displaced
/// at both ends of its deformation (the shader runs at each end's time, where the mesh stands
/// then), so that it deforms from one displaced shape to the other.
fn displaced_mesh(
    frame: &Frame,
    (index, inst): (u32, &InstanceShading),
    (diced, spacing): (Diced, &[f32]),
) -> Option<(Arc<Mesh>, Arc<[u32]>)> {
    let world = frame.world;
    let Diced { mut mesh, origins, of_triangle } = diced;
    // Points in groups of one material, a packet at most each.
    let material_of = |v: usize| inst.material_at(origins[v].triangle);
    let mut order: Vec<u32> = (0..origins.len() as u32).collect();
    if inst.parts.is_some() {
        order.sort_by_key(|&v| material_of(v as usize));
    }
    let mut groups: Vec<&[u32]> = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let m = material_of(order[start] as usize);
        let mut end = start + 1;
        while end < order.len() && end - start < PACKET_SIZE && material_of(order[end] as usize) == m {
            end += 1;
        }
        groups.push(&order[start..end]);
        start = end;
    }
    let placed = world.scene.instance_data(index);
    let at = |time: f32| placed.map_or(inst.world_from_object, |d| d.world_from_object_at(time));
    let points = DicedPoints { frame, index, origins: &origins, groups: &groups, spacing };
    let deformation = mesh.deformation.take();
    let count = mesh.positions.len();
    let own =
        |normals: Option<Vec<Vec3>>| normals.filter(|n| n.len() == count).unwrap_or_else(|| vec![Vec3::ZERO; count]);
    let mut normals = own(mesh.normals.take());
    // Where the mesh does not deform, at time 0 (a moving instance: where it stands then).
    let opening = deformation.as_ref().map_or(0.0, |d| d.open);
    // Where a surface shader moved points of a mesh that stands still, where they were: its hits
    // are shaded there (`UNDISPLACED_POSITIONS`).
    let mut undisplaced = Vec::new();
    let before = deformation.is_none().then_some(&mut undisplaced);
    let mut moved = points.displace(opening, at(opening), (&mut mesh.positions, &mut normals), before);
    fill_missing_normals(&mesh.positions, &mesh.triangles, &mut normals);
    mesh.normals = Some(normals);
    if !undisplaced.is_empty() {
        let mut data: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
        for (v, p) in undisplaced {
            if let Some(slot) = data.get_mut(3 * v as usize..3 * v as usize + 3) {
                slot.copy_from_slice(&p.to_array());
            }
        }
        mesh.attributes.push(Attribute::data(UNDISPLACED_POSITIONS, 3, data));
    }
    if let Some(d) = deformation {
        let mut positions = d.positions;
        let mut normals = own(d.normals);
        moved |= points.displace(d.close, at(d.close), (&mut positions, &mut normals), None);
        fill_missing_normals(&positions, &mesh.triangles, &mut normals);
        mesh.deformation = Some(Deformation { positions, normals: Some(normals), open: d.open, close: d.close });
    }
    if !moved {
        return None;
    }
    // What the tracer builds from must hold, as for any mesh given it.
    mesh.validate().ok()?;
    Some((Arc::new(mesh), of_triangle.into()))
}

/// The points of an instance's diced mesh, in groups for the displacement shaders.
struct DicedPoints<'a> {
    frame: &'a Frame<'a>,
    index: u32,
    origins: &'a [DicedVertex],
    groups: &'a [&'a [u32]],
    /// Per diced point: the spacing of the dicing there ([`dicing_spacing`]).
    spacing: &'a [f32],
}

impl DicedPoints<'_> {
    /// Runs the displacement shaders at every diced point as the mesh stands at `time`
    /// (`positions`, object space; `xf` its instance's transform then): moves `positions` and sets
    /// `normals` where they ran. Returns whether any point moved.
    /// With `undisplaced`, the points a surface shader moved are added to it with where they were.
    fn displace(
        &self,
        time: f32,
        xf: glam::Affine3A,
        (positions, normals): (&mut [Vec3], &mut [Vec3]),
        mut undisplaced: Option<&mut Vec<(u32, Vec3)>>,
    ) -> bool {
        let (frame, origins) = (self.frame, self.origins);
        let object_from_world = xf.inverse();
        // Normals move by the inverse transpose; back into object space by the transpose.
        let normal_to_object = xf.matrix3.transpose();
        let eye = frame.world.camera.eye();
        let positions_now: &[Vec3] = positions;
        let results: Vec<Vec<((u32, bool), DisplacedPoint)>> = self
            .groups
            .par_iter()
            .map(|group| {
                let mut jobs: Box<JobRows> = Box::default();
                jobs.clear();
                for &v in group.iter() {
                    let o = origins[v as usize];
                    let at = xf.transform_point3a(Vec3A::from(positions_now[v as usize]));
                    let to = at - eye;
                    let t = to.length();
                    let direction = if t > 0.0 && t.is_finite() { to / t } else { Vec3A::Z };
                    let width = self.spacing.get(v as usize).copied().unwrap_or(0.0);
                    let ray = Ray { origin: eye, direction, tmin: 0.0, tmax: f32::INFINITY, time };
                    let diff = RayDifferential::cone(direction, width, 0.0);
                    let hit = Hit { t, u: o.u, v: o.v, instance: self.index, primitive: o.triangle };
                    let pending = Pending { index: v as usize, start: 0.0, ray, diff, hit, budget: RayBudget::FULL };
                    jobs.push(&pending, RayBudget::FULL);
                }
                jobs.finish();
                let mut out = [None; PACKET_SIZE];
                let by_surface = super::shade::displaced_points(frame, &jobs.rows(), &mut out[..group.len()]);
                group.iter().map(|&v| (v, by_surface)).zip(out).collect()
            })
            .collect();
        let mut moved = false;
        for ((v, by_surface), shaded) in results.into_iter().flatten() {
            let Some((p, n)) = shaded else { continue };
            let (v, p, n) = (v as usize, object_from_world.transform_point3a(p), normal_to_object * n);
            // A point moved out of float range (back in object space) stays where it was.
            if !p.is_finite() {
                continue;
            }
            let (Some(at), Some(normal)) = (positions.get_mut(v), normals.get_mut(v)) else { continue };
            moved |= Vec3::from(p) != *at;
            if by_surface && Vec3::from(p) != *at {
                if let Some(undisplaced) = undisplaced.as_deref_mut() {
                    undisplaced.push((v as u32, *at));
                }
            }
            *at = p.into();
            if n.is_finite() {
                *normal = n.normalize_or_zero().into();
            }
        }
        moved
    }
}

/// Gives each vertex whose normal is zero (no shader ran there, or it left no normal) the
/// area-weighted normal of the triangles around it, the mesh standing at `positions`.
fn fill_missing_normals(positions: &[Vec3], triangles: &[[u32; 3]], normals: &mut [Vec3]) {
    if normals.iter().all(|n| *n != Vec3::ZERO) {
        return;
    }
    let mut summed = vec![Vec3::ZERO; normals.len()];
    for t in triangles {
        let [a, b, c] = t.map(|k| positions.get(k as usize).copied().unwrap_or(Vec3::ZERO));
        let n = (b - a).cross(c - a);
        for &k in t {
            if let Some(s) = summed.get_mut(k as usize) {
                *s += n;
            }
        }
    }
    for (n, s) in normals.iter_mut().zip(summed) {
        if *n == Vec3::ZERO {
            *n = s.normalize_or_zero();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distance to a triangle is the least over points spread across it, whichever region of
    /// its plane the point projects into, and a triangle of no area is measured by its edges.
    #[test]
    fn the_distance_to_a_triangle_is_to_its_nearest_point() {
        let triangles = [
            [Vec3A::ZERO, Vec3A::X, Vec3A::Y],
            [Vec3A::new(1.0, 2.0, -1.0), Vec3A::new(-3.0, 0.5, 2.0), Vec3A::new(0.5, -1.0, 4.0)],
            // No area: a segment with a corner in its middle, and a point.
            [Vec3A::ZERO, Vec3A::new(2.0, 2.0, 0.0), Vec3A::ONE],
            [Vec3A::ONE; 3],
        ];
        let points = (0..64).map(|k| {
            let k = k as f32;
            Vec3A::new((k * 1.7).sin() * 4.0, (k * 0.9).cos() * 3.0, (k * 2.3).sin() * 5.0)
        });
        for p in points {
            for [a, b, c] in triangles {
                let steps = 200;
                let sampled = (0..=steps)
                    .flat_map(|i| (0..=steps - i).map(move |j| (i as f32 / steps as f32, j as f32 / steps as f32)))
                    .map(|(u, v)| (p - (a + (b - a) * u + (c - a) * v)).length())
                    .fold(f32::INFINITY, f32::min);
                let exact = distance_to_triangle(p, [a, b, c]);
                assert!(exact <= sampled + 1e-4, "{p} to {a} {b} {c}: {exact} beyond {sampled}");
                assert!(sampled - exact <= 0.05, "{p} to {a} {b} {c}: {exact} well short of {sampled}");
            }
        }
    }

    /// A floor of two triangles with the eye just above it is split before dicing, its pieces
    /// near the eye then diced finer than those far off; seen from far away, or made of triangles
    /// small for their distance, it is diced whole.
    #[test]
    fn triangles_much_nearer_at_one_end_are_split() {
        let floor = Mesh::from_triangles(
            vec![
                Vec3::new(-100.0, 0.0, -1.0),
                Vec3::new(100.0, 0.0, -1.0),
                Vec3::new(100.0, 0.0, 200.0),
                Vec3::new(-100.0, 0.0, 200.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .expect("a floor");
        let ruler = |eye: Vec3A| Ruler { eye, spread: 0.002, piece: 1.0, xf: glam::Affine3A::IDENTITY };
        let near = ruler(Vec3A::new(0.0, 2.0, 0.0));
        let splits = near.splits(&floor);
        // The eye is above the first triangle, and 70 units from the second.
        assert!(splits[0] >= 16 && splits[0] <= FINEST_SPLIT && splits[1] > 1, "{splits:?}");
        let pieces = split_at(&floor, &splits, &splits.iter().map(|&k| [k; 3]).collect::<Vec<_>>()).expect("pieces");
        let (rates, _) = near.rates(&pieces.diced.mesh);
        // Micropolygon edges, in pixels where each piece is seen nearest: about one (the
        // `ShadingRate` of 1) near the eye and far from it, as the ladder's steps allow.
        let pixels: Vec<(f32, f32)> = (0..rates.len())
            .map(|p| {
                let c = near.corners(&pieces.diced.mesh, &pieces.diced.mesh.triangles[p]);
                let longest = [c[0] - c[1], c[1] - c[2], c[2] - c[0]].iter().map(|e| e.length()).fold(0.0, f32::max);
                let distance = distance_to_triangle(near.eye, c);
                (distance, longest / rates[p] as f32 / (distance * near.spread))
            })
            .collect();
        for (within, beyond) in [(0.0, 4.0), (150.0, f32::INFINITY)] {
            let there: Vec<f32> = pixels.iter().filter(|(d, _)| (within..beyond).contains(d)).map(|x| x.1).collect();
            assert!(!there.is_empty(), "pieces from {within} to {beyond}");
            assert!(there.iter().all(|&px| (0.5..=1.0).contains(&px)), "from {within} to {beyond}: {there:?}");
        }
        assert_eq!(ruler(Vec3A::new(0.0, 10_000.0, 0.0)).splits(&floor), [1, 1]);
        let small = Mesh::from_triangles(
            vec![Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.1, 0.0, 10.0), Vec3::new(0.0, 0.1, 10.0)],
            vec![[0, 1, 2]],
        )
        .expect("a small triangle");
        assert_eq!(near.splits(&small), [1]);
    }

    #[test]
    fn over_the_world_budget_every_rate_is_lowered_alike() {
        let uniform = |n: u32| Rates { split: Vec::new(), triangles: vec![n; 1000], edges: vec![[n; 3]; 1000] };
        let mut rated = [uniform(96), uniform(48), uniform(1)];
        let asked = fit_world_budget(&mut rated.iter_mut().collect::<Vec<_>>()).expect("over the budget");
        assert_eq!(asked, 1000 * (96 * 96 + 48 * 48 + 1));
        // Scaled by sqrt(2^22 / asked), about 0.6, down to the ladder; never below 1.
        assert_eq!(rated, [uniform(48), uniform(24), uniform(1)]);
        let total: usize = rated.iter().map(Rates::count).sum();
        assert!(total <= MAX_WORLD_DICED_TRIANGLES, "{total}");
        // Within the budget, nothing changes.
        let mut within = [uniform(48), uniform(32)];
        assert_eq!(fit_world_budget(&mut within.iter_mut().collect::<Vec<_>>()), None);
        assert_eq!(within, [uniform(48), uniform(32)]);
    }
}

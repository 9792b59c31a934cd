//! The traceable scene: retained objects (mesh + BVH) and a list of instances, with the queries the
//! renderer needs (closest hit and occlusion, for single rays and packets) and surface details of a
//! hit (geometric and shading normals, texture coordinates, attributes).
//!
//! Invariants:
//! - An object's BVH is built when its geometry is set and never otherwise.
//! - Queries see the instance list as of the last [`Scene::commit`], which rebuilds the top-level
//!   BVH; objects replaced since are seen at once (instances refer to objects by id).
//! - Normals are transformed to world space with the inverse transpose of the instance transform.
//! - Every query sees the solids ([`Scene::set_solids`], `crate::csg`) as of the last commit:
//!   a hit on a primitive solid's surface counts only where it bounds the whole solid, for closest
//!   hits and occlusion alike, before any filter of the caller's is asked.

use crate::accel::bvh4::BuildQuality;
use crate::accel::object::{MeshSource, MeshSummary, Object};
use crate::accel::store::BvhStore;
use crate::accel::top::{InstanceData, TopLevel};
use crate::accel::{packet, single};
use crate::cpu::KernelIsa;
use crate::csg::{Csg, Solid};
use crate::geometry::{AlphaMask, Mesh};
use crate::ray::{Hit, HitCandidate, HitFilter, HitPacket, Ray, RayPacket, PACKET_SIZE};
use glam::{Affine3A, Vec2, Vec3, Vec3A};
use std::sync::Arc;

/// Identifies an object of a [`Scene`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ObjectId(pub u32);

/// Identifies an instance of a [`Scene`] (its index in the instance list).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct InstanceId(pub u32);

/// Errors of scene editing.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SceneError {
    /// An object id that the scene does not have.
    #[error("no object with id {0}")]
    NoSuchObject(u32),
    /// An instance id that the scene does not have.
    #[error("no instance with id {0}")]
    NoSuchInstance(u32),
    /// A transform that cannot be inverted (or is not finite).
    #[error("instance transform is singular or not finite")]
    SingularTransform,
}

/// Surface details of a hit, in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceHit {
    /// The hit point, from the barycentrics (more precise than `origin + t * direction`).
    pub p: Vec3A,
    /// Unit geometric normal (`e1 x e2` of the triangle, transformed).
    pub ng: Vec3A,
    /// Unit shading normal: interpolated vertex normals if the mesh has them, else `ng`.
    pub n: Vec3A,
    /// Interpolated texture coordinates, if the mesh has them.
    pub uv: Option<Vec2>,
    /// Interpolated per-vertex attributes, in the mesh's attribute order.
    pub attributes: Vec<Vec<f32>>,
}

/// Objects, instances and the two-level BVH over them.
#[derive(Clone, Debug)]
pub struct Scene {
    objects: Vec<Object>,
    instances: Vec<InstanceData>,
    top: TopLevel,
    quality: BuildQuality,
    /// Where object BVHs come from when other scenes share them ([`Scene::share_bvhs`]).
    bvh_store: Option<Arc<BvhStore>>,
    /// The solids over the instance list being edited, by instance index.
    solids: Vec<Solid<u32>>,
    /// The solids as committed.
    csg: Csg,
}

impl Default for Scene {
    fn default() -> Self {
        Self::new()
    }
}

impl Scene {
    /// An empty scene; object BVHs are built at [`BuildQuality::High`].
    pub fn new() -> Self {
        Self::with_quality(BuildQuality::High)
    }

    /// An empty scene whose object BVHs are built at `quality`.
    pub fn with_quality(quality: BuildQuality) -> Self {
        Scene {
            objects: Vec::new(),
            instances: Vec::new(),
            top: TopLevel::default(),
            quality,
            bvh_store: None,
            solids: Vec::new(),
            csg: Csg::default(),
        }
    }

    /// Shares object BVHs with other scenes through `store` (`None`: builds its own): an object
    /// added or changed from now on takes the BVH of a mesh of the same geometry from it, or
    /// builds it and puts it there.
    pub fn share_bvhs(&mut self, store: Option<Arc<BvhStore>>) {
        self.bvh_store = store;
    }

    /// An object of `mesh` with its BVH, from the shared store where there is one.
    fn object_of(&self, mesh: Arc<Mesh>) -> Object {
        match &self.bvh_store {
            Some(store) => {
                let bvh = store.get_or_build(&mesh, self.quality);
                Object::with_bvh(mesh, bvh)
            }
            None => Object::new(mesh, self.quality),
        }
    }

    /// Adds an object and builds its BVH.
    pub fn add_object(&mut self, mesh: impl Into<Arc<Mesh>>) -> ObjectId {
        let id = self.objects.len() as u32;
        let object = self.object_of(mesh.into());
        self.objects.push(object);
        ObjectId(id)
    }

    /// Replaces an object's geometry and rebuilds its BVH (only this object's).
    pub fn set_object_mesh(&mut self, id: ObjectId, mesh: impl Into<Arc<Mesh>>) -> Result<(), SceneError> {
        if id.0 as usize >= self.objects.len() {
            return Err(SceneError::NoSuchObject(id.0));
        }
        let object = self.object_of(mesh.into());
        let obj = &mut self.objects[id.0 as usize];
        let alpha = obj.alpha.take();
        *obj = object;
        obj.alpha = alpha;
        Ok(())
    }

    /// Adds a demand-loaded object: `source` delivers its mesh (as `key`) when a ray first
    /// reaches its bounds; its BVH is built then.
    pub fn add_remote_object(&mut self, summary: MeshSummary, key: u32, source: Arc<dyn MeshSource>) -> ObjectId {
        let id = self.objects.len() as u32;
        self.objects.push(Object::remote(summary, key, source, self.quality));
        ObjectId(id)
    }

    /// Makes an object demand-loaded with new contents (see [`Scene::add_remote_object`]).
    pub fn set_object_remote(
        &mut self,
        id: ObjectId,
        summary: MeshSummary,
        key: u32,
        source: Arc<dyn MeshSource>,
    ) -> Result<(), SceneError> {
        let quality = self.quality;
        let obj = self.objects.get_mut(id.0 as usize).ok_or(SceneError::NoSuchObject(id.0))?;
        let alpha = obj.alpha.take();
        *obj = Object::remote(summary, key, source, quality);
        obj.alpha = alpha;
        Ok(())
    }

    /// The objects (to see which are resident, or evict them).
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    pub fn objects_mut(&mut self) -> &mut [Object] {
        &mut self.objects
    }

    /// The names and sizes of an object's per-vertex attributes (without fetching a
    /// demand-loaded one).
    pub fn attribute_names(&self, id: ObjectId) -> Vec<(String, usize)> {
        self.objects.get(id.0 as usize).map(Object::attribute_names).unwrap_or_default()
    }

    /// Gives an object cut-outs (or takes them away with `None`); no BVH is rebuilt. Every query
    /// skips hits where the mask is uncovered.
    pub fn set_object_alpha_mask(&mut self, id: ObjectId, mask: Option<Arc<AlphaMask>>) -> Result<(), SceneError> {
        let obj = self.objects.get_mut(id.0 as usize).ok_or(SceneError::NoSuchObject(id.0))?;
        obj.alpha = mask;
        Ok(())
    }

    /// The mesh of an object (fetched first, if it is demand-loaded and not here).
    pub fn mesh(&self, id: ObjectId) -> Option<&Arc<Mesh>> {
        self.objects.get(id.0 as usize).map(|o| &o.data().mesh)
    }

    /// Number of objects.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// Adds an instance of `object` placed by `world_from_object`.
    pub fn add_instance(&mut self, object: ObjectId, world_from_object: Affine3A) -> Result<InstanceId, SceneError> {
        if object.0 as usize >= self.objects.len() {
            return Err(SceneError::NoSuchObject(object.0));
        }
        check_transform(&world_from_object)?;
        self.instances.push(InstanceData::new(object.0, world_from_object));
        Ok(InstanceId(self.instances.len() as u32 - 1))
    }

    /// Adds a moving instance of `object`: placed by `open_transform` at time `open` and by
    /// `close_transform` at `close`, in between linearly interpolated (motion blur; rays carry
    /// their time).
    pub fn add_moving_instance(
        &mut self,
        object: ObjectId,
        open_transform: Affine3A,
        close_transform: Affine3A,
        (open, close): (f32, f32),
    ) -> Result<InstanceId, SceneError> {
        if object.0 as usize >= self.objects.len() {
            return Err(SceneError::NoSuchObject(object.0));
        }
        check_transform(&open_transform)?;
        check_transform(&close_transform)?;
        for s in 0..=8 {
            // Interpolated matrices can pass through singular ones (e.g. a mirror turning over).
            let t = InstanceData::moving(object.0, open_transform, close_transform, 0.0, 1.0);
            check_transform(&t.world_from_object_at(s as f32 / 8.0))?;
        }
        self.instances.push(InstanceData::moving(object.0, open_transform, close_transform, open, close));
        Ok(InstanceId(self.instances.len() as u32 - 1))
    }

    /// Moves an instance (seen by queries after the next [`Scene::commit`]).
    pub fn set_instance_transform(&mut self, id: InstanceId, world_from_object: Affine3A) -> Result<(), SceneError> {
        check_transform(&world_from_object)?;
        let inst = self.instances.get_mut(id.0 as usize).ok_or(SceneError::NoSuchInstance(id.0))?;
        *inst = InstanceData::new(inst.object, world_from_object);
        Ok(())
    }

    /// Makes instance `id` an instance of `object`, where it is (seen by queries after the next
    /// [`Scene::commit`]).
    pub fn set_instance_object(&mut self, id: u32, object: ObjectId) -> Result<(), SceneError> {
        if object.0 as usize >= self.objects.len() {
            return Err(SceneError::NoSuchObject(object.0));
        }
        let inst = self.instances.get_mut(id as usize).ok_or(SceneError::NoSuchInstance(id))?;
        inst.object = object.0;
        Ok(())
    }

    /// The tracer's data of committed instance `id`.
    pub fn instance_data(&self, id: u32) -> Option<&InstanceData> {
        self.top.instances.get(id as usize)
    }

    /// Removes every instance (objects stay), and the solids made of them.
    pub fn clear_instances(&mut self) {
        self.instances.clear();
        self.solids.clear();
    }

    /// The solids (RIB `SolidBegin`/`SolidEnd`) over the instance list, by instance index, seen by
    /// queries from the next [`Scene::commit`]. A solid that fails [`Solid::check`] is left out,
    /// and so is an instance out of range or already in another solid: they are plain surfaces.
    pub fn set_solids(&mut self, solids: Vec<Solid<u32>>) {
        self.solids = solids;
    }

    /// Number of instances in the list being edited.
    pub fn instance_count(&self) -> usize {
        self.instances.len()
    }

    /// Triangles of the committed instances, each instance counting its object's triangles (what
    /// the scene would hold without instancing).
    pub fn instanced_triangle_count(&self) -> usize {
        self.top.instances.iter().filter_map(|i| self.objects.get(i.object as usize)).map(Object::triangle_count).sum()
    }

    /// Rebuilds the top-level BVH from the instance list; call once per frame before tracing.
    pub fn commit(&mut self) {
        self.top = TopLevel::build(self.instances.clone(), &self.objects);
        self.csg = Csg::build(&self.solids, &self.top.instances, &self.objects);
    }

    /// Runs `query` with `filter` joined to the solids' test of each candidate of the ray `ray_of`
    /// gives for a lane; `filter` as it is when the scene has no solid.
    #[inline]
    fn with_solids<R>(
        &self,
        filter: HitFilter,
        ray_of: impl Fn(u32) -> Option<Ray> + Sync,
        query: impl FnOnce(HitFilter) -> R,
    ) -> R {
        if self.csg.is_empty() {
            return query(filter);
        }
        let joined = |c: &HitCandidate| {
            let solid = !self.csg.is_member(c.instance)
                || ray_of(c.lane).is_some_and(|ray| self.csg.accepts(&self.objects, &ray, c));
            solid && filter.is_none_or(|f| f(c))
        };
        query(Some(&joined))
    }

    /// Bytes of heap memory of meshes and BVHs (objects counted once however often instanced).
    pub fn memory_bytes(&self) -> usize {
        self.objects.iter().map(Object::memory_bytes).sum::<usize>()
            + self.top.bvh.memory_bytes()
            + self.top.instances.len() * size_of::<InstanceData>()
    }

    /// Closest hit along `ray`, single-ray traversal.
    pub fn intersect(&self, ray: &Ray) -> Hit {
        self.intersect_filtered(ray, None)
    }

    /// Closest hit accepted by `filter`, single-ray traversal.
    pub fn intersect_filtered(&self, ray: &Ray, filter: HitFilter) -> Hit {
        self.with_solids(filter, |_| Some(*ray), |f| single::intersect_scene(&self.top, &self.objects, ray, f, 0))
    }

    /// Whether anything lies on `ray` within `(tmin, tmax)`, single-ray traversal.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_filtered(ray, None)
    }

    /// Occlusion by hits accepted by `filter`, single-ray traversal.
    pub fn occluded_filtered(&self, ray: &Ray, filter: HitFilter) -> bool {
        self.with_solids(filter, |_| Some(*ray), |f| single::occluded_scene(&self.top, &self.objects, ray, f, 0))
    }

    /// Closest hits of the active lanes of `packet` (packet traversal); other lanes of `out` are
    /// left untouched.
    pub fn intersect_packet(&self, packet: &RayPacket, out: &mut HitPacket) {
        self.intersect_packet_filtered(packet, out, None)
    }

    /// Closest hits accepted by `filter`, packet traversal.
    pub fn intersect_packet_filtered(&self, packet: &RayPacket, out: &mut HitPacket, filter: HitFilter) {
        self.intersect_packet_on(crate::cpu::kernel_isa(), packet, out, filter)
    }

    /// [`Scene::intersect_packet_filtered`] with the packet kernels of `isa` (the built ones on a
    /// processor without it): the same hits bit for bit, at the speed of those kernels.
    pub fn intersect_packet_on(&self, isa: KernelIsa, packet: &RayPacket, out: &mut HitPacket, filter: HitFilter) {
        let lane = |i: u32| ((i as usize) < PACKET_SIZE).then(|| packet.get(i as usize));
        self.with_solids(filter, lane, |f| packet::intersect_packet_with(isa, &self.top, &self.objects, packet, out, f))
    }

    /// Occlusion of the active lanes of `packet`: the mask of lanes that hit something.
    pub fn occluded_packet(&self, packet: &RayPacket) -> u64 {
        self.occluded_packet_filtered(packet, None)
    }

    /// Occlusion by hits accepted by `filter`, packet traversal.
    pub fn occluded_packet_filtered(&self, packet: &RayPacket, filter: HitFilter) -> u64 {
        self.occluded_packet_on(crate::cpu::kernel_isa(), packet, filter)
    }

    /// [`Scene::occluded_packet_filtered`] with the packet kernels of `isa` (the built ones on a
    /// processor without it): the same answers, at the speed of those kernels.
    pub fn occluded_packet_on(&self, isa: KernelIsa, packet: &RayPacket, filter: HitFilter) -> u64 {
        let lane = |i: u32| ((i as usize) < PACKET_SIZE).then(|| packet.get(i as usize));
        self.with_solids(filter, lane, |f| packet::occluded_packet_with(isa, &self.top, &self.objects, packet, f))
    }

    /// Whether the surface of instance `instance` moves over the shutter interval: the instance
    /// moves, or its object's mesh deforms (false for ids out of range).
    pub fn instance_moves(&self, instance: u32) -> bool {
        self.top
            .instances
            .get(instance as usize)
            .is_some_and(|i| i.motion.is_some() || self.objects.get(i.object as usize).is_some_and(|o| o.deforms()))
    }

    /// The lanes of `lanes` (active in `packet`) whose ray hits triangle `primitive` of instance
    /// `instance` within its interval, on a solid part: by the traversals' own arithmetic (the
    /// ray moved into object space as they move it, the same triangle test), so that a lane this
    /// finds blocked is one they find blocked too. 0 for a moving instance, one in a solid (whose
    /// triangles block only where they bound it), or ids out of range.
    pub fn lanes_hitting_triangle(&self, packet: &RayPacket, lanes: u64, instance: u32, primitive: u32) -> u64 {
        if self.csg.is_member(instance) {
            return 0;
        }
        let Some(inst) = self.top.instances.get(instance as usize) else { return 0 };
        let Some(obj) = self.objects.get(inst.object as usize) else { return 0 };
        let mesh = &obj.data().mesh;
        if inst.motion.is_some() || mesh.deformation.is_some() || primitive as usize >= mesh.triangle_count() {
            return 0;
        }
        let [a, b, c] = mesh.corners(primitive as usize);
        let tri = crate::geometry::triangle::PreTriangle::new(a, b, c);
        let mut hit = 0;
        let mut m = lanes & packet.active;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let ray = packet.get(i);
            let (o, d) = if inst.identity {
                (ray.origin, ray.direction)
            } else {
                let xf = &inst.object_from_world;
                (xf.transform_point3a(ray.origin), xf.transform_vector3a(ray.direction))
            };
            let found =
                crate::geometry::triangle::intersect_accept(o.to_array(), d.to_array(), &tri, ray.tmin, ray.tmax);
            if found.is_some_and(|(_, u, v)| obj.solid_at(primitive, u, v)) {
                hit |= 1 << i;
            }
        }
        hit
    }

    /// The closest hit by testing every triangle (the reference for tests; slow).
    pub fn intersect_brute_force(&self, ray: &Ray, filter: HitFilter) -> Hit {
        self.with_solids(filter, |_| Some(*ray), |f| single::intersect_brute_force(&self.top, &self.objects, ray, f))
    }

    /// Occlusion by testing every triangle (the reference for tests; slow).
    pub fn occluded_brute_force(&self, ray: &Ray, filter: HitFilter) -> bool {
        self.with_solids(filter, |_| Some(*ray), |f| single::occluded_brute_force(&self.top, &self.objects, ray, f))
    }

    /// World bounds of committed instance `id` over its motion; `None` for an empty object or
    /// an unknown instance.
    pub fn instance_bounds(&self, id: u32) -> Option<(Vec3A, Vec3A)> {
        let b = self.top.instances.get(id as usize)?.world_bounds(&self.objects)?;
        Some((b.min, b.max))
    }

    /// World bounds of the committed instances, if any.
    pub fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        self.top.bvh.bounds
    }

    /// Surface details of a hit from this scene; `None` for a miss or stale ids. A moving instance
    /// is taken where it is at the shutter's opening, a deforming mesh where it is at its own
    /// opening: see [`Scene::surface_at`].
    pub fn surface(&self, hit: &Hit) -> Option<SurfaceHit> {
        let inst = self.top.instances.get(hit.instance as usize)?;
        let deformation = || self.objects.get(inst.object as usize)?.data().mesh.deformation.as_ref().map(|d| d.open);
        self.surface_at(hit, inst.motion.map(|m| m.open).or_else(deformation).unwrap_or(0.0))
    }

    /// Surface details of a hit by a ray at `time` (where a moving instance then is).
    pub fn surface_at(&self, hit: &Hit, time: f32) -> Option<SurfaceHit> {
        let inst = self.top.instances.get(hit.instance as usize)?;
        let mesh = &self.objects.get(inst.object as usize)?.data().mesh;
        let tri = *mesh.triangles.get(hit.primitive as usize)?;
        let [a, b, c] = tri.map(|i| i as usize);
        let (w0, w1, w2) = (1.0 - hit.u - hit.v, hit.u, hit.v);
        let pa = Vec3A::from(mesh.position_at(a, time));
        let pb = Vec3A::from(mesh.position_at(b, time));
        let pc = Vec3A::from(mesh.position_at(c, time));
        let p_obj = pa * w0 + pb * w1 + pc * w2;
        let xf = &inst.world_from_object_at(time);
        let normal_xf = inst.object_from_world_at(time).matrix3.transpose();
        let ng = (normal_xf * (pb - pa).cross(pc - pa)).normalize_or_zero();
        let n = match mesh.interpolate_normal_at([a, b, c], [w0, w1, w2], time) {
            Some(ni) => (normal_xf * Vec3A::from(ni)).normalize_or(ng),
            None => ng,
        };
        let uv = mesh.uvs.as_ref().map(|t| t[a] * w0 + t[b] * w1 + t[c] * w2);
        let attributes = mesh.interpolate_attributes([a, b, c], [w0, w1, w2]);
        Some(SurfaceHit { p: xf.transform_point3a(p_obj), ng, n, uv, attributes })
    }
}

fn check_transform(xf: &Affine3A) -> Result<(), SceneError> {
    let det = xf.matrix3.determinant();
    if !xf.is_finite() || det == 0.0 || !det.is_finite() || !xf.inverse().is_finite() {
        return Err(SceneError::SingularTransform);
    }
    Ok(())
}

/// A scene with a single object instanced once at the identity, committed: the common case of
/// "trace this mesh".
pub fn scene_from_mesh(mesh: Mesh, quality: BuildQuality) -> Scene {
    let mut s = Scene::with_quality(quality);
    let id = s.add_object(mesh);
    // The identity is always a valid transform and `id` was just added.
    let _ = s.add_instance(id, Affine3A::IDENTITY);
    s.commit();
    s
}

#[allow(dead_code)]
fn _assert_send_sync() {
    fn f<T: Send + Sync>() {}
    f::<Scene>();
    let _ = Vec3::ZERO;
}

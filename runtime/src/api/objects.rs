//! `Context`'s retained objects and their instances, and the primitives and meshes that build
//! them.

use super::*;

impl Context {
    /// Starts a retained object; geometry calls until `end_object` go into it.
    pub fn begin_object(&mut self) -> Result<ObjectId, ApiError> {
        self.begin_object_in(self.matrix)
    }

    /// Starts a retained object whose own space is `frame`: its geometry is placed by the current
    /// matrix relative to `frame` (with `begin_object`, `frame` is the current matrix).
    pub fn begin_object_in(&mut self, frame: Affine3A) -> Result<ObjectId, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("begin_object", "an object"));
        }
        let id = ObjectId(self.objects.len() as u32);
        self.objects.push(ObjectRecord::empty());
        self.building = Some((id, frame, MeshBuilder::default()));
        Ok(id)
    }

    /// Starts replacing the geometry of `id` (its appearance is taken from the state, as when it was
    /// built).
    pub fn redefine_object(&mut self, id: ObjectId) -> Result<(), ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("redefine_object", "an object"));
        }
        match self.objects.get(id.0 as usize) {
            Some(o) if !o.deleted => {}
            _ => return Err(ApiError::UnknownObject(id.0)),
        }
        self.building = Some((id, self.matrix, MeshBuilder::default()));
        Ok(())
    }

    /// Ends a part of the object being built: the triangles added since the object began (or since
    /// the last part) are shaded with the current appearance (colour, opacity, shaders), as
    /// [`Context::end_object`] gives a whole object its appearance; later triangles make the next
    /// part. One object of several materials is one BVH, where an object per material would make
    /// rays enter every one of them that overlaps. Without `end_part` an object has one appearance.
    /// A part without triangles is dropped. The alpha mask ([`Context::alpha_mask`]) stays the
    /// object's: the one current at `end_object`.
    pub fn end_part(&mut self) -> Result<(), ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("end_part", "begin/end"));
        }
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::Unbalanced("end_part", "begin_object"))?;
        b.close_part(&self.appearance);
        Ok(())
    }

    /// Finishes the object: its geometry, and the current appearance (colour, opacity, shader
    /// binding) as its material (that of its last part, when it was built in parts).
    pub fn end_object(&mut self) -> Result<ObjectId, ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("end_object", "begin/end"));
        }
        let (id, _, mut b) = self.building.take().ok_or(ApiError::Unbalanced("end_object", "begin_object"))?;
        if !b.parts.is_empty() {
            b.close_part(&self.appearance);
        }
        // One part is an object of one appearance.
        let parts = (b.parts.len() > 1).then(|| {
            let mut of_triangle = Vec::with_capacity(b.triangles.len());
            let mut from = 0;
            for (k, (end, _)) in b.parts.iter().enumerate() {
                of_triangle.resize(of_triangle.len() + (end - from), k as u32);
                from = *end;
            }
            ObjectParts {
                appearances: b.parts.iter().map(|(_, a)| a.clone()).collect(),
                of_triangle: of_triangle.into(),
            }
        });
        let appearance = match b.parts.as_slice() {
            [(_, only)] => only.clone(),
            _ => self.appearance.clone(),
        };
        let mesh = if b.triangles.is_empty() {
            None
        } else {
            let deformation = b.finish_deformation();
            let mesh = Mesh {
                positions: b.positions,
                normals: b.has_normals.then_some(b.normals),
                uvs: b.has_uvs.then_some(b.uvs),
                deformation,
                attributes: b.attributes,
                triangles: b.triangles,
            };
            mesh.validate()?;
            Some(Arc::new(mesh))
        };
        let version = self.next_object_version();
        let rec = &mut self.objects[id.0 as usize];
        rec.mesh = mesh;
        rec.remote = None;
        rec.appearance = appearance;
        rec.parts = parts;
        rec.dirty = true;
        rec.version = version;
        Ok(id)
    }

    /// The mesh of object `id` as it stands (`None`: deleted, empty, or demand-loaded here).
    pub fn object_mesh(&self, id: ObjectId) -> Option<&Arc<Mesh>> {
        self.objects.get(id.0 as usize)?.mesh.as_ref()
    }

    /// The 4-wide BVH `world` (built from this context) holds for object `id`, where it is built
    /// here (not a demand-loaded object still waiting for its mesh) and built from the mesh
    /// [`Context::object_mesh`] gives.
    pub fn object_bvh<'w>(
        &self,
        id: ObjectId,
        world: &'w crate::render::World,
    ) -> Option<&'w crate::accel::bvh4::Bvh4> {
        let rec = self.objects.get(id.0 as usize)?;
        let object = world.scene.objects().get(rec.scene_object?.0 as usize)?;
        let data = object.resident_data()?;
        Arc::ptr_eq(&data.mesh, rec.mesh.as_ref()?).then_some(&data.bvh.bvh)
    }

    /// Where the meshes of demand-loaded objects come from: a worker's link to its master
    /// ([`Replicator::demand_loading`]). Objects built or replaced from now on use it.
    pub fn set_mesh_source(&mut self, source: Arc<dyn MeshSource>) {
        self.mesh_source = Some(source);
    }

    /// Deletes an object and its instances.
    pub fn delete_object(&mut self, id: ObjectId) -> Result<(), ApiError> {
        let version = self.next_object_version();
        let rec = self.objects.get_mut(id.0 as usize).filter(|o| !o.deleted).ok_or(ApiError::UnknownObject(id.0))?;
        rec.deleted = true;
        rec.mesh = None;
        rec.remote = None;
        rec.dirty = true;
        rec.version = version;
        for i in &mut self.instances {
            if i.object == id {
                i.deleted = true;
            }
        }
        Ok(())
    }

    /// Places an instance of `id` with the current matrix.
    pub fn instantiate_object(&mut self, id: ObjectId) -> Result<InstanceId, ApiError> {
        self.add_instance(id, None)
    }

    /// An instance of `id` whose appearance takes the parts `inherited` names from the current
    /// state and the others from the object, as they are now: RenderMan's `ObjectInstance`, whose
    /// instances take the attributes current where they stand except those set in the object's
    /// own block ([`InheritedAppearance::ALL`]: all of them). An object built in parts keeps its
    /// parts' appearances, and every instance its object's alpha mask, which cuts the geometry
    /// the instances share.
    pub fn instantiate_object_inheriting(
        &mut self,
        id: ObjectId,
        inherited: InheritedAppearance,
    ) -> Result<InstanceId, ApiError> {
        let Some(object) = self.objects.get(id.0 as usize).filter(|o| !o.deleted) else {
            return Err(ApiError::UnknownObject(id.0));
        };
        if inherited == InheritedAppearance::NONE {
            return self.add_instance(id, None);
        }
        let (mut a, now) = (object.appearance.clone(), &self.appearance);
        let InheritedAppearance {
            color,
            opacity,
            surface,
            displacement,
            interior,
            sides,
            matte,
            shading_rate,
            attributes,
        } = inherited;
        if color {
            a.color = now.color;
        }
        if opacity {
            a.opacity = now.opacity;
        }
        if surface {
            a.surface = now.surface.clone();
        }
        if displacement {
            a.displacement = now.displacement.clone();
        }
        if interior {
            a.interior = now.interior.clone();
        }
        if sides {
            a.one_sided = now.one_sided;
        }
        if matte {
            a.matte = now.matte;
        }
        if shading_rate {
            a.shading_rate = now.shading_rate;
        }
        if attributes {
            a.true_displacement = now.true_displacement;
            a.displacement_bound = now.displacement_bound;
            a.shadow_by_shader = now.shadow_by_shader;
            a.photon = now.photon;
            a.ray_values = now.ray_values.clone();
            a.visibility = now.visibility;
            a.identifier = now.identifier.clone();
            a.trace_depths = now.trace_depths;
            a.trace_bias = now.trace_bias;
        }
        self.add_instance(id, Some(a))
    }

    fn add_instance(&mut self, id: ObjectId, appearance: Option<Appearance>) -> Result<InstanceId, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("instantiate_object", "an object"));
        }
        match self.objects.get(id.0 as usize) {
            Some(o) if !o.deleted => {}
            _ => return Err(ApiError::UnknownObject(id.0)),
        }
        // Deleted instances keep their ids: counted too.
        if self.instances.len() >= crate::accel::bvh4::MAX_PRIMITIVES {
            return Err(ApiError::TooManyInstances);
        }
        self.instances.push(InstanceRecord {
            object: id,
            transform: self.matrix,
            close_transform: self.close_matrix,
            deleted: false,
            appearance,
        });
        Ok(InstanceId(self.instances.len() as u32 - 1))
    }

    /// Moves an instance (per frame, for animation).
    pub fn set_instance_transform(&mut self, id: InstanceId, transform: Affine3A) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.transform = transform;
        rec.close_transform = None;
        Ok(())
    }

    /// Where an instance is (its world-from-object transform).
    pub fn instance_transform(&self, id: InstanceId) -> Result<Affine3A, ApiError> {
        self.instances
            .get(id.0 as usize)
            .filter(|i| !i.deleted)
            .map(|i| i.transform)
            .ok_or(ApiError::UnknownInstance(id.0))
    }

    /// The instances a world built now holds, in its order: `World::instances[k]` and a hit's
    /// `instance == k` are `world_instance_ids()[k]` (for picking).
    pub fn world_instance_ids(&self) -> Vec<InstanceId> {
        self.instances
            .iter()
            .enumerate()
            .filter(|(_, inst)| {
                let rec = &self.objects[inst.object.0 as usize];
                !inst.deleted && !rec.deleted && rec.has_geometry() && (rec.scene_object.is_some() || rec.dirty)
            })
            .map(|(i, _)| InstanceId(i as u32))
            .collect()
    }

    /// Adds a solid (RISpec's solids and spatial set operations) over instances placed before:
    /// from the next frame, rays see its boundary only, each part of it shaded as its own instance
    /// is. Each primitive's instances must close a volume, their triangles facing out of it (or
    /// into it where [`crate::csg::SolidPart::inward`] says so). An instance in an earlier solid
    /// stays there; a deleted one drops out.
    pub fn add_solid(&mut self, solid: crate::csg::Solid<InstanceId>) -> Result<(), ApiError> {
        solid.check()?;
        if let Some(bad) = solid.instances().find(|id| id.0 as usize >= self.instances.len()) {
            return Err(ApiError::UnknownInstance(bad.0));
        }
        self.solids.push(solid);
        Ok(())
    }

    /// How many instances were placed (deleted ones included): the next instance's id.
    pub fn instance_count(&self) -> usize {
        self.instances.len()
    }

    pub fn delete_instance(&mut self, id: InstanceId) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.deleted = true;
        Ok(())
    }

    fn object_from_current(&self) -> Result<Affine3A, ApiError> {
        let (_, start, _) = self.building.as_ref().ok_or(ApiError::NoObject("geometry"))?;
        Ok(start.inverse() * self.matrix)
    }

    /// Starts a primitive; vertices follow.
    pub fn begin(&mut self, kind: Primitive) -> Result<(), ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("begin", "begin/end"));
        }
        let (_, _, b) = self.building.as_ref().ok_or(ApiError::NoObject("begin"))?;
        self.primitive = Some(OpenPrimitive { kind, first_vertex: b.positions.len() as u32 });
        self.primitive_values.clear();
        Ok(())
    }

    /// The normal of the following vertices (object space of the current matrix).
    pub fn normal(&mut self, x: f32, y: f32, z: f32) {
        self.current_normal = Vec3::new(x, y, z);
        if let Some((_, _, b)) = self.building.as_mut() {
            b.has_normals = true;
        }
    }

    /// The texture coordinates (s, t) of the following vertices.
    pub fn tex_coord(&mut self, s: f32, t: f32) {
        self.current_uv = Vec2::new(s, t);
        if let Some((_, _, b)) = self.building.as_mut() {
            b.has_uvs = true;
        }
    }

    /// Adds a vertex to the open primitive.
    pub fn vertex(&mut self, x: f32, y: f32, z: f32) -> Result<(), ApiError> {
        if self.primitive.is_none() {
            return Err(ApiError::Unbalanced("vertex", "begin"));
        }
        let xf = self.object_from_current()?;
        let normal_xf = xf.matrix3.inverse().transpose();
        let p = xf.transform_point3(Vec3::new(x, y, z));
        let n = Vec3::from(normal_xf * Vec3A::from(self.current_normal));
        let uv = self.current_uv;
        let values = self.vertex_values.iter().chain(self.primitive_values.iter());
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("vertex"))?;
        let index = b.positions.len();
        b.positions.push(p);
        b.normals.push(n);
        b.uvs.push(uv);
        for (name, v) in values {
            let pos = match b.attributes.iter().position(|a| &a.name == name) {
                Some(i) => i,
                None => {
                    b.attributes.push(Attribute::data(name.clone(), v.len(), vec![0.0; index * v.len()]));
                    b.attributes.len() - 1
                }
            };
            let a = &mut b.attributes[pos];
            if a.components == v.len() {
                a.data.truncate(index * a.components);
                a.data.resize(index * a.components, 0.0);
                a.data.extend_from_slice(v);
            }
        }
        for a in &mut b.attributes {
            a.data.resize((index + 1) * a.components, 0.0);
        }
        Ok(())
    }

    /// Ends the open primitive, triangulating it.
    pub fn end(&mut self) -> Result<(), ApiError> {
        let prim = self.primitive.take().ok_or(ApiError::Unbalanced("end", "begin"))?;
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("end"))?;
        let first = prim.first_vertex;
        let n = b.positions.len() as u32 - first;
        let v = |i: u32| first + i;
        match prim.kind {
            Primitive::Triangles => {
                if n % 3 != 0 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "triangles"));
                }
                for t in 0..n / 3 {
                    b.triangles.push([v(3 * t), v(3 * t + 1), v(3 * t + 2)]);
                }
            }
            Primitive::Quads => {
                if n % 4 != 0 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "quads"));
                }
                for q in 0..n / 4 {
                    b.triangles.push([v(4 * q), v(4 * q + 1), v(4 * q + 2)]);
                    b.triangles.push([v(4 * q), v(4 * q + 2), v(4 * q + 3)]);
                }
            }
            Primitive::Polygon => {
                if n < 3 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "a polygon"));
                }
                let poly: Vec<u32> = (0..n).map(v).collect();
                crate::geometry::mesh::triangulate_into(b.triangles.len(), &poly, &mut b.triangles)?;
            }
            Primitive::TriangleStrip => {
                for i in 2..n {
                    if i % 2 == 0 {
                        b.triangles.push([v(i - 2), v(i - 1), v(i)]);
                    } else {
                        b.triangles.push([v(i - 1), v(i - 2), v(i)]);
                    }
                }
            }
            Primitive::TriangleFan => {
                for i in 2..n {
                    b.triangles.push([v(0), v(i - 1), v(i)]);
                }
            }
        }
        Ok(())
    }

    /// Adds a whole mesh to the object being built (placed by the current matrix relative to the
    /// object's).
    pub fn mesh(&mut self, mesh: &Mesh) -> Result<(), ApiError> {
        // The open primitive counts its vertices from where it began; a mesh in between would
        // become part of it.
        if self.primitive.is_some() {
            return Err(ApiError::Nested("mesh", "begin/end"));
        }
        let xf = self.object_from_current()?;
        let normal_xf = xf.matrix3.inverse().transpose();
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("mesh"))?;
        if let Some(d) = &mesh.deformation {
            // Checked before anything is added: a mesh refused leaves the object as it was.
            mesh.validate()?;
            let close = b.deform(d.open, d.close)?;
            close.positions.extend(d.positions.iter().map(|p| xf.transform_point3(*p)));
            let normals = d.normals.as_ref().or(mesh.normals.as_ref());
            let close_normals = close.normals.get_or_insert_with(Vec::new);
            match normals {
                Some(ns) => close_normals.extend(ns.iter().map(|n| Vec3::from(normal_xf * Vec3A::from(*n)))),
                None => close_normals.extend(std::iter::repeat_n(Vec3::ZERO, mesh.positions.len())),
            }
        }
        let base = b.positions.len() as u32;
        let count = mesh.positions.len();
        b.positions.extend(mesh.positions.iter().map(|p| xf.transform_point3(*p)));
        match &mesh.normals {
            Some(ns) => {
                b.has_normals = true;
                b.normals.extend(ns.iter().map(|n| Vec3::from(normal_xf * Vec3A::from(*n))));
            }
            None => b.normals.extend(std::iter::repeat_n(Vec3::ZERO, count)),
        }
        match &mesh.uvs {
            Some(uvs) => {
                b.has_uvs = true;
                b.uvs.extend_from_slice(uvs);
            }
            None => b.uvs.extend(std::iter::repeat_n(Vec2::ZERO, count)),
        }
        for a in &mesh.attributes {
            let same = |x: &Attribute| x.name == a.name && x.components == a.components && x.kind == a.kind;
            let pos = match b.attributes.iter().position(same) {
                Some(i) => i,
                None => {
                    let data = vec![0.0; base as usize * a.components];
                    b.attributes.push(Attribute { name: a.name.clone(), components: a.components, data, kind: a.kind });
                    b.attributes.len() - 1
                }
            };
            let at = b.attributes[pos].data.len();
            b.attributes[pos].data.extend_from_slice(&a.data);
            a.kind.transform(&mut b.attributes[pos].data[at..], &xf, &normal_xf);
        }
        let total = b.positions.len();
        for x in &mut b.attributes {
            x.data.resize(total * x.components, 0.0);
        }
        b.triangles.extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
        Ok(())
    }

    /// Adds a RenderMan quadric (RISpec's `Sphere`, `Cylinder`, `Cone`, `Disk`, `Paraboloid`,
    /// `Hyperboloid`, `Torus`: swept about the z axis, angles in degrees) to the object being built,
    /// placed by the current matrix as [`Context::mesh`] places a mesh. It is tessellated as the RIB
    /// reader tessellates it: [`Quadric::default_tessellation`], normals of the analytic surface,
    /// and the surface parameters `(u, v)` as texture coordinates.
    pub fn quadric(&mut self, quadric: &Quadric) -> Result<(), ApiError> {
        self.quadric_tessellated(quadric, quadric.default_tessellation())
    }

    /// [`Context::quadric`] with a tessellation of the caller's choosing.
    pub fn quadric_tessellated(&mut self, quadric: &Quadric, tessellation: Tessellation) -> Result<(), ApiError> {
        // Misuse is reported before a fine tessellation is paid for.
        self.object_from_current()?;
        if self.primitive.is_some() {
            return Err(ApiError::Nested("quadric", "begin/end"));
        }
        self.mesh(&quadric.tessellate(tessellation)?)
    }

    /// A whole sphere of `radius` about the origin (RIB `Sphere radius -radius radius 360`).
    pub fn sphere(&mut self, radius: f32) -> Result<(), ApiError> {
        self.quadric(&Quadric::Sphere { radius, zmin: -radius, zmax: radius, thetamax: 360.0 })
    }

    /// An open cylinder about the z axis from `zmin` to `zmax` (RIB `Cylinder radius zmin zmax 360`).
    pub fn cylinder(&mut self, radius: f32, zmin: f32, zmax: f32) -> Result<(), ApiError> {
        self.quadric(&Quadric::Cylinder { radius, zmin, zmax, thetamax: 360.0 })
    }

    /// A cone with its base of `radius` at z = 0 and its apex at z = `height` (RIB `Cone height
    /// radius 360`), without a base: close it with [`Context::disk`].
    pub fn cone(&mut self, height: f32, radius: f32) -> Result<(), ApiError> {
        self.quadric(&Quadric::Cone { height, radius, thetamax: 360.0 })
    }

    /// A disk of `radius` in the plane z = `height`, facing +z (RIB `Disk height radius 360`).
    pub fn disk(&mut self, height: f32, radius: f32) -> Result<(), ApiError> {
        self.quadric(&Quadric::Disk { height, radius, thetamax: 360.0 })
    }

    /// A whole torus about the z axis (RIB `Torus major minor 0 360 360`).
    pub fn torus(&mut self, major_radius: f32, minor_radius: f32) -> Result<(), ApiError> {
        self.quadric(&Quadric::Torus { major_radius, minor_radius, phimin: 0.0, phimax: 360.0, thetamax: 360.0 })
    }

    /// A closed axis-aligned box between corners `a` and `b` (in the current space, placed by the
    /// current matrix), with flat outward normals and each face's uvs over (0, 0) to (1, 1):
    /// [`Mesh::cuboid`].
    pub fn box_mesh(&mut self, a: impl Into<Vec3>, b: impl Into<Vec3>) -> Result<(), ApiError> {
        let mesh = Mesh::cuboid(a.into(), b.into());
        // Not-finite corners would otherwise only be refused at `end_object`, far from the call.
        mesh.validate()?;
        self.mesh(&mesh)
    }
}

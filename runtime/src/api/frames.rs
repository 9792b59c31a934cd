//! `Context`'s frames: the world built from the state as it stands (objects' BVHs rebuilt only
//! where their geometry changed, materials reused while unchanged), and rendering it.

use super::*;

impl Context {
    /// A binding's instance; values the (possibly reloaded) program no longer takes are left out and
    /// reported.
    fn instance_for(&self, binding: &Binding, warnings: &mut Vec<String>) -> Result<ShaderInstance, ApiError> {
        let program = self.program(binding.shader)?.clone();
        let mut inst = ShaderInstance::new(program, binding.world_from_shader);
        for (name, value, m) in &binding.params {
            if let Err(e) = inst.set(name, value, m) {
                let w = format!("{e}; the value is not used");
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
        }
        Ok(inst)
    }

    /// Builds the world as it stands (resolving shader and object references now) and renders it.
    pub fn render_frame(&mut self) -> Result<(Framebuffer, FrameReport), ApiError> {
        let world = self.build_world()?;
        let out = render_frame(&world, None);
        self.scene = Some(world.scene);
        Ok(out)
    }

    /// Builds the world as it stands, for rendering with options (progress, threads) of the caller's
    /// choosing. Give the scene back with [`Context::return_scene`] to keep object BVHs for the next
    /// frame.
    pub fn build_world(&mut self) -> Result<World, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("render_frame", "an object"));
        }
        // Refused here, before the scene is built, rather than when the framebuffer is allocated.
        crate::render::check_image_size(u64::from(self.options.width), u64::from(self.options.height))
            .map_err(ApiError::ImageSize)?;
        let mut scene = self.scene.take().unwrap_or_default();
        scene.share_bvhs(self.bvh_store.clone());
        // Objects: (re)build only the BVHs of changed geometry.
        let bvh_start = std::time::Instant::now();
        let mut objects_rebuilt = 0;
        let mut masks: HashMap<(String, u32), Option<Arc<AlphaMask>>> = HashMap::new();
        for (index, rec) in self.objects.iter_mut().enumerate() {
            if !rec.dirty {
                continue;
            }
            rec.dirty = false;
            objects_rebuilt += 1;
            let remote = match (&rec.remote, &self.mesh_source) {
                (Some(summary), Some(source)) => Some((summary.clone(), source.clone())),
                (Some(_), None) => return Err(ApiError::NoMeshSource(index as u32)),
                (None, _) => None,
            };
            match (&rec.mesh, remote, rec.scene_object) {
                (Some(mesh), _, Some(id)) => scene.set_object_mesh(id, mesh.clone())?,
                (Some(mesh), _, None) => rec.scene_object = Some(scene.add_object(mesh.clone())),
                (None, Some((summary, source)), Some(id)) => {
                    scene.set_object_remote(id, summary, index as u32, source)?
                }
                (None, Some((summary, source)), None) => {
                    rec.scene_object = Some(scene.add_remote_object(summary, index as u32, source))
                }
                (None, None, Some(id)) => {
                    // An emptied or deleted object keeps its slot with no triangles.
                    let empty = Mesh::from_triangles(Vec::new(), Vec::new())?;
                    scene.set_object_mesh(id, empty)?;
                }
                (None, None, None) => {}
            }
            if let Some(id) = rec.scene_object {
                let mask = rec.appearance.alpha_mask.as_ref().and_then(|(name, cutoff)| {
                    let textures = &self.textures;
                    let warnings = &mut self.warnings;
                    masks
                        .entry((name.clone(), cutoff.to_bits()))
                        .or_insert_with(|| match textures.get_texture(name, false) {
                            Some(mip) => AlphaMask::from_image(mip.level(0), *cutoff).map(Arc::new),
                            None => {
                                warnings.push(format!("alpha mask \"{name}\": texture not found; the object is solid"));
                                None
                            }
                        })
                        .clone()
                });
                scene.set_object_alpha_mask(id, mask)?;
            }
        }
        let object_bvhs = bvh_start.elapsed();
        let mut warnings = Vec::new();
        let mut materials = vec![Material::DEFAULT];
        let mut object_material = vec![0u32; self.objects.len()];
        let mut object_parts: Vec<Option<InstanceParts>> = vec![None; self.objects.len()];
        let mut built = std::mem::take(&mut self.built_materials);
        built.resize_with(self.objects.len(), || None);
        for (i, rec) in self.objects.iter().enumerate() {
            if rec.deleted || !rec.has_geometry() {
                continue;
            }
            let appearances = match &rec.parts {
                Some(parts) => &parts.appearances[..],
                None => std::slice::from_ref(&rec.appearance),
            };
            let first = materials.len() as u32;
            let bindings = || appearances.iter().flat_map(|a| [&a.surface, &a.interior, &a.displacement]).flatten();
            // The same version has the same appearances, which name the same shaders, so the
            // programs line up one for one.
            let reusable = built[i].as_ref().is_some_and(|b| {
                debug_assert!(b.version != rec.version || b.appearances == appearances, "object {i} changed");
                b.version == rec.version
                    && b.programs
                        .iter()
                        .zip(bindings())
                        .all(|(was, binding)| self.program(binding.shader).is_ok_and(|is| Arc::ptr_eq(was, is)))
            });
            if !reusable {
                let programs = bindings().map(|b| self.program(b.shader).cloned()).collect::<Result<Vec<_>, _>>()?;
                let mut object_warnings = Vec::new();
                let built_now = appearances
                    .iter()
                    .map(|a| self.material_of(a, i as u32 + 1, &mut object_warnings))
                    .collect::<Result<Vec<_>, _>>()?;
                built[i] = Some(BuiltMaterials {
                    version: rec.version,
                    appearances: appearances.to_vec(),
                    programs,
                    materials: built_now,
                    warnings: object_warnings,
                });
            }
            if let Some(b) = &built[i] {
                materials.extend(b.materials.iter().cloned());
                for w in &b.warnings {
                    if !warnings.contains(w) {
                        warnings.push(w.clone());
                    }
                }
            }
            object_material[i] = first;
            if let Some(parts) = &rec.parts {
                let ids: Vec<u32> = (first..materials.len() as u32).collect();
                object_parts[i] = Some(InstanceParts { of_triangle: parts.of_triangle.clone(), materials: ids.into() });
            }
        }
        self.built_materials = built;
        scene.clear_instances();
        let mut instances = Vec::new();
        // Each context instance's index in the world's list, for the solids.
        let mut in_world = vec![None; self.instances.len()];
        // Instances shaded with appearances of their own: one material for each object and
        // appearance (a material carries its object's id), found by the appearance's encoding
        // (appearances hold floats, so they cannot be hashed as they are).
        let mut own_materials: HashMap<(ObjectId, Vec<u8>), u32> = HashMap::new();
        // Instances placed one after another under one set of attributes are common: the last
        // appearance is compared before any is encoded.
        let mut last_own: Option<(ObjectId, &Appearance, u32)> = None;
        for (index, inst) in self.instances.iter().enumerate() {
            let rec = &self.objects[inst.object.0 as usize];
            let (Some(obj), false) = (rec.scene_object, inst.deleted || rec.deleted || !rec.has_geometry()) else {
                continue;
            };
            let (open, close) = self.options.shutter;
            match inst.close_transform {
                Some(end) if close > open => scene.add_moving_instance(obj, inst.transform, end, (open, close))?,
                _ => scene.add_instance(obj, inst.transform)?,
            };
            in_world[index] = Some(instances.len() as u32);
            let parts = object_parts[inst.object.0 as usize].clone();
            let material = match (&inst.appearance, &parts) {
                (Some(own), None) => match last_own.filter(|&(object, last, _)| object == inst.object && last == own) {
                    Some((_, _, m)) => m,
                    None => {
                        let key = (inst.object, postcard::to_stdvec(own).unwrap_or_default());
                        let m = match own_materials.get(&key) {
                            Some(&m) => m,
                            None => {
                                materials.push(self.material_of(own, inst.object.0 + 1, &mut warnings)?);
                                let m = materials.len() as u32 - 1;
                                own_materials.insert(key, m);
                                m
                            }
                        };
                        last_own = Some((inst.object, own, m));
                        m
                    }
                },
                _ => object_material[inst.object.0 as usize],
            };
            let world_from_object = inst.transform;
            instances.push(InstanceShading { material, object: obj.0, world_from_object, parts, displaced: false });
        }
        scene.set_solids(
            self.solids.iter().map(|s| s.filter_map(|id| in_world.get(id.0 as usize).copied().flatten())).collect(),
        );
        let mut lights = Vec::new();
        for l in self.lights.iter().filter(|l| l.on) {
            let program = self.program(l.shader)?.clone();
            let binding =
                Binding { shader: l.shader, params: l.params.clone(), world_from_shader: l.world_from_shader };
            let inst = self.instance_for(&binding, &mut warnings)?;
            let categories = inst
                .string_param("__category")
                .map(|c| c.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect())
                .unwrap_or_default();
            let area = (!l.area_triangles.is_empty()).then(|| AreaLight::new(l.area_triangles.clone(), l.area_samples));
            let kind = if area.is_some() { LightKind::Local } else { program.light_kind };
            lights.push(LightSource { shader: Arc::new(inst), kind, shadows: l.shadows, categories, area });
        }
        let mut world = World::new(scene);
        world.accel.objects_rebuilt = objects_rebuilt;
        world.accel.object_bvhs = object_bvhs;
        world.materials = materials;
        world.instances = instances;
        world.lights = lights;
        world.pixel = self.pixel.as_ref().map(|b| self.instance_for(b, &mut warnings)).transpose()?.map(Arc::new);
        world.atmosphere =
            self.atmosphere.as_ref().map(|b| self.instance_for(b, &mut warnings)).transpose()?.map(Arc::new);
        world.camera = self.camera;
        world.camera_shader = match &self.camera_shader {
            Some(b) => {
                let mut inst = self.instance_for(b, &mut warnings)?;
                inst.world_from_shader = self.camera.world_from_camera;
                Some(Arc::new(inst))
            }
            None => None,
        };
        world.options = self.options.clone();
        world.ray_parameter_misses = self.ray_parameter_misses.clone();
        world.spaces = self.spaces.clone();
        world.textures = self.textures.clone();
        world.prepare();
        warnings.extend(crate::render::true_displacement::displace_world(&mut world, &mut self.displaced));
        if let (false, Some(source)) = (self.remote_displaced.is_empty(), &self.mesh_source) {
            crate::render::remote_displacement::place_remote(&mut world, &mut self.remote_displaced, source)
                .map_err(ApiError::RemoteDisplacement)?;
        }
        for w in warnings {
            if !self.warnings.contains(&w) {
                self.warnings.push(w);
            }
        }
        Ok(world)
    }

    /// The material of an appearance, for an object with id `object_id` (1-based).
    fn material_of(&self, a: &Appearance, object_id: u32, warnings: &mut Vec<String>) -> Result<Material, ApiError> {
        let mut shader = |b: &Option<Binding>| -> Result<_, ApiError> {
            Ok(b.as_ref().map(|b| self.instance_for(b, warnings)).transpose()?.map(Arc::new))
        };
        Ok(Material {
            surface: shader(&a.surface)?,
            interior: shader(&a.interior)?,
            displacement: shader(&a.displacement)?,
            true_displacement: a.true_displacement.unwrap_or(a.displacement_bound > 0.0),
            shading_rate: a.shading_rate,
            color: a.color,
            opacity: a.opacity,
            photon: a.photon,
            shadow_by_shader: a.shadow_by_shader,
            one_sided: a.one_sided,
            visibility: a.visibility,
            matte: a.matte,
            identifier: a.identifier.as_deref().map(Arc::from),
            trace_depths: a.trace_depths,
            trace_bias: a.trace_bias,
            object_id,
            native: None,
            ray_values: a.ray_values.clone(),
        })
    }

    /// Takes back the scene of a world made by [`Context::build_world`], so the next frame reuses its
    /// object BVHs.
    pub fn return_scene(&mut self, world: World) {
        self.scene = Some(world.scene);
    }
}

//! `Context`'s shaders: search paths, compiling and loading, replacing (hot reload), binding
//! surface, light, pixel, camera, atmosphere, displacement and interior shaders with their values.

use super::*;

impl Context {
    /// Directories searched (in order, before the standard library) by [`Context::find_shader`].
    pub fn set_shader_search_path<P: AsRef<Path>>(&mut self, dirs: impl IntoIterator<Item = P>) {
        self.shader_search_path = dirs.into_iter().map(|d| d.as_ref().to_path_buf()).collect();
    }

    pub fn shader_search_path(&self) -> &[PathBuf] {
        &self.shader_search_path
    }

    /// Adds a directory where textures named by relative paths are looked for.
    pub fn add_texture_search_path(&mut self, dir: impl AsRef<Path>) {
        let dir = dir.as_ref().to_path_buf();
        if !self.texture_search_path.contains(&dir) {
            self.texture_search_path.push(dir);
            self.renew_texture_cache();
        }
    }

    /// Makes `name` a texture from memory (OpenGL's `glTexImage2D`): `width x height` texels of
    /// `channels` linear floats each, rows top to bottom. Shaders look it up by that name, before
    /// any file of the same name; it repeats (periodic wrap).
    pub fn tex_image_2d(
        &mut self,
        name: &str,
        width: usize,
        height: usize,
        channels: usize,
        texels: &[f32],
    ) -> Result<(), ApiError> {
        let image = TexImage::new(width, height, channels, texels.to_vec()).ok_or(ApiError::BadTexture {
            name: name.to_string(),
            width,
            height,
            channels,
            given: texels.len(),
        })?;
        self.textures.insert_texture(name, image.clone(), [Wrap::Periodic; 2]);
        self.memory_textures.retain(|(n, _)| n != name);
        self.memory_textures.push((name.to_string(), image));
        self.memory_changes += 1;
        Ok(())
    }

    /// Makes `name` a texture decoded from a texture file's bytes held in memory (PNG, JPEG, TGA
    /// or PPM, 8-bit colour taken as sRGB like a file's): an application's embedded assets. Shaders
    /// look it up by that name before any file of the same name; it repeats (periodic wrap).
    pub fn texture_file_in_memory(&mut self, name: &str, bytes: &[u8]) -> Result<(), ApiError> {
        let loaded = crate::texture::image::decode_texture_image(Path::new(name), bytes, false)
            .map_err(|e| ApiError::BadTextureFile { name: name.to_string(), message: e.to_string() })?;
        self.textures.insert_texture(name, loaded.image.clone(), [Wrap::Periodic; 2]);
        self.memory_textures.retain(|(n, _)| n != name);
        self.memory_textures.push((name.to_string(), loaded.image));
        self.memory_changes += 1;
        Ok(())
    }

    /// Makes `name` a 3-D grid for `texture3d` parsed from a grid file's bytes held in memory (the
    /// RTSLGRID format of `docs/volumes.md`), looked up before any file of the same name.
    pub fn grid_file_in_memory(&mut self, name: &str, bytes: &[u8]) -> Result<(), ApiError> {
        let grid = crate::texture::grid::Grid::parse(bytes)
            .map_err(|message| ApiError::BadTextureFile { name: name.to_string(), message })?;
        self.textures.insert_grid(name, grid.clone());
        self.memory_grids.retain(|(n, _)| n != name);
        self.memory_grids.push((name.to_string(), grid));
        self.memory_changes += 1;
        Ok(())
    }

    /// Where textures, shadow maps and grids come from instead of files: a worker's link to its
    /// master ([`Replicator::demand_loading`]). Its cache starts afresh.
    pub fn set_texture_source(&mut self, source: Arc<dyn crate::texture::TextureSource>) {
        self.texture_source = Some(source);
        self.renew_texture_cache();
    }

    /// Forgets every texture, shadow map and grid read from a file, so that the next frame reads
    /// them again (after the files changed), here and on the replicas the next update reaches.
    /// What was given in memory stays.
    pub fn reload_textures(&mut self) {
        self.renew_texture_cache();
        // Replicas renew their caches when this count moves (`Replicator::update`).
        self.memory_changes += 1;
    }

    /// Starts an empty texture cache over the search path (and source), holding the textures and
    /// grids given in memory.
    pub(super) fn renew_texture_cache(&mut self) {
        let cache = TextureCache::with_search_paths(self.texture_search_path.clone())
            .with_source(self.texture_source.clone())
            .with_shared(self.shared_files.clone());
        self.textures = Arc::new(cache);
        self.insert_memory_textures();
    }

    /// Shares the texture files this context's textures decode with other contexts (the frames
    /// of a render): a file one decoded is taken as it is by the others while it is unchanged
    /// ([`crate::shared_files::SharedFiles`]). Its cache starts afresh.
    pub fn share_files(&mut self, shared: Arc<crate::shared_files::SharedFiles>) {
        self.shared_files = Some(shared);
        self.renew_texture_cache();
    }

    /// Shares object BVHs with other contexts (the frames of a render): an object whose geometry
    /// is bit for bit that of an object another context built takes its BVH rather than building
    /// one ([`crate::accel::store::BvhStore`]). Objects built already keep theirs.
    pub fn share_bvhs(&mut self, store: Arc<crate::accel::store::BvhStore>) {
        if let Some(scene) = self.scene.as_mut() {
            scene.share_bvhs(Some(store.clone()));
        }
        self.bvh_store = Some(store);
    }

    /// What this context shares what it makes of files with ([`Context::share_files`]).
    pub(crate) fn shared_files(&self) -> Option<&Arc<crate::shared_files::SharedFiles>> {
        self.shared_files.as_ref()
    }

    /// Says that the file at `path` is being written (`MakeShadow`, `MakeTexture`): what the
    /// contexts sharing textures with this one decoded of it is forgotten.
    pub fn file_written(&self, path: &Path) {
        if let Some(shared) = &self.shared_files {
            shared.forget(path);
        }
    }

    /// The texture cache frames use (textures load once and stay loaded across frames).
    pub fn textures(&self) -> &Arc<TextureCache> {
        &self.textures
    }

    /// Directories searched by `#include`.
    pub fn set_include_paths<P: AsRef<Path>>(&mut self, dirs: impl IntoIterator<Item = P>) {
        self.include_paths = dirs.into_iter().map(|d| d.as_ref().to_path_buf()).collect();
    }

    /// Where shader `name` would be loaded from: `NAME.rtso` or `NAME.sl` in the search path, then
    /// in the library directory `RTSL_STDLIB` names, then the library embedded in the binary
    /// ([`locate_shader`]).
    pub fn which_shader(&self, name: &str) -> Option<ShaderLocation> {
        locate_shader(name, &self.shader_search_path)
    }

    /// Compiles the shader file at `path`.
    pub fn shader_file(&mut self, path: impl AsRef<Path>) -> Result<ShaderId, ApiError> {
        let program = ShaderProgram::from_file(path.as_ref(), &self.include_paths)?;
        Ok(self.add_program(program))
    }

    /// Compiles shader source given as a string (`name` names it in diagnostics).
    pub fn compile_shader(&mut self, name: &str, source: &str) -> Result<ShaderId, ApiError> {
        let program = ShaderProgram::from_source(name, source, &self.include_paths)?;
        Ok(self.add_program(program))
    }

    /// Finds shader `name` on the search path (see [`Context::which_shader`]) and compiles it, once:
    /// later calls with the same name return the same id.
    pub fn find_shader(&mut self, name: &str) -> Result<ShaderId, ApiError> {
        if let Some(i) = self.programs.iter().position(|p| p.as_ref().is_some_and(|p| p.name == name)) {
            return Ok(ShaderId(i as u32));
        }
        let location = self.which_shader(name).ok_or_else(|| ShaderError::NotFound { name: name.to_string() })?;
        let cache = self.shader_cache.clone();
        if let Some(program) = cache.as_ref().and_then(|c| c.get(&location, &self.include_paths)) {
            self.programs.push(Some(program));
            return Ok(ShaderId(self.programs.len() as u32 - 1));
        }
        let id = match &location {
            ShaderLocation::File(path) => self.shader_file(path)?,
            ShaderLocation::Library(shader) => {
                let program = ShaderProgram::from_source(&shader.label(), shader.source, &self.include_paths)?;
                self.add_program(program)
            }
        };
        if let (Some(cache), Ok(program)) = (cache, self.program(id)) {
            cache.insert(&location, &self.include_paths, program);
        }
        Ok(id)
    }

    /// Shares `cache` with other contexts: a shader [`Context::find_shader`] finds by name is
    /// taken from it, compiled, while its files are unchanged (and put in it when compiled here).
    /// The frames of a render, each loaded into a context of its own, compile their shaders once.
    pub fn share_shader_cache(&mut self, cache: Arc<ShaderCache>) {
        self.shader_cache = Some(cache);
    }

    /// Replaces the program behind `id` (hot reload): frames from now on use the new code. The
    /// new program must be of the same shader type. Values bound by name stay bound where the new
    /// shader still has a parameter of that name and type; the others are dropped with a warning
    /// at the next frame ([`Context::take_warnings`]), and reported now as
    /// [`ShaderEvent::ParameterDropped`] events ([`Context::take_shader_events`]).
    pub fn replace_shader(&mut self, id: ShaderId, program: ShaderProgram) -> Result<(), ApiError> {
        let dropped = self.swap_program(id, program)?;
        self.events.extend(dropped);
        Ok(())
    }

    /// [`Context::replace_shader`], returning the [`ShaderEvent::ParameterDropped`] events instead
    /// of queueing them (hot reload queues them after its own event).
    pub(crate) fn swap_program(&mut self, id: ShaderId, program: ShaderProgram) -> Result<Vec<ShaderEvent>, ApiError> {
        let dropped = self.dropped_parameters(id, &program);
        let slot = self.programs.get_mut(id.0 as usize).ok_or(ApiError::UnknownShader(id.0))?;
        if let Some(old) = slot.as_ref() {
            if old.kind != program.kind {
                return Err(ApiError::WrongKind {
                    name: program.name.clone(),
                    expected: kind_name(old.kind),
                    got: kind_name(program.kind),
                });
            }
        }
        *slot = Some(Arc::new(program));
        Ok(dropped)
    }

    /// The values bound to shader `id` (surface bindings of objects and of the current and saved
    /// state, lights, the pixel shader) that `program` would not take, once per (parameter, reason).
    fn dropped_parameters(&self, id: ShaderId, program: &ShaderProgram) -> Vec<ShaderEvent> {
        let surfaces =
            std::iter::once(&self.appearance)
                .chain(&self.appearance_stack)
                .chain(self.objects.iter().filter(|o| !o.deleted).flat_map(|o| {
                    std::iter::once(&o.appearance).chain(o.parts.iter().flat_map(|p| p.appearances.iter()))
                }))
                .chain(self.instances.iter().filter(|i| !i.deleted).filter_map(|i| i.appearance.as_ref()))
                .flat_map(|a| a.surface.iter().chain(a.interior.iter()))
                .chain(self.pixel.as_ref())
                .chain(self.atmosphere.as_ref())
                .filter(|b| b.shader == id)
                .flat_map(|b| b.params.iter());
        let lights = self.lights.iter().filter(|l| l.shader == id).flat_map(|l| l.params.iter());
        let mut out = Vec::new();
        for (parameter, value, m) in surfaces.chain(lights) {
            if let Err(e) = crate::shading::bind_param(program, parameter, value, m) {
                let event = ShaderEvent::ParameterDropped {
                    shader: id,
                    name: program.name.clone(),
                    parameter: parameter.clone(),
                    reason: e.to_string(),
                };
                if !out.contains(&event) {
                    out.push(event);
                }
            }
        }
        out
    }

    /// The hot-reload events since the last call, oldest first: shaders reloaded or not
    /// ([`crate::reload`]), and bound values a new parameter list no longer takes. The queue grows
    /// until taken.
    pub fn take_shader_events(&mut self) -> Vec<ShaderEvent> {
        std::mem::take(&mut self.events)
    }

    pub(crate) fn push_shader_events(&mut self, events: impl IntoIterator<Item = ShaderEvent>) {
        self.events.extend(events);
    }

    /// Every file the loaded shaders were compiled from (sources and included headers), for a
    /// watcher.
    pub fn shader_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.programs.iter().flatten().flat_map(|p| p.files.iter().cloned()).collect();
        files.sort();
        files.dedup();
        files
    }

    /// The loaded programs with their ids.
    pub fn programs_by_id(&self) -> Vec<(ShaderId, Program)> {
        self.programs.iter().enumerate().filter_map(|(i, p)| Some((ShaderId(i as u32), p.clone()?))).collect()
    }

    pub fn include_paths(&self) -> &[PathBuf] {
        &self.include_paths
    }

    /// Warnings of the last frames (values that no longer fit a reloaded shader), drained.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    pub fn program(&self, id: ShaderId) -> Result<&Program, ApiError> {
        self.programs.get(id.0 as usize).and_then(Option::as_ref).ok_or(ApiError::UnknownShader(id.0))
    }

    fn add_program(&mut self, program: ShaderProgram) -> ShaderId {
        self.programs.push(Some(Arc::new(program)));
        ShaderId(self.programs.len() as u32 - 1)
    }

    fn expect_kind(&self, id: ShaderId, expected: ShaderKind) -> Result<Program, ApiError> {
        let p = self.program(id)?.clone();
        if p.kind != expected {
            return Err(ApiError::WrongKind {
                name: p.name.clone(),
                expected: kind_name(expected),
                got: kind_name(p.kind),
            });
        }
        Ok(p)
    }

    /// Binds a surface (or lightfield) shader: the object being built (or, outside objects, the
    /// objects built from now on) is shaded by it. Its "shader" space is the current matrix.
    pub fn bind_shader(&mut self, id: ShaderId) -> Result<(), ApiError> {
        // A lightfield shader is bound like a surface: it shades the rays that hit the object.
        if self.program(id)?.kind != ShaderKind::Lightfield {
            self.expect_kind(id, ShaderKind::Surface)?;
        }
        self.appearance.surface = Some(Binding { shader: id, params: Vec::new(), world_from_shader: self.matrix });
        Ok(())
    }

    /// The surface shader bound now, if any.
    pub fn bound_surface(&self) -> Option<ShaderId> {
        self.appearance.surface.as_ref().map(|b| b.shader)
    }

    /// Sets a parameter of the bound surface shader (object scope). The value is checked against the
    /// shader's declaration now; point-like values are in the current space. `value` is a
    /// [`ParamValue`] or anything that converts to one (`0.8`, `[1.0, 0.5, 0.2]`, a glam vector, a
    /// string).
    pub fn parameter(&mut self, name: &str, value: impl Into<ParamValue>) -> Result<(), ApiError> {
        self.parameters(&[(name, value.into())])
    }

    /// Sets several parameters of the bound surface shader (object scope), as
    /// [`Context::parameter`] does one: the list form that lights and the other shaders take
    /// (written most easily with [`crate::params!`]). All are checked before any is set.
    pub fn parameters(&mut self, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.set_binding_parameters(|a| &mut a.surface, params)
    }

    /// Sets parameters of the binding `which` picks out of the appearance, checked against its
    /// shader first, each value with the current matrix; its shader space stays.
    fn set_binding_parameters(
        &mut self,
        which: fn(&mut Appearance) -> &mut Option<Binding>,
        params: &[(&str, ParamValue)],
    ) -> Result<(), ApiError> {
        let Some((first, _)) = params.first() else { return Ok(()) };
        let shader = which(&mut self.appearance).as_ref().map(|b| b.shader);
        let program = self.program(shader.ok_or_else(|| ApiError::NoShaderBound(first.to_string()))?)?.clone();
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        let m = self.matrix;
        if let Some(b) = which(&mut self.appearance).as_mut() {
            for (name, value) in params {
                b.params.retain(|(n, _, _)| n != name);
                b.params.push((name.to_string(), value.clone(), m));
            }
        }
        Ok(())
    }

    /// The displacement shader bound now, if any.
    pub fn bound_displacement(&self) -> Option<ShaderId> {
        self.appearance.displacement.as_ref().map(|b| b.shader)
    }

    /// Sets parameters of the bound displacement shader (object scope), as
    /// [`Context::parameters`] sets the surface shader's: its "shader" space stays where it was
    /// bound, and point-like values are in the current space. All are checked before any is set.
    pub fn displacement_parameters(&mut self, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.set_binding_parameters(|a| &mut a.displacement, params)
    }

    fn varying_param_floats(&self, name: &str, value: &ParamValue) -> Result<Vec<f32>, ApiError> {
        let binding = self.appearance.surface.as_ref().ok_or_else(|| ApiError::NoShaderBound(name.to_string()))?;
        let program = self.program(binding.shader)?.clone();
        let bound = crate::shading::bind_param(&program, name, value, &self.matrix)?;
        if !program.layout().params[bound.index].varying || bound.string.is_some() {
            return Err(ApiError::NotVarying { shader: program.name.clone(), name: name.to_string() });
        }
        Ok(bound.floats)
    }

    /// Sets a varying parameter of the bound surface shader for the open primitive.
    pub fn primitive_parameter(&mut self, name: &str, value: impl Into<ParamValue>) -> Result<(), ApiError> {
        if self.primitive.is_none() {
            return Err(ApiError::Unbalanced("primitive_parameter", "begin"));
        }
        let value = value.into();
        let floats = self.varying_param_floats(name, &value)?;
        self.primitive_values.retain(|(n, _)| n != name);
        self.primitive_values.push((name.to_string(), floats));
        Ok(())
    }

    /// Sets a varying parameter of the bound surface shader for the vertices that follow.
    pub fn vertex_parameter(&mut self, name: &str, value: impl Into<ParamValue>) -> Result<(), ApiError> {
        let value = value.into();
        let floats = self.varying_param_floats(name, &value)?;
        self.vertex_values.retain(|(n, _)| n != name);
        self.vertex_values.push((name.to_string(), floats));
        Ok(())
    }

    /// Adds a light source at the current matrix, with its parameter values (written most easily
    /// with [`crate::params!`]).
    pub fn light_source(&mut self, shader: ShaderId, params: &[(&str, ParamValue)]) -> Result<LightId, ApiError> {
        let program = self.expect_kind(shader, ShaderKind::Light)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        self.lights.push(LightRecord {
            shader,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
            shadows: true,
            area_triangles: Vec::new(),
            area_samples: 16,
            on: true,
        });
        Ok(LightId(self.lights.len() as u32 - 1))
    }

    /// Makes a light an area light (RenderMan's `AreaLightSource`) emitting from `mesh` too (in the
    /// current space): its shader runs with `P` and `N` at samples on the geometry, each sample a
    /// light of its own with a traced shadow (soft shadows).
    pub fn area_light_geometry(&mut self, light: LightId, mesh: &Mesh) -> Result<(), ApiError> {
        let m = self.matrix;
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        rec.area_triangles
            .extend((0..mesh.triangle_count()).map(|i| mesh.corners(i).map(|c| m.transform_point3a(Vec3A::from(c)))));
        Ok(())
    }

    /// Samples of an area light per shading point (16 by default).
    pub fn set_area_light_samples(&mut self, light: LightId, samples: u32) {
        if let Some(rec) = self.lights.get_mut(light.0 as usize) {
            rec.area_samples = samples.clamp(1, crate::render::MAX_AREA_SAMPLES);
        }
    }

    /// The pixel shader (RenderMan's imager, OpenRT's pixel shader) run on every finished tile, with
    /// its parameter values; `None` removes it.
    pub fn pixel_shader(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.pixel = self.kind_binding(ShaderKind::Imager, shader, params)?;
        Ok(())
    }

    /// The camera shader that generates the primary rays (`None`: the built-in pinhole camera). Its
    /// "shader" and "object" spaces are camera space, whatever the current matrix; the camera's
    /// placement still comes from [`Context::camera_look_at`] / [`Context::set_camera`]. The globals it
    /// reads and writes are specified in `docs/cameras.md`.
    pub fn camera_shader(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.camera_shader = self.kind_binding(ShaderKind::Camera, shader, params)?;
        Ok(())
    }

    /// The camera shader bound with [`Context::camera_shader`], if any.
    pub fn camera_shader_id(&self) -> Option<ShaderId> {
        self.camera_shader.as_ref().map(|b| b.shader)
    }

    /// The atmosphere (RenderMan's `Atmosphere`): a volume shader run on every ray segment that ends
    /// on a surface outside objects with an interior shader (`docs/volumes.md`), with its parameter
    /// values; `None` removes it.
    pub fn atmosphere(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.atmosphere = self.volume_binding(shader, params)?;
        Ok(())
    }

    /// The displacement shader (RenderMan's `Displacement`) of objects built from now on, an
    /// attribute like the surface shader. It runs on every hit before the surface shader, and the
    /// normal it leaves is the surface shader's `N`: displacement as bump mapping, where the
    /// traced geometry does not move and `P` stays on it. Objects that ask for true displacement
    /// ([`Context::true_displacement`], [`Context::displacement_bound`]) are diced instead and
    /// moved by the `P` it leaves (`docs/rendering.md`). `None` removes it.
    pub fn displacement(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.appearance.displacement = self.kind_binding(ShaderKind::Displacement, shader, params)?;
        Ok(())
    }

    /// The interior volume shader (RenderMan's `Interior`) of objects built from now on, an
    /// attribute like the surface shader (saved by `push_attributes`): it runs on ray segments that
    /// reach such an object's surface from behind, i.e. travel inside it (`docs/volumes.md`).
    /// `None` removes it.
    pub fn interior(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.appearance.interior = self.volume_binding(shader, params)?;
        Ok(())
    }

    /// A volume shader's binding with its values checked now; `None` for `None`.
    fn volume_binding(
        &self,
        shader: Option<ShaderId>,
        params: &[(&str, ParamValue)],
    ) -> Result<Option<Binding>, ApiError> {
        self.kind_binding(ShaderKind::Volume, shader, params)
    }

    /// A binding of a shader of `kind` with its values checked now; `None` for `None`.
    fn kind_binding(
        &self,
        kind: ShaderKind,
        shader: Option<ShaderId>,
        params: &[(&str, ParamValue)],
    ) -> Result<Option<Binding>, ApiError> {
        let Some(id) = shader else { return Ok(None) };
        let program = self.expect_kind(id, kind)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        Ok(Some(Binding {
            shader: id,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
        }))
    }

    /// Switches a light on or off, and its ray-traced shadows.
    pub fn set_light(&mut self, light: LightId, on: bool, shadows: bool) -> Result<(), ApiError> {
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        rec.on = on;
        rec.shadows = shadows;
        Ok(())
    }

    /// Moves a light between frames: its "shader" space becomes `world_from_light`, and the
    /// values it was given (points such as `from` and `to`, vectors) are read in that space from
    /// now on, so they move with it. An area light's geometry moves along.
    pub fn set_light_transform(&mut self, light: LightId, world_from_light: Affine3A) -> Result<(), ApiError> {
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        // A value given in the light's space (every value of `light_source`) is read in the new
        // one; any other keeps where it stands relative to the light, as its geometry does. A
        // light squashed flat before has no such relation: then everything takes the new space.
        let before = rec.world_from_shader;
        let moved = Some(world_from_light * before.inverse()).filter(|m| m.is_finite());
        for (_, _, m) in &mut rec.params {
            *m = match moved {
                Some(moved) if *m != before => moved * *m,
                _ => world_from_light,
            };
        }
        if let Some(moved) = moved {
            for t in &mut rec.area_triangles {
                *t = t.map(|p| moved.transform_point3a(p));
            }
        }
        rec.world_from_shader = world_from_light;
        Ok(())
    }

    /// A light's "shader" space: where [`Context::light_source`] placed it, or
    /// [`Context::set_light_transform`] moved it.
    pub fn light_transform(&self, light: LightId) -> Result<Affine3A, ApiError> {
        self.lights.get(light.0 as usize).map(|l| l.world_from_shader).ok_or(ApiError::UnknownLight(light.0))
    }

    /// Changes values of a light's parameters between frames (its intensity, colour, position...),
    /// given in the light's own "shader" space, whatever the current matrix; the others keep
    /// theirs. Checked as [`Context::light_source`] checks them: none is set if one is refused.
    pub fn set_light_parameters(&mut self, light: LightId, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        let rec = self.lights.get(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        let (shader, space) = (rec.shader, rec.world_from_shader);
        let program = self.expect_kind(shader, ShaderKind::Light)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &space)?;
        }
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        for (name, value) in params {
            rec.params.retain(|(n, _, _)| n != name);
            rec.params.push((name.to_string(), value.clone(), space));
        }
        Ok(())
    }
}

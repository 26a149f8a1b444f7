//! The preview's render pipeline, two passes of `shaders/gdm_preview.wgsl`: the hit pass
//! rasterizes the prism faces with back faces culled and runs the GDM algorithm's steps 2–5
//! per fragment, writing the hit's depth so that mesostructure occludes across prisms
//! (escapes discarded) and the nearest hit's data to [`HitTargets`]; the shading pass (one
//! full-screen triangle) shades each pixel's hit once (step 6). Renders to a linear
//! `rgba32float` target (alpha = hit mask) and reads it back as an
//! [`Image`](mesobake_render::image::Image).

use super::bindings::{
    init_buffer, layout_entry, storage, storage_read_write, texture, uint_texture, uniform,
};
use super::frames::RealtimePipeline;
use super::gpu::Gpu;
use super::object_passes::{FullScreenStage, MAX_OCCLUDED_LIGHTS, SharedOcclusion, SharedTargets};
use super::resources::{
    GpuEnvironment, GpuMaterial, GpuMemory, GpuPackage, GpuShell, Vertex, upload_environment,
    upload_material, upload_package, upload_prism_bvh, upload_shell,
};
use super::target::{
    DrawState, HitTargets, Target, pixel_target, pixel_target_bytes, target_pipeline,
};
use super::variant::{OCCLUDE_ENTRY, ShaderVariant};
use super::vdm_objects::{FragmentTargets, VdmObject, VdmUpload};
use super::view::{ViewBuffer, ViewUniform, light_records, view_uniform};
use glam::DVec3;
use mesobake_bake::mesostructure::material::MaterialVolume;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_bake::surface::shell::Shell;
use mesobake_bake::vdm::Relief;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::quality::ShadowMethod;
use mesobake_package::vdm::VdmQuery;
use mesobake_render::gi_shading::GiShading;
use mesobake_render::prepared_prism::{PreparedPrism, prepare_prisms};
use mesobake_render::shot::Shot;

/// One object of a preview: what it is drawn from.
pub struct PreviewObject<'a> {
    /// The shot with the object's material; every object's camera, lights and effects are
    /// the first object's.
    pub shot: &'a Shot,
    /// The object's shell.
    pub shell: &'a Shell,
    /// What the object's technique draws it from.
    pub technique: ObjectTechnique<'a>,
}

/// What an object is drawn from, by its technique.
pub enum ObjectTechnique<'a> {
    /// The GDM pipeline (`gdm_preview.wgsl`).
    Gdm {
        /// The object's material (normals and albedo); its grid is the package's.
        material: &'a MaterialVolume,
        /// Its package, whose GDM the pipeline queries.
        package: &'a Package,
        /// The environment shading the CPU twin reads from the same package (where the
        /// scene calls for environment lighting).
        gi: Option<&'a GiShading>,
    },
    /// The VDM pipeline (`vdm_preview.wgsl`; only among several objects: one VDM object
    /// alone is [`crate::vdm_pipeline::VdmPreview`]'s).
    Vdm {
        /// The object's VDM.
        query: &'a VdmQuery,
        /// The relief it was baked from.
        relief: Relief<'a>,
    },
}

/// A scene ready to render with the real-time pipeline: one GDM object, or several objects
/// (GDM and VDM) drawn into the same targets (each object's hits compete in one
/// depth-tested hit pass, and with shadows each object blocks the others' shadow rays:
/// `objects_on.wgsl`).
pub struct Preview<'g> {
    gpu: &'g Gpu,
    objects: Vec<ObjectPasses>,
    hits: HitTargets,
    /// Where VDM objects keep their fragments before merging their hits (with any VDM
    /// object).
    fragments: Option<FragmentTargets>,
    target: Target,
    /// Per pixel, the nearest hit so far this frame (`nearest_hit` of the shader), cleared
    /// before each frame.
    nearest_hit: wgpu::Buffer,
    /// With several objects and shadows, what the occlusion passes share.
    occlusion: Option<SharedOcclusion>,
    memory: GpuMemory,
}

/// One object's passes, by its technique.
enum ObjectPasses {
    Gdm(GdmObject),
    Vdm(VdmObject),
}

impl ObjectPasses {
    fn memory(&self) -> GpuMemory {
        match self {
            ObjectPasses::Gdm(o) => o.memory,
            ObjectPasses::Vdm(o) => o.memory,
        }
    }
}

/// One GDM object's pipelines and the resources its bind groups hold.
struct GdmObject {
    variant: ShaderVariant,
    /// Steps 2–5 per fragment, into the hit targets.
    hit_pipeline: wgpu::RenderPipeline,
    /// Step 6 per pixel the object won, from the hit targets into the target.
    shade_pipeline: wgpu::RenderPipeline,
    /// The object's bindings.
    scene_group: wgpu::BindGroup,
    /// The object's bindings and the hit targets to read.
    shade_group: wgpu::BindGroup,
    /// With several objects and shadows: its start and occlusion passes.
    occlusion: Option<ObjectOcclusion>,
    package: GpuPackage,
    material: GpuMaterial,
    shell: GpuShell,
    environment: Option<GpuEnvironment>,
    view: ViewBuffer,
    memory: GpuMemory,
}

/// One object's part in the occlusion between objects.
struct ObjectOcclusion {
    /// `fs_start`: its pixels' shadow-ray starts.
    start_pipeline: wgpu::RenderPipeline,
    /// `fs_occlude`: its shell against the other objects' shadow rays.
    occlude_pipeline: wgpu::RenderPipeline,
    /// The shading bindings and the starts.
    occlude_group: wgpu::BindGroup,
}

impl<'g> Preview<'g> {
    /// Uploads `shell`, `material` and `package`'s GDM (and, for environment lighting, the
    /// package's RTV with `gi`, the shading the CPU twin reads from the same package), and
    /// builds the pipeline of `shot`'s shader variant (with the early depth test where
    /// `early_depth_test` allows it and the adapter has it). The package's grid must be the
    /// material's.
    pub fn new(
        gpu: &'g Gpu,
        shot: &Shot,
        shell: &Shell,
        material: &MaterialVolume,
        package: &Package,
        gi: Option<&GiShading>,
        early_depth_test: bool,
    ) -> Result<Preview<'g>> {
        let object = PreviewObject {
            shot,
            shell,
            technique: ObjectTechnique::Gdm {
                material,
                package,
                gi,
            },
        };
        Preview::of_objects(gpu, &[object], early_depth_test)
    }

    /// [`Preview::new`] of several objects rendered together (the CPU specification:
    /// `mesobake_render::objects`): the nearest object's hit at each pixel, shaded with the
    /// other objects' shadows where the scene calls for shadows (at most
    /// [`MAX_OCCLUDED_LIGHTS`] lights then). A VDM object needs another object beside it.
    pub fn of_objects(
        gpu: &'g Gpu,
        objects: &[PreviewObject],
        early_depth_test: bool,
    ) -> Result<Preview<'g>> {
        let Some(first) = objects.first() else {
            return Err(Error::InvalidParameter(
                "a preview needs at least one object".into(),
            ));
        };
        let early_depth_test = early_depth_test
            && gpu
                .device
                .features()
                .contains(wgpu::Features::SHADER_EARLY_DEPTH_TEST);
        let occluded = objects.len() > 1 && first.shot.wants(Effect::Shadows);
        if occluded && first.shot.lights.len() > MAX_OCCLUDED_LIGHTS {
            return Err(Error::InvalidParameter(format!(
                "the preview of several objects with shadows takes at most \
                 {MAX_OCCLUDED_LIGHTS} lights; this scene has {}",
                first.shot.lights.len()
            )));
        }
        for o in objects {
            match &o.technique {
                ObjectTechnique::Gdm {
                    material, package, ..
                } => package.check_grid(material.dims())?,
                ObjectTechnique::Vdm { .. } if objects.len() == 1 => {
                    return Err(Error::InvalidParameter(
                        "a VDM object alone is the VDM pipeline's (VdmPreview)".into(),
                    ));
                }
                ObjectTechnique::Vdm { .. } => {}
            }
        }
        // One projection for all: their depths are compared in one depth test.
        let corners: Vec<DVec3> = objects
            .iter()
            .flat_map(|o| o.shell.prisms.iter())
            .flat_map(|p| p.top().into_iter().chain(p.bottom))
            .collect();
        let (width, height) = (first.shot.camera.width, first.shot.camera.height);
        let target = Target::new(gpu, width, height)?;
        let hits = HitTargets::new(gpu, &target);
        let pixels = u64::from(width) * u64::from(height);
        let storage_buffer = |label| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: pixels * 4,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let any_vdm = objects
            .iter()
            .any(|o| matches!(o.technique, ObjectTechnique::Vdm { .. }));
        let (nearest_hit, occlusion, fragments) = gpu.checked("allocating the targets", || {
            let occlusion = occluded.then(|| SharedOcclusion {
                starts: pixel_target(gpu, &target, "shadow-ray starts"),
                blocked: storage_buffer("blocked lights"),
            });
            let fragments = any_vdm.then(|| FragmentTargets::new(gpu, &target));
            (storage_buffer("nearest hit"), occlusion, fragments)
        })?;
        let shared = SharedTargets {
            hits: &hits,
            nearest_hit: &nearest_hit,
            occlusion: occlusion.as_ref(),
            corners: &corners,
        };
        let mut passes = Vec::with_capacity(objects.len());
        for (index, object) in objects.iter().enumerate() {
            passes.push(match object.technique {
                ObjectTechnique::Gdm {
                    material,
                    package,
                    gi,
                } => {
                    let codec = package.manifest().codec;
                    let variant = ShaderVariant::for_shot(
                        object.shot,
                        codec,
                        objects.len(),
                        early_depth_test,
                    );
                    let gdm = GdmUpload {
                        shot: object.shot,
                        material,
                        package,
                        gi,
                        prisms: &prepare_prisms(object.shell, package.dims()),
                    };
                    ObjectPasses::Gdm(GdmObject::new(gpu, &gdm, variant, index, &shared)?)
                }
                ObjectTechnique::Vdm { query, relief } => {
                    let fragments = fragments.as_ref().expect("allocated with any VDM object");
                    let vdm = VdmUpload {
                        shot: object.shot,
                        shell: object.shell,
                        query,
                        relief,
                    };
                    ObjectPasses::Vdm(VdmObject::new(gpu, &vdm, index, &shared, fragments)?)
                }
            });
        }
        let mut memory = passes
            .iter()
            .fold(GpuMemory::default(), |total, o| total + o.memory());
        memory.targets += target.bytes()
            + hits.bytes
            + nearest_hit.size()
            + occlusion
                .as_ref()
                .map_or(0, |o| pixel_target_bytes(&target) + o.blocked.size())
            + fragments.as_ref().map_or(0, |f| f.bytes);
        Ok(Preview {
            gpu,
            objects: passes,
            hits,
            fragments,
            target,
            nearest_hit,
            occlusion,
            memory,
        })
    }

    /// The shader variant of the scene's first GDM object, if it has one.
    pub fn variant(&self) -> Option<ShaderVariant> {
        self.objects.iter().find_map(|o| match o {
            ObjectPasses::Gdm(o) => Some(o.variant),
            ObjectPasses::Vdm(_) => None,
        })
    }
}

/// What a GDM object is drawn from.
struct GdmUpload<'a> {
    shot: &'a Shot,
    material: &'a MaterialVolume,
    package: &'a Package,
    gi: Option<&'a GiShading>,
    prisms: &'a [PreparedPrism],
}

impl GdmObject {
    /// Uploads object number `index` and builds its pipelines of `variant`.
    fn new(
        gpu: &Gpu,
        object: &GdmUpload,
        variant: ShaderVariant,
        index: usize,
        shared: &SharedTargets,
    ) -> Result<GdmObject> {
        let GdmUpload {
            shot,
            package,
            material,
            gi,
            prisms,
        } = *object;
        let codec = package.manifest().codec;
        let frag = wgpu::ShaderStages::FRAGMENT;
        let d = &gpu.device;
        // The shell-shadow variant and an object among several with shadows also read the
        // prisms' BVH (bindings 3 and 4); binding 5 is the per-pixel nearest hit so far
        // (`nearest_hit`).
        let traced = variant.shadows == Some(ShadowMethod::Shell) || variant.occluders;
        let mut scene_entries = vec![
            layout_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT, uniform()),
            layout_entry(1, frag, storage()),
            layout_entry(2, frag, storage()),
            layout_entry(5, frag, storage_read_write()),
        ];
        if traced {
            scene_entries.extend([
                layout_entry(3, frag, storage()),
                layout_entry(4, frag, storage()),
            ]);
        }
        // The full-screen passes also read the hit pass's targets (bindings 6–8) and, with
        // occluders, the blocked lights (10); the occlusion pass also the starts (9).
        let mut shade_entries = scene_entries.clone();
        shade_entries
            .extend((6..9).map(|b| layout_entry(b, frag, texture(wgpu::TextureViewDimension::D2))));
        if variant.occluders {
            shade_entries.push(layout_entry(10, frag, storage_read_write()));
        }
        let new_layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let scene_layout = new_layout("scene", &scene_entries);
        let shade_layout = new_layout("scene and hits", &shade_entries);
        let occlude_layout = variant.occluders.then(|| {
            let mut entries = shade_entries.clone();
            entries.push(layout_entry(
                9,
                frag,
                texture(wgpu::TextureViewDimension::D2),
            ));
            new_layout("scene, hits and starts", &entries)
        });
        let package_entries = match codec {
            GdmCodec::PaperSvd => vec![
                layout_entry(0, frag, uniform()),
                layout_entry(1, frag, texture(wgpu::TextureViewDimension::D3)),
                layout_entry(2, frag, texture(wgpu::TextureViewDimension::D3)),
                layout_entry(3, frag, texture(wgpu::TextureViewDimension::D2)),
                layout_entry(4, frag, texture(wgpu::TextureViewDimension::D2)),
                layout_entry(5, frag, storage()),
            ],
            GdmCodec::Occupancy => vec![layout_entry(
                0,
                frag,
                uint_texture(wgpu::TextureViewDimension::D3),
            )],
        };
        let package_layout = new_layout("package", &package_entries);
        let material_layout = new_layout(
            "material",
            &[
                layout_entry(0, frag, texture(wgpu::TextureViewDimension::D3)),
                layout_entry(1, frag, texture(wgpu::TextureViewDimension::D3)),
            ],
        );
        let environment_layout = new_layout(
            "environment",
            &[
                layout_entry(0, frag, uniform()),
                layout_entry(1, frag, uint_texture(wgpu::TextureViewDimension::D3)),
                layout_entry(2, frag, storage()),
                layout_entry(3, frag, storage()),
                layout_entry(4, frag, storage()),
                layout_entry(5, frag, storage()),
            ],
        );
        let (gpu_package, material, shell, bvh, environment) =
            gpu.checked("uploading the scene", || {
                Ok::<_, Error>((
                    upload_package(gpu, &package_layout, package)?,
                    upload_material(gpu, &material_layout, material)?,
                    upload_shell(gpu, prisms, DVec3::from(shot.camera.eye))?,
                    if traced {
                        Some(upload_prism_bvh(gpu, prisms)?)
                    } else {
                        None
                    },
                    if variant.environment {
                        let gi = gi.ok_or_else(|| {
                            Error::Scene(
                                "effects call for environment_lighting but the preview was \
                                 given no environment shading"
                                    .into(),
                            )
                        })?;
                        Some(upload_environment(gpu, &environment_layout, gi, package)?)
                    } else {
                        None
                    },
                ))
            })??;
        let lights = light_records(shot);
        let view = view_uniform(shot, shared.corners.iter().copied()).of_object(index);
        gpu.checked("building the pipeline", || {
            let view = ViewBuffer::new(d, view, &shot.camera);
            let lights = init_buffer(
                d,
                "lights",
                bytemuck::cast_slice(&lights),
                wgpu::BufferUsages::STORAGE,
            );
            let mut scene = vec![
                (0, view.buffer.as_entire_binding()),
                (1, lights.as_entire_binding()),
                (2, shell.prisms.as_entire_binding()),
                (5, shared.nearest_hit.as_entire_binding()),
            ];
            if let Some(bvh) = &bvh {
                scene.extend([
                    (3, bvh.nodes.as_entire_binding()),
                    (4, bvh.primitives.as_entire_binding()),
                ]);
            }
            let mut shade = scene.clone();
            shade.extend(
                (6..)
                    .zip(&shared.hits.views)
                    .map(|(b, v)| (b, wgpu::BindingResource::TextureView(v))),
            );
            let occlusion = shared.occlusion.filter(|_| variant.occluders);
            if let Some(o) = occlusion {
                shade.push((10, o.blocked.as_entire_binding()));
            }
            let group = |label, layout, entries: &[(u32, wgpu::BindingResource)]| {
                d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(label),
                    layout,
                    entries: &entries
                        .iter()
                        .map(|(binding, resource)| wgpu::BindGroupEntry {
                            binding: *binding,
                            resource: resource.clone(),
                        })
                        .collect::<Vec<_>>(),
                })
            };
            let scene_group = group("scene", &scene_layout, &scene);
            let shade_group = group("scene and hits", &shade_layout, &shade);
            let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("gdm preview"),
                source: wgpu::ShaderSource::Wgsl(variant.source().into()),
            });
            let pipeline = |label, group_layout, vertices: &[_], state| {
                let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &[
                        Some(group_layout),
                        Some(&package_layout),
                        Some(&material_layout),
                        variant.environment.then_some(&environment_layout),
                    ],
                    immediate_size: 0,
                });
                target_pipeline(d, label, &layout, &module, vertices, state)
            };
            let hit_pipeline = pipeline(
                "gdm preview hits",
                &scene_layout,
                &[Some(Vertex::LAYOUT)],
                DrawState {
                    entry_points: ["vs_main", "fs_main"],
                    cull: Some(wgpu::Face::Back),
                    depth_tested: true,
                    blend: None,
                    colour_targets: shared.hits.views.len(),
                },
            );
            let shade_pipeline = pipeline(
                "gdm preview shading",
                &shade_layout,
                &[],
                DrawState::full_screen("fs_shade", 1),
            );
            let occlusion = occlusion
                .zip(occlude_layout.as_ref())
                .map(|(o, occlude_layout)| {
                    let mut occlude = shade.clone();
                    occlude.push((9, wgpu::BindingResource::TextureView(&o.starts)));
                    ObjectOcclusion {
                        start_pipeline: pipeline(
                            "gdm shadow-ray starts",
                            &shade_layout,
                            &[],
                            DrawState::full_screen("fs_start", 1),
                        ),
                        occlude_pipeline: pipeline(
                            "gdm occlusion",
                            occlude_layout,
                            &[],
                            DrawState::full_screen(OCCLUDE_ENTRY, 0),
                        ),
                        occlude_group: group("scene, hits and starts", occlude_layout, &occlude),
                    }
                });
            let memory = GpuMemory {
                package: gpu_package.bytes,
                material: material.bytes,
                geometry: shell.bytes
                    + bvh.as_ref().map_or(0, |b| b.bytes)
                    + (lights.size() + std::mem::size_of::<ViewUniform>() as u64),
                environment: environment.as_ref().map_or(0, |e| e.bytes),
                targets: 0,
            };
            GdmObject {
                variant,
                hit_pipeline,
                shade_pipeline,
                scene_group,
                shade_group,
                occlusion,
                package: gpu_package,
                material,
                shell,
                environment,
                view,
                memory,
            }
        })
    }

    /// Binds `scene_group` and the object's package, material and environment.
    fn bind(&self, pass: &mut wgpu::RenderPass, scene_group: &wgpu::BindGroup) {
        pass.set_bind_group(0, scene_group, &[]);
        pass.set_bind_group(1, &self.package.bind_group, &[]);
        pass.set_bind_group(2, &self.material.bind_group, &[]);
        if let Some(environment) = &self.environment {
            pass.set_bind_group(3, &environment.bind_group, &[]);
        }
    }

    /// Draws its prisms into a pass of the hit targets.
    fn draw_hits(&self, pass: &mut wgpu::RenderPass) {
        pass.set_pipeline(&self.hit_pipeline);
        self.bind(pass, &self.scene_group);
        pass.set_vertex_buffer(0, self.shell.vertices.slice(..));
        pass.draw(0..self.shell.vertex_count, 0..1);
    }

    /// Draws its full-screen pass of `stage` (nothing for the occlusion stages without
    /// occluders).
    fn draw(&self, pass: &mut wgpu::RenderPass, stage: FullScreenStage) {
        let (pipeline, group) = match (stage, &self.occlusion) {
            (FullScreenStage::Shade, _) => (&self.shade_pipeline, &self.shade_group),
            (FullScreenStage::Start, Some(o)) => (&o.start_pipeline, &self.shade_group),
            (FullScreenStage::Occlude, Some(o)) => (&o.occlude_pipeline, &o.occlude_group),
            _ => return,
        };
        pass.set_pipeline(pipeline);
        self.bind(pass, group);
        pass.draw(0..3, 0..1);
    }
}

impl RealtimePipeline for Preview<'_> {
    fn gpu(&self) -> &Gpu {
        self.gpu
    }

    fn target(&self) -> &Target {
        &self.target
    }

    /// The hit pass of every object (a VDM object's fragments kept first, then merged), then
    /// (with several objects and shadows) every object's start and occlusion passes, then
    /// every object's shading of the pixels it won.
    fn submit_frame(&self, read_back: bool) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.nearest_hit, 0, None);
        let views: Vec<_> = self.hits.views.iter().collect();
        {
            let mut pass = self.target.pass_into(&mut encoder, "gdm hits", &views);
            for object in &self.objects {
                if let ObjectPasses::Gdm(o) = object {
                    o.draw_hits(&mut pass);
                }
            }
        }
        for object in &self.objects {
            if let (ObjectPasses::Vdm(o), Some(fragments)) = (object, &self.fragments) {
                o.draw_fragments(&mut encoder, fragments);
                o.draw_merge(&mut self.target.pass_resuming(&mut encoder, "vdm hits", &views));
            }
        }
        let each = |pass: &mut wgpu::RenderPass, stage| {
            for object in &self.objects {
                match object {
                    ObjectPasses::Gdm(o) => o.draw(pass, stage),
                    ObjectPasses::Vdm(o) => o.draw(pass, stage),
                }
            }
        };
        if let Some(shared) = &self.occlusion {
            encoder.clear_buffer(&shared.blocked, 0, None);
            let label = "shadow-ray starts";
            let mut pass = self
                .target
                .pass_into(&mut encoder, label, &[&shared.starts]);
            each(&mut pass, FullScreenStage::Start);
            drop(pass);
            let mut pass = self.target.pass_into(&mut encoder, "occlusion", &[]);
            each(&mut pass, FullScreenStage::Occlude);
        }
        each(
            &mut self.target.pass(&mut encoder, "shading"),
            FullScreenStage::Shade,
        );
        if read_back {
            self.target.copy_out(&mut encoder);
        }
        self.gpu.queue.submit([encoder.finish()]);
    }

    /// Moves the next frames' rays to `offset` in each pixel ([`ViewBuffer::set_subpixel`]).
    fn set_subpixel(&self, offset: [f64; 2]) {
        for object in &self.objects {
            match object {
                ObjectPasses::Gdm(o) => o.view.set_subpixel(self.gpu, offset),
                ObjectPasses::Vdm(o) => o.set_subpixel(self.gpu, offset),
            }
        }
    }

    /// GPU memory taken by this preview's resources.
    fn memory(&self) -> GpuMemory {
        self.memory
    }
}

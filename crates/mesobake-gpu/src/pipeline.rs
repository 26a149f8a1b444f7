//! The preview's render pipeline, two passes of `shaders/gdm_preview.wgsl`: the hit pass
//! rasterizes the prism faces with back faces culled and runs the GDM algorithm's steps 2–5
//! per fragment, writing the hit's depth so that mesostructure occludes across prisms
//! (escapes discarded) and the nearest hit's data to [`HitTargets`]; the shading pass (one
//! full-screen triangle) shades each pixel's hit once (step 6). Renders to a linear
//! `rgba32float` target (alpha = hit mask) and reads it back as an
//! [`Image`](mesobake_render::image::Image).

use super::frames::RealtimePipeline;
use super::gpu::Gpu;
use super::resources::{
    GpuEnvironment, GpuMaterial, GpuMemory, GpuPackage, GpuShell, Vertex, upload_environment,
    upload_material, upload_package, upload_prism_bvh, upload_shell,
};
use super::target::{DrawState, HitTargets, Target, target_pipeline};
use super::variant::ShaderVariant;
use bytemuck::{Pod, Zeroable};
use glam::dcamera::rh;
use glam::{DMat4, DVec3};
use mesobake_bake::mesostructure::material::MaterialVolume;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_bake::surface::shell::Shell;
use mesobake_core::camera::Camera;
use mesobake_core::error::{Error, Result};
use mesobake_core::light::Light;
use mesobake_core::quality::ShadowMethod;
use mesobake_render::gi_shading::GiShading;
use mesobake_render::prepared_prism::prepare_prisms;
use mesobake_render::shot::Shot;
use wgpu::util::DeviceExt;

/// The shader's `View`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    specular: [f32; 4],
    light_count: u32,
    width: u32,
    _pad: [u32; 2],
}

/// The shader's `Light`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct LightRecord {
    kind: u32,
    _pad: [u32; 3],
    vector: [f32; 4],
    colour: [f32; 4],
}

fn light_record(light: &Light) -> LightRecord {
    let (kind, vector, colour) = match *light {
        Light::Point {
            position,
            intensity,
        } => (0, position, intensity),
        Light::Directional {
            direction,
            irradiance,
        } => (1, direction, irradiance),
        Light::Ambient { radiance } => (2, [0.0; 3], radiance),
    };
    let v = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32, 0.0];
    LightRecord {
        kind,
        _pad: [0; 3],
        vector: v(vector),
        colour: v(colour),
    }
}

/// The shader's `View` for `scene`, its depth range around the points `bounds`.
pub(super) fn view_uniform(shot: &Shot, bounds: impl Iterator<Item = DVec3>) -> ViewUniform {
    let m = &shot.material;
    ViewUniform {
        view_proj: view_projection(&shot.camera, bounds)
            .as_mat4()
            .to_cols_array_2d(),
        eye: DVec3::from(shot.camera.eye)
            .extend(0.0)
            .as_vec4()
            .to_array(),
        specular: [
            m.specular[0] as f32,
            m.specular[1] as f32,
            m.specular[2] as f32,
            m.shininess as f32,
        ],
        light_count: shot.lights.len() as u32,
        width: shot.camera.width,
        _pad: [0; 2],
    }
}

/// A view uniform's buffer, which a supersampled preview rewrites for each sample so that
/// the rays pass through the sample's sub-pixel position (`render::sampling`).
pub(super) struct ViewBuffer {
    /// The uniform buffer (the shaders' `view`).
    pub(super) buffer: wgpu::Buffer,
    centre: ViewUniform,
    size: [f64; 2],
}

impl ViewBuffer {
    /// The buffer of `view` (rays through pixel centres) for `camera`'s image.
    pub(super) fn new(d: &wgpu::Device, view: ViewUniform, camera: &Camera) -> ViewBuffer {
        ViewBuffer {
            buffer: d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("view"),
                contents: bytemuck::bytes_of(&view),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            }),
            centre: view,
            size: [f64::from(camera.width), f64::from(camera.height)],
        }
    }

    /// Moves the rays to `offset` in each pixel (from its top-left corner): the image is
    /// shifted by the offset's distance from the centre, so that the fragment at a pixel's
    /// centre sees what lies at `offset`.
    pub(super) fn set_subpixel(&self, gpu: &Gpu, offset: [f64; 2]) {
        let [w, h] = self.size;
        let shift = DVec3::new(
            2.0 * (0.5 - offset[0]) / w,
            2.0 * (offset[1] - 0.5) / h,
            0.0,
        );
        let view_proj = DMat4::from_translation(shift)
            * glam::Mat4::from_cols_array_2d(&self.centre.view_proj).as_dmat4();
        let view = ViewUniform {
            view_proj: view_proj.as_mat4().to_cols_array_2d(),
            ..self.centre
        };
        gpu.queue
            .write_buffer(&self.buffer, 0, bytemuck::bytes_of(&view));
    }
}

/// The shader's lights for `scene` (one zeroed record when it has none: a storage buffer
/// may not be empty).
pub(super) fn light_records(shot: &Shot) -> Vec<LightRecord> {
    let mut lights: Vec<LightRecord> = shot.lights.iter().map(light_record).collect();
    if lights.is_empty() {
        lights.push(LightRecord::zeroed());
    }
    lights
}

/// The camera's view-projection matrix (wgpu clip space, depth 0..1) with near and far
/// planes around the points `bounds` (the shell's corners).
fn view_projection(camera: &Camera, bounds: impl Iterator<Item = DVec3>) -> DMat4 {
    let eye = DVec3::from(camera.eye);
    let forward = (DVec3::from(camera.target) - eye).normalize();
    let (mut near, mut far) = (f64::INFINITY, 0.0f64);
    for p in bounds {
        let depth = (p - eye).dot(forward);
        near = near.min(depth);
        far = far.max(depth);
    }
    let far = if far > 0.0 { far * 1.01 } else { 1.0 };
    let near = near.max(far * 1e-4) * 0.99;
    let aspect = camera.width as f64 / camera.height as f64;
    // WebGPU's clip space: depth 0..1, y up (the DirectX convention).
    let proj = rh::proj::directx::perspective(camera.fov_y_degrees.to_radians(), aspect, near, far);
    proj * rh::view::look_at_mat4(eye, DVec3::from(camera.target), DVec3::from(camera.up))
}

/// A scene ready to render with the real-time pipeline.
pub struct Preview<'g> {
    gpu: &'g Gpu,
    variant: ShaderVariant,
    /// Steps 2–5 per fragment, into `hits`.
    hit_pipeline: wgpu::RenderPipeline,
    /// Step 6 per pixel, from `hits` into the target.
    shade_pipeline: wgpu::RenderPipeline,
    scene_group: wgpu::BindGroup,
    /// The scene's bindings and `hits` to read.
    shade_group: wgpu::BindGroup,
    hits: HitTargets,
    package: GpuPackage,
    material: GpuMaterial,
    shell: GpuShell,
    environment: Option<GpuEnvironment>,
    target: Target,
    /// Per pixel, the nearest hit so far this frame (`nearest_hit` of the shader), cleared
    /// before each frame.
    nearest_hit: wgpu::Buffer,
    view: ViewBuffer,
    memory: GpuMemory,
}

/// A bind group layout over `entries` and the bind group binding each entry's resource.
pub(super) fn bind_group(
    d: &wgpu::Device,
    label: &str,
    entries: &[(wgpu::BindGroupLayoutEntry, wgpu::BindingResource)],
) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries.iter().map(|e| e.0).collect::<Vec<_>>(),
    });
    let group = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &layout,
        entries: &entries
            .iter()
            .map(|(e, resource)| wgpu::BindGroupEntry {
                binding: e.binding,
                resource: resource.clone(),
            })
            .collect::<Vec<_>>(),
    });
    (layout, group)
}

/// A buffer labelled `label` holding `contents`, for `usage`.
pub(super) fn init_buffer(
    d: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

pub(super) fn layout_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    }
}

pub(super) fn storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

pub(super) fn storage_read_write() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: false },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

pub(super) fn uniform() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn texture(dimension: wgpu::TextureViewDimension) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: dimension,
        multisampled: false,
    }
}

fn uint_texture(dimension: wgpu::TextureViewDimension) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Uint,
        view_dimension: dimension,
        multisampled: false,
    }
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
        package.check_grid(material.dims())?;
        let early_depth_test = early_depth_test
            && gpu
                .device
                .features()
                .contains(wgpu::Features::SHADER_EARLY_DEPTH_TEST);
        let codec = package.manifest().codec;
        let variant = ShaderVariant::for_shot(shot, codec, early_depth_test);
        let (width, height) = (shot.camera.width, shot.camera.height);
        let target = Target::new(gpu, width, height)?;
        let hits = HitTargets::new(gpu, &target);
        let frag = wgpu::ShaderStages::FRAGMENT;
        let d = &gpu.device;
        // The shell-shadow variant also reads the prisms' BVH (bindings 3 and 4); binding 5
        // is the per-pixel nearest hit so far (`nearest_hit`).
        let shell_shadows = variant.shadows == Some(ShadowMethod::Shell);
        let mut scene_entries = vec![
            layout_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT, uniform()),
            layout_entry(1, frag, storage()),
            layout_entry(2, frag, storage()),
            layout_entry(5, frag, storage_read_write()),
        ];
        if shell_shadows {
            scene_entries.extend([
                layout_entry(3, frag, storage()),
                layout_entry(4, frag, storage()),
            ]);
        }
        let scene_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene"),
            entries: &scene_entries,
        });
        // The shading pass also reads the hit pass's targets (bindings 6–8).
        let shade_entries: Vec<_> = scene_entries
            .iter()
            .copied()
            .chain((6..9).map(|b| layout_entry(b, frag, texture(wgpu::TextureViewDimension::D2))))
            .collect();
        let shade_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene and hits"),
            entries: &shade_entries,
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
        let package_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("package"),
            entries: &package_entries,
        });
        let material_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("material"),
            entries: &[
                layout_entry(0, frag, texture(wgpu::TextureViewDimension::D3)),
                layout_entry(1, frag, texture(wgpu::TextureViewDimension::D3)),
            ],
        });
        let environment_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("environment"),
            entries: &[
                layout_entry(0, frag, uniform()),
                layout_entry(1, frag, uint_texture(wgpu::TextureViewDimension::D3)),
                layout_entry(2, frag, storage()),
                layout_entry(3, frag, storage()),
                layout_entry(4, frag, storage()),
                layout_entry(5, frag, storage()),
            ],
        });
        let prisms = prepare_prisms(shell, package.dims());
        let (gpu_package, material, shell, bvh, environment) =
            gpu.checked("uploading the scene", || {
                Ok::<_, Error>((
                    upload_package(gpu, &package_layout, package)?,
                    upload_material(gpu, &material_layout, material)?,
                    upload_shell(gpu, &prisms, DVec3::from(shot.camera.eye))?,
                    if shell_shadows {
                        Some(upload_prism_bvh(gpu, &prisms)?)
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
        let corners = prisms.iter().flat_map(|p| {
            p.faces[0]
                .triangle
                .corners
                .into_iter()
                .chain(p.faces[1].triangle.corners)
        });
        let lights = light_records(shot);
        let (hit_pipeline, shade_pipeline, scene_group, shade_group, nearest_hit, view) = gpu
            .checked("building the pipeline", || {
                let view = ViewBuffer::new(d, view_uniform(shot, corners), &shot.camera);
                let lights = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("lights"),
                    contents: bytemuck::cast_slice(&lights),
                    usage: wgpu::BufferUsages::STORAGE,
                });
                let nearest_hit = d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("nearest hit"),
                    size: width as u64 * height as u64 * 4,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let mut buffers = vec![(0, &view.buffer), (1, &lights), (2, &shell.prisms)];
                buffers.push((5, &nearest_hit));
                if let Some(bvh) = &bvh {
                    buffers.extend([(3, &bvh.nodes), (4, &bvh.primitives)]);
                }
                let entries: Vec<wgpu::BindGroupEntry> = buffers
                    .into_iter()
                    .map(|(binding, buffer)| wgpu::BindGroupEntry {
                        binding,
                        resource: buffer.as_entire_binding(),
                    })
                    .collect();
                let scene_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("scene"),
                    layout: &scene_layout,
                    entries: &entries,
                });
                let shade_group =
                    d.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("scene and hits"),
                        layout: &shade_layout,
                        entries: &entries
                            .iter()
                            .cloned()
                            .chain((6..).zip(&hits.views).map(|(binding, view)| {
                                wgpu::BindGroupEntry {
                                    binding,
                                    resource: wgpu::BindingResource::TextureView(view),
                                }
                            }))
                            .collect::<Vec<_>>(),
                    });
                let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("gdm preview"),
                    source: wgpu::ShaderSource::Wgsl(variant.source().into()),
                });
                let layout = |label, scene_layout| {
                    d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(label),
                        bind_group_layouts: &[
                            Some(scene_layout),
                            Some(&package_layout),
                            Some(&material_layout),
                            variant.environment.then_some(&environment_layout),
                        ],
                        immediate_size: 0,
                    })
                };
                let hit_pipeline = target_pipeline(
                    d,
                    "gdm preview hits",
                    &layout("gdm preview hits", &scene_layout),
                    &module,
                    &[Some(Vertex::LAYOUT)],
                    DrawState {
                        entry_points: ["vs_main", "fs_main"],
                        cull: Some(wgpu::Face::Back),
                        depth_tested: true,
                        blend: None,
                        colour_targets: hits.views.len(),
                    },
                );
                let shade_pipeline = target_pipeline(
                    d,
                    "gdm preview shading",
                    &layout("gdm preview shading", &shade_layout),
                    &module,
                    &[],
                    DrawState {
                        entry_points: ["vs_fullscreen", "fs_shade"],
                        cull: None,
                        depth_tested: false,
                        blend: None,
                        colour_targets: 1,
                    },
                );
                (
                    hit_pipeline,
                    shade_pipeline,
                    scene_group,
                    shade_group,
                    nearest_hit,
                    view,
                )
            })?;
        let memory = GpuMemory {
            package: gpu_package.bytes,
            material: material.bytes,
            geometry: shell.bytes
                + bvh.as_ref().map_or(0, |b| b.bytes)
                + (lights.len() * std::mem::size_of::<LightRecord>()
                    + std::mem::size_of::<ViewUniform>()) as u64,
            environment: environment.as_ref().map_or(0, |e| e.bytes),
            targets: target.bytes() + hits.bytes + nearest_hit.size(),
        };
        Ok(Preview {
            gpu,
            variant,
            hit_pipeline,
            shade_pipeline,
            scene_group,
            shade_group,
            hits,
            package: gpu_package,
            material,
            shell,
            environment,
            target,
            nearest_hit,
            view,
            memory,
        })
    }

    /// The shader variant the scene chose.
    pub fn variant(&self) -> ShaderVariant {
        self.variant
    }
}

impl RealtimePipeline for Preview<'_> {
    fn gpu(&self) -> &Gpu {
        self.gpu
    }

    fn target(&self) -> &Target {
        &self.target
    }

    fn submit_frame(&self, read_back: bool) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.nearest_hit, 0, None);
        let bind = |pass: &mut wgpu::RenderPass, scene_group| {
            pass.set_bind_group(0, scene_group, &[]);
            pass.set_bind_group(1, &self.package.bind_group, &[]);
            pass.set_bind_group(2, &self.material.bind_group, &[]);
            if let Some(environment) = &self.environment {
                pass.set_bind_group(3, &environment.bind_group, &[]);
            }
        };
        {
            let views: Vec<_> = self.hits.views.iter().collect();
            let mut pass = self.target.pass_into(&mut encoder, "gdm hits", &views);
            pass.set_pipeline(&self.hit_pipeline);
            bind(&mut pass, &self.scene_group);
            pass.set_vertex_buffer(0, self.shell.vertices.slice(..));
            pass.draw(0..self.shell.vertex_count, 0..1);
        }
        {
            let mut pass = self.target.pass(&mut encoder, "gdm shading");
            pass.set_pipeline(&self.shade_pipeline);
            bind(&mut pass, &self.shade_group);
            pass.draw(0..3, 0..1);
        }
        if read_back {
            self.target.copy_out(&mut encoder);
        }
        self.gpu.queue.submit([encoder.finish()]);
    }

    /// Moves the next frames' rays to `offset` in each pixel ([`ViewBuffer::set_subpixel`]).
    fn set_subpixel(&self, offset: [f64; 2]) {
        self.view.set_subpixel(self.gpu, offset);
    }

    /// GPU memory taken by this preview's resources.
    fn memory(&self) -> GpuMemory {
        self.memory
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The view and light records are laid out as `View` and `Light` in `common.wgsl`.
    #[test]
    fn the_view_and_light_records_are_their_wgsl_structs() {
        let source = source_with_every_struct();
        let view = rust_layout!(ViewUniform {
            view_proj,
            eye,
            specular,
            light_count,
            width
        });
        assert_twin(&source, "View", view);
        assert_twin(
            &source,
            "Light",
            rust_layout!(LightRecord {
                kind,
                vector,
                colour
            }),
        );
    }
}

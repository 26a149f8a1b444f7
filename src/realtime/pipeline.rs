//! The preview's render pipeline: prism faces rasterized with back faces culled, the GDM
//! algorithm per fragment (`shaders/gdm_preview.wgsl`), depth written at the hit so that
//! mesostructure occludes across prisms, escapes discarded. Renders to a linear
//! `rgba32float` target (alpha = hit mask) and reads it back as an [`Image`].

use super::gpu::{AdapterDescription, Gpu};
use super::resources::{
    GpuEnvironment, GpuMaterial, GpuMemory, GpuPackage, GpuShell, Vertex, upload_environment,
    upload_material, upload_package, upload_prism_bvh, upload_shell,
};
use super::variant::ShaderVariant;
use crate::bake::gdm::BakeObserver;
use crate::error::{Error, Result};
use crate::package::Package;
use crate::package::manifest::GdmCodec;
use crate::render::gdm_renderer::prepare_prisms;
use crate::render::image::Image;
use crate::render::quality::ShadowMethod;
use crate::scene::{Camera, Light, LoadedScene};
use bytemuck::{Pod, Zeroable};
use glam::dcamera::rh;
use glam::{DMat4, DVec3};
use std::time::Instant;
use wgpu::util::DeviceExt;

const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Bytes per texel of the colour target.
const COLOUR_TEXEL: u32 = 16;

/// The shader's `View`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ViewUniform {
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
struct LightRecord {
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
    pipeline: wgpu::RenderPipeline,
    scene_group: wgpu::BindGroup,
    package: GpuPackage,
    material: GpuMaterial,
    shell: GpuShell,
    environment: Option<GpuEnvironment>,
    colour: wgpu::Texture,
    depth: wgpu::TextureView,
    /// Per pixel, the nearest hit so far this frame (`nearest_hit` of the shader), cleared
    /// before each frame.
    nearest_hit: wgpu::Buffer,
    readback: wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
    memory: GpuMemory,
}

fn layout_entry(
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

fn storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn storage_read_write() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: false },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn uniform() -> wgpu::BindingType {
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
    /// Uploads `loaded`'s shell and material and `package`'s GDM (and, for environment
    /// lighting, its RTV and PRT with the scene's environment), and builds the pipeline of
    /// the scene's shader variant (with the early depth test where `early_depth_test` allows
    /// it and the adapter has it). The package's grid must be the scene's.
    pub fn new(
        gpu: &'g Gpu,
        loaded: &LoadedScene,
        package: &Package,
        early_depth_test: bool,
    ) -> Result<Preview<'g>> {
        let scene = &loaded.scene;
        package.check_grid(loaded.material.dims())?;
        let early_depth_test = early_depth_test
            && gpu
                .device
                .features()
                .contains(wgpu::Features::SHADER_EARLY_DEPTH_TEST);
        let codec = package.manifest().codec;
        let variant = ShaderVariant::for_scene(scene, codec, early_depth_test);
        let (width, height) = (scene.camera.width, scene.camera.height);
        let max_side = gpu.device.limits().max_texture_dimension_2d;
        if width > max_side || height > max_side {
            return Err(Error::Gpu(format!(
                "a {width}×{height} image exceeds this adapter's limit of {max_side} pixels per side"
            )));
        }
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
        let prisms = prepare_prisms(&loaded.shell, package.dims());
        let (gpu_package, material, shell, bvh, environment) =
            gpu.checked("uploading the scene", || {
                Ok::<_, Error>((
                    upload_package(gpu, &package_layout, package)?,
                    upload_material(gpu, &material_layout, &loaded.material)?,
                    upload_shell(gpu, &prisms, DVec3::from(scene.camera.eye))?,
                    if shell_shadows {
                        Some(upload_prism_bvh(gpu, &prisms)?)
                    } else {
                        None
                    },
                    if variant.environment {
                        Some(upload_environment(
                            gpu,
                            &environment_layout,
                            loaded,
                            package,
                        )?)
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
        let view_proj = view_projection(&scene.camera, corners).as_mat4();
        let m = &scene.material;
        let view = ViewUniform {
            view_proj: view_proj.to_cols_array_2d(),
            eye: DVec3::from(scene.camera.eye)
                .extend(0.0)
                .as_vec4()
                .to_array(),
            specular: [
                m.specular[0] as f32,
                m.specular[1] as f32,
                m.specular[2] as f32,
                m.shininess as f32,
            ],
            light_count: scene.lights.len() as u32,
            width,
            _pad: [0; 2],
        };
        let mut lights: Vec<LightRecord> = scene.lights.iter().map(light_record).collect();
        if lights.is_empty() {
            lights.push(LightRecord::zeroed());
        }
        let (pipeline, scene_group, colour, depth, nearest_hit, readback, padded_row) = gpu
            .checked("building the pipeline", || {
                let view = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("view"),
                    contents: bytemuck::bytes_of(&view),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
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
                let mut buffers = vec![(0, &view), (1, &lights), (2, &shell.prisms)];
                buffers.push((5, &nearest_hit));
                if let Some(bvh) = &bvh {
                    buffers.extend([(3, &bvh.nodes), (4, &bvh.prisms)]);
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
                let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("gdm preview"),
                    source: wgpu::ShaderSource::Wgsl(variant.source().into()),
                });
                let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("gdm preview"),
                    bind_group_layouts: &[
                        Some(&scene_layout),
                        Some(&package_layout),
                        Some(&material_layout),
                        variant.environment.then_some(&environment_layout),
                    ],
                    immediate_size: 0,
                });
                let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("gdm preview"),
                    layout: Some(&layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_main"),
                        compilation_options: Default::default(),
                        buffers: &[Some(Vertex::LAYOUT)],
                    },
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::TriangleList,
                        front_face: wgpu::FrontFace::Ccw,
                        cull_mode: Some(wgpu::Face::Back),
                        ..Default::default()
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_FORMAT,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Less),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_main"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format: COLOUR_FORMAT,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                });
                let target = |format, usage| {
                    d.create_texture(&wgpu::TextureDescriptor {
                        label: Some("target"),
                        size: wgpu::Extent3d {
                            width,
                            height,
                            depth_or_array_layers: 1,
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format,
                        usage,
                        view_formats: &[],
                    })
                };
                let colour = target(
                    COLOUR_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                );
                let depth = target(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT)
                    .create_view(&Default::default());
                let padded_row =
                    (width * COLOUR_TEXEL).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
                let readback = d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("read-back"),
                    size: padded_row as u64 * height as u64,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                });
                (
                    pipeline,
                    scene_group,
                    colour,
                    depth,
                    nearest_hit,
                    readback,
                    padded_row,
                )
            })?;
        let pixels = width as u64 * height as u64;
        let memory = GpuMemory {
            package: gpu_package.bytes,
            material: material.bytes,
            geometry: shell.bytes
                + bvh.as_ref().map_or(0, |b| b.bytes)
                + (lights.len() * std::mem::size_of::<LightRecord>()
                    + std::mem::size_of::<ViewUniform>()) as u64,
            environment: environment.as_ref().map_or(0, |e| e.bytes),
            targets: pixels * (COLOUR_TEXEL as u64 + 4) + nearest_hit.size() + readback.size(),
        };
        Ok(Preview {
            gpu,
            variant,
            pipeline,
            scene_group,
            package: gpu_package,
            material,
            shell,
            environment,
            colour,
            depth,
            nearest_hit,
            readback,
            padded_row,
            width,
            height,
            memory,
        })
    }

    /// The shader variant the scene chose.
    pub fn variant(&self) -> ShaderVariant {
        self.variant
    }

    /// GPU memory taken by this preview's resources.
    pub fn memory(&self) -> GpuMemory {
        self.memory
    }

    /// The adapter it runs on.
    pub fn adapter(&self) -> &AdapterDescription {
        &self.gpu.adapter
    }

    /// Records one frame (and, with `read_back`, the copy of the target into the read-back
    /// buffer) and submits it.
    fn submit_frame(&self, read_back: bool) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.nearest_hit, 0, None);
        {
            let colour = self.colour.create_view(&Default::default());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("gdm preview"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &colour,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.scene_group, &[]);
            pass.set_bind_group(1, &self.package.bind_group, &[]);
            pass.set_bind_group(2, &self.material.bind_group, &[]);
            if let Some(environment) = &self.environment {
                pass.set_bind_group(3, &environment.bind_group, &[]);
            }
            pass.set_vertex_buffer(0, self.shell.vertices.slice(..));
            pass.draw(0..self.shell.vertex_count, 0..1);
        }
        if read_back {
            encoder.copy_texture_to_buffer(
                self.colour.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.padded_row),
                        rows_per_image: Some(self.height),
                    },
                },
                wgpu::Extent3d {
                    width: self.width,
                    height: self.height,
                    depth_or_array_layers: 1,
                },
            );
        }
        self.gpu.queue.submit([encoder.finish()]);
    }

    /// Renders one frame and reads it back.
    pub fn render(&self) -> Result<Image> {
        self.gpu.checked("rendering", || self.submit_frame(true))?;
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.gpu.wait()?;
        rx.recv()
            .map_err(|_| Error::Gpu("read-back was never mapped".into()))?
            .map_err(|e| Error::Gpu(format!("reading the image back: {e}")))?;
        let mut image = Image::new(self.width, self.height);
        {
            let data = slice
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("reading the image back: {e}")))?;
            for (y, row) in data.chunks_exact(self.padded_row as usize).enumerate() {
                let texels: &[[f32; 4]] =
                    bytemuck::cast_slice(&row[..(self.width * COLOUR_TEXEL) as usize]);
                for (x, t) in texels.iter().enumerate() {
                    let i = y * self.width as usize + x;
                    image.mask[i] = t[3] > 0.5;
                    image.rgb[i] = [t[0], t[1], t[2]];
                }
            }
        }
        self.readback.unmap();
        Ok(image)
    }

    /// Mean seconds per frame over `frames` frames (after one warm-up frame), each submitted
    /// and waited for, reported to `observer` as it finishes.
    pub fn time_frames(&self, frames: u32, observer: &dyn BakeObserver) -> Result<f64> {
        self.submit_frame(false);
        self.gpu.wait()?;
        let start = Instant::now();
        for frame in 1..=frames {
            self.submit_frame(false);
            self.gpu.wait()?;
            observer.progress(frame.into(), frames.into());
        }
        Ok(start.elapsed().as_secs_f64() / frames.max(1) as f64)
    }
}

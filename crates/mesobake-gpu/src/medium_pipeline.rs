//! The translucent-media real-time pipeline (`shaders/medium_preview.wgsl`): the shell's
//! tetrahedral cells, each integrated on its own and composited front to back, in one of the
//! [`CellOrder`](mesobake_render::medium_settings::CellOrder)s: a per-pixel sorted list gathered
//! from a BVH over the cells in a compute pass (one invocation per pixel, writing the
//! target), or the cells drawn back to front in an order sorted per view on the CPU (SXMPVO
//! or MPVONC) and blended. Shadows come from shadow maps
//! built by a compute pass before each frame ([`mesobake_render::medium_shadow_map`]) or from
//! shadow rays. Its specification is [`mesobake_render::medium_cells`], which it is tested
//! against.

use super::bindings::{
    bind_group, init_buffer, layout_entry, storage, storage_read_write, uniform,
};
use super::frames::RealtimePipeline;
use super::gpu::Gpu;
use super::resources::{GpuMemory, upload_box_bvh};
use super::target::{DrawState, Target, read_mapped, target_pipeline};
use super::variant::COMMON;
use super::view::{LightRecord, ViewBuffer, ViewUniform, light_records, view_uniform};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use mesobake_core::camera::Camera;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::light::Light;
use mesobake_render::cell_order::ViewSort;
use mesobake_render::medium_cells::{Cell, CellRenderer};
use mesobake_render::medium_settings::{CellIntegration, ShadowMethod};
use mesobake_render::medium_shadow_map::MapMedium;
use mesobake_render::medium_shadow_map::{LightFrame, Projection, map_frames};
use mesobake_render::medium_truth::{DEFAULT_LIGHT_STEP, MIN_TRANSMITTANCE, SHADOW_START};
use mesobake_render::shot::Shot;
use std::time::Instant;

/// The pipeline's WGSL, in the order it is composed (after `common.wgsl`).
const PARTS: [&str; 8] = [
    include_str!("../../../shaders/medium_preview.wgsl"),
    include_str!("../../../shaders/medium_cells.wgsl"),
    include_str!("../../../shaders/medium_voxels.wgsl"),
    include_str!("../../../shaders/medium_shadow_rays.wgsl"),
    include_str!("../../../shaders/medium_compositing.wgsl"),
    include_str!("../../../shaders/medium_pixel_list.wgsl"),
    include_str!("../../../shaders/medium_cell_raster.wgsl"),
    include_str!("../../../shaders/medium_shadow_maps.wgsl"),
];

/// Most mip levels the shader takes.
const MAX_LEVELS: usize = 16;

/// The complete WGSL source of the translucent-media pipeline.
pub fn source() -> String {
    format!("{COMMON}\n{}", PARTS.join("\n"))
}

/// The shader's `Cell`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CellRecord {
    planes: [[f32; 4]; 4],
    to_texture: [[f32; 4]; 3],
    normal_to_object: [[f32; 4]; 3],
    corners: [[f32; 4]; 4],
}

/// The shader's `Medium`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct MediumUniform {
    forward: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    height: u32,
    integration: u32,
    samples: u32,
    shadows: u32,
    level_count: u32,
    mip_bias: f32,
    light_step: f32,
    shadow_start: f32,
    min_transmittance: f32,
    loop_budget: u32,
    shadow_size: u32,
    shadow_stride: u32,
    levels: [[u32; 4]; MAX_LEVELS],
}

/// The shader's `ShadowFrame`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameRecord {
    origin: [f32; 4],
    axis: [f32; 4],
    u_axis: [f32; 4],
    v_axis: [f32; 4],
    kind: u32,
    first: u32,
    _pad: [u32; 2],
}

/// Per light its frame record (kind 0 where it has no map), every light's map `values`
/// floats after the one before, and the total.
fn frame_records(frames: &[Option<LightFrame>], values: u64) -> (Vec<FrameRecord>, u64) {
    let mut first = 0u64;
    let mut records: Vec<FrameRecord> = frames
        .iter()
        .map(|frame| {
            let Some(f) = frame else {
                return FrameRecord::zeroed();
            };
            let record = FrameRecord {
                origin: vec4(f.origin, f.t0),
                axis: vec4(f.axis, f.depth),
                u_axis: vec4(f.u_axis, 1.0 / f.u_axis.length_squared()),
                v_axis: vec4(f.v_axis, 1.0 / f.v_axis.length_squared()),
                kind: match f.projection {
                    Projection::Orthographic => 1,
                    Projection::Perspective => 2,
                },
                first: first as u32,
                _pad: [0; 2],
            };
            first += values;
            record
        })
        .collect();
    if records.is_empty() {
        records.push(FrameRecord::zeroed());
    }
    (records, first)
}

fn vec4(v: DVec3, w: f64) -> [f32; 4] {
    v.extend(w).as_vec4().to_array()
}

fn cell_record(cell: &Cell) -> CellRecord {
    let m = cell.to_texture.matrix3;
    let t = cell.to_texture.translation;
    let n = cell.normal_to_object;
    let density = m.determinant().abs().cbrt();
    CellRecord {
        // Unit normals keep f32 offsets well scaled; a face's two cells still compute the
        // exact negation of each other's plane.
        planes: cell.planes.map(|(n, d)| {
            let len = n.length();
            vec4(n / len, d / len)
        }),
        to_texture: [0, 1, 2].map(|r| vec4(m.row(r), t[r])),
        normal_to_object: [0, 1, 2].map(|r| vec4(n.row(r), if r == 0 { density } else { 0.0 })),
        corners: cell.corners.map(|c| vec4(c, 1.0)),
    }
}

/// The medium's levels as the shader reads them.
struct MediumTexels {
    /// Per voxel (linear albedo, opacity), every level after the one before.
    voxels: Vec<[f32; 4]>,
    /// Per voxel (normal, 0), in the same order.
    normals: Vec<[f32; 4]>,
    /// Per level its dimensions and first voxel.
    levels: Vec<[u32; 4]>,
}

/// [`MediumTexels`] of the cells' medium and its mip levels.
fn medium_texels(cells: &CellRenderer) -> Result<MediumTexels> {
    let (mut voxels, mut normals, mut levels) = (Vec::new(), Vec::new(), Vec::new());
    for medium in cells.levels() {
        let d = medium.dims();
        let first = u32::try_from(voxels.len())
            .map_err(|_| Error::Gpu("the medium's mip-map exceeds 2³² voxels".into()))?;
        levels.push([d.x, d.y, d.z, first]);
        for v in 0..d.voxel_count() as usize {
            let c = medium.colour(v);
            voxels.push([c.x as f32, c.y as f32, c.z as f32, medium.opacity(v) as f32]);
        }
        normals.extend(
            medium
                .material()
                .normal_voxels()
                .iter()
                .map(|n| n.extend(0.0).to_array()),
        );
    }
    if levels.len() > MAX_LEVELS {
        return Err(Error::Gpu(format!(
            "the medium's mip-map has {} levels; the real-time pipeline takes at most {MAX_LEVELS}",
            levels.len()
        )));
    }
    Ok(MediumTexels {
        voxels,
        normals,
        levels,
    })
}

/// The pipeline of a cell order.
enum MediaPipeline {
    /// Per-pixel lists: the compute pipeline.
    PerPixel(wgpu::ComputePipeline),
    /// Per-view order by a sort: the cells' faces rasterized and blended.
    PerView(wgpu::RenderPipeline, ViewSort),
}

/// A translucent scene ready to render with the real-time pipeline.
pub struct MediumPreview<'g> {
    gpu: &'g Gpu,
    cells: CellRenderer<'g>,
    pipeline: MediaPipeline,
    /// Bind group 0 (the scene) and 1 (the order's outputs and the shadow maps).
    group: wgpu::BindGroup,
    pass_group: wgpu::BindGroup,
    /// The shadow maps' build pass and its bind group 1, where a light has a map; texels
    /// along a map's side.
    map_build: Option<(wgpu::ComputePipeline, wgpu::BindGroup, u32)>,
    /// The count of pixels and texels over the adapter's loop budget, and its read-back.
    overflow: wgpu::Buffer,
    overflow_read: wgpu::Buffer,
    /// Light records (the maps' build pass runs over them).
    lights: u32,
    buffers: Buffers,
    /// The medium uniform for rays through pixel centres.
    params: MediumUniform,
    camera: Camera,
    target: Target,
    memory: GpuMemory,
}

/// The buffers a frame rewrites: the view and medium uniforms (for a sample's sub-pixel
/// position) and the cells' order.
struct Buffers {
    view: ViewBuffer,
    medium: wgpu::Buffer,
    order: wgpu::Buffer,
}

impl<'g> MediumPreview<'g> {
    /// Uploads the cells of `cells`, their BVH and its medium's levels, and builds the
    /// pipeline of the cell order of `cells`' transparency settings for `shot`'s camera,
    /// lights and effects.
    pub fn new(gpu: &'g Gpu, shot: &Shot, cells: CellRenderer<'g>) -> Result<MediumPreview<'g>> {
        let settings = cells.settings();
        let shadows = shot.wants(Effect::Shadows);
        let mesh = cells.cells();
        let frames = if shadows {
            map_frames(&cells, shot)
        } else {
            vec![None; shot.lights.len()]
        };
        // Whether some light's shadows are traced as rays.
        let rays = shadows
            && (frames.iter().zip(&shot.lights))
                .any(|(f, l)| f.is_none() && !matches!(l, Light::Ambient { .. }));
        if let (Some(budget), Some(_), true) = (gpu.loop_budget(), settings.order.view_sort(), rays)
        {
            // Fragments cannot count what they ran; the per-pixel lists can.
            return Err(Error::LoopBudget {
                adapter: gpu.adapter.name.clone(),
                budget,
                what: "the per-view order's fragments trace shadow rays without counting them"
                    .into(),
            });
        }
        let stride = match settings.shadows {
            // t_a, t_e and τ_e, then the levels' depths.
            ShadowMethod::DeepMap => settings.shadow_levels + 3,
            _ => 1,
        };
        let map_size = settings.shadow_map_size;
        let (frame_list, map_values) =
            frame_records(&frames, u64::from(map_size).pow(2) * u64::from(stride));
        let target = Target::new(gpu, shot.camera.width, shot.camera.height)?;
        let mut records: Vec<CellRecord> = mesh.cells().iter().map(cell_record).collect();
        if records.is_empty() {
            // A storage buffer may not be empty; the BVH then has no leaf to list it.
            records.push(CellRecord::zeroed());
        }
        let MediumTexels {
            voxels,
            normals,
            levels,
        } = medium_texels(&cells)?;
        let limit = gpu.device.limits().max_storage_buffer_binding_size;
        let voxel_bytes = std::mem::size_of_val(voxels.as_slice()) as u64;
        let map_bytes = map_values.max(1) * 4;
        for (what, bytes) in [("the medium", voxel_bytes), ("the shadow maps", map_bytes)] {
            if bytes > limit {
                return Err(Error::Gpu(format!(
                    "{what} take {bytes} bytes in one buffer; this adapter binds at most {limit}"
                )));
            }
        }
        let camera = &shot.camera;
        let plane = camera.image_plane();
        let mut level_table = [[0u32; 4]; MAX_LEVELS];
        level_table[..levels.len()].copy_from_slice(&levels);
        let params = MediumUniform {
            forward: vec4(
                plane.forward,
                2.0 * plane.half_height / f64::from(camera.height),
            ),
            right: vec4(plane.right * plane.half_width, 0.0),
            up: vec4(plane.up * plane.half_height, 0.0),
            height: camera.height,
            integration: u32::from(settings.integration == CellIntegration::Samples),
            samples: settings.samples,
            shadows: match settings.shadows {
                _ if !shadows => 0,
                ShadowMethod::Rays => 1,
                ShadowMethod::DeepMap => 2,
                ShadowMethod::DepthMap => 3,
            },
            level_count: levels.len() as u32,
            mip_bias: settings.mip_bias as f32,
            light_step: DEFAULT_LIGHT_STEP as f32,
            shadow_start: SHADOW_START as f32,
            min_transmittance: MIN_TRANSMITTANCE as f32,
            loop_budget: gpu.loop_budget().unwrap_or(0),
            shadow_size: map_size,
            shadow_stride: stride,
            levels: level_table,
        };
        let view: ViewUniform = view_uniform(shot, mesh.cells().iter().flat_map(|c| c.corners));
        let lights: Vec<LightRecord> = light_records(shot);
        let bvh = upload_box_bvh(gpu, &mesh.bounds())?;
        let order: Vec<u32> = (0..records.len() as u32).collect();
        let memory = GpuMemory {
            package: 0,
            material: voxel_bytes * 2,
            geometry: (std::mem::size_of_val(records.as_slice())
                + std::mem::size_of_val(order.as_slice())) as u64
                + bvh.bytes,
            environment: 0,
            targets: target.bytes() + map_bytes,
        };
        let d = &gpu.device;
        let built = gpu.checked("building the media pipeline", || {
            let buffer =
                |label: &str, contents: &[u8], usage| init_buffer(d, label, contents, usage);
            let (u, s) = (wgpu::BufferUsages::UNIFORM, wgpu::BufferUsages::STORAGE);
            let view = ViewBuffer::new(d, view, &shot.camera);
            let own = [
                view.buffer.clone(),
                buffer("lights", bytemuck::cast_slice(&lights), s),
                buffer("cells", bytemuck::cast_slice(&records), s),
                buffer(
                    "medium",
                    bytemuck::bytes_of(&params),
                    u | wgpu::BufferUsages::COPY_DST,
                ),
                buffer("voxels", bytemuck::cast_slice(&voxels), s),
                buffer("normals", bytemuck::cast_slice(&normals), s),
                buffer(
                    "order",
                    bytemuck::cast_slice(&order),
                    s | wgpu::BufferUsages::COPY_DST,
                ),
                buffer("shadow frames", bytemuck::cast_slice(&frame_list), s),
            ];
            let [
                view_b,
                lights_b,
                cells_b,
                medium_b,
                voxels_b,
                normals_b,
                order_b,
                frames_b,
            ] = &own;
            let bound = [
                view_b,
                lights_b,
                cells_b,
                &bvh.nodes,
                &bvh.primitives,
                medium_b,
                voxels_b,
                normals_b,
                order_b,
                frames_b,
            ];
            let all = wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE;
            let entries: Vec<_> = (bound.iter().enumerate())
                .map(|(b, buffer)| {
                    let kind = if b == 0 || b == 5 {
                        uniform()
                    } else {
                        storage()
                    };
                    (
                        layout_entry(b as u32, all, kind),
                        buffer.as_entire_binding(),
                    )
                })
                .collect();
            let (layout, group) = bind_group(d, "media", &entries);
            let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("media preview"),
                source: wgpu::ShaderSource::Wgsl(source().into()),
            });
            let maps = d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("shadow maps"),
                size: map_bytes,
                usage: s,
                mapped_at_creation: false,
            });
            let overflow = d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("loop budget overflow"),
                size: 8,
                usage: s | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let overflow_read = d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("loop budget overflow read-back"),
                size: 8,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let compute = wgpu::ShaderStages::COMPUTE;
            // Bind group 1 of one pass: its layout, its group and the pipeline layout over
            // groups 0 and 1.
            let pass_group =
                |label: &str, entries: &[(wgpu::BindGroupLayoutEntry, wgpu::BindingResource)]| {
                    let (pass_layout, group) = bind_group(d, label, entries);
                    let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(label),
                        bind_group_layouts: &[Some(&layout), Some(&pass_layout)],
                        immediate_size: 0,
                    });
                    (layout, group)
                };
            let compute_pipeline = |label: &str, layout: &wgpu::PipelineLayout, entry: &str| {
                d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: Some(layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            let read_maps = (layout_entry(2, all, storage()), maps.as_entire_binding());
            let (pipeline, pass) = match settings.order.view_sort() {
                None => {
                    let image = wgpu::BindGroupLayoutEntry {
                        binding: 0,
                        visibility: compute,
                        ty: wgpu::BindingType::StorageTexture {
                            access: wgpu::StorageTextureAccess::WriteOnly,
                            format: wgpu::TextureFormat::Rgba32Float,
                            view_dimension: wgpu::TextureViewDimension::D2,
                        },
                        count: None,
                    };
                    let label = "media per-pixel lists";
                    let (layout, group) = pass_group(
                        label,
                        &[
                            (
                                image,
                                wgpu::BindingResource::TextureView(target.colour_view()),
                            ),
                            (
                                layout_entry(1, compute, storage_read_write()),
                                overflow.as_entire_binding(),
                            ),
                            read_maps,
                        ],
                    );
                    let pipeline = compute_pipeline(label, &layout, "cs_pixels");
                    (MediaPipeline::PerPixel(pipeline), group)
                }
                Some(sort) => {
                    let label = "media per-view order";
                    let (layout, group) = pass_group(label, &[read_maps]);
                    // Back to front, premultiplied: dst = src + (1 − src α) · dst.
                    let state = DrawState {
                        entry_points: ["vs_cell", "fs_cell"],
                        cull: Some(wgpu::Face::Back),
                        depth_tested: false,
                        blend: Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                        colour_targets: 1,
                    };
                    let pipeline = target_pipeline(d, label, &layout, &module, &[], state);
                    (MediaPipeline::PerView(pipeline, sort), group)
                }
            };
            let map_build = (map_values > 0).then(|| {
                let label = "media shadow maps";
                let (layout, group) = pass_group(
                    label,
                    &[
                        (
                            layout_entry(1, compute, storage_read_write()),
                            overflow.as_entire_binding(),
                        ),
                        (
                            layout_entry(3, compute, storage_read_write()),
                            maps.as_entire_binding(),
                        ),
                    ],
                );
                (
                    compute_pipeline(label, &layout, "cs_shadow_map"),
                    group,
                    map_size,
                )
            });
            let [_, _, _, medium_buffer, _, _, order_buffer, _] = own;
            let buffers = Buffers {
                view,
                medium: medium_buffer,
                order: order_buffer,
            };
            (
                pipeline,
                group,
                pass,
                map_build,
                overflow,
                overflow_read,
                buffers,
            )
        })?;
        let (pipeline, group, pass_group, map_build, overflow, overflow_read, buffers) = built;
        Ok(MediumPreview {
            gpu,
            cells,
            pipeline,
            group,
            pass_group,
            map_build,
            overflow,
            overflow_read,
            lights: frame_list.len() as u32,
            buffers,
            params,
            camera: shot.camera,
            target,
            memory,
        })
    }

    /// CPU seconds to sort the cells for the view once (what each frame of a per-view
    /// order spends before drawing); `None` for the per-pixel lists.
    pub fn sort_seconds(&self) -> Option<f64> {
        let MediaPipeline::PerView(_, sort) = self.pipeline else {
            return None;
        };
        let start = Instant::now();
        std::hint::black_box(self.cells.cells().view_order(&self.camera, sort));
        Some(start.elapsed().as_secs_f64())
    }
}

impl RealtimePipeline for MediumPreview<'_> {
    fn gpu(&self) -> &Gpu {
        self.gpu
    }

    fn target(&self) -> &Target {
        &self.target
    }

    /// Records one frame (for the per-view order: sorting the cells for the eye and
    /// uploading the order first; and, with `read_back`, the copy of the target into the
    /// read-back buffer) and submits it.
    fn submit_frame(&self, read_back: bool) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.overflow, 0, None);
        if let Some((pipeline, group, size)) = &self.map_build {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            pass.set_bind_group(1, group, &[]);
            pass.dispatch_workgroups(size.div_ceil(8), size.div_ceil(8), self.lights);
        }
        match &self.pipeline {
            MediaPipeline::PerPixel(pipeline) => {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.group, &[]);
                pass.set_bind_group(1, &self.pass_group, &[]);
                let (w, h) = self.target.size();
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
            }
            MediaPipeline::PerView(pipeline, sort) => {
                let order = self.cells.cells().view_order(&self.camera, *sort).order;
                self.gpu
                    .queue
                    .write_buffer(&self.buffers.order, 0, bytemuck::cast_slice(&order));
                let mut pass = self.target.pass(&mut encoder, "media per-view order");
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.group, &[]);
                pass.set_bind_group(1, &self.pass_group, &[]);
                pass.draw(0..12, 0..order.len() as u32);
            }
        }
        if read_back {
            encoder.copy_buffer_to_buffer(&self.overflow, 0, &self.overflow_read, 0, 8);
            self.target.copy_out(&mut encoder);
        }
        self.gpu.queue.submit([encoder.finish()]);
    }

    /// Moves the next frames' rays to `offset` in each pixel (from its top-left corner): the
    /// rasterized faces by the view's projection, the per-pixel rays by the camera basis.
    fn set_subpixel(&self, offset: [f64; 2]) {
        self.buffers.view.set_subpixel(self.gpu, offset);
        let shift = self
            .camera
            .at_subpixel(offset)
            .image_plane()
            .subpixel_shift();
        let forward = self.params.forward;
        let params = MediumUniform {
            forward: vec4(
                DVec3::new(forward[0].into(), forward[1].into(), forward[2].into()) + shift,
                forward[3].into(),
            ),
            ..self.params
        };
        (self.gpu.queue).write_buffer(&self.buffers.medium, 0, bytemuck::bytes_of(&params));
    }

    /// GPU memory per kind of resource: the medium (its levels' voxels and normals, as
    /// `material`), the cells, their BVH and order (`geometry`) and the targets.
    fn memory(&self) -> GpuMemory {
        self.memory
    }

    /// Refused ([`Error::LoopBudget`]) where the adapter cut some pixel's loops short.
    fn check_frame(&self) -> Result<()> {
        let [pixels, texels] = read_mapped(self.gpu, &self.overflow_read, |d| {
            [0, 4].map(|i| u32::from_le_bytes([d[i], d[i + 1], d[i + 2], d[i + 3]]))
        })?;
        if pixels + texels > 0 {
            return Err(Error::LoopBudget {
                adapter: self.gpu.adapter.name.clone(),
                budget: self.gpu.loop_budget().unwrap_or(0),
                what: format!(
                    "{pixels} pixels and {texels} shadow-map texels needed more (rays crossing \
                     many cells, shadow rays through the cells, a large medium)"
                ),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The media pipeline's records are laid out as their structs in `medium_preview.wgsl`.
    #[test]
    fn the_media_records_are_their_wgsl_structs() {
        let source = source();
        let cell = rust_layout!(CellRecord {
            planes,
            to_texture,
            normal_to_object,
            corners
        });
        assert_twin(&source, "Cell", cell);
        let medium = rust_layout!(MediumUniform {
            forward,
            right,
            up,
            height,
            integration,
            samples,
            shadows,
            level_count,
            mip_bias,
            light_step,
            shadow_start,
            min_transmittance,
            loop_budget,
            shadow_size,
            shadow_stride,
            levels
        });
        assert_twin(&source, "Medium", medium);
        let frame = rust_layout!(FrameRecord {
            origin,
            axis,
            u_axis,
            v_axis,
            kind,
            first
        });
        assert_twin(&source, "ShadowFrame", frame);
    }
}

//! The VDM real-time pipeline (`shaders/vdm_preview.wgsl`): the shell's top triangles
//! rasterized with back faces culled, the VDM algorithm per fragment, silhouettes discarded so
//! that the depth test keeps the nearest fragment that is not one. Its specification is
//! [`mesobake_render::vdm_renderer`], which it is tested against.

use super::bindings::{bind_group, init_buffer, layout_entry, storage, uniform};
use super::frames::RealtimePipeline;
use super::gpu::Gpu;
use super::resources::{GpuMemory, upload_box_bvh};
use super::target::{Target, triangle_pipeline};
use super::variant::COMMON;
use super::view::{LightRecord, ViewBuffer, ViewUniform, light_records, view_uniform};
use bytemuck::{Pod, Zeroable};
use glam::DMat3;
use mesobake_bake::surface::curvature::VertexCurvature;
use mesobake_bake::surface::shell::Shell;
use mesobake_bake::vdm::Relief;
use mesobake_core::effect::Effect;
use mesobake_core::error::Result;
use mesobake_core::quality::ShadowMethod;
use mesobake_package::vdm::VdmQuery;
use mesobake_render::shot::Shot;
use mesobake_render::vdm_renderer::{TopFace, prepare_top_faces, shadow_tolerance, top_depth};

/// The VDM pipeline's shader (`shaders/vdm_preview.wgsl`), after `COMMON`.
pub(super) const SHADER: &str = include_str!("../../../shaders/vdm_preview.wgsl");

/// The complete WGSL source of the VDM pipeline.
pub fn source() -> String {
    format!("{COMMON}\n{SHADER}")
}

/// The shader's `Curvature`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CurvatureRecord {
    k: [f32; 4],
    dir_max: [f32; 4],
    dir_min: [f32; 4],
}

/// The shader's `Face`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FaceRecord {
    corners: [[f32; 4]; 3],
    uv: [[f32; 4]; 3],
    to_vdm: [[f32; 4]; 3],
    from_vdm: [[f32; 4]; 3],
    curvature: [CurvatureRecord; 3],
}

/// The shader's `Vdm`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct VdmUniform {
    size: [u32; 2],
    n_theta: u32,
    n_phi: u32,
    n_curvature: u32,
    rank: u32,
    mvm_rank: u32,
    shadows: u32,
    c_min: f32,
    c_max: f32,
    depth: f32,
    shadow_tolerance: f32,
    albedo: [f32; 4],
    refine_texels: u32,
    top_depth: f32,
    shell_shadows: u32,
    padding: u32,
}

/// One corner of a top triangle as the vertex stage reads it.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct VdmVertex {
    position: [f32; 3],
    bary: [f32; 3],
    face: u32,
}

impl VdmVertex {
    /// The vertex buffer's layout.
    pub(super) const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<VdmVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Uint32],
    };
}

fn vec4(v: glam::DVec3) -> [f32; 4] {
    v.extend(0.0).as_vec4().to_array()
}

fn rows(m: DMat3) -> [[f32; 4]; 3] {
    [0, 1, 2].map(|r| vec4(m.row(r)))
}

fn curvature_record(c: &VertexCurvature) -> CurvatureRecord {
    CurvatureRecord {
        k: [c.k_max as f32, c.k_min as f32, 0.0, 0.0],
        dir_max: vec4(c.dir_max),
        dir_min: vec4(c.dir_min),
    }
}

fn face_record(f: &TopFace) -> FaceRecord {
    FaceRecord {
        corners: f.triangle.corners.map(vec4),
        uv: f.triangle.texture.map(vec4),
        to_vdm: rows(f.to_vdm),
        from_vdm: rows(f.from_vdm),
        curvature: f.curvature.each_ref().map(curvature_record),
    }
}

/// Whether `shot` calls for step 7, the shadow rays through the shell's other faces.
pub(super) fn shell_shadows(shot: &Shot) -> bool {
    shot.wants(Effect::Shadows) && shot.vdm_shadows == ShadowMethod::Shell
}

/// The VDM's resources on the GPU, which every VDM pass binds (group 0, bindings 0–4 and
/// 11–15 of `vdm_preview.wgsl`), and its top triangles' vertices.
pub(super) struct VdmBuffers {
    /// The view uniform (binding 0).
    pub(super) view: ViewBuffer,
    /// The other bindings' numbers and buffers.
    storage: Vec<(u32, wgpu::BindingType, wgpu::Buffer)>,
    /// The top triangles' corners ([`VdmVertex`]).
    pub(super) vertices: wgpu::Buffer,
    pub(super) vertex_count: u32,
    /// The package and geometry they take.
    pub(super) memory: GpuMemory,
}

impl VdmBuffers {
    /// Uploads `faces` (the shell's top surface), `query`'s factors and `relief`'s heights
    /// (the relief the VDM was baked from), with `view` and `shot`'s lights and knobs; the
    /// faces' BVH where `traced` (step 7, or other objects' shadow rays).
    pub(super) fn new(
        gpu: &Gpu,
        shot: &Shot,
        faces: &[TopFace],
        query: &VdmQuery,
        relief: Relief,
        view: ViewUniform,
        traced: bool,
    ) -> Result<VdmBuffers> {
        let records: Vec<FaceRecord> = faces.iter().map(face_record).collect();
        let vertices: Vec<VdmVertex> = faces
            .iter()
            .enumerate()
            .flat_map(|(fi, f)| {
                (0..3).map(move |c| VdmVertex {
                    position: f.triangle.corners[c].as_vec3().to_array(),
                    bary: glam::Vec3::AXES[c].to_array(),
                    face: fi as u32,
                })
            })
            .collect();
        let lights: Vec<LightRecord> = light_records(shot);
        let g = query.grid();
        let (w, h) = query.size();
        let (rank, mvm_rank) = query.ranks();
        let albedo = shot.material.albedo.map(|c| c as f32);
        // The BVH over the top faces' boxes, the boxes the CPU renderer's traversal tests
        // (one empty node where nothing traces it).
        let face_boxes: Vec<_> = match traced {
            true => faces.iter().map(TopFace::bounds).collect(),
            false => Vec::new(),
        };
        let bvh = upload_box_bvh(gpu, &face_boxes)?;
        let params = VdmUniform {
            size: [w, h],
            n_theta: g.n_theta,
            n_phi: g.n_phi,
            n_curvature: g.n_curvature,
            rank: rank as u32,
            mvm_rank: mvm_rank as u32,
            shadows: u32::from(shot.wants(Effect::Shadows)),
            c_min: g.c_min as f32,
            c_max: g.c_max as f32,
            depth: relief.depth as f32,
            shadow_tolerance: shadow_tolerance(query) as f32,
            albedo: [albedo[0], albedo[1], albedo[2], 0.0],
            refine_texels: shot.vdm_refine_texels,
            top_depth: top_depth(relief) as f32,
            shell_shadows: u32::from(shell_shadows(shot)),
            padding: 0,
        };
        let [weights, eigen, mvm] = query.factors();
        let size = |words: usize| (words * std::mem::size_of::<f32>()) as u64;
        let memory = GpuMemory {
            package: size(weights.len() + eigen.len() + mvm.len() + relief.field.heights().len()),
            material: 0,
            geometry: (std::mem::size_of_val(records.as_slice())
                + std::mem::size_of_val(vertices.as_slice())) as u64
                + bvh.bytes,
            environment: 0,
            targets: 0,
        };
        let d = &gpu.device;
        gpu.checked("uploading the VDM", || {
            let buffer =
                |label: &str, contents: &[u8], usage| init_buffer(d, label, contents, usage);
            let (u, s) = (wgpu::BufferUsages::UNIFORM, wgpu::BufferUsages::STORAGE);
            let storage = vec![
                (
                    1,
                    storage(),
                    buffer("lights", bytemuck::cast_slice(&lights), s),
                ),
                (
                    2,
                    storage(),
                    buffer("faces", bytemuck::cast_slice(&records), s),
                ),
                (3, uniform(), buffer("vdm", bytemuck::bytes_of(&params), u)),
                (
                    4,
                    storage(),
                    buffer("weights", bytemuck::cast_slice(weights), s),
                ),
                (
                    11,
                    storage(),
                    buffer("eigen", bytemuck::cast_slice(eigen), s),
                ),
                (12, storage(), buffer("mvm", bytemuck::cast_slice(mvm), s)),
                (
                    13,
                    storage(),
                    buffer("heights", bytemuck::cast_slice(relief.field.heights()), s),
                ),
                (14, storage(), bvh.nodes.clone()),
                (15, storage(), bvh.primitives.clone()),
            ];
            VdmBuffers {
                view: ViewBuffer::new(d, view, &shot.camera),
                storage,
                vertices: buffer(
                    "top triangles",
                    bytemuck::cast_slice(&vertices),
                    wgpu::BufferUsages::VERTEX,
                ),
                vertex_count: vertices.len() as u32,
                memory,
            }
        })
    }

    /// The layout entries of the VDM's bindings with their buffers.
    pub(super) fn entries(&self) -> Vec<(wgpu::BindGroupLayoutEntry, wgpu::BindingResource<'_>)> {
        let frag = wgpu::ShaderStages::FRAGMENT;
        let view = (
            layout_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT, uniform()),
            self.view.buffer.as_entire_binding(),
        );
        let rest = self.storage.iter().map(|(binding, kind, buffer)| {
            (
                layout_entry(*binding, frag, *kind),
                buffer.as_entire_binding(),
            )
        });
        std::iter::once(view).chain(rest).collect()
    }
}

/// A height-field scene ready to render with the VDM real-time pipeline.
pub struct VdmPreview<'g> {
    gpu: &'g Gpu,
    pipeline: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
    buffers: VdmBuffers,
    target: Target,
    memory: GpuMemory,
}

impl<'g> VdmPreview<'g> {
    /// Uploads `shell`'s top surface, `query`'s factors and `relief`'s heights (the relief
    /// the VDM was baked from) and builds the pipeline that renders `shot`.
    pub fn new(
        gpu: &'g Gpu,
        shot: &Shot,
        shell: &Shell,
        query: &VdmQuery,
        relief: Relief,
    ) -> Result<VdmPreview<'g>> {
        let target = Target::new(gpu, shot.camera.width, shot.camera.height)?;
        let faces = prepare_top_faces(shell, relief.depth);
        let view = view_uniform(shot, faces.iter().flat_map(|f| f.triangle.corners));
        let traced = shell_shadows(shot);
        let buffers = VdmBuffers::new(gpu, shot, &faces, query, relief, view, traced)?;
        let memory = GpuMemory {
            targets: target.bytes(),
            ..buffers.memory
        };
        let d = &gpu.device;
        let (pipeline, group) = gpu.checked("building the VDM pipeline", || {
            let (layout, group) = bind_group(d, "vdm", &buffers.entries());
            let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("vdm preview"),
                source: wgpu::ShaderSource::Wgsl(source().into()),
            });
            let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("vdm preview"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = triangle_pipeline(
                d,
                "vdm preview",
                &pipeline_layout,
                &module,
                VdmVertex::LAYOUT,
            );
            (pipeline, group)
        })?;
        Ok(VdmPreview {
            gpu,
            pipeline,
            group,
            buffers,
            target,
            memory,
        })
    }
}

impl RealtimePipeline for VdmPreview<'_> {
    fn gpu(&self) -> &Gpu {
        self.gpu
    }

    fn target(&self) -> &Target {
        &self.target
    }

    fn submit_frame(&self, read_back: bool) {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = self.target.pass(&mut encoder, "vdm preview");
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            pass.set_vertex_buffer(0, self.buffers.vertices.slice(..));
            pass.draw(0..self.buffers.vertex_count, 0..1);
        }
        if read_back {
            self.target.copy_out(&mut encoder);
        }
        self.gpu.queue.submit([encoder.finish()]);
    }

    fn set_subpixel(&self, offset: [f64; 2]) {
        self.buffers.view.set_subpixel(self.gpu, offset);
    }

    /// GPU memory per kind of resource: the package (factors and heights), the geometry
    /// (top faces, their vertices and BVH) and the targets.
    fn memory(&self) -> GpuMemory {
        self.memory
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The VDM pipeline's records are laid out as their structs in `vdm_preview.wgsl`.
    #[test]
    fn the_vdm_records_are_their_wgsl_structs() {
        let source = source();
        let curvature = rust_layout!(CurvatureRecord {
            k,
            dir_max,
            dir_min
        });
        assert_twin(&source, "Curvature", curvature);
        let face = rust_layout!(FaceRecord {
            corners,
            uv,
            to_vdm,
            from_vdm,
            curvature
        });
        assert_twin(&source, "Face", face);
        let vdm = rust_layout!(VdmUniform {
            size,
            n_theta,
            n_phi,
            n_curvature,
            rank,
            mvm_rank,
            shadows,
            c_min,
            c_max,
            depth,
            shadow_tolerance,
            albedo,
            refine_texels,
            top_depth,
            shell_shadows
        });
        assert_twin(&source, "Vdm", vdm);
    }
}

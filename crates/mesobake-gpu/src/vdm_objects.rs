//! A VDM object among several in the preview (`shaders/vdm_objects.wgsl`): its top
//! triangles drawn into fragment targets of its own under a depth test of their own (the
//! nearest fragment that is not a silhouette, as the one-object VDM pipeline keeps it), the
//! hit of each kept fragment merged into the hit targets every object shares (the nearest
//! hit among objects), then the full-screen passes every object runs: the shadow-ray starts
//! and the occlusion of other objects' shadow rays (with shadows), and the shading of the
//! pixels it won. Its specification is [`mesobake_render::objects`] composing
//! [`mesobake_render::vdm_renderer`].

use super::bindings::{bind_group, layout_entry, storage_read_write, texture_2d};
use super::gpu::Gpu;
use super::object_passes::{FullScreenStage, SharedTargets};
use super::resources::GpuMemory;
use super::target::{DrawState, PassStart, Target, pixel_target, render_pass, target_pipeline};
use super::variant::{COMMON, HIT_TARGETS, OBJECTS_OFF, OBJECTS_ON};
use super::vdm_pipeline::{SHADER, VdmBuffers, VdmVertex, shell_shadows};
use super::view::view_uniform;
use mesobake_bake::surface::shell::Shell;
use mesobake_bake::vdm::Relief;
use mesobake_core::error::Result;
use mesobake_package::vdm::VdmQuery;
use mesobake_render::shot::Shot;
use mesobake_render::vdm_renderer::prepare_top_faces;

const OBJECTS: &str = include_str!("../../../shaders/vdm_objects.wgsl");

/// The complete WGSL source of a VDM object among several, with the occlusion between
/// objects where `occluders`.
pub fn objects_source(occluders: bool) -> String {
    let objects = if occluders { OBJECTS_ON } else { OBJECTS_OFF };
    format!("{COMMON}\n{SHADER}\n{HIT_TARGETS}\n{OBJECTS}\n{objects}")
}

/// The fragments every VDM object keeps per pixel before its merge (`fragment_points`,
/// `fragment_barys` and their depth buffer), shared by the VDM objects of a scene in turn.
pub(super) struct FragmentTargets {
    points: wgpu::TextureView,
    barys: wgpu::TextureView,
    depth: wgpu::TextureView,
    /// GPU bytes of the three.
    pub(super) bytes: u64,
}

impl FragmentTargets {
    /// Targets the size of `target`.
    pub(super) fn new(gpu: &Gpu, target: &Target) -> FragmentTargets {
        FragmentTargets {
            points: pixel_target(gpu, target, "vdm fragment points"),
            barys: pixel_target(gpu, target, "vdm fragment barycentrics"),
            depth: target.depth_buffer(gpu),
            bytes: 2 * super::target::pixel_target_bytes(target) + target.depth_bytes(),
        }
    }
}

/// The entries binding `views` as 2D textures from binding `first` on.
fn textures<'a>(
    first: u32,
    views: &[&'a wgpu::TextureView],
) -> Vec<(wgpu::BindGroupLayoutEntry, wgpu::BindingResource<'a>)> {
    (first..)
        .zip(views)
        .map(|(b, &view)| {
            (
                layout_entry(b, wgpu::ShaderStages::FRAGMENT, texture_2d()),
                wgpu::BindingResource::TextureView(view),
            )
        })
        .collect()
}

/// What a VDM object is drawn from.
pub(super) struct VdmUpload<'a> {
    /// The shot with the object's material.
    pub(super) shot: &'a Shot,
    /// The object's shell, whose top surface is drawn.
    pub(super) shell: &'a Shell,
    /// Its VDM.
    pub(super) query: &'a VdmQuery,
    /// The relief the VDM was baked from.
    pub(super) relief: Relief<'a>,
}

/// One VDM object's pipelines and the bind groups they draw with.
pub(super) struct VdmObject {
    buffers: VdmBuffers,
    /// `fs_fragment`: its nearest fragments into the fragment targets.
    fragment: (wgpu::RenderPipeline, wgpu::BindGroup),
    /// `fs_merge`: their hits into the shared hit targets.
    merge: (wgpu::RenderPipeline, wgpu::BindGroup),
    /// `fs_shade`: the pixels it won.
    shade: (wgpu::RenderPipeline, wgpu::BindGroup),
    /// With occluders, `fs_start` (drawn with the shading group) and `fs_occlude`.
    occlusion: Option<(wgpu::RenderPipeline, wgpu::RenderPipeline, wgpu::BindGroup)>,
    /// What its resources take on the GPU (the shared targets not counted).
    pub(super) memory: GpuMemory,
}

impl VdmObject {
    /// Uploads object number `index` and builds its pipelines, drawing into `shared` and
    /// `fragments`.
    pub(super) fn new(
        gpu: &Gpu,
        object: &VdmUpload,
        index: usize,
        shared: &SharedTargets,
        fragments: &FragmentTargets,
    ) -> Result<VdmObject> {
        let VdmUpload {
            shot,
            shell,
            query,
            relief,
        } = *object;
        let faces = prepare_top_faces(shell, relief.depth);
        let view = view_uniform(shot, shared.corners.iter().copied()).of_object(index);
        let occlusion = shared.occlusion;
        let traced = shell_shadows(shot) || occlusion.is_some();
        let buffers = VdmBuffers::new(gpu, shot, &faces, query, relief, view, traced)?;
        let d = &gpu.device;
        gpu.checked("building a VDM object's pipelines", || {
            let frag = wgpu::ShaderStages::FRAGMENT;
            let base = buffers.entries();
            let mut merge = base.clone();
            merge.push((
                layout_entry(5, frag, storage_read_write()),
                shared.nearest_hit.as_entire_binding(),
            ));
            merge.extend(textures(16, &[&fragments.points, &fragments.barys]));
            let mut shade = base.clone();
            shade.extend(textures(6, &shared.hits.views.each_ref()));
            if let Some(o) = occlusion {
                shade.push((
                    layout_entry(10, frag, storage_read_write()),
                    o.blocked.as_entire_binding(),
                ));
            }
            let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("vdm object"),
                source: wgpu::ShaderSource::Wgsl(objects_source(occlusion.is_some()).into()),
            });
            // A pipeline of `layout`'s bindings.
            let pipeline = |label, layout: &wgpu::BindGroupLayout, vertices: &[_], state| {
                let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &[Some(layout)],
                    immediate_size: 0,
                });
                target_pipeline(d, label, &pipeline_layout, &module, vertices, state)
            };
            // A pipeline with its bind group of `entries`.
            let bound = |label, entries: &[_], vertices: &[_], state| {
                let (layout, group) = bind_group(d, label, entries);
                (pipeline(label, &layout, vertices, state), group)
            };
            let fragment = bound(
                "vdm object fragments",
                &base,
                &[Some(VdmVertex::LAYOUT)],
                DrawState {
                    entry_points: ["vs_main", "fs_fragment"],
                    cull: Some(wgpu::Face::Back),
                    depth_tested: true,
                    blend: None,
                    colour_targets: 2,
                },
            );
            let merge = bound(
                "vdm object hits",
                &merge,
                &[],
                DrawState {
                    depth_tested: true,
                    ..DrawState::full_screen("fs_merge", shared.hits.views.len())
                },
            );
            let (shade_layout, shade_group) = bind_group(d, "vdm object shading", &shade);
            let occlusion = occlusion.map(|o| {
                let start = pipeline(
                    "vdm shadow-ray starts",
                    &shade_layout,
                    &[],
                    DrawState::full_screen("fs_start", 1),
                );
                let mut occlude = shade.clone();
                occlude.extend(textures(9, &[&o.starts]));
                let (occlude, group) = bound(
                    "vdm occlusion",
                    &occlude,
                    &[],
                    DrawState::full_screen("fs_occlude", 0),
                );
                (start, occlude, group)
            });
            let shading = pipeline(
                "vdm object shading",
                &shade_layout,
                &[],
                DrawState::full_screen("fs_shade", 1),
            );
            let memory = buffers.memory;
            VdmObject {
                buffers,
                fragment,
                merge,
                shade: (shading, shade_group),
                occlusion,
                memory,
            }
        })
    }

    /// Records the pass that keeps its nearest fragments in `fragments`.
    pub(super) fn draw_fragments(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        fragments: &FragmentTargets,
    ) {
        let colours = [&fragments.points, &fragments.barys];
        let mut pass = render_pass(
            encoder,
            "vdm object fragments",
            &colours,
            &fragments.depth,
            PassStart::Clear,
        );
        pass.set_pipeline(&self.fragment.0);
        pass.set_bind_group(0, &self.fragment.1, &[]);
        pass.set_vertex_buffer(0, self.buffers.vertices.slice(..));
        pass.draw(0..self.buffers.vertex_count, 0..1);
    }

    /// Draws the merge of its kept fragments' hits into a pass of the shared hit targets.
    pub(super) fn draw_merge(&self, pass: &mut wgpu::RenderPass) {
        pass.set_pipeline(&self.merge.0);
        pass.set_bind_group(0, &self.merge.1, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Draws its full-screen pass of `stage` (nothing for the occlusion stages without
    /// occluders).
    pub(super) fn draw(&self, pass: &mut wgpu::RenderPass, stage: FullScreenStage) {
        let (pipeline, group) = match (stage, &self.occlusion) {
            (FullScreenStage::Shade, _) => (&self.shade.0, &self.shade.1),
            (FullScreenStage::Start, Some((start, _, _))) => (start, &self.shade.1),
            (FullScreenStage::Occlude, Some((_, occlude, group))) => (occlude, group),
            _ => return,
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Moves the next frames' rays to `offset` in each pixel.
    pub(super) fn set_subpixel(&self, gpu: &Gpu, offset: [f64; 2]) {
        self.buffers.view.set_subpixel(gpu, offset);
    }
}

//! The render target every real-time pipeline draws (or, from a compute pass, writes) into:
//! a linear `rgba32float` colour texture (alpha > 0: a hit; translucent media store 1 − transmittance there) with a `depth32float` depth buffer, and the buffer it is read
//! back through as an [`Image`].

use super::gpu::Gpu;
use mesobake_core::error::{Error, Result};
use mesobake_render::image::Image;

/// The colour target's format.
const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The depth buffer's format.
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Bytes per texel of the colour target.
const COLOUR_TEXEL: u32 = 16;

/// A triangle-list pipeline that draws into a [`Target`]: back faces culled (fronts
/// counter-clockwise), depth tested (less) and written, the colour stored as the fragment
/// returns it.
pub fn triangle_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    vertices: wgpu::VertexBufferLayout,
) -> wgpu::RenderPipeline {
    let state = DrawState {
        entry_points: ["vs_main", "fs_main"],
        cull: Some(wgpu::Face::Back),
        depth_tested: true,
        blend: None,
        colour_targets: 1,
    };
    target_pipeline(device, label, layout, module, &[Some(vertices)], state)
}

/// How a [`target_pipeline`] draws.
pub struct DrawState {
    /// The vertex and fragment entry points.
    pub entry_points: [&'static str; 2],
    /// The faces culled (fronts counter-clockwise).
    pub cull: Option<wgpu::Face>,
    /// Depth tested (less) and written, or neither.
    pub depth_tested: bool,
    /// How the fragment's colour meets the target's (`None`: replaces it).
    pub blend: Option<wgpu::BlendState>,
    /// How many `rgba32float` colours the fragment writes: 1 for the target's colour, more
    /// for a pass into [`HitTargets`].
    pub colour_targets: usize,
}

impl DrawState {
    /// One triangle over the whole image (`vs_fullscreen` of `hit_targets.wgsl`) running
    /// `fragment` into `colour_targets` colours, no depth test.
    pub fn full_screen(fragment: &'static str, colour_targets: usize) -> DrawState {
        DrawState {
            entry_points: ["vs_fullscreen", fragment],
            cull: None,
            depth_tested: false,
            blend: None,
            colour_targets,
        }
    }
}

/// A triangle-list pipeline that draws into a [`Target`] as `state` says.
pub fn target_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    buffers: &[Option<wgpu::VertexBufferLayout>],
    state: DrawState,
) -> wgpu::RenderPipeline {
    let [vertex, fragment] = state.entry_points;
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: state.cull,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(state.depth_tested),
            depth_compare: Some(if state.depth_tested {
                wgpu::CompareFunction::Less
            } else {
                wgpu::CompareFunction::Always
            }),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment),
            compilation_options: Default::default(),
            targets: &vec![
                Some(wgpu::ColorTargetState {
                    format: COLOUR_FORMAT,
                    blend: state.blend,
                    write_mask: wgpu::ColorWrites::ALL,
                });
                state.colour_targets
            ],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A colour and depth target with its read-back buffer.
pub struct Target {
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
}

impl Target {
    /// A `width` × `height` target, refused when the adapter cannot hold it.
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Result<Target> {
        let max_side = gpu.device.limits().max_texture_dimension_2d;
        if width > max_side || height > max_side {
            return Err(Error::Gpu(format!(
                "a {width}×{height} image exceeds this adapter's limit of {max_side} pixels per side"
            )));
        }
        let d = &gpu.device;
        let texture = |format, usage| image_texture(d, "target", (width, height), format, usage);
        let colour = texture(
            COLOUR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT)
            .create_view(&Default::default());
        let padded_row =
            (width * COLOUR_TEXEL).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: padded_row as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Ok(Target {
            colour_view: colour.create_view(&Default::default()),
            colour,
            depth,
            readback,
            padded_row,
            width,
            height,
        })
    }

    /// GPU bytes of the target (colour, depth and read-back).
    pub fn bytes(&self) -> u64 {
        self.width as u64 * self.height as u64 * (COLOUR_TEXEL as u64 + 4) + self.readback.size()
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The colour texture's view (for compute passes that write it as a storage texture).
    pub fn colour_view(&self) -> &wgpu::TextureView {
        &self.colour_view
    }

    /// A render pass that clears the target to transparent black and the depth to 1.
    pub fn pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
    ) -> wgpu::RenderPass<'e> {
        self.pass_into(encoder, label, &[&self.colour_view])
    }

    /// A render pass into `colours` (cleared to transparent black; none for a pass that only
    /// writes storage) with the target's depth (cleared to 1).
    pub fn pass_into<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        colours: &[&wgpu::TextureView],
    ) -> wgpu::RenderPass<'e> {
        render_pass(encoder, label, colours, &self.depth, PassStart::Clear)
    }

    /// A render pass into `colours` and the target's depth as an earlier pass left them.
    pub fn pass_resuming<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        colours: &[&wgpu::TextureView],
    ) -> wgpu::RenderPass<'e> {
        render_pass(encoder, label, colours, &self.depth, PassStart::Resume)
    }

    /// A depth buffer the size of the target, for passes depth-tested apart from it.
    pub fn depth_buffer(&self, gpu: &Gpu) -> wgpu::TextureView {
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
        image_texture(&gpu.device, "depth", self.size(), DEPTH_FORMAT, usage)
            .create_view(&Default::default())
    }

    /// GPU bytes of one [`Target::depth_buffer`].
    pub fn depth_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * 4
    }

    /// Records the copy of the colour target into the read-back buffer.
    pub fn copy_out(&self, encoder: &mut wgpu::CommandEncoder) {
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

    /// Reads back what [`Target::copy_out`] copied, once the submission holding it is done.
    pub fn read(&self, gpu: &Gpu) -> Result<Image> {
        read_mapped(gpu, &self.readback, |data| {
            let mut image = Image::new(self.width, self.height);
            for (y, row) in data.chunks_exact(self.padded_row as usize).enumerate() {
                let texels: &[[f32; 4]] =
                    bytemuck::cast_slice(&row[..(self.width * COLOUR_TEXEL) as usize]);
                for (x, t) in texels.iter().enumerate() {
                    let i = y * self.width as usize + x;
                    image.mask[i] = t[3] > 0.0;
                    image.rgb[i] = [t[0], t[1], t[2]];
                }
            }
            image
        })
    }
}

/// How a [`render_pass`] finds its attachments.
#[derive(Clone, Copy)]
pub enum PassStart {
    /// Colours cleared to transparent black, depth to 1.
    Clear,
    /// As an earlier pass left them.
    Resume,
}

/// A render pass into `colours` (none for a pass that only writes storage) and `depth`,
/// starting as `start` says; both are stored for later passes.
pub fn render_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colours: &[&wgpu::TextureView],
    depth: &wgpu::TextureView,
    start: PassStart,
) -> wgpu::RenderPass<'e> {
    let (colour_load, depth_load) = match start {
        PassStart::Clear => (
            wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            wgpu::LoadOp::Clear(1.0),
        ),
        PassStart::Resume => (wgpu::LoadOp::Load, wgpu::LoadOp::Load),
    };
    let colour_attachments: Vec<_> = colours
        .iter()
        .map(|&view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: colour_load,
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect();
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &colour_attachments,
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: depth_load,
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        ..Default::default()
    })
}

/// A 2D texture of one level, `size` pixels.
fn image_texture(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
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
}

/// The per-pixel targets a hit pass writes and a shading pass reads (`rgba32float` each, the
/// target's size; what each holds is the shader's to say).
pub struct HitTargets {
    /// The texture views, in the fragment's output order.
    pub views: [wgpu::TextureView; 3],
    /// GPU bytes of the three.
    pub bytes: u64,
}

impl HitTargets {
    /// Three targets the size of `target`.
    pub fn new(gpu: &Gpu, target: &Target) -> HitTargets {
        HitTargets {
            views: std::array::from_fn(|_| pixel_target(gpu, target, "hit target")),
            bytes: 3 * pixel_target_bytes(target),
        }
    }
}

/// An `rgba32float` texture the size of `target` that a pass draws into and a later pass
/// reads.
pub fn pixel_target(gpu: &Gpu, target: &Target, label: &str) -> wgpu::TextureView {
    image_texture(
        &gpu.device,
        label,
        target.size(),
        COLOUR_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    )
    .create_view(&Default::default())
}

/// GPU bytes of one [`pixel_target`] of `target`.
pub fn pixel_target_bytes(target: &Target) -> u64 {
    let (width, height) = target.size();
    u64::from(width) * u64::from(height) * u64::from(COLOUR_TEXEL)
}

/// Maps `buffer` (MAP_READ) once the submissions writing it are done, hands its bytes to
/// `f` and unmaps it.
pub fn read_mapped<T>(gpu: &Gpu, buffer: &wgpu::Buffer, f: impl FnOnce(&[u8]) -> T) -> Result<T> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu("read-back was never mapped".into()))?
        .map_err(|e| Error::Gpu(format!("reading back: {e}")))?;
    let value = {
        let data = slice
            .get_mapped_range()
            .map_err(|e| Error::Gpu(format!("reading back: {e}")))?;
        f(&data)
    };
    buffer.unmap();
    Ok(value)
}

//! An engine's-eye example of loading mesobake packages: it depends on `mesobake-package`
//! alone (not on mesobake), uploads a package's sections to wgpu textures exactly as they are
//! stored, and computes the GDM of the tile's top layer along one direction bin on the GPU
//! from them — the paper-svd factors decoded and multiplied, or the occupancy texture
//! marched — then shades a depth view of the tiled mesostructure.

use mesobake_package::grid::boundary_distance;
use mesobake_package::manifest::{GdmInfo, TexelFormat, Texture, TextureDimension};
use mesobake_package::{OCCUPANCY_SECTION, Package};
use std::collections::HashMap;
use wgpu::util::DeviceExt;

/// The shaders' parameters (`Params` in common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 4],
    bin: [u32; 4],
    dir: [f32; 4],
    scale_w: [f32; 4],
    bias_w: [f32; 4],
    scale_e: [f32; 4],
    bias_e: [f32; 4],
}

/// A GPU device to render packages with.
pub struct Viewer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The adapter's name.
    pub adapter: String,
}

/// Texels per workgroup side.
const GROUP: u32 = 8;

impl Viewer {
    /// Opens wgpu's default adapter, or the first whose name contains `name`.
    pub fn open(name: Option<&str>) -> Result<Viewer, String> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let adapter = match name {
            Some(name) => adapters.into_iter().find(|a| {
                a.get_info()
                    .name
                    .to_lowercase()
                    .contains(&name.to_lowercase())
            }),
            None => pollster::block_on(instance.request_adapter(&Default::default())).ok(),
        }
        .ok_or("no GPU adapter (on Debian without a GPU: install mesa-vulkan-drivers)")?;
        let (device, queue) = pollster::block_on(adapter.request_device(&Default::default()))
            .map_err(|e| format!("opening the device: {e}"))?;
        Ok(Viewer {
            device,
            queue,
            adapter: adapter.get_info().name,
        })
    }

    /// Uploads section `name` of `package` as the texture its manifest describes.
    fn upload(&self, package: &Package, name: &str) -> wgpu::TextureView {
        let section = package.manifest().sections.iter().find(|s| s.name == name);
        let texture: Texture = section.expect("validated").texture;
        let (dimension, depth) = match texture.dimension {
            TextureDimension::D3 => (wgpu::TextureDimension::D3, texture.depth),
            _ => (wgpu::TextureDimension::D2, 1),
        };
        let format = match texture.format {
            TexelFormat::R32float => wgpu::TextureFormat::R32Float,
            TexelFormat::Rg32float => wgpu::TextureFormat::Rg32Float,
            TexelFormat::Rgba32float => wgpu::TextureFormat::Rgba32Float,
            TexelFormat::R16float => wgpu::TextureFormat::R16Float,
            TexelFormat::Rg16float => wgpu::TextureFormat::Rg16Float,
            TexelFormat::Rgba16float => wgpu::TextureFormat::Rgba16Float,
            TexelFormat::R8unorm => wgpu::TextureFormat::R8Unorm,
            TexelFormat::Rg8unorm => wgpu::TextureFormat::Rg8Unorm,
            TexelFormat::Rgba8unorm => wgpu::TextureFormat::Rgba8Unorm,
            TexelFormat::R8uint => wgpu::TextureFormat::R8Uint,
            TexelFormat::R32uint => wgpu::TextureFormat::R32Uint,
        };
        let texture = self.device.create_texture_with_data(
            &self.queue,
            &wgpu::TextureDescriptor {
                label: Some(name),
                size: wgpu::Extent3d {
                    width: texture.width,
                    height: texture.height,
                    depth_or_array_layers: depth,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension,
                format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            package.section(name).expect("validated"),
        );
        texture.create_view(&Default::default())
    }

    /// The GDM of the top layer's voxel centres (i, j, Z − 1) along direction bin (a, b),
    /// row by row: the distance to the mesostructure, `None` for an escape.
    pub fn top_layer(&self, package: &Package, a: u32, b: u32) -> Result<Vec<Option<f32>>, String> {
        let (dims, dirs) = (package.dims(), package.dirs());
        if a >= dirs.n_theta || b >= dirs.n_phi {
            return Err(format!(
                "direction bin {a},{b} is off the {}x{} grid",
                dirs.n_theta, dirs.n_phi
            ));
        }
        let v = dirs.vector(a, b);
        let params = Params {
            dims: [dims.x, dims.y, dims.z, 0],
            bin: [a, b, 0, 0],
            dir: [v[0] as f32, v[1] as f32, v[2] as f32, 0.0],
            ..Default::default()
        };
        let texels = (dims.x * dims.y) as u64;
        let values = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("values"),
            size: texels * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let groups = [dims.x.div_ceil(GROUP), dims.y.div_ceil(GROUP)];
        // Each entry point is compiled once, however many texture groups it runs over.
        let mut pipelines: HashMap<&str, wgpu::ComputePipeline> = HashMap::new();
        let mut dispatch = |shader: &str,
                            entry: &'static str,
                            params: Params,
                            textures: &[&wgpu::TextureView],
                            integer: bool| {
            let pipeline = pipelines.entry(entry).or_insert_with(|| {
                let source = format!("{}\n{shader}", include_str!("common.wgsl"));
                let module = self
                    .device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some(entry),
                        source: wgpu::ShaderSource::Wgsl(source.into()),
                    });
                self.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&self.layout(textures.len(), integer)),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            });
            let uniform = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("params"),
                    contents: bytemuck::bytes_of(&params),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let globals = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: values.as_entire_binding(),
                    },
                ],
            });
            let entries: Vec<_> = textures
                .iter()
                .enumerate()
                .map(|(n, view)| wgpu::BindGroupEntry {
                    binding: n as u32,
                    resource: wgpu::BindingResource::TextureView(view),
                })
                .collect();
            let textures = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(1),
                entries: &entries,
            });
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &globals, &[]);
            pass.set_bind_group(1, &textures, &[]);
            pass.dispatch_workgroups(groups[0], groups[1], 1);
        };
        match &package.manifest().gdm {
            Some(gdm) => {
                for (g, (w, e)) in gdm
                    .weights
                    .sections
                    .iter()
                    .zip(&gdm.eigen.sections)
                    .enumerate()
                {
                    let p = svd_group_params(params, gdm, g);
                    let (w, e) = (self.upload(package, w), self.upload(package, e));
                    dispatch(include_str!("svd.wgsl"), "svd_group", p, &[&w, &e], false);
                }
                // The escape pass reads only the accumulated values: no textures.
                let mut escape = params;
                escape.dir[3] = (1.0 - gdm.accuracy.escape_margin)
                    * boundary_distance(dims, &dirs, dims.z - 1, a);
                dispatch(include_str!("svd.wgsl"), "svd_escape", escape, &[], false);
            }
            None => {
                let occupancy = self.upload(package, OCCUPANCY_SECTION);
                dispatch(
                    include_str!("march.wgsl"),
                    "march",
                    params,
                    &[&occupancy],
                    true,
                );
            }
        }
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: texels * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_buffer_to_buffer(&values, 0, &readback, 0, texels * 4);
        self.queue.submit([encoder.finish()]);
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| format!("waiting for the GPU: {e}"))?;
        let data = slice
            .get_mapped_range()
            .map_err(|e| format!("reading back: {e}"))?;
        let floats: &[f32] = bytemuck::cast_slice(&data);
        Ok(floats.iter().map(|&d| (d >= 0.0).then_some(d)).collect())
    }

    /// The bind group layouts: the parameters and values (group 0), then `textures`
    /// textures, 3D then 2D, unfilterable float or (`integer`) unsigned (group 1).
    fn layout(&self, textures: usize, integer: bool) -> wgpu::PipelineLayout {
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let globals = self
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: None,
                entries: &[
                    buffer(0, wgpu::BufferBindingType::Uniform),
                    buffer(1, wgpu::BufferBindingType::Storage { read_only: false }),
                ],
            });
        let sample_type = if integer {
            wgpu::TextureSampleType::Uint
        } else {
            wgpu::TextureSampleType::Float { filterable: false }
        };
        let entries: Vec<_> = (0..textures as u32)
            .map(|binding| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Texture {
                    sample_type,
                    view_dimension: if binding == 0 {
                        wgpu::TextureViewDimension::D3
                    } else {
                        wgpu::TextureViewDimension::D2
                    },
                    multisampled: false,
                },
                count: None,
            })
            .collect();
        let textures = self
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: None,
                entries: &entries,
            });
        self.device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: None,
                bind_group_layouts: &[Some(&globals), Some(&textures)],
                immediate_size: 0,
            })
    }
}

/// `params` for texture group `g` of the factors: its channel count and decode constants.
fn svd_group_params(params: Params, gdm: &GdmInfo, g: usize) -> Params {
    let first = 4 * g;
    let channels = (gdm.rank as usize - first).min(4);
    let pick = |v: &[f32]| std::array::from_fn(|c| if c < channels { v[first + c] } else { 0.0 });
    Params {
        dims: [
            params.dims[0],
            params.dims[1],
            params.dims[2],
            channels as u32,
        ],
        scale_w: pick(&gdm.weights.scale),
        bias_w: pick(&gdm.weights.bias),
        scale_e: pick(&gdm.eigen.scale),
        bias_e: pick(&gdm.eigen.bias),
        ..params
    }
}

/// The colour of a top-layer texel whose GDM along a direction with |cos θ| = `cos` is
/// `distance`: grey by depth below the top plane (white at the top, black `depth` voxels
/// down), escapes dark blue.
pub fn shade(distance: Option<f32>, cos: f32, depth: u32) -> [u8; 3] {
    match distance {
        Some(d) => {
            let below = 0.5 + d * cos;
            let grey = (1.0 - below / depth as f32).clamp(0.0, 1.0);
            [(grey * 255.0).round() as u8; 3]
        }
        None => [16, 24, 64],
    }
}

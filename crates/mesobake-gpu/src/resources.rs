//! What the preview uploads: a package's GDM factors (its binary sections, as they are laid
//! out), the material volume and the shell's prisms, with the GPU memory each takes.
//!
//! Factor textures: the component groups of four that fill an `rgba` texel are stacked in
//! one texture per factor (weight maps along depth, one Nφ slab per group; eigenmaps along
//! height, one Nθ band per group); the last group of a rank that is not a multiple of four
//! has its own, narrower texture. Each section is copied byte for byte into its slab.

use super::gpu::Gpu;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use mesobake_bake::mesostructure::material::MaterialVolume;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::TexelFormat;
use mesobake_core::error::{Error, Result};
use mesobake_render::gi_shading::GiShading;
use mesobake_render::prepared_prism::PreparedPrism;
use serde::Serialize;
use wgpu::util::DeviceExt;

/// Bytes of GPU memory per kind of resource.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GpuMemory {
    /// The package: factor textures, decode table and parameters.
    pub package: u64,
    /// Material volume: normal and albedo textures.
    pub material: u64,
    /// Shell: vertex buffer and per-prism data.
    pub geometry: u64,
    /// Environment lighting: the RTV, the incident light per vertex, per-prism triangles.
    pub environment: u64,
    /// Colour, depth, hit and read-back targets.
    pub targets: u64,
}

impl GpuMemory {
    /// The sum.
    pub fn total(&self) -> u64 {
        self.package + self.material + self.geometry + self.environment + self.targets
    }
}

/// The GDM parameters the shader reads (`GdmParams` in `shaders/gdm_preview.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GdmParams {
    dims: [u32; 4],
    n_phi: u32,
    full_groups: u32,
    has_tail: u32,
    margin: f32,
}

/// A package on the GPU.
pub struct GpuPackage {
    /// Group 1 of the pipeline.
    pub bind_group: wgpu::BindGroup,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// The material volume on the GPU.
pub struct GpuMaterial {
    /// Group 2 of the pipeline.
    pub bind_group: wgpu::BindGroup,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// The environment lighting on the GPU (group 3 of the environment variants).
pub struct GpuEnvironment {
    /// Group 3 of the pipeline.
    pub bind_group: wgpu::BindGroup,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// The RTV's grids (`GiParams` in `shaders/gi_on.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GiParams {
    dims: [u32; 4],
    dirs: [u32; 4],
}

/// A prism's base triangle (`GiPrism` in `shaders/gi_on.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GiPrismRecord {
    vertices: [u32; 4],
    uv01: [f32; 4],
    uv2: [f32; 4],
}

/// Uploads what the environment variant reads: `package`'s RTV sections as they are, and
/// from `shading` (the CPU twin's, read from the same package: the same tables on both
/// sides) the incident light at each base vertex and each prism's base triangle in texture
/// space.
pub fn upload_environment(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    shading: &GiShading,
    package: &Package,
) -> Result<GpuEnvironment> {
    use mesobake_bake::package::gi::{RTV_EIGEN, RTV_INDEX, RTV_WEIGHTS};
    let incident: Vec<f32> = shading
        .incident()
        .iter()
        .flatten()
        .flatten()
        .map(|&v| v as f32)
        .collect();
    let prisms: Vec<GiPrismRecord> = shading
        .prisms()
        .iter()
        .map(|(v, uv)| {
            let uv = uv.map(|uv| uv.as_vec2());
            GiPrismRecord {
                vertices: [v[0], v[1], v[2], 0],
                uv01: [uv[0].x, uv[0].y, uv[1].x, uv[1].y],
                uv2: [uv[2].x, uv[2].y, 0.0, 0.0],
            }
        })
        .collect();
    let (dims, dirs) = (package.dims(), package.dirs());
    let info = package.manifest().gi.as_ref().ok_or_else(|| {
        Error::Package("environment lighting needs a package with radiance transfer".into())
    })?;
    let params = GiParams {
        dims: [dims.x, dims.y, dims.z, info.samples],
        dirs: [dirs.n_theta, dirs.n_phi, info.compression.rank as u32, 0],
    };
    let section = |name| package.section(name).expect("checked by Package::parse");
    let max = gpu.device.limits().max_storage_buffer_binding_size;
    let storage = |label: &str, bytes: &[u8]| -> Result<wgpu::Buffer> {
        if bytes.len() as u64 > max {
            return Err(Error::Gpu(format!(
                "{label}: {} bytes exceed this adapter's storage buffer limit of {max} bytes",
                bytes.len()
            )));
        }
        // A binding may not be empty.
        let padded;
        let contents = if bytes.is_empty() {
            padded = [0u8; 4];
            &padded[..]
        } else {
            bytes
        };
        Ok(gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            }))
    };
    let weights = storage("RTV weights", section(RTV_WEIGHTS))?;
    let eigen = storage("RTV eigenfunctions", section(RTV_EIGEN))?;
    let incident_buffer = storage("incident light", bytemuck::cast_slice(&incident))?;
    let prism_buffer = storage("prism triangles", bytemuck::cast_slice(&prisms))?;
    let index = Slabs::new(
        gpu,
        "RTV sample index",
        wgpu::TextureDimension::D3,
        TexelFormat::R32uint,
        extent(dims.x, dims.y, dims.z),
    )?;
    index.write(
        gpu,
        section(RTV_INDEX),
        wgpu::Origin3d::ZERO,
        dims.y,
        dims.z,
    );
    let uniform = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("RTV grids"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
    let index_view = index.view();
    let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("environment"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&index_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: weights.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: eigen.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: incident_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: prism_buffer.as_entire_binding(),
            },
        ],
    });
    let bytes = index.bytes()
        + [&weights, &eigen, &incident_buffer, &prism_buffer, &uniform]
            .iter()
            .map(|b| b.size())
            .sum::<u64>();
    Ok(GpuEnvironment { bind_group, bytes })
}

/// The shell on the GPU: 24 vertices (8 face triangles) per prism, and the prisms.
pub struct GpuShell {
    /// Position, texture coordinate (voxels), prism and face index per vertex.
    pub vertices: wgpu::Buffer,
    /// Vertices to draw.
    pub vertex_count: u32,
    /// `Prism` records of the shader.
    pub prisms: wgpu::Buffer,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// One vertex of a face triangle.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Vertex {
    position: [f32; 3],
    texture: [f32; 3],
    prism: u32,
    face: u32,
}

impl Vertex {
    /// The vertex buffer layout (locations 0–3 of `vs_main`).
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Uint32, 3 => Uint32],
    };
}

/// The shader's `Face`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FaceRecord {
    corners: [[f32; 4]; 3],
    texture: [[f32; 4]; 3],
    plane: [f32; 4],
}

/// The shader's `Prism`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PrismRecord {
    faces: [FaceRecord; 8],
    frame: [[f32; 4]; 3],
    convex: [u32; 4],
}

fn vec4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

fn wgpu_format(f: TexelFormat) -> wgpu::TextureFormat {
    use wgpu::TextureFormat as W;
    match f {
        TexelFormat::R32float => W::R32Float,
        TexelFormat::Rg32float => W::Rg32Float,
        TexelFormat::Rgba32float => W::Rgba32Float,
        TexelFormat::R16float => W::R16Float,
        TexelFormat::Rg16float => W::Rg16Float,
        TexelFormat::Rgba16float => W::Rgba16Float,
        TexelFormat::R8unorm => W::R8Unorm,
        TexelFormat::Rg8unorm => W::Rg8Unorm,
        TexelFormat::Rgba8unorm => W::Rgba8Unorm,
        TexelFormat::R8uint => W::R8Uint,
        TexelFormat::R32uint => W::R32Uint,
    }
}

/// A texture being filled slab by slab.
struct Slabs {
    texture: wgpu::Texture,
    texel_bytes: u32,
    size: wgpu::Extent3d,
}

impl Slabs {
    fn new(
        gpu: &Gpu,
        label: &str,
        dimension: wgpu::TextureDimension,
        format: TexelFormat,
        size: wgpu::Extent3d,
    ) -> Result<Slabs> {
        let limits = gpu.device.limits();
        let max = match dimension {
            wgpu::TextureDimension::D3 => limits.max_texture_dimension_3d,
            _ => limits.max_texture_dimension_2d,
        };
        let largest = size.width.max(size.height).max(size.depth_or_array_layers);
        if largest > max {
            return Err(Error::Gpu(format!(
                "{label}: a {}×{}×{} texture exceeds this adapter's limit of {max} texels per side",
                size.width, size.height, size.depth_or_array_layers
            )));
        }
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension,
            format: wgpu_format(format),
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        Ok(Slabs {
            texture,
            texel_bytes: format.texel_bytes(),
            size,
        })
    }

    /// Copies `bytes` (a width × `rows` × `images` block, x fastest) to `origin`.
    fn write(&self, gpu: &Gpu, bytes: &[u8], origin: wgpu::Origin3d, rows: u32, images: u32) {
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin,
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.size.width * self.texel_bytes),
                rows_per_image: Some(rows),
            },
            wgpu::Extent3d {
                width: self.size.width,
                height: rows,
                depth_or_array_layers: images,
            },
        );
    }

    fn bytes(&self) -> u64 {
        self.size.width as u64
            * self.size.height as u64
            * self.size.depth_or_array_layers as u64
            * self.texel_bytes as u64
    }

    fn view(&self) -> wgpu::TextureView {
        self.texture
            .create_view(&wgpu::TextureViewDescriptor::default())
    }
}

fn extent(width: u32, height: u32, depth: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width,
        height,
        depth_or_array_layers: depth,
    }
}

/// Uploads what `package`'s codec answers GDM queries with, for the pipeline's group 1
/// (`layout`): the factors (`paper-svd`, [`upload_factors`]) or the occupancy field (an
/// `r8uint` 3D texture).
pub fn upload_package(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    package: &Package,
) -> Result<GpuPackage> {
    let Some(info) = &package.manifest().occupancy else {
        return upload_factors(gpu, layout, package);
    };
    let dims = package.dims();
    let field = Slabs::new(
        gpu,
        "occupancy",
        wgpu::TextureDimension::D3,
        TexelFormat::R8uint,
        extent(dims.x, dims.y, dims.z),
    )?;
    let bytes = package.section(&info.section).expect("validated package");
    field.write(gpu, bytes, wgpu::Origin3d::ZERO, dims.y, dims.z);
    let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("package"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&field.view()),
        }],
    });
    Ok(GpuPackage {
        bind_group,
        bytes: field.bytes(),
    })
}

/// Uploads a `paper-svd` package's factors for the pipeline's group 1 (`layout`).
fn upload_factors(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    package: &Package,
) -> Result<GpuPackage> {
    let (dims, dirs) = (package.dims(), package.dirs());
    let g = package
        .manifest()
        .gdm
        .as_ref()
        .expect("a paper-svd package");
    let rank = g.rank as usize;
    let (full_groups, has_tail) = ((rank / 4) as u32, !rank.is_multiple_of(4));
    let section_of = |name: &str| -> (&[u8], TexelFormat) {
        let info = package
            .manifest()
            .sections
            .iter()
            .find(|s| s.name == name)
            .expect("validated package");
        (
            package.section(name).expect("validated package"),
            info.texture.format,
        )
    };
    let full = TexelFormat::of(g.quantization, 4);
    let one = extent(1, 1, 1);
    let d3 = wgpu::TextureDimension::D3;
    let d2 = wgpu::TextureDimension::D2;
    let stacked = |n: u32, per: u32| if n == 0 { 1 } else { n * per };
    let (wx, wy) = if full_groups == 0 {
        (1, 1)
    } else {
        (dims.x, dims.y)
    };
    let weights_full = Slabs::new(
        gpu,
        "weight maps",
        d3,
        full,
        extent(wx, wy, stacked(full_groups, dirs.n_phi)),
    )?;
    let ez = if full_groups == 0 { 1 } else { dims.z };
    let eigen_full = Slabs::new(
        gpu,
        "eigenmaps",
        d2,
        full,
        extent(ez, stacked(full_groups, dirs.n_theta), 1),
    )?;
    for group in 0..full_groups as usize {
        let (w, _) = section_of(&g.weights.sections[group]);
        weights_full.write(
            gpu,
            w,
            wgpu::Origin3d {
                x: 0,
                y: 0,
                z: group as u32 * dirs.n_phi,
            },
            dims.y,
            dirs.n_phi,
        );
        let (e, _) = section_of(&g.eigen.sections[group]);
        eigen_full.write(
            gpu,
            e,
            wgpu::Origin3d {
                x: 0,
                y: group as u32 * dirs.n_theta,
                z: 0,
            },
            dirs.n_theta,
            1,
        );
    }
    let (weights_tail, eigen_tail) = if has_tail {
        let (w, wf) = section_of(&g.weights.sections[full_groups as usize]);
        let (e, ef) = section_of(&g.eigen.sections[full_groups as usize]);
        let wt = Slabs::new(
            gpu,
            "weight maps (last group)",
            d3,
            wf,
            extent(dims.x, dims.y, dirs.n_phi),
        )?;
        wt.write(gpu, w, wgpu::Origin3d::ZERO, dims.y, dirs.n_phi);
        let et = Slabs::new(
            gpu,
            "eigenmaps (last group)",
            d2,
            ef,
            extent(dims.z, dirs.n_theta, 1),
        )?;
        et.write(gpu, e, wgpu::Origin3d::ZERO, dirs.n_theta, 1);
        (wt, et)
    } else {
        (
            Slabs::new(gpu, "no weight maps", d3, full, one)?,
            Slabs::new(gpu, "no eigenmaps", d2, full, one)?,
        )
    };
    // Decode table: per group, weight scale, weight bias, eigen scale, eigen bias (unused
    // channels zero, so that they contribute nothing).
    let groups = (full_groups + has_tail as u32).max(1) as usize;
    let mut dequant = vec![[0f32; 4]; groups * 4];
    for c in 0..rank {
        let (group, ch) = (c / 4, c % 4);
        dequant[group * 4][ch] = g.weights.scale[c];
        dequant[group * 4 + 1][ch] = g.weights.bias[c];
        dequant[group * 4 + 2][ch] = g.eigen.scale[c];
        dequant[group * 4 + 3][ch] = g.eigen.bias[c];
    }
    let dequant = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("factor decode"),
            contents: bytemuck::cast_slice(&dequant),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let params = GdmParams {
        dims: [dims.x, dims.y, dims.z, dirs.n_theta],
        n_phi: dirs.n_phi,
        full_groups,
        has_tail: has_tail as u32,
        margin: g.accuracy.escape_margin,
    };
    let params = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("GDM parameters"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
    let views = [
        weights_full.view(),
        weights_tail.view(),
        eigen_full.view(),
        eigen_tail.view(),
    ];
    let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("package"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&views[0]),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&views[1]),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::TextureView(&views[2]),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::TextureView(&views[3]),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: dequant.as_entire_binding(),
            },
        ],
    });
    let bytes = [&weights_full, &weights_tail, &eigen_full, &eigen_tail]
        .iter()
        .map(|s| s.bytes())
        .sum::<u64>()
        + dequant.size()
        + params.size();
    Ok(GpuPackage { bind_group, bytes })
}

/// Uploads the material volume for the pipeline's group 2 (`layout`): normals and linear
/// albedo as `rgba32float` 3D textures (a 1×1×1 albedo texture for a uniform material).
pub fn upload_material(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    material: &MaterialVolume,
) -> Result<GpuMaterial> {
    let d = material.dims();
    let to_texels = |v: &[glam::Vec3]| -> Vec<[f32; 4]> {
        v.iter().map(|n| n.extend(0.0).to_array()).collect()
    };
    let d3 = wgpu::TextureDimension::D3;
    let normals = Slabs::new(
        gpu,
        "material normals",
        d3,
        TexelFormat::Rgba32float,
        extent(d.x, d.y, d.z),
    )?;
    normals.write(
        gpu,
        bytemuck::cast_slice(&to_texels(material.normal_voxels())),
        wgpu::Origin3d::ZERO,
        d.y,
        d.z,
    );
    let albedo = match material.albedo_voxels() {
        Some(a) => {
            let s = Slabs::new(
                gpu,
                "material albedo",
                d3,
                TexelFormat::Rgba32float,
                extent(d.x, d.y, d.z),
            )?;
            s.write(
                gpu,
                bytemuck::cast_slice(&to_texels(a)),
                wgpu::Origin3d::ZERO,
                d.y,
                d.z,
            );
            s
        }
        None => {
            let s = Slabs::new(
                gpu,
                "uniform albedo",
                d3,
                TexelFormat::Rgba32float,
                extent(1, 1, 1),
            )?;
            s.write(
                gpu,
                bytemuck::cast_slice(&to_texels(&[material.default_albedo().as_vec3()])),
                wgpu::Origin3d::ZERO,
                1,
                1,
            );
            s
        }
    };
    let (nv, av) = (normals.view(), albedo.view());
    let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("material"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&nv),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&av),
            },
        ],
    });
    Ok(GpuMaterial {
        bind_group,
        bytes: normals.bytes() + albedo.bytes(),
    })
}

/// Uploads the prepared prisms: their face triangles as vertices, nearest to `eye` first
/// (so that an early depth test culls what lies behind the first hits), and their records.
pub fn upload_shell(gpu: &Gpu, prisms: &[PreparedPrism], eye: DVec3) -> Result<GpuShell> {
    let limits = gpu.device.limits();
    let record_bytes = std::mem::size_of::<PrismRecord>() as u64;
    let vertex_bytes = 24 * std::mem::size_of::<Vertex>() as u64;
    let n = prisms.len().max(1) as u64;
    if n * record_bytes > limits.max_storage_buffer_binding_size
        || n * vertex_bytes > limits.max_buffer_size
    {
        return Err(Error::Gpu(format!(
            "{} prisms need {} bytes of prism data, over this adapter's storage buffer limit of {} bytes",
            prisms.len(),
            n * record_bytes,
            limits.max_storage_buffer_binding_size
        )));
    }
    let mut vertices = Vec::with_capacity(prisms.len() * 24);
    let mut records = Vec::with_capacity(prisms.len().max(1));
    let distance = |p: &PreparedPrism| {
        let centre: DVec3 = p.faces[0]
            .triangle
            .corners
            .iter()
            .chain(&p.faces[1].triangle.corners)
            .sum();
        (centre / 6.0 - eye).length_squared()
    };
    let mut order: Vec<(f64, usize)> = prisms
        .iter()
        .enumerate()
        .map(|(p, prism)| (distance(prism), p))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    for &(_, p) in &order {
        for (f, face) in prisms[p].faces.iter().enumerate() {
            for c in 0..3 {
                vertices.push(Vertex {
                    position: face.triangle.corners[c].as_vec3().to_array(),
                    texture: face.triangle.texture[c].as_vec3().to_array(),
                    prism: p as u32,
                    face: f as u32,
                });
            }
        }
    }
    for prism in prisms {
        let frame = prism.frame.transpose(); // columns of the transpose are the rows
        records.push(PrismRecord {
            faces: prism.faces.map(|f| FaceRecord {
                corners: f.triangle.corners.map(|c| vec4(c, 0.0)),
                texture: f.triangle.texture.map(|t| vec4(t, 0.0)),
                plane: vec4(f.normal, f.offset),
            }),
            frame: [
                vec4(frame.x_axis, 0.0),
                vec4(frame.y_axis, 0.0),
                vec4(frame.z_axis, 0.0),
            ],
            convex: [
                prism.convex[0] as u32,
                prism.convex[1] as u32,
                prism.convex[2] as u32,
                0,
            ],
        });
    }
    if records.is_empty() {
        records.push(PrismRecord::zeroed());
    }
    let vertex_count = vertices.len() as u32;
    if vertices.is_empty() {
        vertices.push(Vertex::zeroed());
    }
    let vertices = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shell vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
    let prisms = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("prisms"),
            contents: bytemuck::cast_slice(&records),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let bytes = vertices.size() + prisms.size();
    Ok(GpuShell {
        vertices,
        vertex_count,
        prisms,
        bytes,
    })
}

/// A BVH over boxes on the GPU (the prisms' for the shell-shadow variant, the cells' for
/// translucent media).
pub struct GpuBvh {
    /// `BvhNode` records of `shaders/common.wgsl`, the root first.
    pub nodes: wgpu::Buffer,
    /// Primitive (prism, cell) indices that the leaves list.
    pub primitives: wgpu::Buffer,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// The shader's `BvhNode`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct BvhNodeRecord {
    lo: [f32; 3],
    /// Primitives in a leaf (0: an inner node).
    count: u32,
    hi: [f32; 3],
    /// A leaf's first entry in the primitive index list.
    first: u32,
    /// The node after this subtree in depth-first order (the node count: none).
    skip: u32,
    _pad: [u32; 3],
}

/// [`upload_box_bvh`] over the prisms' bounding boxes, the boxes the CPU renderer's
/// traversal tests.
pub fn upload_prism_bvh(gpu: &Gpu, prisms: &[PreparedPrism]) -> Result<GpuBvh> {
    let boxes: Vec<_> = prisms.iter().map(PreparedPrism::bounds).collect();
    upload_box_bvh(gpu, &boxes)
}

/// Builds and uploads a binary BVH (obvhs) over the padded f32 versions of `bounds` (lower
/// and upper corners), laid out in depth-first order with skip links so that the shaders
/// traverse it without a stack: from node i, a hit inner node continues at i + 1 (its first
/// child), a missed node or a leaf at its `skip`.
pub fn upload_box_bvh(gpu: &Gpu, bounds: &[(DVec3, DVec3)]) -> Result<GpuBvh> {
    let boxes: Vec<obvhs::aabb::Aabb> = bounds
        .iter()
        .map(|&b| mesobake_render::accel::padded_f32_box(b))
        .collect();
    let bvh = obvhs::bvh2::builder::build_bvh2(
        &boxes,
        obvhs::BvhBuildParams::medium_build(),
        &mut std::time::Duration::default(),
    );
    let mut nodes = Vec::with_capacity(bvh.nodes.len());
    if !boxes.is_empty() && !bvh.nodes.is_empty() {
        // Preorder: a node is written, then its children's subtrees; its skip is patched once
        // its subtree is complete.
        enum Visit {
            Enter(usize),
            Close(usize),
        }
        let mut stack = vec![Visit::Enter(0)];
        while let Some(visit) = stack.pop() {
            match visit {
                Visit::Enter(i) => {
                    let Some(n) = bvh.nodes.get(i) else {
                        continue;
                    };
                    let at = nodes.len();
                    nodes.push(BvhNodeRecord {
                        lo: n.aabb.min.to_array(),
                        count: n.prim_count,
                        hi: n.aabb.max.to_array(),
                        first: if n.prim_count > 0 { n.first_index } else { 0 },
                        skip: 0,
                        _pad: [0; 3],
                    });
                    stack.push(Visit::Close(at));
                    if n.prim_count == 0 {
                        let first = n.first_index as usize;
                        stack.push(Visit::Enter(first + 1));
                        stack.push(Visit::Enter(first));
                    }
                }
                Visit::Close(at) => nodes[at].skip = nodes.len() as u32,
            }
        }
    }
    if nodes.is_empty() {
        // No box: one node that no ray enters.
        nodes.push(BvhNodeRecord {
            lo: [1.0; 3],
            count: 0,
            hi: [-1.0; 3],
            first: 0,
            skip: 1,
            _pad: [0; 3],
        });
    }
    let mut indices = bvh.primitive_indices.clone();
    if indices.is_empty() {
        indices.push(0);
    }
    let buffer = |label, contents: &[u8]| {
        gpu.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
    };
    let nodes = buffer("bvh nodes", bytemuck::cast_slice(&nodes));
    let primitives = buffer("bvh primitives", bytemuck::cast_slice(&indices));
    let bytes = nodes.size() + primitives.size();
    Ok(GpuBvh {
        nodes,
        primitives,
        bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The GDM pipeline's records are laid out as their structs in the WGSL.
    #[test]
    fn the_gdm_records_are_their_wgsl_structs() {
        let source = source_with_every_struct();
        let gdm = rust_layout!(GdmParams {
            dims,
            n_phi,
            full_groups,
            has_tail,
            margin
        });
        assert_twin(&source, "GdmParams", gdm);
        assert_twin(&source, "GiParams", rust_layout!(GiParams { dims, dirs }));
        let prism = rust_layout!(GiPrismRecord {
            vertices,
            uv01,
            uv2
        });
        assert_twin(&source, "GiPrism", prism);
        let face = rust_layout!(FaceRecord {
            corners,
            texture,
            plane
        });
        assert_twin(&source, "Face", face);
        let prism = rust_layout!(PrismRecord {
            faces,
            frame,
            convex
        });
        assert_twin(&source, "Prism", prism);
        let node = rust_layout!(BvhNodeRecord {
            lo,
            count,
            hi,
            first,
            skip
        });
        assert_twin(&source, "BvhNode", node);
    }
}

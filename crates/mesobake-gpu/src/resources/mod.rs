//! What the preview uploads, one module each: a package's GDM (`package`), the material
//! volume (`material`), the shell's prisms (`shell`), environment light (`environment`) and
//! bounding volume hierarchies (`bvh`), with the GPU memory each takes ([`GpuMemory`]) and
//! the texture uploads they share.

mod bvh;
mod environment;
mod material;
mod package;
mod shell;

use super::gpu::Gpu;
pub use bvh::{GpuBvh, upload_box_bvh, upload_prism_bvh};
use bytemuck::{Pod, Zeroable};
pub use environment::{GpuEnvironment, upload_environment};
use glam::DVec3;
pub use material::{GpuMaterial, upload_material};
use mesobake_bake::mesostructure::material::MaterialVolume;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::TexelFormat;
use mesobake_core::error::{Error, Result};
use mesobake_render::gi_shading::GiShading;
use mesobake_render::prepared_prism::PreparedPrism;
pub use package::{GpuPackage, upload_package};
use serde::Serialize;
pub use shell::{GpuShell, Vertex, upload_shell};
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

impl std::ops::Add for GpuMemory {
    type Output = GpuMemory;

    /// Kind by kind, the memory of two sets of resources.
    fn add(self, other: GpuMemory) -> GpuMemory {
        GpuMemory {
            package: self.package + other.package,
            material: self.material + other.material,
            geometry: self.geometry + other.geometry,
            environment: self.environment + other.environment,
            targets: self.targets + other.targets,
        }
    }
}

fn extent(width: u32, height: u32, depth: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width,
        height,
        depth_or_array_layers: depth,
    }
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

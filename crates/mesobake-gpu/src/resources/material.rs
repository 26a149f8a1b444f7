//! The material volume on the GPU: its normal and albedo textures.

use super::*;

/// The material volume on the GPU.
pub struct GpuMaterial {
    /// Group 2 of the pipeline.
    pub bind_group: wgpu::BindGroup,
    /// Bytes uploaded.
    pub bytes: u64,
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

//! Environment light on the GPU: the package's RTV sections as they are, the incident light
//! per base vertex and each prism's base triangle in texture space.

use super::*;

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
pub(super) struct GiParams {
    dims: [u32; 4],
    dirs: [u32; 4],
}

/// A prism's base triangle (`GiPrism` in `shaders/gi_on.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct GiPrismRecord {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The RTV grids and prism records are laid out as `GiParams` and `GiPrism` in `gi_on.wgsl`.
    #[test]
    fn the_environment_records_are_their_wgsl_structs() {
        let source = source_with_every_struct();
        assert_twin(&source, "GiParams", rust_layout!(GiParams { dims, dirs }));
        let prism = rust_layout!(GiPrismRecord {
            vertices,
            uv01,
            uv2
        });
        assert_twin(&source, "GiPrism", prism);
    }
}

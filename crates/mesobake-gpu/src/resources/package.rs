//! A package's GDM on the GPU: its factor sections copied byte for byte into stacked
//! textures (or its occupancy field), the decode table and the parameters.
//!
//! Factor textures: the component groups of four that fill an `rgba` texel are stacked in
//! one texture per factor (weight maps along depth, one Nφ slab per group; eigenmaps along
//! height, one Nθ band per group); the last group of a rank that is not a multiple of four
//! has its own, narrower texture. Each section is copied byte for byte into its slab.

use super::*;

/// The GDM parameters the shader reads (`GdmParams` in `shaders/gdm_preview.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct GdmParams {
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
pub(super) fn upload_factors(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The GDM parameters are laid out as `GdmParams` in `query_svd.wgsl`.
    #[test]
    fn the_gdm_parameters_are_their_wgsl_struct() {
        let source = source_with_every_struct();
        let gdm = rust_layout!(GdmParams {
            dims,
            n_phi,
            full_groups,
            has_tail,
            margin
        });
        assert_twin(&source, "GdmParams", gdm);
    }
}

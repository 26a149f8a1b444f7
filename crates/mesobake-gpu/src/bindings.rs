//! Bind group plumbing every pipeline shares: layout entries by kind of resource, a layout
//! with its group, initialized buffers.

use wgpu::util::DeviceExt;

/// A bind group layout over `entries` and the bind group binding each entry's resource.
pub(super) fn bind_group(
    d: &wgpu::Device,
    label: &str,
    entries: &[(wgpu::BindGroupLayoutEntry, wgpu::BindingResource)],
) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries.iter().map(|e| e.0).collect::<Vec<_>>(),
    });
    let group = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &layout,
        entries: &entries
            .iter()
            .map(|(e, resource)| wgpu::BindGroupEntry {
                binding: e.binding,
                resource: resource.clone(),
            })
            .collect::<Vec<_>>(),
    });
    (layout, group)
}

/// A buffer labelled `label` holding `contents`, for `usage`.
pub(super) fn init_buffer(
    d: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

pub(super) fn layout_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    }
}

pub(super) fn storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

pub(super) fn storage_read_write() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: false },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

pub(super) fn uniform() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// A 2D `rgba32float` texture read by `textureLoad` (the hit targets).
pub(super) fn texture_2d() -> wgpu::BindingType {
    texture(wgpu::TextureViewDimension::D2)
}

pub(super) fn texture(dimension: wgpu::TextureViewDimension) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: dimension,
        multisampled: false,
    }
}

pub(super) fn uint_texture(dimension: wgpu::TextureViewDimension) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Uint,
        view_dimension: dimension,
        multisampled: false,
    }
}

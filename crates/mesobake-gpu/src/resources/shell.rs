//! The shell on the GPU: the vertex buffer of its prisms' faces and the per-prism records.

use super::*;

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
pub(super) struct FaceRecord {
    corners: [[f32; 4]; 3],
    texture: [[f32; 4]; 3],
    plane: [f32; 4],
}

/// The shader's `Prism`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct PrismRecord {
    faces: [FaceRecord; 8],
    frame: [[f32; 4]; 3],
    convex: [u32; 4],
}

pub(super) fn vec4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The face and prism records are laid out as `Face` and `Prism` in `gdm_preview.wgsl`.
    #[test]
    fn the_shell_records_are_their_wgsl_structs() {
        let source = source_with_every_struct();
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
    }
}

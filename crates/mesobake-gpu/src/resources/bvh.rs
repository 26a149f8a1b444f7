//! Bounding volume hierarchies on the GPU: over the prisms (shell shadows) or any boxes
//! (the media's cells), in depth-first order with skip links.

use super::*;

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
pub(super) struct BvhNodeRecord {
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

    /// The node records are laid out as `BvhNode` in `common.wgsl`.
    #[test]
    fn the_bvh_nodes_are_their_wgsl_struct() {
        let source = source_with_every_struct();
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

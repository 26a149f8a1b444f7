// The GDM of a package's top layer along one direction bin, computed from the package's own
// textures: for each voxel centre (i, j, Z − 1) the distance to the mesostructure, −1 for an
// escape. What both codecs' shaders (svd.wgsl, march.wgsl) share.

struct Params {
    // x, y, z of the voxel grid; w: channels in this group (svd).
    dims: vec4<u32>,
    // x: θ bin a, y: φ bin b.
    bin: vec4<u32>,
    // The direction of bin (a, b), and in w the escape rule's (1 − μ)·b for the top layer.
    dir: vec4<f32>,
    scale_w: vec4<f32>,
    bias_w: vec4<f32>,
    scale_e: vec4<f32>,
    bias_e: vec4<f32>,
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read_write> values: array<f32>;


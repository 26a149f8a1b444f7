// The translucent-media real-time pipeline (semi-transparent 3D textures): the algorithm of
// `crates/mesobake-render/src/medium_cells.rs`, step for step (that file's module documentation is the
// specification; the tests hold the two to PSNR ≥ 35 dB). The shell is cut into
// tetrahedral cells, each with its affine map to texture space; each cell a ray crosses is
// integrated on its own (exactly, voxel by voxel, or with a fixed number of samples) and
// the cells are composited front to back. Two ways to find the cells in order:
//
// - `cs_pixels` (a compute pass, one invocation per pixel): the sorted list of the cells the
//   pixel's ray crosses, gathered from a BVH over the cells in batches of BATCH (the BATCH
//   nearest not yet composited), composited front to back with early termination. Exact
//   order.
// - `fs_cell` (entry `vs_cell`): the cells' front faces rasterized in an order computed per
//   view on the CPU, back to front, each fragment integrating its cell and blended "over"
//   what is behind it (premultiplied). Exact where that order is a visibility order.
//
// Shadows (when the scene asks for them): per light a shadow map built by `cs_shadow_map`
// before each frame (one invocation per light-space texel, its ray's optical depth through
// the cells in order; `crates/mesobake-render/src/medium_shadow_map.rs` is the specification), an opacity
// map (the depths where the light's transmittance passes `shadow_levels` fixed levels) or
// the paper's depth map (where it falls to ½); or, by the `rays` method and for lights without a map, the
// transmittance of a ray through the cells towards the light, found through the same BVH.
// Preceded by `common.wgsl`; followed by, in this order, `medium_cells.wgsl`,
// `medium_voxels.wgsl`, `medium_shadow_rays.wgsl`, `medium_compositing.wgsl`,
// `medium_pixel_list.wgsl`, `medium_cell_raster.wgsl` and `medium_shadow_maps.wgsl`
// (`crates/mesobake-gpu/src/medium_pipeline.rs` composes them).

// One tetrahedron.
struct Cell {
    // Face planes: xyz the unit outward normal, w the offset (inside where n·x < w).
    planes: array<vec4<f32>, 4>,
    // Rows of M^{o→t} (object → texture voxels): texture = rows · (x, 1).
    to_texture: array<vec4<f32>, 3>,
    // Rows of Mᵀ (texture normals → object normals); w of row 0: ∛|det M| (voxels per
    // object length), for the mip level.
    normal_to_object: array<vec4<f32>, 3>,
    // Object-space corners (the rasterized faces' vertices).
    corners: array<vec4<f32>, 4>,
}

struct Medium {
    // Camera basis: forward, right · tan(fov/2) · aspect, up · tan(fov/2); w of forward:
    // the angle one pixel subtends (2 tan(fov/2) / height).
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    height: u32,
    // 0: exact (every voxel), 1: `samples` samples per cell.
    integration: u32,
    samples: u32,
    // 0: no shadows; 1: rays; 2: deep maps; 3: depth maps.
    shadows: u32,
    // Mip levels uploaded (1: none but the medium).
    level_count: u32,
    mip_bias: f32,
    light_step: f32,
    shadow_start: f32,
    min_transmittance: f32,
    // Loop iterations an invocation may run and be sure the adapter cut none short (0: no
    // limit; `Gpu::loop_budget`: Mesa's software rasterizer stops every loop of a SIMD batch
    // of invocations once they have run 65 535 iterations together). Pixels over it are
    // counted in `overflow` instead of being trusted.
    loop_budget: u32,
    // Shadow maps' texels along a side, and values per texel (deep maps: t_a, t_e, τ_e and
    // the levels' depths).
    shadow_size: u32,
    shadow_stride: u32,
    // Per level: xyz its dimensions, w its first voxel in `voxels` and `normals`.
    levels: array<vec4<u32>, 16>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var<storage, read> cells: array<Cell>;
@group(0) @binding(3) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> bvh_cells: array<u32>;
@group(0) @binding(5) var<uniform> medium: Medium;
// Per voxel of every level: rgb the linear albedo, a the opacity per voxel length.
@group(0) @binding(6) var<storage, read> voxels: array<vec4<f32>>;
// Per voxel of every level: xyz the unnormalized outward normal (−∇ opacity).
@group(0) @binding(7) var<storage, read> normals: array<vec4<f32>>;

// A light's shadow map space (`LightFrame`).
struct ShadowFrame {
    // Orthographic: the map's centre; perspective: the light. w: t₀.
    origin: vec4<f32>,
    // The unit direction the light travels. w: the depth range (2r).
    axis: vec4<f32>,
    // The map's axes, scaled; w: 1 / their squared lengths.
    u_axis: vec4<f32>,
    v_axis: vec4<f32>,
    // 0: no map; 1: orthographic; 2: perspective.
    kind: u32,
    // The map's first value in the map buffer.
    first: u32,
    _pad0: u32,
    _pad1: u32,
}

// Per light its map's frame.
@group(0) @binding(9) var<storage, read> shadow_frames: array<ShadowFrame>;

// Cells composited per batch of the per-pixel list.
const BATCH: u32 = 32u;
const FAR: f32 = 3.0e38;
// `MAX_OPTICAL_DEPTH`, `OPAQUE_EXTINCTION` and `DEPTH_THRESHOLD` of the specification.
const MAX_OPTICAL_DEPTH: f32 = 13.815510557964274;
const OPAQUE_EXTINCTION: f32 = 1.0e4;
const DEPTH_THRESHOLD: f32 = 0.6931471805599453;


// What every object's hit pass shares (included by the GDM pipeline and by a VDM object among
// several): the per-pixel nearest hit so far and the hit targets, which the shading and
// occlusion passes read. Each pixel's hit in the targets holds, whatever its object's
// technique, its object-space point in `hit_points.xyz`, a non-zero `hit_textures.w` and its
// object's index in `hit_views.w`; the rest is its technique's to say (`HitOut` below for
// the GDM, the head of `vdm_objects.wgsl` for the VDM).

// Per pixel, the depth of the nearest hit any fragment has found so far this frame, stored
// as the complement of its f32 bits (depths are ≥ 0, so their bits order like them; the
// buffer is cleared to 0 each frame, "no hit yet"). A fragment whose face lies behind it
// cannot win the depth test and stops before its march, and one whose hit lies behind it
// before writing it: the depth test done early by hand, whatever order fragments run in (a
// stale value only culls less). A GDM object's prisms are drawn nearest first, so most
// hidden fragments find a nearer hit already stored.
@group(0) @binding(5) var<storage, read_write> nearest_hit: array<atomic<u32>>;

// The hit pass's targets, read by the shading pass.
@group(0) @binding(6) var hit_points: texture_2d<f32>;
@group(0) @binding(7) var hit_textures: texture_2d<f32>;
@group(0) @binding(8) var hit_views: texture_2d<f32>;

// What the hit pass writes per pixel for the shading pass (the three targets, cleared to zero:
// texture.w = 0 is "no hit"), under the depth test, so the nearest hit wins. A GDM hit: its
// object point and its prism's index (the bits of a u32); its texture coordinate and 1; the
// texture-space direction of the chord that hit and the object's index.
struct HitOut {
    @location(0) point: vec4<f32>,
    @location(1) texture: vec4<f32>,
    @location(2) view: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

fn pixel_index(pixel: vec2<i32>) -> u32 {
    return u32(pixel.y) * view.width + u32(pixel.x);
}

// The depth (0..1, as the depth test compares) of an object-space point.
fn hit_depth(p: vec3<f32>) -> f32 {
    let clip = view.view_proj * vec4<f32>(p, 1.0);
    return clip.z / clip.w;
}

// Whether a nearer hit than `depth` is stored at pixel index `pixel` already.
fn behind_nearest_hit(pixel: u32, depth: f32) -> bool {
    let stored = atomicLoad(&nearest_hit[pixel]);
    return stored != 0u && depth >= bitcast<f32>(~stored);
}

// Stores a hit at `depth` as the pixel's nearest unless a nearer one is stored: whether it
// is the nearest so far.
fn claim_pixel(pixel: u32, depth: f32) -> bool {
    let mine = ~bitcast<u32>(max(depth, 0.0));
    return atomicMax(&nearest_hit[pixel], mine) <= mine;
}

// A full-screen pass (shading, and the passes between objects): one triangle over the whole
// image.
@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let corner = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(corner * 2.0 - 1.0, 0.0, 1.0);
}

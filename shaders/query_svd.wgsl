// GDM queries of the `paper-svd` codec (crates/mesobake-render/src/gdm_lookup.rs, PackageLookup, and the
// default `GdmLookup::segment_hit`): d̃ = Σᵢ W̃ᵢ(x, y, φ)·Ẽᵢ(θ, z), each factor interpolated
// on its own, with the package's escape rule.

// How far short of the previous estimate a refinement query is made, in voxels.
const REFINEMENT_BACKOFF: f32 = 1.0;

struct GdmParams {
    // X, Y, Z voxels and Nθ.
    dims: vec4<u32>,
    n_phi: u32,
    // Component groups of four in the *_full textures, stacked along φ (weights) and θ (eigen).
    full_groups: u32,
    // 1 when the last group (fewer than four components) sits in the *_tail textures.
    has_tail: u32,
    // The package's relative escape margin μ.
    margin: f32,
}

// Per component group: decoded = bias + scale · stored.
struct Dequant {
    weight_scale: vec4<f32>,
    weight_bias: vec4<f32>,
    eigen_scale: vec4<f32>,
    eigen_bias: vec4<f32>,
}

@group(1) @binding(0) var<uniform> gdm: GdmParams;
@group(1) @binding(1) var weights_full: texture_3d<f32>;
@group(1) @binding(2) var weights_tail: texture_3d<f32>;
@group(1) @binding(3) var eigen_full: texture_2d<f32>;
@group(1) @binding(4) var eigen_tail: texture_2d<f32>;
@group(1) @binding(5) var<storage, read> dequant: array<Dequant>;

// Trilinear weight-map value of one component group (stacked at depth `base`).
fn weight_group(tex: texture_3d<f32>, base: u32, x: Taps, y: Taps, phi: Taps) -> vec4<f32> {
    var sum = vec4<f32>(0.0);
    for (var c = 0u; c < 8u; c++) {
        let sx = c & 1u;
        let sy = (c >> 1u) & 1u;
        let sp = (c >> 2u) & 1u;
        let w = select(1.0 - x.frac, x.frac, sx == 1u) * select(1.0 - y.frac, y.frac, sy == 1u)
            * select(1.0 - phi.frac, phi.frac, sp == 1u);
        let i = select(x.i0, x.i1, sx == 1u);
        let j = select(y.i0, y.i1, sy == 1u);
        let b = select(phi.i0, phi.i1, sp == 1u);
        sum += w * textureLoad(tex, vec3<i32>(i32(i), i32(j), i32(base + b)), 0);
    }
    return sum;
}

// Bilinear eigenmap value of one component group (stacked at row `base`).
fn eigen_group(tex: texture_2d<f32>, base: u32, theta: Taps, z: Taps) -> vec4<f32> {
    var sum = vec4<f32>(0.0);
    for (var c = 0u; c < 4u; c++) {
        let st = c & 1u;
        let sz = (c >> 1u) & 1u;
        let w = select(1.0 - theta.frac, theta.frac, st == 1u) * select(1.0 - z.frac, z.frac, sz == 1u);
        let a = select(theta.i0, theta.i1, st == 1u);
        let k = select(z.i0, z.i1, sz == 1u);
        sum += w * textureLoad(tex, vec2<i32>(i32(k), i32(base + a)), 0);
    }
    return sum;
}

// Distance from sample layer k to the top or bottom plane along direction bin a.
fn boundary_distance(k: u32, a: u32) -> f32 {
    let cos_theta = cos((f32(a) + 0.5) * PI / f32(gdm.dims.w));
    let z = f32(k) + 0.5;
    return select(-z / cos_theta, (f32(gdm.dims.z) - z) / cos_theta, cos_theta > 0.0);
}

// d(t, v): t in voxel units, v a unit texture-space direction. Hits give the distance
// (≥ 0), escapes −1.
fn gdm_lookup(t: vec3<f32>, v: vec3<f32>) -> f32 {
    let n_theta = gdm.dims.w;
    let theta = acos(clamp(v.z, -1.0, 1.0));
    var phi = atan2(v.y, v.x);
    if phi < 0.0 {
        phi += TAU;
    }
    let x = periodic_taps(t.x - 0.5, gdm.dims.x);
    let y = periodic_taps(t.y - 0.5, gdm.dims.y);
    let z = clamped_taps(t.z - 0.5, gdm.dims.z);
    let th = clamped_taps(theta / PI * f32(n_theta) - 0.5, n_theta);
    let ph = periodic_taps(phi / TAU * f32(gdm.n_phi) - 0.5, gdm.n_phi);
    var dist = 0.0;
    for (var g = 0u; g < gdm.full_groups; g++) {
        let q = dequant[g];
        let w = q.weight_bias + q.weight_scale * weight_group(weights_full, g * gdm.n_phi, x, y, ph);
        let e = q.eigen_bias + q.eigen_scale * eigen_group(eigen_full, g * n_theta, th, z);
        dist += dot(w, e);
    }
    if gdm.has_tail == 1u {
        let q = dequant[gdm.full_groups];
        let w = q.weight_bias + q.weight_scale * weight_group(weights_tail, 0u, x, y, ph);
        let e = q.eigen_bias + q.eigen_scale * eigen_group(eigen_tail, 0u, th, z);
        dist += dot(w, e);
    }
    let boundary = (1.0 - th.frac) * (1.0 - z.frac) * boundary_distance(z.i0, th.i0)
        + th.frac * (1.0 - z.frac) * boundary_distance(z.i0, th.i1)
        + (1.0 - th.frac) * z.frac * boundary_distance(z.i1, th.i0)
        + th.frac * z.frac * boundary_distance(z.i1, th.i1);
    if dist >= (1.0 - gdm.margin) * boundary {
        return -1.0;
    }
    return max(dist, 0.0);
}

// How far along `view` the query point moves from `t` to reach the centre plane of the top
// layer when it enters from the half voxel above it, or of the bottom layer from below.
fn advance_to_samples(t: vec3<f32>, view_dir: vec3<f32>, z: f32, d_t: f32) -> f32 {
    var s = 0.0;
    if view_dir.z < 0.0 && t.z > z - 0.5 {
        s = (t.z - (z - 0.5)) / -view_dir.z;
    } else if view_dir.z > 0.0 && t.z < 0.5 {
        s = (0.5 - t.z) / view_dir.z;
    }
    return select(0.0, s, s < d_t);
}

// The hit distance along the texture-space segment, or −1 when the ray leaves it first.
fn segment_hit(start: vec3<f32>, view_dir: vec3<f32>, d_t: f32) -> f32 {
    var travelled = advance_to_samples(start, view_dir, f32(gdm.dims.z), d_t);
    var answer = gdm_lookup(start + view_dir * travelled, view_dir);
    for (var r = 0u; r < REFINEMENTS; r++) {
        if answer < 0.0 {
            break;
        }
        let step = answer - REFINEMENT_BACKOFF;
        if step <= 0.0 || travelled + answer >= d_t {
            break;
        }
        let next = gdm_lookup(start + view_dir * (travelled + step), view_dir);
        if next < 0.0 {
            break;
        }
        travelled += step;
        answer = next;
    }
    if answer >= 0.0 && travelled + answer < d_t {
        return travelled + answer;
    }
    return -1.0;
}


// Whether the ray from `origin` along the unit texture direction `l` leaves the volume.
fn escapes(origin: vec3<f32>, l: vec3<f32>) -> bool {
    return gdm_lookup(origin, l) < 0.0;
}

// Environment variant: the scene calls for environment lighting. The incident SH of the
// prism's base vertices (PRT × environment, computed on the CPU per vertex), interpolated with
// the hit's barycentric coordinates in texture space, dotted with the package's compressed
// RTV read at the hit towards the eye: step for step `GiShading::radiance`
// (`crates/mesobake-render/src/gi_shading.rs`) and `CompressedRtv::interpolate`
// (`crates/mesobake-bake/src/gi/compressed_rtv.rs`).

struct GiParams {
    // X, Y, Z, RTV samples.
    dims: vec4<u32>,
    // Nθ, Nφ of the view bins, RTV rank, unused.
    dirs: vec4<u32>,
}

struct GiPrism {
    // The base triangle's vertex indices (w unused).
    vertices: vec4<u32>,
    // Texture coordinates of vertices 0 and 1 (voxel units, x and y).
    uv01: vec4<f32>,
    // Texture coordinates of vertex 2 (zw unused).
    uv2: vec4<f32>,
}

@group(3) @binding(0) var<uniform> gi: GiParams;
// Sample index of each voxel, or NO_SAMPLE.
@group(3) @binding(1) var rtv_index: texture_3d<u32>;
// f16 pairs: component k of sample s, matrix m at (s·48 + m)·rank + k.
@group(3) @binding(2) var<storage, read> rtv_weights: array<u32>;
// f16 pairs: component k of matrix m at view bin v at (m·views + v)·rank + k.
@group(3) @binding(3) var<storage, read> rtv_eigen: array<u32>;
// Incident SH per base vertex: vertex·48 + channel·16 + coefficient.
@group(3) @binding(4) var<storage, read> incident: array<f32>;
@group(3) @binding(5) var<storage, read> gi_prisms: array<GiPrism>;

const NO_SAMPLE: u32 = 0xffffffffu;
// How far back along the view, in voxels, a hit looks for RTV samples, in equal steps.
const MAX_BACKOFF: f32 = 1.5;
const MAX_BACKOFF_STEPS: u32 = 3u;
// 3 channels × 16 light coefficients.
const MATRICES: u32 = 48u;

fn weight_value(e: u32) -> f32 {
    let pair = unpack2x16float(rtv_weights[e >> 1u]);
    return select(pair.x, pair.y, (e & 1u) == 1u);
}

fn eigen_value(e: u32) -> f32 {
    let pair = unpack2x16float(rtv_eigen[e >> 1u]);
    return select(pair.x, pair.y, (e & 1u) == 1u);
}

// The sample voxels around a texture point and their trilinear weights (zero for corners
// that are not samples), and the weights' total.
struct Corners {
    samples: array<u32, 8>,
    weights: array<f32, 8>,
    total: f32,
}

fn sample_corners(t: vec3<f32>) -> Corners {
    let x = periodic_taps(t.x - 0.5, gi.dims.x);
    let y = periodic_taps(t.y - 0.5, gi.dims.y);
    let z = clamped_taps(t.z - 0.5, gi.dims.z);
    var c: Corners;
    c.total = 0.0;
    for (var n = 0u; n < 8u; n++) {
        let dx = (n & 1u) == 1u;
        let dy = ((n >> 1u) & 1u) == 1u;
        let dz = ((n >> 2u) & 1u) == 1u;
        let w = select(1.0 - x.frac, x.frac, dx) * select(1.0 - y.frac, y.frac, dy)
            * select(1.0 - z.frac, z.frac, dz);
        let voxel = vec3<u32>(select(x.i0, x.i1, dx), select(y.i0, y.i1, dy), select(z.i0, z.i1, dz));
        let s = textureLoad(rtv_index, voxel, 0).x;
        c.samples[n] = s;
        c.weights[n] = 0.0;
        if s != NO_SAMPLE && w != 0.0 {
            c.weights[n] = w;
            c.total += w;
        }
    }
    return c;
}

// Barycentric coordinates of p in the prism's base triangle in texture space, clamped to
// [0, 1] and renormalized (the centroid for a degenerate triangle).
fn gi_barycentric(g: GiPrism, p: vec2<f32>) -> vec3<f32> {
    let t0 = g.uv01.xy;
    let e1 = g.uv01.zw - t0;
    let e2 = g.uv2.xy - t0;
    let q = p - t0;
    let det = e1.x * e2.y - e1.y * e2.x;
    if det == 0.0 {
        return vec3<f32>(1.0 / 3.0);
    }
    let b1 = (q.x * e2.y - q.y * e2.x) / det;
    let b2 = (e1.x * q.y - e1.y * q.x) / det;
    let b = clamp(vec3<f32>(1.0 - b1 - b2, b1, b2), vec3<f32>(0.0), vec3<f32>(1.0));
    return b / (b.x + b.y + b.z);
}

fn environment_light(prism: u32, t_hit: vec3<f32>, view_tex: vec3<f32>) -> vec3<f32> {
    // The RTV samples around the hit, or a little further back along the view.
    var corners = sample_corners(t_hit);
    for (var step = 1u; step <= MAX_BACKOFF_STEPS && corners.total <= 0.0; step++) {
        let back = MAX_BACKOFF * f32(step) / f32(MAX_BACKOFF_STEPS);
        corners = sample_corners(t_hit - view_tex * back);
    }
    if corners.total <= 0.0 {
        return vec3<f32>(0.0);
    }
    // The eigenfunctions' view taps: towards the eye, bilinear between bin centres.
    let to_eye = normalize_or(-view_tex, vec3<f32>(0.0, 0.0, 1.0));
    let theta = acos(clamp(to_eye.z, -1.0, 1.0));
    let phi = atan2(to_eye.y, to_eye.x);
    let n_theta = gi.dirs.x;
    let n_phi = gi.dirs.y;
    let ta = clamped_taps(theta / PI * f32(n_theta) - 0.5, n_theta);
    let tb = periodic_taps(phi / TAU * f32(n_phi) - 0.5, n_phi);
    let bins = array<u32, 4>(ta.i0 * n_phi + tb.i0, ta.i1 * n_phi + tb.i0, ta.i0 * n_phi + tb.i1, ta.i1 * n_phi + tb.i1);
    let bin_weights = array<f32, 4>(
        (1.0 - ta.frac) * (1.0 - tb.frac), ta.frac * (1.0 - tb.frac),
        (1.0 - ta.frac) * tb.frac, ta.frac * tb.frac);
    let views = n_theta * n_phi;
    let rank = gi.dirs.z;
    let g = gi_prisms[prism];
    let b = gi_barycentric(g, t_hit.xy);
    var out = vec3<f32>(0.0);
    for (var m = 0u; m < MATRICES; m++) {
        var e: array<f32, 16>;
        for (var k = 0u; k < rank; k++) {
            var v = 0.0;
            for (var c = 0u; c < 4u; c++) {
                v += bin_weights[c] * eigen_value((m * views + bins[c]) * rank + k);
            }
            e[k] = v;
        }
        var t = 0.0;
        for (var n = 0u; n < 8u; n++) {
            if corners.weights[n] > 0.0 {
                let first = (corners.samples[n] * MATRICES + m) * rank;
                var acc = 0.0;
                for (var k = 0u; k < rank; k++) {
                    acc += weight_value(first + k) * e[k];
                }
                t += corners.weights[n] * acc;
            }
        }
        t /= corners.total;
        let light = b.x * incident[g.vertices.x * MATRICES + m]
            + b.y * incident[g.vertices.y * MATRICES + m]
            + b.z * incident[g.vertices.z * MATRICES + m];
        out[m / 16u] += t * light;
    }
    return max(out, vec3<f32>(0.0));
}

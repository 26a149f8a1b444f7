// The VDM real-time pipeline: the per-pixel algorithm of `crates/mesobake-render/src/vdm_renderer.rs`, step
// for step (that file's module documentation is the specification; the tests hold the two
// to PSNR ≥ 35 dB). The shell's top triangles are rasterized with back faces culled; a
// silhouette discards its fragment, so the depth test keeps the nearest fragment that is
// not one. The VDM's factors and the height field come as storage buffers, filtered here
// exactly as `VdmQuery::sample` and `HeightField::sample` filter them. Preceded by
// `common.wgsl`; an object among several adds `hit_targets.wgsl`, `vdm_objects.wgsl` and an
// objects file (`objects_on.wgsl` or `objects_off.wgsl`), which draw its hits into targets
// shared with the other objects and shade them in a pass of their own.

const HALF_PI: f32 = 1.5707963267948966;

// ---- Bindings -------------------------------------------------------------------------

// Principal curvatures (x: k_max, y: k_min) and directions at one corner.
struct Curvature {
    k: vec4<f32>,
    dir_max: vec4<f32>,
    dir_min: vec4<f32>,
}

// One top triangle: corners, texture coordinates (tiles), the rows of A = S·M (object →
// VDM space) and of A⁻¹, and the curvature at each corner.
struct Face {
    corners: array<vec4<f32>, 3>,
    uv: array<vec4<f32>, 3>,
    to_vdm: array<vec4<f32>, 3>,
    from_vdm: array<vec4<f32>, 3>,
    curvature: array<Curvature, 3>,
}

struct Vdm {
    // W, H.
    size: vec2<u32>,
    n_theta: u32,
    n_phi: u32,
    n_curvature: u32,
    rank: u32,
    mvm_rank: u32,
    // 1 when the scene calls for shadows.
    shadows: u32,
    c_min: f32,
    c_max: f32,
    depth: f32,
    // The shadow test's tolerance ε in tiles (`shadow_tolerance`).
    shadow_tolerance: f32,
    albedo: vec4<f32>,
    // The scene's `vdm.refine_texels` (0: the lookup alone).
    refine_texels: u32,
    // The relief's least depth in tiles, depth · (1 − max h).
    top_depth: f32,
    // 1 for the scene's `vdm.shadows: "shell"` (step 7).
    shell_shadows: u32,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var<storage, read> faces: array<Face>;
@group(0) @binding(3) var<uniform> vdm: Vdm;
// W, rows (b·H + j)·W + i, `rank` values each.
@group(0) @binding(4) var<storage, read> weights: array<f32>;
// (Bindings 5–10 are what objects share: `hit_targets.wgsl`, `objects_on.wgsl`.)
// E, rows k·Nθ + a, `rank` values each.
@group(0) @binding(11) var<storage, read> eigen: array<f32>;
// E_MVM, rows k, `mvm_rank` values each.
@group(0) @binding(12) var<storage, read> mvm: array<f32>;
// h(i, j), x fastest.
@group(0) @binding(13) var<storage, read> heights: array<f32>;
// A BVH over the top faces' boxes for step 7 and for other objects' shadow rays (one empty
// node where neither is called for).
@group(0) @binding(14) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(15) var<storage, read> bvh_faces: array<u32>;

// ---- Filtering ------------------------------------------------------------------------

fn height_at(i: u32, j: u32) -> f32 {
    return heights[j * vdm.size.x + i];
}

// The height field, bilinear and periodic.
fn height(t: vec2<f32>) -> f32 {
    let x = periodic_taps(t.x * f32(vdm.size.x) - 0.5, vdm.size.x);
    let y = periodic_taps(t.y * f32(vdm.size.y) - 0.5, vdm.size.y);
    let top = height_at(x.i0, y.i0) * (1.0 - x.frac) + height_at(x.i1, y.i0) * x.frac;
    let bottom = height_at(x.i0, y.i1) * (1.0 - x.frac) + height_at(x.i1, y.i1) * x.frac;
    return top * (1.0 - y.frac) + bottom * y.frac;
}

fn weight_row(i: u32, j: u32, b: u32) -> u32 {
    return ((b * vdm.size.y + j) * vdm.size.x + i) * vdm.rank;
}

struct Sample {
    hit: bool,
    d: f32,
}

// VdmQuery::sample: the displacement at (x, y) for view (θ, φ) and curvature c, or a
// silhouette.
fn sample_vdm(x: f32, y: f32, theta: f32, phi: f32, c: f32) -> Sample {
    var k_f = 0.0;
    if vdm.n_curvature > 1u && vdm.c_max > vdm.c_min {
        k_f = (c - vdm.c_min) / (vdm.c_max - vdm.c_min) * f32(vdm.n_curvature - 1u);
    }
    let k = clamped_taps(k_f, vdm.n_curvature);
    let b = periodic_taps(phi / TAU * f32(vdm.n_phi) - 0.5, vdm.n_phi);
    // The silhouette: W at the texel holding (x, y), linear in φ.
    let i = wrap(i32(floor(x * f32(vdm.size.x))), vdm.size.x);
    let j = wrap(i32(floor(y * f32(vdm.size.y))), vdm.size.y);
    let r0 = weight_row(i, j, b.i0);
    let r1 = weight_row(i, j, b.i1);
    var max_theta = 0.0;
    for (var l = 0u; l < vdm.mvm_rank; l++) {
        let w = weights[r0 + l] * (1.0 - b.frac) + weights[r1 + l] * b.frac;
        let e = mvm[k.i0 * vdm.mvm_rank + l] * (1.0 - k.frac) + mvm[k.i1 * vdm.mvm_rank + l] * k.frac;
        max_theta += w * e;
    }
    if theta > max_theta {
        return Sample(false, 0.0);
    }
    let xi = periodic_taps(x * f32(vdm.size.x) - 0.5, vdm.size.x);
    let yj = periodic_taps(y * f32(vdm.size.y) - 0.5, vdm.size.y);
    let a = clamped_taps(theta / HALF_PI * f32(vdm.n_theta) - 0.5, vdm.n_theta);
    let e00 = (k.i0 * vdm.n_theta + a.i0) * vdm.rank;
    let e01 = (k.i0 * vdm.n_theta + a.i1) * vdm.rank;
    let e10 = (k.i1 * vdm.n_theta + a.i0) * vdm.rank;
    let e11 = (k.i1 * vdm.n_theta + a.i1) * vdm.rank;
    var d = 0.0;
    for (var l = 0u; l < vdm.rank; l++) {
        var w = 0.0;
        for (var c8 = 0u; c8 < 8u; c8++) {
            let bb = select(b.i0, b.i1, (c8 & 4u) != 0u);
            let jj = select(yj.i0, yj.i1, (c8 & 2u) != 0u);
            let ii = select(xi.i0, xi.i1, (c8 & 1u) != 0u);
            let wb = select(1.0 - b.frac, b.frac, (c8 & 4u) != 0u);
            let wj = select(1.0 - yj.frac, yj.frac, (c8 & 2u) != 0u);
            let wi = select(1.0 - xi.frac, xi.frac, (c8 & 1u) != 0u);
            w += wi * wj * wb * weights[weight_row(ii, jj, bb) + l];
        }
        let low = eigen[e00 + l] * (1.0 - a.frac) + eigen[e01 + l] * a.frac;
        let high = eigen[e10 + l] * (1.0 - a.frac) + eigen[e11 + l] * a.frac;
        d += w * (low * (1.0 - k.frac) + high * k.frac);
    }
    return Sample(true, d);
}

// ---- Geometry -------------------------------------------------------------------------

fn apply(rows: array<vec4<f32>, 3>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(rows[0].xyz, v), dot(rows[1].xyz, v), dot(rows[2].xyz, v));
}

fn apply_transposed(rows: array<vec4<f32>, 3>, v: vec3<f32>) -> vec3<f32> {
    return rows[0].xyz * v.x + rows[1].xyz * v.y + rows[2].xyz * v.z;
}


// VertexCurvature::along.
fn along(c: Curvature, d: vec3<f32>) -> f32 {
    let a = dot(d, c.dir_max.xyz);
    let b = dot(d, c.dir_min.xyz);
    let len2 = a * a + b * b;
    if len2 > 0.0 {
        return (c.k.x * a * a + c.k.y * b * b) / len2;
    }
    return 0.0;
}

// The curvature along d interpolated over face fi.
fn corner_curvature(fi: u32, bary: vec3<f32>, d: vec3<f32>) -> f32 {
    var c = 0.0;
    for (var i = 0u; i < 3u; i++) {
        c += bary[i] * along(faces[fi].curvature[i], d);
    }
    return c;
}

// The curvature towards `eye` (per corner) interpolated over face fi.
fn curvature_towards(fi: u32, bary: vec3<f32>, eye: vec3<f32>) -> f32 {
    var c = 0.0;
    for (var i = 0u; i < 3u; i++) {
        let towards = eye - faces[fi].corners[i].xyz;
        c += bary[i] * along(faces[fi].curvature[i], towards);
    }
    return c;
}

// A direction (object space, into the surface) in a face's VDM space.
struct Direction {
    ok: bool,
    theta: f32,
    phi: f32,
    azimuth: vec2<f32>,
    inward: f32,
    tile_length: f32,
}

fn direction(fi: u32, dir: vec3<f32>) -> Direction {
    let v = apply(faces[fi].to_vdm, dir);
    let len2 = dot(v, v);
    if !(len2 > 0.0) {
        return Direction(false, 0.0, 0.0, vec2<f32>(0.0), 0.0, 0.0);
    }
    let d = v * inverseSqrt(len2);
    let inward = -d.z;
    let phi = atan2(d.y, d.x);
    let azimuth = vec2<f32>(cos(phi), sin(phi));
    let tile_length = length(apply(faces[fi].from_vdm, vec3<f32>(azimuth, 0.0)));
    return Direction(true, acos(clamp(inward, -1.0, 1.0)), phi, azimuth, inward, tile_length);
}

// exit_arc (FLAT_CURVATURE = 1e-6): the arc length to where the ray from `depth` below, at θ from the outward
// normal, leaves the surface of curvature c; −1 when it never does.
fn exit_arc(depth: f32, theta: f32, c: f32) -> f32 {
    let s = sin(theta);
    let co = cos(theta);
    if abs(c) < 1e-6 {
        return depth * s / max(co, 1e-12);
    }
    let r = 1.0 / c;
    let half_b = (r - depth) * co;
    let q0 = depth * depth - 2.0 * r * depth;
    let disc = half_b * half_b - q0;
    if disc < 0.0 {
        return -1.0;
    }
    let root = sqrt(disc);
    var s_ray: f32;
    if r > 0.0 {
        s_ray = -q0 / (half_b + root);
    } else {
        s_ray = q0 / (root - half_b);
    }
    if s_ray < 0.0 {
        return -1.0;
    }
    let q = vec2<f32>(s_ray * s, -depth + s_ray * co);
    return r * atan2(sign(r) * q.x, sign(r) * (q.y + r));
}

// The refinement on the height field (`render::vdm_refine`, the same steps): one fragment's
// view ray, entering at T along its azimuth at θ_V, on the surface bent to c (1/tile).
struct BentRay {
    entry: vec2<f32>,
    azimuth: vec2<f32>,
    theta: f32,
    c: f32,
}

const REFINE_STEP: f32 = 0.5;
const REFINE_BISECTIONS: u32 = 6u;

// The relief coordinates (σ, t) of the point at distance τ along the ray.
fn ray_at(r: BentRay, tau: f32) -> vec2<f32> {
    let u = tau * sin(r.theta);
    let w = -tau * cos(r.theta);
    let k = 2.0 * w + r.c * (u * u + w * w);
    let t = -k / (1.0 + sqrt(max(1.0 + r.c * k, 0.0)));
    var sigma = u;
    if abs(r.c) >= 1e-6 {
        sigma = atan2(r.c * u, 1.0 + r.c * w) / r.c;
    }
    return vec2<f32>(sigma, t);
}

fn ray_inside(r: BentRay, tau: f32) -> bool {
    let st = ray_at(r, tau);
    return st.y >= vdm.depth * (1.0 - height(r.entry + r.azimuth * st.x));
}

fn refine_texel() -> f32 {
    return 1.0 / f32(max(vdm.size.x, vdm.size.y));
}

// The first step from `begin` (outside) that lands inside, no further than `end`:
// (1, before, at), or (0, …) without one.
fn first_crossing(r: BentRay, begin: f32, end: f32, step: f32) -> vec3<f32> {
    var a = begin;
    var b = begin + step;
    var found = 0.0;
    loop {
        if b > end {
            break;
        }
        if ray_inside(r, b) {
            found = 1.0;
            break;
        }
        a = b;
        b += step;
    }
    return vec3<f32>(found, a, b);
}

fn ray_bisect(r: BentRay, outside0: f32, inner0: f32) -> f32 {
    var outside = outside0;
    var inner = inner0;
    for (var i = 0u; i < REFINE_BISECTIONS; i++) {
        let mid = 0.5 * (outside + inner);
        if ray_inside(r, mid) {
            inner = mid;
        } else {
            outside = mid;
        }
    }
    return ray_at(r, 0.5 * (outside + inner)).x;
}

// ray_length_to_arc: the distance τ at which the ray lies under arc length σ; −1 for none.
fn ray_length_to_arc(sigma: f32, theta: f32, c: f32) -> f32 {
    if abs(c) < 1e-6 {
        return sigma / sin(theta);
    }
    let alpha = c * sigma;
    let tau = sin(alpha) / (c * sin(theta + alpha));
    if tau >= 0.0 {
        return tau;
    }
    return -1.0;
}

// The arc length σ of the hit refined from the lookup's d.
fn refine_hit(r: BentRay, d: f32, texels: u32) -> f32 {
    let lookup = d * sin(r.theta);
    let texel = refine_texel();
    let window = f32(texels) * texel;
    let step = REFINE_STEP * texel;
    var start = ray_length_to_arc(lookup, r.theta, r.c);
    if start < 0.0 {
        start = d;
    }
    let first = max(start - window, 0.0);
    var outside = first;
    var inner = first;
    if ray_inside(r, first) {
        loop {
            if !(outside > 0.0 && outside > start - 2.0 * window && ray_inside(r, outside)) {
                break;
            }
            inner = outside;
            outside = max(outside - step, 0.0);
        }
    } else {
        let found = first_crossing(r, first, start + window, step);
        if found.x == 0.0 {
            return lookup;
        }
        outside = found.y;
        inner = found.z;
    }
    if ray_inside(r, outside) || !ray_inside(r, inner) {
        return lookup;
    }
    return ray_bisect(r, outside, inner);
}

// A hit the lookup called a miss: (1, σ), or (0, 0).
fn refine_miss(r: BentRay, texels: u32) -> vec2<f32> {
    let co = cos(r.theta);
    let t = vdm.top_depth;
    let e = co * co - r.c * (2.0 * t - r.c * t * t);
    if e < 0.0 {
        return vec2<f32>(0.0);
    }
    let root = sqrt(e);
    let deep = (2.0 * t - r.c * t * t) / (co + root);
    var end = deep + 2.0 * f32(texels) * refine_texel();
    if r.c > 1e-6 {
        end = min(end, (co + root) / r.c);
    }
    if !(deep >= 0.0) {
        return vec2<f32>(0.0);
    }
    if ray_inside(r, deep) {
        return vec2<f32>(1.0, ray_at(r, deep).x);
    }
    let found = first_crossing(r, deep, end, REFINE_STEP * refine_texel());
    if found.x == 0.0 {
        return vec2<f32>(0.0);
    }
    return vec2<f32>(1.0, ray_bisect(r, found.y, found.z));
}

// Steps 2–4 (`VdmRenderer::lookup`): a ray along `dir` entering face fi at texture
// coordinate t, where the surface's curvature along it is c (1/object unit): whether it hits,
// the arc length σ to the hit and its azimuth in texture space.
struct Lookup {
    hit: bool,
    sigma: f32,
    azimuth: vec2<f32>,
}

fn lookup(fi: u32, t: vec2<f32>, dir: vec3<f32>, c: f32) -> Lookup {
    let none = Lookup(false, 0.0, vec2<f32>(0.0));
    let v = direction(fi, dir);
    if !v.ok || v.inward <= 0.0 {
        return none;
    }
    let c_v = c * v.tile_length;
    let d = sample_vdm(t.x, t.y, v.theta, v.phi, c_v);
    var sigma = d.d * sin(v.theta);
    if vdm.refine_texels == 0u {
        if !d.hit {
            return none;
        }
    } else {
        let ray = BentRay(t, v.azimuth, v.theta, c_v);
        if d.hit {
            sigma = refine_hit(ray, d.d, vdm.refine_texels);
        } else {
            let miss = refine_miss(ray, vdm.refine_texels);
            if miss.x == 0.0 {
                return none;
            }
            sigma = miss.y;
        }
    }
    return Lookup(true, sigma, v.azimuth);
}

// Step 6: whether the light from object direction l reaches the hit at T', `depth` below
// the reference surface.
fn lit(fi: u32, bary: vec3<f32>, t_hit: vec2<f32>, depth: f32, l: vec3<f32>) -> bool {
    let light = direction(fi, -l);
    if !light.ok {
        return true;
    }
    if light.inward <= 0.0 {
        return false;
    }
    let c = corner_curvature(fi, bary, l) * light.tile_length;
    let sigma = exit_arc(depth, light.theta, c);
    if sigma < 0.0 {
        return false;
    }
    let theta = clamp(light.theta - c * sigma, 0.0, HALF_PI);
    let entry = t_hit - light.azimuth * sigma;
    let d = sample_vdm(entry.x, entry.y, theta, light.phi, c);
    if !d.hit {
        return true;
    }
    return d.d >= sigma / max(sin(theta), 1e-9) - vdm.shadow_tolerance;
}

// Step 7 (`VdmRenderer::blocked_elsewhere`; named apart from the objects' `blocked_elsewhere`):
// whether the straight ray from o along the light's direction l enters the top surface before
// `distance` at a fragment that is not a silhouette. The traversal is written out as in `shadows_shell.wgsl`: a shared
// `next_leaf` function spent more of llvmpipe's per-invocation loop budget (CPU against
// WGSL, GDM shell shadows: torus-bumps paper-svd high 31.5 dB, under the 33 dB its test
// allows, and four more preset rows under 35 dB).
fn blocked_by_shell(o: vec3<f32>, l: vec3<f32>, distance: f32) -> bool {
    let inv = safe_inverse(l);
    let count = arrayLength(&bvh_nodes);
    var i = 0u;
    while i < count {
        let node = bvh_nodes[i];
        if node_entry(node, o, inv, distance) < 0.0 {
            i = node.skip;
            continue;
        }
        if node.count == 0u {
            i += 1u;
            continue;
        }
        for (var k = 0u; k < node.count; k++) {
            let fi = bvh_faces[node.first + k];
            let c = faces[fi].corners;
            if dot(cross(c[1].xyz - c[0].xyz, c[2].xyz - c[0].xyz), l) >= 0.0 {
                continue; // back-facing
            }
            let h = intersect_triangle(c[0].xyz, c[1].xyz, c[2].xyz, o, l);
            if !(h.x > 0.0 && h.x < distance) {
                continue;
            }
            let bary = vec3<f32>(1.0 - h.y - h.z, h.y, h.z);
            if lookup(fi, texture_at(fi, bary), l, corner_curvature(fi, bary, l)).hit {
                return true;
            }
        }
        i = node.skip;
    }
    return false;
}

// The height field's normal at T' in VDM space.
fn relief_normal(t: vec2<f32>) -> vec3<f32> {
    let dx = 1.0 / f32(vdm.size.x);
    let dy = 1.0 / f32(vdm.size.y);
    let gx = (height(t + vec2<f32>(dx, 0.0)) - height(t - vec2<f32>(dx, 0.0))) / (2.0 * dx);
    let gy = (height(t + vec2<f32>(0.0, dy)) - height(t - vec2<f32>(0.0, dy))) / (2.0 * dy);
    return vec3<f32>(-vdm.depth * gx, -vdm.depth * gy, 1.0);
}

// Lambert + normalized Blinn–Phong from every light, with the VDM shadow test; the lights
// whose bit is set in `blocked` (blocked by other objects) left out.
fn shade(fi: u32, bary: vec3<f32>, t_hit: vec2<f32>, depth: f32, p: vec3<f32>, n: vec3<f32>, to_eye: vec3<f32>, blocked: u32) -> vec3<f32> {
    var out = vec3<f32>(0.0);
    let base = vdm.albedo.rgb;
    // Ambient lights first: llvmpipe ends every loop of an invocation once 65535 iterations
    // have run in all, which a long shadow traversal can spend (docs/BENCHMARKS.md).
    for (var i = 0u; i < view.light_count; i++) {
        if lights[i].kind == 2u {
            out += base * lights[i].colour.rgb;
        }
    }
    for (var i = 0u; i < view.light_count; i++) {
        let light = lights[i];
        if light.kind == 2u {
            continue;
        }
        let inc = light_incidence(light, p);
        if !inc.valid {
            continue;
        }
        let cos_l = dot(n, inc.dir);
        let elsewhere = i < 32u && (blocked & (1u << i)) != 0u;
        if cos_l <= 0.0 || elsewhere || !(vdm.shadows == 0u || lit(fi, bary, t_hit, depth, inc.dir)) {
            continue;
        }
        if vdm.shadows != 0u && vdm.shell_shadows != 0u && blocked_by_shell(p, inc.dir, inc.distance) {
            continue;
        }
        out += direct(n, base, to_eye, inc, cos_l);
    }
    return out;
}

// ---- The pipeline ---------------------------------------------------------------------

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) bary: vec3<f32>,
    @location(2) face: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) bary: vec3<f32>,
    @location(2) @interpolate(flat) face: u32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.bary = v.bary;
    out.face = v.face;
    return out;
}

// Where a ray meets the relief (steps 1–5).
struct VdmHit {
    hit: bool,
    t_hit: vec2<f32>,
    // Below the reference surface, in object units along the VDM's z.
    depth: f32,
    point: vec3<f32>,
    // The view ray's direction.
    dir: vec3<f32>,
}

// The texture coordinate at barycentrics `bary` of face fi.
fn texture_at(fi: u32, bary: vec3<f32>) -> vec2<f32> {
    let uv = faces[fi].uv;
    return bary.x * uv[0].xy + bary.y * uv[1].xy + bary.z * uv[2].xy;
}

// Steps 1–5 at a fragment of face fi (its barycentrics and its point on the top surface):
// where the view ray through it meets the relief.
fn fragment_hit(fi: u32, bary: vec3<f32>, world: vec3<f32>) -> VdmHit {
    return relief_hit(fi, bary, world, normalize(world - view.eye.xyz), view.eye.xyz);
}

// The same along any ray: the one along `dir` that meets face fi at `world`, seen from `eye`
// (for the surface's curvature towards it).
fn relief_hit(fi: u32, bary: vec3<f32>, world: vec3<f32>, dir: vec3<f32>, eye: vec3<f32>) -> VdmHit {
    let t = texture_at(fi, bary);
    let found = lookup(fi, t, dir, curvature_towards(fi, bary, eye));
    if !found.hit {
        return VdmHit(false, t, 0.0, world, dir);
    }
    let offset = found.azimuth * found.sigma;
    let t_hit = t + offset;
    let depth = relief_depth(t_hit);
    let point = world + apply(faces[fi].from_vdm, vec3<f32>(offset, -depth));
    return VdmHit(true, t_hit, depth, point, dir);
}

// The relief's depth below the reference surface at T'.
fn relief_depth(t: vec2<f32>) -> f32 {
    return vdm.depth * (1.0 - height(t));
}

// Step 6 at a hit on face fi (the relief's normal; facing the viewer where degenerate), the
// lights of `blocked`'s bits left out.
fn shade_hit(fi: u32, bary: vec3<f32>, hit: VdmHit, blocked: u32) -> vec3<f32> {
    let n = normalize_or(apply_transposed(faces[fi].to_vdm, relief_normal(hit.t_hit)), -hit.dir);
    return shade(fi, bary, hit.t_hit, hit.depth, hit.point, n, -hit.dir, blocked);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let hit = fragment_hit(in.face, in.bary, in.world);
    if !hit.hit {
        discard;
    }
    return vec4<f32>(shade_hit(in.face, in.bary, hit, 0u), 1.0);
}

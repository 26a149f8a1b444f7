// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// the deep shadow maps and their build.

// ---- Shadow maps --------------------------------------------------------------------------

// The map being written by `cs_shadow_map`.
@group(1) @binding(3) var<storage, read_write> shadow_build: array<f32>;

struct MapRay {
    o: vec3<f32>,
    d: vec3<f32>,
}

// The ray of map point (u, v).
fn map_ray(f: ShadowFrame, u: f32, v: f32) -> MapRay {
    let across = f.u_axis.xyz * u + f.v_axis.xyz * v;
    if f.kind == 1u {
        return MapRay(f.origin.xyz + across, f.axis.xyz);
    }
    return MapRay(f.origin.xyz, normalize(f.axis.xyz + across));
}

// The map point (u, v) and ray parameter t of x, w = 1; w = 0 behind a point light.
fn map_project(f: ShadowFrame, x: vec3<f32>) -> vec4<f32> {
    let d = x - f.origin.xyz;
    let along = dot(d, f.axis.xyz);
    var scale = 1.0;
    var t = along;
    if f.kind == 2u {
        if along <= 0.0 {
            return vec4<f32>(0.0);
        }
        scale = 1.0 / along;
        t = length(d);
    }
    return vec4<f32>(dot(d, f.u_axis.xyz) * f.u_axis.w * scale, dot(d, f.v_axis.xyz) * f.v_axis.w * scale, t, 1.0);
}

// The two texels around map coordinate u and the second one's weight (`texel_span`).
fn texel_span(u: f32, n: u32) -> vec3<f32> {
    let last = f32(n - 1u);
    var f = clamp((u + 1.0) * 0.5 * f32(n) - 0.5, 0.0, last);
    if f != f {
        f = 0.0;
    }
    let i0 = floor(f);
    return vec3<f32>(i0, min(i0 + 1.0, last), f - i0);
}

// Optical depth of deep-map level k (`level_depth`).
fn level_depth(k: u32) -> f32 {
    let levels = medium.shadow_stride - 3u;
    if k + 1u >= levels {
        return MAX_OPTICAL_DEPTH;
    }
    return -log(1.0 - f32(k + 1u) / f32(levels));
}

// The optical depth of the deep-map texel at `at` at ray parameter t
// (`deep_optical_depth`): the polyline through its knots.
fn deep_optical_depth(at: u32, t: f32) -> f32 {
    let ta = shadow_map[at];
    let levels = medium.shadow_stride - 3u;
    if !(t > ta) {
        return 0.0;
    }
    // Levels reached by t: a binary search over the nondecreasing depths, written out step
    // by step for up to 256 levels (loops count against the software driver's budget).
    var k = probe(at, 0u, 128u, t);
    k = probe(at, k, 64u, t);
    k = probe(at, k, 32u, t);
    k = probe(at, k, 16u, t);
    k = probe(at, k, 8u, t);
    k = probe(at, k, 4u, t);
    k = probe(at, k, 2u, t);
    k = probe(at, k, 1u, t);
    if k == levels {
        return MAX_OPTICAL_DEPTH;
    }
    var t0 = ta;
    var tau0 = 0.0;
    if k > 0u {
        t0 = shadow_map[at + 3u + k - 1u];
        tau0 = level_depth(k - 1u);
    }
    var t1 = shadow_map[at + 3u + k];
    var tau1 = level_depth(k);
    if t1 >= FAR {
        t1 = shadow_map[at + 1u];
        tau1 = shadow_map[at + 2u];
    }
    if t >= t1 || t1 <= t0 {
        return tau1;
    }
    return tau0 + (tau1 - tau0) * (t - t0) / (t1 - t0);
}

// One step of the binary search: k + step where the deep-map texel at `at` has at least
// k + step levels and the (k + step)-th is reached by t, else k.
fn probe(at: u32, k: u32, step: u32, t: f32) -> u32 {
    let next = k + step;
    if next <= medium.shadow_stride - 3u && shadow_map[at + 2u + next] <= t {
        return next;
    }
    return k;
}

// exp(−τ), 0 from MAX_OPTICAL_DEPTH.
fn transmittance_of(tau: f32) -> f32 {
    return select(exp(-tau), 0.0, tau >= MAX_OPTICAL_DEPTH);
}

// The fraction of the light of frame f that reaches x, looked up from `start` towards the
// light (`ShadowMap::visibility`).
fn map_visibility(f: ShadowFrame, x: vec3<f32>, start: f32) -> f32 {
    let p = map_project(f, x);
    if p.w == 0.0 {
        return 1.0;
    }
    let t = p.z - start;
    let n = medium.shadow_size;
    let si = texel_span(p.x, n);
    let sj = texel_span(p.y, n);
    let stride = medium.shadow_stride;
    let i = vec2<u32>(u32(si.x), u32(si.y));
    let j = vec2<u32>(u32(sj.x), u32(sj.y));
    let w = vec4<f32>((1.0 - si.z) * (1.0 - sj.z), si.z * (1.0 - sj.z), (1.0 - si.z) * sj.z, si.z * sj.z);
    let at = vec4<u32>(j.x * n + i.x, j.x * n + i.y, j.y * n + i.x, j.y * n + i.y) * stride + f.first;
    if medium.shadows == 2u {
        let tau = vec4<f32>(deep_optical_depth(at.x, t), deep_optical_depth(at.y, t), deep_optical_depth(at.z, t), deep_optical_depth(at.w, t));
        return dot(w, vec4<f32>(transmittance_of(tau.x), transmittance_of(tau.y), transmittance_of(tau.z), transmittance_of(tau.w)));
    }
    let lit = vec4<f32>(vec4<bool>(t < shadow_map[at.x], t < shadow_map[at.y], t < shadow_map[at.z], t < shadow_map[at.w]));
    return dot(w, lit);
}

// Extinction per voxel length of opacity alpha.
fn extinction(alpha: f32) -> f32 {
    if alpha >= 1.0 {
        return OPAQUE_EXTINCTION;
    }
    return -log(1.0 - alpha);
}

// The texel being built: optical depth so far, next level, where the medium starts and
// ends (deep map), the depth-map depth.
var<private> map_tau: f32;
var<private> map_k: u32;
var<private> map_first: f32;
var<private> map_end: f32;
var<private> map_depth: f32;

// Records the piece [ta, tb] of optical depth `piece` into the texel at `base`; false once
// the texel is done.
fn map_piece(base: u32, ta: f32, tb: f32, piece: f32) -> bool {
    if medium.shadows == 3u {
        if map_tau + piece >= DEPTH_THRESHOLD {
            map_depth = ta + (tb - ta) * ((DEPTH_THRESHOLD - map_tau) / piece);
            return false;
        }
        map_tau += piece;
        return true;
    }
    if piece <= 0.0 {
        return true;
    }
    map_first = min(map_first, ta);
    let levels = medium.shadow_stride - 3u;
    while map_k < levels && map_tau + piece >= level_depth(map_k) {
        steps += 1u;
        shadow_build[base + 3u + map_k] = ta + (tb - ta) * ((level_depth(map_k) - map_tau) / piece);
        map_k += 1u;
    }
    map_tau += piece;
    map_end = tb;
    if map_k == levels {
        map_end = shadow_build[base + 3u + levels - 1u];
        map_tau = MAX_OPTICAL_DEPTH;
        return false;
    }
    return true;
}

// Records the crossing r of cell ci by o + t·d, in level 0 (`optical_depths`); false once
// the texel is done.
fn map_crossing(base: u32, ci: u32, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> bool {
    let a = to_texture(ci, o + d * r.x);
    let b = to_texture(ci, o + d * r.y);
    let len = length(b - a);
    var going = true;
    if len == 0.0 {
        return true;
    }
    let dt = (r.y - r.x) / len;
    if medium.integration == 1u {
        let part = len / f32(medium.samples);
        for (var i = 0u; i < medium.samples && going; i++) {
            steps += 1u;
            let s = (f32(i) + 0.5) * part;
            let v = voxel_at(0u, a + (b - a) * (s / len));
            if v >= 0 {
                let ta = r.x + (s - 0.5 * part) * dt;
                let tb = r.x + (s + 0.5 * part) * dt;
                going = map_piece(base, ta, tb, extinction(voxels[v].a) * part);
            }
        }
        return going;
    }
    var w = walk_start(a, (b - a) / len, len);
    while going && walk_next(&w, 0u) {
        steps += 1u;
        let piece = extinction(voxels[w.v].a) * (w.s1 - w.s0);
        going = map_piece(base, r.x + w.s0 * dt, r.x + w.s1 * dt, piece);
    }
    return going;
}

// One invocation per texel (x, y) of light z's map: its ray's optical depth through the
// cells, in order.
@compute @workgroup_size(8, 8)
fn cs_shadow_map(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = medium.shadow_size;
    if id.x >= n || id.y >= n || id.z >= view.light_count {
        return;
    }
    let f = shadow_frames[id.z];
    if f.kind == 0u {
        return;
    }
    steps = 0u;
    let ray = map_ray(f, 2.0 * (f32(id.x) + 0.5) / f32(n) - 1.0, 2.0 * (f32(id.y) + 0.5) / f32(n) - 1.0);
    let stride = medium.shadow_stride;
    let base = f.first + (id.y * n + id.x) * stride;
    let inv = safe_inverse(ray.d);
    let t0 = f.origin.w;
    let t1 = t0 + f.axis.w;
    map_tau = 0.0;
    map_k = 0u;
    map_first = FAR;
    map_end = FAR;
    map_depth = FAR;
    if medium.shadows == 2u {
        for (var k = 0u; k < stride - 3u; k++) {
            steps += 1u;
            shadow_build[base + 3u + k] = FAR;
        }
    }
    var last_t = -FAR;
    var last_cell = 0u;
    var going = true;
    var more = true;
    while going && more {
        steps += 1u;
        more = next_batch(ray.o, ray.d, inv, t0, t1, last_t, last_cell);
        for (var c = 0u; c < batch_n && going; c++) {
            steps += 1u;
            going = map_crossing(base, batch_cell[c], ray.o, ray.d, vec2<f32>(batch_t_in[c], batch_t_out[c]));
        }
        if more {
            last_t = batch_t_in[batch_n - 1u];
            last_cell = batch_cell[batch_n - 1u];
        }
    }
    if medium.shadows == 3u {
        shadow_build[base] = map_depth;
    } else {
        shadow_build[base] = map_first;
        shadow_build[base + 1u] = map_end;
        shadow_build[base + 2u] = map_tau;
    }
    if medium.loop_budget > 0u && steps >= medium.loop_budget {
        atomicAdd(&overflow[1], 1u);
    }
}

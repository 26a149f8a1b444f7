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
// Preceded by `common.wgsl`.

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

// ---- Rays and cells ---------------------------------------------------------------------

// The camera ray's unit direction through the pixel whose centre is `pixel` (framebuffer
// coordinates, as `Camera::ray`).
fn camera_ray(pixel: vec2<f32>) -> vec3<f32> {
    let sx = pixel.x / f32(view.width) * 2.0 - 1.0;
    let sy = 1.0 - pixel.y / f32(medium.height) * 2.0;
    return normalize(medium.forward.xyz + medium.right.xyz * sx + medium.up.xyz * sy);
}

// Whether a cell owns the face with outward normal n when a ray lies in it: n's first
// non-zero component is negative.
fn owns(n: vec3<f32>) -> bool {
    if n.x != 0.0 {
        return n.x < 0.0;
    }
    if n.y != 0.0 {
        return n.y < 0.0;
    }
    return n.z < 0.0;
}

// The stretch (entry, exit) of o + t·d, t ∈ [t_min, t_max], inside cell ci; entry ≥ exit
// when the ray misses it.
fn clip(ci: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> vec2<f32> {
    // Written out plane by plane: loops count against the software driver's budget.
    var r = vec2<f32>(t_min, t_max);
    r = clip_plane(cells[ci].planes[0], o, d, r);
    r = clip_plane(cells[ci].planes[1], o, d, r);
    r = clip_plane(cells[ci].planes[2], o, d, r);
    return clip_plane(cells[ci].planes[3], o, d, r);
}

// (entry, exit) narrowed by the plane p; entry ≥ exit once missed.
fn clip_plane(p: vec4<f32>, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> vec2<f32> {
    let along = dot(p.xyz, d);
    let inside = p.w - dot(p.xyz, o);
    if along == 0.0 {
        if inside < 0.0 || (inside == 0.0 && !owns(p.xyz)) {
            return vec2<f32>(1.0, 0.0);
        }
        return r;
    }
    if along > 0.0 {
        return vec2<f32>(r.x, min(r.y, inside / along));
    }
    return vec2<f32>(max(r.x, inside / along), r.y);
}

fn to_texture(ci: u32, p: vec3<f32>) -> vec3<f32> {
    let m = cells[ci].to_texture;
    return vec3<f32>(dot(m[0].xyz, p) + m[0].w, dot(m[1].xyz, p) + m[1].w, dot(m[2].xyz, p) + m[2].w);
}

// The linear part of M^{o→t} applied to a direction.
fn texture_direction(ci: u32, d: vec3<f32>) -> vec3<f32> {
    let m = cells[ci].to_texture;
    return vec3<f32>(dot(m[0].xyz, d), dot(m[1].xyz, d), dot(m[2].xyz, d));
}

// The mip level of a crossing entered at t_in (`level_for` in the specification).
fn level_for(ci: u32, t_in: f32) -> u32 {
    if medium.level_count <= 1u {
        return 0u;
    }
    let footprint = max(t_in, 0.0) * medium.forward.w * cells[ci].normal_to_object[0].w;
    if !(footprint > 0.0 && footprint < FAR) {
        return 0u;
    }
    let lambda = log2(footprint) + medium.mip_bias;
    return u32(clamp(round(lambda), 0.0, f32(medium.level_count - 1u)));
}

// ---- The medium ---------------------------------------------------------------------------

// Index of voxel (i, j, k) (i, j periodic) of a level, or −1 outside its layers.
fn voxel_index(level: u32, i: i32, j: i32, k: i32) -> i32 {
    let d = medium.levels[level];
    if k < 0 || k >= i32(d.z) {
        return -1;
    }
    return i32(d.w + wrap(i, d.x) + d.x * (wrap(j, d.y) + d.y * u32(k)));
}

// The voxel containing texture point t (voxel units of the level), or −1.
fn voxel_at(level: u32, t: vec3<f32>) -> i32 {
    let c = vec3<i32>(floor(t));
    return voxel_index(level, c.x, c.y, c.z);
}

// Transmittance of `len` voxel lengths of opacity `alpha`: (1 − α)^len.
fn transmit(alpha: f32, len: f32) -> f32 {
    if alpha >= 1.0 {
        return select(1.0, 0.0, len > 0.0);
    }
    return pow(1.0 - alpha, len);
}

// Unit texture-space normal at t, trilinear over voxel centres (x, y periodic, z clamped);
// zero where the gradient vanishes.
fn normal_at(level: u32, t: vec3<f32>) -> vec3<f32> {
    let d = medium.levels[level];
    let f = vec3<f32>(t.x - 0.5, t.y - 0.5, clamp(t.z - 0.5, 0.0, f32(d.z - 1u)));
    let base = floor(f);
    let w1 = f - base;
    let w0 = 1.0 - w1;
    let b = vec3<i32>(base);
    let k0 = i32(min(u32(b.z), d.z - 1u));
    let k1 = i32(min(u32(b.z) + 1u, d.z - 1u));
    // The eight corners written out (loops count against the software driver's budget).
    var n = corner_normal(level, b.x, b.y, k0, w0.x * w0.y * w0.z);
    n += corner_normal(level, b.x + 1, b.y, k0, w1.x * w0.y * w0.z);
    n += corner_normal(level, b.x, b.y + 1, k0, w0.x * w1.y * w0.z);
    n += corner_normal(level, b.x + 1, b.y + 1, k0, w1.x * w1.y * w0.z);
    n += corner_normal(level, b.x, b.y, k1, w0.x * w0.y * w1.z);
    n += corner_normal(level, b.x + 1, b.y, k1, w1.x * w0.y * w1.z);
    n += corner_normal(level, b.x, b.y + 1, k1, w0.x * w1.y * w1.z);
    n += corner_normal(level, b.x + 1, b.y + 1, k1, w1.x * w1.y * w1.z);
    return normalize_or(n, vec3<f32>(0.0));
}

// The weighted normal of one interpolation corner (none at weight 0).
fn corner_normal(level: u32, i: i32, j: i32, k: i32, w: f32) -> vec3<f32> {
    if w == 0.0 {
        return vec3<f32>(0.0);
    }
    return normals[voxel_index(level, i, j, k)].xyz * w;
}

// ---- Voxel traversal ----------------------------------------------------------------------

// The exact voxel walk of a segment (`Medium::walk`): start with `walk_start`, then call
// `walk_next` until it returns false; each call leaves the piece [s0, s1] of voxel `v`.
struct Walk {
    cell: vec3<i32>,
    next: vec3<f32>,
    delta: vec3<f32>,
    step: vec3<i32>,
    s: f32,
    len: f32,
    // The current piece.
    v: i32,
    s0: f32,
    s1: f32,
}

fn walk_start(o: vec3<f32>, d: vec3<f32>, len: f32) -> Walk {
    var w: Walk;
    w.s = 0.0;
    w.len = len;
    let fl = floor(o);
    let moving = d != vec3<f32>(0.0);
    let up = d > vec3<f32>(0.0);
    // Going down from exactly on a voxel face: the voxel below, a whole voxel ahead.
    let on_face = !up & moving & (fl == o);
    w.cell = vec3<i32>(fl) - select(vec3<i32>(0), vec3<i32>(1), on_face);
    w.step = select(vec3<i32>(0), select(vec3<i32>(-1), vec3<i32>(1), up), moving);
    w.delta = select(vec3<f32>(FAR), 1.0 / abs(d), moving);
    let ahead = select((o - fl) / -d, (fl + 1.0 - o) / d, up);
    w.next = select(vec3<f32>(FAR), select(ahead, w.delta, on_face), moving);
    return w;
}

// Advances to the next piece inside the level's layers; false when the segment is done.
// (Vector selects rather than indexing a vector by a varying axis, and loops that leave by
// their conditions: Mesa's software driver of Debian 12 mis-executes both when invocations
// diverge.)
fn walk_next(w: ptr<function, Walk>, level: u32) -> bool {
    let z = i32(medium.levels[level].z);
    var found = false;
    while !found && (*w).s < (*w).len {
        steps += 1u;
        let n = (*w).next;
        // The axis whose face comes first (the first of equals).
        let x = n.x <= n.y && n.x <= n.z;
        let y = !x && n.y <= n.z;
        let axis = vec3<bool>(x, y, !x && !y);
        let end = min(min(n.x, min(n.y, n.z)), (*w).len);
        let c = (*w).cell;
        let start = (*w).s;
        (*w).s = end;
        (*w).cell += select(vec3<i32>(0), (*w).step, axis);
        (*w).next += select(vec3<f32>(0.0), (*w).delta, axis);
        if c.z >= 0 && c.z < z {
            (*w).v = voxel_index(level, c.x, c.y, c.z);
            (*w).s0 = start;
            (*w).s1 = end;
            found = true;
        } else if (c.z < 0 && (*w).step.z <= 0) || (c.z >= z && (*w).step.z >= 0) {
            // Left the layers for good.
            (*w).s = (*w).len;
        }
    }
    return found;
}

// ---- Shadow rays --------------------------------------------------------------------------

// Transmittance of the crossing [t_in, t_out] of cell ci by o + t·d in a level (the walk
// stops once below `min_transmittance`).
fn crossing_transmittance(ci: u32, level: u32, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> f32 {
    let texel = exp2(-f32(level));
    let a = to_texture(ci, o + d * r.x) * texel;
    let b = to_texture(ci, o + d * r.y) * texel;
    let len = length(b - a);
    var t = 1.0;
    if len == 0.0 {
        t = 1.0;
    } else if medium.integration == 1u {
        let part = len / f32(medium.samples);
        for (var i = 0u; i < medium.samples; i++) {
            steps += 1u;
            let v = voxel_at(level, a + (b - a) * ((f32(i) + 0.5) / f32(medium.samples)));
            if v >= 0 {
                t *= transmit(voxels[v].a, part);
            }
        }
    } else {
        var w = walk_start(a, (b - a) / len, len);
        while t >= medium.min_transmittance && walk_next(&w, level) {
            steps += 1u;
            t *= transmit(voxels[w.v].a, w.s1 - w.s0);
        }
    }
    return t;
}

// Transmittance through the cells along o + t·d, t ∈ [t_min, t_max] (any order: it is a
// product); 0 once below `min_transmittance`.
fn transmittance(level: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> f32 {
    let inv = safe_inverse(d);
    let count = arrayLength(&bvh_nodes);
    var t = 1.0;
    var i = 0u;
    while i < count && t >= medium.min_transmittance {
        steps += 1u;
        let node = bvh_nodes[i];
        if node_entry(node, o, inv, t_max) < 0.0 {
            i = node.skip;
        } else if node.count == 0u {
            i += 1u;
        } else {
            for (var k = 0u; k < node.count && t >= medium.min_transmittance; k++) {
                steps += 1u;
                let ci = bvh_cells[node.first + k];
                let r = clip(ci, o, d, t_min, t_max);
                if r.x < r.y {
                    t *= crossing_transmittance(ci, level, o, d, r);
                }
            }
            i = node.skip;
        }
    }
    return select(t, 0.0, t < medium.min_transmittance);
}

// ---- Shading and compositing --------------------------------------------------------------

// Loop iterations this invocation has run (see `loop_budget`).
var<private> steps: u32;

// Composited radiance over black (premultiplied) and the transmittance so far.
var<private> gathered_radiance: vec3<f32>;
var<private> gathered_transmittance: f32;

// Composites a piece absorbing `absorbed` and scattering `light` behind what is gathered;
// false once the ray is absorbed.
fn composite(light: vec3<f32>, absorbed: f32) -> bool {
    gathered_radiance += light * (gathered_transmittance * absorbed);
    gathered_transmittance *= 1.0 - absorbed;
    if gathered_transmittance < medium.min_transmittance {
        gathered_transmittance = 0.0;
        return false;
    }
    return true;
}

// The light scattered towards the eye at `point` (texture point `t` of a level, voxel v,
// in cell ci) under every light, each weighted by the transmittance towards it
// (`shade_transmitted`).
fn scattered(ci: u32, level: u32, point: vec3<f32>, t: vec3<f32>, v: i32, to_eye: vec3<f32>) -> vec3<f32> {
    let albedo = voxels[v].rgb;
    let m = cells[ci].normal_to_object;
    let nt = normal_at(level, t);
    let n_object = normalize_or(vec3<f32>(dot(m[0].xyz, nt), dot(m[1].xyz, nt), dot(m[2].xyz, nt)), vec3<f32>(0.0));
    let has_normal = dot(n_object, n_object) > 0.0;
    var out = vec3<f32>(0.0);
    for (var li = 0u; li < view.light_count; li++) {
        steps += 1u;
        let light = lights[li];
        if light.kind == 2u {
            out += albedo * light.colour.rgb;
            continue;
        }
        let inc = light_incidence(light, point);
        if !inc.valid {
            continue;
        }
        let n = select(inc.dir, n_object, has_normal);
        let cos_l = dot(n, inc.dir);
        if cos_l <= 0.0 {
            continue;
        }
        var visible = 1.0;
        if medium.shadows > 0u {
            // The object distance that is `shadow_start` voxels towards the light.
            let start = medium.shadow_start / length(texture_direction(ci, inc.dir));
            let frame = shadow_frames[li];
            if start >= inc.distance {
                visible = 1.0;
            } else if medium.shadows == 1u || frame.kind == 0u {
                visible = transmittance(level, point, inc.dir, start, inc.distance);
            } else {
                visible = map_visibility(frame, point, start);
            }
        }
        if visible > 0.0 {
            out += direct(n, albedo, to_eye, inc, cos_l) * visible;
        }
    }
    return out;
}

// Integrates the crossing r = (t_in, t_out) of cell ci by the camera ray o + t·d in a level
// and composites it; false once the ray is absorbed.
fn integrate(ci: u32, level: u32, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> bool {
    let texel = exp2(-f32(level));
    let a = to_texture(ci, o + d * r.x) * texel;
    let b = to_texture(ci, o + d * r.y) * texel;
    let len = length(b - a);
    var going = true;
    if len == 0.0 {
        return true;
    }
    // Ray parameter per texture-space length.
    let dt = (r.y - r.x) / len;
    let dir_t = (b - a) / len;
    if medium.integration == 1u {
        let part = len / f32(medium.samples);
        for (var i = 0u; i < medium.samples && going; i++) {
            steps += 1u;
            let s = (f32(i) + 0.5) * part;
            let t = a + (b - a) * (s / len);
            let v = voxel_at(level, t);
            if v >= 0 {
                let absorbed = 1.0 - transmit(voxels[v].a, part);
                if absorbed > 0.0 {
                    let light = scattered(ci, level, o + d * (r.x + s * dt), t, v, -d);
                    going = composite(light, absorbed);
                }
            }
        }
        return going;
    }
    var w = walk_start(a, dir_t, len);
    while going && walk_next(&w, level) {
        steps += 1u;
        let alpha = voxels[w.v].a;
        if alpha > 0.0 {
            // The voxel's stretch in pieces at most `light_step` long, lit at their starts.
            let pieces = max(ceil((w.s1 - w.s0) / medium.light_step), 1.0);
            for (var p = 0.0; p < pieces && going; p += 1.0) {
                steps += 1u;
                let u0 = w.s0 + (w.s1 - w.s0) * p / pieces;
                let u1 = w.s0 + (w.s1 - w.s0) * (p + 1.0) / pieces;
                let absorbed = 1.0 - transmit(alpha, u1 - u0);
                if absorbed > 0.0 {
                    let point = o + d * (r.x + u0 * dt);
                    let light = scattered(ci, level, point, a + dir_t * u0, w.v, -d);
                    going = composite(light, absorbed);
                }
            }
        }
    }
    return going;
}

// What `gathered_*` hold as the target's texel: premultiplied radiance and 1 − T.
fn gathered() -> vec4<f32> {
    return vec4<f32>(gathered_radiance, 1.0 - gathered_transmittance);
}

// ---- Per-pixel sorted list ------------------------------------------------------------

// Whether the crossing (t, cell) comes after (last_t, last_cell) in the list's order:
// by entry, then by cell index.
fn after(t: f32, cell: u32, last_t: f32, last_cell: u32) -> bool {
    return t > last_t || (t == last_t && cell > last_cell);
}

// The batch of crossings `next_batch` gathered: `batch_n` of them, sorted.
var<private> batch_t_in: array<f32, BATCH>;
var<private> batch_t_out: array<f32, BATCH>;
var<private> batch_cell: array<u32, BATCH>;
var<private> batch_n: u32;

// Gathers the BATCH nearest crossings of o + t·d (inv = 1/d), t ∈ [t_min, t_max], after
// (last_t, last_cell) into `batch_*`, sorted; true when more remain after them.
fn next_batch(o: vec3<f32>, d: vec3<f32>, inv: vec3<f32>, t_min: f32, t_max: f32, last_t: f32, last_cell: u32) -> bool {
    let count = arrayLength(&bvh_nodes);
    var n = 0u;
    var more = false;
    var i = 0u;
    while i < count {
        steps += 1u;
        let node = bvh_nodes[i];
        if node_entry(node, o, inv, t_max) < 0.0 {
            i = node.skip;
        } else if node.count == 0u {
            i += 1u;
        } else {
            for (var k = 0u; k < node.count; k++) {
                steps += 1u;
                let ci = bvh_cells[node.first + k];
                let r = clip(ci, o, d, t_min, t_max);
                var keep = r.x < r.y && after(r.x, ci, last_t, last_cell);
                if keep && n == BATCH {
                    // Full: the new crossing replaces the last if it comes before it.
                    more = true;
                    keep = after(batch_t_in[n - 1u], batch_cell[n - 1u], r.x, ci);
                    if keep {
                        n -= 1u;
                    }
                }
                if keep {
                    // Insertion into the sorted batch.
                    var j = n;
                    while j > 0u && after(batch_t_in[j - 1u], batch_cell[j - 1u], r.x, ci) {
                        steps += 1u;
                        batch_t_in[j] = batch_t_in[j - 1u];
                        batch_t_out[j] = batch_t_out[j - 1u];
                        batch_cell[j] = batch_cell[j - 1u];
                        j -= 1u;
                    }
                    batch_t_in[j] = r.x;
                    batch_t_out[j] = r.y;
                    batch_cell[j] = ci;
                    n += 1u;
                }
            }
            i = node.skip;
        }
    }
    batch_n = n;
    return more;
}

// What the camera ray through the pixel centred at `pixel` gathers: the per-pixel sorted list
// of its cells, composited front to back in batches.
fn gather_pixel(pixel: vec2<f32>) -> vec4<f32> {
    let o = view.eye.xyz;
    let d = camera_ray(pixel);
    let inv = safe_inverse(d);
    gathered_radiance = vec3<f32>(0.0);
    gathered_transmittance = 1.0;
    // The last crossing composited (none yet: before every crossing).
    var last_t = -FAR;
    var last_cell = 0u;
    var going = true;
    var more = true;
    while going && more {
        steps += 1u;
        more = next_batch(o, d, inv, 0.0, FAR, last_t, last_cell);
        for (var c = 0u; c < batch_n && going; c++) {
            steps += 1u;
            let level = level_for(batch_cell[c], batch_t_in[c]);
            going = integrate(batch_cell[c], level, o, d, vec2<f32>(batch_t_in[c], batch_t_out[c]));
        }
        if more {
            last_t = batch_t_in[batch_n - 1u];
            last_cell = batch_cell[batch_n - 1u];
        }
    }
    return gathered();
}

// The target, written by `cs_pixels`.
@group(1) @binding(0) var image: texture_storage_2d<rgba32float, write>;
// Pixels (0) and shadow-map texels (1) whose invocation ran out of `loop_budget`.
@group(1) @binding(1) var<storage, read_write> overflow: array<atomic<u32>, 2>;
// Every light's shadow map, as `cs_shadow_map` wrote it.
@group(1) @binding(2) var<storage, read> shadow_map: array<f32>;

// One invocation per pixel (a compute pass: no quads, no helper invocations).
@compute @workgroup_size(8, 8)
fn cs_pixels(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= view.width || id.y >= medium.height {
        return;
    }
    steps = 0u;
    let value = gather_pixel(vec2<f32>(id.xy) + 0.5);
    if medium.loop_budget > 0u && steps >= medium.loop_budget {
        atomicAdd(&overflow[0], 1u);
    }
    textureStore(image, vec2<i32>(id.xy), value);
}

// ---- Cells drawn in a per-view order --------------------------------------------------

struct CellOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) cell: u32,
}

// The cells in drawing order (back to front), written per frame.
@group(0) @binding(8) var<storage, read> order: array<u32>;

@vertex
fn vs_cell(@builtin(vertex_index) i: u32, @builtin(instance_index) instance: u32) -> CellOut {
    // Instance n draws cell order[n]; vertex i is corner i % 3 of its face i / 3 (face f
    // leaves out corner f), wound counter-clockwise seen from outside.
    let ci = order[instance];
    let f = i / 3u;
    var idx = array<u32, 3>((f + 1u) % 4u, (f + 2u) % 4u, (f + 3u) % 4u);
    let e1 = cells[ci].corners[idx[1]].xyz - cells[ci].corners[idx[0]].xyz;
    let e2 = cells[ci].corners[idx[2]].xyz - cells[ci].corners[idx[0]].xyz;
    if dot(cross(e1, e2), cells[ci].planes[f].xyz) < 0.0 {
        let s = idx[1];
        idx[1] = idx[2];
        idx[2] = s;
    }
    return CellOut(view.view_proj * vec4<f32>(cells[ci].corners[idx[i % 3u]].xyz, 1.0), ci);
}

@fragment
fn fs_cell(in: CellOut) -> @location(0) vec4<f32> {
    let o = view.eye.xyz;
    let d = camera_ray(in.clip.xy);
    let r = clip(in.cell, o, d, 0.0, FAR);
    if !(r.x < r.y) {
        discard;
    }
    gathered_radiance = vec3<f32>(0.0);
    gathered_transmittance = 1.0;
    integrate(in.cell, level_for(in.cell, r.x), o, d, r);
    return gathered();
}

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

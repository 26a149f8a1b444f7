// What both real-time pipelines share (prepended to `gdm_preview.wgsl`'s variants and to
// `vdm_preview.wgsl`): constants, the view and light records of bind group 0,
// `normalize_or`, linear interpolation taps, the direct lighting of one light, the
// stackless traversal of a BVH's nodes and the ray–triangle test.

const PI: f32 = 3.141592653589793;
const TAU: f32 = 6.283185307179586;

struct View {
    view_proj: mat4x4<f32>,
    // xyz: eye position.
    eye: vec4<f32>,
    // rgb: Blinn–Phong specular colour, a: shininess.
    specular: vec4<f32>,
    light_count: u32,
    // Image width in pixels (the row stride of `nearest_hit`).
    width: u32,
    // The object drawn, in a scene of several (its index among them; 0 for one object).
    object: u32,
    _pad: u32,
}

struct Light {
    // 0 point, 1 directional, 2 ambient.
    kind: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // Point: position; directional: the direction the light travels.
    vector: vec4<f32>,
    // Point: intensity; directional: irradiance; ambient: radiance.
    colour: vec4<f32>,
}

fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len2 = dot(v, v);
    if len2 > 0.0 && len2 < 3.0e38 {
        return v * inverseSqrt(len2);
    }
    return fallback;
}

// ---- Interpolation taps ---------------------------------------------------------------

// Linear interpolation taps along one axis: two indices and the weight of the second.
struct Taps {
    i0: u32,
    i1: u32,
    frac: f32,
}

// i modulo n, in [0, n). By the floor of an f32 quotient, not `%`: x86 has no vector
// integer division, so Mesa's software rasterizer would divide lane by lane. Exact for
// |i| < 2^24, where the f32 quotient's floor is exact, and by one correction either way a
// little beyond; in [0, n) always (tests/scene/preview.rs checks it against the integer
// remainder).
fn wrap(i: i32, n: u32) -> u32 {
    let m = i32(n);
    var r = i - i32(floor(f32(i) / f32(m))) * m;
    r = select(r, r + m, r < 0);
    r = select(r, r - m, r >= m);
    return u32(clamp(r, 0, m - 1));
}

fn periodic_taps(coord: f32, n: u32) -> Taps {
    let f = floor(coord);
    let i = i32(f);
    return Taps(wrap(i, n), wrap(i + 1, n), coord - f);
}

fn clamped_taps(coord: f32, n: u32) -> Taps {
    let c = clamp(coord, 0.0, f32(n - 1u));
    let f = floor(c);
    let i = u32(f);
    return Taps(i, min(i + 1u, n - 1u), c - f);
}

// A point or directional light as seen from p (`incident` in crates/mesobake-render/src/lighting.rs): the
// unit direction towards it, its distance (3e38 for directional lights) and the irradiance
// on a surface facing it; `valid` is false for a point light at p itself.
struct Incident {
    valid: bool,
    dir: vec3<f32>,
    distance: f32,
    irradiance: vec3<f32>,
}

fn light_incidence(light: Light, p: vec3<f32>) -> Incident {
    if light.kind == 0u {
        let to = light.vector.xyz - p;
        let r2 = dot(to, to);
        if r2 <= 0.0 {
            return Incident(false, vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
        }
        let distance = sqrt(r2);
        return Incident(true, to / distance, distance, light.colour.rgb / r2);
    }
    return Incident(true, -normalize(light.vector.xyz), 3.0e38, light.colour.rgb);
}

// Lambert + normalized Blinn–Phong of one visible light arriving at cos_l = n·l > 0.
fn direct(n: vec3<f32>, base: vec3<f32>, to_eye: vec3<f32>, inc: Incident, cos_l: f32) -> vec3<f32> {
    let s = view.specular.w;
    let h = normalize_or(inc.dir + to_eye, vec3<f32>(0.0));
    let lobe = view.specular.rgb * ((s + 8.0) / (8.0 * PI) * pow(max(dot(n, h), 0.0), s));
    return (base / PI + lobe) * inc.irradiance * cos_l;
}

// ---- BVH nodes ------------------------------------------------------------------------

// Nodes in depth-first order: an inner node's first child follows it; `skip` is the node
// after its subtree (the node count at the end), so traversal needs no stack.
struct BvhNode {
    lo: vec3<f32>,
    // 0: an inner node; else a leaf of `count` primitives (prisms, cells) listed from
    // `first` in the pipeline's index list.
    count: u32,
    hi: vec3<f32>,
    first: u32,
    skip: u32,
}

// 1 / dir with zero components replaced by a tiny positive one: their slabs then span all
// of space.
fn safe_inverse(dir: vec3<f32>) -> vec3<f32> {
    return 1.0 / select(dir, vec3<f32>(1.0e-30), abs(dir) < vec3<f32>(1.0e-30));
}

// Entry distance (≥ 0) of the ray o + t·d (inv = 1/d) into the node's box before t_max, or
// −1 when it misses.
fn node_entry(node: BvhNode, o: vec3<f32>, inv: vec3<f32>, t_max: f32) -> f32 {
    let a = (node.lo - o) * inv;
    let b = (node.hi - o) * inv;
    let near = max(max(min(a.x, b.x), min(a.y, b.y)), max(min(a.z, b.z), 0.0));
    let far = min(min(max(a.x, b.x), max(a.y, b.y)), min(max(a.z, b.z), t_max));
    return select(-1.0, near, near <= far);
}

// ---- Triangles ------------------------------------------------------------------------

// Edge tolerance of the ray–triangle test, in barycentric units: rays through shared edges
// and vertices meet at least one neighbour.
const EDGE: f32 = 1.0e-6;

// Möller–Trumbore: (t, b1, b2) of the ray o + t·d on the triangle (a, b, c); t ≤ 0 for
// none.
fn intersect_triangle(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if det == 0.0 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = dot(s, pv) * inv;
    let qv = cross(s, e1);
    let v = dot(d, qv) * inv;
    if u < -EDGE || v < -EDGE || u + v > 1.0 + EDGE {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    return vec3<f32>(dot(e2, qv) * inv, u, v);
}

// The GDM real-time pipeline: the per-pixel algorithm of `crates/mesobake-render/src/gdm_renderer.rs`, step
// for step (that file's module documentation is the specification; the tests hold the two
// to PSNR ≥ 35 dB). This file is completed by one query file for the package's GDM codec
// (`query_svd.wgsl` or `query_occupancy.wgsl`: group 1, `segment_hit` and `escapes`), one
// shadow file (`shadows_off.wgsl`, `shadows_local.wgsl` or `shadows_shell.wgsl`:
// `light_visible`; `shell_trace.wgsl` before the shell's), one environment file (`gi_on.wgsl`
// or `gi_off.wgsl`), one objects file (`objects_on.wgsl`, with `shell_trace.wgsl`, or
// `objects_off.wgsl`: `blocked_elsewhere`) and by the constants REFINEMENTS, CHORDS and
// JACOBIAN_FRAME, chosen from the package and the scene's effects and quality
// (`crates/mesobake-gpu/src/variant.rs`); `common.wgsl` precedes it, `hit_targets.wgsl`
// follows. Two passes:
// `vs_main`/`fs_main` find each pixel's nearest hit (steps 2–5) and write it to the hit
// targets, `vs_fullscreen`/`fs_shade` shade it once (step 6); with several objects each
// object's module draws both into the same targets (its hits and the pixels it won).

// Where the shadow query starts, in voxels from the hit along the texture normal (every
// renderer's convention: SHADOW_OFFSET in crates/mesobake-render/src/lighting.rs).
const SHADOW_OFFSET: f32 = 1.0;
// How far past a hit, in voxels along the ray, the albedo is read.
const ALBEDO_DEPTH: f32 = 0.25;
// No exit face found.
const NO_FACE: u32 = 8u;

// ---- Bindings -------------------------------------------------------------------------


// One face triangle of a prism: object-space corners (counter-clockwise from outside),
// texture coordinates in voxel units, and the outward unit plane (xyz normal, w = n·x).
struct Face {
    corners: array<vec4<f32>, 3>,
    texture: array<vec4<f32>, 3>,
    plane: vec4<f32>,
}

// Faces: top, bottom, then the two triangles of fins 0, 1, 2.
struct Prism {
    faces: array<Face, 8>,
    // Rows of the object → texture (voxel units) matrix.
    frame: array<vec4<f32>, 3>,
    // Whether fins 0, 1, 2 are convex (w unused).
    convex: vec4<u32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var<storage, read> prisms: array<Prism>;

// xyz: unnormalized outward normal (−∇ solid fraction) per voxel centre.
@group(2) @binding(0) var normals: texture_3d<f32>;
// rgb: linear albedo per voxel (1×1×1 for a uniform albedo).
@group(2) @binding(1) var albedo: texture_3d<f32>;

// ---- Material and lighting (crates/mesobake-render/src/lighting.rs) ------------

// Trilinear texture-space normal (unnormalized; zero where the gradient vanishes).
fn normal_at(t: vec3<f32>) -> vec3<f32> {
    let dims = textureDimensions(normals);
    let z_max = f32(dims.z - 1u);
    let f = vec3<f32>(t.x - 0.5, t.y - 0.5, clamp(t.z - 0.5, 0.0, z_max));
    let f0 = floor(f);
    let a = f - f0;
    var n = vec3<f32>(0.0);
    for (var c = 0u; c < 8u; c++) {
        let d = vec3<u32>(c & 1u, (c >> 1u) & 1u, (c >> 2u) & 1u);
        let w = select(1.0 - a.x, a.x, d.x == 1u) * select(1.0 - a.y, a.y, d.y == 1u)
            * select(1.0 - a.z, a.z, d.z == 1u);
        let i = wrap(i32(f0.x) + i32(d.x), dims.x);
        let j = wrap(i32(f0.y) + i32(d.y), dims.y);
        let k = min(u32(f0.z) + d.z, dims.z - 1u);
        n += w * textureLoad(normals, vec3<i32>(i32(i), i32(j), i32(k)), 0).xyz;
    }
    return n;
}

// Linear albedo of the voxel containing t.
fn albedo_at(t: vec3<f32>) -> vec3<f32> {
    let dims = textureDimensions(albedo);
    let i = wrap(i32(floor(t.x)), dims.x);
    let j = wrap(i32(floor(t.y)), dims.y);
    let k = min(u32(max(floor(t.z), 0.0)), dims.z - 1u);
    return textureLoad(albedo, vec3<i32>(i32(i), i32(j), i32(k)), 0).rgb;
}

// Normalizes v, or returns `fallback` for a zero or non-finite vector.

// Where a hit's shadow tests start: its prism, the point one voxel off the hit along the
// texture normal in texture space and in object space, the shading frame and that normal.
struct ShadowStart {
    prism: u32,
    texture: vec3<f32>,
    point: vec3<f32>,
    frame: mat3x3<f32>,
    normal: vec3<f32>,
}

// Lambert + normalized Blinn–Phong from every light, with the variant's shadow test, lights
// whose bit is set in `blocked` (blocked by other objects: `objects_on.wgsl`) left out. The
// ambient lights are summed first, in a loop of their own: Mesa's llvmpipe ends every loop
// of a shader invocation once 65535 loop iterations have run in all, all loops and lanes
// together (LP_MAX_TGSI_LOOP_ITERATIONS), and a shell shadow query that grazes the surface
// near the light's terminator can spend them; the ambient term then still arrives.
fn shade(p: vec3<f32>, n: vec3<f32>, base: vec3<f32>, to_eye: vec3<f32>, start: ShadowStart, blocked: u32) -> vec3<f32> {
    var out = vec3<f32>(0.0);
    for (var l = 0u; l < view.light_count; l++) {
        if lights[l].kind == 2u {
            out += base * lights[l].colour.rgb;
        }
    }
    for (var l = 0u; l < view.light_count; l++) {
        let light = lights[l];
        if light.kind == 2u {
            continue;
        }
        let inc = light_incidence(light, p);
        if !inc.valid {
            continue;
        }
        let cos_l = dot(n, inc.dir);
        let elsewhere = l < 32u && (blocked & (1u << l)) != 0u;
        if cos_l <= 0.0 || elsewhere || !light_visible(start, inc.dir, inc.distance) {
            continue;
        }
        out += direct(n, base, to_eye, inc, cos_l);
    }
    return out;
}

// ---- The prism mapping (crates/mesobake-render/src/prism_map.rs) ---------------------------------------

// The inverse of m (columns a, b, c: rows b×c, c×a, a×b over the determinant); the zero
// matrix where m is singular.
fn inverse3(m: mat3x3<f32>) -> mat3x3<f32> {
    let det = determinant(m);
    if det == 0.0 || !(abs(det) < 3.0e38) {
        return mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    }
    return transpose(mat3x3<f32>(cross(m[1], m[2]), cross(m[2], m[0]), cross(m[0], m[1]))) * (1.0 / det);
}

// P(b₁, b₂, w) = Σ bᵢ (Bᵢ + w·Eᵢ) of a prism, read from its top and bottom faces, object
// coordinates relative to B₀; texture coordinates affine in (b₁, b₂, w).
struct Mapping {
    origin: vec3<f32>,
    e1: vec3<f32>,
    e2: vec3<f32>,
    extrusion: vec3<f32>,
    f1: vec3<f32>,
    f2: vec3<f32>,
    uv0: vec2<f32>,
    uv1: vec2<f32>,
    uv2: vec2<f32>,
    // Rows of the inverse of [uv1 uv2].
    uv_inv0: vec2<f32>,
    uv_inv1: vec2<f32>,
    depth: f32,
    valid: bool,
}

fn prism_mapping(pi: u32) -> Mapping {
    var m: Mapping;
    let top = prisms[pi].faces[0];
    let bottom = prisms[pi].faces[1];
    let b0 = bottom.corners[0].xyz;
    let b1 = bottom.corners[2].xyz;
    let b2 = bottom.corners[1].xyz;
    m.origin = b0;
    m.e1 = b1 - b0;
    m.e2 = b2 - b0;
    m.extrusion = top.corners[0].xyz - b0;
    m.f1 = (top.corners[1].xyz - b1) - m.extrusion;
    m.f2 = (top.corners[2].xyz - b2) - m.extrusion;
    m.uv0 = top.texture[0].xy;
    m.uv1 = top.texture[1].xy - m.uv0;
    m.uv2 = top.texture[2].xy - m.uv0;
    m.depth = top.texture[0].z;
    let det = m.uv1.x * m.uv2.y - m.uv1.y * m.uv2.x;
    m.valid = det != 0.0 && abs(det) < 3.0e38;
    m.uv_inv0 = vec2<f32>(m.uv2.y, -m.uv2.x) / det;
    m.uv_inv1 = vec2<f32>(-m.uv1.y, m.uv1.x) / det;
    return m;
}

fn mapping_coordinates(m: Mapping, t: vec3<f32>) -> vec3<f32> {
    let r = t.xy - m.uv0;
    return vec3<f32>(dot(m.uv_inv0, r), dot(m.uv_inv1, r), t.z / m.depth);
}

// ∂P/∂(b₁, b₂, w) at c.
fn mapping_derivative(m: Mapping, c: vec3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(m.e1 + m.f1 * c.z, m.e2 + m.f2 * c.z, m.extrusion + m.f1 * c.x + m.f2 * c.y);
}

// The texture coordinate of object point p: NEWTON_STEPS Newton steps from `guess`.
const NEWTON_STEPS: u32 = 3u;
fn texture_of(m: Mapping, p: vec3<f32>, guess: vec3<f32>) -> vec3<f32> {
    let target_point = p - m.origin;
    var c = mapping_coordinates(m, guess);
    for (var i = 0u; i < NEWTON_STEPS; i++) {
        let j = mapping_derivative(m, c);
        let q = m.extrusion * c.z + j[0] * c.x + j[1] * c.y;
        if determinant(j) == 0.0 {
            break;
        }
        c -= inverse3(j) * (q - target_point);
    }
    return vec3<f32>(m.uv0 + m.uv1 * c.x + m.uv2 * c.y, c.z * m.depth);
}

// ∂P/∂T at texture coordinate t (object units per voxel).
fn mapping_jacobian(m: Mapping, t: vec3<f32>) -> mat3x3<f32> {
    let dc = mat3x3<f32>(
        vec3<f32>(m.uv_inv0.x, m.uv_inv1.x, 0.0),
        vec3<f32>(m.uv_inv0.y, m.uv_inv1.y, 0.0),
        vec3<f32>(0.0, 0.0, 1.0 / m.depth),
    );
    return mapping_derivative(m, mapping_coordinates(m, t)) * dc;
}

// ---- The pipeline ---------------------------------------------------------------------

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) texture: vec3<f32>,
    @location(2) prism: u32,
    @location(3) face: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) texture: vec3<f32>,
    @location(2) @interpolate(flat) prism: u32,
    @location(3) @interpolate(flat) face: u32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.texture = v.texture;
    out.prism = v.prism;
    out.face = v.face;
    return out;
}

// Ray parameter (from the entry point) where the ray meets face f's plane from inside, or
// −1 when the plane faces away from the ray.
fn plane_exit(p: u32, f: u32, p_in: vec3<f32>, dir: vec3<f32>) -> vec2<f32> {
    let plane = prisms[p].faces[f].plane;
    let c = dot(plane.xyz, dir);
    return vec2<f32>((plane.w - dot(plane.xyz, p_in)) / c, select(0.0, 1.0, c > 0.0));
}

// Barycentric coordinates (xyz) of p projected onto the face's plane, extrapolated outside
// the triangle; w = 0 for a zero-area face.
fn barycentric(prism: u32, f: u32, p: vec3<f32>) -> vec4<f32> {
    let c0 = prisms[prism].faces[f].corners[0].xyz;
    let c1 = prisms[prism].faces[f].corners[1].xyz;
    let c2 = prisms[prism].faces[f].corners[2].xyz;
    let n = cross(c1 - c0, c2 - c0);
    let nn = dot(n, n);
    if nn == 0.0 {
        return vec4<f32>(0.0);
    }
    let l1 = dot(cross(c2 - c1, p - c1), n) / nn;
    let l2 = dot(cross(c0 - c2, p - c2), n) / nn;
    return vec4<f32>(l1, l2, 1.0 - l1 - l2, 1.0);
}

fn texture_at(prism: u32, f: u32, l: vec3<f32>) -> vec3<f32> {
    let t = prisms[prism].faces[f].texture;
    return t[0].xyz * l.x + t[1].xyz * l.y + t[2].xyz * l.z;
}

// A fragment's answer: whether it hit, the hit's object point and texture coordinate, and
// the texture-space direction of the chord that hit.
struct FragmentHit {
    hit: bool,
    point: vec3<f32>,
    texture: vec3<f32>,
    view: vec3<f32>,
}

fn no_hit() -> FragmentHit {
    return FragmentHit(false, vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

// Steps 3–5 along the texture-space path from t_in_tex (object point p_in) to t_out_tex
// (p_out) in prism pi: CHORDS segments between the exactly mapped points at fractions k/n of
// the way (one straight segment when CHORDS is 1), queried in order.
fn path_hit(pi: u32, p_in: vec3<f32>, t_in_tex: vec3<f32>, p_out: vec3<f32>, t_out_tex: vec3<f32>) -> FragmentHit {
    var m: Mapping;
    if CHORDS > 1u {
        m = prism_mapping(pi);
    }
    var start = t_in_tex;
    var p_start = p_in;
    for (var k = 1u; k <= CHORDS; k++) {
        let s = f32(k) / f32(CHORDS);
        var end = t_out_tex;
        var p_end = p_out;
        if k < CHORDS {
            p_end = mix(p_in, p_out, s);
            end = mix(t_in_tex, t_out_tex, s);
            if m.valid {
                end = texture_of(m, p_end, end);
                end.z = clamp(end.z, 0.0, m.depth);
            }
        }
        let chord = end - start;
        let length_k = length(chord);
        if length_k > 0.0 {
            let v = chord / length_k;
            let d = segment_hit(start, v, length_k);
            if d >= 0.0 {
                return FragmentHit(true, mix(p_start, p_end, d / length_k), start + v * d, v);
            }
        }
        start = end;
        p_start = p_end;
    }
    return no_hit();
}

// Steps 2–5 for the fragment of prism pi entered at p_in with texture coordinate t_in_tex
// along dir.
fn fragment(pi: u32, p_in: vec3<f32>, t_in_tex: vec3<f32>, dir: vec3<f32>) -> FragmentHit {
    // Step 2: the exit point by ray–plane intersections with the concave/convex fin rule.
    var t_out = 3.0e38;
    var exit_face = NO_FACE;
    for (var f = 0u; f < 2u; f++) {
        let h = plane_exit(pi, f, p_in, dir);
        if h.y > 0.0 && h.x < t_out {
            t_out = h.x;
            exit_face = f;
        }
    }
    for (var k = 0u; k < 3u; k++) {
        let a = 2u + 2u * k;
        let b = a + 1u;
        let convex = prisms[pi].convex[k] == 1u;
        let ha = plane_exit(pi, a, p_in, dir);
        let hb = plane_exit(pi, b, p_in, dir);
        var pick = vec2<f32>(0.0, 0.0);
        var face = NO_FACE;
        if ha.y > 0.0 && hb.y > 0.0 {
            if (ha.x <= hb.x) == convex {
                pick = ha;
                face = a;
            } else {
                pick = hb;
                face = b;
            }
        } else if ha.y > 0.0 && convex {
            pick = ha;
            face = a;
        } else if hb.y > 0.0 && convex {
            pick = hb;
            face = b;
        }
        if face != NO_FACE && pick.x < t_out {
            t_out = pick.x;
            exit_face = face;
        }
    }
    if exit_face == NO_FACE {
        return no_hit();
    }
    t_out = max(t_out, 0.0);
    let p_out = p_in + dir * t_out;

    // T_out: the exit point's texture coordinate, extrapolated over the exit face triangle
    // (for a fin, over whichever of its two triangles holds P_out).
    var t_out_tex: vec3<f32>;
    if exit_face < 2u {
        let b = barycentric(pi, exit_face, p_out);
        if b.w == 0.0 {
            return no_hit();
        }
        t_out_tex = texture_at(pi, exit_face, b.xyz);
    } else {
        let a = 2u + (exit_face - 2u) / 2u * 2u;
        let ba = barycentric(pi, a, p_out);
        let bb = barycentric(pi, a + 1u, p_out);
        if ba.w == 0.0 || bb.w == 0.0 {
            return no_hit();
        }
        if min(ba.x, min(ba.y, ba.z)) >= min(bb.x, min(bb.y, bb.z)) {
            t_out_tex = texture_at(pi, a, ba.xyz);
        } else {
            t_out_tex = texture_at(pi, a + 1u, bb.xyz);
        }
    }
    // Steps 3–5.
    return path_hit(pi, p_in, t_in_tex, p_out, t_out_tex);
}

// The shading frame at a hit (object → texture, voxel units): the prism's mean frame, or the
// inverse Jacobian of the mapping at the hit (JACOBIAN_FRAME).
fn shading_frame(pi: u32, t_hit: vec3<f32>) -> mat3x3<f32> {
    let rows = prisms[pi].frame;
    let mean = transpose(mat3x3<f32>(rows[0].xyz, rows[1].xyz, rows[2].xyz));
    if JACOBIAN_FRAME {
        let m = prism_mapping(pi);
        if m.valid {
            let j = mapping_jacobian(m, t_hit);
            if determinant(j) != 0.0 {
                return inverse3(j);
            }
        }
    }
    return mean;
}

// Where the shadow tests of fragment hit `hit` of prism pi start.
fn shadow_start(pi: u32, hit: FragmentHit) -> ShadowStart {
    let frame = shading_frame(pi, hit.texture);
    let n_tex = normalize_or(normal_at(hit.texture), -hit.view);
    let offset = n_tex * SHADOW_OFFSET;
    return ShadowStart(pi, hit.texture + offset, hit.point + inverse3(frame) * offset, frame, n_tex);
}

// Step 6: the radiance of fragment hit `hit` of prism pi seen along dir, the lights of
// `blocked`'s bits left out.
fn shade_hit(pi: u32, hit: FragmentHit, dir: vec3<f32>, blocked: u32) -> vec3<f32> {
    let start = shadow_start(pi, hit);
    let n_obj = normalize_or(transpose(start.frame) * start.normal, -dir);
    let base = albedo_at(hit.texture + hit.view * ALBEDO_DEPTH);
    return environment_light(pi, hit.texture, hit.view) + shade(hit.point, n_obj, base, -dir, start, blocked);
}

// The hit pass: steps 2–5 per fragment; the nearest hit's data to the targets.
@fragment
fn fs_main(in: VertexOut) -> HitOut {
    let pixel = pixel_index(vec2<i32>(in.clip.xy));
    if behind_nearest_hit(pixel, in.clip.z) {
        discard;
    }
    let dir = normalize(in.world - view.eye.xyz);
    let hit = fragment(in.prism, in.world, in.texture, dir);
    if !hit.hit {
        discard;
    }
    let depth = hit_depth(hit.point);
    if !claim_pixel(pixel, depth) {
        discard; // a nearer hit is stored already
    }
    var out: HitOut;
    out.point = vec4<f32>(hit.point, bitcast<f32>(in.prism));
    out.texture = vec4<f32>(hit.texture, 1.0);
    out.view = vec4<f32>(hit.view, f32(view.object));
    out.depth = depth;
    return out;
}

// Step 6 once per pixel whose hit is this object's, on the hit the hit pass kept (shading in
// the hit pass ran on the few winning fragments of each small face's blocks: llvmpipe shades
// a triangle's 4×4 blocks whole).
@fragment
fn fs_shade(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(frag.xy);
    let own = own_hit(pixel);
    if !own.hit.hit {
        discard;
    }
    let dir = normalize(own.hit.point - view.eye.xyz);
    return vec4<f32>(shade_hit(own.prism, own.hit, dir, blocked_elsewhere(pixel)), 1.0);
}

// The hit the hit pass kept at a pixel, with its prism; no hit where none was kept or
// another object's was.
struct PixelHit {
    hit: FragmentHit,
    prism: u32,
}

fn own_hit(pixel: vec2<i32>) -> PixelHit {
    let texture = textureLoad(hit_textures, pixel, 0);
    let chord = textureLoad(hit_views, pixel, 0);
    if texture.w == 0.0 || u32(chord.w) != view.object {
        return PixelHit(no_hit(), 0u);
    }
    let point = textureLoad(hit_points, pixel, 0);
    return PixelHit(FragmentHit(true, point.xyz, texture.xyz, chord.xyz), bitcast<u32>(point.w));
}

// The shadow-ray start of the pixel's hit (w = 1) if it is this object's (the start
// `shade_hit` computes), else w = 0.
fn own_start(pixel: vec2<i32>) -> vec4<f32> {
    let own = own_hit(pixel);
    if !own.hit.hit {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(shadow_start(own.prism, own.hit).point, 1.0);
}

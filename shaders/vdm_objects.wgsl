// A VDM object among several (`crates/mesobake-render/src/objects.rs`, the specification,
// with `VdmRenderer` as its `ObjectRenderer`). Within the object the nearest fragment that
// is not a silhouette holds the hit (as in `fs_main`), while among objects the nearest *hit*
// wins. So the object's top triangles are first drawn into fragment targets of its own under
// a depth test of their own (`fs_fragment`: the fragment's depth), then a full-screen pass in
// the shared hit pass (`fs_merge`) finds the hit of each pixel's kept fragment and writes it
// into the shared hit targets under the shared depth test (the hit's depth), as a GDM
// object's hit pass does; `fs_shade` shades the pixels the object won. Follows
// `vdm_preview.wgsl` and `hit_targets.wgsl`; an objects file completes it.
//
// A VDM hit in the shared targets: `hit_points` (point, face index), `hit_textures` (T', the
// fragment's barycentric b0, 1), `hit_views` (the view ray's direction, octahedron-encoded,
// b1, object index); the depth below the reference surface is read again from T'.

// The fragment kept at each pixel: its point on the top surface and face index; its
// barycentrics and 1 (0 where none was kept).
@group(0) @binding(16) var fragment_points: texture_2d<f32>;
@group(0) @binding(17) var fragment_barys: texture_2d<f32>;

struct FragmentOut {
    @location(0) point: vec4<f32>,
    @location(1) bary: vec4<f32>,
}

// The object's own pass: the nearest fragment that is not a silhouette.
@fragment
fn fs_fragment(in: VertexOut) -> FragmentOut {
    if !fragment_hit(in.face, in.bary, in.world).hit {
        discard;
    }
    return FragmentOut(vec4<f32>(in.world, f32(in.face)), vec4<f32>(in.bary, 1.0));
}

// A unit vector as a point of the octahedron unfolded onto [−1, 1]² (and back).
fn octahedron(d: vec3<f32>) -> vec2<f32> {
    let p = d.xy / (abs(d.x) + abs(d.y) + abs(d.z));
    if d.z >= 0.0 {
        return p;
    }
    return (1.0 - abs(p.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
}

fn from_octahedron(e: vec2<f32>) -> vec3<f32> {
    var d = vec3<f32>(e, 1.0 - abs(e.x) - abs(e.y));
    if d.z < 0.0 {
        d = vec3<f32>((1.0 - abs(d.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), d.xy >= vec2<f32>(0.0)), d.z);
    }
    return normalize(d);
}

// The hit of each pixel's kept fragment into the shared hit targets, unless another object's
// hit lies nearer.
@fragment
fn fs_merge(@builtin(position) frag: vec4<f32>) -> HitOut {
    let pixel = vec2<i32>(frag.xy);
    let bary = textureLoad(fragment_barys, pixel, 0);
    if bary.w == 0.0 {
        discard;
    }
    let kept = textureLoad(fragment_points, pixel, 0);
    let hit = fragment_hit(u32(kept.w), bary.xyz, kept.xyz);
    let depth = hit_depth(hit.point);
    if !hit.hit || !claim_pixel(pixel_index(pixel), depth) {
        discard;
    }
    var out: HitOut;
    out.point = vec4<f32>(hit.point, kept.w);
    out.texture = vec4<f32>(hit.t_hit, bary.x, 1.0);
    out.view = vec4<f32>(octahedron(hit.dir), bary.y, f32(view.object));
    out.depth = depth;
    return out;
}

// The hit the shared targets hold at a pixel if it is this object's, with its face and
// barycentrics.
struct PixelHit {
    hit: VdmHit,
    face: u32,
    bary: vec3<f32>,
}

fn own_hit(pixel: vec2<i32>) -> PixelHit {
    let texture = textureLoad(hit_textures, pixel, 0);
    let chord = textureLoad(hit_views, pixel, 0);
    if texture.w == 0.0 || u32(chord.w) != view.object {
        return PixelHit(VdmHit(false, vec2<f32>(0.0), 0.0, vec3<f32>(0.0), vec3<f32>(0.0)), 0u, vec3<f32>(0.0));
    }
    let point = textureLoad(hit_points, pixel, 0);
    let hit = VdmHit(true, texture.xy, relief_depth(texture.xy), point.xyz, from_octahedron(chord.xy));
    return PixelHit(hit, u32(point.w), vec3<f32>(texture.z, chord.z, 1.0 - texture.z - chord.z));
}

// Step 6 once per pixel whose hit is this object's.
@fragment
fn fs_shade(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(frag.xy);
    let own = own_hit(pixel);
    if !own.hit.hit {
        discard;
    }
    return vec4<f32>(shade_hit(own.face, own.bary, own.hit, blocked_elsewhere(pixel)), 1.0);
}

// The start of the shadow rays other objects may block (`VdmRenderer::shade_hit`: one
// texel off the hit along the relief's normal), w = 1; w = 0 where the pixel is not this
// object's.
fn own_start(pixel: vec2<i32>) -> vec4<f32> {
    let own = own_hit(pixel);
    if !own.hit.hit {
        return vec4<f32>(0.0);
    }
    let texel = 1.0 / f32(vdm.size.x);
    let offset = normalize(relief_normal(own.hit.t_hit)) * texel;
    return vec4<f32>(own.hit.point + apply(faces[own.face].from_vdm, offset), 1.0);
}

// `VdmRenderer::occludes`: whether the ray from o along dir meets a top face from behind
// before `distance` (the relief is solid down to the shell's base: the ray runs inside the
// object), or its first hit (seen from o, the nearest front fragment that is not a
// silhouette) lies before it. Fragments beyond `distance` are not looked up: their hits lie
// further still.
fn occludes(o: vec3<f32>, dir: vec3<f32>, distance: f32) -> bool {
    let inv = safe_inverse(dir);
    let count = arrayLength(&bvh_nodes);
    // The nearest front fragment that hits so far, and its hit's distance along the ray.
    var nearest = distance;
    var hit_distance = distance;
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
            let h = intersect_triangle(c[0].xyz, c[1].xyz, c[2].xyz, o, dir);
            if !(h.x > 0.0 && h.x < distance) {
                continue;
            }
            let facing = dot(cross(c[1].xyz - c[0].xyz, c[2].xyz - c[0].xyz), dir);
            if facing > 0.0 {
                return true; // from behind
            }
            if !(facing < 0.0 && h.x < nearest) {
                continue;
            }
            let bary = vec3<f32>(1.0 - h.y - h.z, h.y, h.z);
            let hit = relief_hit(fi, bary, o + dir * h.x, dir, o);
            if hit.hit {
                nearest = h.x;
                hit_distance = dot(hit.point - o, dir);
            }
        }
        i = node.skip;
    }
    return hit_distance < distance;
}

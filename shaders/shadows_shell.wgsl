// Shadow variant `shell`: the per-pixel algorithm itself traced towards the light (as
// `GdmRenderer::shell_blocked`): the rest of the hit's prism from the shadow ray's start,
// then every front face the ray meets beyond it, found through a BVH over the prisms'
// boxes. A light is visible iff no fragment hits nearer than the light.

struct BvhNode {
    lo: vec3<f32>,
    // 0: an inner node whose children are nodes `first` and `first + 1`; else a leaf of
    // `count` prisms listed from `bvh_prisms[first]`.
    count: u32,
    hi: vec3<f32>,
    first: u32,
}

@group(0) @binding(3) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> bvh_prisms: array<u32>;

// Deepest BVH the traversal's stack holds (the upload refuses deeper ones).
const BVH_STACK: u32 = 64u;
// Edge tolerance of the ray–triangle test, in barycentric units: rays through shared edges
// and vertices meet at least one neighbour.
const EDGE: f32 = 1.0e-6;

fn light_visible(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    return !shadow_query(start, dir, distance);
}

// Whether a fragment's hit lies nearer to `o` than `distance`.
fn blocks(hit: FragmentHit, o: vec3<f32>, distance: f32) -> bool {
    return hit.hit && length(hit.point - o) < distance;
}

// Möller–Trumbore: (t, b1, b2) of the ray o + t·d on face f of prism pi; t ≤ 0 for none.
fn intersect_face(pi: u32, f: u32, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let c = prisms[pi].faces[f].corners;
    let e1 = c[1].xyz - c[0].xyz;
    let e2 = c[2].xyz - c[0].xyz;
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if det == 0.0 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let inv = 1.0 / det;
    let s = o - c[0].xyz;
    let u = dot(s, pv) * inv;
    let qv = cross(s, e1);
    let v = dot(d, qv) * inv;
    if u < -EDGE || v < -EDGE || u + v > 1.0 + EDGE {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    return vec3<f32>(dot(e2, qv) * inv, u, v);
}

fn shadow_query(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    let o = start.point;
    if blocks(fragment(start.prism, o, start.texture, dir), o, distance) {
        return true;
    }
    // Zero components replaced by a tiny positive one: their slabs then span all of space.
    let inv = 1.0 / select(dir, vec3<f32>(1.0e-30), abs(dir) < vec3<f32>(1.0e-30));
    var stack: array<u32, BVH_STACK>;
    var top = 1u;
    stack[0] = 0u;
    while top > 0u {
        top -= 1u;
        let node = bvh_nodes[stack[top]];
        let a = (node.lo - o) * inv;
        let b = (node.hi - o) * inv;
        let near = max(max(min(a.x, b.x), min(a.y, b.y)), max(min(a.z, b.z), 0.0));
        let far = min(min(max(a.x, b.x), max(a.y, b.y)), min(max(a.z, b.z), distance));
        if near > far {
            continue;
        }
        if node.count == 0u {
            if top + 2u <= BVH_STACK {
                stack[top] = node.first;
                stack[top + 1u] = node.first + 1u;
                top += 2u;
            }
            continue;
        }
        for (var i = 0u; i < node.count; i++) {
            let pi = bvh_prisms[node.first + i];
            for (var f = 0u; f < 8u; f++) {
                if dot(prisms[pi].faces[f].plane.xyz, dir) >= 0.0 {
                    continue; // back-facing
                }
                let h = intersect_face(pi, f, o, dir);
                if !(h.x > 0.0 && h.x < distance) {
                    continue;
                }
                let bary = vec3<f32>(1.0 - h.y - h.z, h.y, h.z);
                if blocks(fragment(pi, o + dir * h.x, texture_at(pi, f, bary), dir), o, distance) {
                    return true;
                }
            }
        }
    }
    return false;
}

// The shell traced along any ray, as the rasterizer and the hit pass would (`GdmRenderer::trace`):
// every front face the ray meets, found through a BVH over the prisms' boxes
// (`upload_prism_bvh` in `crates/mesobake-gpu/src/resources/bvh.rs`), runs the per-pixel
// algorithm (steps 2–5). Included by the shell-shadow variant and by the variant of an object
// whose shell blocks other objects' shadow rays (`objects_on.wgsl`).

@group(0) @binding(3) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> bvh_prisms: array<u32>;

// (t, b1, b2) of the ray o + t·d on face f of prism pi; t ≤ 0 for none.
fn intersect_face(pi: u32, f: u32, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let c = prisms[pi].faces[f].corners;
    return intersect_triangle(c[0].xyz, c[1].xyz, c[2].xyz, o, d);
}

// The fragment that the ray o + t·dir makes on face f of prism pi, if it meets that face
// from the front at 0 < t < t_max (what the rasterizer would produce, depth-tested against
// t_max), with its answer (steps 2–5).
fn face_fragment(pi: u32, f: u32, o: vec3<f32>, dir: vec3<f32>, t_max: f32) -> FragmentHit {
    if dot(prisms[pi].faces[f].plane.xyz, dir) >= 0.0 {
        return no_hit(); // back-facing
    }
    let h = intersect_face(pi, f, o, dir);
    if !(h.x > 0.0 && h.x < t_max) {
        return no_hit();
    }
    let bary = vec3<f32>(1.0 - h.y - h.z, h.y, h.z);
    return fragment(pi, o + dir * h.x, texture_at(pi, f, bary), dir);
}

// Whether a fragment's hit lies nearer to `o` than `distance`.
fn blocks(hit: FragmentHit, o: vec3<f32>, distance: f32) -> bool {
    return hit.hit && length(hit.point - o) < distance;
}

// Whether the ray from `o` (outside every prism it enters) along `dir` hits the
// mesostructure nearer than `distance`: any front face's fragment that hits within it.
fn shell_hit_within(o: vec3<f32>, dir: vec3<f32>, distance: f32) -> bool {
    let inv = safe_inverse(dir);
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
            let pi = bvh_prisms[node.first + k];
            for (var f = 0u; f < 8u; f++) {
                if blocks(face_fragment(pi, f, o, dir, distance), o, distance) {
                    return true;
                }
            }
        }
        i = node.skip;
    }
    return false;
}

// `ObjectRenderer::occludes` of a GDM object (`objects_on.wgsl`): whether its shell's first
// hit along the shadow ray lies before the light.
fn occludes(o: vec3<f32>, dir: vec3<f32>, distance: f32) -> bool {
    return shell_hit_within(o, dir, distance);
}

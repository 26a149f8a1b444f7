// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// transmittance along shadow rays.

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

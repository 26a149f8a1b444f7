// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// the compute path: each pixel's sorted list of cells.

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

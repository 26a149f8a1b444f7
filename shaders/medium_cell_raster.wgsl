// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// the raster path: cells drawn in a per-view order.

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

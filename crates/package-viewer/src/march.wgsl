// occupancy: a voxel-by-voxel march through the occupancy texture. Follows common.wgsl.

@group(1) @binding(0) var occupancy: texture_3d<u32>;

fn solid(c: vec3<i32>) -> bool {
    let n = vec3<i32>(p.dims.xyz);
    let wrapped = vec3<i32>(((c.x % n.x) + n.x) % n.x, ((c.y % n.y) + n.y) % n.y, c.z);
    return textureLoad(occupancy, wrapped, 0).r == 0u;
}

@compute @workgroup_size(8, 8)
fn march(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= p.dims.x || id.y >= p.dims.y {
        return;
    }
    let at = id.y * p.dims.x + id.x;
    var cell = vec3<i32>(i32(id.x), i32(id.y), i32(p.dims.z) - 1);
    if solid(cell) {
        values[at] = 0.0;
        return;
    }
    let v = p.dir.xyz;
    let start = vec3<f32>(cell) + 0.5;
    let step = vec3<i32>(sign(v));
    let far = 1e30;
    let delta = select(vec3(far), 1.0 / abs(v), v != vec3(0.0));
    var next = select(vec3(far), (vec3<f32>(cell) + max(sign(v), vec3(0.0)) - start) / v, v != vec3(0.0));
    // A ray from the top layer leaves or hits within this many cells.
    let cells = i32(p.dims.x + p.dims.y + p.dims.z) * i32(ceil(1.0 / abs(v.z)) + 1.0);
    for (var n = 0; n < cells; n++) {
        var axis = 0;
        if next.y < next[axis] { axis = 1; }
        if next.z < next[axis] { axis = 2; }
        let t = next[axis];
        cell[axis] += step[axis];
        next[axis] += delta[axis];
        if cell.z < 0 || cell.z >= i32(p.dims.z) {
            values[at] = -1.0;
            return;
        }
        if solid(cell) {
            values[at] = t;
            return;
        }
    }
    values[at] = -1.0;
}

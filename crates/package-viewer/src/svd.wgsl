// paper-svd: `svd_group` accumulates one texture group of the factors, then `svd_escape`
// applies the escape rule. Follows common.wgsl.

@group(1) @binding(0) var weights: texture_3d<f32>;
@group(1) @binding(1) var eigen: texture_2d<f32>;

@compute @workgroup_size(8, 8)
fn svd_group(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= p.dims.x || id.y >= p.dims.y {
        return;
    }
    let w = p.bias_w + p.scale_w * textureLoad(weights, vec3<u32>(id.x, id.y, p.bin.y), 0);
    let e = p.bias_e + p.scale_e * textureLoad(eigen, vec2<u32>(p.dims.z - 1u, p.bin.x), 0);
    var sum = 0.0;
    for (var c = 0u; c < p.dims.w; c++) {
        sum += w[c] * e[c];
    }
    values[id.y * p.dims.x + id.x] += sum;
}

@compute @workgroup_size(8, 8)
fn svd_escape(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= p.dims.x || id.y >= p.dims.y {
        return;
    }
    let at = id.y * p.dims.x + id.x;
    let d = values[at];
    values[at] = select(max(d, 0.0), -1.0, d >= p.dir.w);
}


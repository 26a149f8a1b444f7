// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// shading and front-to-back compositing.

// ---- Shading and compositing --------------------------------------------------------------

// Loop iterations this invocation has run (see `loop_budget`).
var<private> steps: u32;

// Composited radiance over black (premultiplied) and the transmittance so far.
var<private> gathered_radiance: vec3<f32>;
var<private> gathered_transmittance: f32;

// Composites a piece absorbing `absorbed` and scattering `light` behind what is gathered;
// false once the ray is absorbed.
fn composite(light: vec3<f32>, absorbed: f32) -> bool {
    gathered_radiance += light * (gathered_transmittance * absorbed);
    gathered_transmittance *= 1.0 - absorbed;
    if gathered_transmittance < medium.min_transmittance {
        gathered_transmittance = 0.0;
        return false;
    }
    return true;
}

// The light scattered towards the eye at `point` (texture point `t` of a level, voxel v,
// in cell ci) under every light, each weighted by the transmittance towards it
// (`shade_transmitted`).
fn scattered(ci: u32, level: u32, point: vec3<f32>, t: vec3<f32>, v: i32, to_eye: vec3<f32>) -> vec3<f32> {
    let albedo = voxels[v].rgb;
    let m = cells[ci].normal_to_object;
    let nt = normal_at(level, t);
    let n_object = normalize_or(vec3<f32>(dot(m[0].xyz, nt), dot(m[1].xyz, nt), dot(m[2].xyz, nt)), vec3<f32>(0.0));
    let has_normal = dot(n_object, n_object) > 0.0;
    var out = vec3<f32>(0.0);
    for (var li = 0u; li < view.light_count; li++) {
        steps += 1u;
        let light = lights[li];
        if light.kind == 2u {
            out += albedo * light.colour.rgb;
            continue;
        }
        let inc = light_incidence(light, point);
        if !inc.valid {
            continue;
        }
        let n = select(inc.dir, n_object, has_normal);
        let cos_l = dot(n, inc.dir);
        if cos_l <= 0.0 {
            continue;
        }
        var visible = 1.0;
        if medium.shadows > 0u {
            // The object distance that is `shadow_start` voxels towards the light.
            let start = medium.shadow_start / length(texture_direction(ci, inc.dir));
            let frame = shadow_frames[li];
            if start >= inc.distance {
                visible = 1.0;
            } else if medium.shadows == 1u || frame.kind == 0u {
                visible = transmittance(level, point, inc.dir, start, inc.distance);
            } else {
                visible = map_visibility(frame, point, start);
            }
        }
        if visible > 0.0 {
            out += direct(n, albedo, to_eye, inc, cos_l) * visible;
        }
    }
    return out;
}

// Integrates the crossing r = (t_in, t_out) of cell ci by the camera ray o + t·d in a level
// and composites it; false once the ray is absorbed.
fn integrate(ci: u32, level: u32, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> bool {
    let texel = exp2(-f32(level));
    let a = to_texture(ci, o + d * r.x) * texel;
    let b = to_texture(ci, o + d * r.y) * texel;
    let len = length(b - a);
    var going = true;
    if len == 0.0 {
        return true;
    }
    // Ray parameter per texture-space length.
    let dt = (r.y - r.x) / len;
    let dir_t = (b - a) / len;
    if medium.integration == 1u {
        let part = len / f32(medium.samples);
        for (var i = 0u; i < medium.samples && going; i++) {
            steps += 1u;
            let s = (f32(i) + 0.5) * part;
            let t = a + (b - a) * (s / len);
            let v = voxel_at(level, t);
            if v >= 0 {
                let absorbed = 1.0 - transmit(voxels[v].a, part);
                if absorbed > 0.0 {
                    let light = scattered(ci, level, o + d * (r.x + s * dt), t, v, -d);
                    going = composite(light, absorbed);
                }
            }
        }
        return going;
    }
    var w = walk_start(a, dir_t, len);
    while going && walk_next(&w, level) {
        steps += 1u;
        let alpha = voxels[w.v].a;
        if alpha > 0.0 {
            // The voxel's stretch in pieces at most `light_step` long, lit at their starts.
            let pieces = max(ceil((w.s1 - w.s0) / medium.light_step), 1.0);
            for (var p = 0.0; p < pieces && going; p += 1.0) {
                steps += 1u;
                let u0 = w.s0 + (w.s1 - w.s0) * p / pieces;
                let u1 = w.s0 + (w.s1 - w.s0) * (p + 1.0) / pieces;
                let absorbed = 1.0 - transmit(alpha, u1 - u0);
                if absorbed > 0.0 {
                    let point = o + d * (r.x + u0 * dt);
                    let light = scattered(ci, level, point, a + dir_t * u0, w.v, -d);
                    going = composite(light, absorbed);
                }
            }
        }
    }
    return going;
}

// What `gathered_*` hold as the target's texel: premultiplied radiance and 1 − T.
fn gathered() -> vec4<f32> {
    return vec4<f32>(gathered_radiance, 1.0 - gathered_transmittance);
}

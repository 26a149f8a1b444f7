// Part of the translucent-media pipeline (see `medium_preview.wgsl`):
// the rays and the tetrahedral cells they cross.

// ---- Rays and cells ---------------------------------------------------------------------

// The camera ray's unit direction through the pixel whose centre is `pixel` (framebuffer
// coordinates, as `Camera::ray`).
fn camera_ray(pixel: vec2<f32>) -> vec3<f32> {
    let sx = pixel.x / f32(view.width) * 2.0 - 1.0;
    let sy = 1.0 - pixel.y / f32(medium.height) * 2.0;
    return normalize(medium.forward.xyz + medium.right.xyz * sx + medium.up.xyz * sy);
}

// Whether a cell owns the face with outward normal n when a ray lies in it: n's first
// non-zero component is negative.
fn owns(n: vec3<f32>) -> bool {
    if n.x != 0.0 {
        return n.x < 0.0;
    }
    if n.y != 0.0 {
        return n.y < 0.0;
    }
    return n.z < 0.0;
}

// The stretch (entry, exit) of o + t·d, t ∈ [t_min, t_max], inside cell ci; entry ≥ exit
// when the ray misses it.
fn clip(ci: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> vec2<f32> {
    // Written out plane by plane: loops count against the software driver's budget.
    var r = vec2<f32>(t_min, t_max);
    r = clip_plane(cells[ci].planes[0], o, d, r);
    r = clip_plane(cells[ci].planes[1], o, d, r);
    r = clip_plane(cells[ci].planes[2], o, d, r);
    return clip_plane(cells[ci].planes[3], o, d, r);
}

// (entry, exit) narrowed by the plane p; entry ≥ exit once missed.
fn clip_plane(p: vec4<f32>, o: vec3<f32>, d: vec3<f32>, r: vec2<f32>) -> vec2<f32> {
    let along = dot(p.xyz, d);
    let inside = p.w - dot(p.xyz, o);
    if along == 0.0 {
        if inside < 0.0 || (inside == 0.0 && !owns(p.xyz)) {
            return vec2<f32>(1.0, 0.0);
        }
        return r;
    }
    if along > 0.0 {
        return vec2<f32>(r.x, min(r.y, inside / along));
    }
    return vec2<f32>(max(r.x, inside / along), r.y);
}

fn to_texture(ci: u32, p: vec3<f32>) -> vec3<f32> {
    let m = cells[ci].to_texture;
    return vec3<f32>(dot(m[0].xyz, p) + m[0].w, dot(m[1].xyz, p) + m[1].w, dot(m[2].xyz, p) + m[2].w);
}

// The linear part of M^{o→t} applied to a direction.
fn texture_direction(ci: u32, d: vec3<f32>) -> vec3<f32> {
    let m = cells[ci].to_texture;
    return vec3<f32>(dot(m[0].xyz, d), dot(m[1].xyz, d), dot(m[2].xyz, d));
}

// The mip level of a crossing entered at t_in (`level_for` in the specification).
fn level_for(ci: u32, t_in: f32) -> u32 {
    if medium.level_count <= 1u {
        return 0u;
    }
    let footprint = max(t_in, 0.0) * medium.forward.w * cells[ci].normal_to_object[0].w;
    if !(footprint > 0.0 && footprint < FAR) {
        return 0u;
    }
    let lambda = log2(footprint) + medium.mip_bias;
    return u32(clamp(round(lambda), 0.0, f32(medium.level_count - 1u)));
}

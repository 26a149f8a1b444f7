// Shadow variant `shell`: the per-pixel algorithm itself traced towards the light (as
// `GdmRenderer::shell_blocked`): the rest of the hit's prism from the shadow ray's start,
// then the shell beyond it (`shell_trace.wgsl`, which precedes this file). A light is
// visible iff no fragment hits nearer than the light.

fn light_visible(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    return !shadow_query(start, dir, distance);
}

// A start above the prism's top (or below its base) lies outside the prism: only the prisms
// the ray enters count (`GdmRenderer::shell_blocked`).
fn shadow_query(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    let o = start.point;
    let inside = start.texture.z > 0.0 && start.texture.z < f32(textureDimensions(normals).z);
    if inside && blocks(fragment(start.prism, o, start.texture, dir), o, distance) {
        return true;
    }
    return shell_hit_within(o, dir, distance);
}

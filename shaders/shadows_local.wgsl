// Shadow variant `local` (the paper's): a light is visible iff the GDM query one voxel off
// the hit along the texture normal, towards the light mapped by the shading frame, escapes
// (local mesostructure shadows, as in `GdmRenderer::radiance`).

fn light_visible(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    let l_tex = start.frame * dir;
    let len2 = dot(l_tex, l_tex);
    if !(len2 > 0.0) {
        return true;
    }
    return shadow_query(start.texture, l_tex * inverseSqrt(len2));
}

fn shadow_query(origin: vec3<f32>, l: vec3<f32>) -> bool {
    return escapes(origin, l);
}

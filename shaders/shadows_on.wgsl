// Shadow variant: the scene calls for shadows. A light is visible iff the GDM query one
// voxel off the hit along the texture normal escapes (local mesostructure shadows, as in the
// paper and `GdmRenderer::radiance`).

fn light_visible(shadow_origin: vec3<f32>, l_tex: vec3<f32>) -> bool {
    let len2 = dot(l_tex, l_tex);
    if !(len2 > 0.0) {
        return true;
    }
    return shadow_query(shadow_origin, l_tex * inverseSqrt(len2));
}

fn shadow_query(origin: vec3<f32>, l: vec3<f32>) -> bool {
    return escapes(origin, l);
}

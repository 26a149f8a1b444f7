// Shadow variant: the scene does not call for shadows; every light is visible and no shadow
// query exists in the module.

fn light_visible(shadow_origin: vec3<f32>, l_tex: vec3<f32>) -> bool {
    return true;
}

// Shadow variant: the scene does not call for shadows; every light is visible and no shadow
// query exists in the module.

fn light_visible(start: ShadowStart, dir: vec3<f32>, distance: f32) -> bool {
    return true;
}

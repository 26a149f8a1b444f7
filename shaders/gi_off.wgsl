// Environment variant: the scene does not call for environment lighting; no radiance
// transfer is bound or read.

fn environment_light(prism: u32, t_hit: vec3<f32>, view_tex: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(0.0);
}

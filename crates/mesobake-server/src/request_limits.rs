//! What a scene may ask the server for, checked when a job or preview is submitted, before
//! any work starts: lights, image size, path samples and built-in base mesh triangles (the
//! configuration's `max_*` keys; the bake's memory is checked by its plan). Each refusal
//! names the limit it hit.

use super::api_error::{ApiError, ApiResult};
use super::config::ServerConfig;
use axum::http::StatusCode;
use mesobake_scene::{BaseMeshSource, Scene};

/// Refuses `scene` with 422 when its cost is out of the bounds of `config`.
pub fn check_scene_cost(scene: &Scene, config: &ServerConfig) -> ApiResult<()> {
    let refuse = |what: String| Err(ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, what));
    if scene.lights.len() as u64 > u64::from(config.max_lights) {
        return refuse(format!(
            "the scene has {} lights, over the server's limit of {} (max_lights)",
            scene.lights.len(),
            config.max_lights
        ));
    }
    let camera = &scene.camera;
    if camera.width > config.max_image_side || camera.height > config.max_image_side {
        return refuse(format!(
            "the camera's image is {}×{}, over the server's limit of {} pixels a side \
             (max_image_side)",
            camera.width, camera.height, config.max_image_side
        ));
    }
    // Supersampling casts as many rays as a larger image: the same bound on the rays.
    let side = u64::from(config.max_image_side);
    if let Err(e) = camera
        .samples_per_pixel
        .check_image(camera.width, camera.height, side * side)
    {
        return refuse(format!("{e} (max_image_side squared)"));
    }
    if scene.gi.path_samples > config.max_path_samples {
        return refuse(format!(
            "gi.path_samples is {}, over the server's limit of {} (max_path_samples)",
            scene.gi.path_samples, config.max_path_samples
        ));
    }
    if let BaseMeshSource::Builtin(builtin) = &scene.base_mesh {
        let triangles = builtin.triangle_count();
        if triangles > config.max_base_triangles {
            return refuse(format!(
                "the built-in base mesh has {triangles} triangles, over the server's limit of \
                 {} (max_base_triangles)",
                config.max_base_triangles
            ));
        }
    }
    Ok(())
}

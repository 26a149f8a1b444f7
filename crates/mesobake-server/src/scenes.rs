//! `GET /api/v1/scenes`: the shipped sample scenes (`scenes/*.json`, and the scene of several
//! objects `docs/examples/torus-over-weave.json`; built-in meshes and mesostructure only, so
//! the server bakes them as they are), by name; `sample` is the one the web page starts
//! from.

use super::api_error::{ApiError, ApiResult};
use axum::Json;
use axum::extract::Path;
use axum::http::header;
use axum::response::IntoResponse;

/// The scene the web page starts from and the server seeds (`scenes/torus-chain.json`).
pub const SAMPLE_SCENE: &str = include_str!("../../../scenes/torus-chain.json");

/// The shipped sample scenes by name, with the technique each calls for (every object's, for
/// the scene of several objects that ends the list).
pub const SAMPLE_SCENES: [(&str, &str, &str); 12] = [
    ("torus-chain", "gdm", SAMPLE_SCENE),
    (
        "plane-weave",
        "gdm",
        include_str!("../../../scenes/plane-weave.json"),
    ),
    (
        "plane-weave-sky",
        "gdm",
        include_str!("../../../scenes/plane-weave-sky.json"),
    ),
    (
        "cylinder-bark",
        "gdm",
        include_str!("../../../scenes/cylinder-bark.json"),
    ),
    (
        "teapot-grid",
        "gdm",
        include_str!("../../../scenes/teapot-grid.json"),
    ),
    (
        "vase-squama",
        "gdm",
        include_str!("../../../scenes/vase-squama.json"),
    ),
    (
        "torus-bumps",
        "vdm",
        include_str!("../../../scenes/torus-bumps.json"),
    ),
    (
        "plane-bricks",
        "gdm",
        include_str!("../../../scenes/plane-bricks.json"),
    ),
    (
        "torus-fur",
        "transparency",
        include_str!("../../../scenes/torus-fur.json"),
    ),
    (
        "plane-clouds",
        "transparency",
        include_str!("../../../scenes/plane-clouds.json"),
    ),
    (
        "vase-inclusions",
        "transparency",
        include_str!("../../../scenes/vase-inclusions.json"),
    ),
    (
        "torus-over-weave",
        "gdm",
        include_str!("../../../docs/examples/torus-over-weave.json"),
    ),
];

/// One entry of the list.
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct SceneEntry {
    /// The name, as `GET /api/v1/scenes/{name}` takes it.
    pub name: &'static str,
    /// The technique its plan chooses: `gdm`, `vdm` or `transparency`.
    pub technique: &'static str,
}

/// The sample scenes' names and techniques.
#[utoipa::path(get, path = "/api/v1/scenes", responses((status = 200, body = Vec<SceneEntry>)))]
pub async fn list() -> Json<Vec<SceneEntry>> {
    Json(
        SAMPLE_SCENES
            .iter()
            .map(|&(name, technique, _)| SceneEntry { name, technique })
            .collect(),
    )
}

/// A sample scene (`sample`: the one the web page starts from).
#[utoipa::path(
    get,
    path = "/api/v1/scenes/{name}",
    params(("name" = String, Path, description = "A name from GET /api/v1/scenes, or sample")),
    responses(
        (status = 200, description = "A scene (docs/scene-format.md)"),
        (status = 404, description = "No such sample scene")
    )
)]
pub async fn get(Path(name): Path<String>) -> ApiResult<impl IntoResponse> {
    let text = match name.as_str() {
        "sample" => SAMPLE_SCENE,
        _ => SAMPLE_SCENES
            .iter()
            .find(|(n, ..)| *n == name)
            .map(|(.., text)| *text)
            .ok_or_else(|| ApiError::not_found(format!("sample scene {name:?}")))?,
    };
    Ok(([(header::CONTENT_TYPE, "application/json")], text))
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesobake_bake::surface::shell::Shell;
    use mesobake_core::limits::Limits;
    use mesobake_scene::load_base_mesh;
    use mesobake_scene::objects::{self, SceneObject};
    use mesobake_scene::technique::{Surface, choose};

    #[test]
    fn every_listed_scene_parses_and_names_the_technique_its_plan_chooses() {
        let mut several = 0;
        for (name, technique, text) in SAMPLE_SCENES {
            let objects = objects::from_json(text).unwrap_or_else(|e| panic!("{name}: {e}"));
            several += usize::from(objects.len() > 1);
            for SceneObject { scene, .. } in objects {
                let dir = std::path::Path::new(".");
                let (base, report) = load_base_mesh(&scene, dir, &Limits::default()).unwrap();
                let surface = Surface::of(&report, &Shell::new(&base, scene.shell).unwrap());
                assert_eq!(
                    choose(&scene, &surface).technique.name(),
                    technique,
                    "{name}"
                );
            }
        }
        let shipped = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"))
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .path()
                    .extension()
                    .is_some_and(|x| x == "json")
            })
            .count();
        assert_eq!(
            shipped + several,
            SAMPLE_SCENES.len(),
            "every shipped scene is listed"
        );
    }
}

//! A scene's inputs for the explicit geometry export (`mesobake explicit --scene`).

use super::{MesostructureSource, Scene, load_base_mesh};
use mesobake_bake::mesostructure::samples;
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::surface::explicit::ExplicitInput;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use std::path::Path;

/// Reads the scene file at `path`: its base mesh (scaled by `mesh_scale`), shell, and
/// mesostructure — an OBJ tile, or a built-in sample tessellated for the scene's resolution;
/// the tile height is the resolution's Z/X. Reliefs, media and volumes have no triangles and
/// are refused.
pub fn explicit_input(path: &Path, limits: &Limits) -> Result<ExplicitInput> {
    let scene = Scene::read(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let (base, _) = load_base_mesh(&scene, dir, limits)?;
    let dims = scene.dims()?;
    let tile = match &scene.mesostructure {
        MesostructureSource::Sample(kind) | MesostructureSource::SampleTile(kind) => {
            samples::mesh(*kind, dims)?
        }
        MesostructureSource::Tile(p) => TriMesh::read_obj(&dir.join(p), limits.memory_bytes / 8)?,
        MesostructureSource::Relief(_) => {
            return Err(Error::Scene(
                "explicit geometry needs triangles, but the mesostructure is a relief".into(),
            ));
        }
        MesostructureSource::Medium(_) => {
            return Err(Error::Scene(
                "explicit geometry needs triangles, but the mesostructure is a translucent \
                 medium"
                    .into(),
            ));
        }
        MesostructureSource::Volume(p) | MesostructureSource::HeightField(p) => {
            return Err(Error::Scene(format!(
                "{}: explicit geometry needs triangles, but the mesostructure is the \
                 volume (or height field) {}; use a tile or a sample",
                path.display(),
                p.display()
            )));
        }
    };
    Ok(ExplicitInput {
        base,
        shell: scene.shell,
        tile,
        tile_height: f64::from(dims.z) / f64::from(dims.x),
    })
}

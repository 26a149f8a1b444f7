//! What an export reads from files: the base mesh, the tile and the shell's proportions.

use super::*;

/// Everything an export reads: base mesh, shell parameters, tile and tile height.
#[derive(Clone, Debug)]
pub struct ExplicitInput {
    /// The validated base mesh.
    pub base: BaseMesh,
    /// How the base mesh is extruded.
    pub shell: ShellParams,
    /// The tile in tile units.
    pub tile: TriMesh,
    /// The tile's height H (tile units): its z ∈ [0, H] fills the shell.
    pub tile_height: f64,
}

impl ExplicitInput {
    /// Reads a base mesh OBJ and a tile OBJ. Without `thickness`, the shell is
    /// [`proportional_thickness`] thick.
    pub fn from_files(
        mesh: &Path,
        tile: &Path,
        thickness: Option<f64>,
        tiles_per_uv: [f64; 2],
        tile_height: f64,
        limits: &Limits,
    ) -> Result<ExplicitInput> {
        let (base, _) = BaseMesh::read_obj(mesh, limits)?;
        let tile = TriMesh::read_obj(tile, limits.memory_bytes / 8)?;
        let thickness = match thickness {
            Some(h) => h,
            None => proportional_thickness(&base, tiles_per_uv, tile_height)?,
        };
        Ok(ExplicitInput {
            base,
            shell: ShellParams {
                thickness,
                tiles_per_uv,
                smoothing: 0,
            },
            tile,
            tile_height,
        })
    }

    /// Builds the shell and exports; `tolerance` defaults to
    /// [`DEFAULT_RELATIVE_TOLERANCE`] × thickness.
    pub fn export(
        &self,
        tolerance: Option<f64>,
        record_texture: bool,
        limits: &Limits,
        observer: &dyn BakeObserver,
    ) -> Result<(Shell, Explicit)> {
        let shell = Shell::new(&self.base, self.shell)?;
        let params = ExplicitParams {
            tile_height: self.tile_height,
            tolerance: tolerance.unwrap_or(DEFAULT_RELATIVE_TOLERANCE * self.shell.thickness),
            record_texture,
        };
        let explicit = export(&shell, &self.tile, &params, limits, observer)?;
        Ok((shell, explicit))
    }
}

/// The shell thickness that keeps a tile's proportions: H times the tile's mean edge length
/// in object units, √(object area / area in tiles) over the base mesh.
pub fn proportional_thickness(
    base: &BaseMesh,
    tiles_per_uv: [f64; 2],
    tile_height: f64,
) -> Result<f64> {
    let (mut object, mut texture) = (0.0, 0.0);
    for t in &base.triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let p = [a, b, c].map(|i| base.positions[i]);
        let u = [a, b, c].map(|i| base.uvs[i] * DVec2::from(tiles_per_uv));
        object += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        texture += 0.5 * (u[1] - u[0]).perp_dot(u[2] - u[0]).abs();
    }
    let h = tile_height * (object / texture).sqrt();
    if h.is_finite() && h > 0.0 {
        Ok(h)
    } else {
        Err(Error::InvalidParameter(format!(
            "cannot derive a shell thickness from the base mesh's UV area ({texture} tiles²); \
             pass --thickness"
        )))
    }
}

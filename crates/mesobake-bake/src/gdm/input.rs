//! Loading a mesostructure input file of either kind into something rays can be cast into.

use crate::gdm::caster::Caster;
use crate::gdm::height_field_caster::HeightFieldCaster;
use crate::gdm::mesh_caster::MeshCaster;
use crate::gdm::volume_caster::VolumeCaster;
use crate::mesostructure::file_kind::FileKind;
use crate::mesostructure::height_field::HeightField;
use crate::mesostructure::mesh_tile::MeshTile;
use crate::mesostructure::trimesh::TriMesh;
use crate::mesostructure::volume_format;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::path::Path;

/// A loaded mesostructure input.
pub enum Mesostructure {
    /// A voxel volume (`.mbvol`).
    Volume(VolumeCaster),
    /// An OBJ tile on a chosen grid.
    Mesh(Box<MeshCaster>),
    /// A height field on a chosen grid, cast exactly.
    HeightField(HeightFieldCaster),
}

impl Mesostructure {
    /// The loaded input as a [`Caster`].
    pub fn caster(&self) -> &dyn Caster {
        match self {
            Mesostructure::Volume(c) => c,
            Mesostructure::Mesh(c) => c.as_ref(),
            Mesostructure::HeightField(c) => c,
        }
    }

    /// The mesh tile's triangles (tile units), for a mesh tile.
    pub fn tile_mesh(&self) -> Option<&crate::mesostructure::trimesh::TriMesh> {
        match self {
            Mesostructure::Volume(_) | Mesostructure::HeightField(_) => None,
            Mesostructure::Mesh(c) => Some(c.tile()),
        }
    }
}

/// Loads `path`: a `.mbvol` volume, a PNG height field or an OBJ tile, told apart by content
/// ([`FileKind`]); any other kind is refused, naming what the file holds. `res` is required
/// for height fields and OBJ tiles (the grid to sample them on) and, for volumes, must match
/// the volume's own resolution when given. A volume with an opacity channel (a translucent
/// medium) is refused: every caster is opaque.
pub fn load(
    path: &Path,
    res: Option<Dims>,
    allow_open: bool,
    limits: &Limits,
) -> Result<Mesostructure> {
    let kind = FileKind::of_file(path)?;
    let needs_res = |what: &str| {
        res.ok_or_else(|| {
            Error::InvalidParameter(format!(
                "{}; {what} needs --res to choose its sampling grid",
                kind.describe_file(path)
            ))
        })
    };
    match kind {
        FileKind::Volume => {
            let volume = volume_format::read(path, limits)?;
            if let Some(res) = res
                && res != volume.dims()
            {
                return Err(Error::InvalidParameter(format!(
                    "{} is a {} volume but --res asks for {res}; volumes are baked at their own resolution",
                    path.display(),
                    volume.dims()
                )));
            }
            if volume.opacity().is_some() {
                return Err(Error::InvalidParameter(format!(
                    "{}: {}",
                    path.display(),
                    crate::mesostructure::medium::translucent_refusal("a GDM bake")
                )));
            }
            Ok(Mesostructure::Volume(VolumeCaster::new(&volume)))
        }
        FileKind::Png => {
            let res = needs_res("a height field")?;
            let field = HeightField::read(path, limits)?;
            Ok(Mesostructure::HeightField(HeightFieldCaster::new(
                field, res, limits,
            )?))
        }
        FileKind::Obj => {
            let res = needs_res("an OBJ tile")?;
            let mesh = TriMesh::read_obj(path, limits.memory_bytes / 8)?;
            let tile = MeshTile::new(mesh, allow_open)?;
            Ok(Mesostructure::Mesh(Box::new(MeshCaster::new(
                &tile, res, limits,
            )?)))
        }
        other => Err(Error::InvalidParameter(format!(
            "{}, not a mesostructure input: give a .mbvol volume, a grayscale PNG height field \
             or an OBJ tile",
            other.describe_file(path)
        ))),
    }
}

//! Loading a mesostructure input file of either kind into something rays can be cast into.

use crate::bake::gdm::caster::Caster;
use crate::bake::gdm::mesh_caster::MeshCaster;
use crate::bake::gdm::volume_caster::VolumeCaster;
use crate::error::{Error, Result};
use crate::grid::Dims;
use crate::mesostructure::height_field::{HeightField, PNG_MAGIC};
use crate::mesostructure::mesh_tile::MeshTile;
use crate::mesostructure::trimesh::TriMesh;
use crate::mesostructure::volume_format;
use crate::util::limits::Limits;
use std::io::Read;
use std::path::Path;

/// A loaded mesostructure input.
pub enum Mesostructure {
    /// A voxel volume (`.mbvol`).
    Volume(VolumeCaster),
    /// An OBJ tile on a chosen grid.
    Mesh(Box<MeshCaster>),
}

impl Mesostructure {
    /// The loaded input as a [`Caster`].
    pub fn caster(&self) -> &dyn Caster {
        match self {
            Mesostructure::Volume(c) => c,
            Mesostructure::Mesh(c) => c.as_ref(),
        }
    }
}

/// Loads `path`: a `.mbvol` volume or a PNG height field (each recognized by its magic
/// number), or else an OBJ tile. `res` is required for height fields and OBJ tiles (the grid
/// to sample them on) and, for volumes, must match the volume's own resolution when given.
pub fn load(
    path: &Path,
    res: Option<Dims>,
    allow_open: bool,
    limits: &Limits,
) -> Result<Mesostructure> {
    let mut magic = [0u8; 8];
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = file.read(&mut magic).map_err(|e| Error::io(path, e))?;
    if volume_format::has_magic(&magic[..n]) {
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
        return Ok(Mesostructure::Volume(VolumeCaster::new(&volume)));
    }
    if magic[..n] == PNG_MAGIC[..] {
        let res = res.ok_or_else(|| {
            Error::InvalidParameter("a height field needs --res to choose its voxel grid".into())
        })?;
        let volume = HeightField::read(path, limits)?.to_volume(res, limits)?;
        return Ok(Mesostructure::Volume(VolumeCaster::new(&volume)));
    }
    let res = res.ok_or_else(|| {
        Error::InvalidParameter("an OBJ tile needs --res to choose its sampling grid".into())
    })?;
    let mesh = TriMesh::read_obj(path, limits.memory_bytes / 8)?;
    let tile = MeshTile::new(mesh, allow_open)?;
    Ok(Mesostructure::Mesh(Box::new(MeshCaster::new(
        &tile, res, limits,
    )?)))
}

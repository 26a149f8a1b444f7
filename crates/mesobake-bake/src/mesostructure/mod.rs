//! Mesostructure inputs: what a tile of surface detail is made of, and how it is read.
//! Voxel volumes ([`volume`], the `.mbvol` format in [`volume_format`]), closed OBJ tiles
//! ([`trimesh`], validated on the tiling by [`mesh_tile`]), grayscale height fields
//! ([`height_field`]), translucent media ([`medium`], built-in ones in [`media`]), the
//! built-in analytic samples ([`samples`]) and reliefs ([`reliefs`]), the empty-space distance
//! that makes exact casting fast ([`empty_space`]), and what an input file holds, told by
//! content ([`file_kind`]). [`crate::gdm::input`] loads any input file as a ray caster.

pub mod empty_space;
pub mod file_kind;
pub mod height_field;
pub mod material;
pub mod media;
pub mod medium;
pub mod mesh_tile;
pub mod openvdb;
pub mod raw_medium;
pub mod reliefs;
pub mod samples;
pub mod trimesh;
pub mod volume;
pub mod volume_format;

//! OpenVDB volumes in: a level set or a fog volume of a `.vdb` file becomes a mesostructure
//! volume (`mesobake import`, the server's volume uploads). Read by mesobake's own reader
//! ([`archive`], [`tree`], [`blosc`]) of the subset artists' tools write: file versions
//! 222–225, 5-4-3 trees of `float`, `double`, `vec3s` and `vec3d` values (also saved as half
//! floats), uncompressed, zip or Blosc (LZ4, zlib), transforms that scale uniformly and
//! translate. Anything else is refused by name.
//!
//! The index box — `res` voxels from index (0, 0, 0), or the grid's active bounding box —
//! becomes the volume's grid: volume voxel (i, j, k) is the VDB voxel at box minimum +
//! (i, j, k) (whose centre is a VDB index point).
//!
//! - A **level set** (grid class `level set`, φ in world units, negative inside) becomes an
//!   opaque volume: density `clamp(½ − φ/h, 0, 1)` with `h` the voxel size and threshold ½,
//!   so a voxel is solid where φ ≤ 0 and the material's normals follow the distance field.
//! - A **fog volume** (class `fog volume`, or `unknown`: a float density, an extinction
//!   coefficient per world unit) becomes a translucent medium: the opacity of one voxel
//!   length is `α = 1 − exp(−s·ρ·h)` (`s` the density scale, 1 by default), and the voxels
//!   with α = 1 are its solid; a `vec3s` grid named `Cd` or `color` with the same transform
//!   gives the albedo (linear RGB in [0, 1]; its background where inactive).
//!
//! (The `vdb-rs` crate was tried first: its 0.6 release misreads vector and half-float
//! grids and can panic or read out of bounds on malformed files, which a server that takes
//! uploads cannot allow.)

pub mod archive;
pub mod blosc;
pub mod tree;

use crate::mesostructure::volume::Volume;
use archive::{Archive, GridInfo, ValueType};
use mesobake_core::color::linear_to_srgb;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use serde::Serialize;
use tree::Tree;

/// What to import of a `.vdb` file.
#[derive(Clone, Debug, PartialEq)]
pub struct VdbImport {
    /// The grid; by default the first level set or fog volume, else the first float grid
    /// named `density`.
    pub grid: Option<String>,
    /// The index box from (0, 0, 0); by default the grid's active bounding box.
    pub res: Option<Dims>,
    /// Multiplies a fog volume's density (`s` in `α = 1 − exp(−s·ρ·h)`).
    pub density_scale: f64,
}

impl Default for VdbImport {
    fn default() -> Self {
        VdbImport {
            grid: None,
            res: None,
            density_scale: 1.0,
        }
    }
}

/// What an import read.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VdbImported {
    /// The grid imported.
    pub grid: String,
    /// What it became: `level set` (an opaque volume) or `fog volume` (a medium).
    pub class: String,
    /// The voxel edge in world units.
    pub voxel_size: f64,
    /// The index of volume voxel (0, 0, 0).
    pub origin: [i32; 3],
    /// The volume's grid.
    pub dims: [u32; 3],
    /// The colour grid a fog volume's albedo came from.
    pub color_grid: Option<String>,
}

fn bad(why: impl std::fmt::Display) -> Error {
    Error::VolumeFormat(format!("OpenVDB file: {why}"))
}

/// Imports a grid of the `.vdb` file `bytes` as a volume (see the module's documentation).
pub fn import(bytes: &[u8], options: &VdbImport, limits: &Limits) -> Result<(Volume, VdbImported)> {
    if !(options.density_scale.is_finite() && options.density_scale > 0.0) {
        return Err(Error::InvalidParameter(format!(
            "density scale {}: must be finite and positive",
            options.density_scale
        )));
    }
    let archive = Archive::read(bytes).map_err(bad)?;
    let grid = pick_grid(&archive, options.grid.as_deref())?;
    let transform = grid
        .transform
        .clone()
        .map_err(|e| bad(format!("grid {:?}: {e}", grid.name)))?;
    if let Some(parent) = &grid.instance_of {
        return Err(bad(format!(
            "grid {:?} is an instance of {parent:?} (it shares that grid's tree); import {parent:?}",
            grid.name
        )));
    }
    let level_set = match grid.class.as_str() {
        "level set" => true,
        "fog volume" | "unknown" => false,
        other => {
            return Err(bad(format!(
                "grid {:?} is of class {other}; mesobake imports level sets and fog volumes",
                grid.name
            )));
        }
    };
    // The box from the options, or (to check memory before reading) the writer's record.
    let declared = match options.res {
        Some(d) => Some(([0; 3], d)),
        None => grid
            .bbox
            .and_then(|(lo, hi)| Some((lo, box_dims(lo, hi).ok()?))),
    };
    if let Some((_, d)) = declared {
        check_volume_memory(d, limits)?;
    }
    let budget = limits.memory_bytes.saturating_sub(bytes.len() as u64);
    let keep = |leaf: [i32; 3]| match options.res {
        Some(d) => overlaps(leaf, [0; 3], d),
        None => true,
    };
    let tree = Tree::read(bytes, grid, budget, keep)
        .map_err(|e| bad(format!("grid {:?}: {e}", grid.name)))?;
    let (origin, dims) = match options.res {
        Some(d) => ([0; 3], d),
        None => {
            let (lo, hi) = tree.active_bbox().ok_or_else(|| {
                bad(format!(
                    "grid {:?} has no active voxels; give the box with --res",
                    grid.name
                ))
            })?;
            (lo, box_dims(lo, hi)?)
        }
    };
    check_volume_memory(dims, limits)?;
    let colour = if level_set {
        None
    } else {
        colour_grid(&archive, grid)?
    };
    let colour_tree = match colour {
        Some(g) => Some(
            Tree::read(bytes, g, budget - tree.bytes(), |leaf| {
                overlaps(leaf, origin, dims)
            })
            .map_err(|e| bad(format!("grid {:?}: {e}", g.name)))?,
        ),
        None => None,
    };
    let h = transform.voxel_size;
    let n = dims.voxel_count() as usize;
    let mut values = Vec::with_capacity(n);
    let mut albedo = colour_tree.as_ref().map(|_| Vec::with_capacity(n));
    for k in 0..dims.z {
        for j in 0..dims.y {
            for i in 0..dims.x {
                let p = [
                    origin[0] + i as i32,
                    origin[1] + j as i32,
                    origin[2] + k as i32,
                ];
                let v = tree.voxel(p).value[0];
                if !v.is_finite() || (!level_set && v < 0.0) {
                    return Err(bad(format!(
                        "grid {:?}: voxel {p:?} holds {v}, not a {}",
                        grid.name,
                        if level_set {
                            "finite distance"
                        } else {
                            "density ≥ 0"
                        }
                    )));
                }
                values.push(if level_set {
                    (0.5 - f64::from(v) / h).clamp(0.0, 1.0) as f32
                } else {
                    -(-options.density_scale * f64::from(v) * h).exp_m1() as f32
                });
                if let (Some(tree), Some(albedo)) = (&colour_tree, &mut albedo) {
                    albedo.push(srgb_bytes(tree.voxel(p).value, p)?);
                }
            }
        }
    }
    let volume = if level_set {
        Volume::new(dims, values, 0.5, None)?
    } else {
        Volume::new(dims, values.clone(), 1.0, albedo)?.with_opacity(values)?
    };
    let imported = VdbImported {
        grid: grid.name.clone(),
        class: if level_set { "level set" } else { "fog volume" }.into(),
        voxel_size: h,
        origin,
        dims: [dims.x, dims.y, dims.z],
        color_grid: colour.map(|g| g.name.clone()),
    };
    Ok((volume, imported))
}

/// The grid `name`, or the default one, checked to hold scalar values.
fn pick_grid<'a>(archive: &'a Archive, name: Option<&str>) -> Result<&'a GridInfo> {
    let scalar = |g: &GridInfo| matches!(g.value_type, Ok(ValueType::Float | ValueType::Double));
    let listing = || {
        let grids: Vec<String> = archive
            .grids
            .iter()
            .map(|g| {
                let ty = match &g.value_type {
                    Ok(t) => format!("{t:?}").to_lowercase(),
                    Err(t) => t.clone(),
                };
                format!("{:?} ({ty}, {})", g.name, g.class)
            })
            .collect();
        grids.join(", ")
    };
    let grid = match name {
        Some(name) => archive.grid(name).ok_or_else(|| {
            bad(format!(
                "no grid is named {name:?}; the file holds {}",
                listing()
            ))
        })?,
        None => archive
            .grids
            .iter()
            .find(|g| scalar(g) && matches!(g.class.as_str(), "level set" | "fog volume"))
            .or_else(|| {
                archive
                    .grids
                    .iter()
                    .find(|g| scalar(g) && g.name == "density")
            })
            .ok_or_else(|| {
                bad(format!(
                    "no level set, fog volume or float grid named \"density\" to import; the \
                     file holds {}; name one with --grid",
                    listing()
                ))
            })?,
    };
    match &grid.value_type {
        Ok(ValueType::Float | ValueType::Double) => Ok(grid),
        Ok(t) => Err(bad(format!(
            "grid {:?} holds {t:?} values; a level set or a fog density is a float grid",
            grid.name
        ))),
        Err(t) => Err(bad(format!(
            "grid {:?} is of type {t}, which mesobake does not import (it reads float, \
             double, vec3s and vec3d 5-4-3 trees)",
            grid.name
        ))),
    }
}

/// The colour grid of fog volume `density`: a vector grid named `Cd` or `color`, with the
/// same transform.
fn colour_grid<'a>(archive: &'a Archive, density: &GridInfo) -> Result<Option<&'a GridInfo>> {
    let Some(g) = archive
        .grids
        .iter()
        .find(|g| g.name == "Cd" || g.name == "color")
    else {
        return Ok(None);
    };
    if !matches!(g.value_type, Ok(ValueType::Vec3s | ValueType::Vec3d)) {
        return Err(bad(format!(
            "the colour grid {:?} does not hold vec3 values",
            g.name
        )));
    }
    if g.transform != density.transform {
        return Err(bad(format!(
            "the colour grid {:?}'s transform differs from {:?}'s ({:?} and {:?}): their \
             voxels do not line up",
            g.name, density.name, g.transform, density.transform
        )));
    }
    Ok(Some(g))
}

/// The grid of the index box `lo..=hi`.
fn box_dims(lo: [i32; 3], hi: [i32; 3]) -> Result<Dims> {
    let edge = |a: usize| i64::from(hi[a]) - i64::from(lo[a]) + 1;
    let edges = [edge(0), edge(1), edge(2)].map(|e| u32::try_from(e).unwrap_or(u32::MAX));
    Dims::new(edges[0], edges[1], edges[2]).map_err(|e| {
        bad(format!(
            "the active voxels span {lo:?} to {hi:?}: {e}; give a smaller box with --res"
        ))
    })
}

/// Refuses a volume of `dims` over the memory limit: density and opacity (f32 each) and
/// albedo (3 bytes) per voxel.
fn check_volume_memory(dims: Dims, limits: &Limits) -> Result<()> {
    limits.check("the imported volume", dims.voxel_count(), 11)?;
    Ok(())
}

/// Whether the leaf (8³ voxels) at `leaf` meets the box of `dims` from `origin`.
fn overlaps(leaf: [i32; 3], origin: [i32; 3], dims: Dims) -> bool {
    let size = [dims.x, dims.y, dims.z];
    (0..3).all(|a| {
        let (l, o) = (i64::from(leaf[a]), i64::from(origin[a]));
        l + 8 > o && l < o + i64::from(size[a])
    })
}

/// A linear colour in [0, 1] as sRGB bytes.
fn srgb_bytes(rgb: &[f32], p: [i32; 3]) -> Result<[u8; 3]> {
    if let Some(c) = rgb.iter().find(|c| !(0.0..=1.0).contains(*c)) {
        return Err(bad(format!(
            "the colour at voxel {p:?} has a component {c}, not a number in [0, 1]"
        )));
    }
    Ok([0, 1, 2].map(|c| (linear_to_srgb(rgb[c]) * 255.0).round() as u8))
}

//! The occupancy codec: instead of a table of distances, the mesostructure itself — one byte
//! per voxel holding 0 for a solid voxel and otherwise the Chebyshev distance to the nearest
//! solid voxel ([`EmptySpace`], saturating at 255) — which renderers ray-march along each
//! query, skipping empty space exactly (`render::gdm_lookup::OccupancyLookup`, and the WGSL
//! `shaders/query_occupancy.wgsl`). The answers are the exact GDM of the voxel grid at any
//! position and direction, not only at the baked samples.

use crate::error::{Error, Result};
use crate::grid::Dims;
use crate::mesostructure::empty_space::EmptySpace;
use crate::mesostructure::volume::Occupancy;

/// A voxel grid's occupancy with its empty-space distances, as a package stores them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OccupancyField {
    dims: Dims,
    /// Per voxel (x fastest, then y, then z): 0 solid, else the distance to solid.
    distance: Vec<u8>,
}

impl OccupancyField {
    /// Encodes `occ`.
    pub fn new(occ: &Occupancy) -> Self {
        OccupancyField {
            dims: occ.dims(),
            distance: EmptySpace::new(occ).distances().to_vec(),
        }
    }

    /// Decodes and validates stored bytes: one per voxel of `dims`, and every distance the
    /// one its solid voxels (the zeros) imply, so that a march skipping by them is exact.
    pub fn from_bytes(dims: Dims, bytes: &[u8]) -> Result<Self> {
        if bytes.len() as u64 != dims.voxel_count() {
            return Err(Error::Package(format!(
                "the occupancy field holds {} bytes, not one per voxel of {dims} ({})",
                bytes.len(),
                dims.voxel_count()
            )));
        }
        let field = OccupancyField::new(&occupancy_of(dims, bytes));
        if field.distance != bytes {
            let voxel = bytes.iter().zip(&field.distance).position(|(a, b)| a != b);
            return Err(Error::Package(format!(
                "the occupancy field's distance at voxel {} is {}, but its solid voxels give {}",
                voxel.unwrap_or(0),
                voxel.map_or(0, |v| bytes[v]),
                voxel.map_or(0, |v| field.distance[v])
            )));
        }
        Ok(field)
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The stored bytes: one per voxel, x fastest.
    pub fn bytes(&self) -> &[u8] {
        &self.distance
    }

    /// The occupancy the field encodes.
    pub fn occupancy(&self) -> Occupancy {
        occupancy_of(self.dims, &self.distance)
    }

    /// Solid voxels.
    pub fn solid_voxels(&self) -> u64 {
        self.distance.iter().filter(|&&d| d == 0).count() as u64
    }
}

/// The occupancy whose solid voxels are the zeros of `bytes` (one per voxel of `dims`).
fn occupancy_of(dims: Dims, bytes: &[u8]) -> Occupancy {
    let mut occ = Occupancy::empty(dims);
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    for (v, _) in bytes.iter().enumerate().filter(|(_, d)| **d == 0) {
        occ.set(
            (v % nx) as u32,
            (v / nx % ny) as u32,
            (v / (nx * ny)) as u32,
        );
    }
    occ
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Occupancy {
        let dims = Dims::new(8, 6, 5).unwrap();
        let mut occ = Occupancy::empty(dims);
        occ.set(1, 2, 0);
        occ.set(7, 5, 4);
        occ.set(3, 3, 2);
        occ
    }

    #[test]
    fn a_field_round_trips_and_its_distances_are_chebyshev_to_the_nearest_solid() {
        let occ = sample();
        let field = OccupancyField::new(&occ);
        let back = OccupancyField::from_bytes(occ.dims(), field.bytes()).unwrap();
        assert_eq!(back, field);
        assert_eq!(back.occupancy(), occ);
        assert_eq!(field.solid_voxels(), 3);
        // Brute force: L∞ distance, periodic in x and y, over the three solid voxels.
        let solids = [(1i64, 2i64, 0i64), (7, 5, 4), (3, 3, 2)];
        let d = occ.dims();
        for (v, &stored) in field.bytes().iter().enumerate() {
            let (i, j, k) = ((v % 8) as i64, (v / 8 % 6) as i64, (v / 48) as i64);
            let periodic =
                |a: i64, b: i64, n: i64| (a - b).rem_euclid(n).min((b - a).rem_euclid(n));
            let expected = solids
                .iter()
                .map(|&(x, y, z)| {
                    periodic(i, x, d.x as i64)
                        .max(periodic(j, y, d.y as i64))
                        .max((k - z).abs())
                })
                .min()
                .unwrap();
            assert_eq!(stored as i64, expected, "voxel {v}");
        }
    }

    #[test]
    fn inconsistent_or_short_fields_are_refused_naming_the_voxel() {
        let occ = sample();
        let mut bytes = OccupancyField::new(&occ).bytes().to_vec();
        let e = OccupancyField::from_bytes(occ.dims(), &bytes[1..]).unwrap_err();
        assert!(e.to_string().contains("not one per voxel"), "{e}");
        // A distance larger than the truth would let a march skip a solid voxel.
        bytes[0] += 1;
        let e = OccupancyField::from_bytes(occ.dims(), &bytes).unwrap_err();
        assert!(e.to_string().contains("distance at voxel 0"), "{e}");
    }
}

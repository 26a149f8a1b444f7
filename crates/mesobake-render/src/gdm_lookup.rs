//! GDM queries at continuous positions and directions, as the renderers and shaders make
//! them: d(T, V) for a texture point T (voxel units) and a unit texture-space direction V.
//!
//! Interpolation (the same for raw GDMs and packages, mirroring GPU texture filtering):
//! positions are linear between voxel centres, x and y periodic, z clamped to the centres of
//! the first and last layers; directions are linear between bin centres, φ periodic, θ clamped
//! to the first and last bins.
//! - A raw GDM interpolates over all 32 corners (x, y, z, θ, φ). Escaping corners vote: the
//!   query escapes when their weight is at least ½; otherwise the distance is the weighted
//!   mean of the hitting corners.
//! - A package reconstructs d̃ = Σᵢ W̃ᵢ(x, y, φ)·Ẽᵢ(θ, z), each factor interpolated on its
//!   own (trilinear in the weight maps' 3D textures, bilinear in the eigenmaps' 2D ones), and
//!   applies the package's escape rule d̃ ≥ (1 − μ)·b̃ with the boundary distance b̃
//!   interpolated like the eigenmaps.
//! - An occupancy package marches its voxels exactly ([`OccupancyLookup`]): no interpolation
//!   and no escape rule, the exact GDM of the voxel grid at any position and direction.
//! - A split GDM ([`SplitLookup`]) answers segment queries from its capped distances and
//!   shadow queries from its escape bits, both as a raw GDM.

use glam::DVec3;
use mesobake_bake::compress::accuracy::is_escape;
use mesobake_bake::compress::occupancy::OccupancyField;
use mesobake_bake::compress::quantize::QuantizedFactor;
use mesobake_bake::compress::split::SplitGdm;
use mesobake_bake::gdm::caster::{Caster, Trace};
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::gdm::{ESCAPE_TOLERANCE, EscapeConvention, Gdm};
use mesobake_bake::mesostructure::volume::Occupancy;
use mesobake_bake::package::Package;
use mesobake_core::error::{Error, Result};
use mesobake_package::grid::{Dims, DirectionGrid, Wrap};
use std::f64::consts::{PI, TAU};

/// How far short of the previous estimate, in voxels, a refinement query is made: close enough
/// that the neighbouring samples agree on the remaining distance, far enough to stay in front
/// of the surface (measured on the torus + chain and flat chain scenes: 0.5 and 2 are 0.1 dB
/// worse).
pub const REFINEMENT_BACKOFF: f64 = 1.0;

/// How far along `view` the query point moves from `t` (voxel units) to reach the centre
/// plane of the top layer (z = Z − ½) when it enters from the half voxel above it, or of the
/// bottom layer (z = ½) from below; 0 otherwise, or when that plane lies beyond the segment's
/// length `d_t`. Samples sit at voxel centres, so this keeps the query on the ray instead of
/// clamping it half a voxel away.
pub fn advance_to_samples(t: DVec3, view: DVec3, z: f64, d_t: f64) -> f64 {
    let s = if view.z < 0.0 && t.z > z - 0.5 {
        (t.z - (z - 0.5)) / -view.z
    } else if view.z > 0.0 && t.z < 0.5 {
        (0.5 - t.z) / view.z
    } else {
        0.0
    };
    if s < d_t { s } else { 0.0 }
}

/// The answer to one query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lookup {
    /// Solid at this distance (voxel units; 0 inside solid).
    Hit(f64),
    /// The ray leaves through the top or bottom plane first.
    Escape,
}

/// Something that answers GDM queries.
pub trait GdmLookup: Sync {
    /// The voxel grid.
    fn dims(&self) -> Dims;
    /// d(`t`, `v`): `t` in voxel units, `v` a unit texture-space direction.
    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup;

    /// Steps 3–5 of the per-pixel algorithm (`render::gdm_renderer`) on the texture-space
    /// segment from `start` along `view` of length `d_t`: the hit distance, or `None` when
    /// the ray leaves the segment first. By default the paper's query on a table of
    /// distances: one lookup from the sample layers ([`advance_to_samples`]), then up to
    /// `refinements` more from [`REFINEMENT_BACKOFF`] voxel short of the last hit.
    fn segment_hit(&self, start: DVec3, view: DVec3, d_t: f64, refinements: u32) -> Option<f64> {
        let mut travelled = advance_to_samples(start, view, self.dims().z as f64, d_t);
        let mut answer = self.lookup(start + view * travelled, view);
        for _ in 0..refinements {
            let Lookup::Hit(d) = answer else { break };
            let step = d - REFINEMENT_BACKOFF;
            if step <= 0.0 || travelled + d >= d_t {
                break;
            }
            let next = self.lookup(start + view * (travelled + step), view);
            if next == Lookup::Escape {
                break;
            }
            travelled += step;
            answer = next;
        }
        match answer {
            Lookup::Hit(d) if travelled + d < d_t => Some(travelled + d),
            _ => None,
        }
    }

    /// The shadow query: whether the ray from `t` along the unit direction `v` leaves the
    /// volume without a hit. By default [`GdmLookup::lookup`]'s answer.
    fn escapes(&self, t: DVec3, v: DVec3) -> bool {
        self.lookup(t, v) == Lookup::Escape
    }
}

/// The lookup a package's codec calls for: [`OccupancyLookup`] or [`PackageLookup`].
pub fn package_lookup(package: &Package) -> Result<Box<dyn GdmLookup>> {
    Ok(match package.occupancy() {
        Some(field) => Box::new(OccupancyLookup::new(&field?)),
        None => Box::new(PackageLookup::new(package)?),
    })
}

/// Queries answered exactly by ray marching a package's occupancy field (the `occupancy`
/// codec): the voxel traversal of the GDM bake ([`VolumeCaster`], closed voxel boxes,
/// empty-space skipping), from the query point (z clamped into the grid) along the query
/// direction. Segment queries march only as far as the segment; no refinement applies.
pub struct OccupancyLookup {
    caster: VolumeCaster,
}

impl OccupancyLookup {
    /// Prepares `field` for marching.
    pub fn new(field: &OccupancyField) -> Self {
        OccupancyLookup {
            caster: VolumeCaster::from_occupancy(Occupancy::of_field(field), true),
        }
    }

    fn march(&self, t: DVec3, v: DVec3, max: f64) -> Option<f64> {
        let z = self.caster.dims().z as f64;
        // A start on or past the top (bottom) plane, not moving down (up), is outside the
        // volume and stays there: it escapes, as the shader's march says, even where the
        // layer it touches is solid (a shadow ray from a hit on the top layer, whose start
        // one voxel off the surface clamps onto the top plane).
        if (t.z >= z && v.z >= 0.0) || (t.z <= 0.0 && v.z <= 0.0) {
            return None;
        }
        match self
            .caster
            .trace(t.with_z(t.z.clamp(0.0, z)).to_array(), v.to_array(), max)
        {
            Trace::Inside => Some(0.0),
            Trace::Hit(s) => Some(s),
            Trace::Escape(_) | Trace::Limit => None,
        }
    }
}

impl GdmLookup for OccupancyLookup {
    fn dims(&self) -> Dims {
        self.caster.dims()
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        self.march(t, v, f64::INFINITY)
            .map_or(Lookup::Escape, Lookup::Hit)
    }

    fn segment_hit(&self, start: DVec3, view: DVec3, d_t: f64, _refinements: u32) -> Option<f64> {
        self.march(start, view, d_t).filter(|&d| d < d_t)
    }
}

/// Linear interpolation taps along one axis: two indices and the weight of the second.
#[derive(Clone, Copy, Debug)]
struct Taps {
    index: [u32; 2],
    frac: f64,
}

impl Taps {
    fn periodic(coord: f64, n: u32) -> Taps {
        let f = coord.floor();
        let wrap = Wrap::new(n);
        Taps {
            index: [wrap.apply(f as i64) as u32, wrap.apply(f as i64 + 1) as u32],
            frac: coord - f,
        }
    }

    fn clamped(coord: f64, n: u32) -> Taps {
        let c = coord.clamp(0.0, (n - 1) as f64);
        let f = c.floor();
        let i = f as u32;
        Taps {
            index: [i, (i + 1).min(n - 1)],
            frac: c - f,
        }
    }

    fn weight(&self, side: u32) -> f64 {
        if side == 1 {
            self.frac
        } else {
            1.0 - self.frac
        }
    }
}

/// Position and direction taps of one query.
struct QueryTaps {
    x: Taps,
    y: Taps,
    z: Taps,
    theta: Taps,
    phi: Taps,
}

impl QueryTaps {
    fn new(dims: Dims, dirs: DirectionGrid, t: DVec3, v: DVec3) -> QueryTaps {
        let theta = v.z.clamp(-1.0, 1.0).acos();
        let phi = v.y.atan2(v.x).rem_euclid(TAU);
        QueryTaps {
            x: Taps::periodic(t.x - 0.5, dims.x),
            y: Taps::periodic(t.y - 0.5, dims.y),
            z: Taps::clamped(t.z - 0.5, dims.z),
            theta: Taps::clamped(theta / PI * dirs.n_theta as f64 - 0.5, dirs.n_theta),
            phi: Taps::periodic(phi / TAU * dirs.n_phi as f64 - 0.5, dirs.n_phi),
        }
    }
}

/// Queries on a dense GDM as baked (either escape convention).
pub struct RawLookup<'a> {
    gdm: &'a Gdm,
    /// Per direction bin θ and layer k (index θ·Z + k): stored values at or above this are
    /// escapes (`+∞` in the infinite convention).
    escape_from: Vec<f32>,
}

impl<'a> RawLookup<'a> {
    /// Wraps `gdm`.
    pub fn new(gdm: &'a Gdm) -> Self {
        let (dims, dirs) = (gdm.dims(), gdm.dirs());
        let escape_from = (0..dirs.n_theta)
            .flat_map(|a| (0..dims.z).map(move |k| (a, k)))
            .map(|(a, k)| match gdm.escape_convention() {
                EscapeConvention::Infinite => f32::INFINITY,
                EscapeConvention::Boundary => ESCAPE_TOLERANCE * gdm.boundary_distance(k, a),
            })
            .collect();
        RawLookup { gdm, escape_from }
    }
}

impl GdmLookup for RawLookup<'_> {
    fn dims(&self) -> Dims {
        self.gdm.dims()
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        let g = self.gdm;
        let (dims, data) = (g.dims(), g.data());
        let q = QueryTaps::new(dims, g.dirs(), t, v);
        // The 8 spatial taps: weight, flat index within one direction's volume, layer.
        let spatial: [(f64, usize, u32); 8] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let (i, j, k) = (q.x.index[s[0]], q.y.index[s[1]], q.z.index[s[2]]);
            let w = q.x.weight(s[0] as u32) * q.y.weight(s[1] as u32) * q.z.weight(s[2] as u32);
            (w, dims.index(i, j, k), k)
        });
        let (mut escape, mut hit, mut sum) = (0.0, 0.0, 0.0);
        for (sa, &a) in q.theta.index.iter().enumerate() {
            let escape_from = &self.escape_from[(a * dims.z) as usize..];
            for (sb, &b) in q.phi.index.iter().enumerate() {
                let w_dir = q.theta.weight(sa as u32) * q.phi.weight(sb as u32);
                if w_dir == 0.0 {
                    continue;
                }
                let base = g.index(0, 0, 0, a, b);
                for &(w, index, k) in &spatial {
                    let w = w * w_dir;
                    let value = data[base + index];
                    if value >= escape_from[k as usize] {
                        escape += w;
                    } else {
                        hit += w;
                        sum += w * value as f64;
                    }
                }
            }
        }
        if escape >= 0.5 || hit == 0.0 {
            Lookup::Escape
        } else {
            Lookup::Hit(sum / hit)
        }
    }
}

/// Queries on a split GDM ([`SplitGdm`]): lookups and segment queries on the capped primary
/// distances (no hit within the cap reads as an escape), shadow queries on the escape bits,
/// both with the raw lookup's interpolation.
pub struct SplitLookup<'a> {
    primary: RawLookup<'a>,
    visibility: RawLookup<'a>,
}

impl<'a> SplitLookup<'a> {
    /// Wraps `split`.
    pub fn new(split: &'a SplitGdm) -> Self {
        SplitLookup {
            primary: RawLookup::new(&split.primary.reconstruction),
            visibility: RawLookup::new(&split.visibility),
        }
    }
}

impl GdmLookup for SplitLookup<'_> {
    fn dims(&self) -> Dims {
        self.primary.dims()
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        self.primary.lookup(t, v)
    }

    fn escapes(&self, t: DVec3, v: DVec3) -> bool {
        self.visibility.escapes(t, v)
    }
}

/// Queries on a package's factors: the reconstruction a shader computes.
pub struct PackageLookup {
    dims: Dims,
    dirs: DirectionGrid,
    rank: usize,
    /// Dequantized weights, rows (φ, y, x) as in the package's 3D textures.
    weights: Vec<f32>,
    /// Dequantized eigenmaps, rows (θ, z).
    eigen: Vec<f32>,
    /// Boundary distance per (θ, z).
    boundary: Vec<f32>,
    margin: f32,
}

impl PackageLookup {
    /// Unpacks `package`'s factors (codec `paper-svd`).
    pub fn new(package: &Package) -> Result<Self> {
        let (Some((w, e)), Some(g)) = (package.factors(), &package.manifest().gdm) else {
            return Err(Error::Package(format!(
                "the package's codec is {}, not paper-svd",
                package.manifest().codec
            )));
        };
        let margin = g.accuracy.escape_margin;
        Ok(Self::from_factors(
            package.dims(),
            package.dirs(),
            &w,
            &e,
            margin,
        ))
    }

    /// From quantized factors as a package holds them (weight maps rows (φ, y, x), eigenmaps
    /// rows (θ, z)) and the escape margin μ.
    pub fn from_factors(
        dims: Dims,
        dirs: DirectionGrid,
        weights: &QuantizedFactor,
        eigen: &QuantizedFactor,
        margin: f32,
    ) -> Self {
        let boundary = (0..dirs.n_theta)
            .flat_map(|a| (0..dims.z).map(move |k| (a, k)))
            .map(|(a, k)| mesobake_package::grid::boundary_distance(dims, &dirs, k, a))
            .collect();
        PackageLookup {
            dims,
            dirs,
            rank: weights.rank,
            weights: weights.dequantize(),
            eigen: eigen.dequantize(),
            boundary,
            margin,
        }
    }
}

impl GdmLookup for PackageLookup {
    fn dims(&self) -> Dims {
        self.dims
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        let (d, k) = (self.dims, self.rank);
        let q = QueryTaps::new(d, self.dirs, t, v);
        let w_taps: [(f64, usize); 8] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let weight =
                q.x.weight(s[0] as u32) * q.y.weight(s[1] as u32) * q.phi.weight(s[2] as u32);
            let row = (q.phi.index[s[2]] * d.y + q.y.index[s[1]]) * d.x + q.x.index[s[0]];
            (weight, row as usize * k)
        });
        let e_taps: [(f64, usize); 4] = std::array::from_fn(|c| {
            let s = [c & 1, (c >> 1) & 1];
            let weight = q.theta.weight(s[0] as u32) * q.z.weight(s[1] as u32);
            (
                weight,
                (q.theta.index[s[0]] * d.z + q.z.index[s[1]]) as usize,
            )
        });
        let mut dist = 0.0;
        for i in 0..k {
            let w: f64 = w_taps
                .iter()
                .map(|&(c, r)| c * self.weights[r + i] as f64)
                .sum();
            let e: f64 = e_taps
                .iter()
                .map(|&(c, r)| c * self.eigen[r * k + i] as f64)
                .sum();
            dist += w * e;
        }
        let boundary: f64 = e_taps
            .iter()
            .map(|&(c, r)| c * self.boundary[r] as f64)
            .sum();
        if is_escape(dist as f32, boundary as f32, self.margin) {
            Lookup::Escape
        } else {
            Lookup::Hit(dist.max(0.0))
        }
    }
}

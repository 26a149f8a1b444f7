//! Shadow maps of a translucent medium, the real-time algorithm's alternatives to a shadow ray
//! per sample ([`ShadowMethod`]); the WGSL pipeline builds and reads the same maps.
//!
//! 1. **Light space.** Each point or directional light gets a [`LightFrame`] over the cells'
//!    bounding sphere (centre c, radius r: half the bounding box's diagonal, 1 % larger): a
//!    directional light an orthographic map, square, 2r wide, perpendicular to the light's
//!    direction; a point light outside the sphere a perspective map from the light, the
//!    square frustum around the sphere. A point light inside the sphere has no map: its
//!    shadows are traced as rays. Texel (i, j) of an n × n map has its centre at
//!    u = 2(i + ½)/n − 1, v = 2(j + ½)/n − 1 and casts one ray, whose parameter t (object
//!    distance from the map's origin) runs over the sphere: [t₀, t₀ + 2r].
//! 2. **Build**, one texel ray at a time through the cells ([`CellRenderer::optical_depths`]),
//!    order-independent and from nothing but the cells and the medium (rebuilt each frame,
//!    so animated meshes and media need nothing precomputed): the optical depth τ(t), exact
//!    and piecewise linear along the ray (each voxel piece adds σ·ℓ, σ = −ln(1 − α) per voxel
//!    length, [`OPAQUE_EXTINCTION`] where α = 1), in mip level 0.
//!    - **Opacity map** (Kim and Neumann's opacity shadow maps, with optical depth rather
//!      than opacity so that it interpolates linearly, and the slices per texel over the
//!      stretch its ray spends in the shell rather than over the whole sphere: a thin shell
//!      would otherwise fall between two slices): the ray's first entry into the cells t_a
//!      and last exit t_b, and τ at K depths t_k = t_a + (t_b − t_a)·(k + 1)/K, k < K
//!      (τ(t_a) = 0), capped at [`MAX_OPTICAL_DEPTH`]. A texel whose ray meets no cell has
//!      t_a = t_b = +∞ and τ = 0.
//!    - **Depth map** (the paper's shadow map): the first t where τ reaches
//!      [`DEPTH_THRESHOLD`] (transmittance ½), or none.
//! 3. **Lookup** of a point x lit from a light: its map coordinates (u, v, t), with t moved
//!    towards the light by the same start as the shadow rays ([`SHADOW_START`] voxels), then
//!    bilinear over the four nearest texel centres (clamped at the edges): of τ, linear
//!    between the slices, giving exp(−τ) (0 from [`MAX_OPTICAL_DEPTH`]); or of the depth
//!    test t < depth (percentage-closer filtering).
//!
//! [`SHADOW_START`]: super::medium_truth::SHADOW_START

use super::medium_cells::CellRenderer;
use crate::scene::transparency::ShadowMethod;
use crate::scene::{Light, Scene};
use glam::DVec3;
use rayon::prelude::*;
use std::ops::ControlFlow;

/// Optical depth from which a map counts the light as blocked: −ln of
/// [`super::medium_truth::MIN_TRANSMITTANCE`].
pub const MAX_OPTICAL_DEPTH: f64 = 13.815510557964274;

/// Extinction per voxel length that stands for an opaque voxel (α = 1): the light is blocked
/// within 1/700 voxel.
pub const OPAQUE_EXTINCTION: f64 = 1.0e4;

/// Optical depth at which the depth map records its depth: ln 2, transmittance ½.
pub const DEPTH_THRESHOLD: f64 = std::f64::consts::LN_2;

/// Bounding sphere's margin over the cells' box.
const SPHERE_MARGIN: f64 = 1.01;

/// How a map's texels cast their rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// Parallel rays along the axis from the map's plane (a directional light).
    Orthographic,
    /// Rays from the map's origin (a point light) through the square around the axis.
    Perspective,
}

/// A light's shadow map space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightFrame {
    /// How texels cast rays.
    pub projection: Projection,
    /// Orthographic: the map's centre (on the sphere, towards the light); perspective: the
    /// light.
    pub origin: DVec3,
    /// Unit direction the light travels (towards the sphere's centre).
    pub axis: DVec3,
    /// The map's u axis, scaled: orthographic, u = 1 is `origin + u_axis`; perspective,
    /// direction `axis + u_axis`.
    pub u_axis: DVec3,
    /// The map's v axis, scaled the same way.
    pub v_axis: DVec3,
    /// Ray parameter where the sphere starts.
    pub t0: f64,
    /// Ray parameter length across the sphere (2r).
    pub depth: f64,
}

impl LightFrame {
    /// The frame of `light` over the sphere at `centre` of `radius`; `None` for ambient
    /// light and point lights inside the sphere.
    pub fn new(light: &Light, centre: DVec3, radius: f64) -> Option<LightFrame> {
        let (projection, axis, origin, t0, scale) = match *light {
            Light::Directional { direction, .. } => {
                let axis = DVec3::from(direction).try_normalize()?;
                (
                    Projection::Orthographic,
                    axis,
                    centre - axis * radius,
                    0.0,
                    radius,
                )
            }
            Light::Point { position, .. } => {
                let p = DVec3::from(position);
                let distance = p.distance(centre);
                if distance <= radius {
                    return None;
                }
                // tan of the half-angle under which the light sees the sphere.
                let tan = radius / (distance * distance - radius * radius).sqrt();
                let axis = (centre - p) / distance;
                (Projection::Perspective, axis, p, distance - radius, tan)
            }
            Light::Ambient { .. } => return None,
        };
        // A basis perpendicular to the axis, from the world axis least aligned with it.
        let helper = if axis.x.abs() < 0.9 {
            DVec3::X
        } else {
            DVec3::Y
        };
        let u = helper.cross(axis).normalize();
        let v = axis.cross(u);
        Some(LightFrame {
            projection,
            origin,
            axis,
            u_axis: u * scale,
            v_axis: v * scale,
            t0,
            depth: 2.0 * radius,
        })
    }

    /// The ray (origin, unit direction) of map point (u, v).
    pub fn ray(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let across = self.u_axis * u + self.v_axis * v;
        match self.projection {
            Projection::Orthographic => (self.origin + across, self.axis),
            Projection::Perspective => (self.origin, (self.axis + across).normalize()),
        }
    }

    /// The map point (u, v) and ray parameter t of object point `x` (`None` behind a point
    /// light).
    pub fn project(&self, x: DVec3) -> Option<(f64, f64, f64)> {
        let d = x - self.origin;
        let along = d.dot(self.axis);
        let (scale, t) = match self.projection {
            Projection::Orthographic => (1.0, along),
            Projection::Perspective if along > 0.0 => (1.0 / along, d.length()),
            Projection::Perspective => return None,
        };
        let u = d.dot(self.u_axis) / self.u_axis.length_squared() * scale;
        let v = d.dot(self.v_axis) / self.v_axis.length_squared() * scale;
        Some((u, v, t))
    }
}

/// One light's map.
#[derive(Clone, Debug)]
pub struct ShadowMap {
    /// Its space.
    pub frame: LightFrame,
    /// Texels along a side.
    pub size: u32,
    /// Values per texel: t_a, t_b and K optical depths (opacity map) or one depth (depth
    /// map, +∞ where the light is never blocked), texel (i, j) at (j·size + i)·stride.
    pub values: Vec<f64>,
    method: ShadowMethod,
    stride: usize,
}

impl ShadowMap {
    /// Builds the map of `method` (not [`ShadowMethod::Rays`]) of the light seen through
    /// `frame`, with the settings' size and slices, through `cells`.
    pub fn build(cells: &CellRenderer, frame: LightFrame, method: ShadowMethod) -> ShadowMap {
        let settings = cells.settings();
        let size = settings.shadow_map_size;
        let stride = match method {
            ShadowMethod::OpacityMap => settings.shadow_slices as usize + 2,
            _ => 1,
        };
        let n = size as usize;
        let mut values = vec![0.0; n * n * stride];
        values
            .par_chunks_mut(n * stride)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, texel) in row.chunks_mut(stride).enumerate() {
                    let (o, d) = frame.ray(texel_centre(i, size), texel_centre(j, size));
                    let (t0, t1) = (frame.t0, frame.t0 + frame.depth);
                    match method {
                        ShadowMethod::OpacityMap => opacity_texel(cells, o, d, (t0, t1), texel),
                        _ => texel[0] = depth_texel(cells, o, d, t0, t1),
                    }
                }
            });
        ShadowMap {
            frame,
            size,
            values,
            method,
            stride,
        }
    }

    /// The fraction of the light that reaches `x` through the medium, looked up from
    /// `start` (object distance) towards the light.
    pub fn visibility(&self, x: DVec3, start: f64) -> f64 {
        let Some((u, v, t)) = self.frame.project(x) else {
            return 1.0;
        };
        let t = t - start;
        let n = self.size;
        let (i0, i1, wi) = texel_span(u, n);
        let (j0, j1, wj) = texel_span(v, n);
        let corners = [
            (i0, j0, (1.0 - wi) * (1.0 - wj)),
            (i1, j0, wi * (1.0 - wj)),
            (i0, j1, (1.0 - wi) * wj),
            (i1, j1, wi * wj),
        ];
        let texel = |i: usize, j: usize| {
            let at = (j * n as usize + i) * self.stride;
            &self.values[at..at + self.stride]
        };
        match self.method {
            ShadowMethod::OpacityMap => {
                let tau: f64 = corners
                    .iter()
                    .map(|&(i, j, w)| w * optical_depth_at(texel(i, j), t))
                    .sum();
                if tau >= MAX_OPTICAL_DEPTH {
                    0.0
                } else {
                    (-tau).exp()
                }
            }
            _ => corners
                .iter()
                .filter(|&&(i, j, _)| t < texel(i, j)[0])
                .map(|c| c.2)
                .sum(),
        }
    }
}

/// The map coordinate of texel `i`'s centre.
fn texel_centre(i: usize, size: u32) -> f64 {
    2.0 * (i as f64 + 0.5) / f64::from(size) - 1.0
}

/// The two texels around map coordinate `u` and the second one's bilinear weight (clamped
/// at the edges).
fn texel_span(u: f64, size: u32) -> (usize, usize, f64) {
    let last = f64::from(size - 1);
    let f = ((u + 1.0) * 0.5 * f64::from(size) - 0.5).clamp(0.0, last);
    let f = if f.is_nan() { 0.0 } else { f };
    let i0 = f.floor();
    let i1 = (i0 + 1.0).min(last);
    (i0 as usize, i1 as usize, f - i0)
}

/// An opacity-map texel's optical depth at ray parameter `t`: linear between its nodes,
/// node 0 at t_a (τ = 0), node k + 1 at slice k; 0 before t_a, the last slice's after t_b.
fn optical_depth_at(texel: &[f64], t: f64) -> f64 {
    let (ta, tb, slices) = (texel[0], texel[1], &texel[2..]);
    let k_max = slices.len() as f64;
    let g = if tb > ta {
        ((t - ta) / (tb - ta) * k_max).clamp(0.0, k_max)
    } else if t > ta {
        k_max
    } else {
        0.0
    };
    slice_depth(slices, g)
}

/// Optical depth at slice coordinate `g` ∈ [0, K] (node 0, where it is 0; node k + 1 the
/// value of slice k), linear between nodes.
fn slice_depth(values: &[f64], g: f64) -> f64 {
    let node = |k: usize| if k == 0 { 0.0 } else { values[k - 1] };
    let k = (g.floor() as usize).min(values.len() - 1);
    let w = g - k as f64;
    node(k) * (1.0 - w) + node(k + 1) * w
}

/// Fills an opacity-map texel: the stretch of `o + t·d`, t ∈ `range`, in the cells, and the
/// optical depth at each of its slices.
fn opacity_texel(cells: &CellRenderer, o: DVec3, d: DVec3, range: (f64, f64), out: &mut [f64]) {
    let crossings = cells.cells().crossings(o, d, range.0, range.1);
    out.fill(0.0);
    let Some(entry) = crossings.first() else {
        out[..2].fill(f64::INFINITY);
        return;
    };
    let first = entry.t_in;
    let last = crossings.iter().map(|c| c.t_out).fold(first, f64::max);
    out[0] = first;
    out[1] = last;
    let out = &mut out[2..];
    let slices = out.len();
    let slice_t = |k: usize| first + (last - first) * (k + 1) as f64 / slices as f64;
    let (mut tau, mut k) = (0.0, 0);
    let _ = cells.optical_depths(o, d, first, last, |ta, tb, piece| {
        while k < slices && slice_t(k) <= tb {
            let w = if tb > ta {
                ((slice_t(k) - ta) / (tb - ta)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            out[k] = (tau + piece * w).min(MAX_OPTICAL_DEPTH);
            k += 1;
        }
        tau += piece;
        if tau >= MAX_OPTICAL_DEPTH {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    out[k..].fill(tau.min(MAX_OPTICAL_DEPTH));
}

/// A depth-map texel: where the optical depth along `o + t·d`, t ∈ [`t0`, `t1`], reaches
/// [`DEPTH_THRESHOLD`], or +∞.
fn depth_texel(cells: &CellRenderer, o: DVec3, d: DVec3, t0: f64, t1: f64) -> f64 {
    let mut tau = 0.0;
    let mut depth = f64::INFINITY;
    let _ = cells.optical_depths(o, d, t0, t1, |ta, tb, piece| {
        if tau + piece >= DEPTH_THRESHOLD {
            depth = ta + (tb - ta) * ((DEPTH_THRESHOLD - tau) / piece);
            return ControlFlow::Break(());
        }
        tau += piece;
        ControlFlow::Continue(())
    });
    depth
}

/// Every light's map for `cells` under `scene` (`None` where a light has none: ambient,
/// a point light inside the bounding sphere, or shadows by [`ShadowMethod::Rays`]).
pub fn build_maps(cells: &CellRenderer, scene: &Scene) -> Vec<Option<ShadowMap>> {
    let method = cells.settings().shadows;
    let frames = light_frames(cells, scene);
    frames
        .into_iter()
        .map(|frame| {
            frame
                .filter(|_| method != ShadowMethod::Rays)
                .map(|f| ShadowMap::build(cells, f, method))
        })
        .collect()
}

/// Every light's frame over the cells' bounding sphere (`None` where it has none).
pub fn light_frames(cells: &CellRenderer, scene: &Scene) -> Vec<Option<LightFrame>> {
    let bounds = cells.cells().bounds();
    let Some((lo, hi)) = bounds
        .into_iter()
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    else {
        return vec![None; scene.lights.len()];
    };
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5 * SPHERE_MARGIN;
    scene
        .lights
        .iter()
        .map(|l| LightFrame::new(l, centre, radius))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_optical_depth_is_that_of_the_smallest_transmittance() {
        let expected = -super::super::medium_truth::MIN_TRANSMITTANCE.ln();
        assert!((MAX_OPTICAL_DEPTH - expected).abs() < 1e-12);
    }

    /// A texel ray projects back onto its own map point, at its own parameter, for both
    /// projections.
    #[test]
    fn rays_project_back_to_their_map_points() {
        let centre = DVec3::new(0.3, -0.2, 0.5);
        let lights = [
            Light::Directional {
                direction: [0.2, -1.0, 0.3],
                irradiance: [1.0; 3],
            },
            Light::Point {
                position: [2.5, 4.0, 3.0],
                intensity: [1.0; 3],
            },
        ];
        for light in &lights {
            let frame = LightFrame::new(light, centre, 1.5).unwrap();
            for (u, v, t) in [(0.0, 0.0, 1.0), (0.7, -0.4, 2.0), (-1.0, 1.0, 2.9)] {
                let (o, d) = frame.ray(u, v);
                let (pu, pv, pt) = frame.project(o + d * (frame.t0 + t)).unwrap();
                assert!(
                    (pu - u).abs() < 1e-12 && (pv - v).abs() < 1e-12,
                    "{light:?}: ({u}, {v}) came back as ({pu}, {pv})"
                );
                assert!((pt - frame.t0 - t).abs() < 1e-12, "{light:?}: t {pt}");
            }
            // The map's corners' rays miss the sphere or graze it: every point of the sphere
            // projects inside the map.
            for dir in [
                DVec3::X,
                DVec3::Y,
                DVec3::Z,
                -DVec3::X,
                -DVec3::Y,
                -DVec3::Z,
            ] {
                let (u, v, _) = frame.project(centre + dir * 1.5).unwrap();
                assert!(u.abs() <= 1.0 + 1e-12 && v.abs() <= 1.0 + 1e-12, "{u} {v}");
            }
        }
        let inside = Light::Point {
            position: [0.3, -0.2, 1.0],
            intensity: [1.0; 3],
        };
        assert!(LightFrame::new(&inside, centre, 1.5).is_none());
    }

    #[test]
    fn slices_interpolate_linearly_from_zero() {
        let values = [1.0, 3.0, 3.0];
        assert_eq!(slice_depth(&values, 0.0), 0.0);
        assert!((slice_depth(&values, 0.5) - 0.5).abs() < 1e-15);
        assert!((slice_depth(&values, 1.25) - 1.5).abs() < 1e-15);
        assert_eq!(slice_depth(&values, 3.0), 3.0);
        // Slices over the texel's own stretch [1, 3].
        let texel = [1.0, 3.0, 1.0, 3.0, 3.0];
        assert_eq!(optical_depth_at(&texel, 0.5), 0.0);
        assert!((optical_depth_at(&texel, 2.0) - 2.0).abs() < 1e-15);
        assert_eq!(optical_depth_at(&texel, 9.0), 3.0);
        let empty = [f64::INFINITY, f64::INFINITY, 0.0, 0.0];
        assert_eq!(optical_depth_at(&empty, 1e300), 0.0);
    }
}

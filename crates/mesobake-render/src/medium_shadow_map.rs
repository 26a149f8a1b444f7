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
//! 2. **Build**, one texel ray at a time through the cells ([`MapMedium::optical_depths`]),
//!    order-independent and from nothing but the cells and the medium (rebuilt each frame,
//!    so animated meshes and media need nothing precomputed): the optical depth τ(t), exact
//!    and piecewise linear along the ray (each voxel piece adds σ·ℓ, σ = −ln(1 − α) per voxel
//!    length, [`OPAQUE_EXTINCTION`] where α = 1), in mip level 0.
//!    - **Deep map** (after Lokovic and Veach's deep shadow maps, with knots at fixed
//!      levels instead of a compressed curve): K transmittance levels T_k = 1 − (k + 1)/K,
//!      k < K − 1, and the last at [`MAX_OPTICAL_DEPTH`] (blocked); per texel the depth t_k
//!      where τ reaches each level (+∞ where it never does), the depth t_a where τ starts
//!      to grow (the first medium), and t_e, τ_e where the last medium ends and what τ
//!      totals there. τ(t) is the polyline through (t_a, 0), the reached (t_k, τ_k) and
//!      (t_e, τ_e), constant after it: exact at steps (an opaque surface puts every level
//!      at one depth) and wherever the medium between two knots is uniform, and it spends no
//!      knots on empty space. (Slices at fixed depths, as in Kim and Neumann's opacity
//!      shadow maps, smeared each opaque surface over a slice: samples just in front of it
//!      fell into its shadow; measured in docs/BENCHMARKS.md.)
//!    - **Depth map** (the paper's shadow map): the first t where τ reaches
//!      [`DEPTH_THRESHOLD`] (transmittance ½), or none.
//! 3. **Lookup** of a point x lit from a light: its map coordinates (u, v, t), with t moved
//!    towards the light by the same start as the shadow rays ([`SHADOW_START`] voxels), then
//!    bilinear over the four nearest texel centres (clamped at the edges): of each texel's
//!    transmittance exp(−τ(t)) (0 from [`MAX_OPTICAL_DEPTH`]; averaging transmittance, not
//!    optical depth, lets half a texel's worth of light past a strand's edge); or of the
//!    depth test t < depth (percentage-closer filtering).
//!
//! [`SHADOW_START`]: super::medium_truth::SHADOW_START

use crate::medium_settings::{ShadowMethod, TransparencySettings};
use crate::shot::Shot;
use glam::DVec3;
use mesobake_core::light::Light;
use rayon::prelude::*;
use std::ops::ControlFlow;

/// What shadow maps are built through: the medium's optical depth along rays (the cells of
/// `medium_cells::CellRenderer`, in mip level 0), the boxes that hold it, and the settings
/// that size the maps.
pub trait MapMedium: Sync {
    /// The settings the maps are built with (method, size, levels).
    fn settings(&self) -> TransparencySettings;

    /// Boxes (min, max) that together hold the medium (none when it is empty).
    fn bounds(&self) -> Vec<(DVec3, DVec3)>;

    /// Visits the optical depth along `origin + t·dir` (unit `dir`), t ∈ [`t_min`, `t_max`],
    /// in order: `f(t_a, t_b, τ)` per piece of constant medium; stops when `f` breaks.
    fn optical_depths(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
        f: impl FnMut(f64, f64, f64) -> ControlFlow<()>,
    ) -> ControlFlow<()>;
}

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
    /// Values per texel: t_a, t_e, τ_e and the K levels' depths (deep map) or one depth
    /// (depth map, +∞ where the light is never blocked), texel (i, j) at
    /// (j·size + i)·stride.
    pub values: Vec<f64>,
    method: ShadowMethod,
    stride: usize,
}

impl ShadowMap {
    /// Builds the map of `method` (not [`ShadowMethod::Rays`]) of the light seen through
    /// `frame`, with the settings' size and levels, through `cells`.
    pub fn build(cells: &impl MapMedium, frame: LightFrame, method: ShadowMethod) -> ShadowMap {
        let settings = cells.settings();
        let size = settings.shadow_map_size;
        let stride = match method {
            ShadowMethod::DeepMap => settings.shadow_levels as usize + 3,
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
                        ShadowMethod::DeepMap => deep_texel(cells, o, d, (t0, t1), texel),
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
            ShadowMethod::DeepMap => corners
                .iter()
                .map(|&(i, j, w)| w * transmittance(deep_optical_depth(texel(i, j), t)))
                .sum(),
            _ => corners
                .iter()
                .filter(|&&(i, j, _)| t < texel(i, j)[0])
                .map(|c| c.2)
                .sum(),
        }
    }
}

/// exp(−τ), 0 from [`MAX_OPTICAL_DEPTH`].
fn transmittance(tau: f64) -> f64 {
    if tau >= MAX_OPTICAL_DEPTH {
        0.0
    } else {
        (-tau).exp()
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

/// Optical depth of deep-map level `k` of `levels`: −ln(1 − (k + 1)/K), the last
/// [`MAX_OPTICAL_DEPTH`].
pub fn level_depth(k: usize, levels: usize) -> f64 {
    if k + 1 >= levels {
        MAX_OPTICAL_DEPTH
    } else {
        -(1.0 - (k + 1) as f64 / levels as f64).ln()
    }
}

/// A deep-map texel's optical depth at ray parameter `t`: the polyline through its knots.
fn deep_optical_depth(texel: &[f64], t: f64) -> f64 {
    let (ta, te, tau_e, depths) = (texel[0], texel[1], texel[2], &texel[3..]);
    let levels = depths.len();
    if t.is_nan() || t <= ta {
        return 0.0;
    }
    // Levels reached by t.
    let k = depths.partition_point(|&d| d <= t);
    if k == levels {
        return MAX_OPTICAL_DEPTH;
    }
    let (t0, tau0) = if k == 0 {
        (ta, 0.0)
    } else {
        (depths[k - 1], level_depth(k - 1, levels))
    };
    let (t1, tau1) = if depths[k].is_finite() {
        (depths[k], level_depth(k, levels))
    } else {
        (te, tau_e)
    };
    if t >= t1 || t1 <= t0 {
        tau1
    } else {
        tau0 + (tau1 - tau0) * (t - t0) / (t1 - t0)
    }
}

/// Fills a deep-map texel from the ray `o + t·d`, t ∈ `range`: t_a, t_e, τ_e and the
/// levels' depths.
fn deep_texel(cells: &impl MapMedium, o: DVec3, d: DVec3, range: (f64, f64), out: &mut [f64]) {
    let levels = out.len() - 3;
    out.fill(f64::INFINITY);
    let (mut first, mut end, mut tau, mut k) = (f64::INFINITY, f64::INFINITY, 0.0, 0);
    let _ = cells.optical_depths(o, d, range.0, range.1, |ta, tb, piece| {
        if piece <= 0.0 {
            return ControlFlow::Continue(());
        }
        first = first.min(ta);
        while k < levels && tau + piece >= level_depth(k, levels) {
            out[3 + k] = ta + (tb - ta) * ((level_depth(k, levels) - tau) / piece);
            k += 1;
        }
        tau += piece;
        end = tb;
        if k == levels {
            (end, tau) = (out[3 + levels - 1], MAX_OPTICAL_DEPTH);
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    out[0] = first;
    out[1] = end;
    out[2] = tau;
}

/// A depth-map texel: where the optical depth along `o + t·d`, t ∈ [`t0`, `t1`], reaches
/// [`DEPTH_THRESHOLD`], or +∞.
fn depth_texel(cells: &impl MapMedium, o: DVec3, d: DVec3, t0: f64, t1: f64) -> f64 {
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

/// Every light's map for `cells` under `shot` (`None` where a light has none: ambient,
/// a point light inside the bounding sphere, or shadows by [`ShadowMethod::Rays`]).
pub fn build_maps(cells: &impl MapMedium, shot: &Shot) -> Vec<Option<ShadowMap>> {
    let method = cells.settings().shadows;
    map_frames(cells, shot)
        .into_iter()
        .map(|frame| frame.map(|f| ShadowMap::build(cells, f, method)))
        .collect()
}

/// Every light's map frame over the cells' bounding sphere (`None` where it has no map:
/// ambient, a point light inside the sphere, or shadows by [`ShadowMethod::Rays`]).
pub fn map_frames(cells: &impl MapMedium, shot: &Shot) -> Vec<Option<LightFrame>> {
    let bounds = cells.bounds();
    let Some((lo, hi)) = bounds
        .into_iter()
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
        .filter(|_| cells.settings().shadows != ShadowMethod::Rays)
    else {
        return vec![None; shot.lights.len()];
    };
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5 * SPHERE_MARGIN;
    shot.lights
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

    /// A texel whose optical depth rises uniformly from 1 to 3 (τ 0 → 0.6), steps at 5 to
    /// the blocked level, with four levels (T ¾, ½, ¼, blocked).
    #[test]
    fn deep_texels_interpolate_between_their_knots() {
        let levels = 4;
        let tau = |k| level_depth(k, levels);
        assert!((tau(0) - (4.0f64 / 3.0).ln()).abs() < 1e-15);
        assert_eq!(tau(3), MAX_OPTICAL_DEPTH);
        // Rising 0.3 per unit from t = 1: level 0 (0.2877) at 1 + 0.2877/0.3.
        let t0 = 1.0 + tau(0) / 0.3;
        let texel = [1.0, 5.0, MAX_OPTICAL_DEPTH, t0, 5.0, 5.0, 5.0];
        assert_eq!(deep_optical_depth(&texel, 0.5), 0.0);
        assert!((deep_optical_depth(&texel, 1.5) - 0.15).abs() < 1e-12);
        let mid = (t0 + 5.0) / 2.0;
        let expected = (tau(0) + tau(1)) / 2.0;
        assert!((deep_optical_depth(&texel, mid) - expected).abs() < 1e-12);
        assert_eq!(deep_optical_depth(&texel, 5.0), MAX_OPTICAL_DEPTH);
        // Never blocked: after the last level reached, on to (t_e, τ_e), then constant.
        let fog = [
            1.0,
            3.0,
            0.5,
            t0,
            f64::INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        ];
        let at = (t0 + 3.0) / 2.0;
        assert!((deep_optical_depth(&fog, at) - (tau(0) + 0.5) / 2.0).abs() < 1e-12);
        assert_eq!(deep_optical_depth(&fog, 9.0), 0.5);
        let empty = [f64::INFINITY; 7];
        assert_eq!(deep_optical_depth(&empty, 1e300), 0.0);
    }
}

//! The radiance transfer volume (RTV): per mesostructure surface voxel, the radiance it sends
//! towards view direction v in response to incident light given in SH, in texture space (+z
//! out of the base surface). Per sample and RGB channel it is a 16×16 matrix A (rows: view SH,
//! columns: light SH), and shading is L_out(v) = y(v)ᵀ·A·ℓ, with ℓ the incident SH from the
//! macro-scale PRT ([`super::prt`]). The package stores it sampled on the GDM's direction grid
//! and SVD-compressed ([`super::compressed_rtv`]).
//!
//! **Samples.** The surface voxels are the *empty* voxels with a solid voxel among their 26
//! neighbours (x and y periodic). A GDM hit point lies where a ray leaves such a voxel for a
//! solid one, so a renderer interpolates the RTV over the sample voxels around its hit
//! (weights renormalized over the voxels that are samples).
//!
//! **Diffuse transfer.** At sample p (the voxel centre) with outward normal n (the material
//! volume's normal) and albedo ρ (of the material just inside the surface, 0.75 voxel along
//! −n), the Lambertian response to basis light yᵢ is
//!   Dᵢ(p) = ρ · Σ_ω w_ω · [escapes upward(p, ω)] · yᵢ(ω)              (direct)
//!          + ρ · Σ_ω w_ω · [hits at q(p, ω)] · Dᵢ(q)                   (bounces)
//! over the GDM's direction bins ω with n·ω > 0, w_ω = Ω_ω (n·ω) / Σ Ω (n·ω), where Ω_ω is
//! the bin's solid angle. Normalizing the cosine weights per point makes a white furnace
//! (ρ = 1, constant light, no escape through the bottom) converge to exactly the light's
//! radiance. Visibility is the GDM's answer at the sample voxel, read from its table
//! without interpolation: a ray that escapes through the top sees the incident light; one that
//! escapes through the bottom meets the opaque base surface and brings nothing; one that hits
//! brings the response of the sample voxel it was in just before the hit, q (the bounce). The
//! bounce sum is truncated after `bounces` bounces (the knob; 0 = direct light only). Being
//! view-independent, D fills row 0 of A: A₀ᵢ = Dᵢ / y₀.
//!
//! **Glossy transfer** (optional, [`Glossy`]). A normalized Phong lobe of exponent s about the
//! mirror direction r = 2(n·v)n − v, scaled by the specular colour k_s, filters the light
//! arriving at p: L_g(v) = k_s ∫ (s+1)/(2π)·max(ω·r, 0)^s · L_in(p, ω) dω (the lobe without
//! the cosine at the light, the usual prefiltered-reflection approximation). The incident light
//! is projected to SH over the upper-hemisphere bins, Tₖᵢ = Σ_ω Ω_ω yₖ(ω) L_in,ᵢ(p, ω), with
//! L_in,ᵢ the light for basis yᵢ as above (yᵢ(ω) when the ray escapes upward, Dᵢ(q) at a hit:
//! bounced light is the diffuse light of the point hit). By Funk–Hecke the lobe scales band l
//! by Λₗ ([`sh::phong_convolution`]), and r = R_n v with R_n the half turn about n, so
//! yₖ(r) = Σⱼ Mⱼₖ yⱼ(v) with M the SH rotation of R_n: A += k_s · M · diag(Λ) · T. The lobe is
//! band-limited to band 3, so sharp highlights are blurred: a modelling error of the 16
//! coefficients, not of the bake.

use super::sh::{self, COEFFS, Sh};
use crate::gdm::Gdm;
use crate::mesostructure::material::MaterialVolume;
use glam::{DMat3, DVec3};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::{Dims, Wrap, trilinear_corners};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::time::Instant;

/// One channel of a sample's transfer: row j is the view SH coefficient j, column i the light
/// SH coefficient i.
pub type ViewLightMatrix = [[f32; COEFFS]; COEFFS];

/// The RTV of one mesostructure.
#[derive(Clone, Debug)]
pub struct Rtv {
    dims: Dims,
    /// Sample index per voxel (x fastest), or [`NO_SAMPLE`].
    sample_of: Vec<u32>,
    /// The sample voxels.
    voxels: Vec<[u32; 3]>,
    /// Per sample, per RGB channel, the view × light matrix.
    matrices: Vec<[ViewLightMatrix; 3]>,
}

/// Marks a voxel that is not an RTV sample.
pub use mesobake_package::gi::NO_SAMPLE;

pub use mesobake_package::manifest::Glossy;

/// The knobs of an RTV bake.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RtvParams {
    /// Interreflection bounces (0 = direct light only; at most [`MAX_BOUNCES`]).
    pub bounces: u32,
    /// The specular lobe; `None` bakes Lambert only (a view-independent RTV).
    pub glossy: Option<Glossy>,
}

/// What an RTV bake measured.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct RtvStats {
    /// Surface samples.
    pub samples: usize,
    /// Ray links between samples (bounce paths), after merging rays that reach the same voxel.
    pub links: usize,
    /// Hit rays whose voxel before the hit was not a sample (their light is dropped).
    pub lost_rays: u64,
    /// Seconds finding samples and tracing their rays through the GDM.
    pub trace_seconds: f64,
    /// Seconds iterating the bounces.
    pub bounce_seconds: f64,
    /// Seconds projecting the incident light for the glossy lobe (0 without one).
    pub glossy_seconds: f64,
}

/// Where a ray from a sample ends.
#[derive(Clone, Copy, Debug, PartialEq)]
enum RayEnd {
    /// It escapes through the top: the incident light.
    Sky,
    /// It escapes through the bottom, onto the opaque base surface: nothing.
    Ground,
    /// It hits; the sample voxel before the hit.
    Sample(u32),
    /// It hits, but the voxel before the hit is not a sample: its light is dropped.
    Lost,
}

/// A traced sample: its direct transfer per channel, its bounce links, its lost rays.
type Traced = ([Sh; 3], Vec<(u32, f32)>, u64);

/// Which bounce targets a sample's rays reach, with their weights (ρ·w summed per target).
struct Links {
    start: Vec<usize>,
    targets: Vec<(u32, f32)>,
}

/// A direction bin of the GDM: its indices, vector, SH values and solid angle.
struct Bin {
    a: u32,
    b: u32,
    v: DVec3,
    y: Sh,
    omega: f64,
}

impl Rtv {
    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The sample voxels.
    pub fn voxels(&self) -> &[[u32; 3]] {
        &self.voxels
    }

    /// Per voxel (x fastest), its sample index or [`NO_SAMPLE`].
    pub fn sample_map(&self) -> &[u32] {
        &self.sample_of
    }

    /// The view × light matrices of sample `s`, per channel.
    pub fn matrices(&self, s: usize) -> &[ViewLightMatrix; 3] {
        &self.matrices[s]
    }

    /// The transfer vector of sample `s` towards view direction `view` (unit, texture space):
    /// per channel, the 16 weights of the light SH, y(view)ᵀ·A.
    pub fn transfer(&self, s: usize, view: DVec3) -> [Sh; 3] {
        let y = sh::eval(view);
        self.matrices[s].map(|a| {
            let mut out = [0.0; COEFFS];
            for (row, &yj) in a.iter().zip(&y) {
                if yj != 0.0 {
                    out.iter_mut()
                        .zip(row)
                        .for_each(|(o, &v)| *o += yj * f64::from(v));
                }
            }
            out
        })
    }

    /// The transfer vector towards `view` at texture point `t` (voxel units), interpolated as
    /// [`interpolate_samples`] does.
    pub fn interpolate(&self, t: DVec3, view: DVec3) -> Option<[Sh; 3]> {
        interpolate_samples(self.dims, &self.sample_of, t, |s| self.transfer(s, view))
    }

    /// The outgoing RGB radiance of sample `s` towards `view` under incident light `light`.
    pub fn shade(&self, s: usize, view: DVec3, light: &[Sh; 3]) -> [f64; 3] {
        let t = self.transfer(s, view);
        std::array::from_fn(|c| sh::dot(&t[c], &light[c]))
    }
}

/// A per-sample quantity at texture point `t` (voxel units): trilinear over the voxel centres
/// around it, renormalized over those that are samples (x and y periodic, z clamped); `None`
/// where no sample has weight.
pub fn interpolate_samples(
    dims: Dims,
    sample_of: &[u32],
    t: DVec3,
    value: impl Fn(usize) -> [Sh; 3],
) -> Option<[Sh; 3]> {
    let mut out = [[0.0; COEFFS]; 3];
    let mut total = 0.0;
    for ([i, j, k], w) in trilinear_corners(dims, t.to_array()) {
        let s = sample_of[dims.index(i, j, k)];
        if s == NO_SAMPLE || w == 0.0 {
            continue;
        }
        total += w;
        for (o, v) in out.iter_mut().zip(value(s as usize)) {
            o.iter_mut().zip(v).for_each(|(o, v)| *o += w * v);
        }
    }
    if total <= 0.0 {
        return None;
    }
    Some(out.map(|c| c.map(|v| v / total)))
}

/// Bakes the RTV of the mesostructure whose GDM (any escape convention) is `gdm` and whose
/// albedo and normals are `material`.
pub fn bake(
    gdm: &Gdm,
    material: &MaterialVolume,
    params: &RtvParams,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<(Rtv, RtvStats)> {
    let dims = gdm.dims();
    if material.dims() != dims {
        return Err(Error::InvalidParameter(format!(
            "the material volume is {} but the GDM is {dims}",
            material.dims()
        )));
    }
    if params.bounces > MAX_BOUNCES {
        return Err(Error::InvalidParameter(format!(
            "RTV bounces must be at most {MAX_BOUNCES}, got {}",
            params.bounces
        )));
    }
    if let Some(g) = params.glossy {
        let valid = g.specular.iter().all(|k| (0.0..=1.0).contains(k))
            && (0.0..=MAX_EXPONENT).contains(&g.exponent);
        if !valid {
            return Err(Error::InvalidParameter(format!(
                "the glossy lobe needs a specular colour in [0, 1] and an exponent in \
                 [0, {MAX_EXPONENT}], got {g:?}"
            )));
        }
    }
    let start = Instant::now();
    let (sample_of, voxels) = surface_samples(gdm, limits)?;
    limits.check(
        "RTV transfer",
        voxels.len() as u64,
        (3 * COEFFS * COEFFS * 4 + 3 * COEFFS * 8 * 3) as u64,
    )?;
    let dirs = gdm.dirs();
    let bins: Vec<Bin> = (0..dirs.n_theta)
        .flat_map(|a| (0..dirs.n_phi).map(move |b| (a, b)))
        .map(|(a, b)| {
            let v = DVec3::from(dirs.vector(a, b));
            let (t0, t1) = (
                PI * a as f64 / dirs.n_theta as f64,
                PI * (a + 1) as f64 / dirs.n_theta as f64,
            );
            let omega = 2.0 * PI / dirs.n_phi as f64 * (t0.cos() - t1.cos());
            Bin {
                a,
                b,
                v,
                y: sh::eval(v),
                omega,
            }
        })
        .collect();
    // Per sample: its normal and albedo.
    let surface: Vec<(DVec3, DVec3)> = voxels
        .par_iter()
        .map(|&[i, j, k]| {
            let centre = voxel_centre([i, j, k]);
            let n = material.normal_at(centre).unwrap_or(DVec3::Z);
            (n, material.albedo_at(centre - ALBEDO_DEPTH * n))
        })
        .collect();
    let trace = |[i, j, k]: [u32; 3], bin: &Bin| ray_end(gdm, &sample_of, [i, j, k], bin);
    let traced: Vec<Traced> = voxels
        .par_iter()
        .zip(&surface)
        .map(|(&voxel, &(n, rho))| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let norm: f64 = bins.iter().map(|b| b.omega * n.dot(b.v).max(0.0)).sum();
            let mut direct = [[0.0; COEFFS]; 3];
            let mut links: Vec<(u32, f32)> = Vec::new();
            let mut lost = 0;
            for bin in &bins {
                let cos = n.dot(bin.v);
                if cos <= 0.0 {
                    continue;
                }
                let w = bin.omega * cos / norm;
                match trace(voxel, bin) {
                    RayEnd::Sky => {
                        for (c, out) in direct.iter_mut().enumerate() {
                            let f = rho[c] * w;
                            out.iter_mut().zip(&bin.y).for_each(|(o, y)| *o += f * y);
                        }
                    }
                    RayEnd::Sample(s) => links.push((s, w as f32)),
                    RayEnd::Ground => {}
                    RayEnd::Lost => lost += 1,
                }
            }
            // Merge the rays that reach the same sample (ρ is applied in the bounce loop).
            links.sort_unstable_by_key(|l| l.0);
            links.dedup_by(|b, a| {
                if a.0 == b.0 {
                    a.1 += b.1;
                    true
                } else {
                    false
                }
            });
            Ok((direct, links, lost))
        })
        .collect::<Result<_>>()?;
    let mut stats = RtvStats {
        samples: voxels.len(),
        ..RtvStats::default()
    };
    let mut link_table = Links {
        start: Vec::with_capacity(voxels.len() + 1),
        targets: Vec::new(),
    };
    let mut diffuse: Vec<[Sh; 3]> = Vec::with_capacity(voxels.len());
    for (direct, links, lost) in traced {
        link_table.start.push(link_table.targets.len());
        link_table.targets.extend(links);
        diffuse.push(direct);
        stats.lost_rays += lost;
    }
    link_table.start.push(link_table.targets.len());
    stats.links = link_table.targets.len();
    stats.trace_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let mut previous = diffuse.clone();
    for _ in 0..params.bounces {
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        let next: Vec<[Sh; 3]> = (0..voxels.len())
            .into_par_iter()
            .map(|s| {
                let mut out = [[0.0; COEFFS]; 3];
                let links = &link_table.targets[link_table.start[s]..link_table.start[s + 1]];
                for &(t, w) in links {
                    let from = &previous[t as usize];
                    for c in 0..3 {
                        let f = surface[s].1[c] * f64::from(w);
                        out[c]
                            .iter_mut()
                            .zip(&from[c])
                            .for_each(|(o, v)| *o += f * v);
                    }
                }
                out
            })
            .collect();
        diffuse.par_iter_mut().zip(&next).for_each(|(t, n)| {
            for c in 0..3 {
                t[c].iter_mut().zip(&n[c]).for_each(|(t, n)| *t += n);
            }
        });
        previous = next;
    }
    stats.bounce_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let y0 = sh::eval(DVec3::Z)[0];
    let matrices = voxels
        .par_iter()
        .enumerate()
        .map(|(s, &voxel)| {
            let mut a = [[[0.0f64; COEFFS]; COEFFS]; 3];
            for c in 0..3 {
                a[c][0] = diffuse[s][c].map(|d| d / y0);
            }
            if let Some(glossy) = params.glossy {
                let n = surface[s].0;
                let incident = incident_light(&bins, n, &diffuse, |bin| trace(voxel, bin));
                let half_turn = DMat3::from_cols(
                    2.0 * n.x * n - DVec3::X,
                    2.0 * n.y * n - DVec3::Y,
                    2.0 * n.z * n - DVec3::Z,
                );
                let m = sh::rotation_matrix(half_turn);
                let lambda = sh::phong_convolution(glossy.exponent);
                for c in 0..3 {
                    for (j, row) in a[c].iter_mut().enumerate() {
                        for (k, t_row) in incident[c].iter().enumerate() {
                            let f = glossy.specular[c] * m[j][k] * lambda[sh::band(k)];
                            if f != 0.0 {
                                row.iter_mut().zip(t_row).for_each(|(a, t)| *a += f * t);
                            }
                        }
                    }
                }
            }
            a.map(|c| c.map(|row| row.map(|v| v as f32)))
        })
        .collect();
    if params.glossy.is_some() {
        stats.glossy_seconds = start.elapsed().as_secs_f64();
    }
    Ok((
        Rtv {
            dims,
            sample_of,
            voxels,
            matrices,
        },
        stats,
    ))
}

/// The SH of the light arriving at a sample with normal `n` over its upper hemisphere, per
/// channel and basis light i: Tₖᵢ = Σ_ω Ω_ω yₖ(ω) L_in,ᵢ(ω), indexed `[channel][k][i]`.
fn incident_light(
    bins: &[Bin],
    n: DVec3,
    diffuse: &[[Sh; 3]],
    end: impl Fn(&Bin) -> RayEnd,
) -> [[Sh; COEFFS]; 3] {
    let mut t = [[[0.0; COEFFS]; COEFFS]; 3];
    for bin in bins.iter().filter(|b| n.dot(b.v) > 0.0) {
        let light = match end(bin) {
            RayEnd::Sky => [&bin.y; 3],
            RayEnd::Sample(q) => {
                let d = &diffuse[q as usize];
                [&d[0], &d[1], &d[2]]
            }
            RayEnd::Ground | RayEnd::Lost => continue,
        };
        for (t, light) in t.iter_mut().zip(light) {
            for (row, &y) in t.iter_mut().zip(&bin.y) {
                let f = bin.omega * y;
                row.iter_mut().zip(light).for_each(|(t, l)| *t += f * l);
            }
        }
    }
    t
}

/// Where the ray from sample voxel `voxel` along `bin` ends, by the GDM's table.
fn ray_end(gdm: &Gdm, sample_of: &[u32], voxel: [u32; 3], bin: &Bin) -> RayEnd {
    let [i, j, k] = voxel;
    if gdm.is_escape(i, j, k, bin.a, bin.b) {
        return if bin.v.z > 0.0 {
            RayEnd::Sky
        } else {
            RayEnd::Ground
        };
    }
    let dims = gdm.dims();
    let (wx, wy) = (Wrap::new(dims.x), Wrap::new(dims.y));
    let d = f64::from(gdm.get(i, j, k, bin.a, bin.b));
    // The voxel just before the hit; step back if rounding lands elsewhere.
    [1e-3, 0.25, 0.5]
        .iter()
        .find_map(|&back| {
            let q = voxel_centre(voxel) + bin.v * (d - back).max(0.0);
            if !(0.0..dims.z as f64).contains(&q.z) {
                return None;
            }
            let (qi, qj) = (wx.apply(q.x.floor() as i64), wy.apply(q.y.floor() as i64));
            let s = sample_of[dims.index(qi as u32, qj as u32, q.z as u32)];
            (s != NO_SAMPLE).then_some(RayEnd::Sample(s))
        })
        .unwrap_or(RayEnd::Lost)
}

/// The centre of voxel (i, j, k), in voxel units.
fn voxel_centre([i, j, k]: [u32; 3]) -> DVec3 {
    DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5)
}

/// Largest Phong exponent accepted (the band-3 lobe is nearly a delta long before).
pub const MAX_EXPONENT: f64 = 1e4;

/// How far inside the surface, in voxels along −n, a sample's albedo is read.
const ALBEDO_DEPTH: f64 = 0.75;

/// Most interreflection bounces accepted.
pub const MAX_BOUNCES: u32 = 64;

/// The sample voxels of the mesostructure: empty voxels (GDM value non-zero) with a solid
/// 26-neighbour (x and y periodic); and the voxel → sample map.
fn surface_samples(gdm: &Gdm, limits: &Limits) -> Result<(Vec<u32>, Vec<[u32; 3]>)> {
    let dims = gdm.dims();
    limits.check("RTV sample map", dims.voxel_count(), 4 + 1)?;
    let solid: Vec<bool> = (0..dims.voxel_count() as usize)
        .map(|v| gdm.data()[v] == 0.0)
        .collect();
    let (wx, wy) = (Wrap::new(dims.x), Wrap::new(dims.y));
    let mut sample_of = vec![NO_SAMPLE; solid.len()];
    let mut voxels = Vec::new();
    for k in 0..dims.z {
        for j in 0..dims.y {
            for i in 0..dims.x {
                if solid[dims.index(i, j, k)] {
                    continue;
                }
                let touches = (-1i64..=1).any(|dz| {
                    let kk = k as i64 + dz;
                    (0..dims.z as i64).contains(&kk)
                        && (-1i64..=1).any(|dy| {
                            (-1i64..=1).any(|dx| {
                                let ii = wx.apply(i as i64 + dx) as u32;
                                let jj = wy.apply(j as i64 + dy) as u32;
                                solid[dims.index(ii, jj, kk as u32)]
                            })
                        })
                });
                if touches {
                    sample_of[dims.index(i, j, k)] = voxels.len() as u32;
                    voxels.push([i, j, k]);
                }
            }
        }
    }
    Ok((sample_of, voxels))
}

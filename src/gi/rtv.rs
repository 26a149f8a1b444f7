//! The radiance transfer volume (RTV): per mesostructure surface voxel, the 16 SH
//! coefficients (per RGB channel) of the radiance it sends out in response to incident light
//! given in SH, in texture space (+z out of the base surface). Shading is
//! L_out = Σᵢ RTVᵢ · ℓᵢ, with ℓ the incident SH from the macro-scale PRT ([`super::prt`]).
//!
//! **Samples.** The surface voxels are the *empty* voxels with a solid voxel among their 26
//! neighbours (x and y periodic). A GDM hit point lies where a ray leaves such a voxel for a
//! solid one, so a renderer interpolates the RTV over the sample voxels around its hit
//! (weights renormalized over the voxels that are samples).
//!
//! **Transfer.** At sample p (the voxel centre) with outward normal n (the material volume's
//! normal) and albedo ρ (of the material just inside the surface, 0.75 voxel along −n), the
//! Lambertian response to basis light yᵢ is
//!   Dᵢ(p) = ρ · Σ_ω w_ω · [escapes upward(p, ω)] · yᵢ(ω)              (direct)
//!          + ρ · Σ_ω w_ω · [hits at q(p, ω)] · Dᵢ(q)                   (bounces)
//! over the GDM's direction bins ω with n·ω > 0, w_ω = Ω_ω (n·ω) / Σ Ω (n·ω), where Ω_ω is
//! the bin's solid angle. Normalizing the cosine weights per point makes a white furnace
//! (ρ = 1, constant light, no escape through the bottom) converge to exactly the light's
//! radiance. Visibility is the GDM's answer at the sample voxel, read from its table
//! without interpolation: a ray that escapes through the top sees the incident light; one that
//! escapes through the bottom meets the opaque base surface and brings nothing; one that hits
//! brings the response of the sample voxel it was in just before the hit, q (the bounce). The
//! bounce sum is truncated after `bounces` bounces (the knob; 0 = direct light only).

use super::sh::{self, COEFFS};
use crate::error::{Error, Result};
use crate::gdm::{BakeObserver, Gdm};
use crate::grid::{Dims, Wrap, trilinear_corners};
use crate::limits::Limits;
use crate::render::material::MaterialVolume;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// The RTV of one mesostructure: Lambertian response per surface voxel.
#[derive(Clone, Debug)]
pub struct Rtv {
    dims: Dims,
    /// Sample index per voxel (x fastest), or [`NO_SAMPLE`].
    sample_of: Vec<u32>,
    /// The sample voxels.
    voxels: Vec<[u32; 3]>,
    /// Per sample, per RGB channel, the 16 SH coefficients.
    transfer: Vec<[[f32; COEFFS]; 3]>,
}

/// Marks a voxel that is not an RTV sample.
pub const NO_SAMPLE: u32 = u32::MAX;

/// What an RTV bake measured.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
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
}

/// A traced sample: its direct transfer per channel, its bounce links, its lost rays.
type Traced = ([[f64; COEFFS]; 3], Vec<(u32, f32)>, u64);

/// Which bounce targets a sample's rays reach, with their weights (ρ·w summed per target).
struct Links {
    start: Vec<usize>,
    targets: Vec<(u32, f32)>,
}

impl Rtv {
    /// The sample voxels.
    pub fn voxels(&self) -> &[[u32; 3]] {
        &self.voxels
    }

    /// The transfer of sample `s`: per channel, 16 coefficients.
    pub fn transfer(&self, s: usize) -> &[[f32; COEFFS]; 3] {
        &self.transfer[s]
    }

    /// The sample of voxel (i, j, k), if it is one.
    pub fn sample_at(&self, i: u32, j: u32, k: u32) -> Option<usize> {
        let s = self.sample_of[self.dims.index(i, j, k)];
        (s != NO_SAMPLE).then_some(s as usize)
    }

    /// The transfer at texture point `t` (voxel units): trilinear over the voxel centres
    /// around it, renormalized over those that are samples (x and y periodic, z clamped);
    /// `None` where no sample has weight.
    pub fn interpolate(&self, t: DVec3) -> Option<[[f64; COEFFS]; 3]> {
        let mut out = [[0.0; COEFFS]; 3];
        let mut total = 0.0;
        for ([i, j, k], w) in trilinear_corners(self.dims, t.to_array()) {
            let Some(s) = self.sample_at(i, j, k) else {
                continue;
            };
            total += w;
            for (o, t) in out.iter_mut().zip(&self.transfer[s]) {
                o.iter_mut()
                    .zip(t)
                    .for_each(|(o, &t)| *o += w * f64::from(t));
            }
        }
        if total <= 0.0 {
            return None;
        }
        Some(out.map(|c| c.map(|v| v / total)))
    }

    /// The outgoing RGB radiance of sample `s` under incident light `light` (SH per channel).
    pub fn shade(&self, s: usize, light: &[[f64; COEFFS]; 3]) -> [f64; 3] {
        std::array::from_fn(|c| {
            let t: [f64; COEFFS] = self.transfer[s][c].map(f64::from);
            sh::dot(&t, &light[c])
        })
    }
}

/// Bakes the RTV of the mesostructure whose GDM (any escape convention) is `gdm` and whose
/// albedo and normals are `material`, with `bounces` interreflection bounces.
pub fn bake(
    gdm: &Gdm,
    material: &MaterialVolume,
    bounces: u32,
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
    if bounces > MAX_BOUNCES {
        return Err(Error::InvalidParameter(format!(
            "RTV bounces must be at most {MAX_BOUNCES}, got {bounces}"
        )));
    }
    let start = Instant::now();
    let (sample_of, voxels) = surface_samples(gdm, limits)?;
    limits.check(
        "RTV transfer",
        voxels.len() as u64,
        3 * COEFFS as u64 * 4 * 3,
    )?;
    let dirs = gdm.dirs();
    // Per direction bin: its vector, its SH values and its solid angle.
    let bins: Vec<(DVec3, [f64; COEFFS], f64, u32, u32)> = (0..dirs.n_theta)
        .flat_map(|a| (0..dirs.n_phi).map(move |b| (a, b)))
        .map(|(a, b)| {
            let v = DVec3::from(dirs.vector(a, b));
            let (t0, t1) = (
                PI * a as f64 / dirs.n_theta as f64,
                PI * (a + 1) as f64 / dirs.n_theta as f64,
            );
            let omega = 2.0 * PI / dirs.n_phi as f64 * (t0.cos() - t1.cos());
            (v, sh::eval(v), omega, a, b)
        })
        .collect();
    // Per sample: its normal and albedo.
    let surface: Vec<(DVec3, DVec3)> = voxels
        .par_iter()
        .map(|&[i, j, k]| {
            let centre = DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
            let n = material.normal_at(centre).unwrap_or(DVec3::Z);
            (n, material.albedo_at(centre - ALBEDO_DEPTH * n))
        })
        .collect();
    let (wx, wy) = (Wrap::new(dims.x), Wrap::new(dims.y));
    let traced: Vec<Traced> = voxels
        .par_iter()
        .zip(&surface)
        .map(|(&[i, j, k], &(n, rho))| {
            if observer.cancelled() {
                return Err(Error::Cancelled);
            }
            let centre = DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
            let norm: f64 = bins
                .iter()
                .map(|(v, _, omega, _, _)| omega * n.dot(*v).max(0.0))
                .sum();
            let mut direct = [[0.0; COEFFS]; 3];
            let mut links: Vec<(u32, f32)> = Vec::new();
            let mut lost = 0;
            for (v, y, omega, a, b) in &bins {
                let cos = n.dot(*v);
                if cos <= 0.0 {
                    continue;
                }
                let w = omega * cos / norm;
                if gdm.is_escape(i, j, k, *a, *b) {
                    if v.z > 0.0 {
                        for (c, out) in direct.iter_mut().enumerate() {
                            let f = rho[c] * w;
                            out.iter_mut().zip(y).for_each(|(o, y)| *o += f * y);
                        }
                    }
                    continue;
                }
                let d = f64::from(gdm.get(i, j, k, *a, *b));
                // The voxel just before the hit; step back if rounding lands elsewhere.
                let target = [1e-3, 0.25, 0.5].iter().find_map(|&back| {
                    let q = centre + *v * (d - back).max(0.0);
                    if !(0.0..dims.z as f64).contains(&q.z) {
                        return None;
                    }
                    let (qi, qj) = (wx.apply(q.x.floor() as i64), wy.apply(q.y.floor() as i64));
                    let s = sample_of[dims.index(qi as u32, qj as u32, q.z as u32)];
                    (s != NO_SAMPLE).then_some(s)
                });
                match target {
                    Some(s) => links.push((s, w as f32)),
                    None => lost += 1,
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
    let mut total: Vec<[[f64; COEFFS]; 3]> = Vec::with_capacity(voxels.len());
    for (direct, links, lost) in traced {
        link_table.start.push(link_table.targets.len());
        link_table.targets.extend(links);
        total.push(direct);
        stats.lost_rays += lost;
    }
    link_table.start.push(link_table.targets.len());
    stats.links = link_table.targets.len();
    stats.trace_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let mut previous = total.clone();
    for _ in 0..bounces {
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        let next: Vec<[[f64; COEFFS]; 3]> = (0..voxels.len())
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
        total.par_iter_mut().zip(&next).for_each(|(t, n)| {
            for c in 0..3 {
                t[c].iter_mut().zip(&n[c]).for_each(|(t, n)| *t += n);
            }
        });
        previous = next;
    }
    stats.bounce_seconds = start.elapsed().as_secs_f64();
    let transfer = total
        .into_iter()
        .map(|t| t.map(|c| c.map(|v| v as f32)))
        .collect();
    Ok((
        Rtv {
            dims,
            sample_of,
            voxels,
            transfer,
        },
        stats,
    ))
}

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

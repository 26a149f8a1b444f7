//! `mesobake report gi`: what the global-illumination knobs cost in time and buy in accuracy
//! on a scene that calls for environment lighting.
//! - **RTV**: over direction grids × bounce counts, the bake time (GDM bake, ray tracing
//!   through the GDM, bounces) and the error of the shaded surface radiance against the
//!   finest setting. Each sample is lit by the scene's environment as a flat, up-facing
//!   surface would receive it (the environment rotated so that world +y is texture +z); the
//!   error is the RMS difference over samples and channels, relative to the reference's RMS.
//! - **RTV compression**: over SVD ranks, on the scene's own grids and knobs, the stored
//!   bytes, the seconds, the transfer's relative RMSE at the view-bin centres (as the manifest
//!   reports it) and the relative RMS error of the radiance the compressed RTV sends under the
//!   same flat-surface light towards every view bin above the surface.
//! - **PRT**: over visibility sample counts, the time for all base vertices and the relative
//!   Frobenius error of the transfer matrices against the largest count.
//! - **Images**: the path tracer at each paths-per-pixel count and the GDM renderer with the
//!   scene's own GI settings, each against the path tracer at the largest count (PSNR of the
//!   sRGB images, as in `report render`), on the scene's camera reduced by `image_scale`.

use crate::LoadedScene;
use crate::gi::{self, rtv_params};
use crate::report::accuracy::table;
use glam::{DMat3, DVec3};
use mesobake_bake::gdm;
use mesobake_bake::gi::compressed_rtv::CompressedRtv;
use mesobake_bake::gi::environment::RgbSh;
use mesobake_bake::gi::prt::{self, Visibility};
use mesobake_bake::gi::rtv::{self, Rtv, RtvParams};
use mesobake_bake::gi::sh;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_package::grid::DirectionGrid;
use mesobake_render::gdm_lookup::RawLookup;
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::image::{Image, compare};
use mesobake_render::render_image;
use serde::Serialize;
use std::time::Instant;

/// The settings the report covers.
#[derive(Clone, Debug, PartialEq)]
pub struct GiSweep {
    /// Direction grids of the GDM (and so of the RTV's integration); the last is the
    /// reference.
    pub dirs: Vec<DirectionGrid>,
    /// Bounce counts; the largest, on the last grid, is the reference.
    pub bounces: Vec<u32>,
    /// PRT visibility sample counts; the largest is the reference.
    pub prt_samples: Vec<usize>,
    /// Path tracer paths per pixel; the largest is the reference image.
    pub path_samples: Vec<u32>,
    /// RTV SVD ranks (1–16).
    pub rtv_ranks: Vec<usize>,
    /// The camera's width and height are divided by this.
    pub image_scale: u32,
}

/// One image against the path-traced reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageRow {
    /// `path traced` or `GDM + RTV`.
    pub renderer: String,
    /// Paths per pixel (path tracer) or bounces (GDM + RTV).
    pub samples: u32,
    /// Seconds to render (the GDM + RTV row includes its GDM, PRT and RTV bakes).
    pub seconds: f64,
    /// PSNR in dB against the reference.
    pub psnr_db: f64,
    /// Mean ꟻLIP error against the reference.
    pub flip_mean: f64,
    /// Fraction of pixels whose hit/miss differs from the reference.
    pub mask_disagreement: f64,
}

impl ImageRow {
    /// `image` by `renderer` (with its `samples`, in `seconds`) against `reference`.
    fn new(
        (renderer, samples, seconds): (&str, u32, f64),
        image: &Image,
        reference: &Image,
    ) -> Result<ImageRow> {
        let c = compare(image, reference)?;
        Ok(ImageRow {
            renderer: renderer.into(),
            samples,
            seconds,
            psnr_db: c.psnr_db,
            flip_mean: c.flip_mean,
            mask_disagreement: c.mask_disagreement,
        })
    }
}

/// One RTV setting.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RtvRow {
    /// Direction grid, `Nθ×Nφ`.
    pub dirs: String,
    /// Bounces.
    pub bounces: u32,
    /// Seconds baking the exact GDM at this grid.
    pub gdm_seconds: f64,
    /// Seconds tracing the samples' rays through the GDM.
    pub trace_seconds: f64,
    /// Seconds iterating the bounces.
    pub bounce_seconds: f64,
    /// Relative RMS error of the shaded radiance against the reference.
    pub relative_error: f64,
    /// Surface samples.
    pub samples: usize,
    /// Bytes of the uncompressed transfer (per sample and channel a 16×16 f32 matrix).
    pub bytes: usize,
}

/// One RTV compression rank.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CompressionRow {
    /// Components stored per matrix.
    pub rank: usize,
    /// Bytes of the RTV sections (index, weights, eigenfunctions).
    pub bytes: usize,
    /// Seconds of the SVD and rounding.
    pub seconds: f64,
    /// The transfer's relative RMSE at the view-bin centres.
    pub transfer_relative_rmse: f64,
    /// Relative RMS error of the shaded radiance over samples, upper view bins and channels.
    pub radiance_relative_error: f64,
}

/// One PRT setting.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PrtRow {
    /// Visibility directions per vertex (0 for the unshadowed rotation).
    pub samples: usize,
    /// Seconds for all vertices.
    pub seconds: f64,
    /// Relative Frobenius error against the reference.
    pub relative_error: f64,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GiAccuracy {
    /// RTV rows.
    pub rtv: Vec<RtvRow>,
    /// RTV compression rows.
    pub compression: Vec<CompressionRow>,
    /// PRT rows.
    pub prt: Vec<PrtRow>,
    /// Image rows.
    pub images: Vec<ImageRow>,
    /// Image size, width × height.
    pub image_size: [u32; 2],
    /// Base-mesh vertices.
    pub vertices: usize,
}

/// Runs the sweep on `loaded` (which must have an environment).
pub fn gi_accuracy(
    loaded: &LoadedScene,
    sweep: &GiSweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<GiAccuracy> {
    let environment = loaded.environment.as_ref().ok_or_else(|| {
        Error::Scene("the report needs a scene that calls for environment_lighting".into())
    })?;
    let (Some(&reference_dirs), Some(&max_bounces), Some(&max_samples)) = (
        sweep.dirs.last(),
        sweep.bounces.iter().max(),
        sweep.prt_samples.iter().max(),
    ) else {
        return Err(Error::InvalidParameter(
            "the GI report needs direction grids, bounce counts and PRT sample counts".into(),
        ));
    };
    // World +y becomes texture +z: a flat, up-facing surface.
    let up = DMat3::from_cols(DVec3::X, DVec3::NEG_Z, DVec3::Y);
    let light: RgbSh = environment
        .project()
        .map(|c| sh::apply(&sh::rotation_matrix(up.transpose()), &c));
    let caster = loaded.mesostructure.caster();
    let mut baked = Vec::new();
    for &dirs in &sweep.dirs {
        let start = Instant::now();
        let g = gdm::exact::bake(caster, dirs, limits, observer)?;
        let gdm_seconds = start.elapsed().as_secs_f64();
        for &bounces in &sweep.bounces {
            let params = RtvParams {
                bounces,
                ..rtv_params(&loaded.scene)
            };
            let (rtv, stats) = rtv::bake(&g, &loaded.material, &params, limits, observer)?;
            let row = RtvRow {
                dirs: format!("{}x{}", dirs.n_theta, dirs.n_phi),
                bounces,
                gdm_seconds,
                trace_seconds: stats.trace_seconds,
                bounce_seconds: stats.bounce_seconds,
                relative_error: 0.0,
                samples: stats.samples,
                bytes: stats.samples * 3 * sh::COEFFS * sh::COEFFS * 4,
            };
            baked.push((
                row,
                shaded(&rtv, &light),
                dirs == reference_dirs && bounces == max_bounces,
            ));
        }
    }
    let reference = baked
        .iter()
        .find(|b| b.2)
        .map(|b| b.1.clone())
        .expect("the sweep includes its reference");
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let reference_rms = rms(&reference).max(f64::MIN_POSITIVE);
    let rtv_rows = baked
        .into_iter()
        .map(|(mut row, values, _)| {
            let diff: Vec<f64> = values.iter().zip(&reference).map(|(a, b)| a - b).collect();
            row.relative_error = rms(&diff) / reference_rms;
            row
        })
        .collect();

    let compression = compression_rows(loaded, &sweep.rtv_ranks, &light, limits, observer)?;
    let mut prt_rows = Vec::new();
    let mut matrices = Vec::new();
    let mut counts: Vec<usize> = sweep.prt_samples.clone();
    counts.sort_unstable();
    for &samples in &counts {
        let start = Instant::now();
        let t = prt::transfer(&loaded.base, Visibility::Shadowed { samples })?;
        prt_rows.push(PrtRow {
            samples,
            seconds: start.elapsed().as_secs_f64(),
            relative_error: 0.0,
        });
        matrices.push(t.matrices);
    }
    let start = Instant::now();
    prt::transfer(&loaded.base, Visibility::Unshadowed)?;
    let unshadowed_seconds = start.elapsed().as_secs_f64();
    let reference = &matrices[counts
        .iter()
        .position(|&c| c == max_samples)
        .expect("present")];
    let frobenius = |m: &[[[f64; 16]; 16]]| -> f64 {
        m.iter()
            .flatten()
            .flatten()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
    };
    let reference_norm = frobenius(reference).max(f64::MIN_POSITIVE);
    for (row, m) in prt_rows.iter_mut().zip(&matrices) {
        let diff: Vec<[[f64; 16]; 16]> = m
            .iter()
            .zip(reference)
            .map(|(a, b)| std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] - b[i][j])))
            .collect();
        row.relative_error = frobenius(&diff) / reference_norm;
    }
    prt_rows.insert(
        0,
        PrtRow {
            samples: 0,
            seconds: unshadowed_seconds,
            relative_error: f64::NAN,
        },
    );
    let (images, image_size) = image_rows(loaded, sweep, limits, observer)?;
    Ok(GiAccuracy {
        rtv: rtv_rows,
        compression,
        prt: prt_rows,
        images,
        image_size,
        vertices: loaded.base.positions.len(),
    })
}

/// The compression part of the report: the scene's RTV compressed at each rank.
fn compression_rows(
    loaded: &LoadedScene,
    ranks: &[usize],
    light: &RgbSh,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<Vec<CompressionRow>> {
    let dirs = loaded.scene.dirs()?;
    let g = gdm::exact::bake(loaded.mesostructure.caster(), dirs, limits, observer)?;
    let (rtv, _) = rtv::bake(
        &g,
        &loaded.material,
        &rtv_params(&loaded.scene),
        limits,
        observer,
    )?;
    let views: Vec<DVec3> = (0..dirs.count())
        .map(|v| DVec3::from(dirs.vector_of(v)))
        .filter(|v| v.z > 0.0)
        .collect();
    let radiance = |transfer: &dyn Fn(usize, DVec3) -> [sh::Sh; 3]| -> Vec<f64> {
        (0..rtv.voxels().len())
            .flat_map(|s| views.iter().map(move |&v| (s, v)))
            .flat_map(|(s, v)| {
                let t = transfer(s, v);
                (0..3).map(move |c| sh::dot(&t[c], &light[c]))
            })
            .collect()
    };
    let exact = radiance(&|s, v| rtv.transfer(s, v));
    let norm = exact
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    ranks
        .iter()
        .map(|&rank| {
            let (c, report, seconds) = CompressedRtv::compress(&rtv, dirs, rank, limits)?;
            let approx = radiance(&|s, v| c.transfer(s, v));
            let error: f64 = exact
                .iter()
                .zip(&approx)
                .map(|(a, b)| (a - b).powi(2))
                .sum();
            Ok(CompressionRow {
                rank: report.rank,
                bytes: 4 * c.sample_map().len() + 2 * (c.weights().len() + c.eigen().len()),
                seconds,
                transfer_relative_rmse: report.relative_rmse,
                radiance_relative_error: (error / norm).sqrt(),
            })
        })
        .collect()
}

/// The image part of the report.
fn image_rows(
    loaded: &LoadedScene,
    sweep: &GiSweep,
    limits: &Limits,
    observer: &dyn BakeObserver,
) -> Result<(Vec<ImageRow>, [u32; 2])> {
    let mut scene = loaded.scene.clone();
    let scale = sweep.image_scale.max(1);
    scene.camera.width = (scene.camera.width / scale).max(1);
    scene.camera.height = (scene.camera.height / scale).max(1);
    let mut counts = sweep.path_samples.clone();
    counts.sort_unstable();
    let mut traced = Vec::new();
    for &n in &counts {
        let start = Instant::now();
        let shot = scene.shot();
        let tracer = loaded.path_tracer(&shot, n)?;
        let image = render_image(&shot.camera, |o, d| tracer.radiance(&shot, o, d));
        traced.push((n, start.elapsed().as_secs_f64(), image));
    }
    let Some((_, _, reference)) = traced.last() else {
        return Err(Error::InvalidParameter(
            "the GI report needs at least one path-tracer sample count".into(),
        ));
    };
    let start = Instant::now();
    let g = gdm::exact::bake(
        loaded.mesostructure.caster(),
        scene.dirs()?,
        limits,
        observer,
    )?;
    let (gi, _) = gi::bake_shading(loaded, &g, limits, observer)?;
    let lookup = RawLookup::new(&g);
    let renderer = GdmRenderer::new(
        &loaded.shell,
        &lookup,
        &loaded.material,
        scene.gdm_refinements,
    )
    .with_quality(scene.quality)
    .with_gi(&gi);
    let shot = scene.shot();
    let gdm_image = render_image(&shot.camera, |o, d| renderer.radiance(&shot, o, d));
    let gdm_seconds = start.elapsed().as_secs_f64();
    let mut rows = Vec::new();
    for (n, seconds, image) in &traced {
        rows.push(ImageRow::new(
            ("path traced", *n, *seconds),
            image,
            reference,
        )?);
    }
    rows.push(ImageRow::new(
        ("GDM + RTV", scene.gi.bounces, gdm_seconds),
        &gdm_image,
        reference,
    )?);
    Ok((rows, [scene.camera.width, scene.camera.height]))
}

/// The shaded radiance of every sample and channel under `light`, seen from straight above.
fn shaded(rtv: &Rtv, light: &RgbSh) -> Vec<f64> {
    (0..rtv.voxels().len())
        .flat_map(|s| rtv.shade(s, DVec3::Z, light))
        .collect()
}

/// The report as Markdown tables.
pub fn markdown(report: &GiAccuracy) -> String {
    let rtv = table(
        &[
            "directions",
            "bounces",
            "GDM bake s",
            "RTV trace s",
            "bounces s",
            "relative RMS error",
            "samples",
            "RTV bytes (uncompressed)",
        ],
        report.rtv.iter().map(|r| {
            vec![
                r.dirs.clone(),
                r.bounces.to_string(),
                format!("{:.2}", r.gdm_seconds),
                format!("{:.2}", r.trace_seconds),
                format!("{:.3}", r.bounce_seconds),
                format!("{:.4}", r.relative_error),
                r.samples.to_string(),
                r.bytes.to_string(),
            ]
        }),
    );
    let compression = table(
        &[
            "rank",
            "bytes",
            "seconds",
            "transfer relative RMSE",
            "radiance relative error",
        ],
        report.compression.iter().map(|r| {
            vec![
                r.rank.to_string(),
                r.bytes.to_string(),
                format!("{:.3}", r.seconds),
                format!("{:.5}", r.transfer_relative_rmse),
                format!("{:.5}", r.radiance_relative_error),
            ]
        }),
    );
    let prt = table(
        &[
            "PRT samples per vertex",
            "seconds",
            "relative Frobenius error",
        ],
        report.prt.iter().map(|r| {
            vec![
                if r.samples == 0 {
                    "unshadowed (rotation)".into()
                } else {
                    r.samples.to_string()
                },
                format!("{:.3}", r.seconds),
                if r.relative_error.is_nan() {
                    "—".into()
                } else {
                    format!("{:.4}", r.relative_error)
                },
            ]
        }),
    );
    let images = table(
        &[
            "renderer",
            "paths per pixel / bounces",
            "seconds",
            "PSNR dB",
            "FLIP",
            "mask disagreement",
        ],
        report.images.iter().map(|r| {
            vec![
                r.renderer.clone(),
                r.samples.to_string(),
                format!("{:.2}", r.seconds),
                format!("{:.1}", r.psnr_db),
                format!("{:.4}", r.flip_mean),
                format!("{:.4}", r.mask_disagreement),
            ]
        }),
    );
    format!(
        "### RTV\n\n{rtv}\n### RTV compression (the scene's grids and knobs)\n\n\
         {compression}\n### Macro-scale PRT ({} vertices)\n\n{prt}\n### Images against the \
         path tracer at its largest count ({}×{})\n\n{images}",
        report.vertices, report.image_size[0], report.image_size[1]
    )
}

//! Every scene under `scenes/`, through the real-time pipeline (WGSL) against its CPU
//! specification: the package the scene bakes by default, and for every opaque scene the GDM
//! with both codecs at every preset. The bar is the preview tests' (PSNR ≥ 35 dB over sRGB
//! values, FLIP ≤ 0.02, hit/miss mask disagreement ≤ 0.5 %), at a reduced image size so that
//! all of it runs in CI on Mesa's software driver; a scene added under `scenes/` is held to
//! it without editing this file. Needs an adapter (see tests/scene/preview.rs).

use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::limits::Limits;
use mesobake_core::quality::Preset;
use mesobake_gpu::gpu::Gpu;
use mesobake_render::image::{Image, compare};
use mesobake_scene::package::{ScenePackageParams, gdm_scene_package, scene_package};
use mesobake_scene::preview::{preview, render_on_cpu};
use mesobake_scene::technique::Technique;
use mesobake_scene::{LoadedScene, Scene};
use std::path::{Path, PathBuf};

/// The image's longer side in these tests.
const SIDE: u32 = 160;

/// Every scene file under `scenes/`, sorted.
fn scene_files() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    assert!(files.len() >= 11, "{files:?}");
    files
}

/// `path` loaded with its image shrunk to [`SIDE`] on its longer side (aspect kept).
fn load_small(path: &Path) -> LoadedScene {
    let mut scene = Scene::read(path).unwrap();
    let c = &mut scene.camera;
    let scale = f64::from(SIDE) / f64::from(c.width.max(c.height));
    c.width = (f64::from(c.width) * scale).round() as u32;
    c.height = (f64::from(c.height) * scale).round() as u32;
    LoadedScene::load(scene, path.parent().unwrap(), &Limits::default()).unwrap()
}

/// The WGSL image against the CPU twin's: `label` and what broke the bar, if anything did.
fn disagreement(
    gpu: &Gpu,
    loaded: &LoadedScene,
    package: &AnyPackage,
    label: &str,
) -> Option<String> {
    let (wgsl, _) = preview(gpu, loaded, package, 0, &()).unwrap();
    let cpu: Image = render_on_cpu(loaded, package, &()).unwrap();
    let c = compare(&wgsl, &cpu).unwrap();
    eprintln!(
        "{label}: PSNR {:.2} dB, FLIP {:.4}, mask {:.4} %, {} hit pixels (CPU {})",
        c.psnr_db,
        c.flip_mean,
        100.0 * c.mask_disagreement,
        wgsl.hits(),
        cpu.hits()
    );
    assert!(
        cpu.hits() > cpu.mask.len() / 20,
        "{label}: too little to test"
    );
    let ok = c.psnr_db >= 35.0 && c.flip_mean <= 0.02 && c.mask_disagreement <= 0.005;
    (!ok).then(|| {
        format!(
            "{label}: PSNR {:.2} dB (≥ 35), FLIP {:.4} (≤ 0.02), mask {:.3} % (≤ 0.5)",
            c.psnr_db,
            c.flip_mean,
            100.0 * c.mask_disagreement
        )
    })
}

/// Panics listing every disagreement found.
fn assert_none(failures: &[String]) {
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn every_scene_s_default_package_renders_alike_in_wgsl_and_on_the_cpu() {
    let Some(gpu) = crate::common::gpu() else {
        return;
    };
    let mut failures = Vec::new();
    for path in scene_files() {
        let loaded = load_small(&path);
        let dir = path.parent().unwrap();
        let package =
            scene_package(&loaded, dir, Default::default(), &Limits::default(), &()).unwrap();
        let name = path.file_stem().unwrap().to_string_lossy();
        let label = format!("{name} ({})", Technique::of_package(&package).name());
        failures.extend(disagreement(&gpu, &loaded, &package, &label));
    }
    assert_none(&failures);
}

/// Cases that Mesa's llvmpipe (the software driver CI runs) renders wrong, held to a lower bar
/// there only: (scene, codec, preset, PSNR at least). llvmpipe ends every loop of a shader
/// invocation once 65535 loop iterations have run in all (`LP_MAX_TGSI_LOOP_ITERATIONS` in
/// Mesa's gallivm: one counter for all loops, nested ones included, of the SIMD group's
/// lanes), and a shell shadow query that grazes the torus near the light's terminator
/// (hundreds of prisms, each with its face loop and its march) spends them: the query stops
/// part way and says lit or shadowed at random. The shader sums ambient light first, so those
/// pixels are no longer black; the CPU specification agrees with the truth on them.
/// Measured: `balanced` 35.8 → 40.4 dB with the ambient light first (no longer listed),
/// `high` 33.9 → 35.3 dB (listed: a margin of 0.3 dB is no bar).
const LLVMPIPE_DEFECTS: [(&str, GdmCodec, Preset, f64); 1] =
    [("torus-bumps", GdmCodec::PaperSvd, Preset::High, 33.0)];

#[test]
fn every_opaque_scene_s_gdm_renders_alike_with_both_codecs_at_every_preset() {
    let Some(gpu) = crate::common::gpu() else {
        return;
    };
    let mut failures = Vec::new();
    for path in scene_files() {
        let mut loaded = load_small(&path);
        if loaded.medium.is_some() {
            continue;
        }
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = path.parent().unwrap();
        for codec in GdmCodec::ALL {
            let params = ScenePackageParams {
                codec,
                rank: RankChoice::Rank(8),
                quantization: Quantization::F16,
            };
            let package = AnyPackage::Gdm(
                gdm_scene_package(&loaded, dir, params, &Limits::default(), &()).unwrap(),
            );
            for preset in Preset::ALL {
                loaded.scene.quality = preset.quality();
                let label = format!("{name} GDM {codec} {}", preset.name());
                let known = LLVMPIPE_DEFECTS
                    .iter()
                    .find(|d| (d.0, d.1, d.2) == (name.as_str(), codec, preset))
                    .filter(|_| gpu.adapter.name.contains("llvmpipe"));
                match known {
                    Some(&(.., floor)) => {
                        let (wgsl, _) = preview(&gpu, &loaded, &package, 0, &()).unwrap();
                        let cpu = render_on_cpu(&loaded, &package, &()).unwrap();
                        let psnr = compare(&wgsl, &cpu).unwrap().psnr_db;
                        eprintln!("{label}: {psnr:.2} dB (a known llvmpipe defect)");
                        if psnr < floor {
                            failures.push(format!("{label}: {psnr:.2} dB < {floor} dB"));
                        }
                    }
                    None => failures.extend(disagreement(&gpu, &loaded, &package, &label)),
                }
            }
        }
    }
    assert_none(&failures);
}

/// The GDM's presets buy accuracy on every opaque scene under point and directional light:
/// against the ground truth (both at 4 samples per pixel), `balanced` and `high` are never
/// more than 0.5 dB worse than `paper`. Shell shadows from hits on the volume's top layer
/// once ran the hit prism's chord back down into the solid: plane-bricks `balanced` was
/// 17.6 dB against `paper`'s 36.0 (`report conformance`, 16 samples per pixel).
#[test]
fn every_preset_is_at_least_as_close_to_the_truth_as_the_paper_s_algorithm() {
    use mesobake_core::effect::Effect;
    use mesobake_core::samples_per_pixel::SamplesPerPixel;
    use mesobake_scene::render::{MapSource, RenderMethod, render};
    let limits = Limits::default();
    let mut failures = Vec::new();
    for path in scene_files() {
        let mut loaded = load_small(&path);
        if loaded.medium.is_some() || loaded.scene.wants(Effect::EnvironmentLighting) {
            continue;
        }
        let camera = &mut loaded.scene.camera;
        (camera.width, camera.height) = (camera.width * 3 / 5, camera.height * 3 / 5);
        camera
            .set_samples_per_pixel(SamplesPerPixel::new(4).unwrap())
            .unwrap();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = path.parent().unwrap();
        let truth = render(&loaded, RenderMethod::Truth, MapSource::Bake, &limits, &())
            .unwrap()
            .image;
        let package = AnyPackage::Gdm(
            gdm_scene_package(&loaded, dir, Default::default(), &limits, &()).unwrap(),
        );
        let psnr: Vec<f64> = Preset::ALL
            .iter()
            .map(|preset| {
                loaded.scene.quality = preset.quality();
                let image = render_on_cpu(&loaded, &package, &()).unwrap();
                compare(&truth, &image).unwrap().psnr_db
            })
            .collect();
        eprintln!("{name}: paper, balanced, high {psnr:.2?} dB");
        if psnr[1..].iter().any(|&p| p < psnr[0] - 0.5) {
            failures.push(format!("{name}: {psnr:.2?} dB"));
        }
    }
    assert_none(&failures);
}

//! Every scene under `scenes/`, through the real-time pipeline (WGSL) against its CPU
//! specification: the package the scene bakes by default, and for every opaque scene the GDM
//! with both codecs at every preset. The bar is the preview tests' (PSNR ≥ 35 dB over sRGB
//! values, FLIP ≤ 0.02, hit/miss mask disagreement ≤ 0.5 %), at a reduced image size so that
//! all of it runs in CI on Mesa's software driver; a scene added under `scenes/` is held to
//! it without editing this file. Needs an adapter (see tests/preview.rs).

mod common;

use mesobake::compress::quantize::Quantization;
use mesobake::compress::svd::RankChoice;
use mesobake::package::AnyPackage;
use mesobake::package::manifest::GdmCodec;
use mesobake::realtime::gpu::Gpu;
use mesobake::render::image::{Image, compare};
use mesobake::render::quality::Preset;
use mesobake::scene::package::{ScenePackageParams, gdm_scene_package, scene_package};
use mesobake::scene::preview::{preview, render_on_cpu};
use mesobake::scene::{LoadedScene, Scene};
use mesobake::util::limits::Limits;
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

/// The WGSL image against the CPU twin's; panics with `label` when they disagree.
fn assert_agree(gpu: &Gpu, loaded: &LoadedScene, package: &AnyPackage, label: &str) {
    let (wgsl, _) = preview(gpu, loaded, package, 0, &()).unwrap();
    let cpu: Image = render_on_cpu(loaded, package).unwrap();
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
    assert!(c.psnr_db >= 35.0, "{label}: PSNR {:.2} dB < 35", c.psnr_db);
    assert!(
        c.flip_mean <= 0.02,
        "{label}: FLIP {:.4} > 0.02",
        c.flip_mean
    );
    assert!(
        c.mask_disagreement <= 0.005,
        "{label}: mask disagreement {:.3} % > 0.5 %",
        100.0 * c.mask_disagreement
    );
}

#[test]
fn every_scene_s_default_package_renders_alike_in_wgsl_and_on_the_cpu() {
    let Some(gpu) = common::gpu() else { return };
    for path in scene_files() {
        let loaded = load_small(&path);
        let dir = path.parent().unwrap();
        let package =
            scene_package(&loaded, dir, Default::default(), &Limits::default(), &()).unwrap();
        let name = path.file_stem().unwrap().to_string_lossy();
        assert_agree(
            &gpu,
            &loaded,
            &package,
            &format!("{name} ({})", package.technique().name()),
        );
    }
}

#[test]
fn every_opaque_scene_s_gdm_renders_alike_with_both_codecs_at_every_preset() {
    let Some(gpu) = common::gpu() else { return };
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
                assert_agree(&gpu, &loaded, &package, &label);
            }
        }
    }
}

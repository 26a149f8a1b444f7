//! Samples per pixel (`render::sampling`): the supersampled truth converges, and every
//! real-time pipeline moves its rays to a sample's sub-pixel position as its CPU
//! specification does, so that the two stay comparable at any count.

use mesobake_bake::package::AnyPackage;
use mesobake_core::limits::Limits;
use mesobake_core::samples_per_pixel::SamplesPerPixel;
use mesobake_render::image::{Image, compare};
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use mesobake_scene::package::scene_package;
use mesobake_scene::preview::{preview, render_on_cpu};
use mesobake_scene::{LoadedScene, Scene};
use std::path::Path;

fn load(name: &str, width: u32, height: u32) -> LoadedScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let mut scene = Scene::read(&path).unwrap();
    scene.camera.width = width;
    scene.camera.height = height;
    LoadedScene::load(scene, path.parent().unwrap(), &Limits::default()).unwrap()
}

/// The error of the truth at N samples per pixel against the truth at 64 falls as N grows
/// (torus-bumps, whose bumps alias at one sample: the 25.5 dB at 512²).
#[test]
fn the_supersampled_truth_converges() {
    let mut loaded = load("torus-bumps.json", 96, 96);
    let truth = TruthRenderer::new(
        &loaded.shell,
        loaded.mesostructure.caster(),
        &loaded.material,
    );
    let mut render = |n: u32| -> Image {
        let scene = &mut loaded.scene;
        scene
            .camera
            .set_samples_per_pixel(SamplesPerPixel::new(n).unwrap())
            .unwrap();
        let shot = scene.shot();
        render_image(&shot.camera, |o, d| truth.radiance(&shot, o, d))
    };
    let reference = render(64);
    let errors: Vec<(f64, f64)> = [1, 4, 16]
        .map(|n| {
            let c = compare(&render(n), &reference).unwrap();
            eprintln!(
                "{n:>2} spp against 64: PSNR {:.2} dB, mask {:.3} %",
                c.psnr_db,
                100.0 * c.mask_disagreement
            );
            (c.psnr_db, c.mask_disagreement)
        })
        .to_vec();
    // Each fourfold count gains at least 3 dB (Monte Carlo alone gives 6 dB per fourfold
    // count; stratification more: measured 17.3, 24.0, 34.0 dB). The mask, a vote of few
    // samples at 4 (two of four hits is a hit), is only required to end below where it
    // began (0.16, 0.37, 0.07 %).
    for w in errors.windows(2) {
        assert!(w[1].0 >= w[0].0 + 3.0, "{errors:?}");
    }
    assert!(errors[2].1 < errors[0].1, "{errors:?}");
}

/// Each pipeline (the GDM's, the VDM's and the translucent media's), with its rays moved to
/// one off-centre sub-pixel position and at 4 samples per pixel, against its CPU twin there:
/// the bar of the agreement tests. The move is large enough to matter: the moved image is
/// further from the centred one than the bar.
#[test]
fn every_pipeline_moves_its_rays_to_the_sample_positions_as_its_cpu_twin_does() {
    let Some(gpu) = crate::common::gpu() else {
        return;
    };
    for name in ["torus-chain.json", "torus-bumps.json", "torus-fur.json"] {
        let mut loaded = load(name, 96, 96);
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let package: AnyPackage =
            scene_package(&loaded, &dir, Default::default(), &Limits::default(), &()).unwrap();
        let centred = preview(&gpu, &loaded, &package, 0, &()).unwrap().0;
        let centre_camera = loaded.scene.camera;
        for (label, camera) in [
            ("at (0.1, 0.85)", centre_camera.at_subpixel([0.1, 0.85])),
            ("at 4 spp", {
                let mut c = centre_camera;
                c.set_samples_per_pixel(SamplesPerPixel::new(4).unwrap())
                    .unwrap();
                c
            }),
        ] {
            loaded.scene.camera = camera;
            let wgsl = preview(&gpu, &loaded, &package, 0, &()).unwrap().0;
            let cpu = render_on_cpu(&loaded, &package, &()).unwrap();
            let c = compare(&wgsl, &cpu).unwrap();
            let moved = compare(&wgsl, &centred).unwrap();
            eprintln!(
                "{name} {label}: WGSL vs CPU {:.2} dB, mask {:.3} %; vs the centred WGSL {:.2} dB",
                c.psnr_db,
                100.0 * c.mask_disagreement,
                moved.psnr_db
            );
            assert!(
                c.psnr_db >= 35.0 && c.mask_disagreement <= 0.005,
                "{name} {label}"
            );
            if camera.samples_per_pixel.is_one() {
                assert!(
                    moved.psnr_db < 30.0,
                    "{name} {label}: the move changed little"
                );
            }
        }
        loaded.scene.camera = centre_camera;
    }
}

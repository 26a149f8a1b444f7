//! Medium packages: the transparency technique's plan, its package against the scene's own
//! medium (each quantization's error measured), an animated surface that re-bakes nothing,
//! an opaque mesostructure as a medium against the opaque truth, and bad input.

use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::medium as medium_package;
use mesobake_core::limits::Limits;
use mesobake_render::image::{Comparison, compare};
use mesobake_render::medium_truth::MediumTruth;
use mesobake_render::render_image;
use mesobake_render::truth::TruthRenderer;
use mesobake_scene::package::{
    ScenePackageParams, bake_scene_package, check_any_package_input, scene_package,
};
use mesobake_scene::preview::{medium_render_on_cpu, render_on_cpu};
use mesobake_scene::{LoadedScene, Scene};
use serde_json::{Value, json};
use std::path::Path;

/// Fur on a torus under a slanted sun with shadows (deep maps), 64² pixels, 16×16×8 voxels.
fn fur() -> Value {
    json!({
        "base_mesh": { "builtin": { "torus": { "segments": [24, 12] } } },
        "mesostructure": { "medium": "fur" },
        "resolution": [16, 16, 8],
        "shell": { "thickness": 0.15, "tiles_per_uv": [8, 4] },
        "camera": { "eye": [0, 2, 2.5], "target": [0, 0, 0], "fov_y_degrees": 45,
                    "width": 64, "height": 64 },
        "lights": [
            { "directional": { "direction": [-0.4, -1, -0.5], "irradiance": [2.5, 2.5, 2.5] } },
            { "ambient": { "radiance": [0.1, 0.1, 0.1] } }
        ],
        "effects": ["silhouettes", "shadows"]
    })
}

fn load(scene: &Value) -> LoadedScene {
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    LoadedScene::load(scene, Path::new("."), &Limits::default()).unwrap()
}

fn package(loaded: &LoadedScene) -> AnyPackage {
    let params = ScenePackageParams::default();
    scene_package(loaded, Path::new("."), params, &Limits::default(), &()).unwrap()
}

/// The cells renderer on `loaded`'s package against the cells renderer on its own medium.
fn package_vs_scene(loaded: &LoadedScene) -> Comparison {
    let from_package = render_on_cpu(loaded, &package(loaded), &()).unwrap();
    compare(&medium_render_on_cpu(loaded).unwrap(), &from_package).unwrap()
}

#[test]
fn a_translucent_scene_plans_only_its_medium_and_renders_from_its_package() {
    let loaded = load(&fur());
    let baked = bake_scene_package(
        &loaded,
        Path::new("."),
        ScenePackageParams::default(),
        &Limits::default(),
        &(),
    )
    .unwrap();
    let plan = &baked.plan;
    assert_eq!(plan.technique.technique.name(), "transparency");
    assert!(
        plan.technique.reason.contains("translucent medium"),
        "{plan:?}"
    );
    assert_eq!(plan.stages, ["load", "encode"]);
    let skipped: Vec<&str> = plan.skipped.iter().map(|k| k.stage.as_str()).collect();
    assert_eq!(
        skipped,
        [
            "bake_gdm",
            "occupancy",
            "compress",
            "bake_prt",
            "bake_rtv",
            "compress_rtv",
            "medium_mips"
        ]
    );
    assert!(plan.skipped[0].reason.contains("no precomputed visibility"));

    // Each quantization against the scene's own medium (CPU cells renderer, same settings):
    // f32 stores the medium exactly (the same image to the bit); f16 and u8 cost what they
    // cost (measured on fur: 90.9 and 73.3 dB, mask 0). The uniform absorbing medium has no
    // gradient inside, which every format must keep (u8 normals would not: they are f16).
    let mut psnr = Vec::new();
    for (medium, q, mipmap, at_least_db) in [
        ("fur", "f32", false, f64::INFINITY),
        ("fur", "f32", true, f64::INFINITY),
        ("fur", "f16", false, 60.0),
        ("fur", "f16", true, 60.0),
        ("fur", "u8", false, 40.0),
        ("absorbing", "u8", false, 40.0),
    ] {
        let mut scene = fur();
        scene["mesostructure"] = json!({ "medium": medium });
        scene["transparency"] = json!({ "quantization": q, "mipmap": mipmap });
        let loaded = load(&scene);
        let c = package_vs_scene(&loaded);
        eprintln!("{medium}, {q}, mipmap {mipmap}: {c:?}");
        assert!(
            c.psnr_db >= at_least_db && c.mask_disagreement == 0.0,
            "{medium}, {q}, mipmap {mipmap}: {c:?}"
        );
        psnr.push(c.psnr_db);
    }
    assert!(psnr[2] > psnr[4], "{psnr:?}");
    // At 64² the pixels pick level 0, so the images above cannot see the mip levels: an f32
    // package's levels are the medium's own mip-map, value for value.
    let mut scene = fur();
    scene["transparency"] = json!({ "quantization": "f32", "mipmap": true });
    let loaded = load(&scene);
    let AnyPackage::Medium(p) = package(&loaded) else {
        panic!("not a medium package")
    };
    let levels = medium_package::levels(&p, loaded.scene.transparency.mipmap).unwrap();
    let medium = loaded.medium.as_ref().unwrap();
    let expected = medium.coarser_levels();
    assert_eq!(levels.len(), 1 + expected.len());
    assert_eq!(expected.len(), 3, "16×16×8 halves to 2×2×1");
    for (got, want) in levels[1..].iter().zip(&expected) {
        assert_eq!(got.dims(), want.dims());
        for v in 0..want.dims().voxel_count() as usize {
            assert_eq!(got.opacity(v), want.opacity(v));
            assert!((got.colour(v) - want.colour(v)).length() < 1e-6);
        }
    }
}

#[test]
fn an_animated_surface_renders_from_the_same_package_bit_for_bit() {
    let first = load(&fur());
    let mut moved = fur();
    moved["base_mesh"] = json!({ "builtin": { "torus": { "major_radius": 1.2, "minor_radius": 0.3,
                                                       "segments": [30, 14] } } });
    moved["shell"]["thickness"] = json!(0.1);
    let moved = load(&moved);
    let bake = |loaded: &LoadedScene| {
        bake_scene_package(
            loaded,
            Path::new("."),
            ScenePackageParams::default(),
            &Limits::default(),
            &(),
        )
        .unwrap()
        .bytes
    };
    let bytes = bake(&first);
    assert_eq!(
        bytes,
        bake(&moved),
        "a new surface changed the medium package"
    );
    let package = AnyPackage::parse(bytes).unwrap();
    check_any_package_input(&package, &moved.scene, Path::new(".")).unwrap();
    // The moved surface renders from it as from its own medium (f16: ≥ 60 dB, as above).
    let c = compare(
        &medium_render_on_cpu(&moved).unwrap(),
        &render_on_cpu(&moved, &package, &()).unwrap(),
    )
    .unwrap();
    assert!(c.psnr_db >= 60.0 && c.mask_disagreement == 0.0, "{c:?}");
    // Another medium's package is refused by name.
    let mut clouds = fur();
    clouds["mesostructure"] = json!({ "medium": "clouds" });
    let e = check_any_package_input(&package, &load(&clouds).scene, Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(e.contains("baked from another mesostructure"), "{e}");
}

/// An opaque mesostructure with the `transparency` effect is the medium with α = 1 in its
/// solid voxels: the package's level 0 is opaque exactly where the opaque caster's voxel
/// centres are inside (a volume, a mesh tile and a relief), and the media's ground truth of
/// the package's medium matches the opaque ground truth of the same voxels (a renderer that
/// shares no code with the media), unshadowed and with the same normals, to 0.1 % of the
/// mask and 30 dB (as the opaque sample in tests/scene/medium_render.rs).
#[test]
fn an_opaque_mesostructure_as_a_medium_is_its_solid_voxels() {
    // The shipped torus-chain scene, shrunk to 96² pixels and a 32 × 32 × 16 grid.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/torus-chain.json");
    let mut scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["resolution"] = json!([32, 32, 16]);
    scene["camera"]["width"] = json!(96);
    scene["camera"]["height"] = json!(96);
    scene["effects"] = json!(["transparency"]);
    scene["transparency"] = json!({ "quantization": "f32" });
    for mesostructure in [
        json!({ "sample": "chain" }),
        json!({ "sample_tile": "chain" }),
        json!({ "relief": "bumps" }),
    ] {
        scene["mesostructure"] = mesostructure.clone();
        let loaded = load(&scene);
        assert_eq!(loaded.technique().technique.name(), "transparency");
        let AnyPackage::Medium(p) = package(&loaded) else {
            panic!("{mesostructure}: not a medium package")
        };
        let solid = loaded.mesostructure.caster().centres_inside();
        let d = solid.dims();
        let level = &p.levels()[0];
        for k in 0..d.z {
            for j in 0..d.y {
                for i in 0..d.x {
                    let alpha = level.voxels[d.index(i, j, k)][3];
                    assert_eq!(
                        alpha,
                        f32::from(u8::from(solid.get(i, j, k))),
                        "{mesostructure}"
                    );
                }
            }
        }
        assert!(solid.solid_count() > 0, "{mesostructure}");
        if mesostructure != json!({ "sample": "chain" }) {
            continue;
        }
        let levels = medium_package::levels(&p, loaded.scene.transparency.mipmap).unwrap();
        let s = &loaded.scene;
        let media = MediumTruth::new(&loaded.shell, &levels[0]);
        let shot = s.shot();
        let media_image = render_image(&shot.camera, |o, d| media.radiance(&shot, o, d));
        let opaque = TruthRenderer::new(
            &loaded.shell,
            loaded.mesostructure.caster(),
            levels[0].material(),
        );
        let shot = s.shot();
        let reference = render_image(&shot.camera, |o, d| opaque.radiance(&shot, o, d));
        let c = compare(&reference, &media_image).unwrap();
        eprintln!("the chain's medium package against the opaque truth: {c:?}");
        assert!(reference.hits() > 96 * 96 / 8);
        assert!(c.mask_disagreement <= 0.001 && c.psnr_db >= 30.0, "{c:?}");
    }
}

#[test]
fn scenes_and_packages_that_do_not_fit_are_refused_by_name() {
    for (edit, expected) in [
        (
            json!({ "technique": "gdm", "effects": ["transparency"] }),
            "technique gdm renders opaque mesostructure only",
        ),
        (
            json!({ "technique": "vdm", "effects": ["transparency"] }),
            "technique vdm renders opaque mesostructure only",
        ),
        (
            json!({ "effects": ["environment_lighting"],
                    "environment": { "sky": { "overcast": { "zenith": [1, 1, 1], "ground": [0, 0, 0] } } } }),
            "the translucent-media pipeline shades point, directional and ambient lights",
        ),
        (
            json!({ "transparency": { "quantization": "f8" } }),
            "unknown variant",
        ),
    ] {
        let mut scene = fur();
        for (k, v) in edit.as_object().unwrap() {
            scene[k] = v.clone();
        }
        let e = Scene::from_json(&scene.to_string())
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "{edit}: {e}");
    }
    // A volume file whose header has an opacity channel is found translucent when the scene
    // is loaded: environment lighting is refused then, before anything is baked.
    let dir = tempfile::tempdir().unwrap();
    let dims = mesobake_package::grid::Dims::new(16, 16, 8).unwrap();
    let clouds = mesobake_bake::mesostructure::media::volume(
        mesobake_bake::mesostructure::media::MediumKind::Clouds,
        dims,
        &Limits::default(),
    )
    .unwrap();
    mesobake_bake::mesostructure::volume_format::write(&clouds, &dir.path().join("c.mbvol"))
        .unwrap();
    let mut lit = fur();
    lit["mesostructure"] = json!({ "volume": "c.mbvol" });
    lit["effects"] = json!(["environment_lighting"]);
    lit["environment"] =
        json!({ "sky": { "overcast": { "zenith": [1, 1, 1], "ground": [0, 0, 0] } } });
    let scene = Scene::from_json(&lit.to_string()).unwrap();
    let loaded = LoadedScene::load(scene, dir.path(), &Limits::default()).unwrap();
    let params = ScenePackageParams::default();
    let e = bake_scene_package(&loaded, dir.path(), params, &Limits::default(), &())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("the translucent-media pipeline shades point"),
        "{e}"
    );
    // A package baked without the mip-map cannot serve a scene that filters.
    let flat = package(&load(&fur()));
    let mut filtered = fur();
    filtered["transparency"] = json!({ "mipmap": true });
    let e = render_on_cpu(&load(&filtered), &flat, &())
        .unwrap_err()
        .to_string();
    assert!(e.contains("holds level 0 only"), "{e}");
    // Nor a scene on another grid.
    let mut finer = fur();
    finer["resolution"] = json!([32, 32, 8]);
    let e = check_any_package_input(&flat, &load(&finer).scene, Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(e.contains("holds a 16x16x8 medium"), "{e}");
}

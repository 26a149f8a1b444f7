//! The real-time preview of several objects (`Preview::of_objects`, `objects_on.wgsl`) against
//! its specification, the objects' CPU GDM renderers composed (`render_objects` on the same
//! packages): PSNR ≥ 35 dB over sRGB values, FLIP ≤ 0.02, hit-mask disagreement ≤ 0.5 %, both
//! at 1 spp. On a plane under a smaller turned plane whose shadow falls on it (both shadow
//! methods, both codecs) and on the Blender knight's two materials, each with its own
//! mesostructure. That the shadow between objects is drawn is checked on its own too: the
//! ground under the roof is darker than the ground's own preview.

use crate::objects::{VIEW, knight_scene, plane_dir};
use crate::preview::gpu_or_skip;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_bake::package::{AnyPackage, Package};
use mesobake_core::limits::Limits;
use mesobake_gpu::gpu::Gpu;
use mesobake_render::image::{Comparison, Image, compare};
use mesobake_scene::LoadedScene;
use mesobake_scene::objects::{self, SceneObject};
use mesobake_scene::package::{ScenePackageParams, gdm_scene_package};
use mesobake_scene::preview::objects_preview;
use mesobake_scene::render::{RenderMethod, render_objects};
use std::path::Path;

/// The objects loaded from `dir`, with a package of `codec` each.
fn loaded(
    objects: &[SceneObject],
    dir: &Path,
    codec: GdmCodec,
) -> (Vec<LoadedScene>, Vec<AnyPackage>) {
    let limits = Limits::default();
    let loaded: Vec<LoadedScene> = objects
        .iter()
        .map(|o| LoadedScene::load(o.scene.clone(), dir, &limits).unwrap())
        .collect();
    let params = ScenePackageParams {
        codec,
        ..ScenePackageParams::default()
    };
    let packages = loaded
        .iter()
        .map(|o| AnyPackage::Gdm(gdm_scene_package(o, dir, params, &limits, &()).unwrap()))
        .collect();
    (loaded, packages)
}

/// The WGSL image of the objects.
fn gpu_image(loaded: &[LoadedScene], packages: &[AnyPackage]) -> Image {
    let refs: Vec<&Package> = packages
        .iter()
        .map(|p| match p {
            AnyPackage::Gdm(p) => p,
            _ => unreachable!("GDM packages only"),
        })
        .collect();
    objects_preview(&Gpu::open(None).unwrap(), loaded, &refs, 0, &())
        .unwrap()
        .0
}

/// The WGSL against the composed CPU renderers on the same packages.
fn agreement(loaded: &[LoadedScene], packages: &[AnyPackage], label: &str) -> (Image, Comparison) {
    let gpu = gpu_image(loaded, packages);
    let given: Vec<Option<&AnyPackage>> = packages.iter().map(Some).collect();
    let methods = vec![RenderMethod::Gdm; loaded.len()];
    let cpu = render_objects(loaded, &methods, &given, &(), &Limits::default())
        .unwrap()
        .image;
    let c = compare(&gpu, &cpu).unwrap();
    eprintln!(
        "{label}: PSNR {:.2} dB, FLIP {:.4}, mask {:.4} %, {} hit pixels (CPU {})",
        c.psnr_db,
        c.flip_mean,
        c.mask_disagreement * 100.0,
        gpu.hits(),
        cpu.hits()
    );
    assert!(
        cpu.hits() > cpu.mask.len() / 20,
        "{label}: too little shows"
    );
    assert!(
        c.psnr_db >= 35.0 && c.flip_mean <= 0.02 && c.mask_disagreement <= 0.005,
        "{label}: {c:?}"
    );
    (gpu, c)
}

/// The plane and its roof: the WGSL draws what the composed CPU renderers draw, the roof's
/// shadow on the ground included, with the paper's local shadows and with shell shadows
/// (whose own query and the occlusion pass both trace shells), for both codecs.
#[test]
fn the_preview_of_a_plane_under_a_roof_matches_the_composed_cpu_renderers() {
    if !gpu_or_skip() {
        return;
    }
    let (dir, _) = plane_dir();
    for shadows in ["local", "shell"] {
        let two = objects::from_json(&format!(
            r#"{{ {VIEW},
  "quality": {{ "shadows": "{shadows}" }},
  "shell": {{ "thickness": 0.1, "tiles_per_uv": [2, 2] }},
  "mesostructure": {{ "sample": "weave" }}, "resolution": [16, 16, 8],
  "base_mesh": {{ "obj": "plane.obj" }},
  "objects": [
    {{ "name": "ground" }},
    {{ "name": "roof", "mesostructure": {{ "sample": "chain" }},
       "transform": {{ "translate": [0.2, 0.3, 0.1], "rotate_degrees": [0, 30, 0], "scale": 0.5 }} }}
  ] }}"#
        ))
        .unwrap();
        for codec in [GdmCodec::Occupancy, GdmCodec::PaperSvd] {
            let (loaded, packages) = loaded(&two, dir.path(), codec);
            let label = format!("plane and roof, {shadows} shadows, {codec}");
            let (together, _) = agreement(&loaded, &packages, &label);
            let ground = gpu_image(&loaded[..1], &packages[..1]);
            let roof = gpu_image(&loaded[1..], &packages[1..]);
            let shaded = (0..together.rgb.len())
                .filter(|&i| {
                    together.mask[i] && !roof.mask[i] && together.rgb[i][0] < 0.8 * ground.rgb[i][0]
                })
                .count();
            assert!(shaded > 20, "{label}: {shaded} pixels in the roof's shadow");
        }
    }
}

/// The knight Blender wrote (`tests/data/blender/knight.glb`), its two materials two objects
/// with a mesostructure each: the WGSL draws what the composed CPU renderers draw.
#[test]
fn the_preview_of_the_blender_knights_two_materials_matches_the_composed_cpu_renderers() {
    if !gpu_or_skip() {
        return;
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender");
    let glb = data.join("knight.glb");
    let knight = objects::from_json(&knight_scene(
        glb.to_str().unwrap(),
        r#", "materials": { "Chain": {}, "Leather": { "mesostructure": { "sample": "weave" },
             "material": { "albedo": [0.6, 0.35, 0.2] } } }"#,
    ))
    .unwrap();
    assert_eq!(knight.len(), 2);
    let (loaded, packages) = loaded(&knight, &data, GdmCodec::Occupancy);
    agreement(&loaded, &packages, "the knight's chain and leather");
}

//! The real-time preview of several objects (`Preview::of_objects`, `objects_on.wgsl`,
//! `vdm_objects.wgsl`) against its specification, the objects' CPU real-time renderers
//! composed (`render_objects` on the same packages: GDM or VDM by each package): PSNR ≥ 35 dB
//! over sRGB values, FLIP ≤ 0.02, hit-mask disagreement ≤ 0.5 %, both at 1 spp. On a plane
//! under a smaller turned plane whose shadow falls on it (GDM objects with both shadow methods
//! and both codecs; VDM objects with both of theirs; a GDM object with a VDM object either way
//! round) and on the Blender knight's two materials, each with its own mesostructure. That the
//! shadow between objects is drawn is checked on its own too: the ground under the roof is
//! darker than the ground's own preview.

use crate::objects::{VIEW, knight_scene, plane_dir};
use crate::preview::gpu_or_skip;
use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::limits::Limits;
use mesobake_gpu::gpu::Gpu;
use mesobake_render::image::{Comparison, Image, compare};
use mesobake_scene::LoadedScene;
use mesobake_scene::objects::{self, SceneObject};
use mesobake_scene::package::{ScenePackageParams, scene_package};
use mesobake_scene::preview::objects_preview;
use mesobake_scene::render::{RenderMethod, render_objects};
use mesobake_scene::technique::Technique;
use std::path::Path;

/// The objects loaded from `dir`, with the package of each one's technique (GDM ones of
/// `codec`).
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
    let packages = loaded
        .iter()
        .map(|o| {
            let params = match o.technique().technique {
                Technique::Vdm => ScenePackageParams::default(),
                _ => ScenePackageParams {
                    codec,
                    ..ScenePackageParams::default()
                },
            };
            scene_package(o, dir, params, &limits, &()).unwrap()
        })
        .collect();
    (loaded, packages)
}

/// The WGSL image of the objects.
fn gpu_image(loaded: &[LoadedScene], packages: &[AnyPackage]) -> Image {
    objects_preview(&Gpu::open(None).unwrap(), loaded, packages, 0, &())
        .unwrap()
        .0
}

/// The WGSL against the composed CPU renderers on the same packages.
fn agreement(loaded: &[LoadedScene], packages: &[AnyPackage], label: &str) -> (Image, Comparison) {
    let gpu = gpu_image(loaded, packages);
    let given: Vec<Option<&AnyPackage>> = packages.iter().map(Some).collect();
    let methods: Vec<RenderMethod> = packages
        .iter()
        .map(|p| match p {
            AnyPackage::Vdm(_) => RenderMethod::Vdm,
            _ => RenderMethod::Gdm,
        })
        .collect();
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

/// The roof's turn above the plane.
const TURNED: [i32; 3] = [0, 30, 0];

/// The plane and its roof (`ground` and `roof`: each object's entries; the roof turned by
/// `rotate` degrees) drawn by the WGSL and by the composed CPU renderers from the same
/// packages; the roof's shadow darkens the ground.
fn plane_and_roof(
    dir: &Path,
    shared: &str,
    [ground, roof]: [&str; 2],
    rotate: [i32; 3],
    codec: GdmCodec,
    label: &str,
) {
    let two = objects::from_json(&format!(
        r#"{{ {VIEW}, {shared},
  "shell": {{ "thickness": 0.1, "tiles_per_uv": [2, 2] }},
  "base_mesh": {{ "obj": "plane.obj" }},
  "objects": [
    {{ "name": "ground", {ground} }},
    {{ "name": "roof", {roof},
       "transform": {{ "translate": [0.2, 0.3, 0.1], "rotate_degrees": {rotate:?}, "scale": 0.5 }} }}
  ] }}"#
    ))
    .unwrap();
    let (loaded, packages) = loaded(&two, dir, codec);
    let (together, _) = agreement(&loaded, &packages, label);
    let ground = gpu_image(&loaded[..1], &packages[..1]);
    let roof = gpu_image(&loaded[1..], &packages[1..]);

    let shaded = (0..together.rgb.len())
        .filter(|&i| {
            together.mask[i] && !roof.mask[i] && together.rgb[i][0] < 0.8 * ground.rgb[i][0]
        })
        .count();
    assert!(shaded > 20, "{label}: {shaded} pixels in the roof's shadow");
}

/// GDM objects: the WGSL draws what the composed CPU renderers draw, the roof's shadow on the
/// ground included, with the paper's local shadows and with shell shadows (whose own query
/// and the occlusion pass both trace shells), for both codecs.
#[test]
fn the_preview_of_a_plane_under_a_roof_matches_the_composed_cpu_renderers() {
    if !gpu_or_skip() {
        return;
    }
    let (dir, _) = plane_dir();
    let weave = r#""mesostructure": { "sample": "weave" }"#;
    let chain = r#""mesostructure": { "sample": "chain" }"#;
    for shadows in ["local", "shell"] {
        let shared =
            format!(r#""quality": {{ "shadows": "{shadows}" }}, "resolution": [16, 16, 8]"#);
        for codec in [GdmCodec::Occupancy, GdmCodec::PaperSvd] {
            let label = format!("plane and roof, {shadows} shadows, {codec}");
            plane_and_roof(dir.path(), &shared, [weave, chain], TURNED, codec, &label);
        }
    }
}

/// VDM objects, alone and beside GDM objects: the ground and the roof as reliefs (both VDM
/// shadow methods; the ground's shadow rays meet the roof's top faces from behind), the roof
/// upside down (its relief facing the ground: unseen from above, it blocks the shadow rays by
/// its lookups), then a relief ground under a GDM chain roof and a GDM weave ground under a
/// relief roof.
#[test]
fn the_preview_of_vdm_objects_matches_the_composed_cpu_renderers() {
    if !gpu_or_skip() {
        return;
    }
    let (dir, _) = plane_dir();
    let bumps =
        r#""mesostructure": { "relief": "bumps" }, "technique": "vdm", "resolution": [32, 32, 8]"#;
    let chain = r#""mesostructure": { "sample": "chain" }, "resolution": [16, 16, 8]"#;
    let weave = r#""mesostructure": { "sample": "weave" }, "resolution": [16, 16, 8]"#;
    let codec = GdmCodec::Occupancy;
    for shadows in ["local", "shell"] {
        let shared = format!(r#""vdm": {{ "shadows": "{shadows}" }}"#);
        let label = format!("relief plane and roof, {shadows} shadows");
        plane_and_roof(dir.path(), &shared, [bumps, bumps], TURNED, codec, &label);
    }
    let shared = r#""vdm": { "shadows": "local" }"#;
    let label = "relief plane under an upside-down relief roof";
    plane_and_roof(
        dir.path(),
        shared,
        [bumps, bumps],
        [180, 30, 0],
        codec,
        label,
    );
    for (objects, label) in [
        ([bumps, chain], "relief plane under a GDM roof"),
        ([weave, bumps], "GDM plane under a relief roof"),
    ] {
        plane_and_roof(dir.path(), shared, objects, TURNED, codec, label);
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

//! The bakes' peak heap against the bound their plan checks (`mesobake_scene::memory`), on
//! every shipped scene and codec.

use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::limits::Limits;
use mesobake_scene::bench::bakes::MemoryProbe;
use mesobake_scene::memory::bake_memory;
use mesobake_scene::package::{ScenePackageParams, bake_scene_package, plan_package};
use mesobake_scene::{LoadedScene, Scene};
use std::path::{Path, PathBuf};

/// Every scene file under `scenes/`, sorted.
fn shipped_scenes() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut found = Vec::new();
    let mut dirs = vec![root];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "json") {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}

/// The peak heap, above what was live before, of planning, loading and baking `scene`'s
/// package with `params`.
fn measured_peak(scene: &Scene, dir: &Path, params: ScenePackageParams) -> u64 {
    let limits = Limits::default();
    let before = crate::ALLOCATOR.current_bytes();
    crate::ALLOCATOR.reset_peak();
    plan_package(scene, dir, params, &limits).unwrap();
    let loaded = LoadedScene::load(scene.clone(), dir, &limits).unwrap();
    let baked = bake_scene_package(&loaded, dir, params, &limits, &()).unwrap();
    drop((baked, loaded));
    crate::ALLOCATOR.peak_bytes().saturating_sub(before)
}

#[test]
fn every_scenes_bake_stays_within_the_memory_its_plan_checks() {
    let _one = crate::measuring();
    let paper_svd = ScenePackageParams {
        codec: GdmCodec::PaperSvd,
        ..ScenePackageParams::default()
    };
    let mut rows = Vec::new();
    for path in shipped_scenes() {
        let scene = Scene::read(&path).unwrap();
        let dir = path.parent().unwrap();
        let plan = plan_package(
            &scene,
            dir,
            ScenePackageParams::default(),
            &Limits::default(),
        )
        .unwrap();
        let technique = plan.technique.technique;
        let mut codecs = vec![ScenePackageParams::default()];
        if technique.name() == "gdm" {
            codecs.push(paper_svd);
        }
        for params in codecs {
            let peak = measured_peak(&scene, dir, params);
            let gdm = (params.codec, params.rank);
            let bound = bake_memory(&scene, dir, technique, gdm).unwrap().total();
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            let codec = format!("{:?}", params.codec);
            eprintln!(
                "{name:>16} {codec:>10}: peak {:>6.1} MiB, bound {:>7.1} MiB ({:.1}×)",
                peak as f64 / 1048576.0,
                bound as f64 / 1048576.0,
                bound as f64 / peak.max(1) as f64
            );
            rows.push((name, codec, peak, bound));
        }
    }
    let under: Vec<_> = rows
        .iter()
        .filter(|(_, _, peak, bound)| bound < peak)
        .collect();
    assert!(
        under.is_empty(),
        "bounds under the measured peak: {under:?}"
    );
}

//! The default package against the uncompressed GDM on every sample scene (the packages
//! issue's target): rendered by the CPU GDM renderer, both are compared with the ground truth,
//! and the default package must come within 0.5 dB PSNR of the uncompressed GDM's image (or
//! closer to the truth) with at most 0.3 points more mask disagreement, in at most 2.2 MB. The
//! images are scaled down to 128 pixels per side to keep the suite fast; the grids are the
//! scenes' own. Scenes lit by an environment only are left out: their truth is the path
//! tracer, and their GDM part is the one of the same mesostructure under point lights.

use glam::DVec3;
use mesobake_bake::gdm::EscapeConvention;
use mesobake_core::effect::Effect;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_render::gdm_lookup::{GdmLookup, Lookup, RawLookup};
use mesobake_render::gdm_renderer::GdmRenderer;
use mesobake_render::prepared_prism::{longest_segment, prepare_prisms};
use mesobake_render::render_image;
use mesobake_scene::render::load_scene;
use mesobake_scene::report::codecs::{CodecSweep, codec_report};
use std::path::Path;

use crate::common::{each_fails_with, small_scene, succeeds};

#[test]
fn the_default_package_renders_like_the_uncompressed_gdm_on_every_sample_scene() {
    let limits = Limits::default();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let mut loaded = load_scene(&path, &limits).unwrap();
        // Height-field scenes are the VDM's (tests/scene/vdm_render.rs): their exact surface is not
        // the voxel grid an occupancy package stores. Translucent media have no GDM.
        if loaded.scene.wants(Effect::EnvironmentLighting)
            || loaded.height_field.is_some()
            || loaded.medium.is_some()
        {
            continue;
        }
        let camera = &mut loaded.scene.camera;
        let scale = 128.0 / camera.width.max(camera.height) as f64;
        camera.width = (camera.width as f64 * scale).round() as u32;
        camera.height = (camera.height as f64 * scale).round() as u32;
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        scenes.push((name, loaded, dir.as_path()));
    }
    scenes.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(scenes.len() >= 5, "{} sample scenes", scenes.len());
    let sweep = CodecSweep {
        ranks: vec![],
        quantization: Default::default(),
        tiles: vec![],
        visibility: vec![],
        frames: 0,
    };
    let report = codec_report(&scenes, &sweep, &limits, &()).unwrap();
    eprintln!("{}", mesobake_scene::report::codecs::markdown(&report));
    for pair in report.rows.chunks(2) {
        let [uncompressed, default] = pair else {
            panic!("rows come in pairs: {pair:?}")
        };
        assert_eq!(
            (uncompressed.codec.as_str(), default.codec.as_str()),
            ("uncompressed", "occupancy")
        );
        let scene = &default.scene;
        assert!(
            default.bytes <= 2_200_000,
            "{scene}: {} bytes",
            default.bytes
        );
        assert!(
            default.psnr_db >= uncompressed.psnr_db - 0.5,
            "{scene}: {:.2} dB against {:.2} dB uncompressed",
            default.psnr_db,
            uncompressed.psnr_db
        );
        assert!(
            default.mask_disagreement <= uncompressed.mask_disagreement + 0.003,
            "{scene}: mask {} against {}",
            default.mask_disagreement,
            uncompressed.mask_disagreement
        );
        // On volumes the march answers the exact GDM at every sample.
        assert_eq!(default.flip_rate, 0.0, "{scene}");
        assert!(default.hit_rmse < 1e-4, "{scene}: {}", default.hit_rmse);
    }
}

#[test]
fn report_codecs_writes_the_table_json_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_scene(dir.path());
    let out = dir.path().join("report");
    let o = succeeds(&[
        "report",
        "codecs",
        "--scenes",
        path.to_str().unwrap(),
        "--ranks",
        "2,4",
        "--tiles",
        "8",
        "--visibility",
        "2x4",
        "--frames",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    let table = String::from_utf8(o.stdout).unwrap();
    assert_eq!(
        table,
        std::fs::read_to_string(out.join("codecs.md")).unwrap()
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("codecs.json")).unwrap()).unwrap();
    let rows = report["rows"].as_array().unwrap();
    let codecs: Vec<&str> = rows.iter().map(|r| r["codec"].as_str().unwrap()).collect();
    assert_eq!(
        codecs,
        [
            "uncompressed",
            "occupancy",
            "paper-svd",
            "paper-svd",
            "tiled-svd",
            "tiled-svd",
            "split-svd",
            "split-svd",
            "split-svd",
            "split-svd"
        ]
    );
    assert_eq!(rows[2]["setting"], "f16, rank 2");
    assert_eq!(rows[4]["setting"], "8×8 tiles f16, rank 2");
    assert_eq!(
        rows[6]["setting"],
        "global basis f16, escape bits 2×4, rank 2"
    );
    assert_eq!(rows[8]["series"], "8×8 tiles f16, escape bits 2×4");
    // The global basis at rank 2: (16·16·8 weight rows + 4·8 eigen rows) · 2 · 2 bytes, a
    // scale and bias per factor and component (4 × 2 × 4 bytes), and one bit per sample of
    // the 2×4 visibility grid (16·16·8·8 / 8 bytes).
    assert_eq!(rows[6]["bytes"], (2048 + 32) * 2 * 2 + 32 + 2048);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row["shadow_flip_rate"].is_number(), i >= 6, "{row}");
    }
    // Tiles fit better than one basis at the same rank (the weight maps' bytes are equal).
    assert!(rows[4]["flip_rate"].as_f64() <= rows[2]["flip_rate"].as_f64());
    // The uncompressed GDM is 4 bytes per sample; the SVD flips samples, the march none.
    assert_eq!(rows[0]["bytes"], 16 * 16 * 8 * 4 * 8 * 4);
    assert!(rows[2]["flip_rate"].as_f64().unwrap() > 0.0);
    assert_eq!(rows[1]["flip_rate"], 0.0);
    let svg = std::fs::read_to_string(out.join("codecs.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("paper-svd"),
        "{svg:.200}"
    );
    let (scene, out) = (path.to_str().unwrap(), out.to_str().unwrap());
    let missing = dir.path().join("missing.json");
    each_fails_with(&[
        (
            vec![
                "report", "codecs", "--scenes", scene, "--ranks", "0", "--out", out,
            ],
            "rank must be in 1..=64, got 0",
        ),
        (
            vec![
                "report",
                "codecs",
                "--scenes",
                missing.to_str().unwrap(),
                "--out",
                out,
            ],
            "missing.json",
        ),
    ]);
}

/// Records the longest segment a renderer asks about, answering from `inner`.
struct SegmentRecorder<'a> {
    inner: &'a dyn GdmLookup,
    longest: std::sync::Mutex<f64>,
}

impl GdmLookup for SegmentRecorder<'_> {
    fn dims(&self) -> Dims {
        self.inner.dims()
    }

    fn lookup(&self, t: DVec3, v: DVec3) -> Lookup {
        self.inner.lookup(t, v)
    }

    fn segment_hit(&self, start: DVec3, view: DVec3, d_t: f64, refinements: u32) -> Option<f64> {
        let mut longest = self.longest.lock().unwrap();
        *longest = longest.max(d_t);
        drop(longest);
        self.inner.segment_hit(start, view, d_t, refinements)
    }
}

#[test]
fn no_fragment_segment_is_longer_than_the_distance_cap() {
    // The cap bounds every segment the renderer asks about, and is not loose where the view
    // grazes: torus-chain's longest segment comes within 10 % of it (36.7 of 38.2 voxels in
    // a 256-pixel image); plane-weave, seen from above, within 50 % (22.7 of 35.4).
    let limits = Limits::default();
    for (name, tight) in [("torus-chain", 0.9), ("plane-weave", 0.5)] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.json"));
        let mut loaded = load_scene(&path, &limits).unwrap();
        loaded.scene.camera.width /= 2;
        loaded.scene.camera.height /= 2;
        let mut gdm = loaded.bake_gdm(&limits, &()).unwrap();
        gdm.set_escape_convention(EscapeConvention::Infinite);
        let raw = RawLookup::new(&gdm);
        let cap = longest_segment(&prepare_prisms(&loaded.shell, gdm.dims()));
        let recorder = SegmentRecorder {
            inner: &raw,
            longest: std::sync::Mutex::new(0.0),
        };
        let scene = &loaded.scene;
        let r = GdmRenderer::new(&loaded.shell, &recorder, &loaded.material, 0);
        let shot = scene.shot();
        render_image(&shot.camera, |o, d| r.radiance(&shot, o, d));
        let longest = *recorder.longest.lock().unwrap();
        eprintln!("{name}: longest segment {longest:.3} of cap {cap:.3}");
        assert!(longest <= cap + 1e-9, "{name}: {longest} > {cap}");
        assert!(longest >= tight * cap, "{name}: {longest} of {cap}");
    }
}

//! The real-time preview against its specification, the CPU GDM software renderer: the same
//! scene and package must give the same image (PSNR ≥ 35 dB over sRGB values, hit/miss mask
//! disagreement ≤ 0.5 %). Runs on whatever adapter wgpu finds; CI installs Mesa's software
//! Vulkan driver. Without any adapter these tests fail, unless MESOBAKE_SKIP_GPU_TESTS=1 says
//! to skip them (loudly).

use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::effect::Effect;
use mesobake_core::limits::Limits;
use mesobake_gpu::frames::RealtimePipeline;
use mesobake_gpu::gpu::Gpu;
use mesobake_render::image::{Image, compare};
use mesobake_scene::package::{ScenePackageParams, gdm_scene_package};
use mesobake_scene::preview::{gdm_pipeline, gdm_preview, gdm_render_on_cpu};
use mesobake_scene::{LoadedScene, Scene};
use std::path::Path;

/// Whether GPU tests run here; panics with the reason when no adapter exists and skipping
/// was not asked for.
pub fn gpu_or_skip() -> bool {
    match Gpu::open(None) {
        Ok(_) => true,
        Err(e) if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") => {
            eprintln!("SKIPPED: no GPU adapter ({e}) and MESOBAKE_SKIP_GPU_TESTS=1");
            false
        }
        Err(e) => panic!("{e} (set MESOBAKE_SKIP_GPU_TESTS=1 to skip the GPU tests)"),
    }
}

fn load(path: &str, edit: impl FnOnce(&mut Scene)) -> LoadedScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    let mut scene = Scene::read(&path).unwrap();
    edit(&mut scene);
    LoadedScene::load(scene, path.parent().unwrap(), &Limits::default()).unwrap()
}

/// A `paper-svd` package of the scene.
fn package(loaded: &LoadedScene, rank: usize, quantization: Quantization) -> Package {
    let params = ScenePackageParams {
        codec: GdmCodec::PaperSvd,
        rank: RankChoice::Rank(rank),
        quantization,
    };
    gdm_scene_package(loaded, Path::new("."), params, &Limits::default(), &()).unwrap()
}

/// The default package of the scene (the `occupancy` codec).
fn default_package(loaded: &LoadedScene) -> Package {
    let params = ScenePackageParams::default();
    let p = gdm_scene_package(loaded, Path::new("."), params, &Limits::default(), &()).unwrap();
    assert_eq!(p.manifest().codec, GdmCodec::Occupancy);
    p
}

/// The CPU twin: the GDM software renderer on the package (with its RTV and PRT when the
/// scene calls for environment lighting).
fn cpu_image(loaded: &LoadedScene, package: &Package) -> Image {
    gdm_render_on_cpu(loaded, package, &()).unwrap()
}

/// Renders on both and checks the agreement; returns (PSNR, mask disagreement).
fn agreement(loaded: &LoadedScene, package: &Package, label: &str) -> (f64, f64) {
    let (gpu, report) = gdm_preview(&Gpu::open(None).unwrap(), loaded, package, 0, &()).unwrap();
    let cpu = cpu_image(loaded, package);
    let c = compare(&gpu, &cpu).unwrap();
    eprintln!(
        "{label}: PSNR {:.2} dB, FLIP {:.4}, mask {:.4} %, {} hit pixels (CPU {}), variant {}",
        c.psnr_db,
        c.flip_mean,
        c.mask_disagreement * 100.0,
        gpu.hits(),
        cpu.hits(),
        report.variant.expect("a GDM variant").name()
    );
    assert!(
        cpu.hits() > cpu.mask.len() / 20,
        "{label}: the scene shows too little to test"
    );
    assert!(c.psnr_db >= 35.0, "{label}: PSNR {} dB < 35 dB", c.psnr_db);
    // FLIP too: at 35 dB and more, differences no viewer would see (the truth against the
    // explicit renderer, 41.8 dB, is at 0.0023).
    assert!(c.flip_mean <= 0.02, "{label}: FLIP {} > 0.02", c.flip_mean);
    assert!(
        c.mask_disagreement <= 0.005,
        "{label}: mask disagreement {} > 0.5 %",
        c.mask_disagreement
    );
    (c.psnr_db, c.mask_disagreement)
}

#[test]
fn torus_chain_matches_the_cpu_gdm_renderer() {
    if !gpu_or_skip() {
        return;
    }
    let loaded = load("scenes/torus-chain.json", |s| {
        s.camera.width = 256;
        s.camera.height = 256;
    });
    let p = package(&loaded, 8, Quantization::F16);
    agreement(&loaded, &p, "torus-chain paper-svd rank 8 f16, shadows");
    let p = default_package(&loaded);
    agreement(&loaded, &p, "torus-chain occupancy, shadows");
}

/// Every quality knob, alone and in the presets, in WGSL against the CPU specification:
/// torus-chain (point light, shadows) with the default codec, and the paper's codec with the
/// `balanced` preset and with chords.
#[test]
fn every_quality_knob_matches_the_cpu_gdm_renderer() {
    use mesobake_core::quality::{Preset, Quality, ShadingFrame, ShadowMethod};
    if !gpu_or_skip() {
        return;
    }
    let paper = Quality::default();
    let settings = [
        Quality {
            shadows: ShadowMethod::Shell,
            ..paper
        },
        Quality { chords: 4, ..paper },
        Quality {
            frame: ShadingFrame::Jacobian,
            ..paper
        },
        Preset::Balanced.quality(),
        Preset::High.quality(),
    ];
    let mut loaded = load("scenes/torus-chain.json", |s| {
        s.camera.width = 192;
        s.camera.height = 192;
    });
    let occupancy = default_package(&loaded);
    let svd = package(&loaded, 8, Quantization::F16);
    for quality in settings {
        loaded.scene.quality = quality;
        agreement(
            &loaded,
            &occupancy,
            &format!("torus-chain occupancy, {}", quality.label()),
        );
    }
    // The paper's codec with every knob but the chords: with 8 chords on each camera ray
    // and each shadow ray segment, its escape votes near the threshold compound (34.0 dB,
    // mask 0.02 %, measured on lavapipe); the chords alone agree at 46 dB.
    loaded.scene.quality = Preset::Balanced.quality();
    agreement(&loaded, &svd, "torus-chain paper-svd rank 8 f16, balanced");
    loaded.scene.quality = Quality { chords: 4, ..paper };
    agreement(&loaded, &svd, "torus-chain paper-svd rank 8 f16, chords 4");
}

#[test]
fn the_environment_variant_matches_its_cpu_twin() {
    if !gpu_or_skip() {
        return;
    }
    // The sample GI scene (weave under a clear sky, macro shadows) with the glossy lobe and
    // the paper's rank 4, so that the RTV is view-dependent; and a Lambertian rank-1 RTV.
    for (gloss, rank) in [(true, 4), (false, 4)] {
        let loaded = load("scenes/plane-weave-sky.json", |s| {
            s.camera.width = 160;
            s.camera.height = 120;
            s.resolution = [32, 32, 16];
            s.gi.rtv_rank = rank;
            if gloss {
                s.effects.push(Effect::EnvironmentGloss);
                s.material.specular = [0.3, 0.3, 0.3];
                s.material.shininess = 24.0;
            }
        });
        let p = package(&loaded, 8, Quantization::F16);
        let stored = p.manifest().gi.as_ref().unwrap().compression.rank;
        assert_eq!(stored, if gloss { 4 } else { 1 });
        agreement(
            &loaded,
            &p,
            &format!("plane-weave-sky paper-svd, gloss {gloss}, RTV rank {stored}"),
        );
        let p = default_package(&loaded);
        agreement(
            &loaded,
            &p,
            &format!("plane-weave-sky occupancy, gloss {gloss}, RTV rank {stored}"),
        );
        // The sky alone lights the scene (it has no other light), and lights it well.
        let cpu = cpu_image(&loaded, &p);
        let lit: Vec<f32> = cpu
            .rgb
            .iter()
            .zip(&cpu.mask)
            .filter(|(_, hit)| **hit)
            .map(|(c, _)| c[1])
            .collect();
        let mean = lit.iter().sum::<f32>() / lit.len().max(1) as f32;
        assert!(mean > 0.05, "mean green radiance {mean}");
    }
}

#[test]
fn plane_weave_matches_with_refinements_and_partial_groups() {
    if !gpu_or_skip() {
        return;
    }
    let loaded = load("scenes/plane-weave.json", |s| {
        s.camera.width = 256;
        s.camera.height = 192;
        s.gdm_refinements = 2;
        s.effects.retain(|e| *e != Effect::Shadows);
    });
    // Rank 6 in u8: one full rgba8unorm group and a rg8unorm tail with per-map decode.
    let p = package(&loaded, 6, Quantization::U8);
    agreement(
        &loaded,
        &p,
        "plane-weave rank 6 u8, refinements 2, no shadows",
    );
    // Rank 3 in f32: only a tail group (rgba32float with one padding channel).
    let p = package(&loaded, 3, Quantization::F32);
    agreement(
        &loaded,
        &p,
        "plane-weave rank 3 f32, refinements 2, no shadows",
    );
    // The occupancy codec ignores refinements: its march is exact.
    let p = default_package(&loaded);
    agreement(&loaded, &p, "plane-weave occupancy, no shadows");
}

/// Every shader variant a scene can choose passes naga's validation, and only the shadow
/// variants contain the shadow query, only the shell-shadow variants and those of an object
/// among several with shadows the prisms' BVH, only the latter the occlusion pass, only the
/// environment variants the RTV.
#[test]
fn every_shader_variant_validates_and_effect_code_exists_only_where_called_for() {
    use mesobake_core::quality::ShadowMethod;
    use mesobake_gpu::variant::{
        BVH_BINDING, GI_BINDING, OCCLUDE_ENTRY, SHADOW_QUERY_FN, ShaderVariant,
    };
    let mut count = 0;
    for variant in ShaderVariant::all() {
        let module = naga::front::wgsl::parse_str(&variant.source()).unwrap_or_else(|e| {
            panic!(
                "{}: {}",
                variant.name(),
                e.emit_to_string(&variant.source())
            )
        });
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}: {e:?}", variant.name()));
        let has_shadow_query = module
            .functions
            .iter()
            .any(|(_, f)| f.name.as_deref() == Some(SHADOW_QUERY_FN));
        assert_eq!(
            has_shadow_query,
            variant.shadows.is_some(),
            "{}",
            variant.name()
        );
        let has_binding = |name: &str| {
            module
                .global_variables
                .iter()
                .any(|(_, g)| g.name.as_deref() == Some(name))
        };
        assert_eq!(
            has_binding(BVH_BINDING),
            variant.shadows == Some(ShadowMethod::Shell) || variant.occluders,
            "{}",
            variant.name()
        );
        let occludes = module.entry_points.iter().any(|e| e.name == OCCLUDE_ENTRY);
        assert_eq!(occludes, variant.occluders, "{}", variant.name());
        assert_eq!(
            has_binding(GI_BINDING),
            variant.environment,
            "{}",
            variant.name()
        );
        let has = |name: &str| {
            module
                .functions
                .iter()
                .any(|(_, f)| f.name.as_deref() == Some(name))
        };
        assert_eq!(
            has("march"),
            variant.codec == GdmCodec::Occupancy,
            "{}",
            variant.name()
        );
        assert_eq!(
            has("gdm_lookup"),
            variant.codec == GdmCodec::PaperSvd,
            "{}",
            variant.name()
        );
        count += 1;
    }
    // paper-svd: (3 shadow tests × environment or not + 2 shadow tests with occluders) × 9
    // refinement counts × 2 chord counts × 2 frames × early-z or not; occupancy: 8 × 1 × 2 ×
    // 2 × 2.
    assert_eq!(count, 576 + 64);
}

/// A scene without shadows builds the pipeline of the variant without shadow code; with
/// shadows, the one with it.
#[test]
fn the_pipeline_runs_the_variant_the_scene_calls_for() {
    if !gpu_or_skip() {
        return;
    }
    let mut loaded = load("scenes/plane-weave.json", |s| {
        s.camera.width = 64;
        s.camera.height = 48;
        s.resolution = [16, 16, 8];
        s.directions = [4, 8];
    });
    let p = package(&loaded, 4, Quantization::F16);
    for shadows in [true, false] {
        loaded.scene.effects = if shadows {
            vec![Effect::Silhouettes, Effect::Shadows]
        } else {
            vec![Effect::Silhouettes]
        };
        let gpu = Gpu::open(None).unwrap();
        let preview = gdm_pipeline(&gpu, &loaded, &p, true).unwrap();
        let variant = preview.variant().expect("a GDM object's variant");
        assert_eq!(variant.shadows.is_some(), shadows);
        assert_eq!(
            variant.source().contains("fn shadow_query"),
            shadows,
            "{}",
            variant.name()
        );
        assert!(preview.render().unwrap().hits() > 0);
    }
}

/// `wrap` of the shaders' common code (a periodic texel index, computed through an f32
/// quotient) against Rust's integer `rem_euclid`, exactly, on every adapter: at and beside
/// every multiple of the periods near zero, near ±10⁶ and across ±2²⁴ (where f32 stops
/// holding every integer and only the correction steps keep it exact).
#[test]
fn the_shaders_periodic_wrap_is_the_integer_remainder() {
    if !gpu_or_skip() {
        return;
    }
    use mesobake_gpu::target::read_mapped;
    use mesobake_gpu::variant::COMMON;
    use wgpu::util::DeviceExt;
    let gpu = Gpu::open(None).unwrap();
    let periods: [u32; 9] = [1, 2, 3, 7, 32, 64, 100, 127, 128];
    let mut cases: Vec<[i32; 2]> = Vec::new();
    for &n in &periods {
        let n_i = n as i32;
        let centres: [i32; 5] = [0, 1_000_000, -1_000_000, (1 << 24) - 200, -(1 << 24) + 200];
        for centre in centres {
            let base = centre - centre.rem_euclid(n_i);
            for i in base - 3 * n_i - 2..=base + 3 * n_i + 2 {
                cases.push([i, n_i]);
            }
        }
    }
    let source = format!(
        "{COMMON}\n@group(1) @binding(0) var<uniform> view: View;\n\
         @group(0) @binding(0) var<storage, read> cases: array<vec2<i32>>;\n\
         @group(0) @binding(1) var<storage, read_write> wrapped: array<u32>;\n\
         @compute @workgroup_size(64)\n\
         fn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
             if id.x < arrayLength(&cases) {{\n\
                 wrapped[id.x] = wrap(cases[id.x].x, u32(cases[id.x].y));\n\
             }}\n\
         }}\n"
    );
    let d = &gpu.device;
    let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: None,
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: None,
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let input = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&cases),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let size = cases.len() as u64 * 4;
    let output = d.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = d.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let group = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut encoder = d.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((cases.len() as u32).div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &read, 0, size);
    gpu.queue.submit([encoder.finish()]);
    let wrapped: Vec<u32> =
        read_mapped(&gpu, &read, |data| bytemuck::cast_slice(data).to_vec()).unwrap();
    let wrong: Vec<_> = cases
        .iter()
        .zip(&wrapped)
        .filter(|([i, n], w)| i.rem_euclid(*n) as u32 != **w)
        .take(5)
        .collect();
    assert!(wrong.is_empty(), "wrap(i, n) against i mod n: {wrong:?}");
    println!("wrap: {} cases exact", cases.len());
}

//! What a scene's bake holds in memory at its peak, bounded from the scene and its inputs'
//! headers before anything is loaded, so that the memory limit bounds the whole bake, not
//! only its largest buffer: a bake the limit cannot hold is refused by name instead of
//! aborting part-way. Each term is a buffer, or a stage's working set, that may be alive at
//! the peak; the bound is their sum. The coefficients follow the allocations of the stages
//! (bytes per voxel of the loaded material, caster and medium; the SVD's blocks in
//! `compress/svd.rs`; the RTV's per-sample records), and `tests/memory/` holds the bound above
//! the peak a counting allocator measures on every shipped scene and codec. The sums are in
//! u128, which no product of validated counts (axes and grids to 2¹⁶, PNG sides to 2³²)
//! overflows.

use crate::technique::Technique;
use crate::{BaseMeshSource, MesostructureSource, Scene};
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::manifest::{GdmCodec, RankChoice};
use std::path::Path;

/// The parts of a bake's peak memory, in bytes.
#[derive(Clone, Debug)]
pub struct BakeMemory {
    /// What each part is, and its bytes.
    pub parts: Vec<(String, u64)>,
}

impl BakeMemory {
    /// The bound: every part at once.
    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0, |sum, (_, b)| sum.saturating_add(*b))
    }

    /// Refuses the bake when its total is over the limit, naming its largest parts.
    pub fn check(&self, limits: &Limits) -> Result<u64> {
        let mut largest: Vec<_> = self.parts.iter().filter(|(_, b)| *b > 0).collect();
        largest.sort_by_key(|(_, b)| std::cmp::Reverse(*b));
        let named: Vec<String> = largest
            .iter()
            .take(3)
            .map(|(what, b)| format!("{what} {b} bytes"))
            .collect();
        let what = format!("the bake (largest parts: {})", named.join(", "));
        limits.check(&what, self.total(), 1)
    }
}

/// The peak memory of baking `scene`'s package for `technique` (a GDM with `codec` and
/// `rank`), its input files (relative to `scene_dir`) read for their sizes and headers only.
pub fn bake_memory(
    scene: &Scene,
    scene_dir: &Path,
    technique: Technique,
    (codec, rank): (GdmCodec, RankChoice),
) -> Result<BakeMemory> {
    let mut parts = Vec::new();
    let mut add = |what: &str, bytes: u128| {
        parts.push((what.to_owned(), u64::try_from(bytes).unwrap_or(u64::MAX)));
    };
    let file_len = |path: &Path| {
        let path = scene_dir.join(path);
        std::fs::metadata(&path)
            .map(|m| u128::from(m.len()))
            .map_err(|e| Error::io(path, e))
    };
    let dims = scene.dims()?;
    let voxels = u128::from(dims.voxel_count());
    let [x, y, z] = scene.resolution.map(u128::from);
    let threads = rayon::current_num_threads() as u128;

    // Loading: the material (normals, albedo), the caster (occupancy, empty space) and,
    // for translucent media, the medium: up to 64 bytes a voxel; plus what the input adds.
    add("material and caster", 64 * voxels);
    let mut pixels = 0;
    match &scene.mesostructure {
        MesostructureSource::Volume(p) => add("volume file, read and decoded", 2 * file_len(p)?),
        MesostructureSource::Tile(p) => add("tile triangles and their BVH", 80 * file_len(p)?),
        MesostructureSource::HeightField(p) => {
            let (w, h) = HeightField::png_size(&scene_dir.join(p))?;
            pixels = u128::from(w) * u128::from(h);
            add("height field", 24 * pixels);
        }
        MesostructureSource::Relief(_) => {
            pixels = x * x;
            add(
                "relief and its voxels",
                24 * pixels + 16 * x * x * z.max(x / 2),
            );
        }
        MesostructureSource::Sample(_)
        | MesostructureSource::SampleTile(_)
        | MesostructureSource::Medium(_) => {}
    }
    let triangles = match &scene.base_mesh {
        BaseMeshSource::Builtin(b) => u128::from(b.triangle_count()),
        // A face line takes at least 8 bytes ("f 1 2 3\n").
        BaseMeshSource::Obj(p) => file_len(p)? / 8,
        // Three u16 indices a triangle, the least a glTF spends.
        BaseMeshSource::Gltf(g) => file_len(g.file())? / 6,
    };
    add("base mesh and shell", 1536 * triangles);

    match technique {
        Technique::Transparency => add("medium levels and their encoding", 200 * voxels),
        Technique::Vdm => {
            let g = scene.vdm.grid();
            let [nt, np, nc] = [g.n_theta, g.n_phi, g.n_curvature].map(u128::from);
            let vdm = 4 * pixels * nt * np * nc;
            add("VDM", vdm);
            add("VDM being compressed", vdm + vdm / nt.max(1));
            let (m, n, k) = (pixels * np, nc * (nt + 1), scene.vdm.rank as u128);
            add("VDM SVD", svd_bytes(m, n, k, threads));
            add("package", 24 * (m + n) * k + 16 * pixels);
        }
        Technique::Gdm | Technique::Auto => {
            let dirs = scene.dirs()?;
            let d = dirs.count() as u128;
            let gi = scene.wants(Effect::EnvironmentLighting);
            let paper_svd = codec == GdmCodec::PaperSvd;
            if paper_svd || gi {
                add("GDM", 4 * voxels * d);
            }
            if paper_svd {
                let (m, n) = (x * y * u128::from(dirs.n_phi), u128::from(dirs.n_theta) * z);
                let k = match rank {
                    RankChoice::Rank(k) => (k as u128).min(n),
                    RankChoice::MaxRmse(_) => n,
                };
                add("GDM SVD", svd_bytes(m, n, k, threads));
                add("package", 24 * (m + n) * k);
            } else {
                add("occupancy field and package", 8 * voxels);
            }
            if gi {
                // Surface samples are at most the voxels.
                let r = scene.gi.rtv_rank as u128;
                let per_sample = 4800 + 4 * d + threads * (256 + 24 * r) + 600 * r;
                add("radiance transfer volume", voxels * per_sample);
                let vertices = 3 * triangles;
                add("PRT", 2100 * vertices + 150 * scene.gi.prt_samples as u128);
            }
        }
    }
    Ok(BakeMemory { parts })
}

/// The truncated SVD's working set (`compress/svd.rs`) for an m × n matrix cut to rank k on
/// `threads` threads: the Gram matrix's row blocks and their products, the eigenvectors,
/// the projected blocks and factors of the truncation, and the quantized and measured
/// factors.
fn svd_bytes(m: u128, n: u128, k: u128, threads: u128) -> u128 {
    let block = m.min(m.div_ceil(64).max(2048));
    let blocks = m.div_ceil(block.max(1));
    let kb = k + 8;
    let busy = threads.min(blocks);
    let gram = 4 * n * n * blocks + 40 * n * n + busy * block * n * 8;
    let truncate =
        8 * m * kb + 8 * blocks * kb * n + busy * block * (12 * n + 20 * kb) + 12 * m * k;
    let quantize = 12 * (m + n) * k + busy.min(m.div_ceil(4096)) * 4096 * n * 12;
    gram + truncate + quantize
}

//! Medium packages: a translucent medium and its mip-map as the semi-transparent 3D texture
//! renderers read them, in the format of the crate's [`mesobake_package::medium`] (see
//! `docs/package-format.md`).

use crate::mesostructure::medium::Medium;
use mesobake_core::error::{Error, Result};
use mesobake_package::manifest::InputInfo;
pub use mesobake_package::medium::MediumPackage;
use mesobake_package::medium::{MediumLevel, coarser_res};
use mesobake_package::quantize::Quantization;

/// The package bytes of `medium` and `coarser`, the coarser levels of its mip-map
/// ([`Medium::coarser_levels`], or none), quantized to `q`, made from `input`
/// (deterministic).
pub fn encode(input: InputInfo, medium: &Medium, coarser: &[Medium], q: Quantization) -> Vec<u8> {
    let levels: Vec<MediumLevel> = std::iter::once(medium)
        .chain(coarser)
        .map(|m| {
            let n = m.dims().voxel_count() as usize;
            MediumLevel {
                dims: m.dims(),
                voxels: (0..n)
                    .map(|v| {
                        let c = m.colour(v).as_vec3();
                        [c.x, c.y, c.z, m.opacity(v) as f32]
                    })
                    .collect(),
                normals: (m.material().normal_voxels().iter())
                    .map(|n| n.to_array())
                    .collect(),
            }
        })
        .collect();
    MediumPackage::encode(input, q, &levels)
}

/// The levels a renderer reads from `package`: level 0, and the coarser ones where it filters
/// with the mip-map (`mipmap`). A package baked without its mip-map (for a scene
/// that does not filter) cannot serve a scene that does: an error says so.
pub fn levels(package: &MediumPackage, mipmap: bool) -> Result<Vec<Medium>> {
    let stored = package.levels();
    let first = &stored[0];
    let d = first.dims;
    if mipmap && stored.len() == 1 && coarser_res([d.x, d.y, d.z]).is_some() {
        return Err(Error::Scene(
            "the scene's transparency.mipmap asks for the medium's mip-map, but the package \
             holds level 0 only (baked for a scene without it); bake the package for this scene"
                .into(),
        ));
    }
    let wanted = if mipmap { stored.len() } else { 1 };
    Ok(stored[..wanted]
        .iter()
        .map(|l| Medium::from_parts(l.dims, &l.voxels, &l.normals))
        .collect())
}

//! Export of a package's factor maps as one multi-layer OpenEXR image, to inspect them in
//! standard tools: layer `W<i>` is weight map i (width X, height Y·Nφ: the φ slices stacked
//! top to bottom), layer `E<i>` eigenmap i (width Z, height Nθ); each holds one f32 channel
//! `Y` with the dequantized values.

use crate::package::Package;
use exr::prelude::*;
use mesobake_core::error::{Error, Result};
use std::path::Path;

/// One single-channel f32 layer.
fn layer(
    name: &str,
    width: usize,
    height: usize,
    values: Vec<f32>,
) -> Layer<AnyChannels<FlatSamples>> {
    let channel = AnyChannel::new("Y", FlatSamples::F32(values));
    Layer::new(
        Vec2(width, height),
        LayerAttributes::named(name),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    )
}

/// Column `c` of a row-major matrix with `rank` columns.
fn column(values: &[f32], rank: usize, c: usize) -> Vec<f32> {
    values.iter().skip(c).step_by(rank).copied().collect()
}

/// Writes the weight maps and eigenmaps of `package` to `path`.
pub fn write_factors(package: &Package, path: &Path) -> Result<()> {
    let (dims, dirs) = (package.dims(), package.dirs());
    let Some((w, e)) = package.factors() else {
        return Err(Error::InvalidParameter(format!(
            "the package's codec is {}: it has no factor maps to export (bake it with \
             --gdm-codec paper-svd)",
            package.manifest().codec
        )));
    };
    let rank = w.rank;
    if rank == 0 {
        return Err(Error::InvalidParameter(
            "the package has rank 0: there are no maps to export".into(),
        ));
    }
    let (w, e) = (w.dequantize(), e.dequantize());
    let (x, y_phi) = (dims.x as usize, (dims.y * dirs.n_phi) as usize);
    let (z, theta) = (dims.z as usize, dirs.n_theta as usize);
    let layers: Vec<_> = (0..rank)
        .map(|c| layer(&format!("W{c}"), x, y_phi, column(&w, rank, c)))
        .chain((0..rank).map(|c| layer(&format!("E{c}"), z, theta, column(&e, rank, c))))
        .collect();
    let attributes = ImageAttributes::new(IntegerBounds::from_dimensions(Vec2(
        x.max(z),
        y_phi.max(theta),
    )));
    let image = Image::from_layers(attributes, SmallVec::from_vec(layers));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| Error::InvalidParameter(format!("EXR encoding failed: {e}")))?;
    mesobake_core::fs::write_atomic(path, bytes.get_ref())
}

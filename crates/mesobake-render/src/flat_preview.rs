//! A preview of a baked GDM on a flat base surface, rendered from the GDM alone.
//!
//! Orthographic camera looking along a grid direction `view` (cos θ < 0, into the surface)
//! over a few tiles. Per pixel: the ray meets the top plane z = Z, moves to the top layer's
//! centre plane, reads the GDM there ([`sample_layer`]); a hit gives the mesostructure
//! point, shaded Lambert with the albedo and the density gradient's normal, and shadowed when
//! the GDM towards the light (a grid direction) reports a hit; an escape shows the base surface.
//! The full renderer on curved base meshes comes with the scene format.

use mesobake_bake::gdm::Gdm;
use mesobake_bake::gdm::interpolate::sample_layer;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_core::error::{Error, Result};
use mesobake_package::grid::Wrap;

/// What to render.
#[derive(Clone, Copy, Debug)]
pub struct PreviewSetup {
    /// View direction bin (a, b) of the GDM's grid; must point into the surface.
    pub view: (u32, u32),
    /// Light direction bin (a, b) (towards the light); must point out of the surface.
    pub light: (u32, u32),
    /// Image width and height in pixels.
    pub size: u32,
    /// Tiles across the image.
    pub tiles: f64,
}

/// Renders an sRGB8 RGB image, `size`×`size`, row-major.
pub fn render(volume: &Volume, gdm: &Gdm, setup: &PreviewSetup) -> Result<Vec<u8>> {
    let dims = gdm.dims();
    let dirs = gdm.dirs();
    if volume.dims() != dims {
        return Err(Error::InvalidParameter(
            "preview: volume and GDM grids differ".into(),
        ));
    }
    let w = dirs.vector(setup.view.0, setup.view.1);
    let l = dirs.vector(setup.light.0, setup.light.1);
    if w[2] >= 0.0 || l[2] <= 0.0 {
        return Err(Error::InvalidParameter(
            "preview: the view must point into the surface and the light out of it".into(),
        ));
    }
    let occ = volume.occupancy();
    let albedo = volume.albedo();
    let stride = gdm.direction_stride();
    let layer = (dims.x * dims.y) as usize;
    let view_d = (setup.view.0 * dirs.n_phi + setup.view.1) as usize;
    let light_d = (setup.light.0 * dirs.n_phi + setup.light.1) as usize;
    let top_k = dims.z - 1;
    let top = &gdm.data()[view_d * stride + top_k as usize * layer..][..layer];
    let hlen = w[0].hypot(w[1]).max(1e-9);
    let h = [w[0] / hlen, w[1] / hlen];
    let r = [-h[1], h[0]];
    let span = setup.tiles * dims.x as f64;
    let px = span / setup.size as f64;
    let wrap = [Wrap::new(dims.x), Wrap::new(dims.y)];
    let voxel = |p: [f64; 3]| -> Option<(usize, usize, usize)> {
        let k = p[2].floor();
        if k < 0.0 || k >= dims.z as f64 {
            return None;
        }
        Some((
            wrap[0].apply(p[0].floor() as i64),
            wrap[1].apply(p[1].floor() as i64),
            k as usize,
        ))
    };
    let density = |p: [f64; 3]| -> f64 {
        voxel(p).map_or(0.0, |(i, j, k)| {
            occ.get(i as u32, j as u32, k as u32) as u8 as f64
        })
    };
    let mut image = Vec::with_capacity((setup.size * setup.size * 3) as usize);
    for y in 0..setup.size {
        for x in 0..setup.size {
            let (sx, sy) = ((x as f64 + 0.5) * px, (y as f64 + 0.5) * px / (-w[2]));
            let q = [r[0] * sx - h[0] * sy, r[1] * sx - h[1] * sy, dims.z as f64];
            let t0 = 0.5 / -w[2];
            let p = [q[0] + t0 * w[0], q[1] + t0 * w[1], q[2] + t0 * w[2]];
            let d = sample_layer(dims, top, [p[0], p[1]]);
            let rgb = if d.is_infinite() {
                [0.18, 0.18, 0.2]
            } else {
                let d = d as f64;
                let hit = [p[0] + d * w[0], p[1] + d * w[1], p[2] + d * w[2]];
                let inside = [
                    hit[0] + 0.3 * w[0],
                    hit[1] + 0.3 * w[1],
                    hit[2] + 0.3 * w[2],
                ];
                let base = match (albedo, voxel(inside)) {
                    (Some(a), Some((i, j, k))) => {
                        a[dims.index(i as u32, j as u32, k as u32)].map(|c| c as f64 / 255.0)
                    }
                    _ => [0.7, 0.7, 0.7],
                };
                let mut n = [0.0; 3];
                for (a, na) in n.iter_mut().enumerate() {
                    let mut e = [0.0; 3];
                    e[a] = 1.0;
                    let f =
                        |s: f64| density([hit[0] + s * e[0], hit[1] + s * e[1], hit[2] + s * e[2]]);
                    *na = f(-1.0) - f(1.0);
                }
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let n = if len > 0.0 {
                    n.map(|c| c / len)
                } else {
                    w.map(|c| -c)
                };
                let outside = [
                    hit[0] - 0.5 * w[0],
                    hit[1] - 0.5 * w[1],
                    hit[2] - 0.5 * w[2],
                ];
                let shadowed = voxel(outside).is_some_and(|(i, j, k)| {
                    let v = gdm.data()[light_d * stride + dims.index(i as u32, j as u32, k as u32)];
                    v > 0.0 && v.is_finite()
                });
                let lambert = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
                let light = 0.25 + 0.75 * lambert * if shadowed { 0.2 } else { 1.0 };
                base.map(|c| c * light)
            };
            image.extend(rgb.map(|c| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8));
        }
    }
    Ok(image)
}

/// Encodes an RGB8 image as PNG bytes.
pub fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .map_err(|e| Error::InvalidParameter(format!("PNG: {e}")))?;
    writer
        .write_image_data(rgb)
        .map_err(|e| Error::InvalidParameter(format!("PNG: {e}")))?;
    writer
        .finish()
        .map_err(|e| Error::InvalidParameter(format!("PNG: {e}")))?;
    Ok(out)
}

/// The default setup for `gdm`'s direction grid: looking about 40° off the normal, light from
/// the side.
pub fn default_setup(gdm: &Gdm) -> PreviewSetup {
    let dirs = gdm.dirs();
    PreviewSetup {
        view: (dirs.n_theta * 11 / 16, dirs.n_phi / 8),
        light: (dirs.n_theta * 4 / 16, dirs.n_phi * 5 / 8),
        size: 512,
        tiles: 3.0,
    }
}

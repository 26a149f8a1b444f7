//! Shading environment light at a GDM hit (the CPU twin of the GI shader): the incident SH
//! of the prism's three base vertices (PRT × environment), interpolated with the hit's
//! barycentric coordinates in texture space, dotted with the RTV's transfer towards the
//! viewer interpolated at the hit: the exact RTV of a bake, or the compressed one of a
//! package.
//!
//! The vertex frames (tangent along +u, bitangent, normal) stand in for the prism's texture
//! axes, which are orthonormal only where the mapping is conformal and voxels are cubic in
//! object space; directions in the RTV are texture-space directions.

use glam::{DVec2, DVec3};
use mesobake_bake::gi::compressed_rtv::CompressedRtv;
use mesobake_bake::gi::environment::RgbSh;
use mesobake_bake::gi::prt;
use mesobake_bake::gi::rtv::Rtv;
use mesobake_bake::gi::sh::{self, COEFFS, ShMatrix};
use mesobake_bake::surface::base_mesh::BaseMesh;
use mesobake_bake::surface::shell::Shell;

/// The transfer a [`GiShading`] reads.
pub enum Transfer {
    /// As baked.
    Exact(Rtv),
    /// As a package holds it.
    Compressed(CompressedRtv),
}

/// What the GI renderers need: the RTV, and the incident light per base vertex and prism.
pub struct GiShading {
    transfer: Transfer,
    /// Incident SH per base-mesh vertex, in its frame.
    incident: Vec<RgbSh>,
    /// Per prism: its base vertices and their texture coordinates (voxel units, x and y).
    prisms: Vec<([u32; 3], [DVec2; 3])>,
}

impl GiShading {
    /// Shading with `transfer` under the environment `light` (its SH projection), carried to
    /// each vertex of `base` by its macro-scale PRT matrix (`matrices`), over `shell`'s prisms.
    pub fn new(
        transfer: Transfer,
        matrices: &[ShMatrix],
        light: &RgbSh,
        shell: &Shell,
        base: &BaseMesh,
    ) -> GiShading {
        let incident = matrices.iter().map(|m| prt::incident(m, light)).collect();
        let d = match &transfer {
            Transfer::Exact(r) => r.dims(),
            Transfer::Compressed(r) => r.dims(),
        };
        let scale = DVec2::new(d.x as f64, d.y as f64);
        let prisms = shell
            .prisms
            .iter()
            .map(|p| {
                let vertices = base.triangles[p.triangle as usize];
                (vertices, p.uv.map(|uv| uv * scale))
            })
            .collect();
        GiShading {
            transfer,
            incident,
            prisms,
        }
    }

    /// Incident SH per base-mesh vertex (per channel, in the vertex frame).
    pub fn incident(&self) -> &[RgbSh] {
        &self.incident
    }

    /// Per prism: its base vertices and their texture coordinates (voxel units, x and y).
    pub fn prisms(&self) -> &[([u32; 3], [DVec2; 3])] {
        &self.prisms
    }

    /// The environment light leaving the hit at texture point `texture` (voxel units) of
    /// prism `prism`, reached along texture direction `view` (RGB radiance). A GDM hit can
    /// lie up to a voxel inside the solid, beyond the reach of the samples' interpolation;
    /// the RTV is then read up to [`MAX_BACKOFF`] voxels back along the view, and the hit is
    /// black only when no sample is found there.
    pub fn radiance(&self, prism: usize, texture: DVec3, view: DVec3) -> DVec3 {
        let (vertices, uv) = self.prisms[prism];
        // The RTV is indexed by the direction towards the viewer.
        let towards_eye = (-view).normalize_or(DVec3::Z);
        let Some(transfer) = (0..=MAX_BACKOFF_STEPS).find_map(|step| {
            let back = MAX_BACKOFF * f64::from(step) / f64::from(MAX_BACKOFF_STEPS);
            let t = texture - view * back;
            match &self.transfer {
                Transfer::Exact(r) => r.interpolate(t, towards_eye),
                Transfer::Compressed(r) => r.interpolate(t, towards_eye),
            }
        }) else {
            return DVec3::ZERO;
        };
        let b = barycentric(uv, texture.truncate());
        let mut out = [0.0; 3];
        for (c, out) in out.iter_mut().enumerate() {
            let mut light = [0.0; COEFFS];
            for (v, w) in vertices.iter().zip(b) {
                let inc = &self.incident[*v as usize][c];
                light.iter_mut().zip(inc).for_each(|(l, i)| *l += w * i);
            }
            *out = sh::dot(&transfer[c], &light).max(0.0);
        }
        DVec3::from(out)
    }
}

/// How far back along the view, in voxels, a hit looks for RTV samples.
pub const MAX_BACKOFF: f64 = 1.5;

/// The back-off is tried in this many equal steps after the hit itself.
const MAX_BACKOFF_STEPS: u32 = 3;

/// Barycentric coordinates of `p` in triangle `t` (extrapolated outside, clamped to [0, 1]
/// and renormalized; the centroid for a degenerate triangle).
fn barycentric(t: [DVec2; 3], p: DVec2) -> [f64; 3] {
    let (e1, e2, q) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let det = e1.perp_dot(e2);
    if det.abs() < 1e-300 || !det.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let (b1, b2) = (q.perp_dot(e2) / det, e1.perp_dot(q) / det);
    let b = [1.0 - b1 - b2, b1, b2].map(|v| v.clamp(0.0, 1.0));
    let sum: f64 = b.iter().sum();
    b.map(|v| v / sum)
}

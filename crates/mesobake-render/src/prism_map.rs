//! The prism mapping as the per-pixel algorithm's accuracy knobs evaluate it (the
//! specification of the same functions in `shaders/gdm_preview.wgsl`), read from a prepared
//! prism's top and bottom face triangles, which is all the shaders receive:
//! P(b₁, b₂, w) = Σ bᵢ (Bᵢ + w·Eᵢ) with b₀ = 1 − b₁ − b₂, and texture coordinates
//! T = (Σ bᵢ·uvᵢ, w·Z) in voxel units, affine in (b₁, b₂, w).
//!
//! - [`PrismMap::texture_of`]: the exact inverse mapping of an object-space point, by a fixed
//!   number of Newton steps on P(b₁, b₂, w) = p from a texture-space guess (the chord knob;
//!   `surface::shell::Prism::locate` solves the same equation through the roots of a cubic
//!   in w, the independent reference of the tests).
//! - [`PrismMap::jacobian`]: ∂P/∂T at a texture coordinate (the frame knob).

use super::prepared_prism::PreparedPrism;
use glam::{DMat3, DVec2, DVec3};

/// Newton steps of the inverse mapping. The guess lies on the straight texture-space segment,
/// within a fraction of a prism of the answer, and convergence is quadratic: three steps
/// reach round-off on the test shells (the tests hold it to 1e-6 voxel against the cubic).
pub const NEWTON_STEPS: u32 = 3;

/// A prism's mapping (object coordinates relative to B₀).
#[derive(Clone, Copy, Debug)]
pub struct PrismMap {
    /// B₀.
    origin: DVec3,
    /// B₁ − B₀, B₂ − B₀.
    edges: [DVec3; 2],
    /// E₀ and E₁ − E₀, E₂ − E₀.
    extrusion: DVec3,
    extrusion_edges: [DVec3; 2],
    /// uv₀ (voxel units) and the inverse of [uv₁ − uv₀, uv₂ − uv₀].
    uv0: DVec2,
    uv_edges: [DVec2; 2],
    uv_inverse: [[f64; 2]; 2],
    /// The volume's depth Z in voxels.
    depth: f64,
}

impl PrismMap {
    /// The mapping of `prism`: B from its bottom face (corners 0, 2, 1), B + E and uv from its
    /// top face. `None` where the UV triangle has no area.
    pub fn new(prism: &PreparedPrism) -> Option<PrismMap> {
        let top = &prism.faces[0].triangle;
        let bottom = &prism.faces[1].triangle.corners;
        let b = [bottom[0], bottom[2], bottom[1]];
        let e = [0, 1, 2].map(|i| top.corners[i] - b[i]);
        let uv = top.texture.map(|t| t.truncate());
        let uv_edges = [uv[1] - uv[0], uv[2] - uv[0]];
        let det = uv_edges[0].perp_dot(uv_edges[1]);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let [u1, u2] = uv_edges;
        Some(PrismMap {
            origin: b[0],
            edges: [b[1] - b[0], b[2] - b[0]],
            extrusion: e[0],
            extrusion_edges: [e[1] - e[0], e[2] - e[0]],
            uv0: uv[0],
            uv_edges,
            uv_inverse: [[u2.y / det, -u2.x / det], [-u1.y / det, u1.x / det]],
            depth: top.texture[0].z,
        })
    }

    /// (b₁, b₂, w) of texture coordinate `t`.
    fn coordinates(&self, t: DVec3) -> DVec3 {
        let r = t.truncate() - self.uv0;
        let m = &self.uv_inverse;
        DVec3::new(
            m[0][0] * r.x + m[0][1] * r.y,
            m[1][0] * r.x + m[1][1] * r.y,
            t.z / self.depth,
        )
    }

    /// The texture coordinate of (b₁, b₂, w).
    fn texture(&self, c: DVec3) -> DVec3 {
        (self.uv0 + self.uv_edges[0] * c.x + self.uv_edges[1] * c.y).extend(c.z * self.depth)
    }

    /// P(b₁, b₂, w) − B₀ and ∂P/∂(b₁, b₂, w).
    fn point_and_derivative(&self, c: DVec3) -> (DVec3, DMat3) {
        let [e1, e2] = self.edges;
        let [f1, f2] = self.extrusion_edges;
        let d1 = e1 + f1 * c.z;
        let d2 = e2 + f2 * c.z;
        let dw = self.extrusion + f1 * c.x + f2 * c.y;
        (
            self.extrusion * c.z + d1 * c.x + d2 * c.y,
            DMat3::from_cols(d1, d2, dw),
        )
    }

    /// The texture coordinate of object point `p`: [`NEWTON_STEPS`] Newton steps on
    /// P(b₁, b₂, w) = p from the texture coordinate `guess`. Where a step meets a singular
    /// Jacobian the last estimate stands.
    pub fn texture_of(&self, p: DVec3, guess: DVec3) -> DVec3 {
        let target = p - self.origin;
        let mut c = self.coordinates(guess);
        for _ in 0..NEWTON_STEPS {
            let (q, j) = self.point_and_derivative(c);
            let det = j.determinant();
            if det == 0.0 || !det.is_finite() {
                break;
            }
            c -= j.inverse() * (q - target);
        }
        self.texture(c)
    }

    /// ∂P/∂T at texture coordinate `t` (object units per voxel), or `None` where it is
    /// singular.
    pub fn jacobian(&self, t: DVec3) -> Option<DMat3> {
        let (_, j) = self.point_and_derivative(self.coordinates(t));
        // ∂(b₁, b₂, w)/∂T: the inverse UV matrix and 1/Z.
        let m = &self.uv_inverse;
        let dc = DMat3::from_cols(
            DVec3::new(m[0][0], m[1][0], 0.0),
            DVec3::new(m[0][1], m[1][1], 0.0),
            DVec3::new(0.0, 0.0, 1.0 / self.depth),
        );
        let jt = j * dc;
        let det = jt.determinant();
        (det != 0.0 && det.is_finite()).then_some(jt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prepared_prism::prepare_prisms;
    use mesobake_bake::surface::base_mesh::BuiltinMesh;
    use mesobake_bake::surface::shell::{PrismPoint, Shell, ShellParams};
    use mesobake_package::grid::Dims;

    /// A coarse torus with a thick shell (strong curvature across each prism), the shell's
    /// prisms and the same prisms prepared on a 64×64×32 grid.
    fn torus() -> (Shell, Vec<PreparedPrism>, DVec3) {
        let mesh = BuiltinMesh::Torus {
            major_radius: 1.0,
            minor_radius: 0.4,
            segments: [24, 12],
        };
        let (base, _) = mesh.build().unwrap();
        let params = ShellParams {
            thickness: 0.15,
            tiles_per_uv: [6.0, 3.0],
            smoothing: 0,
        };
        let shell = Shell::new(&base, params).unwrap();
        let dims = Dims::new(64, 64, 32).unwrap();
        let prepared = prepare_prisms(&shell, dims);
        (shell, prepared, DVec3::new(64.0, 64.0, 32.0))
    }

    /// Points spread over each prism: barycentric coordinates on a grid, heights 0 to 1.
    fn points() -> Vec<PrismPoint> {
        let mut out = Vec::new();
        for (i, j) in [(1, 1), (4, 1), (1, 4), (2, 2), (0, 0), (6, 0)] {
            for w in [0.0, 0.3, 0.7, 1.0] {
                let (b1, b2) = (i as f64 / 6.0, j as f64 / 6.0);
                out.push(PrismPoint {
                    bary: [1.0 - b1 - b2, b1, b2],
                    w,
                });
            }
        }
        out
    }

    #[test]
    fn newton_inverse_matches_the_cubic_inverse() {
        // Reference: the point's own prism coordinates (what `Prism::locate` recovers through
        // the cubic's roots, checked here too), against Newton from a guess 3 voxels off in
        // every coordinate, farther than a chord's guess strays on the scene shells.
        let (shell, prepared, scale) = torus();
        let mut worst = 0.0f64;
        for (prism, prep) in shell.prisms.iter().zip(&prepared) {
            let map = PrismMap::new(prep).unwrap();
            for q in points() {
                let p = prism.point(q);
                let exact = prism.texture(q) * scale;
                let located = prism.locate(p, 1e-9, None).unwrap();
                assert!((prism.texture(located) * scale - exact).length() < 1e-6);
                let got = map.texture_of(p, exact + DVec3::splat(3.0));
                worst = worst.max((got - exact).length());
            }
        }
        // Three quadratic steps from 3 voxels: round-off (1e-6 voxel).
        assert!(worst < 1e-6, "worst Newton error {worst} voxels");
    }

    #[test]
    fn jacobian_matches_the_shells_and_central_differences() {
        let (shell, prepared, scale) = torus();
        let mut worst = 0.0f64;
        for (prism, prep) in shell.prisms.iter().zip(&prepared) {
            let map = PrismMap::new(prep).unwrap();
            for q in points() {
                let t = prism.texture(q) * scale;
                let j = map.jacobian(t).unwrap();
                // The shell's own Jacobian (tile units), rescaled to voxels.
                let reference = prism.jacobian(q).unwrap() * DMat3::from_diagonal(scale.recip());
                worst = worst.max(
                    (j - reference)
                        .abs()
                        .to_cols_array()
                        .iter()
                        .fold(0.0f64, |m, &x| m.max(x)),
                );
                // A third, plainer reference: central differences of P along each texture
                // axis (the mapping is quadratic, so they are exact up to round-off).
                let h = 1e-3;
                for axis in 0..3 {
                    let step = DVec3::AXES[axis] * h;
                    let at = |t: DVec3| {
                        let r = t / scale;
                        let c = prism.point_at_texture(r).unwrap();
                        prism.point(c)
                    };
                    let diff = (at(t + step) - at(t - step)) / (2.0 * h);
                    assert!(
                        (diff - j.col(axis)).length() < 1e-9,
                        "{diff} vs {}",
                        j.col(axis)
                    );
                }
            }
        }
        assert!(worst < 1e-12, "worst Jacobian difference {worst}");
    }
}

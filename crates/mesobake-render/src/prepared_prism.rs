//! The shell's prisms as the per-pixel algorithms receive them (and the shaders, per prism):
//! each face's object-space triangle with texture coordinates in voxel units and its plane,
//! the fins' convexity and the prism's object-to-texture frame.

use glam::{DMat3, DVec3};
use mesobake_bake::surface::shell::{FaceTriangle, Shell};
use mesobake_package::grid::Dims;

/// A face triangle with its texture coordinates in voxel units and its plane.
#[derive(Clone, Copy, Debug)]
pub struct PreparedFace {
    /// Object-space corners and texture coordinates (voxel units).
    pub triangle: FaceTriangle,
    /// Unit outward normal.
    pub normal: DVec3,
    /// n·x on the plane.
    pub offset: f64,
}

/// A prism prepared for the per-pixel algorithm (what the shaders receive per prism).
#[derive(Clone, Debug)]
pub struct PreparedPrism {
    /// Top, bottom, then the two triangles of fins 0, 1, 2.
    pub faces: [PreparedFace; 8],
    /// Whether each fin is convex.
    pub convex: [bool; 3],
    /// Object → texture (voxel units).
    pub frame: DMat3,
}

impl PreparedPrism {
    /// The bounding box (min, max) of the prism's six corners, which holds the prism.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let corners = self.faces[0]
            .triangle
            .corners
            .iter()
            .chain(&self.faces[1].triangle.corners);
        let lo = corners.clone().fold(DVec3::INFINITY, |a, &c| a.min(c));
        let hi = corners.fold(DVec3::NEG_INFINITY, |a, &c| a.max(c));
        (lo, hi)
    }
}

/// The prisms of `shell` prepared for a GDM on the voxel grid `dims`.
pub fn prepare_prisms(shell: &Shell, dims: Dims) -> Vec<PreparedPrism> {
    let scale = DVec3::new(dims.x as f64, dims.y as f64, dims.z as f64);
    shell
        .prisms
        .iter()
        .map(|p| PreparedPrism {
            faces: p.faces().map(|f| {
                let triangle = FaceTriangle {
                    corners: f.corners,
                    texture: f.texture.map(|t| t * scale),
                };
                let normal = triangle.normal().normalize_or_zero();
                PreparedFace {
                    triangle,
                    normal,
                    offset: normal.dot(f.corners[0]),
                }
            }),
            convex: p.fins.map(|f| f.convex),
            frame: DMat3::from_diagonal(scale) * p.to_texture,
        })
        .collect()
}

/// The longest texture-space segment (voxel units) a fragment of any of `prisms` can have.
/// In texture space a prism is the convex hull of its six corners (its base triangle's texture
/// coordinates at w = 0 and w = Z), a fragment's segment joins two points of its boundary,
/// so no segment is longer than the largest distance between two corners.
pub fn longest_segment(prisms: &[PreparedPrism]) -> f64 {
    let mut longest = 0.0f64;
    for p in prisms {
        let corners = p.faces.iter().flat_map(|f| f.triangle.texture);
        for a in corners.clone() {
            for b in corners.clone() {
                longest = longest.max(a.distance(b));
            }
        }
    }
    longest
}

/// Ray–triangle intersection (Möller–Trumbore in f64, edges inclusive so that rays through
/// shared edges and vertices hit at least one neighbour): ray parameter t > 0 and the
/// barycentric coordinates of the hit.
pub fn intersect(tri: &FaceTriangle, o: DVec3, d: DVec3) -> Option<(f64, [f64; 3])> {
    let [a, b, c] = tri.corners;
    let (e1, e2) = (b - a, c - a);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(pv) * inv;
    let qv = s.cross(e1);
    let v = d.dot(qv) * inv;
    const EDGE: f64 = 1e-12;
    if u < -EDGE || v < -EDGE || u + v > 1.0 + EDGE {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0).then_some((t, [1.0 - u - v, u, v]))
}

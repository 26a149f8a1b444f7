//! Macro-scale precomputed radiance transfer: per base-mesh vertex, the 16×16 matrix T that
//! maps the environment's SH coefficients (world space) to the SH coefficients of the light
//! arriving at the vertex, expressed in the vertex's texture frame (tangent along +u, bitangent,
//! normal = +z: the mesostructure's own axes, in which the RTV is baked).
//!
//! Tᵢⱼ = ∫ yᵢ(ω)·V(Fω)·yⱼ(Fω) dω over local directions ω, F the frame (local → world) and
//! V the base mesh's visibility from the vertex (1 where a ray escapes the mesh). Directions
//! below the surface see the mesh's own back side, so V is 0 there on closed meshes and on
//! open ones alike (the ray starts just above the surface and the surface is opaque from both
//! sides).
//! - **Shadowed** (the scene calls for macro-scale shadows): V by ray casting with obvhs, on a
//!   product quadrature of about `samples` directions ([`Quadrature::with_about`]); the error
//!   against sample count is measured by `mesobake report prt`.
//! - **Unshadowed** (no macro-scale shadows): V ≡ 1, so T is the pure rotation into the frame,
//!   [`sh::rotation_matrix`]`(Fᵀ)`. Light from below the tangent plane then reaches the vertex
//!   in the SH; the RTV blocks it, since a ray that leaves the mesostructure through its bottom
//!   meets the opaque base surface.

use super::sh::{self, COEFFS, Quadrature, ShMatrix};
use crate::surface::base_mesh::BaseMesh;
use glam::{DMat3, DVec2, DVec3, Vec3A};
use mesobake_core::error::{Error, Result};
use obvhs::{
    BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, ray::Ray,
    triangle::Triangle,
};
use rayon::prelude::*;
use std::time::Duration;

/// Per-vertex transfer matrices and frames.
#[derive(Clone, Debug)]
pub struct Transfer {
    /// Local → world frame of each vertex: columns tangent (+u), bitangent, normal.
    pub frames: Vec<DMat3>,
    /// Each vertex's 16×16 transfer matrix.
    pub matrices: Vec<ShMatrix>,
}

/// How the transfer is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Visibility {
    /// No macro-scale shadows: the pure rotation into the vertex frame.
    Unshadowed,
    /// Base-mesh self-shadowing, integrated over about this many directions.
    Shadowed {
        /// Quadrature directions per vertex.
        samples: usize,
    },
}

/// Distance above the surface at which visibility rays start, relative to the mesh's
/// bounding-box diagonal (f32 traversal stays clear of the vertex's own triangles).
const RAY_OFFSET: f64 = 1e-4;

/// The vertex frames of `mesh`: the normal, and the tangent along ∂P/∂u (area-weighted over
/// the vertex's triangles, made orthogonal to the normal; any perpendicular where the UVs
/// give none).
pub fn vertex_frames(mesh: &BaseMesh) -> Vec<DMat3> {
    let mut tangents = vec![DVec3::ZERO; mesh.positions.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (d1, d2): (DVec2, DVec2) = (mesh.uvs[b] - mesh.uvs[a], mesh.uvs[c] - mesh.uvs[a]);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() < 1e-300 {
            continue;
        }
        // ∂P/∂u, times the triangle's UV area (det) so larger triangles count more; the sign
        // of det is divided out so that flipped UVs still point along +u.
        let dpdu = (e1 * d2.y - e2 * d1.y) * det.signum();
        if dpdu.is_finite() {
            for v in [a, b, c] {
                tangents[v] += dpdu;
            }
        }
    }
    mesh.normals
        .iter()
        .zip(tangents)
        .map(|(&n, t)| {
            let n = n.normalize_or(DVec3::Z);
            let t = (t - n * n.dot(t))
                .try_normalize()
                .unwrap_or_else(|| n.any_orthonormal_vector());
            DMat3::from_cols(t, n.cross(t), n)
        })
        .collect()
}

/// The transfer of every vertex of `mesh`.
pub fn transfer(mesh: &BaseMesh, visibility: Visibility) -> Result<Transfer> {
    let frames = vertex_frames(mesh);
    let matrices = match visibility {
        Visibility::Unshadowed => frames
            .iter()
            .map(|f| sh::rotation_matrix(f.transpose()))
            .collect(),
        Visibility::Shadowed { samples } => {
            if !(16..=1 << 20).contains(&samples) {
                return Err(Error::InvalidParameter(format!(
                    "PRT samples must be 16–{}, got {samples}",
                    1 << 20
                )));
            }
            let occluder = Occluder::new(mesh);
            let quadrature = Quadrature::with_about(samples);
            frames
                .par_iter()
                .zip(&mesh.positions)
                .map(|(&frame, &p)| {
                    let origin = p + frame.z_axis * occluder.offset;
                    sh::transfer_matrix(&quadrature, frame, |d| {
                        let world = frame * d;
                        if occluder.blocked(origin, world) {
                            0.0
                        } else {
                            1.0
                        }
                    })
                })
                .collect()
        }
    };
    Ok(Transfer { frames, matrices })
}

/// The base mesh as an occluder for visibility rays (opaque from both sides).
pub struct Occluder {
    bvh: CwBvh,
    tris: Vec<Triangle>,
    /// How far above the surface rays start.
    offset: f64,
}

impl Occluder {
    /// A BVH over `mesh`'s triangles.
    pub fn new(mesh: &BaseMesh) -> Occluder {
        let (lo, hi) = mesh.bounds();
        let to_f32 = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
        let tris: Vec<Triangle> = mesh
            .triangles
            .iter()
            .map(|t| Triangle {
                v0: to_f32(mesh.positions[t[0] as usize]),
                v1: to_f32(mesh.positions[t[1] as usize]),
                v2: to_f32(mesh.positions[t[2] as usize]),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        // Traversal reports positions in the BVH's primitive order.
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        Occluder {
            bvh,
            tris,
            offset: RAY_OFFSET * (hi - lo).length().max(f64::MIN_POSITIVE),
        }
    }

    /// Whether the ray `origin + t·dir`, t > 0, meets the mesh.
    pub fn blocked(&self, origin: DVec3, dir: DVec3) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let ray = Ray::new_inf(
            Vec3A::new(origin.x as f32, origin.y as f32, origin.z as f32),
            Vec3A::new(dir.x as f32, dir.y as f32, dir.z as f32),
        );
        let mut hit = false;
        self.bvh.ray_traverse_anyhit(ray, |r, id| {
            if self.tris[id].intersect(r) < f32::INFINITY {
                hit = true;
            }
        });
        hit
    }
}

/// The incident-light SH (per channel) at a vertex: its transfer matrix times the environment.
pub fn incident(matrix: &ShMatrix, environment: &[[f64; COEFFS]; 3]) -> [[f64; COEFFS]; 3] {
    environment.map(|e| sh::apply(matrix, &e))
}

/// BLAKE3 of `mesh`'s geometry (positions, normals, texture coordinates and triangles, as
/// little-endian bytes), lowercase hex: the identity a package records for its PRT.
pub fn geometry_hash(mesh: &BaseMesh) -> String {
    let mut hasher = blake3::Hasher::new();
    for v in mesh.positions.iter().chain(&mesh.normals) {
        for c in v.to_array() {
            hasher.update(&c.to_le_bytes());
        }
    }
    for uv in &mesh.uvs {
        for c in uv.to_array() {
            hasher.update(&c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            hasher.update(&i.to_le_bytes());
        }
    }
    hasher.finalize().to_hex().to_string()
}

//! The parametric grid that the built-in base meshes and the teapot's patches are
//! tessellated on.

use super::BaseMesh;
use glam::{DVec2, DVec3};

/// The (nu + 1)·(nv + 1) vertices `vertex(i, j)` (position, normal) with UVs (i/nu, j/nv),
/// row j after row j − 1, and two triangles per quad, counter-clockwise in UV space. With
/// `pole_at_v0` the row j = 0 is a single point and each of its quads gives only the triangle
/// that is not zero-area.
pub(super) fn grid(
    nu: u32,
    nv: u32,
    pole_at_v0: bool,
    vertex: impl Fn(u32, u32) -> (DVec3, DVec3),
) -> BaseMesh {
    let mut mesh = BaseMesh::empty();
    let count = (nu as usize + 1) * (nv as usize + 1);
    mesh.positions.reserve(count);
    mesh.normals.reserve(count);
    mesh.uvs.reserve(count);
    for j in 0..=nv {
        for i in 0..=nu {
            let (p, n) = vertex(i, j);
            mesh.positions.push(p);
            mesh.normals.push(n);
            mesh.uvs.push(DVec2::new(
                f64::from(i) / f64::from(nu),
                f64::from(j) / f64::from(nv),
            ));
        }
    }
    let index = |i: u32, j: u32| j * (nu + 1) + i;
    mesh.triangles.reserve(2 * nu as usize * nv as usize);
    for j in 0..nv {
        for i in 0..nu {
            let (a, b) = (index(i, j), index(i + 1, j));
            let (c, d) = (index(i + 1, j + 1), index(i, j + 1));
            if !(pole_at_v0 && j == 0) {
                mesh.triangles.push([a, b, c]);
            }
            mesh.triangles.push([a, c, d]);
        }
    }
    mesh
}

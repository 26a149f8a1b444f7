//! glTF 2.0 base meshes (`.gltf` with embedded or external buffers, and `.glb`), read with the
//! `gltf` crate: every triangle primitive of the default scene (or of one material), with its
//! node transforms applied (world space, y up as glTF is), NORMAL where every primitive has
//! it (else computed), and a TEXCOORD set converted to the OBJ convention the shell uses
//! (glTF's v runs down the image: v = 1 − v_glTF). Strips and fans become triangles; points
//! and lines are refused by name, as are sparse accessors and byte ranges outside their
//! buffers (checked before anything is read).

use super::{BaseMesh, MeshReport};
use base64::Engine;
use glam::{DMat3, DMat4, DVec2, DVec3};
use gltf::mesh::Mode;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use std::path::Path;

/// Which primitives of a glTF file make the base mesh, and with which UV set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GltfSelection<'a> {
    /// Only the primitives of the material of this name (all when `None`).
    pub material: Option<&'a str>,
    /// The TEXCOORD set: 0 for TEXCOORD_0.
    pub texcoord: u32,
}

impl BaseMesh {
    /// Reads a glTF or GLB file (at most `limits.memory_bytes / 8` bytes, as an OBJ) and its
    /// external buffers (from the file's folder, each within the same bound), see
    /// [`BaseMesh::from_gltf`].
    pub fn read_gltf(
        path: &Path,
        selection: GltfSelection,
        limits: &Limits,
    ) -> Result<(BaseMesh, MeshReport)> {
        let bytes = mesobake_core::fs::read_bounded(path, "glTF file", limits.memory_bytes / 8)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Self::from_gltf(&bytes, Some(dir), selection, limits).map_err(|e| e.context(path.display()))
    }

    /// Parses glTF JSON or GLB `bytes`; external buffer files are read from `dir` (refused
    /// when it is `None`: an upload holds one file). Validated as [`BaseMesh::validated`].
    pub fn from_gltf(
        bytes: &[u8],
        dir: Option<&Path>,
        selection: GltfSelection,
        limits: &Limits,
    ) -> Result<(BaseMesh, MeshReport)> {
        let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| bad(format!("glTF: {e}")))?;
        let buffers = load_buffers(&gltf, dir, limits)?;
        let document = &gltf.document;
        let scene = document
            .default_scene()
            .or_else(|| document.scenes().next())
            .ok_or_else(|| bad("the glTF file has no scene".into()))?;
        let mut mesh = BaseMesh::empty();
        let mut normals_read = true;
        let mut materials_seen = Vec::new();
        let mut stack: Vec<(gltf::Node, DMat4)> =
            scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
        let mut visits = 0;
        while let Some((node, parent)) = stack.pop() {
            visits += 1;
            if visits > document.nodes().len() {
                return Err(bad(
                    "the scene's node hierarchy is not a tree (a cycle, or a node with two \
                     parents)"
                        .into(),
                ));
            }
            let world = parent * to_dmat4(node.transform().matrix());
            stack.extend(node.children().map(|c| (c, world)));
            let Some(gltf_mesh) = node.mesh() else {
                continue;
            };
            for primitive in gltf_mesh.primitives() {
                let material = primitive.material().name().unwrap_or("");
                materials_seen.push(material.to_owned());
                if selection.material.is_some_and(|m| m != material) {
                    continue;
                }
                let what = format!(
                    "primitive {} of mesh {:?}",
                    primitive.index(),
                    gltf_mesh.name().unwrap_or("")
                );
                let read = add_primitive(&mut mesh, &primitive, world, &buffers, selection)
                    .map_err(|e| bad(format!("{what}: {e}")))?;
                normals_read &= read;
            }
        }
        if mesh.triangles.is_empty() {
            return Err(match selection.material {
                Some(m) => {
                    materials_seen.sort();
                    materials_seen.dedup();
                    bad(format!(
                        "no primitive has the material {m:?} (the file's materials: {materials_seen:?})"
                    ))
                }
                None => bad("the glTF file's default scene has no triangles".into()),
            });
        }
        let mut mesh = welded(mesh);
        if !normals_read {
            mesh.compute_normals();
        }
        let (mesh, mut report) = mesh.validated()?;
        report.computed_normals = !normals_read;
        Ok((mesh, report))
    }
}

/// `mesh` with its vertices of bit-identical position, UV and normal made one, as an OBJ's
/// face vertices with the same `v/vt/vn` are: exporters write glTF vertices per corner or
/// per primitive, and the shell joins neighbouring prisms through shared vertices.
fn welded(mesh: BaseMesh) -> BaseMesh {
    let mut out = BaseMesh::empty();
    let mut index = std::collections::HashMap::new();
    let key = |i: usize| {
        let (p, t, n) = (mesh.positions[i], mesh.uvs[i], mesh.normals[i]);
        [p.x, p.y, p.z, t.x, t.y, n.x, n.y, n.z].map(|c| (c + 0.0).to_bits())
    };
    let remap: Vec<u32> = (0..mesh.positions.len())
        .map(|i| {
            *index.entry(key(i)).or_insert_with(|| {
                out.positions.push(mesh.positions[i]);
                out.uvs.push(mesh.uvs[i]);
                out.normals.push(mesh.normals[i]);
                out.positions.len() as u32 - 1
            })
        })
        .collect();
    out.triangles = (mesh.triangles.iter())
        .map(|t| t.map(|i| remap[i as usize]))
        .collect();
    out
}

/// A base-mesh error.
fn bad(message: String) -> Error {
    Error::BaseMesh(message)
}

/// glTF's column-major matrix in f64.
fn to_dmat4(m: [[f32; 4]; 4]) -> DMat4 {
    DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from)))
}

/// The bytes of every buffer: the GLB's binary chunk, a `data:` URI's, or a file beside the
/// document; each at least as long as it declares.
fn load_buffers(gltf: &gltf::Gltf, dir: Option<&Path>, limits: &Limits) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let name = format!("buffer {}", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| bad(format!("{name} refers to a GLB binary chunk there is not")))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, encoded) = uri
                    .split_once(";base64,")
                    .ok_or_else(|| bad(format!("{name}: a data URI that is not base64")))?;
                limits.check(&name, encoded.len() as u64 / 4 * 3, 1)?;
                base64::engine::general_purpose::STANDARD
                    .decode(encoded)
                    .map_err(|e| bad(format!("{name}: its data URI: {e}")))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let dir = dir.ok_or_else(|| {
                    bad(format!(
                        "{name} is the external file {uri:?}; an upload holds one file: \
                         export a .glb, or a .gltf with embedded buffers"
                    ))
                })?;
                let file = percent_encoding::percent_decode_str(uri)
                    .decode_utf8()
                    .map_err(|e| bad(format!("{name}: the URI {uri:?}: {e}")))?;
                if file.contains("..") || file.starts_with(['/', '\\']) || file.contains(':') {
                    return Err(bad(format!(
                        "{name}: the URI {uri:?} leaves the glTF file's folder"
                    )));
                }
                let path = dir.join(&*file);
                mesobake_core::fs::read_bounded(&path, &name, limits.memory_bytes / 8).map_err(
                    |e| match e {
                        Error::Io { source, .. } => bad(format!("{name}, {uri:?}: {source}")),
                        other => other,
                    },
                )?
            }
        };
        if (data.len() as u64) < buffer.length() as u64 {
            return Err(bad(format!(
                "{name} declares {} bytes but holds {}",
                buffer.length(),
                data.len()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

/// Refuses an accessor the reader would not read whole: sparse, without a buffer view, or
/// with bytes outside its view or the view outside its buffer.
fn check_accessor(accessor: &gltf::Accessor, buffers: &[Vec<u8>], what: &str) -> Result<()> {
    let bad_range = || {
        bad(format!(
            "the {what} accessor's bytes lie outside its buffer"
        ))
    };
    if accessor.sparse().is_some() {
        return Err(bad(format!(
            "the {what} accessor is sparse, which is not read"
        )));
    }
    let view = accessor
        .view()
        .ok_or_else(|| bad(format!("the {what} accessor has no buffer view")))?;
    let count = accessor.count();
    if count == 0 {
        return Err(bad(format!("the {what} accessor is empty")));
    }
    let size = accessor.size();
    let stride = view.stride().unwrap_or(size);
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(accessor.offset()))
        .and_then(|n| n.checked_add(size))
        .ok_or_else(bad_range)?;
    let view_end = view
        .offset()
        .checked_add(view.length())
        .ok_or_else(bad_range)?;
    let buffer = buffers.get(view.buffer().index()).ok_or_else(bad_range)?;
    if end > view.length() || view_end > buffer.len() {
        return Err(bad_range());
    }
    Ok(())
}

/// Appends `primitive`'s triangles under `world` to `mesh`; returns whether it had normals.
fn add_primitive(
    mesh: &mut BaseMesh,
    primitive: &gltf::Primitive,
    world: DMat4,
    buffers: &[Vec<u8>],
    selection: GltfSelection,
) -> Result<bool> {
    let mode = primitive.mode();
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Err(bad(format!(
            "its mode is {mode:?}; a base mesh is made of triangles"
        )));
    }
    let uv_name = format!("TEXCOORD_{}", selection.texcoord);
    let positions_accessor = primitive
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| bad("it has no POSITION".into()))?;
    let uv_accessor = primitive
        .get(&gltf::Semantic::TexCoords(selection.texcoord))
        .ok_or_else(|| bad(format!("it has no {uv_name}: the shell needs UVs")))?;
    check_accessor(&positions_accessor, buffers, "POSITION")?;
    check_accessor(&uv_accessor, buffers, &uv_name)?;
    let normal_accessor = primitive.get(&gltf::Semantic::Normals);
    if let Some(a) = &normal_accessor {
        check_accessor(a, buffers, "NORMAL")?;
    }
    if let Some(a) = primitive.indices() {
        check_accessor(&a, buffers, "indices")?;
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<DVec3> = reader
        .read_positions()
        .ok_or_else(|| bad("its POSITION cannot be read".into()))?
        .map(|p| world.transform_point3(DVec3::from(p.map(f64::from))))
        .collect();
    let count = positions.len();
    let uvs: Vec<DVec2> = reader
        .read_tex_coords(selection.texcoord)
        .ok_or_else(|| bad(format!("its {uv_name} cannot be read")))?
        .into_f32()
        .map(|[u, v]| DVec2::new(f64::from(u), 1.0 - f64::from(v)))
        .collect();
    if uvs.len() != count {
        return Err(bad(format!(
            "{count} positions but {} {uv_name} values",
            uvs.len()
        )));
    }
    let normal_matrix = DMat3::from_mat4(world).inverse().transpose();
    let normals: Option<Vec<DVec3>> = reader.read_normals().map(|n| {
        n.map(|n| normal_matrix * DVec3::from(n.map(f64::from)))
            .collect()
    });
    let read_normals = normals.as_ref().is_some_and(|n| n.len() == count);
    let indices: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..count as u32).collect(),
    };
    if let Some(&i) = indices.iter().find(|&&i| i as usize >= count) {
        return Err(bad(format!("index {i} is out of its {count} vertices")));
    }
    let mut triangles: Vec<[u32; 3]> = match mode {
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(k, w)| {
                if k % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..indices.len().saturating_sub(1))
            .map(|k| [indices[0], indices[k], indices[k + 1]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    };
    // A mirroring transform turns the winding around.
    if DMat3::from_mat4(world).determinant() < 0.0 {
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }
    let base = u32::try_from(mesh.positions.len() + count)
        .map(|end| end - count as u32)
        .map_err(|_| bad("more than 2³² vertices".into()))?;
    mesh.positions.extend(positions);
    mesh.uvs.extend(uvs);
    match normals.filter(|_| read_normals) {
        Some(n) => mesh.normals.extend(n),
        None => mesh.normals.resize(mesh.positions.len(), DVec3::ZERO),
    }
    mesh.triangles
        .extend(triangles.into_iter().map(|t| t.map(|i| i + base)));
    Ok(read_normals)
}

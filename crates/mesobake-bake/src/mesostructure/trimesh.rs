//! Indexed triangle meshes and their OBJ text form.

use mesobake_core::error::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

/// An indexed triangle mesh, counter-clockwise triangles facing outward.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Appends `other`, re-indexing its triangles.
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// Applies `f` to every vertex position.
    pub fn map_positions(&mut self, f: impl Fn([f64; 3]) -> [f64; 3]) {
        for p in &mut self.positions {
            *p = f(*p);
        }
    }

    /// The three corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// A binary glTF 2.0 file (`.glb`) of the mesh: one node, one mesh, one triangle
    /// primitive with f32 positions (their bounds as glTF requires) and u32 indices,
    /// coordinates as they are (glTF reads them as metres, y up). Deterministic.
    pub fn to_glb(&self, generator: &str) -> Vec<u8> {
        let mut bin: Vec<u8> =
            Vec::with_capacity(self.positions.len() * 12 + self.triangles.len() * 12);
        let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in &self.positions {
            for axis in 0..3 {
                let v = p[axis] as f32;
                (min[axis], max[axis]) = (min[axis].min(v), max[axis].max(v));
                bin.extend(v.to_le_bytes());
            }
        }
        let positions = bin.len();
        bin.extend(
            self.triangles
                .iter()
                .flatten()
                .flat_map(|i| i.to_le_bytes()),
        );
        let indices = bin.len() - positions;
        let mut json = serde_json::json!({
            "asset": {"version": "2.0", "generator": generator},
            "buffers": [{"byteLength": bin.len()}],
        });
        if !self.triangles.is_empty() {
            const ARRAY_BUFFER: u32 = 34962;
            const ELEMENT_ARRAY_BUFFER: u32 = 34963;
            const FLOAT: u32 = 5126;
            const UNSIGNED_INT: u32 = 5125;
            const TRIANGLES: u32 = 4;
            let more = serde_json::json!({
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0}],
                "meshes": [{"primitives": [{
                    "attributes": {"POSITION": 0}, "indices": 1, "mode": TRIANGLES
                }]}],
                "bufferViews": [
                    {"buffer": 0, "byteOffset": 0, "byteLength": positions, "target": ARRAY_BUFFER},
                    {"buffer": 0, "byteOffset": positions, "byteLength": indices,
                     "target": ELEMENT_ARRAY_BUFFER},
                ],
                "accessors": [
                    {"bufferView": 0, "componentType": FLOAT, "count": self.positions.len(),
                     "type": "VEC3", "min": min, "max": max},
                    {"bufferView": 1, "componentType": UNSIGNED_INT,
                     "count": 3 * self.triangles.len(), "type": "SCALAR"},
                ],
            });
            json.as_object_mut()
                .expect("an object")
                .extend(more.as_object().expect("an object").clone());
        }
        let mut json = serde_json::to_vec(&json).expect("finite numbers");
        json.resize(json.len().next_multiple_of(4), b' ');
        bin.resize(bin.len().next_multiple_of(4), 0);
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut glb = Vec::with_capacity(total);
        glb.extend(b"glTF");
        glb.extend(2u32.to_le_bytes());
        glb.extend((total as u32).to_le_bytes());
        for (chunk, kind) in [(&json, b"JSON"), (&bin, b"BIN\0")] {
            glb.extend((chunk.len() as u32).to_le_bytes());
            glb.extend(kind);
            glb.extend(chunk.iter());
        }
        glb
    }

    /// OBJ text: `v x y z` lines with 9 decimals, then `f a b c` (1-based). Deterministic.
    pub fn to_obj(&self, comment: &str) -> String {
        let mut s = String::with_capacity(self.positions.len() * 40 + self.triangles.len() * 24);
        for line in comment.lines() {
            let _ = writeln!(s, "# {line}");
        }
        for p in &self.positions {
            let _ = writeln!(s, "v {:.9} {:.9} {:.9}", p[0], p[1], p[2]);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// Parses OBJ text (all objects and groups merged, polygons triangulated as fans by tobj).
    /// Indices out of range, unparsable lines and non-finite coordinates are errors.
    pub fn from_obj(text: &str) -> Result<Self> {
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| Error::MeshTile(format!("cannot parse OBJ: {e}")))?;
        let mut mesh = TriMesh::default();
        for model in &models {
            let m = &model.mesh;
            let base = mesh.positions.len() as u32;
            for (n, p) in m.positions.chunks_exact(3).enumerate() {
                if !p.iter().all(|c| c.is_finite()) {
                    return Err(Error::MeshTile(format!(
                        "vertex {} of object {:?} has a non-finite coordinate ({}, {}, {})",
                        n + 1,
                        model.name,
                        p[0],
                        p[1],
                        p[2]
                    )));
                }
                mesh.positions.push([p[0], p[1], p[2]]);
            }
            let count = (m.positions.len() / 3) as u32;
            for t in m.indices.chunks_exact(3) {
                if t.iter().any(|&i| i >= count) {
                    return Err(Error::MeshTile(format!(
                        "a face of object {:?} refers to a vertex that does not exist",
                        model.name
                    )));
                }
                mesh.triangles.push([t[0] + base, t[1] + base, t[2] + base]);
            }
        }
        if mesh.triangles.is_empty() {
            return Err(Error::MeshTile("the OBJ file has no faces".into()));
        }
        Ok(mesh)
    }

    /// Reads and parses an OBJ file, refusing files larger than `max_bytes`.
    pub fn read_obj(path: &Path, max_bytes: u64) -> Result<Self> {
        let bytes = mesobake_core::fs::read_bounded(path, "OBJ file", max_bytes)?;
        let text = std::str::from_utf8(&bytes)
            .map_err(|e| Error::MeshTile(format!("not UTF-8 text: {e}")))?;
        Self::from_obj(text)
    }
}

/// Cross product.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// a − b.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

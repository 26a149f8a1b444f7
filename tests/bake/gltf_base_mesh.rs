//! glTF base meshes against files Blender wrote (`tests/data/blender/make_knight.py`): the
//! same triangulated torus with a node transform and two materials, exported as GLB, as glTF
//! with embedded buffers and as OBJ. The OBJ reader is the independent reference: Blender
//! applies the transform to the OBJ's vertices and writes its UVs unflipped, while the glTF
//! carries the transform on its node and v flipped.

use mesobake_bake::surface::base_mesh::{BaseMesh, GltfSelection};
use mesobake_core::limits::Limits;
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/blender")
        .join(name)
}

fn read(name: &str, material: Option<&str>) -> BaseMesh {
    let selection = GltfSelection {
        material,
        texcoord: 0,
    };
    BaseMesh::read_gltf(&data(name), selection, &Limits::default())
        .unwrap()
        .0
}

/// Whether `a` and `b` hold the same triangles, whatever their vertex order: each of `a`'s
/// matched to one of `b`'s, corner by corner in the same cyclic order (the same winding),
/// positions and UVs within 1e-5 (the files hold f32, and the OBJ six decimals), normals
/// within 0.1° (both Blender's).
fn same_triangles(a: &BaseMesh, b: &BaseMesh) -> bool {
    let corner = |m: &BaseMesh, i: u32| {
        let i = i as usize;
        (m.positions[i], m.uvs[i], m.normals[i])
    };
    type Corner = (glam::DVec3, glam::DVec2, glam::DVec3);
    let close = |(p, t, n): Corner, (q, s, m): Corner| {
        (p - q).abs().max_element() < 1e-5
            && (t - s).abs().max_element() < 1e-5
            && n.dot(m) > 0.1f64.to_radians().cos()
    };
    let mut used = vec![false; b.triangles.len()];
    a.triangles.len() == b.triangles.len()
        && a.triangles.iter().all(|ta| {
            let found = b.triangles.iter().enumerate().position(|(k, tb)| {
                !used[k]
                    && (0..3).any(|r| {
                        (0..3).all(|c| close(corner(a, ta[c]), corner(b, tb[(c + r) % 3])))
                    })
            });
            found.map(|k| used[k] = true).is_some()
        })
}

#[test]
fn a_blender_glb_and_gltf_hold_the_triangles_of_its_obj_export() {
    let text = std::fs::read_to_string(data("knight.obj")).unwrap();
    let (obj, _) = BaseMesh::from_obj(&text).unwrap();
    let glb = read("knight.glb", None);
    let gltf = read("knight.gltf", None);
    assert_eq!(obj.triangles.len(), 256);
    // Same triangles, same winding, same UVs (to 1e-5: the files hold f32 and six decimals).
    assert!(same_triangles(&glb, &obj));
    // The vertices the two primitives repeat along their material seam are one again, as in
    // the OBJ: the shell joins neighbouring prisms through shared vertices.
    assert_eq!(glb.positions.len(), obj.positions.len());
    assert!(same_triangles(&gltf, &glb));
    // The node's transform is applied: the torus' box is centred on the node's translation
    // (Blender's (0.25, 0, 0.5), z up, is glTF's (0.25, 0.5, 0), y up).
    let (low, high) = glb.bounds();
    let centre = (low + high) / 2.0;
    assert!(
        (centre - glam::DVec3::new(0.25, 0.5, 0.0)).length() < 1e-3,
        "{centre}"
    );
}

#[test]
fn a_material_selects_its_primitives() {
    let all = read("knight.glb", None);
    let chain = read("knight.glb", Some("Chain"));
    let leather = read("knight.glb", Some("Leather"));
    assert!(!chain.triangles.is_empty() && !leather.triangles.is_empty());
    assert_eq!(
        chain.triangles.len() + leather.triangles.len(),
        all.triangles.len()
    );
    // Blender put Chain on the faces of positive x (before its small rotation).
    assert!(chain.positions.iter().all(|p| p.x > 0.25 - 0.3));
    let mut both = chain.clone();
    let offset = both.positions.len() as u32;
    both.positions.extend(&leather.positions);
    both.uvs.extend(&leather.uvs);
    both.normals.extend(&leather.normals);
    both.triangles
        .extend(leather.triangles.iter().map(|t| t.map(|i| i + offset)));
    assert!(same_triangles(&both, &all));
    let selection = GltfSelection {
        material: Some("Velvet"),
        texcoord: 0,
    };
    let e = BaseMesh::read_gltf(&data("knight.glb"), selection, &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("\"Velvet\"") && e.contains("\"Chain\"") && e.contains("\"Leather\""),
        "{e}"
    );
}

/// The embedded glTF's JSON, edited by `edit`, read from a folder of its own.
fn edited(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data("knight.gltf")).unwrap()).unwrap();
    edit(&mut json);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("edited.gltf");
    std::fs::write(&path, json.to_string()).unwrap();
    match BaseMesh::read_gltf(&path, GltfSelection::default(), &Limits::default()) {
        Ok((mesh, _)) => panic!("accepted with {} triangles", mesh.triangles.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn broken_gltf_files_are_refused_naming_the_part() {
    let cases: Vec<(String, &str)> = vec![
        (
            edited(|j| {
                j["meshes"][0]["primitives"][0]["attributes"]
                    .as_object_mut()
                    .unwrap()
                    .remove("TEXCOORD_0");
            }),
            "no TEXCOORD_0: the shell needs UVs",
        ),
        (
            edited(|j| j["meshes"][0]["primitives"][0]["mode"] = 0.into()),
            "Points",
        ),
        (
            edited(|j| j["accessors"][0]["count"] = 1_000_000.into()),
            "POSITION accessor's bytes lie outside its buffer",
        ),
        (
            edited(|j| j["buffers"][0]["uri"] = "missing.bin".into()),
            "missing.bin",
        ),
        (
            edited(|j| j["buffers"][0]["uri"] = "../../etc/passwd".into()),
            "leaves the glTF file's folder",
        ),
        (edited(|j| j["meshes"] = serde_json::json!([])), "glTF"),
        (
            edited(|j| j["buffers"][0]["uri"] = "%2E%2E/%2E%2E/etc/passwd".into()),
            "leaves the glTF file's folder",
        ),
        (
            edited(|j| j["nodes"][0]["children"] = serde_json::json!([0])),
            "not a tree",
        ),
    ];
    for (message, expected) in cases {
        assert!(message.contains(expected), "{expected:?} in {message:?}");
        assert!(
            message.contains("edited.gltf"),
            "the file is named: {message}"
        );
    }
    // A truncated GLB, and a GLB's bytes as an OBJ.
    let glb = std::fs::read(data("knight.glb")).unwrap();
    let e = BaseMesh::from_gltf(
        &glb[..glb.len() / 2],
        None,
        GltfSelection::default(),
        &Limits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("glTF"), "{e}");
    // An upload holds one file: external buffers are refused there.
    let text = std::fs::read(data("knight.gltf")).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&text).unwrap();
    json["buffers"][0]["uri"] = "knight.bin".into();
    let e = BaseMesh::from_gltf(
        json.to_string().as_bytes(),
        None,
        GltfSelection::default(),
        &Limits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("an upload holds one file"), "{e}");
}

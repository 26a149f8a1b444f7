//! Scenes of several objects. A scene file with `"objects": [...]` holds one entry per object
//! — a base mesh with its mesostructure, shell, material, technique and grids, and a
//! `transform` — beside what they share: camera, lights, effects, environment and GI knobs.
//! Any other field at the top level (a mesostructure, a shell, a grid) is a default for every
//! object, which the object's own overrides. An object whose base mesh
//! is a glTF may map the file's materials to mesostructures in one entry, `"materials":
//! {"Chain": {…}, "Leather": null}`: one object per non-null material, its base mesh that
//! material's primitives, its fields the entry's over the object's (`null`: the material's
//! primitives carry no mesostructure and mesobake draws nothing of them; so does a material
//! the map leaves out).
//!
//! Each object is checked as, and becomes, a single-object [`Scene`]: every stage that takes
//! a scene takes an object (its own plan and package: one package per object), and
//! [`crate::render::render_objects`] draws them together.

use crate::Scene;
use mesobake_core::error::{Error, Result};
use serde_json::{Map, Value};
use std::path::Path;

/// The fields every object shares, given only at the top level.
pub const SHARED_FIELDS: [&str; 5] = ["camera", "lights", "effects", "environment", "gi"];

/// Most objects in one scene.
pub const MAX_OBJECTS: usize = 64;

/// One object of a scene: its name and the single-object scene it renders as.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// The entry's `name`, its material's for a `materials` map, else `object N`.
    pub name: String,
    /// The object as a scene of its own (sharing the camera, lights and effects).
    pub scene: Scene,
}

/// Parses a scene file's JSON into its objects: one for a single-object scene.
pub fn from_json(text: &str) -> Result<Vec<SceneObject>> {
    let value: Value = serde_json::from_str(text).map_err(|e| Error::Scene(e.to_string()))?;
    let Value::Object(mut top) = value else {
        return Err(Error::Scene("a scene is a JSON object".into()));
    };
    let Some(entries) = top.remove("objects") else {
        let scene = Scene::from_json(text)?;
        return Ok(vec![SceneObject {
            name: "scene".into(),
            scene,
        }]);
    };
    let Value::Array(entries) = entries else {
        return Err(Error::Scene("objects is a list of objects".into()));
    };
    if entries.is_empty() || entries.len() > MAX_OBJECTS {
        return Err(Error::Scene(format!(
            "objects holds {} entries; a scene has 1 to {MAX_OBJECTS}",
            entries.len()
        )));
    }
    let mut objects = Vec::new();
    for (index, entry) in entries.into_iter().enumerate() {
        let Value::Object(mut entry) = entry else {
            return Err(Error::Scene(format!(
                "objects[{index}] is not a JSON object"
            )));
        };
        let name = match entry.remove("name") {
            None => format!("object {index}"),
            Some(Value::String(name)) => name,
            Some(other) => {
                return Err(Error::Scene(format!(
                    "objects[{index}].name is {other}, not a string"
                )));
            }
        };
        if let Some(field) = SHARED_FIELDS.iter().find(|f| entry.contains_key(**f)) {
            return Err(Error::Scene(format!(
                "object {name:?}: {field} is shared by every object; give it at the top level"
            )));
        }
        match entry.remove("materials") {
            None => objects.push(object(&top, entry, name)?),
            Some(Value::Object(materials)) => {
                for (material, fields) in materials {
                    let fields = match fields {
                        Value::Null => continue,
                        Value::Object(fields) => fields,
                        other => {
                            return Err(Error::Scene(format!(
                                "object {name:?}: materials.{material} is {other}; give the \
                                 material's fields, or null for none"
                            )));
                        }
                    };
                    let mut merged = entry.clone();
                    let base = select_material(merged.remove("base_mesh"), &material)
                        .map_err(|why| Error::Scene(format!("object {name:?}: {why}")))?;
                    merged.insert("base_mesh".into(), base);
                    merged.extend(fields);
                    objects.push(object(&top, merged, material)?);
                }
            }
            Some(other) => {
                return Err(Error::Scene(format!(
                    "object {name:?}: materials is {other}, not a map of material names"
                )));
            }
        }
    }
    if objects.is_empty() {
        return Err(Error::Scene(
            "every material of every object is null: the scene draws nothing".into(),
        ));
    }
    Ok(objects)
}

/// Reads a scene file's objects (at most [`crate::MAX_SCENE_BYTES`]).
pub fn read(path: &Path) -> Result<Vec<SceneObject>> {
    from_json(&crate::read_scene_text(path)?).map_err(|e| e.context(path.display()))
}

/// The object of `fields` over the scene's top-level fields, checked as a scene.
fn object(
    top: &Map<String, Value>,
    fields: Map<String, Value>,
    name: String,
) -> Result<SceneObject> {
    let mut merged = top.clone();
    merged.extend(fields);
    let scene = Scene::from_json(&Value::Object(merged).to_string())
        .map_err(|e| e.context(format!("object {name:?}")))?;
    Ok(SceneObject { name, scene })
}

/// The glTF base mesh `base` narrowed to the primitives of `material`.
fn select_material(base: Option<Value>, material: &str) -> std::result::Result<Value, String> {
    let not_gltf = || "a materials map needs a glTF base mesh ({\"gltf\": …})".to_string();
    let Some(Value::Object(mut base)) = base else {
        return Err(not_gltf());
    };
    let mut source = match base.remove("gltf") {
        Some(Value::String(file)) => Map::from_iter([("file".to_string(), Value::String(file))]),
        Some(Value::Object(source)) if !source.contains_key("material") => source,
        Some(Value::Object(_)) => {
            return Err(
                "a materials map chooses the glTF's material itself; drop base_mesh.gltf.material"
                    .into(),
            );
        }
        _ => return Err(not_gltf()),
    };
    source.insert("material".into(), Value::String(material.into()));
    Ok(Value::Object(Map::from_iter([(
        "gltf".to_string(),
        Value::Object(source),
    )])))
}

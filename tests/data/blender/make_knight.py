# Writes knight.glb, knight.gltf (embedded buffers) and knight.obj: a smooth triangulated torus with
# two materials ("Chain" on +x, "Leather" on -x) and a node transform, exported by Blender.
# Run: blender -b --python make_knight.py -- tests/data/blender/knight   (Blender 3.4, Debian)
import bpy, bmesh, sys
out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_torus_add(major_radius=1.0, minor_radius=0.4, major_segments=16, minor_segments=8)
obj = bpy.context.active_object
obj.name = "Knight"
bm = bmesh.new(); bm.from_mesh(obj.data)
bmesh.ops.triangulate(bm, faces=bm.faces[:])
bm.to_mesh(obj.data); bm.free()
for p in obj.data.polygons:
    p.use_smooth = True
chain = bpy.data.materials.new("Chain"); leather = bpy.data.materials.new("Leather")
obj.data.materials.append(chain); obj.data.materials.append(leather)
for p in obj.data.polygons:
    p.material_index = 0 if p.center.x > 0 else 1
obj.location = (0.25, 0.0, 0.5)
obj.rotation_euler = (0.3, 0.0, 0.2)
obj.scale = (1.0, 1.0, 1.5)
bpy.ops.export_scene.gltf(filepath=out + ".glb", export_format='GLB', export_materials='EXPORT')
bpy.ops.export_scene.gltf(filepath=out + ".gltf", export_format='GLTF_EMBEDDED', export_materials='EXPORT')
bpy.ops.wm.obj_export(filepath=out + ".obj", export_materials=False, export_selected_objects=False)

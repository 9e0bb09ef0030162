"""Build a user's .blend from a JSON spec, with meshes made by trimesh (run by tests/test_scene_mode.py).

    python make_scene_blend.py SPEC.json OUT.blend                 # bpy module
    blender -b --factory-startup -P make_scene_blend.py -- SPEC.json OUT.blend

The spec: ``resolution`` [W, H] (``resolution_percentage``, default 100); ``camera`` {location,
rotation_deg (XYZ Euler), lens, sensor_width,
sensor_height, sensor_fit, shift_x, shift_y}; ``boxes``: {name, size [x, y, z], location, class (the
fogsim_class property, optional), parent (optional; location is then relative to the parent's),
hidden (from renders), hide_eye, viewport_off (hidden in the viewport only), color [r, g, b],
keys {frame: location} (animated), data_of (a linked duplicate of that box), collection (a
collection not in the scene, to be instanced)}; ``collections`` {name: class}; ``instances``
[{name, collection, location, viewport_off}]; ``points`` [{name, object, points}] a geometry-nodes
Instance on Points of ``object`` on a mesh of those vertices; ``frames`` [start, end]; ``cameras``
[{name, type}] more cameras (e.g. "ORTHO", "PANO"); ``resolution_percentage`` (default 100);
``link`` [{library, object}]: objects linked from another .blend (path relative to OUT's folder).
"""
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.append(str(site))

import bpy  # noqa: E402
import trimesh  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
spec = json.loads(Path(args[0]).read_text())
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.render.resolution_x, scene.render.resolution_y = spec["resolution"]
scene.render.resolution_percentage = spec.get("resolution_percentage", 100)
scene.frame_start, scene.frame_end = spec["frames"]
scene.cycles.samples = 4

world = bpy.data.worlds.new("sky")
if bpy.app.version < (5, 0, 0):  # from 5.0 every world has its node tree (use_nodes deprecated)
    world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.6, 0.7, 0.9, 1.0)
scene.world = world
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (math.radians(40), 0, math.radians(30))
scene.collection.objects.link(sun)

c = spec["camera"]
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
for key in ("lens", "sensor_width", "sensor_height", "sensor_fit", "shift_x", "shift_y"):
    setattr(cam.data, key, c[key])
cam.location = c["location"]
cam.rotation_euler = [math.radians(a) for a in c["rotation_deg"]]
scene.collection.objects.link(cam)
scene.camera = cam
for extra in spec.get("cameras", []):  # more cameras, e.g. {"name": "Ortho", "type": "ORTHO"}
    data = bpy.data.cameras.new(extra["name"])
    data.type = extra["type"]
    other = bpy.data.objects.new(extra["name"], data)
    other.location, other.rotation_euler = cam.location, cam.rotation_euler
    scene.collection.objects.link(other)

collections = {}
for name, cls in spec.get("collections", {}).items():
    coll = bpy.data.collections.new(name)  # not linked to the scene: only instanced
    if cls:
        coll["fogsim_class"] = cls
    collections[name] = coll

objects = {}
for b in spec["boxes"]:
    if b.get("data_of"):  # a linked duplicate: the other box's mesh (and size)
        obj = bpy.data.objects.new(b["name"], objects[b["data_of"]].data)
        scene.collection.objects.link(obj)
        obj.location = b["location"]
        if b.get("class"):
            obj["fogsim_class"] = b["class"]
        objects[b["name"]] = obj
        continue
    tm = trimesh.creation.box(extents=b["size"])
    mesh = bpy.data.meshes.new(b["name"])
    mesh.from_pydata(tm.vertices.tolist(), [], tm.faces.tolist())
    mesh.update()
    if b.get("color"):
        mat = bpy.data.materials.new(b["name"])
        if bpy.app.version < (5, 0, 0):  # likewise materials
            mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*b["color"], 1.0)
        mesh.materials.append(mat)
    obj = bpy.data.objects.new(b["name"], mesh)
    (collections[b["collection"]] if b.get("collection") else scene.collection).objects.link(obj)
    if b.get("parent"):
        obj.parent = objects[b["parent"]]
    obj.location = b["location"]
    if b.get("class"):
        obj["fogsim_class"] = b["class"]
    if b.get("hidden"):
        obj.hide_render = True
    if b.get("hide_eye"):  # hidden in the viewport only: Blender still renders it
        obj.hide_set(True)
    obj.hide_viewport = bool(b.get("viewport_off"))  # disabled in viewports only: rendered too
    for frame, loc in sorted(b.get("keys", {}).items(), key=lambda kv: int(kv[0])):
        obj.location = loc
        obj.keyframe_insert("location", frame=int(frame))
    objects[b["name"]] = obj

for inst in spec.get("instances", []):
    empty = bpy.data.objects.new(inst["name"], None)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = collections[inst["collection"]]
    empty.location = inst["location"]
    scene.collection.objects.link(empty)
    empty.hide_viewport = bool(inst.get("viewport_off"))

for spread in spec.get("points", []):  # geometry nodes: instance an object on every vertex of a mesh
    tree = bpy.data.node_groups.new(spread["name"], "GeometryNodeTree")
    if hasattr(tree, "interface"):  # Blender 4.0+
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
    nodes = tree.nodes
    given, result = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    on_points, info = nodes.new("GeometryNodeInstanceOnPoints"), nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = objects[spread["object"]]
    info.inputs["As Instance"].default_value = True
    tree.links.new(given.outputs[0], on_points.inputs["Points"])
    tree.links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    tree.links.new(on_points.outputs["Instances"], result.inputs[0])
    mesh = bpy.data.meshes.new(spread["name"])
    mesh.from_pydata(spread["points"], [], [])
    obj = bpy.data.objects.new(spread["name"], mesh)
    scene.collection.objects.link(obj)
    obj.modifiers.new("spread", "NODES").node_group = tree

for link in spec.get("link", []):  # objects linked (not appended) from another .blend
    library = Path(args[1]).resolve().parent / link["library"]
    with bpy.data.libraries.load(str(library), link=True, relative=True) as (src, dst):
        dst.objects = [link["object"]]
    for obj in dst.objects:
        scene.collection.objects.link(obj)

scene.frame_set(spec["frames"][0])
bpy.ops.wm.save_as_mainfile(filepath=str(Path(args[1]).resolve()))
print("saved", args[1])

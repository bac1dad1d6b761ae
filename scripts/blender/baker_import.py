# baker_import.py: a Blender add-on that imports a baked lighting file.
#
# File > Import > Baked lighting (.vdb) makes a volume object from a file
# `baker bake` wrote and a material that renders it as baker's viewing pass
# does, L = ∫ T σs L̄ dt: the `emission` grid (σs ⊙ L̄, W·m⁻³·sr⁻¹) drives an
# Emission shader of strength 1, and the `extinction` grid (σt, 1/m) a Volume
# Absorption (Cycles absorbs density·(1 − colour), so the colour is black for a
# grey σt and 1 − σt with density 1 for an RGB one); there is no scattering,
# since the baked light already holds it. Scenes are Y-up and Blender is Z-up:
# by default the object (and the camera and meshes brought in with it) is
# turned +90° about x. A path with #### (or the first file of a numbered run)
# loads as an animated sequence. Optionally the scene's camera and its meshes
# (as glass of each object's IOR) come too, read from the scene JSON.
# A file with `radiance_camera` (some g != 0 and a scene camera) scales the
# emission by radiance_camera / Y(radiance), the light scattered towards the
# baked camera, as `baker view` does from there: exact from that camera, and
# wrong elsewhere (turn "Phase towards the baked camera" off for another
# camera: the isotropic emission).
#
# Headless: import_baked(path, ...) does the same from a script, e.g.
#   blender -b -P script.py, or `import bpy` from the bpy module.
import json
import math
import os
import re

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ImportHelper
from mathutils import Euler, Matrix, Vector

bl_info = {
    "name": "Baked lighting (baker)",
    "author": "baker",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > Baked lighting (.vdb)",
    "description": "Imports a baker lighting bake as an emissive, absorbing volume",
    "category": "Import-Export",
}

# Scene (Y-up) -> Blender (Z-up): +90° about x, (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = Matrix.Rotation(math.pi / 2.0, 4, "X")


def _sequence(path):
    """(first file, first frame, frame count) of the run `path` belongs to:
    a name with #### or one ending in digits with numbered siblings; None
    for a single file."""
    folder, name = os.path.split(os.path.abspath(path))
    m = re.search(r"#+", name) or re.search(r"(\d+)(?=\.n?vdb$)", name)
    if not m:
        return None
    head, tail, width = name[: m.start()], name[m.end():], m.end() - m.start()
    pat = re.compile(re.escape(head) + r"(\d{%d,})" % width + re.escape(tail) + "$")
    frames = sorted(int(g.group(1)) for g in map(pat.match, os.listdir(folder)) if g)
    if not frames or (len(frames) < 2 and "#" not in name):
        return None
    first = os.path.join(folder, "%s%0*d%s" % (head, width, frames[0], tail))
    return first, frames[0], frames[-1] - frames[0] + 1


def _node(nodes, kind, loc, **props):
    n = nodes.new(kind)
    n.location = loc
    for k, v in props.items():
        setattr(n, k, v)
    return n


def _camera_phase(nodes, links, emi_attr):
    """`emission` × radiance_camera / Y(radiance) (Math's divide gives 0 for
    0, where no light came); returns the socket to emit."""
    rad = _node(nodes, "ShaderNodeAttribute", (-800, 500), attribute_name="radiance")
    cam = _node(nodes, "ShaderNodeAttribute", (-800, 350), attribute_name="radiance_camera")
    lum = _node(nodes, "ShaderNodeRGBToBW", (-600, 500))  # Rec. 709 luminance
    div = _node(nodes, "ShaderNodeMath", (-400, 400), operation="DIVIDE")
    scale = _node(nodes, "ShaderNodeVectorMath", (-200, 300), operation="SCALE")
    links.new(rad.outputs["Color"], lum.inputs["Color"])
    links.new(cam.outputs["Fac"], div.inputs[0])
    links.new(lum.outputs["Val"], div.inputs[1])
    links.new(emi_attr.outputs["Vector"], scale.inputs["Vector"])
    links.new(div.outputs["Value"], scale.inputs["Scale"])
    return scale.outputs["Vector"]


def _material(name, rgb_extinction, camera_phase=False):
    """Emission × `emission` grid (× the camera's phase) + Volume Absorption of
    the `extinction` grid."""
    mat = bpy.data.materials.new(name)
    if hasattr(mat, "use_nodes") and not mat.use_nodes:
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = _node(nodes, "ShaderNodeOutputMaterial", (600, 0))
    emi_attr = _node(nodes, "ShaderNodeAttribute", (-400, 200), attribute_name="emission")
    emission = _node(nodes, "ShaderNodeEmission", (0, 200))
    emission.inputs["Strength"].default_value = 1.0
    links.new(_camera_phase(nodes, links, emi_attr) if camera_phase else emi_attr.outputs["Color"],
              emission.inputs["Color"])
    ext_attr = _node(nodes, "ShaderNodeAttribute", (-400, -200), attribute_name="extinction")
    absorb = _node(nodes, "ShaderNodeVolumeAbsorption", (0, -200))
    if rgb_extinction:  # σa = density·(1 − colour): density 1, colour 1 − σt
        sub = _node(nodes, "ShaderNodeVectorMath", (-200, -200), operation="SUBTRACT")
        sub.inputs[0].default_value = (1.0, 1.0, 1.0)
        links.new(ext_attr.outputs["Vector"], sub.inputs[1])
        links.new(sub.outputs["Vector"], absorb.inputs["Color"])
        absorb.inputs["Density"].default_value = 1.0
    else:
        absorb.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        links.new(ext_attr.outputs["Fac"], absorb.inputs["Density"])
    add = _node(nodes, "ShaderNodeAddShader", (300, 0))
    links.new(emission.outputs[0], add.inputs[0])
    links.new(absorb.outputs[0], add.inputs[1])
    links.new(add.outputs[0], out.inputs["Volume"])
    return mat


def _look_at(pos, target, up):
    """World matrix of a Blender camera (looks down −z, y up) at pos."""
    fwd = (Vector(target) - Vector(pos)).normalized()
    right = fwd.cross(Vector(up)).normalized()
    true_up = right.cross(fwd)
    m = Matrix((right, true_up, -fwd)).transposed().to_4x4()
    m.translation = Vector(pos)
    return m


def _add_camera(scene_json, axis, context):
    cam = scene_json.get("camera")
    if not cam:
        return None
    data = bpy.data.cameras.new("baker camera")
    data.sensor_fit = "VERTICAL"
    data.angle_y = math.radians(cam.get("fov_deg", 40.0))
    obj = bpy.data.objects.new("baker camera", data)
    context.collection.objects.link(obj)
    obj.matrix_world = axis @ _look_at(cam["position"], cam.get("look_at", (0, 0, 0)),
                                       cam.get("up", (0, 1, 0)))
    context.scene.camera = obj
    res = cam.get("resolution")
    if res:
        context.scene.render.resolution_x, context.scene.render.resolution_y = res
    return obj


def _glass(ior):
    mat = bpy.data.materials.new("baker glass %g" % ior)
    if hasattr(mat, "use_nodes") and not mat.use_nodes:
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out = _node(nodes, "ShaderNodeOutputMaterial", (300, 0))
    glass = _node(nodes, "ShaderNodeBsdfGlass", (0, 0))
    glass.inputs["IOR"].default_value = ior
    glass.inputs["Roughness"].default_value = 0.0
    mat.node_tree.links.new(glass.outputs[0], out.inputs["Surface"])
    return mat


def _object_matrix(t):
    """The scene's object transform: scale, rotate x then y then z, translate."""
    s = t.get("scale", 1.0)
    s = (s, s, s) if isinstance(s, (int, float)) else s
    r = [math.radians(a) for a in t.get("rotate_deg", (0, 0, 0))]
    rot = Euler(r, "XYZ").to_matrix().to_4x4()
    return Matrix.Translation(t.get("translate", (0, 0, 0))) @ rot @ Matrix.Diagonal((*s, 1.0))


def _add_meshes(scene_json, scene_dir, axis, context):
    made = []
    for i, o in enumerate(scene_json.get("objects", [])):
        path = os.path.join(scene_dir, o["mesh"])
        before = set(bpy.data.objects)
        # the mesh's own coordinates (no axis change): the scene places it below
        bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
        for obj in set(bpy.data.objects) - before:
            obj.matrix_world = axis @ _object_matrix(o.get("transform", {}))
            obj.data.materials.clear()
            obj.data.materials.append(_glass(float(o.get("ior", 1.5))))
            obj.name = "baker object %d" % i
            made.append(obj)
    return made


def import_baked(filepath, y_up=True, sequence=True, scene_path="", camera=False,
                 meshes=False, context=None, camera_phase=True):
    """Imports a baked file; returns the volume object. Callable headless.

    scene_path: the scene JSON, read for camera=True and meshes=True.
    camera_phase: use `radiance_camera` when the file has it."""
    context = context or bpy.context
    axis = Y_UP_TO_Z_UP if y_up else Matrix.Identity(4)
    seq = _sequence(filepath) if sequence else None
    vol = bpy.data.volumes.new(os.path.basename(filepath))
    vol.filepath = seq[0] if seq else filepath
    vol.grids.load()  # the first file's grids, before frames come into play
    grids = {g.name: g for g in vol.grids}
    if "emission" not in grids:
        raise RuntimeError("%s: no `emission` grid (%s)" % (
            vol.filepath, vol.grids.error_message or "bake it with a newer baker"))
    ext = grids.get("extinction") or grids.get("density")
    rgb = ext is not None and ext.data_type.startswith("VECTOR")
    if seq:
        vol.is_sequence = True
        vol.frame_start = seq[1]
        vol.frame_duration = seq[2]
        vol.frame_offset = seq[1] - 1
    phase = camera_phase and "radiance_camera" in grids and "radiance" in grids
    vol.materials.append(_material("baker " + os.path.basename(filepath), rgb, phase))
    obj = bpy.data.objects.new(vol.name, vol)
    obj.matrix_world = axis
    context.collection.objects.link(obj)
    if scene_path and (camera or meshes):
        with open(scene_path) as f:
            sj = json.load(f)
        if camera:
            _add_camera(sj, axis, context)
        if meshes:
            _add_meshes(sj, os.path.dirname(os.path.abspath(scene_path)), axis, context)
    return obj


class IMPORT_OT_baked_lighting(bpy.types.Operator, ImportHelper):
    """Import a baker lighting bake as an emissive, absorbing volume"""
    bl_idname = "import_scene.baked_lighting"
    bl_label = "Import Baked Lighting"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb;*.nvdb", options={"HIDDEN"})
    y_up: BoolProperty(name="Scene is Y-up", default=True,
                       description="Turn the scene's Y-up into Blender's Z-up")
    sequence: BoolProperty(name="Sequence", default=True,
                           description="Load numbered files (####) as an animated volume")
    scene_path: StringProperty(name="Scene JSON", subtype="FILE_PATH",
                               description="The scene file, for its camera and meshes")
    camera: BoolProperty(name="Camera", default=False, description="The scene's camera")
    meshes: BoolProperty(name="Meshes as glass", default=False,
                         description="The scene's meshes, as glass of each object's IOR")
    camera_phase: BoolProperty(name="Phase towards the baked camera", default=True,
                               description="Files with radiance_camera (g != 0): the light "
                               "scattered towards the scene's camera, exact from there only")

    def execute(self, context):
        try:
            import_baked(self.filepath, self.y_up, self.sequence, bpy.path.abspath(self.scene_path),
                         self.camera, self.meshes, context, self.camera_phase)
        except (OSError, RuntimeError, ValueError, KeyError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}


def _menu(self, context):
    self.layout.operator(IMPORT_OT_baked_lighting.bl_idname, text="Baked lighting (.vdb)")


def register():
    bpy.utils.register_class(IMPORT_OT_baked_lighting)
    bpy.types.TOPBAR_MT_file_import.append(_menu)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(_menu)
    bpy.utils.unregister_class(IMPORT_OT_baked_lighting)


if __name__ == "__main__":
    register()

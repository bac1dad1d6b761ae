"""Scene variants for the stability report, written next to the results.

In: a bundled scene (scenes/*.json) and edits. Out: a new scene file under
OUT/scenes/ whose mesh paths are absolute (paths in a scene are relative to
the scene file, and the variant lives elsewhere).
"""
import copy
import json
import os


def load(path):
    with open(path) as f:
        return json.load(f)


def write_variant(base_path, out_dir, name, edit):
    """Copies the scene at base_path, applies edit(scene) (which changes the
    dict in place), writes OUT_DIR/scenes/NAME.json and returns its path."""
    scene = copy.deepcopy(load(base_path))
    base_dir = os.path.dirname(os.path.abspath(base_path))
    for obj in scene.get("objects", []):
        if "mesh" in obj and not os.path.isabs(obj["mesh"]):
            obj["mesh"] = os.path.join(base_dir, obj["mesh"])
    # the report's closed forms are single scattering (photons.bounces 0)
    scene.setdefault("photons", {})["bounces"] = 0
    edit(scene)
    os.makedirs(os.path.join(out_dir, "scenes"), exist_ok=True)
    path = os.path.join(out_dir, "scenes", name + ".json")
    with open(path, "w") as f:
        json.dump(scene, f, indent=1)
    return path


def grey(v):
    return [float(v)] * 3


def sigma_t(scene):
    """Grey extinction of the medium: mean over channels of sigma_s + sigma_a."""
    m = scene.get("medium", {})
    s = m.get("sigma_s", [0, 0, 0])
    a = m.get("sigma_a", [0, 0, 0])
    return sum(x + y for x, y in zip(s, a)) / 3.0


def homogeneous_objects(scene):
    """Gives every object the medium's coefficients: the object then only
    bends light, and the medium is one sigma_t everywhere."""
    m = scene.get("medium", {})
    for obj in scene.get("objects", []):
        obj["sigma_s"] = list(m.get("sigma_s", [0, 0, 0]))
        obj["sigma_a"] = list(m.get("sigma_a", [0, 0, 0]))

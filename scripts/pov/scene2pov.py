#!/usr/bin/env python3
"""scene2pov: a baker scene JSON as a POV-Ray 3.7 scene, for the yardstick in
scripts/bench_povray (issue 15: baker against POV-Ray's photon-mapped render
of the same picture).

usage: scripts/pov/scene2pov.py SCENE.json [-o OUT.pov] [--resolution WxH]
           [--photon-spacing S] [--media-samples N] [--exposure EV]

Only what scenes/sphere.json uses is translated, and anything else is refused
(exit 2, naming the key) rather than dropped: a homogeneous medium filling
the grid's box, spot and point lights, objects whose mesh is the bundled unit
icosphere (meshes/sphere.obj, drawn as POV-Ray's exact sphere) with a uniform
scale and a translation, clear (zero sigma) and isotropic.

How the conventions map (see docs/bench.md, "Against POV-Ray"):
* Units: POV-Ray has none; one POV unit is one scene metre. Its isotropic
  phase function is 1 where physics (and baker) has 1/(4 pi), so the
  scattering colour is sigma_s / (4 pi) with `extinction 4 pi`: extinction
  sigma_a + sigma_s as in baker, in-scattered light sigma_s/(4 pi) E.
* A light of intensity I (W/sr) gives irradiance I / d^2. POV-Ray's fade is
  2 / (1 + (d / D)^2) with fade_power 2, so the colour is I / (2 D^2) with a
  small D (1 cm: off by (D/d)^2 < 3e-5 in the fog, which starts 2 m away).
  `media_attenuation on` dims it through the fog as baker's photons are.
* A spot of half angle a (hard edge, uniform in the cone): radius a,
  falloff a, tightness 0.
* Camera: baker's fov_deg is vertical; POV-Ray's `angle` is horizontal, so
  angle = 2 atan(tan(fov/2) * W/H) with right = W/H. POV-Ray is left-handed:
  the picture is baker's mirrored left to right (the bundled scenes are
  symmetric in x).
* The fog fills the grid's box minus the objects (a difference, the hole
  0.1 mm larger than the glass so that the two surfaces never coincide).
  Single scattering only: POV-Ray's media has no multiple scattering.
* Glass: an exact sphere, n = ior, no reflection, no Fresnel loss (baker has
  neither); photons from the light refract through it and are stored in the
  fog (`media` photons), which draws the caustic. POV-Ray's shadow rays go
  straight through a transparent object, which would light the fog behind
  the ball twice (unrefracted, and again by the photons): an opaque sphere
  just inside the glass, invisible to camera and photons (`no_image
  no_reflection`, photons `pass_through`), casts the shadow instead.
"""
import argparse
import json
import math
import os
import sys

SPHERE_MESHES = ("meshes/sphere.obj",)  # unit icosphere (scripts/make_icosphere.py)
GAP = 1e-4                                # fog hole radius minus glass radius (m)
FADE_D = 0.01                             # POV-Ray fade_distance (m)


class SceneError(Exception):
    pass


def vec(v):
    return "<%s>" % ", ".join("%.9g" % float(c) for c in v)


def rgb(v):
    if isinstance(v, (int, float)):
        v = [v, v, v]
    return "rgb " + vec(v)


def grey3(v, key):
    if isinstance(v, (int, float)):
        return [float(v)] * 3
    if not (isinstance(v, list) and len(v) == 3):
        raise SceneError(f"{key}: expected a number or [r, g, b], got {v!r}")
    return [float(c) for c in v]


def refuse_keys(obj, allowed, where):
    for k in obj:
        if k not in allowed:
            raise SceneError(f"{where}.{k}: not translated to POV-Ray (scene2pov handles {', '.join(allowed)})")


def camera_block(cam, width, height):
    refuse_keys(cam, ("position", "look_at", "up", "fov_deg", "resolution"), "camera")
    aspect = width / height
    fov = float(cam.get("fov_deg", 40.0))
    angle = 2.0 * math.degrees(math.atan(math.tan(math.radians(fov) / 2.0) * aspect))
    return (f"camera {{\n  perspective\n  location {vec(cam['position'])}\n"
            f"  sky {vec(cam.get('up', [0, 1, 0]))}\n  up y\n  right x * {aspect:.9g}\n"
            f"  angle {angle:.9g}  // horizontal; vertical {fov:g} as in the scene\n"
            f"  look_at {vec(cam.get('look_at', [0, 0, 0]))}\n}}\n")


def light_block(light, i, exposure):
    kind = light.get("type")
    if kind not in ("spot", "point"):
        raise SceneError(f"lights[{i}].type: {kind!r} is not translated (spot and point are)")
    scale = 2.0 ** exposure / (2.0 * FADE_D * FADE_D)
    colour = [c * scale for c in grey3(light.get("intensity"), f"lights[{i}].intensity")]
    common = (f"  color {rgb(colour)}  // I / (2 D^2), I = {light['intensity']} W/sr\n"
              f"  fade_distance {FADE_D:g}\n  fade_power 2\n"
              f"  media_interaction on\n  media_attenuation on\n"
              f"  photons {{ refraction on reflection off }}\n")
    if kind == "spot":
        refuse_keys(light, ("type", "position", "direction", "angle_deg", "intensity"), f"lights[{i}]")
        p, d, a = light["position"], light["direction"], float(light["angle_deg"])
        target = [p[k] + d[k] for k in range(3)]
        return (f"light_source {{\n  {vec(p)}\n{common}  spotlight\n  point_at {vec(target)}\n"
                f"  radius {a:g}\n  falloff {a:g}\n  tightness 0\n}}\n")
    refuse_keys(light, ("type", "position", "intensity"), f"lights[{i}]")
    return f"light_source {{\n  {vec(light['position'])}\n{common}}}\n"


def sphere_of(obj, i):
    refuse_keys(obj, ("mesh", "ior", "sigma_a", "sigma_s", "g", "transform"), f"objects[{i}]")
    if obj.get("mesh") not in SPHERE_MESHES:
        raise SceneError(f"objects[{i}].mesh: {obj.get('mesh')!r} is not the unit sphere; "
                         "only meshes/sphere.obj is translated")
    for key in ("sigma_a", "sigma_s"):
        if any(grey3(obj.get(key, 0.0), f"objects[{i}].{key}")):
            raise SceneError(f"objects[{i}].{key}: only clear objects (0) are translated")
    if float(obj.get("g", 0.0)) != 0.0:
        raise SceneError(f"objects[{i}].g: only isotropic scattering is translated")
    tr = obj.get("transform", {})
    refuse_keys(tr, ("scale", "translate"), f"objects[{i}].transform")
    scale = tr.get("scale", 1.0)
    if not isinstance(scale, (int, float)):
        raise SceneError(f"objects[{i}].transform.scale: only a uniform scale is translated")
    ior = obj.get("ior", 1.5)
    if not isinstance(ior, (int, float)):
        raise SceneError(f"objects[{i}].ior: only one n for all channels is translated")
    return tr.get("translate", [0, 0, 0]), float(scale), float(ior)


def medium_block(scene, spheres, media_samples):
    med = scene.get("medium", {})
    refuse_keys(med, ("sigma_s", "sigma_a", "ior", "g"), "medium")
    if float(med.get("ior", 1.0)) != 1.0 or float(med.get("g", 0.0)) != 0.0:
        raise SceneError("medium.ior / medium.g: only n = 1 and isotropic fog are translated")
    ss = grey3(med.get("sigma_s", 0.0), "medium.sigma_s")
    sa = grey3(med.get("sigma_a", 0.0), "medium.sigma_a")
    lo, hi = scene["grid"]["bounds"]
    holes = "".join(f"  sphere {{ {vec(c)}, {r + GAP:.9g} }}\n" for c, r, _ in spheres)
    return (f"// the fog: sigma_s {ss}, sigma_a {sa} (1/m) in the grid's box, not in the glass\n"
            f"difference {{\n  box {{ {vec(lo)}, {vec(hi)} }}\n{holes}"
            f"  pigment {{ rgbt 1 }}\n  finish {{ ambient 0 diffuse 0 specular 0 }}\n  hollow\n"
            f"  interior {{\n    media {{\n      method 3\n      intervals 1\n"
            f"      samples {media_samples}\n"
            f"      absorption {rgb(sa)}\n"
            f"      scattering {{ 1, {rgb([s / (4 * math.pi) for s in ss])}  // sigma_s / (4 pi)\n"
            f"        extinction {4 * math.pi:.9g} }}  // extinction sigma_a + sigma_s\n"
            f"    }}\n  }}\n  photons {{ pass_through collect off }}\n}}\n")


def glass_block(centre, radius, ior):
    return (f"sphere {{\n  {vec(centre)}, {radius:.9g}\n  pigment {{ rgbf 1 }}\n"
            f"  finish {{ ambient 0 diffuse 0 specular 0 reflection 0 }}\n"
            f"  interior {{ ior {ior:g} }}\n"
            f"  photons {{ target refraction on reflection off collect off }}\n}}\n"
            f"// its shadow: the light through the glass arrives only as refracted photons\n"
            f"sphere {{\n  {vec(centre)}, {radius - GAP:.9g}\n  pigment {{ rgb 0 }}\n"
            f"  finish {{ ambient 0 diffuse 0 specular 0 }}\n"
            f"  no_image\n  no_reflection\n  photons {{ pass_through }}\n}}\n")


def convert(scene, width, height, spacing, media_samples, exposure, name="a baker scene"):
    refuse_keys(scene, ("grid", "medium", "objects", "lights", "photons", "adaptive", "camera",
                        "background"), "scene")
    spheres = [sphere_of(o, i) for i, o in enumerate(scene.get("objects", []))]
    photon_steps = 100  # most media photons stored per ray segment (POV-Ray docs' suggestion)
    out = [f"// Generated by scripts/pov/scene2pov.py from {name}; do not edit.\n",
           "#version 3.7;\n",
           f"global_settings {{\n  assumed_gamma 1.0\n  ambient_light 0\n  max_trace_level 10\n"
           f"  photons {{\n    spacing {spacing:g}\n    media {photon_steps}\n  }}\n}}\n",
           f"background {{ {rgb(scene.get('background', [0, 0, 0]))} }}\n",
           camera_block(scene["camera"], width, height)]
    out += [light_block(l, i, exposure) for i, l in enumerate(scene.get("lights", []))]
    out.append(medium_block(scene, spheres, media_samples))
    out += [glass_block(c, r, n) for c, r, n in spheres]
    return "".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("-o", "--out", help="output .pov (default stdout)")
    ap.add_argument("--resolution", help="WxH for the camera's aspect (default: the scene's)")
    ap.add_argument("--photon-spacing", type=float, default=0.005,
                    help="POV-Ray photons spacing in metres (default 0.005)")
    ap.add_argument("--media-samples", type=int, default=20,
                    help="media samples per interval, method 3 (default 20: 10 leaves a dark "
                         "band in the ball's shadow and a 7%% brighter fog, docs/bench.md)")
    ap.add_argument("--exposure", type=float, default=0.0,
                    help="scale the lights by 2^EV, as baker view --exposure")
    a = ap.parse_args()
    try:
        with open(a.scene) as f:
            scene = json.load(f)
        w, h = scene["camera"].get("resolution", [800, 600])
        if a.resolution:
            w, h = (int(t) for t in a.resolution.lower().split("x"))
        text = convert(scene, w, h, a.photon_spacing, a.media_samples, a.exposure,
                       os.path.basename(a.scene))
    except (OSError, ValueError, KeyError, SceneError) as e:
        print(f"scene2pov: {a.scene}: {e}", file=sys.stderr)
        return 2
    if a.out:
        tmp = a.out + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, a.out)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""POV-Ray 3.7 as the yardstick of scripts/bench's `povray` section (issue 15).

In: a baker scene, translated by scripts/pov/scene2pov.py. Out: POV-Ray's
command line, the times it printed (parse, photons, trace), how many media
photons it stored, and the comparison of two 8-bit sRGB PNGs of the same
picture (baker view --png against POV-Ray's +FN with File_Gamma=sRGB):
the ratio of their mean linear luminance and the relative RMS difference.
POV-Ray is left-handed, so its picture is baker's mirrored left to right;
it is flipped back before the comparison.
"""
import os
import re
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "pov"))

import scene2pov  # noqa: E402,F401  (re-exported for scripts/bench)

REC709 = np.array([0.2126, 0.7152, 0.0722])
_TIME = re.compile(r"^\s*(Parse|Bounding|Photon|Trace) Time:.*\(([\d.]+) seconds\)", re.M)
_MEDIA_PHOTONS = re.compile(r"Media photons stored:\s+(\d+)")
_SHOT = re.compile(r"Number of photons shot:\s+(\d+)")


def find():
    """The povray executable, or None."""
    return shutil.which("povray")


def version(exe):
    try:
        p = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"POV-Ray (\d[\w.]*)", p.stdout + p.stderr)
    return m.group(1) if m else None


def command(exe, pov_name, png_name, size, threads):
    """POV-Ray's arguments for a render of pov_name to an sRGB PNG: no
    display (-D), no anti-aliasing (-A: one ray per pixel, as baker view),
    `threads` render threads. File names are relative: POV-Ray's default I/O
    policy only lets it read and write the current folder (and /tmp)."""
    w, h = size
    return [exe, f"+I{pov_name}", f"+O{png_name}", "+FN", f"+W{w}", f"+H{h}", "-D", "-A",
            f"+WT{threads}", "File_Gamma=sRGB"]


def parse_log(text):
    """Seconds per stage and photon counts from POV-Ray's statistics."""
    out = {f"{m.group(1).lower()}_s": float(m.group(2)) for m in _TIME.finditer(text)}
    m = _MEDIA_PHOTONS.search(text)
    out["media_photons"] = int(m.group(1)) if m else None
    m = _SHOT.search(text)
    out["photons_shot"] = int(m.group(1)) if m else None
    return out


def linear_luminance(png_path):
    """Linear Rec. 709 luminance of an 8-bit sRGB PNG (matplotlib reads it
    as floats in [0, 1])."""
    import matplotlib.image as mpimg
    c = mpimg.imread(png_path)[..., :3].astype(np.float64)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return lin @ REC709


def compare(baker_png, pov_png):
    """{"mean_ratio": mean baker / mean POV-Ray, "rel_rms": RMS difference /
    RMS of POV-Ray's, "clipped": share of pixels at 255 in either} on linear
    luminance, POV-Ray's picture mirrored back to baker's handedness."""
    b = linear_luminance(baker_png)
    p = linear_luminance(pov_png)[:, ::-1]
    if b.shape != p.shape:
        return {"error": f"sizes differ: baker {b.shape}, POV-Ray {p.shape}"}
    ref = float(np.sqrt(np.mean(p ** 2)))
    return {"mean_ratio": float(b.mean() / p.mean()) if p.mean() > 0 else None,
            "rel_rms": float(np.sqrt(np.mean((b - p) ** 2)) / ref) if ref > 0 else None,
            "clipped": float(np.mean((b >= 0.999) | (p >= 0.999)))}


def side_by_side(panels, out_png, title):
    """One PNG of the pictures in panels [(label, png)], POV-Ray's flipped
    as in compare() when its label says POV-Ray."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6))
    for ax, (label, path) in zip(np.atleast_1d(axes), panels):
        img = mpimg.imread(path)
        ax.imshow(img[:, ::-1] if "POV-Ray" in label else img)
        ax.set_title(label, fontsize=9)
        ax.axis("off")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out_png, dpi=100)
    plt.close(fig)

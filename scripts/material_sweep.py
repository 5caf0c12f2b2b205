"""Writes the demo's sweep of material edits (relume-materials JSON files) into a folder.

The sweep walks the Cornell scene's two editable regions through the range the paper
shows: the object from chalk-matte to glossy (ns 1 → 200, Ks 0 → 0.8) and the white walls
from diffuse to glossy, plus a few colours (the walls' Kd tints the bounce light).
"""
import json
import os
import sys


def frame(obj, walls):
    return {"format": "relume-materials", "version": 1, "regions": {"Object": obj, "White walls": walls}}


def bp(kd, ks, ns):
    return {"model": "blinn_phong", "kd": kd, "ks": ks, "ns": ns}


def main(out):
    os.makedirs(out, exist_ok=True)
    frames = []
    for i, ns in enumerate([1, 5, 20, 60, 120, 200]):
        ks = 0.15 * i
        frames.append(frame(bp([0.8 - ks] * 3, [ks] * 3, ns), bp([0.3] * 3, [0.3] * 3, 5)))
    frames.append(frame(bp([0.2, 0.2, 0.2], [0.4] * 3, 5), bp([0.3] * 3, [0.3] * 3, 5)))  # the paper's Fig. 3(a-d)
    frames.append(frame(bp([0.2, 0.2, 0.2], [0.4] * 3, 180), bp([0.3] * 3, [0.3] * 3, 180)))  # Fig. 3(e-h)
    frames.append(frame(bp([0.7, 0.5, 0.1], [0.1] * 3, 40), bp([0.5, 0.5, 0.8], [0.0] * 3, 1)))
    frames.append(frame({"model": "principled", "base_color": [0.9, 0.6, 0.2], "metallic": 1.0, "roughness": 0.35},
                        {"model": "principled", "base_color": [0.8, 0.8, 0.8], "roughness": 0.9}))
    captions = [f"object ns {ns}, ks {0.15 * i:.2f}" for i, ns in enumerate([1, 5, 20, 60, 120, 200])]
    captions += ["paper fig. 3 (a-d): ns 5", "paper fig. 3 (e-h): ns 180", "ochre object, blue walls",
                 "gold metal, rough walls"]
    for i, f in enumerate(frames):
        with open(os.path.join(out, f"frame_{i:02d}.json"), "w") as fh:
            json.dump(f, fh, indent=1)
    # One caption a frame, for the demo's contact sheet.
    with open(os.path.join(out, "captions.json"), "w") as fh:
        json.dump({f"frame_{i:02d}": c for i, c in enumerate(captions)}, fh, indent=1)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/sweep")

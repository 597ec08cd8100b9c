"""A world model that lives in its own environment, as one stand-alone script: it imports nothing of imply.

It reads a video package written by ``imply suite export`` (manifest.json, cases.csv, the
context frames and calibration pushes) and writes one MP4 per case, named as cases.csv
says, into a folder that ``imply evaluate --videos`` scores. Its physics is a guess a
video model could make: through the two calibration pushes it shows (speeds and observed
slides) it fits a power law, slide = a speed^b, and reads the query's slide off it; with
no calibration (condition none) it guesses one typical slide. It draws the box of the
last context frame moved by that slide (metres per pixel from the manifest), and writes
the context frames followed by that frame.

Run: python examples/video_world_model.py PACKAGE OUT_FOLDER [--cases CASES.csv]
Needs numpy, Pillow and PyAV (pip install numpy pillow av).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import av
import numpy as np
from PIL import Image

TYPICAL_SLIDE = 0.15  # metres at 0.55 m/s, growing with the square of speed: the guess without calibration


def predicted_slide(row: dict) -> float:
    """The query push's slide (m) from the calibration pushes of the case (a power law through both)."""
    v = float(row["speed"])
    if not row.get("calibration_slide_1"):
        return TYPICAL_SLIDE * (v / 0.55) ** 2
    v1, v2 = float(row["calibration_speed_1"]), float(row["calibration_speed_2"])
    d1, d2 = float(row["calibration_slide_1"]), float(row["calibration_slide_2"])
    b = math.log(d2 / d1) / math.log(v2 / v1)
    return d1 * (v / v1) ** b


def moved_box(frame: np.ndarray, pixels: float) -> np.ndarray:
    """``frame`` with its red box moved ``pixels`` to the right (the push's direction in the picture)."""
    rgb = frame.astype(int)
    box = (rgb[..., 0] > rgb[..., 1] + 40) & (rgb[..., 0] > rgb[..., 2] + 40)
    out = frame.copy()
    out[box] = np.median(frame[~box], axis=0).astype(np.uint8)
    ys, xs = np.nonzero(box)
    shift = int(round(pixels))
    keep = xs + shift < frame.shape[1]
    out[ys[keep], xs[keep] + shift] = frame[ys[keep], xs[keep]]
    return out


def write_video(path: Path, frames: list[np.ndarray], fps: float) -> None:
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=round(fps))
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "yuv420p"
        for f in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(f, format="rgb24")))
        container.mux(stream.encode())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("package", type=Path, help="the folder imply suite export wrote")
    ap.add_argument("out", type=Path, help="folder for the generated videos")
    ap.add_argument("--cases", type=Path, help="the cases to generate (default: the package's cases.csv)")
    args = ap.parse_args()
    manifest = json.loads((args.package / "manifest.json").read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.cases or args.package / "cases.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        context = [np.asarray(Image.open(p).convert("RGB")) for p in sorted((args.package / row["context"]).iterdir())]
        rest = moved_box(context[-1], predicted_slide(row) / manifest["metres_per_pixel"])
        write_video(args.out / row["output"], [*context, rest, rest], manifest["fps"])
    print(f"wrote {len(rows)} videos to {args.out}")


if __name__ == "__main__":
    main()

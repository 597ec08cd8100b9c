"""The suite as files a model in any environment can read, and the videos it generates read back.

``imply suite export SUITE -o DIR`` writes the *package* (:func:`export_package`)::

    manifest.json   format "imply-video-package", version; the suite's checksum; the size (height, width)
                    and fps of the exported frames and videos; the suite's camera size, frame times,
                    metres per pixel, context frames C, query speeds, calibration speeds; the naming
                    rule of the generated videos; the conditions; the number of cases
    cases.csv       one row per case: case_id, object_id, condition, speed (the action: the pusher's
                    commanded speed, m/s), context (folder of its C PNG frames), calibration_object_id,
                    calibration_speed_1, calibration_slide_1, calibration_video_1, the same for push 2
                    (empty in condition none), output (the file the generated video must have)
    cases.json      the same rows, with the manifest
    context/<object>_q<k>/frame_<i>.png                the first C frames of each query push
    calibration/<object>/push<j>.mp4, push<j>/frame_<t>.png   each calibration push, whole (frame
                    times, then the rest frame), as H.264 video and as PNG frames
    README.md       the same in words

No truth is in it: the query pushes' slides and rest frames stay in the suite's sealed file.

A model writes one video per case and sample set into a folder: ``<case_id>.mp4`` (one
sample set) or ``<case_id>_s<index>.mp4`` (several, from 0), or the same names as folders
of PNG frames (read in name order). Any fps and resolution: every frame is resized to the
suite's camera (:func:`to_camera`: an area average when it shrinks, bilinear when it grows,
untouched at the camera's size). A video may start with the context it was shown; what is
scored is its last frame, the box at rest (the frame-difference readout's rule).

:func:`check_videos` finds everything wrong with a folder before anything is scored (one
problem per kind, with the count and the first names); :func:`read_videos` turns a checked
folder into the same rollouts a ``--rollouts`` file gives (:class:`RolloutsFile`, kind
``frames``), so a folder scores exactly as the in-process path does on the same frames.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from imply.evaluate.rollouts_file import RolloutsFile
from imply.evaluate.suite import Suite
from imply.evaluate.suite import read_manifest as read_folder_manifest
from imply.io import write_csv, write_folder, write_json, write_text

PACKAGE_FORMAT = "imply-video-package"
PACKAGE_VERSION = 1
VIDEO_EXT = ".mp4"
SHOWN = 3  # names a problem line shows


class VideoFolderError(ValueError):
    """A folder of generated videos that cannot be scored: one line per kind of problem."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = problems


@dataclass(frozen=True)
class Case:
    """One generated video asked for: object ``n`` of the suite, condition, query speed ``k``."""

    case_id: str
    n: int
    object_id: str
    condition: str
    k: int
    speed: float
    shown: int | None  # the object whose calibration pushes are shown (None: condition none)


def case_list(suite: Suite, conditions: tuple[str, ...]) -> list[Case]:
    """Every case of ``suite`` in ``conditions``, object by object, condition by condition, speed by speed."""
    out = []
    for n, oid in enumerate(suite.object_ids.astype(str)):
        for c in conditions:
            shown = None if c == "none" else int(suite.partner[n]) if c == "other" else n
            for k, v in enumerate(suite.query_speeds):
                out.append(Case(f"{oid}_{c}_q{k}", n, oid, c, k, float(v), shown))
    return out


def output_name(case_id: str, sample: int | None) -> str:
    """The generated video's file name (sample None: a single sample set)."""
    return f"{case_id}{VIDEO_EXT}" if sample is None else f"{case_id}_s{sample}{VIDEO_EXT}"


def to_camera(frame: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``frame`` (h, w, 3) uint8 at the camera's (H, W): an area average when it shrinks, bilinear when it grows,
    untouched when it is already that size."""
    if frame.shape[:2] == tuple(shape):
        return frame
    from PIL import Image

    h, w = shape
    img = Image.fromarray(np.ascontiguousarray(frame[..., :3]))
    shrink = frame.shape[0] >= h and frame.shape[1] >= w
    return np.asarray(img.resize((w, h), Image.Resampling.BOX if shrink else Image.Resampling.BILINEAR))


def _write_png(path: Path, frame: np.ndarray) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(frame).save(path, format="PNG")


def write_mp4(
    path: Path,
    frames: np.ndarray,
    fps: float,
    *,
    codec: str = "libx264",
    crf: int | None = 18,
    bit_rate: int | None = None,
) -> None:
    """Frames (F, H, W, 3) uint8 as an MP4 (yuv420p; H and W must be even): H.264 at constant quality ``crf`` by
    default, or ``codec`` at ``bit_rate`` (bits/s) as another file was encoded."""
    import av

    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), mode="w") as out:
        stream = out.add_stream(codec, rate=max(round(fps), 1))
        stream.height, stream.width = frames.shape[1:3]
        stream.pix_fmt = "yuv420p"
        if crf is not None:
            stream.options = {"crf": str(crf)}
        if bit_rate:
            stream.bit_rate = int(bit_rate)
        for f in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f), format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)


def read_mp4(path: Path) -> tuple[np.ndarray, float]:
    """Every frame of a video (F, H, W, 3) uint8 and its frame rate."""
    frames, fps, _ = read_video(path)
    return frames, fps


def read_video(path: Path) -> tuple[np.ndarray, float, dict]:
    """Every frame of a video (F, H, W, 3) uint8, its frame rate, and its encoding (codec, height, width, fps,
    bit_rate in bits/s)."""
    import av

    with av.open(str(path)) as src:
        stream = src.streams.video[0]
        fps = float(stream.average_rate) if stream.average_rate else float("nan")
        frames = [f.to_ndarray(format="rgb24") for f in src.decode(stream)]
        rate = stream.bit_rate or src.bit_rate or 0
        encoding = {
            "codec": stream.codec_context.name,
            "height": stream.codec_context.height,
            "width": stream.codec_context.width,
            "fps": fps,
            "bit_rate": int(rate),
        }
    if not frames:
        raise ValueError("no frame")
    return np.stack(frames), fps, encoding


def through_codec(clips: np.ndarray, encoding: dict, shape: tuple[int, int]) -> np.ndarray:
    """Clips (M, F, H, W, 3) encoded as ``encoding`` says (codec, size, fps, bit rate), decoded, and resized back
    to the camera's ``shape``: what a submission's encoding does to real frames."""
    import tempfile

    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for m, clip in enumerate(clips):
            path = Path(tmp) / f"clip{m}.mp4"
            write_mp4(
                path,
                _resized(clip, (encoding["height"], encoding["width"])),
                encoding["fps"],
                codec=encoding["codec"],
                crf=None,
                bit_rate=encoding.get("bit_rate"),
            )
            back, _, _ = read_video(path)
            out.append(_resized(back, shape))
    return np.stack(out)


def _resized(frames: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    return np.stack([to_camera(f, shape) for f in frames])


def export_package(
    suite: Suite, out: Path, *, conditions: tuple[str, ...], size: tuple[int, int] | None = None, fps: float = 30.0
) -> dict:
    """Write the package of ``suite`` (module docstring) into ``out``, a new or empty folder (written beside it and
    moved in whole); returns its manifest. ``size`` (height, width): the frames' size (default the suite's
    camera)."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"-o {out}: must be a new or empty folder (a package is never written over files)")
    cam = suite.frame_shape[:2]
    size = tuple(size) if size is not None else cam
    if size[0] % 2 or size[1] % 2:
        raise ValueError(f"--size {size[0]}x{size[1]}: H.264 needs an even height and width")
    cases = case_list(suite, conditions)
    C = suite.context_frames.shape[2]
    manifest = {
        "format": PACKAGE_FORMAT,
        "version": PACKAGE_VERSION,
        "suite": suite.checksum,
        "size": {"height": int(size[0]), "width": int(size[1])},
        "fps": float(fps),
        "camera": {"height": int(cam[0]), "width": int(cam[1])},
        "frame_times": [float(t) for t in suite.frame_times],
        "context_frames": int(C),
        "metres_per_pixel": float(suite.metres_per_pixel) * cam[1] / size[1],
        "query_speeds": [float(v) for v in suite.query_speeds],
        "calibration_speeds": [float(v) for v in suite.calibration_speeds],
        "conditions": list(conditions),
        "n_cases": len(cases),
        "output": "<case_id>.mp4, or <case_id>_s<index>.mp4 for several sample sets (from 0); or folders of PNG "
        "frames of the same names; any fps and resolution; the last frame shows the box at rest",
    }
    rows = []
    for c in cases:
        row = {
            "case_id": c.case_id,
            "object_id": c.object_id,
            "condition": c.condition,
            "speed": c.speed,
            "context": f"context/{c.object_id}_q{c.k}",
            "calibration_object_id": "",
        }
        for j in range(2):
            row[f"calibration_speed_{j + 1}"] = float(suite.calibration_speeds[j]) if c.shown is not None else None
            row[f"calibration_slide_{j + 1}"] = (
                float(suite.calibration_displacement[c.shown, j]) if c.shown is not None else None
            )
            row[f"calibration_video_{j + 1}"] = (
                f"calibration/{suite.object_ids[c.shown]}/push{j + 1}{VIDEO_EXT}" if c.shown is not None else ""
            )
        if c.shown is not None:
            row["calibration_object_id"] = str(suite.object_ids[c.shown])
        row["output"] = output_name(c.case_id, None)
        rows.append(row)

    def write(tmp: Path) -> None:
        for n, oid in enumerate(suite.object_ids.astype(str)):
            for k in range(suite.n_speeds):
                for i, f in enumerate(_resized(suite.context_frames[n, k], size)):
                    _write_png(tmp / "context" / f"{oid}_q{k}" / f"frame_{i:02d}.png", f)
            for j in range(2):
                frames = _resized(suite.calibration_frames[n, j], size)
                write_mp4(tmp / "calibration" / oid / f"push{j + 1}{VIDEO_EXT}", frames, fps)
                for t, f in enumerate(frames):
                    _write_png(tmp / "calibration" / oid / f"push{j + 1}" / f"frame_{t:02d}.png", f)
        write_csv(tmp / "cases.csv", pd.DataFrame(rows))
        write_json(tmp / "cases.json", {"manifest": manifest, "cases": rows})
        write_json(tmp / "manifest.json", manifest)
        write_text(tmp / "README.md", _readme(manifest))

    write_folder(out, write)
    return manifest


def _readme(m: dict) -> str:
    return (
        "# A video package of an imply evaluation suite\n\n"
        f"{m['n_cases']} cases (object x condition x query speed; conditions {', '.join(m['conditions'])}), "
        f"frames {m['size']['height']} x {m['size']['width']} px, videos at {m['fps']:g} fps, "
        f"{m['metres_per_pixel']:.4g} m per pixel. `cases.csv` lists each case: the object, the condition, the "
        "commanded speed of the query push (the action), the folder of its context frames, and the calibration "
        "pushes shown (their speeds, observed slides and videos; none in condition none).\n\n"
        f"Write one video per case into a folder: {m['output']}. Then score it: "
        "`imply evaluate --videos FOLDER --suite SUITE -o REPORT` (`--check` only checks the folder).\n"
    )


_NAME = re.compile(r"^(?P<case>.+?)(?:_s(?P<sample>\d+))?$")


def _entries(folder: Path) -> tuple[dict[tuple[str, int | None], list[Path]], list[str]]:
    """The folder's videos and PNG folders by (case id, sample or None), and names that are neither."""
    found: dict[tuple[str, int | None], list[Path]] = {}
    other = []
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_file() and p.suffix.lower() == VIDEO_EXT:
            stem = p.stem
        elif p.is_dir():
            stem = p.name
        else:
            other.append(p.name)
            continue
        m = _NAME.match(stem)
        sample = int(m["sample"]) if m["sample"] is not None else None
        found.setdefault((m["case"], sample), []).append(p)
    return found, other


def _decode(path: Path) -> tuple[np.ndarray, float | None, dict | None]:
    """A video's or a PNG folder's frames (F, h, w, 3), fps and encoding (None for PNG frames: lossless)."""
    if path.is_dir():
        from PIL import Image

        pngs = sorted(q for q in path.iterdir() if q.suffix.lower() == ".png")
        if not pngs:
            raise ValueError("no PNG frame")
        return np.stack([np.asarray(Image.open(q).convert("RGB")) for q in pngs]), None, None
    return read_video(path)


def _problem(kind: str, names: list[str]) -> str:
    shown = ", ".join(names[:SHOWN]) + (f", ... ({len(names) - SHOWN} more)" if len(names) > SHOWN else "")
    return f"{kind}: {len(names)} ({shown})"


@dataclass(frozen=True)
class CheckedFolder:
    """A folder of generated videos, checked: each case's and sample set's frames, first and last (F = 2)."""

    frames: dict[tuple[str, int], np.ndarray]
    n_samples: int
    fps: float | None
    encoding: dict | None  # the lossy videos' codec, size, fps and median bit rate (None: all PNG)


def check_videos(folder: str | Path, suite: Suite, conditions: tuple[str, ...]) -> CheckedFolder:
    """Read and check every generated video of ``folder`` for ``suite`` in ``conditions``; VideoFolderError lists
    every kind of problem (missing, extra, duplicated, undecodable, mixed frame rates, no frame after the
    context), nothing read is kept then."""
    folder = Path(folder)
    if not folder.is_dir():
        raise VideoFolderError([f"{folder}: no such folder"])
    cases = {c.case_id: c for c in case_list(suite, conditions)}
    found, other = _entries(folder)
    problems: dict[str, list[str]] = {}

    def add(kind: str, name: str) -> None:
        problems.setdefault(kind, []).append(name)

    for name in other:
        add("extra files (not a video or a folder of PNG frames)", name)
    single = {c for c, s in found if s is None}
    numbered = {c for c, s in found if s is not None}
    for (case, _sample), paths in found.items():
        if case not in cases:
            add("extra videos (no such case in the package)", paths[0].name)
        elif len(paths) > 1:
            add("duplicated (a video and a PNG folder of one case)", paths[0].stem)
    for case in single & numbered:
        add("duplicated (both <case> and <case>_s<index>)", case)
    samples = sorted({s for c, s in found if s is not None and c in cases})
    n_samples = (max(samples) + 1) if samples else 1
    wanted = [(c, None if not numbered else s) for c in cases for s in range(n_samples if numbered else 1)]
    for c, s in wanted:
        if (c, s) not in found:
            add("missing", output_name(c, s))
    C = suite.context_frames.shape[2]
    frames: dict[tuple[str, int], np.ndarray] = {}
    rates: dict[float, list[str]] = {}
    encodings: list[dict] = []
    shape = suite.frame_shape[:2]
    for c, s in wanted:
        paths = found.get((c, s))
        if not paths or len(paths) > 1:
            continue
        try:
            video, fps, encoding = _decode(paths[0])
        except Exception as exc:  # noqa: BLE001 (any decoder failure is the file's problem, named)
            add("undecodable", f"{paths[0].name} ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})")
            continue
        if len(video) <= C:
            add(f"no frame after the {C} context frames", paths[0].name)
            continue
        if fps is not None:
            rates.setdefault(round(fps, 3), []).append(paths[0].name)
        if encoding is not None:
            encodings.append(encoding)
        frames[(c, 0 if s is None else s)] = np.stack([to_camera(video[0], shape), to_camera(video[-1], shape)])
    if len(rates) > 1:
        listed = sorted(rates.items(), key=lambda kv: -len(kv[1]))
        add("mixed frame rates", ", ".join(f"{r:g} fps: {len(n)} videos ({n[0]}...)" for r, n in listed))
    if problems:
        raise VideoFolderError([f"{folder}: {_problem(kind, names)}" for kind, names in problems.items()])
    fps_all = next(iter(rates)) if rates else None
    encoding = None
    if encodings:
        first = encodings[0]
        encoding = {**first, "bit_rate": int(np.median([e["bit_rate"] for e in encodings]))}
    return CheckedFolder(frames=frames, n_samples=n_samples, fps=fps_all, encoding=encoding)


def read_videos(
    folder: str | Path,
    suite: Suite,
    conditions: tuple[str, ...],
    *,
    model: str | None = None,
    checked: CheckedFolder | None = None,
) -> RolloutsFile:
    """A checked folder of generated videos as rollouts (kind ``frames``: each rollout's first and last frame at
    the suite's camera), named ``model`` (default the folder's name)."""
    folder = Path(folder)
    checked = checked or check_videos(folder, suite, conditions)
    cases = case_list(suite, conditions)
    S = checked.n_samples
    shape = (len(conditions), S, suite.n_objects, suite.n_speeds)
    row = np.empty(shape, dtype=np.int64)
    outputs = []
    for c in cases:
        for s in range(S):
            row[conditions.index(c.condition), s, c.n, c.k] = len(outputs)
            outputs.append(checked.frames[(c.case_id, s)])
    return RolloutsFile(
        model=model or folder.name,
        kind="frames",
        conditions=tuple(conditions),
        n_samples=S,
        row=row,
        output=np.stack(outputs),
        encoded_train=None,
        encoded_check=None,
        encoding=checked.encoding,
    )


def read_manifest(path: str | Path) -> dict:
    """A package's manifest (:class:`imply.evaluate.suite.SuiteError`, a ValueError, naming the file when it is not
    one), read by the suite's manifest reader."""
    return read_folder_manifest(path, kind=PACKAGE_FORMAT, what="video package")


class CommandError(RuntimeError):
    """The user's generation command failed: the message holds its exit status and last lines."""


def pending_cases(package: Path, videos: Path) -> pd.DataFrame:
    """The package's cases whose video is not in ``videos`` yet (a video, or a folder of PNG frames, of the case's
    output name): what an interrupted generation still owes."""
    cases = pd.read_csv(Path(package) / "cases.csv", keep_default_na=False)
    done = {p.stem if p.is_file() else p.name for p in Path(videos).iterdir()} if Path(videos).is_dir() else set()
    return cases[[Path(name).stem not in done for name in cases["output"]]]


def run_command(command: str, *, package: Path, videos: Path, log_path: Path, tail: int = 15) -> int:
    """Run the user's generation ``command`` for the cases still pending, in its own process (no shell): the
    placeholders ``{package}`` (the exported folder), ``{cases}`` (a cases file of the pending cases) and
    ``{out}`` (the videos folder) are filled in; its output is appended to ``log_path``. Returns how many cases
    it was asked for; CommandError with its last ``tail`` lines when it exits non-zero."""
    import shlex
    import subprocess

    videos = Path(videos)
    videos.mkdir(parents=True, exist_ok=True)
    todo = pending_cases(package, videos)
    if todo.empty:
        return 0
    cases_path = videos.parent / f".{videos.name}.pending.csv"
    write_csv(cases_path, todo)
    try:
        argv = [
            part.format(package=str(package), cases=str(cases_path), out=str(videos)) for part in shlex.split(command)
        ]
    except (KeyError, IndexError, ValueError) as exc:
        raise CommandError(f"--command: {exc} (placeholders: {{package}}, {{cases}}, {{out}})") from None
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with open(log_path, "a") as log_file:
        log_file.write(f"$ {shlex.join(argv)}  # {len(todo)} cases\n")
        log_file.flush()
        try:
            status = subprocess.run(argv, stdout=log_file, stderr=subprocess.STDOUT).returncode
        except OSError as exc:
            raise CommandError(f"--command: {argv[0]}: {exc.strerror}") from None
    cases_path.unlink(missing_ok=True)
    if status != 0:
        last = log_path.read_text().splitlines()[-tail:]
        raise CommandError(f"--command exited with status {status}; its last lines ({log_path}):\n" + "\n".join(last))
    return len(todo)

"""The frozen evaluation suite: what every world model is shown, and the sealed truth it is scored on.

A suite is a folder (the workflow's ``results/suite/``, built by :func:`build_suite`,
``imply suite build``) of five files:

``manifest.json``
    ``format`` (``imply-suite``) and ``version`` (:data:`SUITE_VERSION`); the imply and
    MuJoCo versions that built it; ``config``: the settings used (section ``suite`` as
    given, and the subsets of ``clips``, ``scene`` and ``score`` the build read);
    ``split``; ``sizes`` ``{N, K, C, T, M, M_c, H, W}``; ``frame_times``,
    ``query_speeds``, ``calibration_speeds``, ``metres_per_pixel`` and ``camera`` as
    rendered; ``failed_pushes`` (pushes that failed the simulator's checks, kept);
    ``files``: the sha256 of ``suite.npz``, ``truth.npz`` and ``table.npz``. The
    checksum of ``suite.npz`` names the suite (:attr:`Suite.checksum`).
``suite.npz`` (public; zip-compressed, byte-stable)
    The arrays of :class:`Suite`, under the same names: what a model and a readout may see.
``truth.npz`` (sealed; zip-compressed)
    The arrays of :class:`SuiteTruth`: read only when scoring (:func:`load_truth`).
``table.npz``
    A byte copy of the push table the suite is scored with (:func:`suite_table_path`), so
    a suite folder scores on its own.
``README.md``
    The layout in words, with this suite's sizes.

What is in it (sizes: N objects, K query speeds, C context frames, T frames a clip):

* N held-out objects: the first ``suite.n_objects`` objects of the study's held-out split
  ``suite.split``, drawn as :func:`imply.data.clips.sample_objects` draws them, so they
  are the study's own held-out objects. Per object the 2 calibration clips (all T frames:
  ``frame_times`` then the rest frame), and per query speed the first C frames of the
  query push; the query's rest frame and slide go to the truth only.
* The fixed partner of each object (condition ``other``):
  :func:`imply.stats.derangement` with ``suite.partner_seed``, Section 5's swap.
* Readout clips: the first ``suite.n_readout_train`` training objects' 3 clips each
  (2 calibration, 1 query, as :func:`imply.data.clips.plan_clips` plans them), frame 0 and
  the rest frame, with their speeds and slides (M = 3 n_readout_train); the next
  ``suite.n_readout_check`` training objects' 3 clips (M_c) are the check clips whose
  slides are sealed.

Every push is simulated (:func:`imply.data.clips.record_planned`) at the clips' frame
times and drawn by :class:`imply.sim.render.ClipRenderer`, as the clips rule does, so with
the study's camera a suite frame equals the frame of the same push in ``results/clips``.
Only the frames a suite holds are drawn.

:func:`load_suite` checks format, version and every checksum before it reads anything.
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from imply.evaluate.config import CONDITIONS  # noqa: F401 (re-exported: the conditions a suite serves)
from imply.options import Config, option
from imply.sim.render import CameraConfig

if TYPE_CHECKING:  # the build's settings; imported where used (pandas, the clips' planning)
    import pandas as pd

    from imply.data.clips import ClipsConfig
    from imply.score import ScoreConfig
    from imply.sim.scene import SceneConfig

log = logging.getLogger("imply.suite")

SUITE_FORMAT = "imply-suite"
SUITE_VERSION = 1

SUITE_SPLITS = ("heldout_calib", "heldout_nocalib")
FILES = ("suite.npz", "truth.npz", "table.npz")
REBUILD = "rebuild it with `snakemake --cores 2 results/suite/manifest.json` (or `imply suite build`)"
BUILD = "build one with `snakemake --cores 2 results/suite/manifest.json` (or `imply suite build`)"
EXPORT = "write one with `imply suite export SUITE -o FOLDER`"
# the clips keys a build reads (what the workflow rule passes)
CLIPS_KEYS = (
    "seed",
    "masses",
    "frictions",
    "size_scale",
    "train_speed",
    "n_train_episodes",
    "n_heldout_calib",
    "n_heldout_nocalib",
    "frame_times",
    "camera",
    "batch",
)
SUITE_ARRAYS = (
    "object_ids",
    "partner",
    "calibration_speeds",
    "calibration_frames",
    "calibration_displacement",
    "query_speeds",
    "context_frames",
    "frame_times",
    "train_frames",
    "train_speed",
    "train_displacement",
    "check_frames",
    "metres_per_pixel",
)
TRUTH_ARRAYS = ("displacement", "mass", "friction", "half_extents", "rest_frames", "check_displacement")


class SuiteError(ValueError):
    """A suite that cannot be used: missing files, another format or version, a broken checksum."""


@dataclass(frozen=True, kw_only=True)
class SuiteConfig(Config):
    """Config section ``suite``: which objects, clips and frames the evaluation suite holds.

    The objects and physics come from section ``clips`` (and the speeds from ``score``):
    a suite's objects are the study's held-out objects. ``frame_times`` and ``camera``
    left null take the clips' own.
    """

    config_key: ClassVar[str] = "suite"

    split: str = option("heldout_calib", doc="the held-out split whose objects the suite holds", choices=SUITE_SPLITS)
    n_objects: int = option(300, doc="held-out objects: the split's first n (at most its size)", minimum=2)
    n_readout_train: int = option(
        400, doc="training objects (3 clips each) whose first and rest frames fit the readouts", minimum=1
    )
    n_readout_check: int = option(
        100, doc="the next training objects (3 clips each) on which a readout's R^2 is measured", minimum=1
    )
    context_frames: int = option(1, doc="frames of each query push shown as context (fewer than a clip's)", minimum=1)
    partner_seed: int = option(
        11, doc="seed of the fixed partners (Section 5's swap: model.derangement_seed)", minimum=0
    )
    frame_times: tuple[float, ...] | None = option(
        None, doc="s, frames before the rest frame (null: clips.frame_times)", min_items=1, items={"minimum": 0}
    )
    camera: CameraConfig | None = option(None, doc="the top-down view (null: clips.camera), e.g. 256 x 256 px")

    def __post_init__(self) -> None:
        if self.frame_times is not None and self.context_frames > len(self.frame_times):
            raise ValueError(
                f"context_frames {self.context_frames} must be fewer than a clip's {len(self.frame_times) + 1} frames"
            )


@dataclass(frozen=True, eq=False)
class Suite:
    """What a model may see, for N held-out objects, K query speeds and M + M_c real readout clips.

    object_ids: (N,) str.
    partner: (N,) int64; the object whose calibration is shown in condition ``other``
      (never the object itself).
    calibration_speeds: (2,) m/s. calibration_frames: uint8 (N, 2, T, H, W, 3), the full
      calibration clips (frame_times, then the rest frame). calibration_displacement: (N, 2)
      observed slide of each calibration push, metres.
    query_speeds: (K,) m/s. context_frames: uint8 (N, K, C, H, W, 3), the first C frames
      of each query push (C = ``context_frames`` of the config; frame 0 shows the box before
      the push).
    frame_times: (T - 1,) nominal frame times (s); the T-th frame shows the box at rest.
    train_frames: uint8 (M, 2, H, W, 3), first and rest frame of real training clips;
      train_speed, train_displacement: (M,) their commanded speed and true slide (public:
      readouts are fitted on them).
    check_frames: uint8 (M_c, 2, H, W, 3), first and rest frame of real clips of other
      training objects, on which a readout's R^2 is measured (their slides are sealed).
    metres_per_pixel: the camera's scale. manifest: the parsed manifest.json.
    """

    path: Path
    manifest: dict[str, Any]
    object_ids: np.ndarray
    partner: np.ndarray
    calibration_speeds: np.ndarray
    calibration_frames: np.ndarray
    calibration_displacement: np.ndarray
    query_speeds: np.ndarray
    context_frames: np.ndarray
    frame_times: np.ndarray
    train_frames: np.ndarray
    train_speed: np.ndarray
    train_displacement: np.ndarray
    check_frames: np.ndarray
    metres_per_pixel: float

    @property
    def n_objects(self) -> int:
        return len(self.object_ids)

    @property
    def n_speeds(self) -> int:
        return len(self.query_speeds)

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        """(H, W, 3)."""
        return tuple(self.context_frames.shape[-3:])

    @property
    def checksum(self) -> str:
        """The sha256 of suite.npz as the manifest records it: names this suite in reports and caches."""
        return str(self.manifest["files"]["suite.npz"])


@dataclass(frozen=True, eq=False)
class SuiteTruth:
    """The sealed answers (truth.npz), read only when scoring.

    displacement: (N, K) true slide of each query push, metres. mass, friction: (N,).
    half_extents: (N, 3) metres. rest_frames: uint8 (N, K, H, W, 3), each query push's true
    rest frame. check_displacement: (M_c,) true slide of each check clip.
    """

    displacement: np.ndarray
    mass: np.ndarray
    friction: np.ndarray
    half_extents: np.ndarray
    rest_frames: np.ndarray
    check_displacement: np.ndarray


# -- building -----------------------------------------------------------------------


def suite_view(cfg: SuiteConfig, clips: ClipsConfig) -> tuple[tuple[float, ...], CameraConfig]:
    """The frame times and camera a suite renders with, after checking ``cfg`` against the clips settings.

    Raises :class:`SuiteError` naming the option when the suite asks for more objects
    than the clips' splits hold, or for as many context frames as a clip has.
    """
    size = clips.n_objects(cfg.split)
    if cfg.n_objects > size:
        key = "n_heldout_calib" if cfg.split == "heldout_calib" else "n_heldout_nocalib"
        raise SuiteError(
            f"suite.n_objects {cfg.n_objects} is more than the {size} objects of split {cfg.split} (clips.{key})"
        )
    readout = cfg.n_readout_train + cfg.n_readout_check
    if readout > clips.n_train_episodes:
        raise SuiteError(
            f"suite.n_readout_train + suite.n_readout_check ({cfg.n_readout_train} + {cfg.n_readout_check}) is more "
            f"than the {clips.n_train_episodes} training objects (clips.n_train_episodes)"
        )
    frame_times = tuple(cfg.frame_times if cfg.frame_times is not None else clips.frame_times)
    if any(b <= a for a, b in zip(frame_times, frame_times[1:], strict=False)):
        raise SuiteError("suite.frame_times: times must increase")
    if cfg.context_frames > len(frame_times):
        raise SuiteError(
            f"suite.context_frames {cfg.context_frames} must be fewer than a clip's {len(frame_times) + 1} frames"
        )
    return frame_times, cfg.camera if cfg.camera is not None else clips.camera


@dataclass(frozen=True)
class _Plan:
    """Every push of a suite, in one table: held-out pushes (object-major, 2 + K each), then readout, then check."""

    pushes: pd.DataFrame  # plan_clips rows: speed, mass, friction, size_x/y/z, ...
    n_objects: int
    n_speeds: int
    n_train: int  # M
    n_check: int  # M_c
    context_frames: int  # C

    @property
    def n_heldout(self) -> int:
        return self.n_objects * (2 + self.n_speeds)


def _plan(cfg: SuiteConfig, clips: ClipsConfig, scene: SceneConfig, speeds: ScoreConfig) -> _Plan:
    import pandas as pd

    from imply.data.clips import plan_clips

    held = plan_clips(clips, cfg.split, scene=scene, speeds=speeds)
    held = held[held["episode"] < cfg.n_objects]
    train = plan_clips(clips, "train", scene=scene, speeds=speeds)
    fit = train[train["episode"] < cfg.n_readout_train]
    check = train[
        (train["episode"] >= cfg.n_readout_train) & (train["episode"] < cfg.n_readout_train + cfg.n_readout_check)
    ]
    pushes = pd.concat([held, fit, check], ignore_index=True)
    return _Plan(pushes, cfg.n_objects, len(speeds.query_speeds), len(fit), len(check), cfg.context_frames)


def _simulate_and_draw(
    plan: _Plan,
    *,
    frame_times: tuple[float, ...],
    camera: CameraConfig,
    scene: SceneConfig,
    batch: int,
    nthread: int,
    progress: bool,
) -> dict[str, np.ndarray]:
    """Simulate every push of ``plan`` and draw only the frames the suite holds.

    Returns the frame arrays (calibration, context, rest, train, check) and, per push
    (P,), displacement and ok.
    """
    from tqdm.auto import tqdm

    from imply.data.clips import record_planned
    from imply.sim.render import ClipRenderer

    n, k = plan.n_objects, plan.n_speeds
    per_object = 2 + k
    n_frames = len(frame_times) + 1
    rest = n_frames - 1
    n_context = plan.context_frames
    h, w = camera.height, camera.width
    out = {
        "calibration": np.zeros((n, 2, n_frames, h, w, 3), dtype=np.uint8),
        "context": np.zeros((n, k, n_context, h, w, 3), dtype=np.uint8),
        "rest": np.zeros((n, k, h, w, 3), dtype=np.uint8),
        "train": np.zeros((plan.n_train, 2, h, w, 3), dtype=np.uint8),
        "check": np.zeros((plan.n_check, 2, h, w, 3), dtype=np.uint8),
    }

    def into(array: np.ndarray, index: tuple[int, ...]) -> Callable[[list[np.ndarray]], None]:
        def put(imgs: list[np.ndarray]) -> None:
            array[index] = np.stack(imgs)

        return put

    def frames_of(p: int) -> tuple[list[int], Callable[[list[np.ndarray]], None]]:
        """Which frames push ``p`` needs, and where they go."""
        if p < plan.n_heldout:
            obj, j = divmod(p, per_object)
            if j < 2:
                return list(range(n_frames)), into(out["calibration"], (obj, j))

            def put_query(imgs: list[np.ndarray]) -> None:
                out["context"][obj, j - 2] = np.stack(imgs[:-1])
                out["rest"][obj, j - 2] = imgs[-1]

            return [*range(n_context), rest], put_query
        m = p - plan.n_heldout
        if m < plan.n_train:
            return [0, rest], into(out["train"], (m,))
        return [0, rest], into(out["check"], (m - plan.n_train,))

    pushes = plan.pushes
    n_push = len(pushes)
    todo = [frames_of(p) for p in range(n_push)]
    n_draw = sum(len(idx) for idx, _ in todo)
    displacement = np.zeros(n_push)
    ok = np.zeros(n_push, dtype=bool)
    t_sim = t_draw = 0.0
    bar = tqdm(total=n_draw, desc="suite", unit="frame", disable=not progress, mininterval=2.0)
    with ClipRenderer(scene, camera) as renderer:
        for lo in range(0, n_push, batch):
            part = pushes.iloc[lo : lo + batch]
            t0 = time.perf_counter()
            rec = record_planned(part, frame_times, scene=scene, nthread=nthread)
            t1 = time.perf_counter()
            for j in range(len(part)):
                indices, put = todo[lo + j]
                renderer.set_object(rec.half_extents[j])
                put([renderer.render_state(rec.box_qpos[j, i], rec.pusher_q[j, i]) for i in indices])
                bar.update(len(indices))
            t_draw += time.perf_counter() - t1
            t_sim += t1 - t0
            displacement[lo : lo + len(part)] = rec.displacement
            ok[lo : lo + len(part)] = rec.ok
    bar.close()
    log.info(
        "suite: %d pushes simulated in %.1f s (%.0f pushes/s); %d frames drawn in %.1f s (%.0f frames/s); "
        "%.0f frames/s overall",
        n_push,
        t_sim,
        n_push / max(t_sim, 1e-9),
        n_draw,
        t_draw,
        n_draw / max(t_draw, 1e-9),
        n_draw / max(t_sim + t_draw, 1e-9),
    )
    return {**out, "displacement": displacement, "ok": ok}


def build_suite(
    cfg: SuiteConfig,
    *,
    clips: ClipsConfig,
    scene: SceneConfig,
    speeds: ScoreConfig,
    table_path: str | Path,
    out_dir: str | Path,
    nthread: int = 1,
    progress: bool = True,
) -> Path:
    """Simulate, draw and write the suite folder ``out_dir`` (layout in the module docstring); returns it.

    clips: :class:`imply.data.clips.ClipsConfig` (objects, frame times, camera, batch);
    scene: :class:`imply.sim.scene.SceneConfig`; speeds: :class:`imply.score.ScoreConfig`
    (calibration and query speeds); table_path: the push table, copied byte for byte.
    The folder is written in one step (:func:`imply.io.write_folder`): a folder that holds
    other files of the same names is refused (:class:`imply.io.OutputError`); a previous
    suite is replaced. The same settings give the same bytes.
    """
    import imply
    from imply.io import check_folder, write_folder, write_json, write_npz
    from imply.stats import derangement
    from imply.table import PushTable, TableError

    frame_times, camera = suite_view(cfg, clips)
    table_path, out_dir = Path(table_path), Path(out_dir)
    try:
        PushTable.load(table_path)
    except (TableError, OSError, ValueError, KeyError) as exc:
        raise SuiteError(f"{table_path}: not a push table ({exc})") from exc
    check_folder(out_dir, [*FILES, "manifest.json", "README.md"], force=True, inputs=[table_path])

    plan = _plan(cfg, clips, scene, speeds)
    t0 = time.perf_counter()
    drawn = _simulate_and_draw(
        plan,
        frame_times=frame_times,
        camera=camera,
        scene=scene,
        batch=clips.batch,
        nthread=nthread,
        progress=progress,
    )
    n, k = plan.n_objects, plan.n_speeds
    pushes = plan.pushes
    failed = int((~drawn["ok"]).sum())
    if failed:
        log.warning("suite: %d of %d pushes failed the simulator's checks (kept)", failed, len(pushes))

    held = pushes.iloc[: plan.n_heldout]
    objects = held.iloc[:: 2 + k]
    held_disp = drawn["displacement"][: plan.n_heldout].reshape(n, 2 + k)
    fit = slice(plan.n_heldout, plan.n_heldout + plan.n_train)
    check = slice(plan.n_heldout + plan.n_train, len(pushes))
    public = {
        "object_ids": objects["object_id"].to_numpy(dtype=str),
        "partner": derangement(n, cfg.partner_seed),
        "calibration_speeds": np.asarray(speeds.calibration_speeds, dtype=float),
        "calibration_frames": drawn["calibration"],
        "calibration_displacement": held_disp[:, :2].copy(),
        "query_speeds": np.asarray(speeds.query_speeds, dtype=float),
        "context_frames": drawn["context"],
        "frame_times": np.asarray(frame_times, dtype=float),
        "train_frames": drawn["train"],
        "train_speed": pushes["speed"].to_numpy(dtype=float)[fit],
        "train_displacement": drawn["displacement"][fit],
        "check_frames": drawn["check"],
        "metres_per_pixel": np.float64(camera.metres_per_pixel),
    }
    truth = {
        "displacement": held_disp[:, 2:].copy(),
        "mass": objects["mass"].to_numpy(dtype=float),
        "friction": objects["friction"].to_numpy(dtype=float),
        "half_extents": objects[["size_x", "size_y", "size_z"]].to_numpy(dtype=float),
        "rest_frames": drawn["rest"],
        "check_displacement": drawn["displacement"][check],
    }
    sizes = {
        "N": n,
        "K": k,
        "C": cfg.context_frames,
        "T": len(frame_times) + 1,
        "M": plan.n_train,
        "M_c": plan.n_check,
        "H": camera.height,
        "W": camera.width,
    }

    def write(tmp: Path) -> None:
        import mujoco

        write_npz(tmp / "suite.npz", compressed=True, **public)
        write_npz(tmp / "truth.npz", compressed=True, **truth)
        shutil.copyfile(table_path, tmp / "table.npz")
        clip_settings = clips.to_dict()
        manifest = {
            "format": SUITE_FORMAT,
            "version": SUITE_VERSION,
            "imply_version": imply.__version__,
            "mujoco_version": mujoco.__version__,
            "config": {
                "suite": cfg.to_dict(),
                "clips": {key: clip_settings[key] for key in CLIPS_KEYS},
                "scene": scene.to_dict(),
                "score": {
                    "calibration_speeds": list(speeds.calibration_speeds),
                    "query_speeds": list(speeds.query_speeds),
                },
            },
            "split": cfg.split,
            "sizes": sizes,
            "frame_times": list(frame_times),
            "query_speeds": list(speeds.query_speeds),
            "calibration_speeds": list(speeds.calibration_speeds),
            "metres_per_pixel": camera.metres_per_pixel,
            "camera": camera.to_dict(),
            "failed_pushes": failed,
            "files": {name: _sha256(tmp / name) for name in FILES},
        }
        write_json(tmp / "manifest.json", manifest)
        (tmp / "README.md").write_text(_readme(sizes, cfg.split))

    write_folder(out_dir, write, force=True)
    log.info("suite: written to %s in %.1f s", out_dir, time.perf_counter() - t0)
    return out_dir


def _readme(sizes: dict[str, int], split: str) -> str:
    s = sizes
    return (
        "# IMPLY evaluation suite\n\n"
        f"Written by `imply suite build` (format {SUITE_FORMAT}, version {SUITE_VERSION}); the layout is documented "
        "in `imply.evaluate.suite`. Read it with `imply.evaluate.suite.load_suite`, which checks every checksum.\n\n"
        f"- `manifest.json`: format, version, settings, sizes, frame times, speeds, camera, and the sha256 of "
        "each .npz file.\n"
        f"- `suite.npz` (public): {s['N']} held-out objects of split `{split}`, each with its 2 calibration clips "
        f"({s['T']} frames of {s['H']} x {s['W']} px, the last at rest) and the first {s['C']} frame(s) of its "
        f"query push at each of {s['K']} speeds; each object's fixed partner for the other-object condition; "
        f"first and rest frames of {s['M']} real training clips with their speeds and slides (readout fitting) "
        f"and of {s['M_c']} check clips (readout R^2).\n"
        "- `truth.npz` (sealed, read only when scoring): the query pushes' true slides and rest frames, each "
        "object's mass, friction and half-extents, the check clips' slides.\n"
        "- `table.npz`: a byte copy of the push table the suite is scored with.\n"
    )


# -- reading ------------------------------------------------------------------------


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _check_file(folder: Path, manifest: dict[str, Any], name: str) -> Path:
    path = folder / name
    if not path.is_file():
        raise SuiteError(f"{folder}: {name} is missing; {REBUILD}")
    if _sha256(path) != manifest["files"][name]:
        raise SuiteError(f"{path}: checksum differs from the manifest's (the file was changed or broken); {REBUILD}")
    return path


def read_manifest(path: str | Path, *, kind: str = SUITE_FORMAT, what: str = "suite") -> dict[str, Any]:
    """The manifest.json of folder ``path``, of format ``kind`` (a suite's, or ``imply suite export``'s package's),
    read and its format checked (:class:`SuiteError` naming the file); a suite's version and file list too (no
    checksums)."""
    folder = Path(path)
    if not folder.is_dir():
        raise SuiteError(f"{folder}: no {what} here (not a folder); {BUILD if kind == SUITE_FORMAT else EXPORT}")
    file = folder / "manifest.json"
    if not file.is_file():
        raise SuiteError(f"{folder}: manifest.json is missing (not a {what}, or an unfinished one)")
    try:
        manifest = json.loads(file.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise SuiteError(f"{file}: not valid JSON ({exc})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != kind:
        raise SuiteError(f"{folder}: manifest.json is not an {kind} manifest")
    if kind != SUITE_FORMAT:
        return manifest
    if manifest.get("version") != SUITE_VERSION:
        raise SuiteError(
            f"{folder}: suite version {manifest.get('version')}; this imply reads version {SUITE_VERSION}; {REBUILD}"
        )
    files = manifest.get("files")
    if not isinstance(files, dict) or any(not isinstance(files.get(name), str) for name in FILES):
        raise SuiteError(f"{file}: 'files' must give the sha256 of {', '.join(FILES)}")
    return manifest


def _arrays(path: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [name for name in names if name not in z.files]
            if missing:
                raise SuiteError(f"{path}: lacks array(s) {', '.join(missing)}")
            return {name: z[name] for name in names}
    except (OSError, ValueError) as exc:
        if isinstance(exc, SuiteError):
            raise
        raise SuiteError(f"{path}: cannot be read ({exc})") from exc


def load_suite(path: str | Path) -> Suite:
    """The suite in folder ``path``: format, version and every file's checksum checked first (:class:`SuiteError`)."""
    folder = Path(path)
    manifest = read_manifest(folder)
    for name in FILES:
        _check_file(folder, manifest, name)
    arrays = _arrays(folder / "suite.npz", SUITE_ARRAYS)
    arrays["metres_per_pixel"] = float(arrays["metres_per_pixel"])
    return Suite(path=folder, manifest=manifest, **arrays)


def load_truth(suite: Suite) -> SuiteTruth:
    """The sealed truth of ``suite`` (its checksum checked again: the file is read only now)."""
    path = _check_file(suite.path, suite.manifest, "truth.npz")
    return SuiteTruth(**_arrays(path, TRUTH_ARRAYS))


def suite_table_path(suite: Suite) -> Path:
    """The suite's own copy of the push table (its checksum checked)."""
    return _check_file(suite.path, suite.manifest, "table.npz")

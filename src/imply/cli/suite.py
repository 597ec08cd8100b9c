"""``imply suite build`` and ``imply suite show``: the frozen evaluation suite that ``imply evaluate`` scores models on."""

from __future__ import annotations

import argparse
import logging

from imply.cli.common import config_from_json, int_range, json_arg, output_dir, positive_float, user_errors

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("suite", help="the frozen evaluation suite of imply evaluate")
    ssub = s.add_subparsers(dest="suite_command", required=True)
    b = ssub.add_parser(
        "build", help="simulate and render the suite: manifest.json, suite.npz, truth.npz, table.npz, README.md"
    )
    b.add_argument("--suite-json", type=json_arg, help="config section 'suite' as JSON (default: its defaults)")
    b.add_argument("--clips-json", type=json_arg, help="config section 'clips' as JSON (default: its defaults)")
    b.add_argument("--scene-json", type=json_arg, help="config section 'scene' as JSON (default: its defaults)")
    b.add_argument(
        "--score-json", type=json_arg, help="calibration_speeds and query_speeds as JSON (default: the study's)"
    )
    b.add_argument("--table", required=True, help="the push table (.npz of imply table build), copied into the suite")
    b.add_argument("--threads", type=int_range(1), default=1, help="simulation threads")
    b.add_argument(
        "-o",
        "--output",
        required=True,
        help="the suite folder to write: manifest.json, suite.npz, truth.npz, table.npz, README.md "
        "(a previous suite there is replaced)",
    )
    b.set_defaults(func=cmd_build)
    e = ssub.add_parser(
        "export",
        help="the suite as files for a model in any environment: context frames (PNG), calibration pushes (MP4 and "
        "PNG), cases.csv and cases.json naming the video each case must produce; never the truth",
    )
    e.add_argument("suite", help="the suite folder")
    e.add_argument(
        "-o",
        "--output",
        required=True,
        help="the package folder to write (new or empty): manifest.json, cases.csv, cases.json, the context "
        "frames and calibration videos",
    )
    e.add_argument("--size", type=_size, help="HEIGHTxWIDTH of the exported frames (default: the suite's camera)")
    e.add_argument("--fps", type=positive_float, default=30.0, help="frame rate of the videos (default %(default)g)")
    e.add_argument(
        "--conditions",
        default="own,other,none",
        help="calibration conditions to export cases of, comma-separated (default %(default)s)",
    )
    e.set_defaults(func=cmd_export)
    w = ssub.add_parser("show", help="check a suite's checksums and print its sizes, camera and settings")
    w.add_argument("suite", help="the suite folder")
    w.set_defaults(func=cmd_show)


def cmd_build(args: argparse.Namespace) -> int:
    from imply.data.clips import ClipsConfig
    from imply.evaluate.suite import SuiteConfig, SuiteError, build_suite
    from imply.io import OutputError
    from imply.score import ScoreConfig
    from imply.sim import SceneConfig

    out = output_dir(args.output)
    cfg = config_from_json(SuiteConfig, args.suite_json, "--suite-json")
    clips = config_from_json(ClipsConfig, args.clips_json, "--clips-json")
    speeds = config_from_json(ScoreConfig, args.score_json, "--score-json")
    scene = config_from_json(SceneConfig, args.scene_json, "--scene-json")
    with user_errors(SuiteError, OutputError):
        build_suite(
            cfg, clips=clips, scene=scene, speeds=speeds, table_path=args.table, out_dir=out, nthread=args.threads
        )
    return 0


def _size(text: str) -> tuple[int, int]:
    """HEIGHTxWIDTH, or one number for a square."""
    parts = text.lower().split("x")
    try:
        h, w = (int(parts[0]), int(parts[0])) if len(parts) == 1 else (int(parts[0]), int(parts[1]))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not HEIGHTxWIDTH (e.g. 256x256)") from None
    if len(parts) > 2 or h < 2 or w < 2:
        raise argparse.ArgumentTypeError(f"{text!r} is not HEIGHTxWIDTH (e.g. 256x256)")
    return h, w


def cmd_export(args: argparse.Namespace) -> int:
    from imply.evaluate.config import parse_conditions
    from imply.evaluate.suite import SuiteError, load_suite
    from imply.evaluate.video_package import export_package

    with user_errors(ValueError, message="--conditions: {error}"):
        conditions = parse_conditions(args.conditions)
    with user_errors(SuiteError, message="{error}"):
        suite = load_suite(args.suite)
    with user_errors(ValueError):
        m = export_package(suite, output_dir(args.output), conditions=conditions, size=args.size, fps=args.fps)
    log.info(
        "exported %d cases (%dx%d px, %g fps) -> %s",
        m["n_cases"],
        m["size"]["height"],
        m["size"]["width"],
        m["fps"],
        args.output,
    )
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from imply.evaluate.suite import SuiteError, load_suite

    with user_errors(SuiteError):
        suite = load_suite(args.suite)
    m = suite.manifest
    s = m["sizes"]
    cam = m["camera"]
    lines = [
        f"suite {suite.path}: {m['format']} version {m['version']}, built by imply {m['imply_version']}",
        f"  objects    {s['N']} of split {m['split']}, each with 2 calibration clips of {s['T']} frames",
        f"  queries    {s['K']} speeds ({', '.join(f'{v:g}' for v in m['query_speeds'])} m/s), "
        f"{s['C']} context frame(s) each",
        f"  readout    {s['M']} training clips, {s['M_c']} check clips (first and rest frames)",
        f"  frames     {s['H']} x {s['W']} px at times {', '.join(f'{t:g}' for t in m['frame_times'])} s, then at rest",
        f"  camera     x {cam['x_min']:g} to {cam['x_max']:g} m, {m['metres_per_pixel']:.4g} m per pixel, "
        f"multisample {cam['multisample']}, supersample {cam['supersample']}",
        f"  failed     {m['failed_pushes']} push(es) failed the simulator's checks",
        f"  checksums  OK ({', '.join(m['files'])}); suite sha256 {suite.checksum}",
    ]
    print("\n".join(lines))
    return 0

"""``imply sim export-xml|pushes``: the push scene as MJCF, and pushes simulated on it (or on a user's MJCF)."""

from __future__ import annotations

import argparse
import logging

from imply.cli.common import (
    UserError,
    add_scene_options,
    int_range,
    output_file,
    positive_float,
    scene_from_args,
    user_errors,
)

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("sim", help="the push scene: export MJCF, simulate pushes")
    ssub = s.add_subparsers(dest="sim_command", required=True)
    ex = ssub.add_parser(
        "export-xml",
        help="write the scene's MJCF for one object",
        description="OBJECT settings are key=value: mass=KG friction=MU size=HX,HY,HZ (half-extents, m).",
    )
    ex.add_argument("object", nargs="*", metavar="OBJECT", help="key=value settings of the box")
    add_scene_options(ex)
    ex.add_argument("-o", "--output", required=True, help="the MJCF file to write (.xml)")
    ex.set_defaults(func=cmd_export_xml)

    pu = ssub.add_parser(
        "pushes",
        help="simulate pushes and write a push log",
        description=(
            "Reads PUSHES (object_id,speed and optional mass,friction,size_x,size_y,size_z) and writes a push "
            "log object_id,speed,displacement,stop_time plus the physics used (with --track-rate the boxes' tracks, "
            "with --probes the calibration probes, each in a file beside it). With --model, the pushes run "
            "on that MJCF (it must name body/geom 'box' with a free joint, slide joint 'push', velocity "
            "actuator 'servo', and <custom><numeric name='stroke'>)."
        ),
    )
    pu.add_argument("pushes", help="CSV of pushes to simulate")
    pu.add_argument("--model", help="user MJCF file (default: the built-in scene)")
    add_scene_options(pu)
    pu.add_argument(
        "-o",
        "--output",
        required=True,
        help="the push log to write (.csv); --track-rate and --probes write files beside it",
    )
    pu.add_argument(
        "--track-rate",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="also film each push: the box's track at HZ frames per second, written beside the log as "
        "<output stem>.track.csv (where `imply diagnose` finds it)",
    )
    pu.add_argument(
        "--probes",
        action="store_true",
        help="also run the calibration probes a lab would (a free stroke at every speed, a pull test of every object's "
        "friction, every object pushed with a load of half its mass at its lowest and highest speed), written beside "
        "the log as <output stem>.probes.csv (where `imply diagnose` finds it; format: the formats reference)",
    )
    pu.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    pu.set_defaults(func=cmd_pushes)


def parse_object_settings(items: list[str]) -> dict:
    settings: dict = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise UserError(f"OBJECT setting {item!r} is not key=value")
        with user_errors(ValueError, message=f"OBJECT setting {item!r}: bad value"):
            if key == "size":
                parts = [float(x) for x in value.split(",")]
                if len(parts) != 3 or not all(0 < x < float("inf") for x in parts):
                    raise ValueError
                settings["half_extents"] = tuple(parts)
            elif key in ("mass", "friction"):
                settings[key] = float(value)
                if not 0 < settings[key] < float("inf"):
                    raise ValueError
            else:
                raise UserError(f"unknown OBJECT setting {key!r} (use mass, friction, size)")
    return settings


def cmd_export_xml(args: argparse.Namespace) -> int:
    import mujoco

    from imply.io import write_text
    from imply.sim import build_xml

    output = output_file(args.output, [getattr(args, "config", None)])
    scene = scene_from_args(args)
    xml = build_xml(scene, **parse_object_settings(args.object))
    with user_errors(ValueError, message="the scene does not compile: {error}"):
        mujoco.MjModel.from_xml_string(xml)  # fail here, not in the user's hands
    write_text(output, xml)
    log.info("wrote %s", output)
    return 0


def cmd_pushes(args: argparse.Namespace) -> int:
    from imply.input_files import InputError
    from imply.io import write_csv
    from imply.realworld.probes import simulate_probe_table
    from imply.sim.push_file import load_push_model, read_pushes, simulate_push_table

    output = output_file(args.output, [args.pushes, args.model, getattr(args, "config", None)])
    # an InputError is a ValueError too: the inner one names the file's row and column
    with user_errors(ValueError, message="--model {error}"), user_errors(InputError):
        pushes = read_pushes(args.pushes)
        model = load_push_model(args.model) if args.model else None
    scene = scene_from_args(args) if model is None else None
    with user_errors(KeyError, ValueError, message="cannot simulate on this model: {error}"), user_errors(InputError):
        log_frame, track = simulate_push_table(
            pushes, model=model, scene=scene, nthread=args.threads, progress=True, track_rate=args.track_rate
        )
    if args.probes:
        probes_path = output.with_name(f"{output.stem}.probes.csv")
        with user_errors(KeyError, ValueError, message="cannot run the probes on this model: {error}"):
            probes = simulate_probe_table(pushes, log_frame, model=model, scene=scene, nthread=args.threads)
        write_csv(probes_path, probes)
        log.info("%d calibration probes -> %s", len(probes), probes_path)
    if track is not None:
        track_path = output.with_name(f"{output.stem}.track.csv")
        write_csv(track_path, track)
        log.info("the boxes' tracks at %g frames per second -> %s", args.track_rate, track_path)
    write_csv(output, log_frame)
    log.info("simulated %d pushes (%d failed checks) -> %s", len(log_frame), int((~log_frame["ok"]).sum()), output)
    return 0

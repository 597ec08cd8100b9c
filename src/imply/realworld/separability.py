"""Is a log's effect separable from its contact's difference? Marked per log and per observable set, from its label.

A log from a world whose contact is not the table's carries two departures from the
table: the effect (if any) and the contact's difference. The diagnostic fits every
object's mass and friction, so what either can show is what is left of it after that
fit. For each effect log, with the noise-free observables its label holds
(:mod:`imply.realworld.lab`):

- the effect's signature ``s_e``: the log's world minus the same world without the
  effect;
- the contact's signature ``s_c``: the world without the effect minus the nominal MuJoCo
  world (the table's physics, converged) at the objects' true masses and frictions;
- both in noise sds (each observable over its noise sd, shrunk by the replicates), with
  the per-object fit projected out: the directions in which the nominal world's
  observables move with each object's log mass and log friction (finite differences; the
  mass's only where the log does not weigh its objects).

A push (a probe) counts where every run read (:func:`imply.realworld.lab.marked_runs`)
simulated it cleanly.

The effect is **separable** from its contact under an observable set when the cosine of
the two projected signatures is below ``alias_cos`` in absolute value (as the
diagnostic's aliasing marks two effects one class), and **big** when its projected
displacement signature is at least ``min_size_sd`` noise sds RMS (the benchmark's
threshold for effects that count). Observable sets, each adding to the one before:
:data:`OBSERVABLE_SETS`.

The cosine alone does not say how far the contact moves the effect's estimate: a contact
many times the effect's size leaks into it even at a small angle. Fitting the effect's
amplitude alone to both signatures, with the contact left unmodelled, misses it by the
**leak** ``cos * |s_c| / |s_e|`` (relative), and the effect is **readable** under an
observable set when the leak is below ``within`` (the benchmark's magnitude tolerance).

On null logs the contact's projected displacement signature is the engine's **null gap**
against the table (RMS over pushes, in noise sds and in log d).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from imply.io import write_text
from imply.realworld.lab import JACOBIAN_STEP, fitted_runs, marked_runs

# what each observable set holds: d displacement, t stop time, p the pusher's measured speed, c the track's crossing
# times, probes: free strokes, friction measurements and added-mass pushes
OBSERVABLE_SETS: dict[str, tuple[str, ...]] = {
    "displacement": ("d",),
    "stop_time": ("d", "t"),
    "pusher_track": ("d", "t", "p", "c"),
    "probes": ("d", "t", "p", "c", "probes"),
}
SET_WORDS = {
    "displacement": "displacement only",
    "stop_time": "+ stop time",
    "pusher_track": "+ pusher speed and track",
    "probes": "+ probes",
}


def _pieces(
    nf: Mapping, label: Mapping, keep: np.ndarray, keep_probe: np.ndarray, parts: tuple[str, ...], crossing_sd: float
) -> tuple[np.ndarray, np.ndarray]:
    """One run's observables of ``parts`` in noise sds, (k,), and the object each belongs to, (k,) (-1: none)."""
    noise = label["noise"]
    reps = math.sqrt(label.get("replicates", 1))
    names = list(label["objects"])
    obj = np.array([names.index(o) for o in label["pushes"]["object"]])[keep]
    values, owners = [], []
    if "d" in parts:
        values.append(np.asarray(nf["log_d"])[keep] / (noise["sd"] / reps))
        owners.append(obj)
    if "t" in parts:
        values.append(np.asarray(nf["log_t"])[keep] / (noise["stop_time_sd"] / reps))
        owners.append(obj)
    if "p" in parts:
        values.append(np.asarray(nf["log_p"])[keep] / (noise["pusher_speed_sd"] / reps))
        owners.append(obj)
    if "c" in parts:
        c = np.asarray(nf["log_c"], float)[keep]
        values.append((c / (crossing_sd / reps)).ravel())
        owners.append(np.repeat(obj, c.shape[1]))
    if "probes" in parts:
        pr = nf["probes"]
        kind = np.asarray(pr["kind"])[keep_probe]
        pobj = np.asarray(pr["object"], int)[keep_probe]
        strokes = math.sqrt(label.get("free_strokes", 1))
        for key, sd, kinds in (
            ("log_p", noise["pusher_speed_sd"] / strokes, ("free_stroke",)),
            ("log_p", noise["pusher_speed_sd"] / reps, ("added_mass",)),
            ("reading", noise["friction_sd"], ("friction",)),
            ("log_d", noise["sd"] / reps, ("added_mass",)),
            ("log_t", noise["stop_time_sd"] / reps, ("added_mass",)),
        ):
            sel = np.isin(kind, kinds)
            values.append(np.asarray(pr[key], float)[keep_probe][sel] / sd)
            owners.append(pobj[sel])
    return np.concatenate(values), np.concatenate(owners)


def _kept(label: Mapping, runs: tuple[str, ...], probes: bool) -> tuple[np.ndarray, np.ndarray]:
    """Pushes, and with ``probes`` probes (else none), every run of ``runs`` simulated cleanly (finite crossing times
    included)."""
    nf = label["noise_free"]
    keep = np.all([np.asarray(nf[r]["ok"], bool) for r in runs], axis=0)
    keep &= np.all([np.isfinite(np.asarray(nf[r]["log_c"], float)).all(axis=1) for r in runs], axis=0)
    keep_probe = (
        np.all([np.asarray(nf[r]["probes"]["ok"], bool) for r in runs], axis=0) if probes else np.zeros(0, bool)
    )
    return keep, keep_probe


def _fit_directions(label: Mapping, keep, keep_probe, parts, crossing_sd) -> np.ndarray:
    """(k, 2 n_obj) the per-object fit's directions (log mass, log friction), zero outside each object's rows."""
    nf = label["noise_free"]
    base, owner = _pieces(nf["table"], label, keep, keep_probe, parts, crossing_sd)
    cols = []
    for what in fitted_runs(bool(label.get("measured_mass"))):
        moved, _ = _pieces(nf[what], label, keep, keep_probe, parts, crossing_sd)
        slope = (moved - base) / JACOBIAN_STEP
        for i in range(len(label["objects"])):
            cols.append(np.where(owner == i, slope, 0.0))
    return np.stack(cols, axis=1)


def _residual(J: np.ndarray, s: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(J, s, rcond=None)
    return s - J @ coef


def mark_log(label: Mapping, *, alias_cos: float, min_size_sd: float, crossing_sd: float, within: float = 0.3) -> dict:
    """One log's marking: for an effect log, per observable set, the cosine, whether separable, the effect's and
    the contact's projected sizes (noise sds, norm); for a null log, its contact's null gap."""
    effects = label["effects"]
    # the runs it reads, and only theirs decide which pushes count: a push the fit's unused log-mass run lost is kept
    runs = marked_runs(bool(effects), bool(label.get("measured_mass")))
    keep, keep_probe = _kept(label, runs, probes=bool(effects))
    reps = math.sqrt(label.get("replicates", 1))
    out = {
        "id": label["id"],
        "group": label["group"],
        "engine": label.get("engine", "mujoco"),
        "contact": label.get("contact", {}).get("kinds", []),
        "probes": bool(label.get("probes")),
        "effect": effects[0]["name"] if effects else None,
        "in_library": bool(effects[0]["in_library"]) if effects else None,
        "magnitude": effects[0]["magnitude"] if effects else None,
    }
    nf = label["noise_free"]
    if not effects:
        parts = OBSERVABLE_SETS["displacement"]
        J = _fit_directions(label, keep, keep_probe, parts, crossing_sd)
        gap = _pieces(nf["all"], label, keep, keep_probe, parts, crossing_sd)[0]
        gap = gap - _pieces(nf["table"], label, keep, keep_probe, parts, crossing_sd)[0]
        r = _residual(J, gap) / reps  # per push, in one push's noise sds
        rms_sd = float(np.sqrt(np.mean(r**2)))
        out["null_gap_sd"] = rms_sd
        out["null_gap_log_d"] = rms_sd * label["noise"]["sd"]
        return out
    sets = {}
    for name, parts in OBSERVABLE_SETS.items():
        J = _fit_directions(label, keep, keep_probe, parts, crossing_sd)
        v = {r: _pieces(nf[r], label, keep, keep_probe, parts, crossing_sd)[0] for r in ("all", "contact", "table")}
        re = _residual(J, v["all"] - v["contact"])
        rc = _residual(J, v["contact"] - v["table"])
        ne, nc = float(np.linalg.norm(re)), float(np.linalg.norm(rc))
        cos = float(re @ rc / (ne * nc)) if ne > 0 and nc > 0 else 0.0
        sets[name] = {
            "cos": cos,
            "separable": bool(abs(cos) < alias_cos),
            "effect_sd": ne,
            "contact_sd": nc,
            "apart_sd": ne * math.sqrt(max(0.0, 1.0 - cos * cos)),
            "leak": cos * nc / ne if ne > 0 else math.inf,
        }
        sets[name]["readable"] = bool(abs(sets[name]["leak"]) < within)
    # big: the effect's displacement signature after the fit, RMS per push in one push's noise sds
    J = _fit_directions(label, keep, keep_probe, ("d",), crossing_sd)
    d = {r: _pieces(nf[r], label, keep, keep_probe, ("d",), crossing_sd)[0] for r in ("all", "contact")}
    visible = float(np.sqrt(np.mean((_residual(J, d["all"] - d["contact"]) / reps) ** 2)))
    out.update(visible_sd=visible, big=bool(visible >= min_size_sd), sets=sets)
    return out


def mark_logs(
    labels: Mapping[str, Mapping], *, alias_cos: float, min_size_sd: float, crossing_sd: float, within: float = 0.3
) -> list:
    """:func:`mark_log` for every log, in the labels' order (``within``: the readable leak's bound)."""
    return [
        mark_log(lab, alias_cos=alias_cos, min_size_sd=min_size_sd, crossing_sd=crossing_sd, within=within)
        for lab in labels.values()
    ]


def summarise(marks: list[dict]) -> dict:
    """Per engine (and ``all``), per observable set: effect logs, big ones, separable ones, big and separable; and
    each engine's null gap (median and largest over its null logs)."""
    engines = list(dict.fromkeys(m["engine"] for m in marks))
    out: dict[str, dict] = {}
    for engine in [*engines, "all"]:
        mine = [m for m in marks if engine in ("all", m["engine"])]
        eff = [m for m in mine if m["effect"] is not None]
        row = {"effect_logs": len(eff), "big": sum(m["big"] for m in eff), "sets": {}}
        for name in OBSERVABLE_SETS:
            sep = [m for m in eff if m["sets"][name]["separable"]]
            row["sets"][name] = {
                "separable": len(sep),
                "big_separable": sum(m["big"] for m in sep),
                "share": len(sep) / len(eff) if eff else math.nan,
                "big_share": (sum(m["big"] for m in sep) / row["big"]) if row["big"] else math.nan,
                "readable": sum(m["sets"][name]["readable"] for m in eff),
                "big_readable": sum(m["big"] and m["sets"][name]["readable"] for m in eff),
            }
        nulls = [m["null_gap_sd"] for m in mine if m["effect"] is None]
        row["null_logs"] = len(nulls)
        row["null_gap_sd_median"] = float(np.median(nulls)) if nulls else math.nan
        row["null_gap_sd_max"] = float(np.max(nulls)) if nulls else math.nan
        out[engine] = row
    return out


def _cell(value: float, digits: int = 2) -> str:
    return "–" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}f}"


def _count_table(summary: Mapping, what: str, title: str) -> list[str]:
    """A report table of how many effect logs are ``what`` (``separable`` or ``readable``; the big ones in brackets),
    per world and observable set."""
    lines = [
        title,
        "",
        "| world | effect logs (big) | " + " | ".join(SET_WORDS[s] for s in OBSERVABLE_SETS) + " |",
        "|---|---|" + "---|" * len(OBSERVABLE_SETS),
    ]
    for engine, row in summary.items():
        cells = [f"{row['sets'][s][what]} ({row['sets'][s][f'big_{what}']})" for s in OBSERVABLE_SETS]
        lines.append(f"| {engine} | {row['effect_logs']} ({row['big']}) | " + " | ".join(cells) + " |")
    return lines


def separability_markdown(result: Mapping) -> str:
    """The separability report: per set, a table by engine and observable set, the null gaps, each world's time
    per push, and every log's marking."""
    lines = [
        "# Lab benchmark: is each effect separable from its contact?",
        "",
        "Each effect log's effect signature against its contact's, both after the per-object fit of mass and "
        "friction, in noise sds: separable when |cos| < "
        f"{result['alias_cos']:g}; big when its displacement signature is at least {result['min_size_sd']:g} "
        "noise sds RMS; readable when the contact, left unmodelled, moves the effect's fitted amplitude by less "
        f"than {result.get('within', 0.3):g} of it (the leak, cos x |contact| / |effect|). The development set "
        "is the one choices may be made on; the sealed set adds the SAPIEN world, on which none was made.",
        "",
    ]
    for set_name, data in result["sets"].items():
        lines += [f"## The {set_name} set ({len(data['logs'])} logs)", ""]
        lines += _count_table(
            data["summary"],
            "separable",
            "Separable effect logs (big and separable in brackets), by world and observable set:",
        )
        lines += [""]
        lines += _count_table(
            data["summary"],
            "readable",
            "Readable effect logs (big and readable in brackets): the contact's leak into the effect's amplitude "
            "below the tolerance:",
        )
        lines += [
            "",
            "Null gap against the table's physics (RMS over pushes after the per-object fit):",
            "",
            "| world | null logs | median (noise sds) | largest (noise sds) |",
            "|---|---|---|---|",
        ]
        for engine, row in data["summary"].items():
            lines.append(
                f"| {engine} | {row['null_logs']} | {_cell(row['null_gap_sd_median'], 1)} | "
                f"{_cell(row['null_gap_sd_max'], 1)} |"
            )
        lines += ["", "Time per push, per world (s):", "", "| world | pushes | s per push |", "|---|---|---|"]
        for engine, t in data["timing"].items():
            lines.append(f"| {engine} | {t['pushes']} | {t['seconds_per_push']:.4f} |")
        lines += [
            "",
            "Every log (cos and leak per observable set; * separable, r readable):",
            "",
            "| log | world | contact | probes | effect | visible (sd) | "
            + " | ".join(SET_WORDS[s] for s in OBSERVABLE_SETS)
            + " |",
            "|---|---|---|---|---|---|" + "---|" * len(OBSERVABLE_SETS),
        ]
        for m in data["logs"]:
            if m["effect"] is None:
                cells = ["null gap " + _cell(m["null_gap_sd"], 1) + " sd"] + [""] * (len(OBSERVABLE_SETS) - 1)
                effect, visible = "none", "–"
            else:
                cells = [
                    f"{m['sets'][s]['cos']:+.2f}{'*' if m['sets'][s]['separable'] else ''}, "
                    f"{m['sets'][s]['leak']:+.2g}{' r' if m['sets'][s]['readable'] else ''}"
                    for s in OBSERVABLE_SETS
                ]
                effect, visible = f"{m['effect']} {m['magnitude']:.3g}", _cell(m["visible_sd"], 1)
            contact = ", ".join(m["contact"]) or "its engine's"
            lines.append(
                f"| {m['id']} | {m['engine']} | {contact} | {'yes' if m['probes'] else 'no'} | {effect} | "
                f"{visible} | " + " | ".join(cells) + " |"
            )
        lines.append("")
    return "\n".join(lines)


def write_separability(result: Mapping, markdown_path) -> None:
    write_text(markdown_path, separability_markdown(result))

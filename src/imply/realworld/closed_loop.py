"""The next experiments, checked in a closed loop on the other-contact and the lab benchmarks' worlds.

For every log whose verdict keeps several explanations in contention (a set of
hypotheses, whatever it states), the pushes its report recommends
(``next_pushes.csv``) are run in the same world (its objects, contact model, engine and
effects, the log's protocol and noise: :func:`imply.realworld.cases.extra_pushes`),
appended to the log, and the log is diagnosed again. Where probes are allowed (the lab
benchmark), the calibration probe the report recommends (``next_probes.csv``) is run too
(:func:`imply.realworld.lab.extra_probes`) and appended to the log's probes file. The
baseline arm appends as many pushes drawn at random from the log's own design (its
distinct object, speed and direction; one more for each probe the other arm ran), run
the same way. :func:`run_closed_loop` writes both arms' logs and reports;
:func:`score_closed_loop` scores them against the sealed labels: how often the true effect
is then stated as the one cause with its magnitude within the target's tolerance (one-effect
logs; beside it, how often the true effect's own hypothesis has its magnitude within that
whatever the verdict, :func:`imply.realworld.benchmark.told_error`), how often a null log
states no library effect, and how often an effect outside the library is stated as a library
mechanism's one cause.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from imply.diagnose.analysis import Summary
from imply.diagnose.conclusion.verdict import Identification
from imply.diagnose.run import Report, Session, diagnose_report, read_checked_pushlog
from imply.io import write_csv, write_json
from imply.realworld.benchmark import (
    CONTACT_NULL,
    CONTACT_OUTSIDE,
    CONTACT_SINGLE,
    effect_size_on_contact,
    stated_error,
    told_within,
)
from imply.realworld.cases import ContactBenchmarkConfig, extra_pushes, object_names
from imply.realworld.lab import LabBenchmarkConfig, extra_probes
from imply.sim.scene import SceneConfig

log = logging.getLogger("imply.diagnose")

ARMS = {"next": 1, "random": 2}  # arm -> the seed of its noise draws (beside the log's own)


def _summary(folder: Path) -> Summary:
    with open(folder / "summary.json") as fh:
        return Summary.from_dict(json.load(fh))


def _log_design(frame: pd.DataFrame, n: int, rng: np.random.Generator) -> pd.DataFrame:
    """``n`` distinct pushes (object, speed, direction) of the log's own, drawn at random."""
    design = frame[["object_id", "speed", "direction"]].drop_duplicates().reset_index(drop=True)
    return design.iloc[np.sort(rng.choice(len(design), size=min(n, len(design)), replace=False))]


def _probes_file(path: Path) -> Path:
    return path.with_name(path.stem + ".probes.csv")


def run_closed_loop(
    *,
    design: ContactBenchmarkConfig,
    drawn: list[dict],
    scene: SceneConfig,
    logs: Path,
    reports: Path,
    session: Session,
    out: Path,
    references: Path | None = None,
    nthread: int = 0,
    progress: bool = True,
) -> list[dict]:
    """Both arms for every log of ``reports`` with several contenders (one report folder per log of ``logs``;
    ``drawn``: the benchmark's cases, :func:`imply.realworld.cases.draw_cases` or
    :func:`imply.realworld.lab.draw_lab_cases`): the appended logs (and probes files) in ``out/logs``, their reports
    in ``out/reports``; returns one row per log and arm. Probes are run where ``design`` is a lab benchmark's. With
    ``references`` (a folder of each log's reference session, under its file name), every diagnosis is against the
    log's reference: the new pushes are ones the reference never ran, so their standing gap is its fit's."""
    probes_allowed = isinstance(design, LabBenchmarkConfig)
    cases = {c["id"]: c for c in drawn}
    # the random arm's draws follow the log's place in the benchmark, not in this job's share of it
    number = {c["id"]: k for k, c in enumerate(drawn)}
    index = {name: i for i, name in enumerate(object_names(design.n_objects))}
    folders = sorted(p for p in reports.iterdir() if (p / "summary.json").is_file())
    chosen = [f for f in folders if len(_summary(f).verdict.contenders) > 1]
    log.info(
        "%d of %d logs with several explanations in contention: running their next pushes and as many random ones",
        len(chosen),
        len(folders),
    )
    rows = []
    for folder in tqdm(chosen, desc="closed loop", unit="log", disable=not progress):
        cid = folder.name
        case = cases[cid]
        frame = pd.read_csv(logs / f"{cid}.csv")
        nxt = pd.read_csv(folder / "next_pushes.csv")
        own_probes = _probes_file(logs / f"{cid}.csv")
        logged_probes = pd.read_csv(own_probes) if own_probes.is_file() else None
        probe_rec = folder / "next_probes.csv"
        rec = pd.read_csv(probe_rec) if probes_allowed and probe_rec.is_file() else pd.DataFrame()
        rng = np.random.default_rng([design.seed, number[cid]])
        picks = {"next": nxt, "random": _log_design(frame, len(nxt) + len(rec), rng)}
        for arm, pushes in picks.items():
            new = extra_pushes(
                case,
                design,
                scene,
                pushes["object_id"].map(index).to_numpy(),
                pushes["speed"].to_numpy(float),
                pushes["direction"].to_numpy(float),
                seed=ARMS[arm],
                nthread=nthread,
            )
            appended = pd.concat([frame, new[frame.columns]], ignore_index=True)
            path = out / "logs" / f"{cid}-{arm}.csv"
            write_csv(path, appended)
            probe_rows = logged_probes
            ran = 0
            if arm == "next" and len(rec):
                more = extra_probes(case, design, scene, rec, seed=ARMS[arm], nthread=nthread)
                ran = len(rec)
                probe_rows = more if probe_rows is None else pd.concat([probe_rows, more], ignore_index=True)
            if probe_rows is not None:
                write_csv(_probes_file(path), probe_rows)
            ref = read_checked_pushlog(references / f"{cid}.csv", session.table) if references is not None else None
            report = Report(
                pushlog=read_checked_pushlog(path, session.table),
                folder=out / "reports" / f"{cid}-{arm}",
                reference=ref,
            )
            diagnose_report(report, session, force=True)
            rows.append(
                {
                    "case": cid,
                    "arm": arm,
                    "pushes_added": int(len(new)),
                    "probes_added": ran,
                    "report": f"{cid}-{arm}",
                }
            )
    write_json(out / "closed_loop.json", {"rows": rows})
    return rows


def _one_cause_right(label: dict, s: Summary, within: float) -> bool:
    """The log's one effect stated as the one cause, alone, with its magnitude within ``within``."""
    if s.verdict.identification != Identification.ONE_CAUSE or len(s.verdict.effects) != 1:
        return False
    rel = stated_error(label["effects"][0], s)
    return rel is not None and rel <= within


def score_closed_loop(labels: dict[str, dict], folders: list[Path], *, within: float, min_size_sd: float) -> dict:
    """The closed loop's figures from the sealed ``labels`` and the closed-loop ``folders`` (each with
    ``closed_loop.json`` and ``reports/``); a one-effect log counts where its effect is at least ``min_size_sd``
    noise sds on its contact (:func:`imply.realworld.benchmark.effect_size_on_contact`)."""
    rows = []
    for folder in folders:
        with open(folder / "closed_loop.json") as fh:
            for r in json.load(fh)["rows"]:
                lab = labels[r["case"]]
                s = _summary(folder / "reports" / r["report"])
                group = lab["group"]
                row = {
                    **r,
                    "group": group,
                    "engine": lab.get("engine", "mujoco"),
                    "effects": "+".join(e["name"] for e in lab["effects"]) or "null",
                    "identification": str(s.verdict.identification),
                    "causes": "+".join(s.verdict.effects) or "none",
                    "n_contenders": len(s.verdict.contenders),
                }
                if group in CONTACT_SINGLE:
                    size = effect_size_on_contact(lab, lab["effects"][0]["name"])
                    row["big"] = bool(size >= min_size_sd * lab["noise"]["sd"])
                    row["one_cause_right"] = _one_cause_right(lab, s, within)
                    row["told_right"] = told_within(lab["effects"][0], s, within)
                elif group in CONTACT_NULL:
                    row["no_library"] = not s.verdict.effects
                elif group in CONTACT_OUTSIDE:
                    row["wrong_single"] = (
                        bool(s.verdict.effects) and s.verdict.identification == Identification.ONE_CAUSE
                    )
                rows.append(row)
    columns = [
        "arm",
        "group",
        "big",
        "one_cause_right",
        "told_right",
        "no_library",
        "wrong_single",
        "n_contenders",
        "pushes_added",
        "probes_added",
    ]
    frame = pd.DataFrame(rows).reindex(columns=columns)  # every column, so that an empty loop scores as nan

    def mean(values: pd.Series) -> float:
        return float(values.astype(float).mean()) if len(values) else float("nan")

    out: dict = {"rows": rows}
    for arm in ARMS:
        sub = frame[frame["arm"] == arm]
        single = sub[sub["group"].isin(CONTACT_SINGLE) & sub["big"].eq(True)]
        null = sub[sub["group"].isin(CONTACT_NULL)]
        outside = sub[sub["group"].isin(CONTACT_OUTSIDE)]
        out[arm] = {
            "one_cause_right": mean(single["one_cause_right"]),
            "n_single": int(len(single)),
            "told_right": mean(single["told_right"]),
            "null_no_library": mean(null["no_library"]),
            "n_null": int(len(null)),
            "wrong_single": mean(outside["wrong_single"]),
            "n_outside": int(len(outside)),
            "contenders_mean": mean(sub["n_contenders"]),
            "pushes_added_mean": mean(sub["pushes_added"]),
            "probes_added_mean": mean(sub["probes_added"].fillna(0)),
        }
    return out

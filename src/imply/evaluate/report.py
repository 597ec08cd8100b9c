"""The report of ``imply evaluate``: ``results.json``, ``report.md``, figures and per-object readings.

:func:`write_report` writes one report folder for one or several evaluated models (the
same suite), moved into place whole by :func:`imply.io.write_folder`, so a failure
half-way leaves no half-written report and a folder that holds something needs ``force``:

* ``results.json``: ``format`` (``imply-evaluation``), ``version``, ``suite`` (the suite's
  checksum), ``models`` (each :meth:`Evaluation.to_dict`) and ``comparison`` (the
  comparison table's rows, :func:`comparison_rows`); NaN is written as ``null``.
* ``report.md``: the comparison table, a row per model, then a section per model.
* ``slides.{png,pdf}``: read against true slide per model and condition (sample set 0).
* ``scores.{png,pdf}``: mean self and anchored disagreement per model and condition.
* ``selection.{png,pdf}``: mean log error of each selection rule (only when some model
  has a selection).
* ``per_object.csv``: one row per model, condition, sample set, object and query speed.

Every interval is a bootstrap 95% percentile interval over objects.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imply.evaluate.evaluation import Estimate, Evaluation, Selection
from imply.evaluate.suite import CONDITIONS
from imply.io import check_folder, write_columns, write_folder, write_text
from imply.score import DEFAULT_FLOOR

REPORT_FORMAT = "imply-evaluation"
REPORT_VERSION = 1
# every file write_report may put in the report folder (selection.* only when some model has a selection)
REPORT_FILES: tuple[str, ...] = (
    "results.json",
    "report.md",
    "per_object.csv",
    "slides.png",
    "slides.pdf",
    "scores.png",
    "scores.pdf",
    "selection.png",
    "selection.pdf",
)
PNG_DPI = 150
CONDITION_NAMES = {"own": "own calibration", "other": "another object's calibration", "none": "no calibration"}
CONDITION_COLOURS = {"own": "C0", "other": "C3", "none": "C7"}
# number formats, one per kind of quantity
R_SPEC = ".2f"  # correlations
LOG_SPEC = ".3f"  # log errors, disagreements, spreads, R^2
PERCENT_SPEC = ".0f"  # shares, in percent


# -- entry points -----------------------------------------------------------------------


def check_report_folder(out_dir: str | os.PathLike, *, force: bool, inputs: Iterable[str | os.PathLike] = ()) -> None:
    """Refuse (:class:`imply.io.OutputError`) a folder the report cannot be written to, before any work."""
    check_folder(out_dir, REPORT_FILES, force, list(inputs))


def write_report(
    evaluations: Sequence[Evaluation],
    out_dir: str | os.PathLike,
    *,
    force: bool = False,
    inputs: Iterable[str | os.PathLike] = (),
) -> list[str]:
    """Write the report of ``evaluations`` (one or more models, one suite) into ``out_dir``; the names written.

    ValueError for no evaluations, models of different suites or two models of one name;
    :class:`imply.io.OutputError` for a folder that holds something (without ``force``),
    files a previous report did not write, or an input among the files to be replaced.
    """
    evaluations = tuple(evaluations)
    check_evaluations(evaluations)
    check_report_folder(out_dir, force=force, inputs=inputs)
    return write_folder(out_dir, lambda tmp: _write_all(evaluations, tmp), force=force)


def read_report(folder: str | os.PathLike) -> tuple[dict[str, Any], Any]:
    """(``results.json``'s document, ``per_object.csv`` as a DataFrame) of a folder :func:`write_report` wrote."""
    import json

    import pandas as pd

    folder = Path(folder)
    if not (folder / "results.json").is_file() or not (folder / "per_object.csv").is_file():
        raise ValueError(f"{folder} is not an imply evaluate report (results.json, per_object.csv)")
    doc = json.loads((folder / "results.json").read_text())
    return doc, pd.read_csv(folder / "per_object.csv", dtype={"object_id": str, "model": str})


def check_evaluations(evaluations: Sequence[Evaluation]) -> None:
    """ValueError unless there is at least one evaluation, all of one suite, with distinct model names."""
    if not evaluations:
        raise ValueError("no evaluations to report")
    suites = {(ev.suite, ev.suite_version) for ev in evaluations}
    if len(suites) > 1:
        named = ", ".join(f"{ev.model}: {ev.suite[:12]} v{ev.suite_version}" for ev in evaluations)
        raise ValueError(f"the models were evaluated on different suites ({named}); one report needs one suite")
    names = [ev.model for ev in evaluations]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"two models are named {', '.join(map(repr, twice))}; give each model its own name")


def _write_all(evaluations: tuple[Evaluation, ...], out: Path) -> None:
    rows = comparison_rows(evaluations)
    write_text(out / "results.json", results_json(evaluations, rows))
    _per_object_csv(evaluations, out / "per_object.csv")
    figures = ["slides", "scores"]
    _slides_figure(evaluations, out / "slides")
    _scores_figure(evaluations, out / "scores")
    if _has_selection(evaluations):
        _selection_figure(evaluations, out / "selection")
        figures.append("selection")
    write_text(out / "report.md", markdown(evaluations, rows, figures=figures))


def results_json(evaluations: Sequence[Evaluation], rows: list[dict[str, Any]]) -> str:
    """The text of ``results.json``, keys in table order (NaN as null; refuses any non-finite number that slipped
    through)."""
    import json

    doc = {
        "format": REPORT_FORMAT,
        "version": REPORT_VERSION,
        "suite": evaluations[0].suite,
        "models": [ev.to_dict() for ev in evaluations],
        "comparison": rows,
    }
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"


# -- the comparison table ----------------------------------------------------------------


def conditions_present(evaluations: Sequence[Evaluation]) -> tuple[str, ...]:
    """The conditions any model was scored in: the suite's order first, then any other in order seen."""
    seen = [c.condition for ev in evaluations for c in ev.conditions]
    return tuple(c for c in CONDITIONS if c in seen) + tuple(dict.fromkeys(c for c in seen if c not in CONDITIONS))


def _json_value(x: Any) -> Any:
    if isinstance(x, Estimate):
        return {"value": _json_value(x.value), "low": _json_value(x.low), "high": _json_value(x.high)}
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def comparison_rows(evaluations: Sequence[Evaluation]) -> list[dict[str, Any]]:
    """One row per model, the same keys in every row (JSON-ready: estimates as value/low/high, NaN as None).

    Keys: model, kind, readout, readout_r2_check; per condition C present in any model
    ``track_C`` and ``error_C`` (None where the model has no such condition);
    own_lower_self and own_lower_anchored (shares 0..1 of objects whose score is lower with
    their own calibration than with another's); corr_self_own and corr_anchored_own (each
    score's correlation with the log error, own condition); sets and rollouts (over all
    conditions) with static_sets, not_growing_sets, no_box_rollouts and unphysical_rollouts among them.
    """
    present = conditions_present(evaluations)
    rows = []
    for ev in evaluations:
        row: dict[str, Any] = {
            "model": ev.model,
            "kind": ev.kind,
            "readout": ev.readout.name,
            "readout_r2_check": ev.readout.r2_check,
            "readout_r2_codec": ev.readout.r2_codec,
        }
        for name in present:
            scores = ev.condition(name)
            row[f"track_{name}"] = scores.track if scores else None
            row[f"error_{name}"] = scores.error if scores else None
        own_other = ev.own_vs_other
        row["own_lower_self"] = own_other.self_disagreement if own_other else None
        row["own_lower_anchored"] = own_other.anchored_disagreement if own_other else None
        own = ev.condition("own")
        row["corr_self_own"] = own.corr_self if own else None
        row["corr_anchored_own"] = own.corr_anchored if own else None
        row["sets"] = sum(d.n_sets for d in ev.degenerate)
        row["rollouts"] = sum(d.n_rollouts for d in ev.degenerate)
        row["static_sets"] = sum(d.static for d in ev.degenerate)
        row["not_growing_sets"] = sum(d.not_growing for d in ev.degenerate)
        row["no_box_rollouts"] = sum(d.no_box for d in ev.degenerate)
        row["unphysical_rollouts"] = sum(d.unphysical for d in ev.degenerate)
        rows.append({key: _json_value(value) for key, value in row.items()})
    return rows


def _estimate(x: dict | None, spec: str, scale: float = 1.0) -> str:
    """A row's estimate (value/low/high with None for NaN) as Estimate.format writes it."""
    if x is None:
        return "n/a"
    nan = float("nan")
    values = [nan if x[k] is None else scale * x[k] for k in ("value", "low", "high")]
    return Estimate(*values).format(spec)


def _number(x: float | None, spec: str) -> str:
    return "n/a" if x is None or not math.isfinite(x) else format(x, spec)


@dataclass(frozen=True)
class Column:
    """A column of the Markdown comparison table: its header and its cell from a comparison row."""

    header: str
    cell: Callable[[dict[str, Any]], str]


def comparison_columns(present: Sequence[str]) -> tuple[Column, ...]:
    """The comparison table's columns, for the conditions ``present`` (the same for every model)."""
    columns = [
        Column("model", lambda r: r["model"]),
        Column("kind", lambda r: r["kind"]),
        Column("readout", lambda r: r["readout"]),
        Column("readout R^2 (real check clips)", lambda r: _number(r["readout_r2_check"], LOG_SPEC)),
    ]
    for name in present:
        columns.append(Column(f"tracking r, {name}", lambda r, n=name: _estimate(r[f"track_{n}"], R_SPEC)))
        columns.append(Column(f"log error, {name}", lambda r, n=name: _estimate(r[f"error_{n}"], LOG_SPEC)))
    columns += [
        Column("own < other, self (%)", lambda r: _estimate(r["own_lower_self"], PERCENT_SPEC, 100.0)),
        Column("own < other, anchored (%)", lambda r: _estimate(r["own_lower_anchored"], PERCENT_SPEC, 100.0)),
        Column("r(self, error), own", lambda r: _estimate(r["corr_self_own"], R_SPEC)),
        Column("r(anchored, error), own", lambda r: _estimate(r["corr_anchored_own"], R_SPEC)),
        Column(
            "degenerate: static / not growing / no box",
            lambda r: f"{r['static_sets']} / {r['not_growing_sets']} / {r['no_box_rollouts']}",
        ),
    ]
    return tuple(columns)


# -- report.md ---------------------------------------------------------------------------


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(headers: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(_cell(h) for h in headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return lines


def _intervals_sentence(evaluations: Sequence[Evaluation]) -> str:
    counts = sorted({ev.bootstrap for ev in evaluations})
    resamples = f"{counts[0]} resamples" if len(counts) == 1 else "resamples per model in its section"
    return f"Brackets: bootstrap 95% percentile interval over objects ({resamples}); n/a: not defined or not asked."


def markdown(evaluations: Sequence[Evaluation], rows: list[dict[str, Any]], *, figures: Sequence[str] = ()) -> str:
    """``report.md``: the comparison table, the figures named in ``figures``, then a section per model."""
    first = evaluations[0]
    present = conditions_present(evaluations)
    columns = comparison_columns(present)
    lines = [
        "# IMPLY evaluation",
        "",
        f"Suite `{first.suite}` (version {first.suite_version}): {first.n_objects} held-out objects, "
        f"{first.n_speeds} query speeds. Conditions: "
        + "; ".join(f"**{c}**: {CONDITION_NAMES.get(c, c)}" for c in present)
        + ".",
        "",
        "## Comparison",
        "",
        *_table([c.header for c in columns], ([c.cell(r) for c in columns] for r in rows)),
        "",
        _intervals_sentence(evaluations),
        "Tracking r: correlation across objects of read and true log slide (each the mean over speeds). "
        "Log error: per object the RMS over speeds of read minus true log slide, mean over objects. "
        "Own < other: share of objects whose disagreement is lower with their own calibration than with "
        "another object's. r(score, error): correlation across objects of a disagreement with the log error. "
        "Degenerate, summed over conditions: static and not-growing sample sets, rollouts without a box.",
        "",
    ]
    captions = {
        "slides": "Read against true slide per object and query speed (sample set 0; log axes, clamped at the "
        f"readout floor of {DEFAULT_FLOOR * 1000:g} mm; dashed: read = true).",
        "scores": "Mean self and anchored disagreement per model and condition, with intervals.",
        "selection": "Mean log error of the rollouts each selection rule picks, with intervals.",
    }
    for name in figures:
        lines += [f"![{name}]({name}.png)", "", captions[name], ""]
    for ev in evaluations:
        lines += _model_section(ev)
    lines += [
        "## Files",
        "",
        "`results.json` holds every number above (NaN as null); `per_object.csv` one row per model, condition, "
        "sample set, object and query speed with the read and true slide (m) and whether a box was found; the "
        "figures are also written as PDF.",
        "",
    ]
    return "\n".join(lines)


def _model_section(ev: Evaluation) -> list[str]:
    lines = [f"## {ev.model}", ""]
    lines.append(
        f"Kind: {ev.kind}. {ev.n_objects} objects, {ev.n_speeds} query speeds, "
        f"{ev.n_samples} sample set{'s' if ev.n_samples != 1 else ''} per object. "
        f"Intervals: bootstrap 95% over objects, {ev.bootstrap} resamples."
    )
    lines += ["", _readout_paragraph(ev), ""]
    if ev.conditions:
        lines += [
            "### Conditions",
            "",
            *_table(
                [
                    "condition",
                    "objects",
                    "tracking r",
                    "log error",
                    "self disagreement",
                    "anchored disagreement",
                    "r(self, error)",
                    "r(anchored, error)",
                ],
                (
                    [
                        c.condition,
                        str(c.n_objects),
                        c.track.format(R_SPEC),
                        c.error.format(LOG_SPEC),
                        c.self_disagreement.format(LOG_SPEC),
                        c.anchored_disagreement.format(LOG_SPEC),
                        c.corr_self.format(R_SPEC),
                        c.corr_anchored.format(R_SPEC),
                    ]
                    for c in ev.conditions
                ),
            ),
            "",
            "Scores on sample set 0. Anchoring always uses the object's own observed calibration pushes.",
            "",
        ]
    if ev.own_vs_other is not None:
        o = ev.own_vs_other
        lines += [
            "### Own calibration against another's",
            "",
            f"Of {o.n_objects} objects, the share scoring lower with their own calibration than with another "
            f"object's: self disagreement {_percent(o.self_disagreement)}, anchored disagreement "
            f"{_percent(o.anchored_disagreement)}.",
            "",
        ]
    if ev.selection_conditions is not None:
        lines += _selection_lines(ev.selection_conditions)
    for sel in ev.selection_samples:
        lines += _selection_lines(sel)
    if ev.spread:
        lines += [
            f"Spread across the {ev.n_samples} sample sets, per condition: "
            + "; ".join(f"{c} {e.format(LOG_SPEC)}" for c, e in ev.spread.items())
            + ".",
            "",
        ]
    lines += _degenerate_lines(ev)
    if ev.frame_quality is not None:
        q = ev.frame_quality
        lines += [
            "### Frame quality",
            "",
            f"Generated rest frames against the true ones (condition {q.condition}, sample set 0): box saliency "
            f"ratio {q.saliency_ratio.format(LOG_SPEC)} (1: as salient as the true box), PSNR "
            f"{q.psnr.format('.1f')} dB.",
            "",
        ]
    return lines


def _percent(e: Estimate) -> str:
    return Estimate(100 * e.value, 100 * e.low, 100 * e.high).format(PERCENT_SPEC) + " %"


def _readout_paragraph(ev: Evaluation) -> str:
    r = ev.readout
    text = f"Readout: **{r.name}**"
    if r.n_fit > 0:
        text += f", fitted on {r.fitted_on} ({r.n_fit} real clips), never on the outputs it reads"
    text += "."
    if math.isfinite(r.r2_check):
        text += (
            f" On {r.n_check} real check clips it reads log slide with R^2 {r.r2_check:{LOG_SPEC}} and mean "
            f"|log error| {_number(r.error_check, LOG_SPEC)}."
        )
    else:
        text += " Not checked on real clips: the model's displacements are scored as given."
    if r.encoding:
        text += (
            f" Through the submission's own encoding ({r.encoding}), the same real check clips read with R^2 "
            f"{_number(r.r2_codec, LOG_SPEC)} and mean |log error| {_number(r.error_codec, LOG_SPEC)}: what "
            "compression costs the readout before any rollout is read."
        )
    return text


def _selection_lines(sel: Selection) -> list[str]:
    return [
        f"### Choosing among {sel.among}",
        "",
        f"Per object, each rule chooses one of {sel.n_candidates} candidates; the scores are those of the chosen.",
        "",
        *_table(
            ["rule", "tracking r", "log error"],
            ([row.rule, row.track.format(R_SPEC), row.error.format(LOG_SPEC)] for row in sel.rows),
        ),
        "",
    ]


def _verb(count: int, one: str, many: str) -> str:
    return one if count == 1 else many


def _degenerate_lines(ev: Evaluation) -> list[str]:
    if not ev.degenerate:
        return []
    lines = [
        "### Degenerate rollouts",
        "",
        *_table(
            ["condition", "sets", "static", "not growing", "rollouts", "no box"],
            (
                [d.condition, str(d.n_sets), str(d.static), str(d.not_growing), str(d.n_rollouts), str(d.no_box)]
                for d in ev.degenerate
            ),
        ),
        "",
    ]
    flags = []
    for d in ev.degenerate:
        if d.static:
            flags.append(
                f"In condition {d.condition}, {d.static} of {d.n_sets} sets {_verb(d.static, 'is', 'are')} static: "
                "a future where nothing moves scores as perfectly consistent."
            )
        if d.not_growing:
            flags.append(
                f"In condition {d.condition}, {d.not_growing} of {d.n_sets} sets "
                f"{_verb(d.not_growing, 'does', 'do')} not slide further when pushed faster."
            )
        if d.unphysical:
            flags.append(
                f"In condition {d.condition}, {d.unphysical} of {d.n_rollouts} rollouts "
                f"{_verb(d.unphysical, 'reads', 'read')} a slide more than ten times the longest real one of the "
                "suite: no pushed box slides that far (a units slip, millimetres for metres?); they are scored as "
                "read."
            )
        if d.no_box:
            flags.append(
                f"In condition {d.condition}, {d.no_box} of {d.n_rollouts} rollouts {_verb(d.no_box, 'has', 'have')} "
                "no box the readout can find."
            )
    lines += [*(f"- {f}" for f in flags), ""] if flags else ["No degenerate rollouts.", ""]
    return lines


# -- per_object.csv ----------------------------------------------------------------------


def _per_object_csv(evaluations: Sequence[Evaluation], path: Path) -> None:
    """One row per model x condition x sample set x object x query speed (slides in metres)."""
    columns: dict[str, list] = {
        k: []
        for k in (
            "model",
            "condition",
            "sample",
            "object_id",
            "speed_m_s",
            "read_displacement_m",
            "true_displacement_m",
            "box_found",
        )
    }
    for ev in evaluations:
        r = ev.readings
        n_cond, n_samples, n_objects, n_speeds = r.displacement.shape
        shape = (n_cond, n_samples, n_objects, n_speeds)
        idx = np.indices(shape).reshape(4, -1)
        conditions = np.asarray(r.conditions, dtype=object)
        columns["model"] += [ev.model] * idx.shape[1]
        columns["condition"] += conditions[idx[0]].tolist()
        columns["sample"] += idx[1].tolist()
        columns["object_id"] += np.asarray(r.object_ids).astype(str)[idx[2]].tolist()
        columns["speed_m_s"] += np.asarray(r.query_speeds, float)[idx[3]].tolist()
        columns["read_displacement_m"] += np.asarray(r.displacement, float).ravel().tolist()
        columns["true_displacement_m"] += np.broadcast_to(r.true_displacement, shape).ravel().astype(float).tolist()
        columns["box_found"] += np.asarray(r.box_found, bool).ravel().tolist()
    columns["speed_m_s"] = np.asarray(columns["speed_m_s"], float)
    columns["read_displacement_m"] = np.asarray(columns["read_displacement_m"], float)
    columns["true_displacement_m"] = np.asarray(columns["true_displacement_m"], float)
    write_columns(path, columns)


# -- figures -----------------------------------------------------------------------------


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, stem: Path) -> None:
    """``stem``.png and ``stem``.pdf, without dates or versions in them (the same figure gives the same files)."""
    fig.savefig(stem.with_suffix(".png"), format="png", dpi=PNG_DPI, metadata={"Software": None})
    fig.savefig(
        stem.with_suffix(".pdf"), format="pdf", metadata={"CreationDate": None, "Creator": None, "Producer": None}
    )


def _log_ticks(axis) -> None:
    """Ticks at 1, 2 and 5 per decade, labelled as plain numbers (cheaper to draw than mathtext powers)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
    axis.set_minor_formatter(NullFormatter())


def _slides_figure(evaluations: Sequence[Evaluation], stem: Path) -> None:
    """A row per model, a panel per condition: read against true slide (mm, log axes), sample set 0, by speed.

    The layout is fixed in inches (no layout engine: it costs seconds on log axes), so a
    panel keeps its size for 1 or many models.
    """
    plt = _pyplot()
    n_cols = max(len(ev.readings.conditions) for ev in evaluations)
    n_rows = len(evaluations)
    speeds = np.asarray(evaluations[0].readings.query_speeds, float)
    panel, gap_w, gap_h, left, right, bottom, top = 2.2, 0.5, 0.7, 0.6, 1.0, 0.45, 0.3
    width = left + n_cols * panel + (n_cols - 1) * gap_w + right
    height = bottom + n_rows * panel + (n_rows - 1) * gap_h + top
    with plt.rc_context({"font.size": 8}):
        fig, axes = plt.subplots(n_rows, n_cols, figsize=(width, height), squeeze=False)
        fig.subplots_adjust(
            left=left / width,
            right=1 - right / width,
            bottom=bottom / height,
            top=1 - top / height,
            wspace=gap_w / panel,
            hspace=gap_h / panel,
        )
        scatter = None
        for row, ev in enumerate(evaluations):
            r = ev.readings
            truth = np.maximum(np.asarray(r.true_displacement, float), DEFAULT_FLOOR) * 1000
            all_speeds = np.broadcast_to(np.asarray(r.query_speeds, float), truth.shape)
            for col in range(n_cols):
                ax = axes[row, col]
                if col >= len(r.conditions):
                    ax.axis("off")
                    continue
                read = np.asarray(r.displacement[col, 0], float)
                found = np.asarray(r.box_found[col, 0], bool) & np.isfinite(read)
                read = np.maximum(np.where(np.isfinite(read), read, DEFAULT_FLOOR), DEFAULT_FLOOR) * 1000
                scatter = ax.scatter(
                    truth[found],
                    read[found],
                    c=all_speeds[found],
                    s=5,
                    alpha=0.7,
                    cmap="viridis",
                    linewidths=0,
                    vmin=speeds.min(),
                    vmax=speeds.max(),
                    rasterized=True,
                )
                if (~found).any():
                    ax.scatter(
                        truth[~found],
                        read[~found],
                        s=8,
                        marker="x",
                        color="0.5",
                        linewidths=0.6,
                        label="no box",
                        rasterized=True,
                    )
                    ax.legend(loc="upper left", frameon=False, fontsize=6)
                lo = min(truth.min(), read.min()) / 1.3
                hi = max(truth.max(), read.max()) * 1.3
                ax.plot([lo, hi], [lo, hi], "k--", lw=0.7)
                ax.set(xscale="log", yscale="log", xlim=(lo, hi), ylim=(lo, hi))
                _log_ticks(ax.xaxis)
                _log_ticks(ax.yaxis)
                ax.set_title(f"{ev.model}: {r.conditions[col]}", fontsize=8)
                ax.set_xlabel("true slide (mm)")
                if col == 0:
                    ax.set_ylabel("read slide (mm)")
        if scatter is not None:
            bar = fig.add_axes((1 - (right - 0.2) / width, bottom / height, 0.12 / width, min(panel, 1.8) / height))
            fig.colorbar(scatter, cax=bar, label="query speed (m/s)")
        _save(fig, stem)
        plt.close(fig)


def _error_bars(e: Estimate) -> tuple[float, list[list[float]] | None]:
    if not (math.isfinite(e.low) and math.isfinite(e.high)):
        return e.value, None
    return e.value, [[max(e.value - e.low, 0.0)], [max(e.high - e.value, 0.0)]]


def _model_axis(ax, evaluations: Sequence[Evaluation]) -> None:
    names = [ev.model for ev in evaluations]
    ax.set_xticks(range(len(names)))
    long = len(names) > 3 or max(len(n) for n in names) > 12
    ax.set_xticklabels(names, rotation=30 if long else 0, ha="right" if long else "center")
    ax.set_xlim(-0.6, len(names) - 0.4)


def _scores_figure(evaluations: Sequence[Evaluation], stem: Path) -> None:
    """Two panels (self, anchored): per model, one point per condition with its interval."""
    plt = _pyplot()
    present = conditions_present(evaluations)
    width = 0.6 / max(len(present), 1)
    with plt.rc_context({"font.size": 8}):
        fig, axes = plt.subplots(1, 2, figsize=(max(6.0, 2.0 + 1.3 * len(evaluations)), 3.2), layout="constrained")
        for ax, field, title in (
            (axes[0], "self_disagreement", "self disagreement"),
            (axes[1], "anchored_disagreement", "anchored disagreement"),
        ):
            values: list[float] = []
            labelled: set[str] = set()
            for j, name in enumerate(present):
                colour = CONDITION_COLOURS.get(name, f"C{2 + j}")
                for i, ev in enumerate(evaluations):
                    scores = ev.condition(name)
                    if scores is None or not math.isfinite(getattr(scores, field).value):
                        continue
                    value, bars = _error_bars(getattr(scores, field))
                    x = i + (j - (len(present) - 1) / 2) * width
                    ax.errorbar(
                        x,
                        value,
                        yerr=bars,
                        fmt="o",
                        ms=4,
                        color=colour,
                        capsize=2,
                        lw=1,
                        label=None if name in labelled else name,
                    )
                    labelled.add(name)
                    values += [v for v in (getattr(scores, field).low, value) if math.isfinite(v)]
            positive = [v for v in values if v > 0]
            if positive and len(positive) == len(values) and max(positive) / min(positive) > 20:
                ax.set_yscale("log")
            _model_axis(ax, evaluations)
            ax.set_ylabel(f"{title}, mean over objects")
        handles, labels = axes[0].get_legend_handles_labels()
        unique = dict(zip(labels, handles, strict=True))
        if unique:
            fig.legend(
                unique.values(),
                [f"{c}: {CONDITION_NAMES.get(c, c)}" for c in unique],
                loc="outside upper center",
                ncol=len(unique),
                frameon=False,
                fontsize=7,
            )
        _save(fig, stem)
        plt.close(fig)


def _has_selection(evaluations: Sequence[Evaluation]) -> bool:
    return any(ev.selection_conditions is not None or ev.selection_samples for ev in evaluations)


def _selection_figure(evaluations: Sequence[Evaluation], stem: Path) -> None:
    """A panel per model with a selection, one x axis: each rule's mean log error with its interval, a colour
    per selection (among conditions, among the sample sets of each condition)."""
    plt = _pyplot()
    panels = [
        (
            ev.model,
            ([ev.selection_conditions] if ev.selection_conditions is not None else []) + list(ev.selection_samples),
        )
        for ev in evaluations
    ]
    panels = [(model, selections) for model, selections in panels if selections]
    rules = [list(dict.fromkeys(row.rule for sel in selections for row in sel.rows)) for _, selections in panels]
    among = list(dict.fromkeys(sel.among for _, selections in panels for sel in selections))
    heights = [0.35 + 0.22 * len(r) * max(1.0, len(sels) / 3) for r, (_, sels) in zip(rules, panels, strict=True)]
    left = 0.3 + 0.06 * max(len(rule) for r in rules for rule in r)
    legend = 0.25 + 0.16 * len(among)
    gap, bottom, top, width = 0.35, 0.45, 0.1, 6.5
    height = bottom + sum(heights) + gap * (len(panels) - 1) + top + legend
    with plt.rc_context({"font.size": 8}):
        fig, axes = plt.subplots(
            len(panels),
            1,
            figsize=(width, height),
            sharex=True,
            squeeze=False,
            gridspec_kw={"height_ratios": heights},
        )
        fig.subplots_adjust(
            left=left / width,
            right=1 - 0.15 / width,
            bottom=bottom / height,
            top=1 - (top + legend) / height,
            hspace=gap / np.mean(heights),
        )
        for ax, (model, selections), names in zip(axes[:, 0], panels, rules, strict=True):
            step = 0.6 / max(len(selections), 1)
            for sel in selections:
                colour = f"C{among.index(sel.among) % 10}"
                offset = (selections.index(sel) - (len(selections) - 1) / 2) * step
                for row in sel.rows:
                    if not math.isfinite(row.error.value):
                        continue
                    value, bars = _error_bars(row.error)
                    ax.errorbar(
                        value, names.index(row.rule) + offset, xerr=bars, fmt="o", ms=3.5, color=colour, capsize=2, lw=1
                    )
            ax.set_yticks(range(len(names)))
            ax.set_yticklabels(names)
            ax.set_ylim(len(names) - 0.5, -0.5)
            ax.set_title(model, fontsize=8, loc="left")
            ax.grid(axis="x", lw=0.4, color="0.85")
        axes[-1, 0].set_xlabel("mean log error of the chosen rollouts")
        handles = [plt.Line2D([], [], marker="o", ls="", ms=4, color=f"C{i % 10}") for i in range(len(among))]
        fig.legend(
            handles,
            [f"among {a}" for a in among],
            loc="upper left",
            frameon=False,
            fontsize=7,
            bbox_to_anchor=(left / width, 1 - 0.05 / height),
        )
        _save(fig, stem)
        plt.close(fig)

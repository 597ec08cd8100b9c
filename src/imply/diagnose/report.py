"""The diagnose report directory: ``summary.json``, ``report.md`` and its plots.

``summary.json`` (machine-readable, keys sorted, floats unrounded): ``verdict`` (the
cause: an effect class, or ``none``), ``localisation`` (residual bands with intervals,
objects, the regions beyond noise), ``aliasing`` (identifiability, projected cosines,
classes), ``ranking`` (every candidate: magnitude, 95% interval, likelihood-ratio
statistic, delta BIC, held-out improvement, explained RMS, share of the gap closed),
``shrinkage`` (held-out RMS gap and anchored disagreement before/after, noise floor,
shares closed), ``noise`` and ``options``. ``residuals.csv`` holds every push's
residual before and after the top effect. The plots: ``residuals_vs_speed.png``,
``before_after.png`` and ``ranking.png``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from imply.diagnose.analysis import Diagnosis
from imply.io import atomic_path, write_csv, write_json, write_text

# every file write_report puts in the report folder
REPORT_FILES = (
    "summary.json", "residuals.csv", "residuals_vs_speed.png", "before_after.png", "ranking.png", "report.md",
)  # fmt: skip


def _fmt(x, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, spec)


def write_report(diag: Diagnosis, outdir: str | os.PathLike) -> None:
    """Write the summary, the residuals, the plots and the Markdown report into ``outdir``."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    s = diag.summary
    write_json(out / "summary.json", s)
    r = diag.residuals
    frame = pd.DataFrame({"speed": r["speed"], "direction": r["direction"], "log_d": r["log_d"],
                          "resid_before": r["resid_before"]})  # fmt: skip
    if r["resid_after"] is not None:
        frame["resid_after"] = r["resid_after"]
    write_csv(out / "residuals.csv", frame)
    _plots(diag, out)
    write_text(out / "report.md", markdown(s))


def _plots(diag: Diagnosis, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s, r = diag.summary, diag.residuals
    floor = s["noise"]["sd"]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.scatter(r["speed"], r["resid_before"], s=6, alpha=0.4, color="0.4", label="pushes")
    bands = s["localisation"]["speed"]
    xs = [float(b["band"]) if b["band"].replace(".", "", 1).isdigit() else i for i, b in enumerate(bands)]
    means = [b["mean"] for b in bands]
    err = [[b["mean"] - b["ci95"][0] for b in bands], [b["ci95"][1] - b["mean"] for b in bands]]
    ax.errorbar(xs, means, yerr=err, fmt="o", color="C3", label="band mean, 95% CI")
    if floor:
        ax.axhspan(-floor, floor, color="C0", alpha=0.1, label="noise sd")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("commanded speed (m/s)")
    ax.set_ylabel("log d residual (baseline fit)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, out / "residuals_vs_speed.png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    sp = np.unique(r["speed"])
    rms_b = [np.sqrt(np.mean(r["resid_before"][r["speed"] == v] ** 2)) for v in sp]
    ax.plot(sp, rms_b, "o-", label="baseline table")
    if r["resid_after"] is not None:
        rms_a = [np.sqrt(np.mean(r["resid_after"][r["speed"] == v] ** 2)) for v in sp]
        ax.plot(sp, rms_a, "s-", label=f"with {s['shrinkage']['effect']}")
    if floor:
        ax.axhline(floor, ls="--", color="0.5", label="noise sd")
    ax.set_xlabel("commanded speed (m/s)")
    ax.set_ylabel("RMS log d residual")
    ax.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, out / "before_after.png")
    plt.close(fig)

    _ranking_plot(plt, s, out / "ranking.png")


def ranking_colours(summary: dict) -> list[str]:
    """Bar colour per ranked candidate: green only for the verdict's effect.

    Blue: identifiable and improves the held-out fit; red: makes it worse; grey: not
    identifiable from these pushes. Green must never mark a candidate that hurts.
    """
    chosen = summary["verdict"].get("effect")
    out = []
    for r in summary["ranking"]:
        if not r["identifiable"]:
            out.append("0.75")
        elif r["effect"] == chosen:
            out.append("C2")
        elif (r["heldout_improvement"] or 0.0) > 0:
            out.append("C0")
        else:
            out.append("C3")
    return out


def _ranking_plot(plt, s: dict, path: Path) -> None:
    rank = s["ranking"]
    fig, ax = plt.subplots(figsize=(6, 0.3 * len(rank) + 1.4))
    names = [x["effect"] for x in rank][::-1]
    vals = np.array([x["heldout_improvement"] if x["heldout_improvement"] is not None else np.nan for x in rank])
    vals = np.nan_to_num(vals[::-1])
    colors = ranking_colours(s)[::-1]
    # a candidate that wrecks the held-out fit would dwarf the ones that help: clip the
    # negative side at the largest gain and print the clipped values
    span = max(float(np.max(vals, initial=0.0)), 0.05)
    left = -span
    shown = np.maximum(vals, left)
    ax.barh(names, shown, color=colors)
    for i, (v, w) in enumerate(zip(vals, shown, strict=True)):
        if v < w:
            ax.text(w, i, f" {v:+.2g} (bar cut)", va="center", ha="left", fontsize=7)
    ax.set_xlim(left * 1.05, max(span * 1.15, 0.05))
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("held-out improvement (share of baseline SSE)")
    ax.set_title("green: verdict; blue: helps; red: hurts; grey: not identifiable", fontsize=8)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", metadata={"Software": None})


def _floor_parts(parts: dict | None) -> str:
    if not parts:
        return ""
    numerical = parts.get("numerical_rms")
    return (
        f" (interpolation {_fmt(parts.get('interpolation_rms'))} and the simulator's measured numerical error "
        f"{_fmt(numerical) if numerical is not None else 'not recorded in the table'}, combined)"
    )


def markdown(s: dict) -> str:
    v, sh, noise = s["verdict"], s["shrinkage"], s["noise"]
    lines = [
        "# Sim-to-real gap diagnosis",
        "",
        f"Push log: `{s['pushlog']}` ({s['n_pushes']} pushes, {s['n_objects']} objects"
        f"{', with directions' if s['has_direction'] else ', no directions'}"
        f"{''.join(f', measured {k} held fixed' for k, on in s.get('measured', {}).items() if on)}).",
        f"Noise: sd {_fmt(noise['sd'])} in log d ({noise['source']}). Table model floor: "
        f"{_fmt(s['options'].get('model_floor'))} RMS log d{_floor_parts(s.get('model_floor'))}.",
        "",
        "## Verdict",
        "",
    ]
    if v["verdict"] == "none":
        lines.append(f"**None of the candidates** ({v['reason']}). Unexplained residual above the noise floor: "
                     f"{_fmt(sh['unexplained_rms_above_floor'])} RMS log d.")  # fmt: skip
    else:
        top = next(r for r in s["ranking"] if r["effect"] == v["effect"])
        lines.append(
            f"**{v['class']}** explains the gap: {top['effect']} = {_fmt(top['magnitude'])} {top['unit']} "
            f"(95% CI {_fmt(top['ci95'][0])} to {_fmt(top['ci95'][1])})."
        )
    lines += [
        "",
        "## Where (baseline fit residuals)",
        "",
        f"Baseline RMS residual {_fmt(s['baseline']['rms'])}. Regions whose mean residual differs from zero "
        f"(95% interval across objects excludes 0): {', '.join(s['localisation']['regions_beyond_noise']) or 'none'}.",
        "",
        "![residuals vs speed](residuals_vs_speed.png)",
        "",
    ]
    for factor in ("speed", "displacement", "direction", "fitted_mass", "fitted_friction"):
        rows = s["localisation"].get(factor)
        if not rows:
            continue
        lines += [
            f"**{factor}**",
            "",
            "| band | pushes | mean residual | 95% CI | beyond noise |",
            "|---|---|---|---|---|",
        ]
        for b in rows:
            lines.append(f"| {b['band']} | {b['n_pushes']} | {_fmt(b['mean'], '+.4f')} | "
                         f"[{_fmt(b['ci95'][0], '+.4f')}, {_fmt(b['ci95'][1], '+.4f')}] | {'yes' if b['differs'] else ''} |")  # fmt: skip
        lines.append("")
    lines += [
        "## Which (candidate effects)",
        "",
        "Ranked by held-out improvement (objects left out in folds). LR: likelihood-ratio statistic at the "
        f"noise variance (critical value {_fmt(v['lr_critical'], '.3g')}); dBIC < 0 favours the effect.",
        "",
        "| effect | class | magnitude | 95% CI | LR | dBIC | held-out | explained RMS | share closed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in s["ranking"]:
        lines.append(
            f"| {r['effect']} | {r['class']} | {_fmt(r['magnitude'])} {r['unit']} | [{_fmt(r['ci95'][0])}, "
            f"{_fmt(r['ci95'][1])}] | {_fmt(r['lr_stat'], '.1f')} | {_fmt(r['delta_bic'], '.1f')} | "
            f"{_fmt(r['heldout_improvement'], '+.3f')} | {_fmt(r['explained_rms'], '.4f')} | {_fmt(r['share_closed'], '.2f')} |"
        )
    al = s["aliasing"]
    lines += [
        "",
        f"Not identifiable from these pushes (projected effect below {s['options']['min_visible']} RMS at the "
        f"largest magnitude): {', '.join(al['not_identifiable']) or 'none'}. Alias classes: "
        f"{'; '.join(al['classes'])}.",
        "",
        "![ranking](ranking.png)",
        "",
        "## How far",
        "",
        f"Held-out RMS gap: {_fmt(sh['before_rms'])} before, {_fmt(sh['after_rms'])} after "
        f"({sh['effect'] or 'no effect added'}); noise floor {_fmt(sh['noise_floor_rms'])}; share of the gap above "
        f"the floor closed: {_fmt(sh['gap_share_closed'], '.2f')}.",
        f"Anchored disagreement (mean over objects): {_fmt(sh['anchored_before_mean'])} before, "
        f"{_fmt(sh['anchored_after_mean'])} after; floor {_fmt(sh['anchored_floor'])}; share closed "
        f"{_fmt(sh['anchored_share_closed'], '.2f')}.",
        "",
        "![before and after](before_after.png)",
        "",
    ]
    return "\n".join(lines)

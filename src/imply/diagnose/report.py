"""The diagnose report directory: ``summary.json``, ``report.md``, ``next_pushes.csv`` and the plots.

``summary.json`` (machine-readable, keys sorted, floats unrounded): ``verdict`` (adequacy,
identification, the causes stated, the contenders with their weights, the effects not
separable from the discrepancy or at their library bound), ``sentence`` (the verdict in
words, the report's first line), ``hypotheses`` (every hypothesis fitted: effects,
discrepancy or not, log evidence, weight, chi-square in sample and held out, magnitudes
with 95% intervals), ``inclusion`` (each effect's inclusion weight), ``effects`` (the
leading hypothesis's effects: magnitude, azimuth for a tilt or an anisotropy, 95%
intervals, alias class, aliasing with the per-object fit), ``next_pushes`` (the recommended
pushes and the separation they would bring), ``observables``, ``outliers`` (the gross
outliers left out), ``localisation`` (residual bands with intervals, objects, the regions
beyond noise), ``aliasing`` (identifiability, projected cosines, classes, what the
per-object fit absorbs), ``ranking`` (every candidate on its own: magnitude, 95% interval,
likelihood-ratio statistic and its critical value, delta BIC, held-out gain),
``shrinkage`` (held-out RMS gap, stop times and anchored disagreement before/after, noise
floor, shares closed), ``noise`` and ``options``. ``residuals.csv`` holds every push's
residual before and after the leading hypothesis (held out) and whether it was flagged;
``next_pushes.csv`` the recommended pushes as push-log columns with what each contender
predicts (:mod:`imply.diagnose.conclusion.next_pushes`), and ``next_probes.csv`` the calibration probe
that would separate them more than any push, where one would, as a probes-file row with
what each contender predicts it reads (:mod:`imply.diagnose.conclusion.next_probes`; a file of its own,
so that ``imply sim pushes`` can run ``next_pushes.csv`` as it is). The plots: ``residuals_vs_speed.png``,
``before_after.png``, ``ranking.png`` and ``hypotheses.png`` (the contenders' weights).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from imply.diagnose.analysis import Diagnosis, Summary
from imply.diagnose.conclusion.next_probes import write_next_probes
from imply.diagnose.conclusion.next_pushes import write_next_pushes
from imply.diagnose.conclusion.render import OBSERVABLE_WORDS, probe_sentence
from imply.diagnose.conclusion.simulator_check import CORRECTED_XML
from imply.diagnose.conclusion.verdict import explanations
from imply.diagnose.inference.estimates import AcceptedEffect, RankedCandidate
from imply.diagnose.inference.localisation import FACTORS
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.io import atomic_path, write_csv, write_json, write_text

# every file write_report puts in the report folder
REPORT_FILES = (
    "summary.json",
    "residuals.csv",
    "next_pushes.csv",
    "next_probes.csv",
    "residuals_vs_speed.png",
    "before_after.png",
    "ranking.png",
    "hypotheses.png",
    "report.md",
    CORRECTED_XML,
)


def _fmt(x, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, spec)


def write_report(diag: Diagnosis, outdir: str | os.PathLike, *, plots: bool = True) -> None:
    """Write the summary, the residuals, the plots (unless ``plots`` is false: a benchmark's hundreds of reports
    are read as data) and the Markdown report into ``outdir``."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    s = diag.summary
    write_json(out / "summary.json", s.to_dict())
    r = diag.residuals
    frame = pd.DataFrame({"speed": r.speed, "direction": r.direction, "log_d": r.log_d, "resid_before": r.resid_before})
    if r.resid_after is not None:
        frame["resid_after"] = r.resid_after
    if r.stop_resid_before is not None:
        frame["stop_resid_before"] = r.stop_resid_before
        if r.stop_resid_after is not None:
            frame["stop_resid_after"] = r.stop_resid_after
    if r.pusher_resid_before is not None:
        frame["pusher_speed_resid_before"] = r.pusher_resid_before
        if r.pusher_resid_after is not None:
            frame["pusher_speed_resid_after"] = r.pusher_resid_after
    frame["outlier"] = np.asarray(r.flagged, bool)
    write_csv(out / "residuals.csv", frame)
    write_next_pushes(out / "next_pushes.csv", s.next_pushes, diag.pushlog)
    write_next_probes(out / "next_probes.csv", s.next_pushes.probe if s.next_pushes is not None else None)
    if plots:
        _plots(diag, out)
    if diag.corrected_xml is not None:
        write_text(out / CORRECTED_XML, diag.corrected_xml)
    write_text(out / "report.md", markdown(s, plots=plots))


def _plots(diag: Diagnosis, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s, r = diag.summary, diag.residuals
    floor = s.noise.sd
    fig, ax = plt.subplots(figsize=(6, 3.5))
    flagged = np.asarray(r.flagged, bool)
    ax.scatter(r.speed[~flagged], r.resid_before[~flagged], s=6, alpha=0.4, color="0.4", label="pushes")
    if flagged.any():
        ax.scatter(
            r.speed[flagged], r.resid_before[flagged], s=18, marker="x", color="C1", label="gross outliers (left out)"
        )
    bands = s.localisation.speed
    xs = [0.5 * (b.low + b.high) if b.low is not None else i for i, b in enumerate(bands)]
    means = [b.mean for b in bands]
    err = [[b.mean - b.ci95[0] for b in bands], [b.ci95[1] - b.mean for b in bands]]
    ax.errorbar(xs, means, yerr=err, fmt="o", color="C3", label="band mean, 95% CI")
    if floor:
        ax.axhspan(-floor, floor, color="C0", alpha=0.1, label="noise sd")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("commanded speed (m/s)")
    ax.set_ylabel("log d residual (baseline fit)")
    ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.15, top=0.95)  # fixed margins: no extra draw
    _save(fig, out / "residuals_vs_speed.png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    sp = np.unique(r.speed)
    keep = ~flagged
    rms_b = [np.sqrt(np.mean(r.resid_before[(r.speed == v) & keep] ** 2)) for v in sp]
    ax.plot(sp, rms_b, "o-", label="baseline table")
    if r.resid_after is not None:
        rms_a = [np.sqrt(np.mean(r.resid_after[(r.speed == v) & keep] ** 2)) for v in sp]
        ax.plot(sp, rms_a, "s-", label=f"with {s.shrinkage.effect} (held out)")
    if floor:
        ax.axhline(floor, ls="--", color="0.5", label="noise sd")
    ax.set_xlabel("commanded speed (m/s)")
    ax.set_ylabel("RMS log d residual")
    ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.15, top=0.95)  # fixed margins: no extra draw
    _save(fig, out / "before_after.png")
    plt.close(fig)

    _ranking_plot(plt, s, out / "ranking.png")
    _hypotheses_plot(plt, s, out / "hypotheses.png")


def _hypotheses_plot(plt, s: Summary, path: Path) -> None:
    """The weight of each explanation (hypotheses grouped by their library effects), contenders marked."""
    groups = explanations(s.hypotheses)[:10]
    contenders = {c.label for c in s.verdict.contenders}
    fig, ax = plt.subplots(figsize=(6, 0.3 * len(groups) + 1.4))
    names = [" + ".join(g.effects) or "no library effect" for g in groups][::-1]
    disc = np.array([g.discrepancy_weight for g in groups])[::-1]
    alone = np.array([g.weight - g.discrepancy_weight for g in groups])[::-1]
    colours = ["C2" if g.label in contenders else "0.7" for g in groups][::-1]
    ax.barh(names, alone, color=colours)
    ax.barh(names, disc, left=alone, color=colours, hatch="//", edgecolor="w")
    ax.set_xlim(0, 1)
    ax.set_xlabel("weight (hatched: with the smooth discrepancy)")
    ax.set_title("green: in contention", fontsize=8)
    fig.subplots_adjust(left=0.35, right=0.95, bottom=0.5 / fig.get_figheight() + 0.05, top=0.9)
    _save(fig, path)
    plt.close(fig)


def ranking_colours(ranking: list[RankedCandidate], verdict_effects: list[str]) -> list[str]:
    """Bar colour per ranked candidate: green only for the verdict's effect.

    Green: an effect of the verdict; blue: identifiable and improves the held-out fit
    (alone); red: makes it worse; grey: not identifiable from these
    pushes. Green must never mark a candidate that is not in the verdict.
    """
    chosen = set(verdict_effects)
    out = []
    for r in ranking:
        if not r.identifiable:
            out.append("0.75")
        elif r.effect in chosen:
            out.append("C2")
        elif (r.heldout_improvement or 0.0) > 0:
            out.append("C0")
        else:
            out.append("C3")
    return out


def _ranking_plot(plt, s: Summary, path: Path) -> None:
    rank = s.ranking
    fig, ax = plt.subplots(figsize=(6, 0.3 * len(rank) + 1.4))
    names = [x.effect for x in rank][::-1]
    vals = np.array([x.heldout_improvement if x.heldout_improvement is not None else np.nan for x in rank])
    vals = np.nan_to_num(vals[::-1])
    colors = ranking_colours(rank, s.verdict.effects)[::-1]
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
    fig.subplots_adjust(left=0.3, right=0.95, bottom=0.5 / fig.get_figheight() + 0.05, top=0.9)
    _save(fig, path)
    plt.close(fig)


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png", metadata={"Software": None})


def _floor_parts(parts: dict | None) -> str:
    if not parts:
        return ""
    numerical = parts.get("numerical_rms")
    return (
        f" (interpolation {_fmt(parts.get('interpolation_rms'))} and the simulator's measured numerical error "
        f"{_fmt(numerical) if numerical is not None else 'not recorded in the table'}, combined)"
    )


def _effect_line(e: AcceptedEffect) -> str:
    az = ""
    if e.azimuth_deg is not None and e.azimuth_ci95_deg is None:
        az = f", along {e.azimuth_deg:.0f} deg (fixed by the pushes' directions, table frame)"
    elif e.azimuth_deg is not None:
        lo, hi = e.azimuth_ci95_deg
        az = f", toward {e.azimuth_deg:.0f} deg (95% CI {lo:.0f} to {hi:.0f} deg, table frame)"
    return (
        f"- **{e.effect}** ({e.title}): {_fmt(e.magnitude)} {e.unit} (95% CI {_fmt(e.ci95[0])} to "
        f"{_fmt(e.ci95[1])}){az}"
        + (f"; alias class {e.cls}" if "+" in (e.cls or "") else "")
        + (" (at the edge of the searched range)" if e.at_bound else "")
    )


def _discrepancy_lines(s: Summary) -> list[str]:
    """The discrepancy, what it can imitate on this design, and what these directions identify."""
    lines: list[str] = []
    d, al = s.discrepancy, s.aliasing
    if d is not None:
        coef = ", ".join(f"{k} {v:+.3g}" for k, v in d.coefficients.items())
        lines += [
            "",
            f"**Model discrepancy** (a smooth function of speed, mass and friction fitted beside the effects; "
            f"log units): RMS {_fmt(d.rms_log_d)} in log d; change from the slowest to the fastest push "
            f"{_fmt(d.speed_trend, '+.3f')} (rough minus smooth objects {_fmt(d.speed_trend_rough_minus_smooth, '+.3f')}, "
            f"heavy minus light {_fmt(d.speed_trend_heavy_minus_light, '+.3f')})"
            + (f"; stop-time offset {_fmt(d.stop_time_offset, '+.3f')}" if d.stop_time_offset is not None else "")
            + (
                f"; implied masses {_fmt(d.implied_mass_ratio, '.2f')}x the weighed ones (median, table alone, "
                "masses fitted freely)"
                if d.implied_mass_ratio is not None
                else ""
            )
            + f". Coefficients: {coef}.",
        ]
    if al.discrepancy_mimics:
        can = [f"{k} ({v:.2f})" for k, v in sorted(al.discrepancy_mimics.items(), key=lambda x: -x[1])]
        lines += [
            "",
            "What the discrepancy could imitate on these pushes (canonical correlation of projected changes; "
            f"at least {s.options.alias_cos:g} counts as imitating): " + ", ".join(can) + ".",
        ]
    for name, r in al.restricted.items():
        lines += ["", f"Identifiable from these directions: {name}: {r.note}."]
    return lines


def _next_push_lines(s: Summary) -> list[str]:
    d = s.next_pushes
    if d is None or not d.pushes:
        return ["", "Next pushes: none needed (a single explanation is in contention); `next_pushes.csv` has no rows."]
    lines = [
        "",
        f"**Next pushes** (`next_pushes.csv`, {len(d.pushes)} pushes chosen to separate "
        f"{', '.join(d.contenders)}; separation in noise sds, against as many pushes of this log's own kind):",
        "",
        "| pair | these pushes | the log's kind |",
        "|---|---|---|",
    ]
    for p in d.pairs:
        lines.append(f"| {p.first} vs {p.second} | {p.next_pushes_sd:.1f} | {p.log_design_sd:.1f} |")
    if d.probe is not None:
        lines += ["", probe_sentence(d.probe)]
    names = list(d.pairs[0].by_observable) if d.pairs else []
    if names:
        lines += [
            "",
            "How far the log's own pushes set each pair apart, observable by observable (noise sds):",
            "",
            "| pair | " + " | ".join(OBSERVABLE_WORDS.get(n, n) for n in names) + " |",
            "|---" * (len(names) + 1) + "|",
        ]
        for p in d.pairs:
            lines.append(
                f"| {p.first} vs {p.second} | " + " | ".join(f"{p.by_observable[n]:.1f}" for n in names) + " |"
            )
    lacks = list(d.pairs[0].measure or {}) if d.pairs else []
    if lacks:
        lines += [
            "",
            "What measuring what this log lacks, on its own pushes, would add (noise sds, at an assumed "
            "noise of 0.02 in its log):",
            "",
            "| pair | " + " | ".join(f"measure {OBSERVABLE_WORDS.get(n, n)}" for n in lacks) + " |",
            "|---" * (len(lacks) + 1) + "|",
        ]
        for p in d.pairs:
            lines.append(f"| {p.first} vs {p.second} | " + " | ".join(f"{p.measure[n]:.1f}" for n in lacks) + " |")
    return lines


def _reference_lines(s: Summary) -> list[str]:
    """The report's section on the reference session and the two gaps (none without a reference)."""
    ref = s.reference
    if ref is None:
        return []
    st, sh = ref.standing, s.cause_shrink
    lines = [
        "## Against a reference session",
        "",
        f"Reference: `{ref.pushlog}` ({ref.n_pushes} pushes). Boxes in both sessions: {len(ref.objects_shared)}"
        + (f"; only in the log, left out: {', '.join(ref.objects_log_only)}" if ref.objects_log_only else "")
        + (
            f"; only in the reference, used for the standing gap alone: {', '.join(ref.objects_reference_only)}"
            if ref.objects_reference_only
            else ""
        )
        + f". The standing gap was taken out of {ref.pushes_matched} of the log's pushes by the reference's own "
        f"pushes of the same box, speed and direction, and out of {ref.pushes_modelled} by its fit"
        + (f"; not used against it: {', '.join(ref.observables_dropped)}" if ref.observables_dropped else "")
        + ".",
        "",
        f"**The standing gap** (the reference alone: RMS {_fmt(st.baseline_rms)} in log d, noise sd "
        f"{_fmt(st.noise_sd)}): {st.sentence}",
        "",
    ]
    if sh is not None:
        lines += [
            f"**How far the new session's gap shrinks** (RMS log d against the table, each box refitted, in sample): "
            f"{_fmt(sh.before_rms)} with the table alone; {_fmt(sh.cause_rms)} once the cause of the change is added "
            f"(share of the gap above the noise floor {_fmt(sh.noise_floor_rms)} closed: "
            f"{_fmt(sh.cause_share_closed, '.2f')}); {_fmt(sh.cause_and_standing_rms)} once the standing gap is "
            f"described too (share {_fmt(sh.cause_and_standing_share_closed, '.2f')}).",
            "",
        ]
    return lines


def _simulator_lines(s: Summary) -> list[str]:
    """The stated causes in the simulator: the corrected scene, the shrink re-simulated, the refit, the probes."""
    c = s.simulator
    if c is None:
        return []
    lines = [
        "## The causes in the simulator",
        "",
        f"`{c.corrected_xml}` is the {'built-in scene' if c.scene == 'built-in' else f'scene `{c.scene}`'} with "
        "the causes written in through `MjSpec` (as `mujoco.sysid` parameters); it loads with "
        "`mujoco.MjModel.from_xml_path`, and `imply sim pushes PUSHES.csv --model " + c.corrected_xml + "` runs "
        "pushes in it (pushes along its +x, the table frame's direction 0).",
        "",
        "| cause | value | written as | from |",
        "|---|---|---|---|",
    ]
    for cause in c.causes:
        value = ", ".join(_fmt(x) for x in cause.value)
        lines.append(f"| {cause.cause} | {value} | {cause.mechanism} | {cause.source} |")
    if c.not_in_scene:
        lines += [
            "",
            f"Not in the scene: the leading hypothesis's {' and '.join(c.not_in_scene)} (a smooth correction of the "
            "table, with no MJCF form); the re-simulation below checks the stated causes alone, as the predicted "
            "shrink does.",
        ]
    share = _fmt(c.share_closed, ".2f")
    lines += [
        "",
        f"The log's {c.n_pushes} pushes re-simulated: RMS log d gap {_fmt(c.before_rms)} in the uncorrected scene "
        f"(each box as the table alone fits it), {_fmt(c.after_rms)} in the corrected scene (each box as the stated "
        f"causes fit it); noise floor {_fmt(c.noise_floor_rms)}. Share of the gap above the floor closed: "
        f"**{share} re-simulated**, {_fmt(c.predicted_share_closed, '.2f')} predicted by the tables "
        f"({_fmt(c.predicted_before_rms)} to {_fmt(c.predicted_after_rms)}). Gap left: {c.gap_left_sd:.2f} noise sds"
        + (f"; {c.n_failed} pushes failed the simulator's checks and are left out" if c.n_failed else "")
        + ".",
    ]
    if c.disagrees:
        lines += [
            "",
            f"**The simulator and the tables disagree** on the shrink by more than the tables' own error allows "
            f"(tolerance {_fmt(c.tolerance, '.2f')} of the share, from their model floor)"
            + (
                ": the simulator contradicts the stated causes, which are withdrawn."
                if c.simulator_contradicts
                else "."
            ),
        ]
    if c.refit is not None:
        r = c.refit
        lines += [
            "",
            f"Refitted in the simulator (`mujoco.sysid.optimize`, {r.n_parameters} parameters: the causes and every "
            f"free box mass and friction; {r.pushes_simulated} pushes simulated, {r.seconds:.1f} s; chi-square "
            f"{r.chi2_start:.1f} at the tables' estimates, {r.chi2_end:.1f} after):",
            "",
            "| cause | tables' estimate | simulator's | simulator's 95% interval |",
            "|---|---|---|---|",
        ]
        for name, vals in r.simulator.items():
            lines.append(
                f"| {name} | {', '.join(_fmt(x) for x in r.tables[name])} | {', '.join(_fmt(x) for x in vals)} | "
                + ", ".join(f"[{_fmt(a)}, {_fmt(b)}]" for a, b in r.simulator_ci95[name])
                + " |"
            )
        lines += [
            "",
            "The simulator's interval "
            + ("holds" if r.holds_tables else "**does not hold**")
            + " the tables' estimate, and "
            + (
                "leaves out 0 (the simulator needs the cause)."
                if r.excludes_zero
                else "**holds 0** (the simulator does not need the cause on these pushes)."
            ),
        ]
    if c.probes:
        lines += [
            "",
            "The log's calibration probes under the leading hypothesis (whitened chi-square; "
            f"{'they contradict it, and the causes are withdrawn' if c.probes_contradict else 'none contradicts it'}):",
            "",
            "| probes | n | chi-square | p | worst (sds) |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {k.kind.replace('_', ' ')} | {k.n} | {k.chi2:.3g} | {k.p_value:.3g} | {k.worst_sd:.3g} |"
            for k in c.probes
        ]
    return lines


def markdown(s: Summary, *, plots: bool = True) -> str:
    """The human report; ``plots``: whether the folder holds the plots (their image lines are left out otherwise)."""
    v, sh, noise = s.verdict, s.shrinkage, s.noise

    def image(alt: str, name: str) -> list[str]:
        return [f"![{alt}]({name})", ""] if plots else []

    lines = [
        "# Sim-to-real gap diagnosis",
        "",
        f"**{s.sentence}**",
        "",
        f"Push log: `{s.pushlog}` ({s.n_pushes} pushes, {s.n_objects} objects"
        f"{', with directions' if s.has_direction else ', no directions'}"
        f"{''.join(f', measured {k} held fixed' for k, on in s.measured.items() if on)}). "
        f"Observables used: {s.observables_note}.",
        f"Noise: sd {_fmt(noise.sd)} in log d ({noise.source})"
        + (f", {_fmt(noise.stop_time_sd)} in log stop time" if noise.stop_time_sd else "")
        + (f", {_fmt(noise.pusher_speed_sd)} in log pusher speed" if noise.pusher_speed_sd else "")
        + "".join(
            f", {_fmt(sd)} in log of {OBSERVABLE_WORDS[name]}"
            for name, sd in noise.aux_sd.items()
            if name in TRACK_OBSERVABLES
        )
        + f". Table model floor: {_fmt(s.options.model_floor)} RMS log d{_floor_parts(s.model_floor)}.",
        "",
    ]
    lines += _reference_lines(s)
    lines += ["## Verdict" + (" (what changed since the reference)" if s.reference is not None else ""), ""]
    lines.append(
        f"Adequacy: **{v.adequacy.replace('_', ' ')}**; identification: "
        f"**{v.identification.replace('_', ' ')}**; causes stated: {', '.join(v.effects) or 'none'}"
        + "".join(
            f"; {t.effect}: {t.tier.replace('_', ' ')} ({_fmt(t.across_contact[0])} to {_fmt(t.across_contact[1])} "
            f"over {t.descriptions} description(s) of the contact, 95% interval [{_fmt(t.ci95[0])}, {_fmt(t.ci95[1])}])"
            for t in v.tiers
        )
        + "."
    )
    lines += [
        "",
        f"Explanations in contention (weight at least {s.options.contender_ratio:g} of the leading one's; "
        f"hypotheses weighed by their evidence under a dispersion of {s.dispersion:.3g}):",
        "",
        "| explanation | weight | of which with the discrepancy | effects at their bound |",
        "|---|---|---|---|",
    ]
    for c in v.contenders:
        lines.append(
            f"| {' + '.join(c.effects) or 'no library effect'} | {c.weight:.3f} | "
            f"{c.discrepancy_weight:.3f} | {', '.join(c.at_bound) or ''} |"
        )
    lines += ["", f"The leading hypothesis ({v.leading}), fitted jointly with every object's mass and friction:", ""]
    lines += [_effect_line(e) for e in s.effects] or ["- no library effect"]
    lines += _next_push_lines(s)
    notes = [e.fit_alias for e in s.effects if e.fit_alias]
    if notes:
        lines += ["", "Aliasing with the per-object fit: " + "; ".join(notes) + "."]
    lines += _discrepancy_lines(s)
    if s.simulator is not None:
        lines += [""] + _simulator_lines(s)
    lines += [
        "",
        f"Held-out RMS gap in log d: {_fmt(sh.before_rms)} with the table alone, {_fmt(sh.after_rms)} with "
        f"{' + '.join(sh.effects) or 'no effect added'} (each object's mass and friction refitted at the effects "
        f"fitted without it); noise floor {_fmt(sh.noise_floor_rms)}; share of the gap above the floor closed: "
        f"{_fmt(sh.gap_share_closed, '.2f')}"
        + (f" (stop times: {_fmt(sh.stop_time_share_closed, '.2f')})" if sh.stop_time_share_closed is not None else "")
        + ".",
    ]
    n_out = sum(len(x) for x in s.outliers.values())
    if n_out:
        lines += [
            "",
            f"**Gross outliers** ({n_out}, left out of every fit so they cannot decide the verdict; "
            "their replicates were set aside with them):",
            "",
        ]
        for obs, rows in s.outliers.items():
            for r in rows:
                lines.append(
                    f"- {obs}: row {r.row + 1} (object {r.object_id}, speed {r.speed:g} m/s, "
                    f"direction {r.direction:.3g} rad)"
                )
    lines += [
        "",
        "## Where (baseline fit residuals)",
        "",
        f"Baseline RMS residual {_fmt(s.baseline.rms)}. Regions whose mean residual differs from zero "
        f"(95% interval across objects excludes 0): {', '.join(s.localisation.regions_beyond_noise) or 'none'}.",
        "",
        *image("residuals vs speed", "residuals_vs_speed.png"),
    ]
    for factor in FACTORS:
        rows = s.localisation.bands(factor)
        if not rows:
            continue
        lines += [
            f"**{factor}**",
            "",
            "| band | pushes | mean residual | 95% CI | beyond noise |",
            "|---|---|---|---|---|",
        ]
        for b in rows:
            lines.append(
                f"| {b.band} | {b.n_pushes} | {_fmt(b.mean, '+.4f')} | "
                f"[{_fmt(b.ci95[0], '+.4f')}, {_fmt(b.ci95[1], '+.4f')}] | {'yes' if b.differs else ''} |"
            )
        lines.append("")
    lines += [
        "## Which (candidate effects)",
        "",
        "Every hypothesis (at most "
        f"{s.options.max_effects} library effects, one per alias class, with or "
        "without the smooth discrepancy) is fitted jointly with every object's mass and friction and weighed by its "
        "Laplace-approximated evidence (fit, prior volume and posterior width), chi-squares divided by the "
        "dispersion. Inclusion weights: " + (", ".join(f"{k} {w:.3f}" for k, w in s.inclusion.items()) or "none") + ".",
        "",
        *image("hypotheses", "hypotheses.png"),
        "| hypothesis | weight | log evidence | chi-square | held out | parameters | at bound |",
        "|---|---|---|---|---|---|---|",
    ]
    for h in s.hypotheses[:20]:
        lines.append(
            f"| {h.label} | {h.weight:.3g} | {h.log_evidence:.1f} | {h.chi2:.1f} | {h.heldout_chi2:.1f} | "
            f"{h.n_parameters} | {', '.join(h.at_bound)} |"
        )
    if len(s.hypotheses) > 20:
        lines.append(f"| ({len(s.hypotheses) - 20} more in summary.json) | | | | | | |")
    lines += [
        "",
        "Each candidate alone, on top of the table (the screening pass):",
        "",
        "| effect | class | magnitude | 95% CI | LR (critical) | held-out gain |",
        "|---|---|---|---|---|---|",
    ]
    for r in s.ranking:
        az = f" @ {r.azimuth_deg:.0f} deg" if r.azimuth_deg is not None else ""
        lines.append(
            f"| {r.effect} | {r.cls} | {_fmt(r.magnitude)} {r.unit}{az} | [{_fmt(r.ci95[0])}, "
            f"{_fmt(r.ci95[1])}] | {_fmt(r.lr_stat, '.1f')} ({_fmt(r.lr_critical, '.1f')}) | "
            f"{_fmt(r.heldout_gain, '.1f')} |"
        )
    lines.append("")
    al = s.aliasing
    lines += [
        f"Not identifiable from these pushes (projected effect below {s.options.min_visible} RMS at the "
        f"largest magnitude): {', '.join(al.not_identifiable) or 'none'}. Alias classes: "
        f"{'; '.join(al.classes)}.",
    ]
    fit_alias = [f"{n}: {al.effects[n].fit_alias}" for n in al.aliased_with_fit]
    if fit_alias:
        lines += ["", "Candidates largely absorbed by the per-object (mass, friction) fit:", ""]
        lines += [f"- {x}" for x in fit_alias]
    lines += [
        "",
        *image("ranking", "ranking.png"),
        "## How far",
        "",
        f"Held-out RMS gap: {_fmt(sh.before_rms)} before, {_fmt(sh.after_rms)} after "
        f"({sh.effect or 'no effect added'}); noise floor {_fmt(sh.noise_floor_rms)}; share of the gap above "
        f"the floor closed: {_fmt(sh.gap_share_closed, '.2f')}.",
        f"Anchored disagreement (mean over objects): {_fmt(sh.anchored_before_mean)} before, "
        f"{_fmt(sh.anchored_after_mean)} after; floor {_fmt(sh.anchored_floor)}; share closed "
        f"{_fmt(sh.anchored_share_closed, '.2f')}.",
        "",
        *image("before and after", "before_after.png"),
    ]
    return "\n".join(lines)

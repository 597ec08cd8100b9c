"""The reproduction report: every paper number beside the reproduced one, every claim checked.

``reproduction.csv`` has one row per number the paper prints (the registry's ``paper``
column, :mod:`imply.paper.registry`): name, section, paper (as printed), reproduced
(formatted like the paper), reproduced unrounded, stage, status, read by (the instrument that read the
rollouts behind the number, where its stage names one: Section 5's readouts). ``reproduction.md`` shows the same, then every claim of every
part marked holds / fails, then the reproduced numbers the paper does not print.

Status of a number:

* ``matches`` -- equal to the paper's at the paper's printed precision;
* ``close`` -- within 10% of the paper's value, or within 5 units of its last printed
  digit (whichever is looser);
* ``differs`` -- anything else;
* ``not produced`` -- no stage has reported it (yet).
"""

from __future__ import annotations

import html
import math
import os

import pandas as pd

from imply.io import write_csv, write_text
from imply.paper.macros import Merged
from imply.results import Claim, Entry, Registry, binomial_interval, claim_kind, claim_tally, format_value

STATUSES = ("matches", "close", "differs", "not produced")


def number_status(entry: Entry, reproduced: float | None) -> tuple[str, str]:
    """(status, reproduced value printed at the paper's precision) of a number the paper prints."""
    if reproduced is None:
        return "not produced", "not produced"
    r = float(reproduced)
    if not math.isfinite(r):
        return "differs", "--"
    paper = entry.paper_value
    text = f"{r:.{entry.paper_decimals}f}"
    if float(text) == paper or text == entry.paper:
        return "matches", text
    tol = max(0.1 * abs(paper), 5 * 10.0 ** (-entry.paper_decimals))
    return ("close" if abs(r - paper) <= tol else "differs"), text


def reproduction_frame(registry: Registry, merged: Merged) -> pd.DataFrame:
    rows = []
    for entry in registry.in_paper():
        num = merged.numbers.get(entry.name)
        status, text = number_status(entry, None if num is None else num.value)
        rows.append(
            {
                "name": entry.name,
                "section": entry.section,
                "paper": entry.paper,
                "reproduced": text,
                "reproduced_unrounded": "" if num is None else repr(num.value),
                "stage": "" if num is None else num.stage,
                "status": status,
                "read_by": "" if num is None else merged.read_by.get(num.stage, ""),
            }
        )
    return pd.DataFrame(
        rows,
        columns=["name", "section", "paper", "reproduced", "reproduced_unrounded", "stage", "status", "read_by"],
    )


def _summary(merged: Merged, frame: pd.DataFrame) -> tuple[str, str, str]:
    """The report's summary sentences: the paper's numbers by status, the paper's claims, and this project's own
    targets (each over its own denominator, so that a target of ours that fails is not read as the paper
    failing)."""
    counts = frame["status"].value_counts()
    produced = int((frame["status"] != "not produced").sum())
    numbers = f"Paper numbers: {len(frame)}; produced: {produced}; " + "; ".join(
        f"{s}: {int(counts.get(s, 0))}" for s in STATUSES
    )
    tallies = claim_tally(merged.claims)
    paper, ours = tallies["paper"], tallies["project"]
    return (
        numbers + ".",
        f"The paper's claims checked: {paper['checked']}; hold: {paper['hold']}; "
        f"fail: {paper['checked'] - paper['hold']}.",
        f"This project's own targets (the gap benchmarks, the evaluate checks, the pixel model, the Section 5 "
        f"stand-in's per-seed bar) checked: "
        f"{ours['checked']}; hold: {ours['hold']}; fail: {ours['checked'] - ours['hold']}.",
    )


def claim_count(c: Claim) -> str:
    """``k of n, 95% interval [lo, hi]`` of a claim on a share of logs or objects (empty for other claims)."""
    if c.n is None or c.count is None:
        return ""
    lo, hi = binomial_interval(c.count, c.n)
    return f"{c.count} of {c.n}; 95% interval {lo:.2f}-{hi:.2f}"


def _claim_groups(merged: Merged) -> list[tuple[str, list[tuple[str, Claim]]]]:
    """(title, its claims) for the paper's claims, then this project's targets; a kind with no claim left out."""
    groups = [
        (title, [(stage, c) for stage, c in merged.claims if claim_kind(stage, c.id) == kind])
        for kind, title in (("paper", "The paper's claims"), ("project", "This project's targets"))
    ]
    return [(title, claims) for title, claims in groups if claims]


def _claim_detail(c: Claim) -> str:
    count = claim_count(c)
    return f"{c.detail}; {count}" if count and c.detail else (count or c.detail)


BEYOND = "beyond"  # the registry's section of the numbers of what the paper could not show
BEYOND_TITLE = "Beyond the paper: a pixel-space, stochastic world model"
BEYOND_TEXT = (
    "The paper's pixel-space attempt slid the same distance at every speed, and its rollouts were deterministic. "
    "These numbers measure a small pixel-space model that does both (imply.models.pixel_video), through "
    "imply evaluate, read by the frame-difference readout fitted on real clips; its claims are the "
    "[pixel / px-...] lines above."
)


def _unprinted(registry: Registry, merged: Merged) -> list:
    """Reproduced numbers the paper does not print, outside the beyond-the-paper section."""
    known = {e.name for e in registry.in_paper()}
    return [n for n in merged.numbers.values() if n.name not in known and registry[n.name].section != BEYOND]


def _beyond(registry: Registry, merged: Merged) -> list:
    """(number, its label) of the beyond-the-paper section, in registry order."""
    return [(merged.numbers[e.name], e.label) for e in registry if e.section == BEYOND and e.name in merged.numbers]


def per_seed_rows(registry: Registry, merged: Merged) -> list[tuple[str, list[str], str]]:
    """(label, each data-order seed's value as printed, the range) of every number the study reports for more than
    one seed: entries of one source whose paths differ only in the seed's place (``seeds.0.x`` and ``seeds.1.x``)."""
    by_path: dict[tuple[str, str], dict[int, Entry]] = {}
    for e in registry:
        parts = e.path.split(".")
        if len(parts) > 2 and parts[0] == "seeds" and parts[1].isdigit():
            by_path.setdefault((e.source, ".".join(parts[2:])), {})[int(parts[1])] = e
    rows = []
    for entries in by_path.values():
        produced = {k: merged.numbers[e.name] for k, e in sorted(entries.items()) if e.name in merged.numbers}
        if len(produced) < 2:
            continue
        values = [float(n.value) for n in produced.values()]
        first = entries[min(entries)]
        spread = format_value(max(values) - min(values), first.format) if all(map(math.isfinite, values)) else "--"
        rows.append((f"{first.label} (`{first.name}`)", [n.text for n in produced.values()], spread))
    return rows


def reproduction_md(registry: Registry, merged: Merged, frame: pd.DataFrame) -> str:
    numbers_line, paper_line, project_line = _summary(merged, frame)
    out = [
        "# Reproduction report",
        "",
        "Generated by `imply study paper merge` from the result parts of: "
        + (", ".join(merged.stages) if merged.stages else "(no stage yet)")
        + ".",
        "",
        "## Summary",
        "",
        f"- {numbers_line}",
        f"- {paper_line}",
        f"- {project_line}",
        "",
        "A number *matches* when it equals the paper's at the paper's printed precision, is *close* "
        "within 10% (or 5 units of the last printed digit), and *differs* otherwise. A claim on a share of logs "
        "or objects gives its count and the exact 95% binomial interval of the share: what a threshold on that "
        "many can and cannot tell.",
        "",
        "## Claims",
        "",
    ]
    if not merged.claims:
        out += ["No claims reported yet.", ""]
    for title, claims in _claim_groups(merged):
        out += [f"### {title}", ""]
        for stage, c in claims:
            mark = "holds" if c.holds else "FAILS"
            out.append(f"- **{mark}** [{stage} / {c.id}] {c.statement} ({_claim_detail(c)})")
        out.append("")
    out += ["## Numbers", ""]
    if merged.read_by:
        out += ["Read by (the instrument that read the rollouts behind a stage's numbers):", ""]
        out += [f"- [{stage}] {text}" for stage, text in merged.read_by.items()] + [""]
    out += ["| name | section | paper | reproduced | status | read by |", "|---|---|---|---|---|---|"]
    for r in frame.itertuples(index=False):
        read_by = "readout of each model's `imply evaluate` report (above)" if r.read_by else ""
        out.append(f"| {r.name} | {r.section} | {r.paper} | {r.reproduced} | {r.status} | {read_by} |")
    seeds = per_seed_rows(registry, merged)
    if seeds:
        n = len(seeds[0][1])
        out += [
            "",
            "## Per data-order seed",
            "",
            "The numbers the study reports for every data-order seed (config model.seeds, in order), each seed's "
            "value and the range "
            "(a claim above is checked per seed).",
            "",
            "| quantity | " + " | ".join(f"seed {k}" for k in range(n)) + " | range |",
            "|---|" + "---|" * (n + 1),
        ]
        out += [f"| {label} | " + " | ".join(v) + f" | {spread} |" for label, v, spread in seeds]
    extra = _unprinted(registry, merged)
    if extra:
        out += [
            "",
            "## Reproduced numbers the paper does not print",
            "",
            "| name | stage | value |",
            "|---|---|---|",
        ]
        out += [f"| {n.name} | {n.stage} | {n.text} |" for n in extra]
    beyond = _beyond(registry, merged)
    if beyond:
        out += ["", f"## {BEYOND_TITLE}", "", BEYOND_TEXT, "", "| name | value | what it is |", "|---|---|---|"]
        out += [f"| {n.name} | {n.text} | {label} |" for n, label in beyond]
    return "\n".join(out) + "\n"


_HTML_STYLE = (
    "body{font-family:sans-serif;margin:1.5em;max-width:75em}"
    "table{border-collapse:collapse;font-size:90%}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}"
    ".holds{color:#1a7f37}.fails{color:#cf222e;font-weight:bold}"
)


def reproduction_html(registry: Registry, merged: Merged, frame: pd.DataFrame) -> str:
    """The reproduction report as one HTML page (what `snakemake --report` shows inline): the
    same summary, claims and numbers as :func:`reproduction_md`."""
    lines = _summary(merged, frame)
    out = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Reproduction report</title>"
        f"<style>{_HTML_STYLE}</style></head><body>",
        "<h1>Reproduction report</h1>",
        "<p>" + "<br>".join(html.escape(line) for line in lines) + "</p>",
        "<h2>Claims</h2>",
    ]
    for title, claims in _claim_groups(merged):
        out += [f"<h3>{html.escape(title)}</h3>", "<ul>"]
        for stage, c in claims:
            mark = "<span class='holds'>holds</span>" if c.holds else "<span class='fails'>FAILS</span>"
            out.append(
                f"<li>{mark} [{html.escape(stage)} / {html.escape(c.id)}] {html.escape(c.statement)}"
                f" <i>({html.escape(_claim_detail(c))})</i></li>"
            )
        out.append("</ul>")
    out += ["<h2>Numbers</h2>"]
    out.append(frame[["name", "section", "paper", "reproduced", "status"]].to_html(index=False, na_rep=""))
    extra = _unprinted(registry, merged)
    if extra:
        out.append("<h2>Reproduced numbers the paper does not print</h2>")
        rows = pd.DataFrame([(n.name, n.stage, n.text) for n in extra], columns=["name", "stage", "value"])
        out.append(rows.to_html(index=False))
    beyond = _beyond(registry, merged)
    if beyond:
        out += [f"<h2>{html.escape(BEYOND_TITLE)}</h2>", f"<p>{html.escape(BEYOND_TEXT)}</p>"]
        rows = pd.DataFrame([(n.name, n.text, label) for n, label in beyond], columns=["name", "value", "what it is"])
        out.append(rows.to_html(index=False))
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_report(
    registry: Registry,
    merged: Merged,
    *,
    md_path: str | os.PathLike,
    csv_path: str | os.PathLike,
    html_path: str | os.PathLike | None = None,
    timings: list[str] | None = None,
) -> pd.DataFrame:
    """Write the reproduction report (Markdown, CSV and, if asked, HTML); returns its numbers frame. ``timings``:
    the Markdown lines of the last run's time per rule (:func:`imply.paper.timings.markdown`), appended."""
    frame = reproduction_frame(registry, merged)
    write_csv(csv_path, frame)
    md = reproduction_md(registry, merged, frame)
    if timings:
        md = md.rstrip("\n") + "\n\n" + "\n".join(timings) + "\n"
    write_text(md_path, md)
    if html_path is not None:
        write_text(html_path, reproduction_html(registry, merged, frame))
    return frame

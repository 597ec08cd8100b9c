"""The paper's figures, written as PDF and PNG with fixed metadata (the same inputs give the same files).

Figure 1, the controlled validation at a glance: (a) self and anchored disagreement of
every object under each stand-in (log scale, one dot per object, a bar at the mean);
(b) anchored (solid) and self (dashed) disagreement's AUROC against the oracle as readout
noise grows, one colour per stand-in.

Figure 2, the learned model: (a) predicted against true slide per object, (b) own
against swapped disagreement, (c, d) self and anchored disagreement against true error.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from imply import stats  # noqa: E402
from imply.io import atomic_path  # noqa: E402

NAMES = {"oracle": "oracle", "jitter": "jitter", "blind": "object-blind", "collapse": "collapse"}
COLORS = {"oracle": "#4d4d4d", "jitter": "#1f77b4", "blind": "#d62728", "collapse": "#2ca02c"}


def figure1(
    scores: pd.DataFrame,
    noise: dict,
    *,
    standins: Sequence[str],
    pdf_path: str | os.PathLike,
    png_path: str | os.PathLike,
) -> None:
    """Draw Figure 1 from per-object scores (``scores.csv``) and the noise sweep's result (``noise.json``).

    ``standins``: the stand-ins in the order drawn, the oracle first (the study's
    ``imply.study.section4.standins.STANDINS``; the caller passes it so that this module
    plots without importing the study).
    """
    plt.rcParams.update({"font.size": 8, "svg.hashsalt": "imply"})
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(7.0, 2.8), gridspec_kw={"width_ratios": [1.3, 1]})
    rng = np.random.default_rng(0)  # horizontal jitter of the dots only
    width = 0.35
    for i, name in enumerate(standins):
        sub = scores[scores["standin"] == name]
        for j, (col, marker) in enumerate((("self_disagreement", "o"), ("anchored_disagreement", "s"))):
            x = i + (j - 0.5) * width
            y = np.maximum(sub[col].to_numpy(float), 1e-4)
            ax_a.scatter(
                x + rng.uniform(-0.1, 0.1, y.size),
                y,
                s=3,
                alpha=0.35,
                color=COLORS[name],
                marker=marker,
                linewidths=0,
                rasterized=True,
            )
            ax_a.hlines(y.mean(), x - 0.15, x + 0.15, color="black", lw=1.2)
    ax_a.set_yscale("log")
    ax_a.set_xticks(range(len(standins)))
    ax_a.set_xticklabels([f"{NAMES[s]}\nself | anch." for s in standins])
    ax_a.set_ylabel("disagreement (RMS log residual)")
    ax_a.set_title("(a) self vs anchored disagreement", loc="left")

    sds = [level["sd"] for level in noise["levels"]]
    for name in standins[1:]:
        for key, ls, marker, mfc in (("auroc_anchored", "-", "o", COLORS[name]), ("auroc_self", "--", "^", "white")):
            auroc = [level["standins"][name][key] for level in noise["levels"]]
            ax_b.plot(sds, auroc, ls=ls, marker=marker, ms=3, color=COLORS[name], mfc=mfc, lw=1.2)
    ax_b.axhline(0.5, color="grey", lw=0.8, ls=":")
    ax_b.set_ylim(0.3, 1.02)  # room below chance for the stand-ins' legend
    ax_b.set_xlabel("readout noise (log sd)")
    ax_b.set_ylabel("AUROC vs oracle")
    ax_b.set_title("(b) robustness to readout noise", loc="left")
    # one legend for the colours (stand-ins), one for the line styles (which disagreement)
    colours = [Line2D([], [], color=COLORS[n], lw=1.2, label=NAMES[n]) for n in standins[1:]]
    styles = [
        Line2D([], [], color="black", ls="-", marker="o", ms=3, lw=1.2, label="anchored"),
        Line2D([], [], color="black", ls="--", marker="^", ms=3, mfc="white", lw=1.2, label="self"),
    ]
    ax_b.add_artist(
        ax_b.legend(handles=colours, frameon=False, loc="lower left", ncol=3, fontsize=7, columnspacing=1.2)
    )
    ax_b.legend(handles=styles, frameon=False, loc="center left", bbox_to_anchor=(0.3, 0.62), fontsize=7)
    fig.tight_layout()
    with atomic_path(pdf_path) as tmp:
        fig.savefig(tmp, format="pdf", metadata={"CreationDate": None, "Producer": None, "Creator": None})
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, format="png", dpi=200, metadata={"Software": None})
    plt.close(fig)


def _save_pdf_png(fig, pdf_path: str | os.PathLike, png_path: str | os.PathLike) -> None:
    """Write ``fig`` as PDF and PNG (150 dpi), each atomically and without a timestamp, and close it."""
    with atomic_path(pdf_path) as tmp:
        fig.savefig(tmp, format="pdf", metadata={"CreationDate": None, "ModDate": None})
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, format="png", dpi=150, metadata={"Software": None})
    plt.close(fig)


def _f(x: float, spec: str = ".2f") -> str:
    return format(x, spec) if np.isfinite(x) else "nan"


def figure2(per_object: pd.DataFrame, *, seed: int, pdf_path: str | os.PathLike, png_path: str | os.PathLike) -> None:
    """Figure 2 from the per-object scores (``per_object.csv``) of data-order seed ``seed``:
    (a) predicted vs true per object, (b) own vs swapped disagreement, (c, d) self and
    anchored disagreement against true error (own and swapped pooled)."""
    plt.rcParams.update({"svg.hashsalt": "imply", "pdf.compression": 6})
    f = per_object[(per_object["seed"] == seed) & (per_object["model"] == "calib")]
    by = {ctx: d.set_index("object_id").sort_index() for ctx, d in f.groupby("context")}
    fig, ax = plt.subplots(1, 4, figsize=(14, 3.4))
    colours = {"own": "tab:blue", "swap": "tab:red", "none": "tab:grey"}
    names = {"own": "own calibration", "swap": "other's calibration", "none": "no calibration"}
    for ctx in ("none", "swap", "own"):
        d = by[ctx]
        ax[0].scatter(
            np.exp(d["mean_log_true"]) * 1000,
            np.exp(d["mean_log_pred"]) * 1000,
            s=6,
            alpha=0.6,
            color=colours[ctx],
            label=names[ctx],
        )
    lim = ax[0].get_xlim()
    ax[0].plot(lim, lim, "k--", lw=0.8)
    ax[0].set_xlabel("true slide (mm, geometric mean)")
    ax[0].set_ylabel("predicted slide (mm)")
    ax[0].set_title("(a) prediction per object")
    ax[0].legend(fontsize=7, markerscale=2)
    own, swap = by["own"], by["swap"]
    ax[1].scatter(own["self_disagreement"], swap["self_disagreement"], s=6, alpha=0.6, color="tab:orange", label="self")
    ax[1].scatter(
        own["anchored_disagreement"], swap["anchored_disagreement"], s=6, alpha=0.6, color="tab:green", label="anchored"
    )
    hi = float(
        np.nanmax(
            [
                own[["self_disagreement", "anchored_disagreement"]].to_numpy().max(),
                swap[["self_disagreement", "anchored_disagreement"]].to_numpy().max(),
            ]
        )
    )
    ax[1].plot([0, hi], [0, hi], "k--", lw=0.8)
    ax[1].set_xlabel("disagreement, own calibration")
    ax[1].set_ylabel("disagreement, other's calibration")
    ax[1].set_title("(b) own vs swapped")
    ax[1].legend(fontsize=7, markerscale=2)
    pooled = pd.concat([own, swap])
    for i, (col, name) in enumerate((("self_disagreement", "self"), ("anchored_disagreement", "anchored")), start=2):
        ax[i].scatter(pooled[col], pooled["log_error"], s=6, alpha=0.6, color="tab:purple")
        r = stats.pearson(pooled[col], pooled["log_error"])
        ax[i].set_xlabel(f"{name} disagreement")
        ax[i].set_ylabel("true log error")
        ax[i].set_title(f"({'cd'[i - 2]}) {name} vs error, r = {_f(r)}")
    fig.tight_layout()
    _save_pdf_png(fig, pdf_path, png_path)


def training_figure(histories: list[dict], *, png_path: str | os.PathLike) -> None:
    """Per-epoch validation of every trained predictor on the validation objects (Table 3's quantities).

    ``histories``: the ``--history`` documents of ``imply study model train`` (keys ``seed``,
    ``layout`` and ``history``, a list of per-epoch entries). Left: log error per context,
    the object-blind baseline dashed; middle: tracking r; right: the share of objects
    whose disagreement is lower with their own calibration than with another's, self and
    anchored. Calibration use shows as the own-calibration curves leaving the swapped ones.
    """
    fig, (ax_err, ax_r, ax_share) = plt.subplots(1, 3, figsize=(13.0, 3.6))
    colours = {"own": "C0", "swap": "C3", "none": "C7"}
    styles = ["-", "--", ":", "-."]
    seeds = sorted({int(doc["seed"]) for doc in histories})
    blind_drawn = False
    for doc in histories:
        # the epochs that were validated (every validate_every epochs, the first and the last)
        hist = [h for h in doc["history"] if "own_error" in h or "none_error" in h] or doc["history"]
        epochs = [h["epoch"] for h in hist]
        variant = "calib" if doc["layout"].get("calib") else "nocalib"
        ls = styles[seeds.index(int(doc["seed"])) % len(styles)]
        for ctx, colour in colours.items():
            if f"{ctx}_error" not in hist[0]:
                continue
            label = f"{variant} seed {doc['seed']}: {ctx}"
            ax_err.plot(epochs, [h[f"{ctx}_error"] for h in hist], ls, color=colour, label=label)
            ax_r.plot(epochs, [h[f"{ctx}_track"] for h in hist], ls, color=colour, label=label)
        for key, colour in (("own_lt_swap_anchored", "C2"), ("own_lt_swap_self", "C1")):
            if key in hist[0]:
                name = key.rsplit("_", 1)[1]
                ax_share.plot(epochs, [h[key] for h in hist], ls, color=colour, label=f"seed {doc['seed']}: {name}")
        if not blind_drawn and "blind_error" in hist[0]:
            ax_err.axhline(hist[0]["blind_error"], color="k", lw=0.8, ls="--", label="object-blind baseline")
            blind_drawn = True
    ax_err.set(xlabel="epoch", ylabel="log error (real-clip readout)")
    ax_r.set(xlabel="epoch", ylabel="tracking r")
    ax_r.axhline(0.0, color="k", lw=0.5)
    ax_share.axhline(50.0, color="k", lw=0.5)
    ax_share.set(xlabel="epoch", ylabel="own < swapped (% of objects)", ylim=(0, 100))
    for ax in (ax_err, ax_share):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6, ncol=1)
    fig.suptitle(
        "Predictor validation per epoch on the validation objects: own vs swapped calibration, and none"
        " (colour: context or score; line: data-order seed)",
        fontsize=8,
    )
    fig.tight_layout()
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, format="png", dpi=150, metadata={"Software": None})
    plt.close(fig)


def figure3(
    *,
    true_rest: np.ndarray,
    generated_rest: np.ndarray,
    panel_labels: Sequence[str],
    slides: dict[str, pd.DataFrame],
    selection: dict[str, dict[str, float]],
    pdf_path: str | os.PathLike,
    png_path: str | os.PathLike,
) -> None:
    """Figure 3 (beyond the paper), the pixel-space world model.

    true_rest, generated_rest: uint8 (P, H, W, 3) rest frames of P pushes, labelled by
    ``panel_labels``; slides: per variant label, rows with ``true_displacement_m`` and
    ``read_displacement_m``; selection: rule -> {"track", "error"} among the sample sets.
    """
    plt.rcParams.update({"svg.hashsalt": "imply", "pdf.compression": 6})
    p = len(true_rest)
    fig = plt.figure(figsize=(15, 0.85 * p + 1.0))
    grid = fig.add_gridspec(p, 4, width_ratios=[2.2, 2.2, 1.1, 1.1])
    for i in range(p):
        for j, (frames, title) in enumerate(((true_rest, "true rest frame"), (generated_rest, "generated (sample 0)"))):
            ax = fig.add_subplot(grid[i, j])
            ax.imshow(frames[i], interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if j == 0:
                ax.set_ylabel(panel_labels[i], rotation=0, ha="right", va="center", fontsize=7)
            if i == 0:
                ax.set_title(f"(a) {title}", fontsize=9)
    ax = fig.add_subplot(grid[:, 2])
    colours = ("tab:blue", "tab:grey", "tab:green")
    for (label, d), colour in zip(slides.items(), colours, strict=False):
        ax.scatter(
            d["true_displacement_m"] * 100, d["read_displacement_m"] * 100, s=4, alpha=0.4, color=colour, label=label
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    lim = ax.get_xlim()
    ax.plot(lim, lim, "k--", lw=0.8)
    ax.set_xlabel("true slide (cm)")
    ax.set_ylabel("slide read off generated frames (cm)")
    ax.set_title("(b) read against true", fontsize=9)
    ax.legend(fontsize=7, markerscale=3)
    ax = fig.add_subplot(grid[:, 3])
    rules = list(selection)
    y = np.arange(len(rules))
    ax.barh(y - 0.2, [selection[r]["track"] for r in rules], height=0.4, color="tab:purple", label="tracking r")
    ax.barh(y + 0.2, [selection[r]["error"] for r in rules], height=0.4, color="tab:orange", label="mean log error")
    ax.set_yticks(y, [f"lowest {r}" if r in ("anchored", "self") else r for r in rules], fontsize=8)
    ax.axvline(0, color="k", lw=0.6)
    ax.invert_yaxis()
    ax.set_title("(c) choosing among sample sets", fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    _save_pdf_png(fig, pdf_path, png_path)

"""Figure 1 of the paper: the controlled validation at a glance.

(a) self and anchored disagreement of every object under each stand-in (log scale,
one dot per object, a bar at the mean); (b) anchored disagreement's AUROC against the
oracle as readout noise grows, one line per stand-in. Written as PDF and PNG with
fixed metadata, so the same inputs give the same files.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from imply.io import atomic_path  # noqa: E402
from imply.standins import STANDINS  # noqa: E402

NAMES = {"oracle": "oracle", "jitter": "jitter", "blind": "object-blind", "collapse": "collapse"}
COLORS = {"oracle": "#4d4d4d", "jitter": "#1f77b4", "blind": "#d62728", "collapse": "#2ca02c"}


def figure1(
    scores: pd.DataFrame, noise: pd.DataFrame, pdf_path: str | os.PathLike, png_path: str | os.PathLike
) -> None:
    """Draw Figure 1 from per-object scores (``scores.csv``) and the noise sweep (``noise.csv``)."""
    plt.rcParams.update({"font.size": 8, "svg.hashsalt": "imply"})
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(7.0, 2.8), gridspec_kw={"width_ratios": [1.3, 1]})
    rng = np.random.default_rng(0)  # horizontal jitter of the dots only
    width = 0.35
    for i, name in enumerate(STANDINS):
        sub = scores[scores["standin"] == name]
        for j, (col, marker) in enumerate((("self_disagreement", "o"), ("anchored_disagreement", "s"))):
            x = i + (j - 0.5) * width
            y = np.maximum(sub[col].to_numpy(float), 1e-4)
            ax_a.scatter(
                x + rng.uniform(-0.1, 0.1, y.size), y, s=3, alpha=0.35, color=COLORS[name], marker=marker,
                linewidths=0, rasterized=True,
            )  # fmt: skip
            ax_a.hlines(y.mean(), x - 0.15, x + 0.15, color="black", lw=1.2)
    ax_a.set_yscale("log")
    ax_a.set_xticks(range(len(STANDINS)))
    ax_a.set_xticklabels([f"{NAMES[s]}\nself | anch." for s in STANDINS])
    ax_a.set_ylabel("disagreement (RMS log residual)")
    ax_a.set_title("(a) self vs anchored disagreement", loc="left")

    for name in STANDINS[1:]:
        sub = noise[noise["standin"] == name].sort_values("sd")
        ax_b.plot(sub["sd"], sub["auroc_anchored"], marker="o", ms=3, color=COLORS[name], label=NAMES[name])
    ax_b.axhline(0.5, color="grey", lw=0.8, ls=":")
    ax_b.set_ylim(0.4, 1.02)
    ax_b.set_xlabel("readout noise (log sd)")
    ax_b.set_ylabel("anchored AUROC vs oracle")
    ax_b.set_title("(b) robustness to readout noise", loc="left")
    ax_b.legend(frameon=False)
    fig.tight_layout()
    with atomic_path(pdf_path) as tmp:
        fig.savefig(tmp, format="pdf", metadata={"CreationDate": None, "Producer": None, "Creator": None})
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, format="png", dpi=200, metadata={"Software": None})
    plt.close(fig)

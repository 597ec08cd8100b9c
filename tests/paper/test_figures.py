"""Figure 1's noise panel: anchored and self AUROC per stand-in, told apart by line style."""

from __future__ import annotations

import numpy as np
import pandas as pd

from imply.paper import figures

STANDINS = ("oracle", "jitter", "blind", "collapse")


def test_figure1_noise_panel_draws_anchored_solid_and_self_dashed(tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    scores = pd.DataFrame(
        {
            "standin": np.repeat(STANDINS, 5),
            "self_disagreement": rng.uniform(0.01, 1, 20),
            "anchored_disagreement": rng.uniform(0.01, 1, 20),
        }
    )
    auroc = {"jitter": (1.0, 0.9), "blind": (0.95, 0.55), "collapse": (1.0, 1.0)}  # (anchored, self) at every level
    levels = [
        {
            "sd": sd,
            "standins": {
                "oracle": {"auroc_anchored": None, "auroc_self": None},
                **{n: {"auroc_anchored": a, "auroc_self": s} for n, (a, s) in auroc.items()},
            },
        }
        for sd in (0.0, 0.1)
    ]
    drawn = []
    monkeypatch.setattr(figures.plt, "close", drawn.append)  # keep the figure to look at it
    pdf, png = tmp_path / "f.pdf", tmp_path / "f.png"
    figures.figure1(scores, {"levels": levels}, standins=STANDINS, pdf_path=pdf, png_path=png)
    assert pdf.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    ax_b = drawn[0].axes[1]
    lines = {
        (ln.get_color(), ln.get_linestyle()): list(ln.get_ydata())
        for ln in ax_b.get_lines()
        if len(ln.get_ydata()) == 2
    }
    for name, (anchored, self_) in auroc.items():
        assert lines[(figures.COLORS[name], "-")] == [anchored, anchored]
        assert lines[(figures.COLORS[name], "--")] == [self_, self_]
    legend_text = {t.get_text() for leg in ax_b.findobj(lambda a: hasattr(a, "get_texts")) for t in leg.get_texts()}
    assert {"anchored", "self", "object-blind", "jitter", "collapse"} <= legend_text

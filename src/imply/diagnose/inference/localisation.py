"""Step 2 of the diagnosis: where the baseline fit's residuals lie beyond the noise.

Each object's (m, mu) is fitted against the baseline (a measured mass or friction held
fixed); its displacement residuals are grouped by speed, displacement, fitted mass,
fitted friction, direction and object, each band's mean with a 95% interval across
objects. Flagged outliers are left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.fit import ObjectFit, Problem
from imply.diagnose.records import Record, json_field
from imply.diagnose.tails import chi2_sf, t_ppf

# the factors residuals are banded by, in the order the report shows them
FACTORS = ("speed", "displacement", "direction", "fitted_mass", "fitted_friction")


@dataclass(frozen=True, kw_only=True)
class Band(Record):
    """The residuals of one band of a factor: mean over objects' band means, 95% t interval across objects."""

    band: str
    n_pushes: int
    n_objects: int
    mean: float
    ci95: tuple[float, float]
    rms: float
    differs: bool
    # the band's range of its factor's values (a value of its own: low = high)
    low: float | None = json_field(omit_none=True, default=None)
    high: float | None = json_field(omit_none=True, default=None)


@dataclass(frozen=True, kw_only=True)
class ObjectResidual(Record):
    """One object's baseline fit: its residuals, fitted mass and friction, and a chi-square test at the noise."""

    object_id: str
    n_pushes: int
    rms: float
    mass_hat: float
    friction_hat: float
    p_value: float
    differs: bool


@dataclass(frozen=True, kw_only=True)
class Localisation(Record):
    """The baseline fit's residuals by band of each factor (direction only where the log has directions)."""

    speed: list[Band]
    displacement: list[Band]
    fitted_mass: list[Band]
    fitted_friction: list[Band]
    direction: list[Band] | None = json_field(omit_none=True, default=None)
    object: list[ObjectResidual]
    regions_beyond_noise: list[str]

    def bands(self, factor: str) -> list[Band] | None:
        """The bands of ``factor`` (one of :data:`FACTORS`; None where the log has no such column)."""
        return getattr(self, factor)


def _band_stats(
    label: str, values: np.ndarray, *, obj: np.ndarray, n_obj: int, span: tuple[float, float] | None = None
) -> Band:
    """Mean residual over objects' band means, with a 95% t interval across objects."""
    per_obj = np.bincount(obj, values, minlength=n_obj)
    cnt = np.bincount(obj, minlength=n_obj)
    means = per_obj[cnt > 0] / cnt[cnt > 0]
    k = means.size
    mean = float(means.mean())
    half = float(t_ppf(0.975, k - 1) * means.std(ddof=1) / np.sqrt(k)) if k >= 2 else float("nan")
    lo, hi = mean - half, mean + half
    return Band(
        band=label,
        n_pushes=int(values.size),
        n_objects=int(k),
        mean=mean,
        ci95=(lo, hi),
        rms=float(np.sqrt(np.mean(values**2))),
        differs=bool(np.isfinite(half) and (lo > 0 or hi < 0)),
        low=None if span is None else float(span[0]),
        high=None if span is None else float(span[1]),
    )


def _bands(x: np.ndarray, n_bins: int, distinct_max: int = 12) -> tuple[np.ndarray, list[str], list[tuple]]:
    """Each value's band, the bands' labels and their (low, high) ranges: one band per distinct value where there are
    at most ``distinct_max``, else ``n_bins`` quantile bins."""
    uniq = np.unique(x)
    if uniq.size <= distinct_max:
        return np.searchsorted(uniq, x), [f"{u:.4g}" for u in uniq], [(u, u) for u in uniq]
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bins - 1)
    spans = [(edges[i], edges[i + 1]) for i in range(n_bins)]
    return idx, [f"[{lo:.4g}, {hi:.4g}]" for lo, hi in spans], spans


def localise(problem: Problem, fit: ObjectFit, resid: np.ndarray, *, alpha: float) -> Localisation:
    """Displacement residuals ``resid`` of the baseline fit ``fit``, by region (flagged outliers left out)."""
    keep = problem.w_d > 0
    obj, n_obj = problem.obj[keep], problem.n_obj
    r = resid[keep]
    factors = {
        "speed": _bands(problem.v[keep], 5),
        "displacement": _bands(problem.log.displacement[keep], 5, distinct_max=0),
        "fitted_mass": _bands(np.exp(fit.lm)[obj], 3, distinct_max=0),
        "fitted_friction": _bands(np.exp(fit.lu)[obj], 3, distinct_max=0),
    }
    if problem.log.has_direction:
        sector = np.round(np.mod(problem.phi[keep], 2 * np.pi) / (np.pi / 4)).astype(int) % 8
        uniq = np.unique(sector)
        factors["direction"] = (
            np.searchsorted(uniq, sector),
            [f"{s * 45} deg" for s in uniq],
            [(s * 45.0, s * 45.0) for s in uniq],
        )
    banded = {
        name: [
            _band_stats(label, r[idx == b], obj=obj[idx == b], n_obj=n_obj, span=spans[b])
            for b, label in enumerate(labels)
            if (idx == b).any()
        ]
        for name, (idx, labels, spans) in factors.items()
    }
    sse = np.bincount(obj, r**2, minlength=n_obj)
    sd_row = np.broadcast_to(problem.sd_d, problem.y.shape)[keep]
    wsse = np.bincount(obj, (r / sd_row) ** 2, minlength=n_obj)
    cnt = np.bincount(obj, minlength=n_obj)
    dof = np.maximum(cnt - problem.k_free, 1)
    objects = []
    for i, name in enumerate(problem.log.objects):
        p = chi2_sf(float(wsse[i]), float(dof[i]))
        objects.append(
            ObjectResidual(
                object_id=name,
                n_pushes=int(cnt[i]),
                rms=float(np.sqrt(sse[i] / max(cnt[i], 1))),
                mass_hat=float(np.exp(fit.lm[i])),
                friction_hat=float(np.exp(fit.lu[i])),
                p_value=p,
                differs=bool(p < alpha / n_obj),
            )
        )
    regions = [f"{name}={band.band}" for name, bands in banded.items() for band in bands if band.differs]
    regions += [f"object={o.object_id}" for o in objects if o.differs]
    return Localisation(**banded, object=objects, regions_beyond_noise=regions)

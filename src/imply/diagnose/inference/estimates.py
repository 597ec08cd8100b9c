"""What the diagnosis reports of a fitted candidate: its magnitude (and azimuth) with 95% intervals.

Every effect of the leading hypothesis (:class:`AcceptedEffect`), of every hypothesis
(:class:`EffectEstimate`) and every candidate fitted alone (:class:`RankedCandidate`) is
reported with its magnitude, and for
a tilt or an anisotropy its azimuth, each with a 95% interval from the joint fit's
curvature (delta method).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.aliasing import Aliasing
from imply.diagnose.inference.screening import StepResult
from imply.diagnose.physics.candidates import Candidate, Model
from imply.diagnose.records import Record, json_field

Z95 = 1.959964


@dataclass(frozen=True, kw_only=True)
class EffectEstimate(Record):
    """A candidate's fitted magnitude (and azimuth, degrees, table frame) with 95% intervals."""

    effect: str
    title: str
    unit: str
    components: dict[str, float]
    magnitude: float
    ci95: tuple[float, float]
    sd: float
    at_bound: bool
    azimuth_deg: float | None = json_field(omit_none=True, default=None)
    azimuth_ci95_deg: tuple[float, float] | None = json_field(omit_none=True, default=None)


@dataclass(frozen=True, kw_only=True)
class AcceptedEffect(EffectEstimate):
    """An effect of the verdict: its estimate, alias class and how the per-object fit aliases it."""

    cls: str = json_field(key="class")
    fit_alias: str


@dataclass(frozen=True, kw_only=True)
class RankedCandidate(EffectEstimate):
    """A candidate fitted alone on top of the baseline (the screening pass), with its tests."""

    cls: str = json_field(key="class")
    identifiable: bool
    lr_stat: float
    df: int
    lr_critical: float
    heldout_gain: float
    heldout_improvement: float
    explained_ms: float
    floor_ms: float
    qualifies: bool
    reasons: list[str]
    delta_bic: float


def estimate_fields(c: Candidate, theta: np.ndarray, cov: np.ndarray) -> dict:
    """The fields of an :class:`EffectEstimate` of ``c`` at ``theta`` with covariance ``cov``."""
    theta = np.asarray(theta, float)
    out: dict = {
        "effect": c.name,
        "title": c.title,
        "unit": c.unit,
        "components": dict(zip(c.components, theta.tolist(), strict=True)),
    }
    if c.dim == 1:
        sd = float(np.sqrt(max(cov[0, 0], 0.0)))
        lo, hi = c.lo[0], c.hi[0]
        out.update(
            magnitude=float(theta[0]),
            ci95=(float(max(theta[0] - Z95 * sd, lo)), float(min(theta[0] + Z95 * sd, hi))),
            sd=sd,
            at_bound=bool(np.isclose(theta[0], lo) or np.isclose(theta[0], hi)),
        )
        if c.basis is not None:  # restricted to one direction: its azimuth is the design's, not fitted
            out.update(azimuth_deg=c.restricted_axis_deg())
        return out
    if c.dim > 2:  # the discrepancy: the size of its coefficient vector (described in full apart)
        a = float(np.linalg.norm(theta))
        g = theta / a if a > 0 else np.zeros_like(theta)
        sd_a = float(np.sqrt(max(g @ cov @ g, 0.0)))
        out.update(
            magnitude=a,
            ci95=(max(a - Z95 * sd_a, 0.0), a + Z95 * sd_a),
            sd=sd_a,
            at_bound=bool(np.any(np.isclose(np.abs(theta), c.hi))),
        )
        return out
    a = float(np.hypot(*theta))
    g = theta / a if a > 0 else np.array([1.0, 0.0])
    sd_a = float(np.sqrt(max(g @ cov @ g, 0.0)))
    if a > 0:
        ga = np.array([-theta[1], theta[0]]) / a**2
        sd_ang = float(np.sqrt(max(ga @ cov @ ga, 0.0)))
    else:
        sd_ang = float("inf")
    ang = c.azimuth(theta)
    factor = 0.5 if c.period and c.period < 2 * np.pi - 1e-9 else 1.0
    half = min(Z95 * sd_ang * factor, c.period / 2)
    out.update(
        magnitude=a,
        ci95=(max(a - Z95 * sd_a, 0.0), min(a + Z95 * sd_a, float(c.radius))),
        sd=sd_a,
        azimuth_deg=float(np.degrees(ang)),
        azimuth_ci95_deg=(float(np.degrees(ang - half)), float(np.degrees(ang + half))),
        at_bound=bool(a >= c.radius * (1 - 1e-6)),
    )
    return out


def ranked(results: list[StepResult], alias: Aliasing, *, model_before: Model, n: int) -> list[RankedCandidate]:
    """The candidates tried at one step (``results``, on top of ``model_before``), as reported; ``n`` pushes."""
    rows = []
    k0 = model_before.dim
    for r in results:
        c = r.candidate
        th = r.fit.theta[k0 : k0 + c.dim]
        cov = r.fit.covariance()[k0 : k0 + c.dim, k0 : k0 + c.dim]
        rows.append(
            RankedCandidate(
                **estimate_fields(c, th, cov),
                cls=alias.effects[c.name].cls,
                identifiable=alias.effects[c.name].identifiable,
                lr_stat=r.lr,
                df=r.df,
                lr_critical=r.critical,
                heldout_gain=r.heldout_gain,
                heldout_improvement=r.heldout_share,
                explained_ms=r.explained_ms,
                floor_ms=r.floor_ms,
                qualifies=r.qualifies,
                reasons=r.reasons,
                delta_bic=float(-r.lr + c.dim * np.log(max(n, 2))),
            )
        )
    return rows


def accepted_effects(fit_model: Model, theta: np.ndarray, *, cov: np.ndarray, alias: Aliasing) -> list[AcceptedEffect]:
    """Each effect of ``fit_model`` at ``theta`` (covariance ``cov``), with its alias class and fit aliasing."""
    return [
        AcceptedEffect(
            **estimate_fields(c, theta[sl], cov[sl, sl]),
            cls=alias.effects[c.name].cls,
            fit_alias=alias.effects[c.name].fit_alias,
        )
        for c, sl in zip(fit_model.candidates, fit_model.slices(), strict=True)
        if c.is_library  # the discrepancy is described apart (imply.diagnose.inference.discrepancy)
    ]

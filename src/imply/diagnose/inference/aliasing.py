"""Step 3 of the diagnosis: which candidates these pushes can tell apart, from each other and from the fit.

Each candidate's change of the pushes per unit magnitude (a secant at half its bound),
with each object's (log m, log mu) directions projected out. What the projection removes
is what the per-object fit absorbs: a candidate that loses at least ``fit_alias_share``
of its change this way is reported as aliased with the fit, naming the parameter that
absorbs it (friction, mass, or both) and how measuring it would help. A candidate whose
projected change at its largest magnitude is below ``min_visible`` (RMS, in either
observable) is not identifiable; the others form alias classes when their projected
changes are nearly parallel (|cos| >= ``alias_cos``; for two-component candidates the
largest canonical correlation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.fit import ObjectFit, Problem
from imply.diagnose.physics.candidates import FRICTION2, Candidate, Model
from imply.diagnose.records import Record, json_field
from imply.options import Config

NOT_IDENTIFIABLE = "not identifiable"


@dataclass(frozen=True, kw_only=True)
class CandidateAliasing(Record):
    """One candidate: how much of it these pushes see, what the per-object fit absorbs, its alias class."""

    raw_rms_at_bound: float
    visible_rms_at_bound: float
    visible_stop_time_rms_at_bound: float | None
    visible_share: float
    absorbed_by_fit: float
    absorbed_by_mass: float
    absorbed_by_friction: float
    identifiable: bool
    fit_alias: str  # a sentence when the per-object fit absorbs most of it, else ""
    cls: str = json_field(key="class")  # its alias class ("tilt+height"), or "not identifiable"


@dataclass(frozen=True, kw_only=True)
class Restriction(Record):
    """A two-component effect of which these pushes' directions show one combination only."""

    direction: tuple[float, float]  # the identifiable combination of its two components (unit vector)
    weak_rms_at_bound: float  # what the other combination would change, at the effect's largest magnitude
    note: str  # what can be said, and what to add to tell the rest


@dataclass(frozen=True, kw_only=True)
class Aliasing(Record):
    """Every candidate's aliasing, the alias classes and the cosines between projected changes.

    ``discrepancy_mimics``: for each library candidate, the largest canonical correlation between its projected
    change and the discrepancy term's (1: the discrepancy can imitate it exactly on these pushes);
    ``mimicked``: those at or above ``alias_cos``; ``restricted``: two-component effects of which only one
    combination is identifiable from these pushes' directions."""

    effects: dict[str, CandidateAliasing]
    classes: list[str]
    not_identifiable: list[str]
    aliased_with_fit: list[str]
    projected_cosine: dict[str, float]
    discrepancy_mimics: dict[str, float] = json_field(default_factory=dict)
    mimicked: list[str] = json_field(default_factory=list)
    restricted: dict[str, Restriction] = json_field(default_factory=dict)


def _reference(c: Candidate) -> np.ndarray:
    """Half the candidate's largest magnitude, per component (toward the larger side)."""
    ref = np.where(np.abs(np.asarray(c.hi)) >= np.abs(np.asarray(c.lo)), c.hi, c.lo) * 0.5
    if c.radius is not None:
        ref = ref / np.sqrt(2.0)
    return np.asarray(ref, float)


Projection = Callable[[np.ndarray], np.ndarray]


def _projector(problem: Problem, fit: ObjectFit) -> tuple[Projection, Projection, Projection]:
    """Functions removing each object's (log m, log mu) directions (both, or each alone) from row vectors."""
    lm, lu = fit.lm[None, :], fit.lu[None, :]
    r = problem.residuals(
        Model(), np.zeros((3, 0)), np.concatenate([lm, lm + 1e-4, lm]), np.concatenate([lu, lu, lu + 1e-4])
    )
    jm, ju = (r[1] - r[0]) / 1e-4, (r[2] - r[0]) / 1e-4
    jm, ju = problem._free_columns(jm, ju)
    ro = problem._row_obj()
    n = problem.n_obj

    def onto(x: np.ndarray, cols: list[np.ndarray]) -> np.ndarray:
        cols = [c for c in cols if np.any(c != 0)]
        if not cols:
            return x
        k = len(cols)
        A = np.zeros((n, k, k))
        b = np.zeros((n, k))
        for a in range(k):
            b[:, a] = np.bincount(ro, cols[a] * x, minlength=n)
            for c in range(k):
                A[:, a, c] = np.bincount(ro, cols[a] * cols[c], minlength=n)
        A += 1e-12 * np.eye(k)
        coef = np.linalg.solve(A, b[..., None])[..., 0]
        return x - sum(coef[ro, a] * cols[a] for a in range(k))

    return (lambda x: onto(x, [jm, ju])), (lambda x: onto(x, [jm])), (lambda x: onto(x, [ju]))


def _canonical(a: np.ndarray, b: np.ndarray) -> float:
    """Largest canonical correlation between the column spaces of a and b."""
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max())


def fit_alias_text(
    c: Candidate, *, absorbed: float, by_mass: float, by_friction: float, k_free: int, share: float
) -> str:
    """A sentence when the per-object (mass, friction) fit absorbs at least ``share`` of what ``c`` does."""
    if absorbed < share:
        return ""
    if by_friction >= share and by_friction >= by_mass:
        param, fix = "a friction change", "friction is measured"
    elif by_mass >= share:
        param, fix = "a mass change", "mass is measured"
    else:
        param = "a change of mass and friction together"
        fix = "mass or friction is measured" if k_free == 2 else "both are measured"
    return (
        f"{c.phrase} here is {absorbed:.0%} indistinguishable from {param} of each object (the per-object fit "
        f"absorbs it) unless {fix}"
    )


def aliasing(problem: Problem, candidates: list[Candidate], *, fit: ObjectFit, opts: Config) -> Aliasing:
    """Projected sensitivities, identifiability, alias classes, and aliasing with the per-object fit
    (``opts``: ``min_visible``, ``alias_cos``, ``fit_alias_share``)."""
    both, mass_only, fric_only = _projector(problem, fit)
    n_d = problem.y.size
    lm, lu = fit.lm[None, :], fit.lu[None, :]
    r0 = problem.residuals(Model(), np.zeros((1, 0)), lm, lu)[0]
    rows, vecs = {}, {}
    for c in candidates:
        model = Model((c,))
        ref = _reference(c)
        ths = []
        for j in range(c.dim):
            t = np.zeros(c.dim)
            t[j] = ref[j]
            ths.append(t)
        rr = problem.residuals(model, np.stack(ths), np.repeat(lm, c.dim, 0), np.repeat(lu, c.dim, 0))
        S = np.stack([(rr[j] - r0) / ref[j] for j in range(c.dim)], 1)  # (rows, dim)
        P = np.stack([both(S[:, j]) for j in range(c.dim)], 1)
        ext = float(np.hypot(*c.scale())) if c.radius is None and c.dim == 2 else float(c.radius or c.scale()[0])
        raw2 = float((S**2).sum())
        vis2 = float((P**2).sum())

        def rms_part(M: np.ndarray, part: slice | np.ndarray, sd) -> float:
            x = M[part] * np.broadcast_to(sd, (M[part].shape[0],))[:, None]  # back to log units
            return float(np.sqrt(np.mean((x**2).sum(1)) if x.size else 0.0))

        dpart = slice(0, n_d)
        vis_d = rms_part(P, dpart, problem.sd_d) * ext
        vis_t = 0.0
        if problem.use_t:
            # the stop time's rows where the log has them, else the first observable beside the displacement
            rows_t = problem.aux_rows("stop_time") if "stop_time" in problem.aux else problem.aux_rows(problem.aux[0])
            vis_t = rms_part(P, n_d + rows_t, problem.sd_t[rows_t]) * ext
        absorbed = 1.0 - vis2 / raw2 if raw2 > 0 else 0.0
        by_mass = by_fric = 0.0
        if raw2 > 0:
            if problem.fixed_lm is None:
                by_mass = 1.0 - float(sum((mass_only(S[:, j]) ** 2).sum() for j in range(c.dim))) / raw2
            if problem.fixed_lu is None:
                by_fric = 1.0 - float(sum((fric_only(S[:, j]) ** 2).sum() for j in range(c.dim))) / raw2
        rows[c.name] = dict(
            raw_rms_at_bound=rms_part(S, dpart, problem.sd_d) * ext,
            visible_rms_at_bound=vis_d,
            visible_stop_time_rms_at_bound=vis_t if problem.use_t else None,
            visible_share=1.0 - absorbed,
            absorbed_by_fit=absorbed,
            absorbed_by_mass=by_mass,
            absorbed_by_friction=by_fric,
            identifiable=bool(max(vis_d, vis_t) >= opts.min_visible),
            fit_alias=fit_alias_text(
                c,
                absorbed=absorbed,
                by_mass=by_mass,
                by_friction=by_fric,
                k_free=problem.k_free,
                share=opts.fit_alias_share,
            ),
        )
        vecs[c.name] = P
    restricted = {c.name: r for c in candidates if (r := _restriction(c, vecs[c.name], problem, opts)) is not None}
    for name, r in restricted.items():  # the unseen combination is no part of what it can be confused with
        vecs[name] = vecs[name] @ np.asarray(r.direction)[:, None]
    # the discrepancy is no mechanism: it joins no alias class; what it can imitate is said apart
    disc = next((c.name for c in candidates if not c.is_library), None)
    mimics = {}
    if disc is not None:
        mimics = {
            c.name: _canonical(vecs[disc], vecs[c.name])
            for c in candidates
            if c.is_library and rows[c.name]["identifiable"]
        }
    ident = [c.name for c in candidates if rows[c.name]["identifiable"] and c.is_library]
    cos: dict[str, float] = {}
    parent = {n: n for n in ident}

    def root(n: str) -> str:
        while parent[n] != n:
            n = parent[n]
        return n

    for i, a in enumerate(ident):
        for b in ident[i + 1 :]:
            va, vb = vecs[a], vecs[b]
            if va.shape[1] == 1 and vb.shape[1] == 1:
                cval = float(va[:, 0] @ vb[:, 0] / (np.linalg.norm(va) * np.linalg.norm(vb) + 1e-300))
            else:
                cval = _canonical(va, vb)
            cos[f"{a}|{b}"] = cval
            if abs(cval) >= opts.alias_cos:
                parent[root(b)] = root(a)
    classes: dict[str, list[str]] = {}
    for n in ident:
        classes.setdefault(root(n), []).append(n)
    class_of = {n: "+".join(members) for members in classes.values() for n in members}
    if disc is not None and rows[disc]["identifiable"]:
        class_of[disc] = disc
    effects = {n: CandidateAliasing(**row, cls=class_of.get(n, NOT_IDENTIFIABLE)) for n, row in rows.items()}
    return Aliasing(
        effects=effects,
        classes=sorted(set(class_of.values())),
        not_identifiable=[c.name for c in candidates if not effects[c.name].identifiable],
        aliased_with_fit=[c.name for c in candidates if effects[c.name].fit_alias],
        projected_cosine=cos,
        discrepancy_mimics=mimics,
        mimicked=[n for n, r in mimics.items() if r >= opts.alias_cos],
        restricted=restricted,
    )


def _restriction(c: Candidate, P: np.ndarray, problem: Problem, opts: Config) -> Restriction | None:
    """The one combination of a two-component effect these pushes can see, when they cannot see the other
    (pushes in four directions 90 degrees apart see only the cos 2(theta) part of an anisotropy)."""
    if c.dim != 2 or not c.is_library:
        return None
    M = P * problem.row_sd[:, None]  # back to log units
    _, sv, vt = np.linalg.svd(M, full_matrices=False)
    # the RMS change along each right singular vector at the effect's largest magnitude
    at_bound = sv / np.sqrt(max(M.shape[0], 1)) * float(c.radius)
    strong, weak = float(at_bound[0]), float(at_bound[-1])
    if not (strong >= opts.min_visible > weak):
        return None
    u = vt[0] / np.linalg.norm(vt[0])
    if c.kind == FRICTION2:
        axis = float(np.degrees(np.arctan2(u[1], u[0]) / 2.0)) % 180.0
        note = (
            f"these pushes' directions show only how friction along {axis:.0f}/{(axis + 180) % 360:.0f} degrees "
            f"differs from friction along {(axis + 90) % 180:.0f}/{(axis + 270) % 360:.0f} degrees (a cos 2 theta "
            "part), not the anisotropy's axis; push along the diagonals between them to find it"
        )
    else:
        az = float(np.degrees(np.arctan2(u[1], u[0]))) % 360.0
        note = (
            f"these pushes' directions show only the slope along {az:.0f} degrees, not across it; push in other "
            "directions to find its azimuth"
        )
    return Restriction(direction=(float(u[0]), float(u[1])), weak_rms_at_bound=weak, note=note)
